"""The brows (17-26) where ICT's generic head puts them once its brow region is laid onto the skin.

On a hairless head the face mesh finds no brow hair: its brow points stay where the faces it learned had
them relative to the eyes, and the map carries them to ICT's height above the eyes. On MakeHuman's development
set the true brows (ICT's face registered onto each character's own shape) lie 0.05-0.10 eye distances higher
or lower than that, with the brow ridge. So ICT's generic head's brow region (the skin from the eye centres
:data:`BAND` up, :data:`HALF_WIDTH` to each side) is registered rigidly onto the skin by iterated closest
points, from the pose the found eyes and nose bridge give it (they stay in the fit, holding the region to the
face), at the scale they give; ICT's brow landmarks carried along and taken to the nearest skin point are the
brows. On the development set the brows' median error falls from 8.2 to 6.4 % of the eye distance (outer brows
8.3 to 5.5 %); on ICT's held-out heads they lie 0.2-0.6 mm from ICT's own, as the map's did.

The nasion (27) is found at the eye centres' height, as on ICT, where on the development set's characters whose true
nasion lies low (0.04-0.06 eye distances below the eye centres) it lies 0.07-0.09 too high. The midline between the
eyes is curved along the profile (the glabella above, the nasal root's saddle below), which fixes its height where
the brow region, a wide gently curved sheet, slides: ICT's strip there (:data:`STRIP`) registered on its own, held by
the inner eye corners, places the nasion where the two disagree by more than on ICT's heads
(:func:`nasion_from_midline_strip`; the nose's bridge, 28 and 29, follows it in :mod:`.nose`). It places the inner
brows (21, 22) better too on the development set, but not on a held-out decimated head whose brows then pass the
gate 11.6 % off: they stay the brow region's (design note, *The midline strip*).

The inner brows' height above the nasion is a steadier figure than their height above the eyes: ICT's 21 heads have it
at 0.324-0.341 eye distances, and the registered region, a sheet sliding on a forehead whose slope is not ICT's, can
leave them 0.057-0.103 higher than that over a low nasion (0.075-0.103 on six of the seven) (0.13 too high against the
truth there). Once the nasion is placed, inner brows farther than :data:`INNER_SLACK` from ICT's height above it (either
way) go to that height, on the skin (:func:`inner_brows_over_nasion`; design note, *The inner brows over the nasion*).
"""
from __future__ import annotations

from functools import lru_cache

import numpy as np

from ..assets import generic_head_geometry
from ..geometry import ClosestPoint, similarity
from ..landmark_scheme import NOSE_BRIDGE_TOP, eye_distance
from ..mesh import connected_components
from ..surface.frame import face_frame
from .register import settle_on_skin

#: The brow region of ICT's generic head: heights above the eye centres and half its width (eye distances);
#: its points lie in front of :data:`DEPTH` behind the eye centres (the face, not the temples' sides).
BAND, HALF_WIDTH, DEPTH = (0.0, 0.6), 0.8, 0.35
#: The found landmarks that pose the region and stay in its fit: the eyes and the nose bridge's top.
ANCHORS = (*range(36, 48), 27, 28)
BROWS = range(17, 27)
#: At most this many of the region's vertices take part (evenly spread by their numbering).
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
#: The inner brows, held at ICT's height above the nasion.
INNER_BROWS = (21, 22)
#: They move only where they lie farther than this (eye distances, up or down) from ICT's height above the nasion:
#: over twice the most the found ones lie from it on ICT's 20 identities (0.023; all others within 0.008). On the
#: development set the found ones lie 0.057-0.103 above it over the low nasions, at most 0.057 elsewhere.
INNER_SLACK = 0.05


@lru_cache(maxsize=2)
def _ict_skin_region(band=BAND, half_width=HALF_WIDTH) -> tuple[np.ndarray, np.ndarray]:
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


def _ict_brow_region() -> tuple[np.ndarray, np.ndarray]:
    """ICT's generic head: its brow region's skin vertices (:data:`BAND`, :data:`HALF_WIDTH`) and its 68 landmarks."""
    return _ict_skin_region(BAND, HALF_WIDTH)


def brows_from_template(V, T, points, closest: ClosestPoint | None = None) -> np.ndarray:
    """``points (68, 3)`` with the brows (17-26) from ICT's brow region registered onto the skin ``(V, T)``
    (see the module's docstring).

    Parameters
    ----------
    V, T : arrays
        The mesh and the skin's triangles.
    points : (68, 3) array
        Landmarks on the skin, the mesh's space (the eyes and nose bridge are trusted).
    closest : ClosestPoint, optional
        On ``(V, T)``, when already built.
    """
    out = np.array(points, np.float64)
    region, L = _ict_brow_region()
    anchors = list(ANCHORS)
    closest = ClosestPoint(V, T) if closest is None else closest
    s, R, t = similarity(L[anchors], out[anchors])
    R, t = settle_on_skin(closest, region, L[anchors], out[anchors], (s, R, t), eye_distance(out))
    out[list(BROWS)] = closest.query(s * L[list(BROWS)] @ R.T + t)[3]
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


@lru_cache(maxsize=1)
def ict_inner_brows_over_nasion() -> float:
    """How far ICT's generic head's inner brows (:data:`INNER_BROWS`, their mean) lie above its nasion (27), in eye
    distances along the face frame's up (0.333; its 20 identities' 0.324-0.341)."""
    V, _, landmarks = generic_head_geometry()
    L = V[landmarks]
    return float((L[list(INNER_BROWS)].mean(0) - L[NOSE_BRIDGE_TOP]) @ face_frame(L).rotation[1] / eye_distance(L))


def inner_brows_over_nasion(V, T, points, closest: ClosestPoint | None = None) -> np.ndarray:
    """``points (68, 3)`` with the inner brows (:data:`INNER_BROWS`) moved up or down to
    :func:`ict_inner_brows_over_nasion` above the nasion (27) and onto the skin ``(V, T)``, where they lie farther than
    :data:`INNER_SLACK` from it (see the module's docstring).

    Parameters
    ----------
    V, T : arrays
        The mesh and the skin's triangles.
    points : (68, 3) array
        Landmarks on the skin, the mesh's space (the nasion is trusted).
    closest : ClosestPoint, optional
        On ``(V, T)``, when already built.
    """
    out = np.array(points, np.float64)
    up, eyes = face_frame(out).rotation[1], eye_distance(out)
    inner = list(INNER_BROWS)
    gap = (out[inner].mean(0) - out[NOSE_BRIDGE_TOP]) @ up / eyes - ict_inner_brows_over_nasion()
    if abs(gap) <= INNER_SLACK:
        return out
    closest = ClosestPoint(V, T) if closest is None else closest
    out[inner] = closest.query(out[inner] - gap * eyes * up)[3]
    return out
