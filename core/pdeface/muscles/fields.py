"""Muscle fields learned from scans: each muscle's Waters field plus a correction within its reach.

Twenty-four Waters pulls of fixed shape capture about a third of ICT-FaceKit's AU motion: they
lack the skin's depth, the cheek's fold, the lips' roll and push. Here each muscle keeps its
Waters field (placed on the face from its landmarks, :mod:`pdeface.muscles.placement`) and adds a
*correction* at the face's curve points, confined to the muscle's reach: the curve points within
:data:`REACH` eye distances of where its Waters field moves the skin. The corrections and the AUs'
activations are learned together from scan AUs (:func:`learn_corrections`), so a muscle still acts
only where it lies, and an AU is still 24 activations and one linear shape key.

A correction is stored per curve point of the layout it was learned on, in the face frame (mm at
activation 1), and goes to another face as descriptors do (:mod:`pdeface.au.retarget`): the same
curve index, scaled per axis by the ratio of face sizes.

File (``data/muscle_fields.npz``, named by the muscle table): ``format``, ``muscles`` (the 24
names in order), ``corrections`` (24, K, J, 3), ``face_size`` (3,) mm of the face they were
learned on, ``notice``.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..au.retarget import face_size
from ..errors import ModelFormatError
from ..io.files import load_npz
from ..surface.frame import FACE_REACH_MM
from .placement import BOUNDS, MUSCLE_NAMES

FORMAT = "pdeface.muscle-fields"
#: How far (eye distances) a muscle's correction may reach beyond where its Waters field moves the
#: skin. Median share of the AUs' curve motion matched, by reach: 0.15 e 0.64, 0.3 e 0.70, 0.5 e 0.76,
#: 0.8 e 0.76 (captured 0.78 against 0.76, for muscles reaching 5 cm from their anatomy).
REACH = 0.5
#: Where a Waters field "moves the skin": above this fraction of its largest motion.
MOVES = 0.05
#: Ridge weight pulling the corrections towards zero (the pure Waters field), per unit of an AU's
#: relative error.
RIDGE = 0.01


@dataclass
class LearnedFields:
    """Per-muscle corrections (24, K, J, 3) on the curve points of the face (of ``face_size``) they were learned on."""

    corrections: np.ndarray
    face_size: np.ndarray
    notice: str = ""

    @property
    def layout(self) -> tuple:
        return self.corrections.shape[1:3]

    def on(self, face) -> np.ndarray | None:
        """The corrections carried to ``face`` (scaled per axis by face size); None where its curve
        layout is not the one they were learned on."""

        if face.curve_points().shape[:2] != self.layout:
            return None
        return self.corrections * (face_size(face) / self.face_size)


def reach_mask(points, waters_fields, reach_mm) -> np.ndarray:
    """(24, P) bool: the points within ``reach_mm`` of where each Waters field moves them.

    ``points`` (P, 3); ``waters_fields`` (24, P, 3) at activation 1.
    """
    from scipy.spatial import cKDTree

    points = np.asarray(points, np.float64)
    mag = np.linalg.norm(waters_fields, axis=2)
    mask = np.zeros(mag.shape, bool)
    for m, row in enumerate(mag):
        moving = row > MOVES * row.max() if row.max() > 0 else np.zeros(len(row), bool)
        if moving.any():
            mask[m] = cKDTree(points[moving]).query(points)[0] <= reach_mm
    return mask


def learn_corrections(waters, targets, activations, mask, ridge=RIDGE, rounds=60, log=None):
    """Learn the muscles' corrections and the AUs' activations together (alternating least squares).

    Minimises Σ_k |a_k·(W + C) − t_k|² / |t_k|² + ridge·|C|² / |t_k|² with C zero outside ``mask``
    and each a_k within :data:`~pdeface.muscles.placement.BOUNDS`: each round solves C given the
    activations (one small ridge regression per coordinate, over the muscles that reach it), then
    each AU's activations given C (bounded least squares).

    Parameters
    ----------
    waters : (24, N) array
        Waters fields at activation 1, flattened over curve-point coordinates.
    targets : (n_aus, N) array
        Each AU's curve-point motion.
    activations : (n_aus, 24) array
        Starting activations (e.g. calibrated on the Waters fields alone).
    mask : (24, N) bool
        Where each muscle may be corrected (:func:`reach_mask`, repeated per coordinate).
    ridge : float
    rounds : int
    log : callable, optional
        Called with ``(round, median relative RMS error)``.

    Returns
    -------
    corrections : (24, N) array
    activations : (n_aus, 24) array
    """
    from scipy.optimize import lsq_linear

    W = np.asarray(waters, np.float64)
    T = np.asarray(targets, np.float64)
    A = np.array(activations, np.float64)
    mask = np.asarray(mask, bool)
    weight = 1 / np.maximum(np.sqrt((T ** 2).mean(axis=1)), 1e-12)  # each AU by its own motion
    lo, hi = np.array([BOUNDS[n] for n in MUSCLE_NAMES]).T
    groups = {}  # coordinates reached by the same muscles share one solve
    for j, col in enumerate(mask.T):
        groups.setdefault(col.tobytes(), []).append(j)
    groups = [(np.nonzero(mask[:, js[0]])[0], np.array(js)) for js in groups.values()]
    groups = [(ms, js) for ms, js in groups if len(ms)]
    C = np.zeros_like(W)
    for r in range(rounds):
        Aw = A * weight[:, None]
        R = (T - A @ W) * weight[:, None]
        for ms, js in groups:
            M = Aw[:, ms]
            C[np.ix_(ms, js)] = np.linalg.solve(M.T @ M + ridge * np.eye(len(ms)), M.T @ R[:, js])
        F = W + C
        for k in range(len(T)):
            A[k] = lsq_linear(F.T, T[k], bounds=(lo, hi)).x
        if log is not None:
            err = np.sqrt(((A @ F - T) ** 2).mean(axis=1)) * weight
            log(r, float(np.median(err)))
    return C, A


def load_fields(path) -> LearnedFields:
    """Read and check a muscle-fields file."""
    path = Path(path)
    data = load_npz(path, FORMAT, "muscle fields")
    if [str(n) for n in np.atleast_1d(data.get("muscles", []))] != list(MUSCLE_NAMES):
        raise ModelFormatError(f"{path}: 'muscles' must list the 24 muscles in order")
    try:
        C = np.asarray(data.get("corrections", np.zeros(0)), np.float64)
        size = np.asarray(data.get("face_size", np.zeros(0)), np.float64)
    except (TypeError, ValueError):
        raise ModelFormatError(f"{path}: 'corrections' and 'face_size' must be numbers") from None
    if (C.ndim != 4 or C.shape[0] != len(MUSCLE_NAMES) or C.shape[3] != 3 or not np.isfinite(C).all()
            or np.abs(C).max(initial=0) > FACE_REACH_MM):
        raise ModelFormatError(f"{path}: 'corrections' must be finite (within {FACE_REACH_MM:g} mm), shaped "
                               "(24, curves, points, 3); "
                               f"got {C.shape}")
    if size.shape != (3,) or not (np.isfinite(size).all() and (size > 0).all()):
        raise ModelFormatError(f"{path}: 'face_size' must be 3 positive numbers (mm)")
    return LearnedFields(C, size, str(data.get("notice", "")))
