"""The add-on's headless renderer (``blender_addon/headless.py``), run in a child Python with the bpy module.

Behind ``pdeface render``, the ``.blend`` of ``pdeface rig`` and the batch jobs' render chunks; this
package never imports bpy itself.
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


def headless_command(argv, prog="pdeface render") -> list:
    """The command line running the add-on's headless renderer (``headless.py``) with ``argv`` in a child Python
    with the bpy module. The add-on travels with the package (``pdeface_blender``, or ``blender_addon/`` in a
    checkout), so this works from an install."""
    addon = importlib.util.find_spec("pdeface_blender")
    if importlib.util.find_spec("bpy") is None or addon is None:
        raise PdeFaceError(NO_BLENDER)
    script = Path(next(iter(addon.submodule_search_locations))) / "headless.py"
    code = "import runpy, sys; sys.exit(runpy.run_path(sys.argv.pop(1))['main'](prog=sys.argv.pop(1)))"
    return [sys.executable, "-c", code, str(script), prog, *map(str, argv)]


def run_headless(argv, capture=False, prog="pdeface render"):
    """Run :func:`headless_command`; returns the child's exit status and, with ``capture``, its stdout."""
    res = subprocess.run(headless_command(argv, prog), stdout=subprocess.PIPE if capture else None,
                         text=True, check=False)
    return res.returncode, res.stdout
