"""PDE Face: FACS Action Unit shape keys from a neutral face (Blender 4.2 LTS - 5.0).

Thin over the bpy-free ``pdeface`` package: read Blender data, call pdeface,
write back. The packaged extension ships pdeface as a wheel; in a source
checkout the repository's ``core/`` folder is used.
"""
import os
import sys


def _ensure_core():
    try:
        import pdeface  # noqa: F401
    except ImportError:
        core = os.path.normpath(os.path.join(os.path.dirname(os.path.realpath(__file__)), os.pardir, "core"))
        if os.path.isdir(os.path.join(core, "pdeface")):
            sys.path.insert(0, core)


_ensure_core()

from . import landmarks, operators, panels, properties, warm  # noqa: E402

_modules = (properties, operators, panels, warm)


def register():
    landmarks.add_site()
    for m in _modules:
        m.register()


def unregister():
    for m in reversed(_modules):
        m.unregister()
