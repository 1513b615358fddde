"""ICT's generic head laid onto a character's skin: its landmarks carried by a similarity (:func:`carried`), or a
region of it laid rigidly by iterated closest points (:func:`settle_on_skin`).

Shared by the brows and the nasion strip (:mod:`.brows`) and the jaw's sides (:mod:`.contour`): each poses ICT's head
by found landmarks it trusts (a similarity); a region then settles on the skin with those anchors kept in the fit, so
the region's own landmarks can be read off where they land.
"""
from __future__ import annotations

from functools import lru_cache

import numpy as np

from ..assets import generic_head_geometry
from ..geometry import ClosestPoint, similarity

#: Closest-point iterations at most, and the share of pairs kept each time (the nearest: a region's edge may hang
#: over the skin's); they stop once the region moves less than :data:`SETTLED` (eye distances).
ITERATIONS, KEEP, SETTLED = 15, 0.9, 1e-3


@lru_cache(maxsize=1)
def ict_landmarks() -> np.ndarray:
    """ICT's generic head's 68 landmarks (its vertices)."""
    V, _, landmarks = generic_head_geometry()
    return V[landmarks]


def carried(points, rows, around, closest: ClosestPoint) -> np.ndarray:
    """Where ICT's generic head's landmarks ``rows`` land on the skin once its ``around`` are laid onto ``points``'
    by a similarity."""
    L = ict_landmarks()
    s, R, t = similarity(L[list(around)], points[list(around)])
    return closest.query(s * L[list(rows)] @ R.T + t)[3]


def settle_on_skin(closest: ClosestPoint, region, model_anchors, found_anchors, pose, eye_distance: float):
    """The rigid motion that lays ``region`` onto the skin, its scale held.

    Parameters
    ----------
    closest : ClosestPoint
        On the character's skin.
    region : (n, 3) array
        The region's points on ICT's generic head.
    model_anchors, found_anchors : (a, 3) arrays
        The anchors on ICT's head and where they were found on the character; they stay in every fit.
    pose : tuple
        ``(s, R, t)``: the starting similarity (from the anchors); ``s`` is kept.
    eye_distance : float
        The character's eye distance (the stopping rule's unit).

    Returns
    -------
    R, t : arrays
        The rotation (3, 3) and translation (3,) such that ``s * region @ R.T + t`` lies on the skin.
    """
    s, R, t = pose
    Q = s * region @ R.T + t
    for _ in range(ITERATIONS):
        C = closest.query(Q)[3]
        d = np.linalg.norm(C - Q, axis=1)
        near = d <= np.quantile(d, KEEP)
        _, R, t = similarity(s * np.concatenate([region[near], model_anchors]),
                             np.concatenate([C[near], found_anchors]), scale=False)
        Q, was = s * region @ R.T + t, Q
        if np.abs(Q - was).max() < SETTLED * eye_distance:
            break
    return R, t
