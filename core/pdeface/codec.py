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


def to_byte_planes(codes: np.ndarray) -> np.ndarray:
    """int16 codes → uint8 (2, ...) high and low byte planes.

    Small codes have high bytes of 0 or 255 only; kept apart from the low
    bytes, they deflate to almost nothing.
    """
    c = np.asarray(codes, np.int16).astype(np.int32) & 0xFFFF
    return np.stack([c >> 8, c & 0xFF]).astype(np.uint8)


def from_byte_planes(planes: np.ndarray) -> np.ndarray:
    """Inverse of :func:`to_byte_planes`."""
    p = np.asarray(planes, np.uint16)
    return ((p[0] << 8) | p[1]).astype(np.uint16).view(np.int16)


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
    u = q.astype(np.int32).view(np.uint32)
    return np.stack([(u >> s) & 0xFF for s in (24, 16, 8, 0)]).astype(np.uint8), step


def decode_coefficients(planes: np.ndarray, step: float) -> np.ndarray:
    """Inverse of :func:`encode_coefficients`: → (K, N+1, 3) float."""
    p = np.asarray(planes, np.uint32)
    q = ((p[0] << 24) | (p[1] << 16) | (p[2] << 8) | p[3]).view(np.int32).astype(np.int64)
    return (np.cumsum(q, axis=-1) * float(step)).transpose(2, 0, 1)
