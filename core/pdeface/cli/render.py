"""``pdeface render``: the add-on's headless renderer, run in a child Python with the bpy module."""
from __future__ import annotations

import importlib.util
import subprocess
import sys
from pathlib import Path

from ..errors import PdeFaceError


def run_headless(argv, capture=False):
    """Run the add-on's headless renderer (``headless.py``) in a child Python with the bpy module.

    The add-on travels with the package (``pdeface_blender``, or ``blender_addon/``
    in a checkout), so this works from an install; this package never imports
    bpy itself. Returns the child's exit status and, with ``capture``, its stdout.
    """
    addon = importlib.util.find_spec("pdeface_blender")
    if importlib.util.find_spec("bpy") is None or addon is None:
        raise PdeFaceError("rendering needs Blender's bpy module and the add-on: "
                           "python -m pip install 'pdeface[blender]' (or -e '.[blender]' in a checkout)")
    script = Path(list(addon.submodule_search_locations)[0]) / "headless.py"
    code = ("import runpy, sys; sys.exit(runpy.run_path(sys.argv.pop(1))['main'](prog='pdeface render'))")
    res = subprocess.run([sys.executable, "-c", code, str(script), *argv],
                         stdout=subprocess.PIPE if capture else None, text=True)
    return res.returncode, res.stdout


def cmd_render(args):
    code, _ = run_headless(args.extra)
    if code:
        raise SystemExit(code)


def register(sub):
    """The ``render`` command: its arguments pass on to the renderer, which describes them."""
    p = sub.add_parser("render", add_help=False, help="render a timeline, presets or AU data headless "
                                                      "(pdeface render --help lists its options)")
    p.set_defaults(func=cmd_render, passes_arguments_on=True)
