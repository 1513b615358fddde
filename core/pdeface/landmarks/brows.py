"""The brows (17-26) where ICT's generic head puts them once laid onto the found eyes and nose.

On a hairless head the face mesh finds no brow hair: its brow points stay where the faces it learned had
them relative to the eyes, and the map carries them to ICT's height above the eyes. So ICT's generic head's 68
landmarks are laid by a similarity onto the found eyes and nose (:data:`UPPER_FACE`: the upper face, which the mouth
and jaw do not move; the nose's bottom gives the fit its height), and ICT's brows, carried along and taken to the
nearest skin point, are the brows (:func:`brows_from_upper_face`). On ICT's 20 identities, from their own eyes and
nose, that puts the brows a mean 0.5 % of the eye distance from the identity's own (median over the identities; worst
1.8 %), where ICT's brow region registered onto the skin by closest points (the step before) left them 1.4 % off
(worst 1.9 %): a wide, gently curved sheet slides along a forehead whose slope is not ICT's. On MakeHuman's
development set the found brows lie a median 2.3 % from the registered skin points, where the region's lay 3.4 %
(design note, *The brows from the upper face*).

The nasion (27) is found at the eye centres' height, as on ICT, where on the development set's characters whose true
nasion lies low (0.04-0.06 eye distances below the eye centres) it lies 0.07-0.09 too high. The midline between the
eyes is curved along the profile (the glabella above, the nasal root's saddle below), which fixes its height where
a wide, gently curved sheet of forehead would slide: ICT's strip there (:data:`STRIP`) registered on its own, held by
the inner eye corners, places the nasion where the two disagree by more than on ICT's heads
(:func:`nasion_from_midline_strip`; the nose's bridge, 28 and 29, follows it in :mod:`.nose`; design note, *The
midline strip*). It runs after the brows, which the found nasion poses with the rest of the upper face.
"""
from __future__ import annotations

from functools import lru_cache

import numpy as np

from ..assets import generic_head_geometry
from ..geometry import ClosestPoint, similarity
from ..landmark_scheme import NOSE_BRIDGE_TOP, eye_distance
from ..mesh import connected_components
from ..surface.frame import face_frame
from .register import carried, settle_on_skin

BROWS = range(17, 27)
#: The found landmarks that lay ICT's generic head onto the face for its brows: the eyes and the nose (27-47), the upper
#: face, which the mouth and the jaw do not move. On ICT's 20 identities (ICT's generic head laid on each one's own)
#: the brows land a median 0.5 % of the eye distance from the identity's own with these, 0.45-0.6 % with the eyes
#: alone, with the nose's bottom, the mouth or the jaw too; but with the eyes and the bridge alone (27-30: no lever
#: below the eyes) MakeHuman's other nasal roots pitch the fit (brows 3.8 % off the registered skin points, 2.5 here).
UPPER_FACE = tuple(range(27, 48))
#: ICT's skin regions' points lie in front of :data:`DEPTH` behind the eye centres (eye distances: the face, not the
#: temples' sides).
DEPTH = 0.35
#: The found landmarks that pose the midline strip before it settles: the eyes and the nose bridge's top.
ANCHORS = (*range(36, 48), 27, 28)
#: At most this many of a region's vertices take part (evenly spread by their numbering).
MAX_POINTS = 600
#: The midline strip between the eyes on ICT's generic head: heights from the eye centres (from the nasal root, above
#: the dorsum's hump, up the glabella) and half its width (inside the inner eye corners, 0.3 out: off the orbits),
#: eye distances. On the development set the nasion's height errors spread 0.025-0.03 eye distances (p90-p10)
#: for half-widths 0.15-0.25, lower edges 0.20-0.40 below and upper 0.40-0.70 above the eyes (the found one's: 0.08);
#: a strip down to 0.5 below takes in the dorsum and fails (0.06, 0.05 too low), one 0.3 or more wide takes in the
#: orbits' edges (0.06-0.14).
STRIP, STRIP_HALF_WIDTH = (-0.35, 0.55), 0.2
#: The found landmarks that hold the strip (the inner eye corners: its roll about the profile).
STRIP_ANCHORS = (39, 42)
#: The nasion moves only where the strip puts it farther than this (eye distances) from the found one: on ICT's
#: held-out heads the two lie 0.001-0.005 apart (found or moved, 0.2-0.5 mm off), and a fit's AU capture follows
#: such small moves either way; on the development set 0.03-0.06 where the true nasion lies low.
NASION_MIN_MOVE = 0.01


