"""Compact storage of curve residuals: int16 steps, delta-coded along the curve.

Residuals and point changes are smooth along a curve, so storing each point
minus the previous one (after rounding to a fixed step; twice for point
changes) leaves small integers that deflate well. Integer differences undo
exactly, so nothing drifts.
"""
from __future__ import annotations

import numpy as np

#: Default quantisation step (mm).
STEP_MM = 0.01


def encode_residual(residual: np.ndarray, step: float = STEP_MM, order: int = 1) -> tuple[np.ndarray, float]:
    """(..., J, 3) float values along curves → ((3, ..., J) int16 codes, step used).

    Values are rounded to ``step`` and differenced ``order`` times along the
    curve (each time keeping the first value). The step grows past ``step``
    only if a code would not fit in int16.
    """
    r = np.moveaxis(np.asarray(residual, np.float64), -1, 0)
    step = max(step, float(np.abs(r).max(initial=0.0)) * 2 ** order / 32000.0)
    q = np.round(r / step).astype(np.int64)
    for _ in range(order):
        q[..., 1:] = np.diff(q, axis=-1)
    return q.astype(np.int16), step


def decode_residual(codes: np.ndarray, step: float, order: int = 1) -> np.ndarray:
    """Inverse of :func:`encode_residual`: (3, ..., J) int16 → (..., J, 3) float."""
    q = np.asarray(codes, np.int64)
    for _ in range(order):
        q = np.cumsum(q, axis=-1)
    return np.moveaxis(q * float(step), 0, -1)


def to_byte_planes(codes: np.ndarray, nbytes: int = 2) -> np.ndarray:
    """Signed integer codes (int16, or int32 with ``nbytes=4``) → uint8 (nbytes, ...) byte planes, high first.

    Small codes have high bytes of 0 or 255 only; kept apart from the low
    bytes, they deflate to almost nothing.
    """
    c = np.asarray(codes).astype(np.int64) & ((1 << 8 * nbytes) - 1)
    return np.stack([(c >> 8 * b) & 0xFF for b in range(nbytes - 1, -1, -1)]).astype(np.uint8)


def from_byte_planes(planes: np.ndarray) -> np.ndarray:
    """Inverse of :func:`to_byte_planes`: int16 for 2 planes, int32 for 4."""
    p = np.asarray(planes, np.int64)
    nbytes = len(p)
    u = np.zeros(p.shape[1:], np.int64)
    for plane in p:
        u = (u << 8) | plane
    return u.astype({2: np.uint16, 4: np.uint32}[nbytes]).view({2: np.int16, 4: np.int32}[nbytes])


#: Default quantisation step (mm) of a face model's Fourier coefficients.
COEFFICIENT_STEP_MM = 0.001


def encode_coefficients(coefficients: np.ndarray, step: float = COEFFICIENT_STEP_MM) -> tuple[np.ndarray, float]:
    """(K, N+1, 3) coefficients → (4, N+1, 3, K) uint8 byte planes, and the step used.

    Values are rounded to ``step`` (1 µm: far below the fit's error),
    differenced once from curve to curve (neighbouring curves have similar
    series) and stored as the int32 codes' four byte planes, high byte first.
    The step grows only if a code would not fit in 31 bits.
    """
    c = np.asarray(coefficients, np.float64).transpose(1, 2, 0)
    step = max(step, float(np.abs(c).max(initial=0.0)) * 2 / 2 ** 30)
    q = np.round(c / step).astype(np.int64)
    q[..., 1:] = np.diff(q, axis=-1)
    return to_byte_planes(q, 4), step


def decode_coefficients(planes: np.ndarray, step: float) -> np.ndarray:
    """Inverse of :func:`encode_coefficients`: → (K, N+1, 3) float."""
    q = from_byte_planes(planes).astype(np.int64)
    return (np.cumsum(q, axis=-1) * float(step)).transpose(2, 0, 1)
