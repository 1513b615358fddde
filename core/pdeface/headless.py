"""The add-on's headless renderer (``blender_addon/headless.py``), run in a child Python with the bpy module.

Behind ``pdeface render`` and the ``.blend`` of ``pdeface rig``; this package never imports bpy itself. A batch
worker loads the add-on's renderer into its own process instead (:func:`blender_here`): one Blender per worker,
kept between its tasks.
"""
from __future__ import annotations

import importlib.util
import subprocess
import sys
from pathlib import Path

from .errors import PdeFaceError

NO_BLENDER = ("rendering needs Blender's bpy module and the add-on: "
              "python -m pip install 'pdeface[blender]' (or -e '.[blender]' in a checkout)")


def have_blender() -> bool:
    """Whether the bpy module and the add-on can be found (without importing either)."""
    return importlib.util.find_spec("bpy") is not None and importlib.util.find_spec("pdeface_blender") is not None


def _script() -> Path:
    """The add-on's ``headless.py``. The add-on travels with the package (``pdeface_blender``, or
    ``blender_addon/`` in a checkout), so this works from an install."""
    addon = importlib.util.find_spec("pdeface_blender")
    if importlib.util.find_spec("bpy") is None or addon is None:
        raise PdeFaceError(NO_BLENDER)
    return Path(next(iter(addon.submodule_search_locations))) / "headless.py"


_HERE = None


def blender_here():
    """The add-on's headless renderer as a module of this process, loaded once (without the add-on's package,
    which needs Blender to import): its ``render_here`` and ``blend_identity`` run Blender (the bpy module) in
    this process and keep it for the next call."""
    global _HERE
    if _HERE is None:
        spec = importlib.util.spec_from_file_location("pdeface_headless_here", _script())
        module = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(module)
        _HERE = module
    return _HERE


def headless_command(argv, prog="pdeface render") -> list:
    """The command line running the add-on's headless renderer (``headless.py``) with ``argv`` in a child Python
    with the bpy module."""
    script = _script()
    code = "import runpy, sys; sys.exit(runpy.run_path(sys.argv.pop(1))['main'](prog=sys.argv.pop(1)))"
    return [sys.executable, "-c", code, str(script), prog, *map(str, argv)]


def run_headless(argv, capture=False, prog="pdeface render"):
    """Run :func:`headless_command`; returns the child's exit status and, with ``capture``, its stdout."""
    res = subprocess.run(headless_command(argv, prog), stdout=subprocess.PIPE if capture else None,
                         text=True, check=False)
    return res.returncode, res.stdout
