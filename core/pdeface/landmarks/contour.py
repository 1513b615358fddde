"""The jaw's sides, where the jawline is a contour seen edge on: where ICT's generic head puts them once each side
of its face is laid onto the skin.

The jaw points 0-4 and 12-16 lie where the side of the face turns away from the viewer. A frontal detector
places them well across (x), but where along the contour they sit (how high, how far back) it guesses from the
face's oval on a render with no ear or hairline to go by: on MakeHuman's development set (each character annotated
in ICT's convention, ICT's face registered onto it) its heights lie 0.05-0.08 eye distances (rms) from the truth's,
whose jaw ends spread from 0.1 below to 0.2 above the eye centres (higher where the jaw's angle lies farther back).
So, per side, ICT's generic head's side of the face (the cheek, the jaw and its angle: more than :data:`SIDE` from
the midline, :data:`BAND` about the eyes, in front of :data:`DEPTH`) is posed and scaled by the found eye corners,
nose and mouth corners, then registered rigidly onto the skin by iterated closest points (the anchors stay in the
fit, holding it to the face); ICT's jaw points carried along and taken to the nearest skin point are the sides.

On the development set (offline, on the detector's output) the jaw's median error against the registered skin
points falls from 6.6 to 4.5 % of the eye distance, against the annotated vertices from 7.4 to 6.7 % (their grain:
a perfect point scores 5.3 % there). The pose from the anchors does most of it (no iterations: 4.8 and 7.0 %);
point-to-plane iterations, which slide further along the skin, scored 4.6-7.1 % against the skin points as the
anchors' weight went 3 to 0.3. Before, each side point kept the detector's height and took ICT's depth behind
the eyes (or behind the chin's points 6, 10). The jaw angles (5, 11) and the chin's points (6-10) keep the
detector's: the angles taken along let a stylised character's jaw pass the gate wrongly before; the chin's face
the viewer, the detector sees them squarely.
"""
from __future__ import annotations

from functools import lru_cache

import numpy as np

from ..assets import load_head
from ..geometry import ClosestPoint, similarity
from ..landmark_scheme import eye_distance
from ..mesh import connected_components
from ..surface.frame import face_frame

#: The jaw points placed, per side (the subject's right side first, as ICT numbers them: 0-4, then 16-12).
SIDES = ((0, 1, 2, 3, 4), (16, 15, 14, 13, 12))
UPPER_JAW = SIDES[0] + SIDES[1]
#: ICT's side of the face: farther than ``SIDE`` from the midline, heights ``BAND`` about the eye centres, in front
#: of ``DEPTH`` behind them (eye distances; its jaw ends lie 0.84-0.89 behind the eyes, the chin 1.6-1.7 below).
#: Nearer the midline the nose and the chin's middle would hold the side to the face's front (on the development set
#: 0.45 and 0.6 scored 4.8 and 4.7 % against the skin points, 0.2-0.3 4.5-4.6 %).
SIDE, BAND, DEPTH = 0.3, (-1.9, 0.4), 1.0
#: The found landmarks that pose each side and stay in its fit: the eye corners, the nose's tip and bottom, the
#: mouth's corners.
ANCHORS = (36, 39, 42, 45, 30, 33, 48, 54)
#: Closest-point iterations at most, and the share of pairs kept each time (the nearest: the region's edge may hang
#: over the skin's); they stop once the region moves less than :data:`SETTLED` (eye distances).
ITERATIONS, KEEP, SETTLED = 15, 0.9, 1e-3
#: At most this many of a side's vertices take part (evenly spread by their numbering).
MAX_POINTS = 600


@lru_cache(maxsize=1)
def _ict_sides() -> tuple[tuple[np.ndarray, np.ndarray], np.ndarray]:
    """ICT's generic head: its two sides of the face (the skin's vertices, :data:`SIDE`, :data:`BAND`,
    :data:`DEPTH`; not the eyeballs, lashes or mouth's inside, separate parts), in :data:`SIDES`' order, and its 68
    landmarks."""
    mesh, landmarks = load_head()
    V, T = mesh.vertices, mesh.triangles()[0]
    L = V[landmarks]
    f = face_frame(L)
    F = (f.to_face(V) - f.to_face(L[36:48]).mean(0)) / (eye_distance(L) * f.scale)
    labels = connected_components(len(V), T)
    skin = np.zeros(len(V), bool)
    skin[np.unique(T)] = True
    skin &= np.isin(labels, labels[landmarks]) & (F[:, 1] > BAND[0]) & (F[:, 1] < BAND[1]) & (F[:, 2] > -DEPTH)
    sides = []
    for rows in SIDES:
        side = np.sign(F[landmarks[rows[0]], 0])
        P = V[skin & (side * F[:, 0] > SIDE)]
        sides.append(P[:: max(1, len(P) // MAX_POINTS)])
    return tuple(sides), L


def upper_jaw_at_template_depth(V, T, points, closest: ClosestPoint | None = None) -> np.ndarray:
    """``points (68, 3)`` with the jaw's sides (:data:`SIDES`) where ICT's generic head puts them once each side of
    its face is registered onto the skin ``(V, T)`` (see the module's docstring).

    Parameters
    ----------
    V, T : arrays
        The mesh and the skin's triangles.
    points : (68, 3) array
        Landmarks on the skin, the mesh's space (the eye corners, nose and mouth corners are trusted).
    closest : ClosestPoint, optional
        On ``(V, T)``, when already built.
    """
    out = np.array(points, np.float64)
    sides, L = _ict_sides()
    anchors = list(ANCHORS)
    closest = ClosestPoint(V, T) if closest is None else closest
    s, R0, t0 = similarity(L[anchors], out[anchors])
    for rows, region in zip(SIDES, sides):
        R, t = R0, t0
        Q = s * region @ R.T + t
        for _ in range(ITERATIONS):
            C = closest.query(Q)[3]
            d = np.linalg.norm(C - Q, axis=1)
            near = d <= np.quantile(d, KEEP)
            _, R, t = similarity(s * np.concatenate([region[near], L[anchors]]),
                                 np.concatenate([C[near], out[anchors]]), scale=False)
            Q, was = s * region @ R.T + t, Q
            if np.abs(Q - was).max() < SETTLED * eye_distance(out):
                break
        out[list(rows)] = closest.query(s * L[list(rows)] @ R.T + t)[3]
    return out
