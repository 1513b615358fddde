"""Helpers shared by the benchmark scripts, and the one writer of their measurement pages.

Each ``bench_X.py`` builds its parser with :func:`bench_parser` and runs its ``main`` through
:func:`run_bench`: what it prints goes to stdout as before and, unless ``--no-page`` is given, onto
``docs/measurements/X.md`` with the command, the date and the machine it was measured on.
"""
import argparse
import os
import platform
import shlex
import statistics
import sys
import time
from datetime import datetime, timezone
from pathlib import Path

# numpy is imported by the helpers that need it: bench_stream measures the player's memory without it.

ROOT = Path(__file__).resolve().parents[2]
PAGES = ROOT / "docs" / "measurements"


def bench_parser(doc):
    """The argument parser of a benchmark whose module docstring is ``doc``, with ``--no-page``."""
    ap = argparse.ArgumentParser(description=doc, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--no-page", action="store_true", help="print only; do not write docs/measurements/")
    return ap


class _Tee:
    """A text stream writing to ``stream`` and keeping a copy."""

    def __init__(self, stream):
        self.stream, self.copy = stream, []

    def write(self, text):
        self.copy.append(text)
        return self.stream.write(text)

    def __getattr__(self, name):
        return getattr(self.stream, name)


def cpu_model():
    """The processor's name as the system gives it."""
    try:
        for line in open("/proc/cpuinfo"):
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def run_bench(main, name, argv=None):
    """Run a benchmark's ``main(argv)`` (its arguments: ``sys.argv[1:]`` by default), then, unless
    ``--no-page`` is among them, write what it printed to ``docs/measurements/<name>.md``."""
    argv = sys.argv[1:] if argv is None else list(argv)
    load, start, t = os.getloadavg(), datetime.now(timezone.utc), time.perf_counter()
    tee = _Tee(sys.stdout)
    sys.stdout = tee
    try:
        result = main(argv)
    finally:
        sys.stdout = tee.stream
    if "--no-page" not in argv:
        module = sys.modules[main.__module__]
        path = write_page(name, module, argv, "".join(tee.copy), start, time.perf_counter() - t, load)
        print(f"wrote {path}", file=sys.stderr)
    return result


def write_page(name, module, argv, printed, start, wall_s, load):
    """``docs/measurements/<name>.md``: what the benchmark ``module`` measures, how it was run, where
    and when, and what it printed (``printed``, verbatim). Returns the path."""
    doc = (module.__doc__ or "").strip()
    command = " ".join(["python -m", module.__spec__.name if module.__spec__ else f"scripts.bench.bench_{name}",
                        *map(shlex.quote, argv)])
    end = os.getloadavg()
    lines = [f"# Measured: {name}", "", doc.splitlines()[0] if doc else "", "",
             f"- Command (from the repository root): `{command}`",
             f"- Date: {start:%Y-%m-%d %H:%M} UTC, {wall_s:.0f} s",
             f"- Machine: {os.cpu_count()} cores, {cpu_model()}; {platform.system()} {platform.machine()}, "
             f"Python {platform.python_version()}",
             "- Load average (1, 5, 15 min): " + ", ".join(f"{x:.2f}" for x in load) + " at the start, "
             + ", ".join(f"{x:.2f}" for x in end) + " at the end",
             "", "Written by the benchmark itself (`--no-page` to leave it); run it again rather than edit it.",
             "", "## What it prints", "", "```text", printed.rstrip("\n"), "```", ""]
    see_also = getattr(module, "SEE_ALSO", ())  # (label, link relative to the page[, what it shows]) tuples
    if see_also:
        lines += ["## See also", "", *(f"- [{label}]({link})" + "".join(f": {n}" for n in note)
                                      for label, link, *note in see_also), ""]
    PAGES.mkdir(parents=True, exist_ok=True)
    path = PAGES / f"{name}.md"
    path.write_text("\n".join(lines))
    return path


def installed_env():
    """The environment for a child process timed as an installed pdeface runs: its bytecode written now
    (``compileall``, as pip leaves an install) and read, where this machine sets ``PYTHONDONTWRITEBYTECODE``
    (every process would compile every pdeface module again: ~0.4 s of CPU)."""
    import compileall

    import pdeface

    compileall.compile_dir(Path(pdeface.__file__).parent, quiet=1)
    return {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}


def median_time(fn, repeat=5):
    """Median wall time of ``fn()`` over ``repeat`` calls (seconds)."""
    times = []
    for _ in range(repeat):
        t = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t)
    return float(statistics.median(times))


