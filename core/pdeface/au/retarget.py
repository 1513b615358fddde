"""Apply AU descriptors made on one face to another.

Both faces are fitted with the same layout (curve count, points, modes); the
layout is placed from each face's own landmarks, so curve i lies on the same
anatomy on both. A descriptor is a change in the face frame (mm), so it keeps
its direction there; it is scaled per axis by the ratio of face sizes.
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from ..errors import PdeFaceError
from ..surface.frame import FEATURE_NAMES

SCALINGS = ("face", "none")


def face_size(model) -> np.ndarray:
    """(width, height, depth) of a face in mm from its feature points.

    Width: eye outer corners; height: brows to chin; depth: their mean.
    """
    F = dict(zip(FEATURE_NAMES, model.features))
    width = np.linalg.norm(F["eye_outer_left"] - F["eye_outer_right"])
    brows = np.mean([F[n][1] for n in FEATURE_NAMES if n.startswith("brow")])
    height = brows - F["chin"][1]
    return np.array([width, height, 0.5 * (width + height)])


def retarget(source, target, descriptors=None, scaling="face"):
    """A copy of ``target`` carrying ``source``'s descriptors, scaled to it.

    Parameters
    ----------
    source, target : FaceModel
    descriptors : list, optional
        Defaults to ``source.descriptors``.
    scaling : {'face', 'none'}
        ``face`` scales each axis by the ratio of :func:`face_size`.
    """
    if scaling not in SCALINGS:
        raise PdeFaceError(f"unknown scaling {scaling!r}; use one of {', '.join(SCALINGS)}")
    descriptors = source.descriptors if descriptors is None else descriptors
    if not descriptors:
        raise PdeFaceError("no descriptors to retarget")
    lay = (target.layout.n_curves, target.layout.n_points, target.n_modes)
    bad = [d.key for d in descriptors if d.layout != lay]
    if bad:
        raise PdeFaceError(f"descriptors {', '.join(bad[:5])} were made for layout {descriptors[0].layout}, "
                           f"the target face has {lay}: refit the target with that layout")
    s = face_size(target) / face_size(source) if scaling == "face" else np.ones(3)
    out = replace(target, descriptors=[d.scaled(s) for d in descriptors])
    return out
