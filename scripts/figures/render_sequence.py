"""Render a PDE face animation headless, from a checkout (``pdeface render`` does the same when installed).

Runs as ``blender -b -P scripts/figures/render_sequence.py -- ARGS`` and as
``python scripts/figures/render_sequence.py ARGS`` with the bpy module; ``--help`` lists
the arguments. The work is ``blender_addon/headless.py``, which travels with
the add-on.
"""
import importlib.util
import sys
from pathlib import Path

HEADLESS = Path(__file__).resolve().parents[2] / "blender_addon" / "headless.py"


def load_headless():
    """The headless renderer module, loaded by path (its add-on package imports bpy)."""
    spec = importlib.util.spec_from_file_location("pdeface_headless", HEADLESS)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


if __name__ == "__main__":
    sys.exit(load_headless().main())  # inside blender -b -P too: Blender exits with this status
