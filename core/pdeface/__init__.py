"""pdeface: FACS Action Units as PDE-surface descriptors.

The core is numpy/scipy only and never imports bpy. Its rooms, each using only those listed
before it (``tests/core/test_rooms.py`` holds the order):

- ground: :mod:`~pdeface.errors`, :mod:`~pdeface.geometry`, :mod:`~pdeface.landmark_scheme` (the 68
  landmarks' names), :mod:`~pdeface.units` (mesh units, by name or number), :mod:`~pdeface.facs` (AU keys,
  weights, intensity letters), :mod:`~pdeface.rigid` (jaw hinge, gaze), :mod:`~pdeface.mesh`, :mod:`~pdeface.assets` (the bundled data's paths and meshes)
- :mod:`pdeface.io` — plain files: atomic writes, meshes (OBJ/PLY), PNG, numeric codecs
- :mod:`pdeface.presets` — named AU weight sets, the mixers' names, preset files
- :mod:`pdeface.surface` — a neutral face as PDE boundary curves: frame, layout, rims, curves,
  fourier, pde, fit, sampling, model, report, profiles, scan
- :mod:`pdeface.au` — Action Units on that face: descriptor, capture, expressions (mixing, the shape
  basis), retarget, ict, aureport, descriptor and model files
- :mod:`pdeface.muscles` — the Waters muscles; :mod:`pdeface.posing` — weights + mixer → posed curves
- :mod:`pdeface.stream` — the live AU stream; :mod:`pdeface.animation` — timelines, the method's
  sequence, AU data from trackers
- :mod:`pdeface.head` — the user's whole head; :mod:`pdeface.fdt` — Facial Deformation Tables;
  :mod:`pdeface.landmarks` — the 68 landmarks found automatically
- on top: :mod:`~pdeface.cli` (the command line)

Main entry points, also importable from ``pdeface`` itself: :func:`fit_face`, :func:`face_mesh`,
:func:`accuracy_report`, :func:`save_model` / :func:`load_model`, :func:`read_mesh` /
:func:`write_mesh`, :func:`read_landmarks` / :func:`landmark_points`, :func:`detect_landmarks`.

The module names of pdeface 0.1 (``pdeface.fit``, ``pdeface.model``, ``pdeface.meshio`` ...)
still import: each is an alias of the module(s) its contents moved to (:data:`MOVED`).
"""
import importlib
import importlib.util
import sys
import types

from .errors import LandmarkError, LayoutError, MeshError, ModelFormatError, PdeFaceError

__version__ = "0.1.0"

#: Public names importable from ``pdeface`` → the module that defines them.
_API = {
    "fit_face": "surface.fit", "face_mesh": "surface.fit", "accuracy_report": "surface.report",
    "FaceModel": "surface.model", "save_model": "au.modelfile", "load_model": "au.modelfile",
    "read_mesh": "io.meshio", "write_mesh": "io.meshio",
    "read_landmarks": "surface.frame", "landmark_points": "surface.frame",
}
#: Public names that are another module's name for the same thing.
_ALIASES = {"detect_landmarks": ("landmarks.pipeline", "detect")}
__all__ = ["PdeFaceError", "MeshError", "LandmarkError", "LayoutError", "ModelFormatError", "__version__",
           *_API, *_ALIASES]

#: pdeface 0.1 module → the modules its names now live in (looked up in order).
MOVED = {
    "files": ("io.files",), "meshio": ("io.meshio",), "codec": ("io.codec",), "png": ("io.png",),
    "audata": ("animation.trackers",), "timeline": ("animation.timeline",),
    "frame": ("surface.frame",), "layout": ("surface.layout",), "rims": ("surface.rims",),
    "curves": ("surface.curves",), "fourier": ("surface.fourier",), "pde": ("surface.pde",),
    "fit": ("surface.fit",), "model": ("surface.model", "au.modelfile", "assets"),
    "report": ("surface.report", "surface.profiles"), "texture": ("surface.texture",),
    "descriptor": ("au.descriptor", "au.capture", "au.descriptorfile"),
    "expressions": ("au.expressions", "presets", "posing", "facs"), "retarget": ("au.retarget",),
    "ict": ("au.ict",), "aureport": ("au.aureport",), "sequence": ("animation.sequence",),
}


def __getattr__(name):
    if name in _API:
        return getattr(importlib.import_module(f"{__name__}.{_API[name]}"), name)
    if name in _ALIASES:
        module, attr = _ALIASES[name]
        return getattr(importlib.import_module(f"{__name__}.{module}"), attr)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


class _MovedModules:
    """Imports ``pdeface.<0.1 name>`` as a module that reads its names from where they moved.

    A meta path finder and its loader by their methods (the import system asks for no more): subclassing
    ``importlib.abc``'s classes imported ``importlib.resources``, ``tempfile`` & co. at every command's start
    (about 20 ms, issue #35).
    """

    def find_spec(self, fullname, path=None, target=None):
        prefix, _, old = fullname.rpartition(".")
        if prefix == __name__ and old in MOVED:
            return importlib.util.spec_from_loader(fullname, self)
        return None

    def create_module(self, spec):
        old = spec.name.rpartition(".")[2]
        homes = [importlib.import_module(f"{__name__}.{m}") for m in MOVED[old]]
        module = types.ModuleType(spec.name, f"pdeface 0.1's {old}: now {', '.join(h.__name__ for h in homes)}")

        def lookup(attr):
            for home in homes:
                if hasattr(home, attr):
                    return getattr(home, attr)
            raise AttributeError(f"module {spec.name!r} has no attribute {attr!r}")

        module.__getattr__ = lookup
        return module

    def exec_module(self, module):
        pass


if not any(isinstance(f, _MovedModules) for f in sys.meta_path):
    sys.meta_path.append(_MovedModules())
