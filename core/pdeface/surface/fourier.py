"""Fourier series of closed boundary curves.

Each curve is sampled at ``v_j`` in [0, π] across the face and closed by even
reflection behind it (``X(2π - v) = X(v)``). The closed curve's Fourier series
then has cosine terms only: ``X(v) = Σ_{n=0..N} a_n cos(n v)``, and the sine
coefficients vanish by symmetry, so only ``a_n`` are stored. What the N modes
do not capture is the residual, carried by the PDE's remainder term.
"""
from __future__ import annotations

from functools import lru_cache

import numpy as np


@lru_cache(maxsize=32)
def _fit_operator(n_points: int, n_modes: int) -> tuple[np.ndarray, np.ndarray]:
    v = np.linspace(0.0, np.pi, n_points)
    # The reflected closed curve holds interior points twice and the two ends
    # once; least squares on it weights the front-half samples that way.
    w = np.full(n_points, 2.0)
    w[[0, -1]] = 1.0
    B = np.cos(np.outer(v, np.arange(n_modes + 1)))
    Bw = B * w[:, None]
    return np.linalg.solve(B.T @ Bw, Bw.T), B


def fourier_basis(v: np.ndarray, n_modes: int) -> np.ndarray:
    """``cos(n v)`` for n = 0..N: shape (len(v), N+1)."""
    return np.cos(np.outer(np.asarray(v, dtype=np.float64), np.arange(n_modes + 1)))


def fit_fourier(points: np.ndarray, n_modes: int = 5) -> tuple[np.ndarray, np.ndarray]:
    """Fit N-mode Fourier series to curves sampled evenly in v ∈ [0, π].

    Parameters
    ----------
    points : (K, J, 3) array
        K curves of J points each.
    n_modes : int
        Highest mode N (the method uses 5). Must be < J.

    Returns
    -------
    coefficients : (K, N+1, 3) array
        ``a_n`` per curve and coordinate.
    residual : (K, J, 3) array
        ``points - series(v_j)``; zero when N + 1 >= J.
    """
    P = np.asarray(points, dtype=np.float64)
    K, J, _ = P.shape
    if not 0 <= n_modes < J:
        raise ValueError(f"n_modes must be in 0..{J - 1} for {J} points per curve, got {n_modes}")
    fit, B = _fit_operator(J, n_modes)
    coef = np.einsum("nj,kjc->knc", fit, P)
    residual = P - np.einsum("jn,knc->kjc", B, coef)
    return coef, residual


def evaluate_fourier(coefficients: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Evaluate series ``(K, N+1, 3)`` at ``v``: shape (K, len(v), 3)."""
    B = fourier_basis(v, coefficients.shape[1] - 1)
    return np.einsum("jn,knc->kjc", B, coefficients)
