"""The nose's bottom (32-34) at the subnasale, where the profile under the nose turns into the upper lip, and the
bridge's middle (28, 29) at ICT's shares of the chord from the nasion to the nose tip.

The face mesh places the nose's bottom where the faces it learned have it relative to the rest of the face; on
MakeHuman's longer noses (the nose bottom 0.75 eye distances below the eye centres, ICT's 0.68-0.72) the found
points sit 0.03-0.04 eye distances too high, on the columella. The subnasale (33) is a feature of the profile:
seen straight on, along the face's midline from the nose tip (30) down to the upper lip's top (51), the point
farthest behind the chord between them. On ICT's held-out heads that point lies within 0.003 eye distances of
ICT's own 33. The nostrils' bottom points (32, 34) beside it move up or down with it and back onto the skin.

The bridge's middle points (28, 29) lie, on every one of ICT's 21 heads, at the same shares of the chord from the
nasion (27) to the nose tip (30): 0.33 and 0.65 (within 0.006) of the way down, projected onto it. The face mesh
puts them nearer the nasion on MakeHuman's longer noses (shares 0.28-0.34 and 0.59-0.66); they go to the profile's
points at ICT's shares between the found 27 and 30 (on the development set their error against the registered
points falls from a median 5.2 to 3.7 % of the eye distance: better on 21 characters of 24, worse on 1).
"""
from __future__ import annotations

from functools import lru_cache

import numpy as np

from ..geometry import ClosestPoint
from ..landmark_scheme import NOSE_BOTTOM, NOSE_BRIDGE_TOP, NOSE_TIP, eye_distance
from ..surface.frame import face_frame
from .register import ict_landmarks
from .render import View, back_project, column_depths

#: The upper lip's top, where the profile's chord from the nose tip ends.
UPPER_LIP_TOP = 51
#: The points beside the subnasale that move with it (the nostrils' bottom).
BESIDE = (32, 34)
#: How far (eye distances) the subnasale may move: a found upper lip far off (parted lips on a coarse mesh) ends
#: the chord elsewhere, and its deepest point is then no subnasale (the found ones lie 0.01-0.07 off).
MAX_MOVE = 0.08
#: Pixels across the straight-on view, and its half-width (eye distances): about 0.0026 eye distances a pixel.
SIZE, HALF = 384, 0.5
#: The bridge's middle points, placed at ICT's shares of the chord from the nasion to the nose tip.
BRIDGE_MIDDLE = (28, 29)


def nose_bottom_at_subnasale(V, T, points, closest: ClosestPoint | None = None) -> np.ndarray:
    """``points (68, 3)`` with the subnasale (33) at the profile's deepest point under the nose on the skin
    ``(V, T)``, and the points :data:`BESIDE` it moved up or down as far (see the module's docstring). Points
    stay where the profile is not seen whole, or where that point lies more than :data:`MAX_MOVE` away.

    Parameters
    ----------
    V, T : arrays
        The mesh and the skin's triangles.
    points : (68, 3) array
        Landmarks on the skin, the mesh's space (the nose tip and the upper lip's top are trusted).
    closest : ClosestPoint, optional
        On ``(V, T)``, when already built.
    """
    out = np.array(points, np.float64)
    f = face_frame(out)
    eyes = eye_distance(out)
    view = View.looking(f.rotation[2], f.rotation[1], out[[NOSE_TIP, UPPER_LIP_TOP]].mean(0), HALF * eyes, SIZE)
    x, y, _ = view.project(out)
    c = view.nearest_pixel(x[[NOSE_TIP, NOSE_BOTTOM, UPPER_LIP_TOP]].mean())
    top, bottom = (view.nearest_pixel(y[j]) for j in (NOSE_TIP, UPPER_LIP_TOP))
    if bottom - top < 3:
        return out
    raster, depth = column_depths(V, T, view, c)
    rows = np.arange(top, bottom + 1)
    d = depth[rows, c]
    if not np.isfinite(d).all():
        return out
    chord = d[0] + (d[-1] - d[0]) * (rows - top) / (bottom - top)
    k = rows[int(np.argmax(chord - d))]
    P = back_project(V, T, raster, np.array([float(c)]), np.array([float(k)]), reach=1)[0][0]
    if not np.isfinite(P).all() or np.linalg.norm(P - out[NOSE_BOTTOM]) > MAX_MOVE * eyes:
        return out
    lift = (P - out[NOSE_BOTTOM]) @ f.rotation[1]  # how far the subnasale moved up (mesh units)
    out[NOSE_BOTTOM] = P
    closest = ClosestPoint(V, T) if closest is None else closest
    out[list(BESIDE)] = closest.query(out[list(BESIDE)] + lift * f.rotation[1])[3]
    return out


@lru_cache(maxsize=1)
def ict_bridge_shares() -> np.ndarray:
    """How far down the chord from the nasion (27) to the nose tip (30) :data:`BRIDGE_MIDDLE` lie on ICT's generic
    head, projected onto it (0.333, 0.650; its 20 identities' within 0.006)."""
    L = ict_landmarks()
    chord = L[NOSE_TIP] - L[NOSE_BRIDGE_TOP]
    return (L[list(BRIDGE_MIDDLE)] - L[NOSE_BRIDGE_TOP]) @ chord / (chord @ chord)


def bridge_at_ict_shares(V, T, points) -> np.ndarray:
    """``points (68, 3)`` with the bridge's middle points (28, 29) on the skin ``(V, T)``'s profile where it lies at
    :func:`ict_bridge_shares` of the chord from the nasion (27) to the nose tip (30) (see the module's docstring).
    They stay where the profile between 27 and 30 is not seen whole, or does not reach a share.

    Parameters
    ----------
    V, T : arrays
        The mesh and the skin's triangles.
    points : (68, 3) array
        Landmarks on the skin, the mesh's space (the nasion and the nose tip are trusted).
    """
    out = np.array(points, np.float64)
    f = face_frame(out)
    view = View.looking(f.rotation[2], f.rotation[1], out[[NOSE_BRIDGE_TOP, NOSE_TIP]].mean(0),
                        HALF * eye_distance(out), SIZE)
    x, y, _ = view.project(out)
    c = view.nearest_pixel(x[NOSE_BRIDGE_TOP:NOSE_TIP + 1].mean())
    top, bottom = (view.nearest_pixel(y[j]) for j in (NOSE_BRIDGE_TOP, NOSE_TIP))
    if bottom - top < 3:
        return out
    raster, _ = column_depths(V, T, view, c)
    rows = np.arange(top, bottom + 1, dtype=np.float64)
    P = back_project(V, T, raster, np.full(len(rows), float(c)), rows, reach=1)[0]
    if not np.isfinite(P).all():
        return out
    chord = out[NOSE_TIP] - out[NOSE_BRIDGE_TOP]
    share = (P - out[NOSE_BRIDGE_TOP]) @ chord / (chord @ chord)  # rises down the profile
    for j, want in zip(BRIDGE_MIDDLE, ict_bridge_shares()):
        k = int(np.argmax(share >= want))
        if share[k] < want or k == 0:
            continue
        w = (want - share[k - 1]) / (share[k] - share[k - 1])
        out[j] = P[k - 1] + w * (P[k] - P[k - 1])  # between two neighbouring profile points, on the skin
    return out