def bundled_ict():
    """The bundled face and ICT data every benchmark measures on: (face, V, T, landmark indices, shapes)."""
    from pdeface.assets import load_ict_shapes, load_neutral_scan
    from pdeface.au.modelfile import load_face

    mesh, idx = load_neutral_scan()
    return load_face("default"), mesh.vertices, mesh.triangles()[0], idx, load_ict_shapes()


def clustered(V, T, cell):
    """The mesh remeshed by vertex clustering on a grid of ``cell``: another topology of the same shape."""
    import numpy as np

    key = np.floor(V / cell).astype(np.int64)
    _, inv, counts = np.unique(key, axis=0, return_inverse=True, return_counts=True)
    inv = inv.ravel()
    Vc = np.zeros((len(counts), 3))
    np.add.at(Vc, inv, V)
    Tc = inv[T]
    Tc = Tc[(Tc[:, 0] != Tc[:, 1]) & (Tc[:, 1] != Tc[:, 2]) & (Tc[:, 0] != Tc[:, 2])]
    return Vc / counts[:, None], np.unique(Tc, axis=0)


def body_character(V, T):
    """A whole-body character in metres, Blender's axes (-y front, +z up), of another topology than ``V, T``
    (an ICT head in cm, ICT axes): the head clustered on a 3 mm grid on a box torso, arms and legs.
    Returns vertices, triangles and the matrix taking ICT cm to the body's space (``V @ M.T``)."""
    import numpy as np
    from pdeface.surface.frame import BLENDER_FROM_ICT

    M = BLENDER_FROM_ICT * 0.01
    Vh, Th = clustered(V @ M.T + [0, 0, 1.55], T, 0.003)
    parts = [(Vh, Th)]
    quads = np.array([[0, 1, 3, 2], [4, 6, 7, 5], [0, 4, 5, 1], [2, 3, 7, 6], [0, 2, 6, 4], [1, 5, 7, 3]])
    box_t = np.concatenate([quads[:, [0, 1, 2]], quads[:, [0, 2, 3]]])
    # torso, arms (slightly spread), legs: (centre, half sizes) in metres
    for c, h in [((0, 0, 1.15), (0.18, 0.11, 0.3)), ((-0.3, 0, 1.05), (0.05, 0.05, 0.35)),
                 ((0.3, 0, 1.05), (0.05, 0.05, 0.35)), ((-0.1, 0, 0.42), (0.07, 0.07, 0.42)),
                 ((0.1, 0, 0.42), (0.07, 0.07, 0.42))]:
        box = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)]) * h + c
        parts.append((box, box_t))
    Vs, Ts, n = [], [], 0
    for Vp, Tp in parts:
        Vs.append(Vp)
        Ts.append(Tp + n)
        n += len(Vp)
    return np.concatenate(Vs), np.concatenate(Ts), M, np.array([0, 0, 1.55])


def enable_addon():
    """bpy with the add-on enabled as a real extension (a local repo in a temp dir); returns the add-on module.

    ``BLENDER_USER_RESOURCES`` goes to a temp dir before bpy is imported, so the user's Blender is untouched.
    """
    import tempfile

    os.environ["BLENDER_USER_RESOURCES"] = tempfile.mkdtemp()
    import bpy  # noqa: I001 - first: addon_utils exists only once bpy is imported
    import addon_utils

    repo = Path(tempfile.mkdtemp())
    os.symlink(Path(__file__).resolve().parents[2] / "blender_addon", repo / "pdeface")
    bpy.context.preferences.extensions.repos.new(name="bench", module="bench", custom_directory=str(repo),
                                                 source="USER")
    addon_utils.enable("bl_ext.bench.pdeface", default_set=True)
    return sys.modules["bl_ext.bench.pdeface"]


def disable_addon():
    """Unregister the add-on :func:`enable_addon` enabled (at the session's end, as Blender expects)."""
    import addon_utils

    addon_utils.disable("bl_ext.bench.pdeface", default_set=True)