@lru_cache(maxsize=1)
def _ict_skin_region(band, half_width) -> tuple[np.ndarray, np.ndarray]:
    """ICT's generic head: the skin vertices (not the eyeballs, lashes or sockets behind, separate parts) from
    ``band`` (heights above the eye centres) and ``half_width`` to each side, in front of :data:`DEPTH` behind the
    eye centres (eye distances; at most :data:`MAX_POINTS`), and its 68 landmarks."""
    V, T, landmarks = generic_head_geometry()
    L = V[landmarks]
    f = face_frame(L)
    F = f.to_face(V) / (eye_distance(L) * f.scale)
    eyes = f.to_face(L[36:48]).mean(0) / (eye_distance(L) * f.scale)
    labels = connected_components(len(V), T)
    region = np.zeros(len(V), bool)
    region[np.unique(T)] = True
    region &= np.isin(labels, labels[landmarks])
    region &= ((np.abs(F[:, 0]) < half_width) & (F[:, 1] > eyes[1] + band[0]) & (F[:, 1] < eyes[1] + band[1])
               & (F[:, 2] > eyes[2] - DEPTH))
    P = V[region]
    return P[:: max(1, len(P) // MAX_POINTS)], L


def brows_from_upper_face(V, T, points, closest: ClosestPoint | None = None) -> np.ndarray:
    """``points (68, 3)`` with the brows (17-26) where ICT's generic head, laid by a similarity onto the found eyes and
    nose (:data:`UPPER_FACE`), carries its own, each on its nearest skin point (see the module's docstring).

    Parameters
    ----------
    V, T : arrays
        The mesh and the skin's triangles.
    points : (68, 3) array
        Landmarks on the skin, the mesh's space (the eyes and nose are trusted).
    closest : ClosestPoint, optional
        On ``(V, T)``, when already built.
    """
    out = np.array(points, np.float64)
    closest = ClosestPoint(V, T) if closest is None else closest
    out[list(BROWS)] = carried(out, BROWS, UPPER_FACE, closest)
    return out


def nasion_from_midline_strip(V, T, points, closest: ClosestPoint | None = None) -> np.ndarray:
    """``points (68, 3)`` with the nasion (27) where ICT's midline strip between the eyes (:data:`STRIP`), registered
    rigidly onto the skin ``(V, T)`` and held by the inner eye corners, carries ICT's, where that lies over
    :data:`NASION_MIN_MOVE` from the found one (see the module's docstring).

    Parameters
    ----------
    V, T : arrays
        The mesh and the skin's triangles.
    points : (68, 3) array
        Landmarks on the skin, the mesh's space (the eyes and the nose bridge's top pose the strip).
    closest : ClosestPoint, optional
        On ``(V, T)``, when already built.
    """
    out = np.array(points, np.float64)
    strip, L = _ict_skin_region(STRIP, STRIP_HALF_WIDTH)
    closest = ClosestPoint(V, T) if closest is None else closest
    anchors, held = list(ANCHORS), list(STRIP_ANCHORS)
    s, R, t = similarity(L[anchors], out[anchors])
    R, t = settle_on_skin(closest, strip, L[held], out[held], (s, R, t), eye_distance(out))
    nasion = closest.query(s * L[[NOSE_BRIDGE_TOP]] @ R.T + t)[3][0]
    if np.linalg.norm(nasion - out[NOSE_BRIDGE_TOP]) > NASION_MIN_MOVE * eye_distance(out):
        out[NOSE_BRIDGE_TOP] = nasion
    return out
