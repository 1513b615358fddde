"""Automatic landmarks: the 68 Multi-PIE landmarks found on any head mesh, offline.

:func:`detect` renders the mesh (:mod:`.render`), finds the face with
MediaPipe's detector and 468-point face mesh (:mod:`.detector`, the optional
``pdeface[landmarks]`` extra), casts the points back onto the mesh and maps
them to the 68 (:mod:`.facemap`, a map fitted on ICT-FaceKit heads). The
steps are in :mod:`.pipeline` (:func:`~.pipeline.find_on_mesh` takes a mesh); the
``pdeface landmarks`` command is :mod:`pdeface.cli.landmarks`.
"""
from .detector import MissingDependencyError, available
from .pipeline import FoundLandmarks, detect

__all__ = ["detect", "FoundLandmarks", "MissingDependencyError", "available"]
