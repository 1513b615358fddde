"""The rigid movers of a head: the jaw about its hinge, the eyeballs about their centres.

Constants here were measured on ICT-FaceKit's generic head (``scripts/bench/bench_head.py``
checks them on identities 000-019, which they were not fitted on):

- its jawOpen turns the lower teeth 25.3° about a left-right axis through the
  hinge (residual 0.18 mm over 4,400 teeth vertices). The hinge sits
  :data:`HINGE_DOWN` of the way down from the ear-level jawline landmarks
  (0, 16) to the chin (8), and :data:`HINGE_BACK_IOD` eye distances behind them;
- the chin's skin turns 19-20° of those 25°: soft tissue lags the bone, so the
  bone's rotation is the skin's times :data:`JAW_BONE_GAIN`.
"""
from __future__ import annotations

import numpy as np

from .landmark_scheme import CHIN, JAW_LEFT_END, JAW_RIGHT_END

HINGE_DOWN = 0.386
HINGE_BACK_IOD = 0.26
JAW_BONE_GAIN = 1.3
#: Eyeball rotation (degrees) of the gaze AUs at weight 1: 61 left, 62 right, 63 up, 64 down
#: (the subject's; a comfortable, not extreme, gaze).
GAZE_DEGREES = {61: (0.0, 25.0), 62: (0.0, -25.0), 63: (-20.0, 0.0), 64: (20.0, 0.0)}


def jaw_hinge(Lf, eye_distance) -> np.ndarray:
    """The jaw hinge (face frame, mm) from the landmarks."""
    mid = 0.5 * (Lf[JAW_RIGHT_END] + Lf[JAW_LEFT_END])
    return np.array([0.0, mid[1] + HINGE_DOWN * (Lf[CHIN, 1] - mid[1]), mid[2] - HINGE_BACK_IOD * eye_distance])


def rotation_vector_matrix(rv) -> np.ndarray:
    """Rotation matrix of a rotation vector (axis × angle in radians), by Rodrigues' formula."""
    rv = np.asarray(rv, dtype=np.float64)
    angle = np.linalg.norm(rv)
    if angle < 1e-12:
        return np.eye(3)
    k = rv / angle
    K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + np.sin(angle) * K + (1 - np.cos(angle)) * K @ K


def rotation_vector(R) -> np.ndarray:
    """Rotation vector of a rotation matrix (inverse of :func:`rotation_vector_matrix`)."""
    angle = np.arccos(np.clip((np.trace(R) - 1) / 2, -1.0, 1.0))
    if angle < 1e-12:
        return np.zeros(3)
    w = np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]])
    if np.pi - angle < 1e-6:  # half turn: the axis is the eigenvector of eigenvalue 1
        vals, vecs = np.linalg.eigh(R + R.T)
        return np.pi * vecs[:, np.argmax(vals)]
    return angle * w / (2 * np.sin(angle))


def jaw_motion(points, displacement, hinge):
    """Rotation about ``hinge`` plus translation that best moves ``points`` by ``displacement``.

    Orthogonal Procrustes with the centre held at the hinge, then the mean
    remaining offset as the translation (a jaw slides forward and sideways too).

    Returns
    -------
    rv : (3,) rotation vector (radians)
    t : (3,) translation (mm)
    """
    P = points - hinge
    Q = P + displacement
    U, _, Vt = np.linalg.svd(P.T @ Q)
    d = np.sign(np.linalg.det(Vt.T @ U.T))
    R = Vt.T @ np.diag([1.0, 1.0, d]) @ U.T
    return rotation_vector(R), (Q - P @ R.T).mean(0)


def rigid_displacement(X, centre, R, t=None) -> np.ndarray:
    """Displacement of points ``X`` rotated by ``R`` about ``centre`` and moved by ``t``."""
    Xc = X - centre
    D = Xc @ R.T - Xc
    return D if t is None else D + t


def gaze_matrix(weights) -> np.ndarray:
    """Eyeball rotation for gaze AU weights ``{61: w, ...}``: pitch about x, then yaw about y."""
    pitch = sum(GAZE_DEGREES[a][0] * w for a, w in weights.items())
    yaw = sum(GAZE_DEGREES[a][1] * w for a, w in weights.items())
    Ry = rotation_vector_matrix([0.0, np.radians(yaw), 0.0])
    Rx = rotation_vector_matrix([np.radians(pitch), 0.0, 0.0])
    return Ry @ Rx
