"""The headless renderer's progress: a bar on a terminal, a line per stage elsewhere (no bpy needed)."""
import importlib.util
import io
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture
def headless():
    spec = importlib.util.spec_from_file_location("pdeface_headless_progress", ROOT / "blender_addon" / "headless.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


class Stderr(io.StringIO):
    def __init__(self, tty):
        super().__init__()
        self.tty = tty

    def isatty(self):
        return self.tty


def stages(headless, quiet=False):
    headless.progress_bar(0, 1, "rig", quiet)
    headless.progress_bar(1, 1, "rig", quiet)
    for i in range(1, 8):  # the frames report each frame done, from the first
        headless.progress_bar(i, 7, "frames", quiet)


def test_off_a_terminal_a_line_when_a_stage_starts_and_one_when_it_ends(headless, monkeypatch):
    monkeypatch.setattr("sys.stderr", Stderr(tty=False))
    stages(headless)
    stages(headless)  # a second run in the same process says the same
    lines = ["rig: started (0/1)", "rig: done (1/1)", "frames: started (1/7)", "frames: done (7/7)"]
    assert headless.sys.stderr.getvalue() == "\n".join(2 * lines) + "\n"


def test_on_a_terminal_a_bar_drawn_in_place(headless, monkeypatch):
    monkeypatch.setattr("sys.stderr", Stderr(tty=True))
    stages(headless)
    out = headless.sys.stderr.getvalue()
    assert out.count("\n") == 2 and out.count("\r") == 9 and out.endswith("frames [" + 30 * "#" + "] 7/7\n")


def test_quiet_says_nothing(headless, monkeypatch):
    for tty in (False, True):
        monkeypatch.setattr("sys.stderr", Stderr(tty))
        stages(headless, quiet=True)
        assert headless.sys.stderr.getvalue() == ""
