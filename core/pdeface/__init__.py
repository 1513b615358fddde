"""pdeface: FACS Action Units as PDE-surface descriptors.

The core is numpy/scipy only and never imports bpy. Main entry points:

- :func:`pdeface.surface.fit.fit_face` — neutral mesh + landmarks → :class:`pdeface.surface.model.FaceModel`
- :func:`pdeface.surface.fit.face_mesh` — PDE surface as a quad mesh
- :func:`pdeface.surface.report.accuracy_report` — how well the PDE face matches its scan
- :func:`pdeface.surface.model.save_model` / :func:`pdeface.surface.model.load_model`
"""
from .errors import LandmarkError, LayoutError, MeshError, ModelFormatError, PdeFaceError

__version__ = "0.1.0"
__all__ = ["PdeFaceError", "MeshError", "LandmarkError", "LayoutError", "ModelFormatError", "__version__"]
