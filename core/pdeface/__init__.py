"""pdeface: FACS Action Units as PDE-surface descriptors.

The core is numpy/scipy only and never imports bpy. Its rooms, in data-flow order:

- :mod:`pdeface.surface` — a neutral face as PDE boundary curves: frame, layout, rims, curves,
  fourier, pde, fit, model, report, texture
- :mod:`pdeface.au` — Action Units on that face: facs, descriptor, capture, expressions,
  retarget, ict, aureport, sequence
- :mod:`pdeface.io` — files: meshes, model and descriptor files, tracker CSVs, timelines,
  codecs, PNG and profile writers
- :mod:`pdeface.stream` — the live AU stream: wire formats, player, sender, AU blender rules
- :mod:`pdeface.landmarks` — the 68 landmarks found automatically: render, detector, facemap, pipeline
- shared at the top: :mod:`~pdeface.errors`, :mod:`~pdeface.geometry`, :mod:`~pdeface.mesh`,
  :mod:`~pdeface.assets` (the bundled data) and :mod:`~pdeface.cli` (the command line)

Main entry points, also importable from ``pdeface`` itself: :func:`fit_face`, :func:`face_mesh`,
:func:`accuracy_report`, :func:`save_model` / :func:`load_model`, :func:`read_mesh` /
:func:`write_mesh`, :func:`read_landmarks` / :func:`landmark_points`, :func:`detect_landmarks`.

The module names of pdeface 0.1 (``pdeface.fit``, ``pdeface.model``, ``pdeface.meshio`` ...)
still import: each is an alias of the module(s) its contents moved to (:data:`MOVED`).
"""
import importlib
import importlib.abc
import importlib.util
import sys
import types

from .errors import LandmarkError, LayoutError, MeshError, ModelFormatError, PdeFaceError

__version__ = "0.1.0"

#: Public names importable from ``pdeface`` → the module that defines them.
_API = {
    "fit_face": "surface.fit", "face_mesh": "surface.fit", "accuracy_report": "surface.report",
    "FaceModel": "surface.model", "save_model": "io.modelfile", "load_model": "io.modelfile",
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
    "audata": ("io.trackers",), "timeline": ("io.timeline",),
    "frame": ("surface.frame",), "layout": ("surface.layout",), "rims": ("surface.rims",),
    "curves": ("surface.curves",), "fourier": ("surface.fourier",), "pde": ("surface.pde",),
    "fit": ("surface.fit",), "model": ("surface.model", "io.modelfile", "assets"),
    "report": ("surface.report", "io.profiles"), "texture": ("surface.texture",),
    "facs": ("au.facs",), "descriptor": ("au.descriptor", "au.capture", "io.descriptorfile"),
    "expressions": ("au.expressions",), "retarget": ("au.retarget",), "ict": ("au.ict",),
    "aureport": ("au.aureport",), "sequence": ("au.sequence",),
}


def __getattr__(name):
    if name in _API:
        return getattr(importlib.import_module(f"{__name__}.{_API[name]}"), name)
    if name in _ALIASES:
        module, attr = _ALIASES[name]
        return getattr(importlib.import_module(f"{__name__}.{module}"), attr)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


class _MovedModules(importlib.abc.MetaPathFinder, importlib.abc.Loader):
    """Imports ``pdeface.<0.1 name>`` as a module that reads its names from where they moved."""

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
