r"""Bloor–Wilson spectral solution of the face PDE.

The surface ``X(u, v)``, u ∈ [0, 1] from the top curve to the bottom one,
v ∈ [0, π] across the face, solves

.. math:: (\partial_u^2 + a^2 \partial_v^2)^2 X = 0 .

With ``X = Σ_n A_n(u) cos(n v) + R(u, v)`` each mode's ``A_n`` solves the ODE
``(d²/du² − k²)² A = 0`` with ``k = a n``: its solutions are spanned by
``e^{ku}, u e^{ku}, e^{-ku}, u e^{-ku}`` (cubics when ``k = 0``). ``A_n`` takes
the curves' coefficients at the curves' parameters ``u_i``; the remainder
``R`` does the same with ``k = w`` for the residuals, so the surface passes
exactly through every curve point.

Two assemblies:

``smooth`` (default)
    One piecewise solution through all curves, C2 at every curve (so no
    creases), not-a-knot at the ends. A layout may name *breaks*: curve
    intervals that span an opening (between the lids, between the lips).
    The surface stays C1 there, but the runs of curves above and below are
    solved apart (not-a-knot at their ends), so one lip's or lid's motion
    never rings into the other's.
``patches``
    The original method: patches of four consecutive curves (1–4, 4–7, …),
    each one closed-form solution through its four positional curves, C0
    where patches share a curve. Needs 3m + 1 curves.

Everything here is linear in the curve data and precomputed per layout, so a
solve is a few small matrix products.
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property, lru_cache

import numpy as np

from ..errors import LayoutError

ASSEMBLIES = ("smooth", "patches")
_TAYLOR_TERMS = 40


def ode_basis(kappa: float, t: np.ndarray, deriv: int = 0) -> np.ndarray:
    """Basis of ``(d²/dt² − κ²)² f = 0`` on t ∈ [0, 1], and its derivatives.

    For ``κ < 1`` the canonical basis (``f^{(j)}(0) = δ_{mj}``) is summed as a
    Taylor series, which tends smoothly to ``1, t, t²/2, t³/6`` as κ → 0. For
    ``κ >= 1`` the bounded forms ``e^{-κt}, t e^{-κt}, e^{-κ(1-t)},
    (t-1) e^{-κ(1-t)}`` never overflow, however large κ is. Both span the same
    space, so interpolants built on either agree.

    Parameters
    ----------
    kappa : float
        Non-negative wavenumber scaled to the interval.
    t : (p,) array
    deriv : int
        Order of the derivative in t (0-3).

    Returns
    -------
    (p, 4) array
    """
    t = np.asarray(t, dtype=np.float64)
    if kappa < 1.0:
        return _taylor_table(float(kappa), deriv)(t)
    out = np.empty((len(t), 4))
    for m, (lam, c, p) in enumerate(((-kappa, 0.0, 0), (-kappa, 0.0, 1), (kappa, 1.0, 0), (kappa, 1.0, 1))):
        s = t - c
        poly = lam ** deriv * s ** p + (p * deriv * lam ** (deriv - 1) if deriv else 0.0)
        out[:, m] = poly * np.exp(lam * s)
    return out


def ode_bases(kappas, t, deriv: int = 0) -> np.ndarray:
    """:func:`ode_basis` of many wavenumbers at once: ``(len(kappas), p, 4)``, at the same ``t`` (p,) for each or
    at its own row of ``t`` (len(kappas), p). A mesh's operators ask for one basis per curve interval and mode:
    the Taylor sums of all of them are one batched product."""
    kappas = np.asarray(kappas, dtype=np.float64)
    t = np.asarray(t, dtype=np.float64)
    T = np.broadcast_to(t, (len(kappas), t.shape[-1])) if t.ndim == 1 else t
    out = np.empty(T.shape + (4,))
    small = kappas < 1.0
    if small.any():
        D1j, above, power, fact, orders = _taylor_constants(deriv)
        # powers as running products: ``**`` of an integer array is ~50 ns an element
        scale = _powers(kappas[small], power.max())[:, power] * above
        coef = D1j * scale / fact  # (I, 4, terms)
        out[small] = np.matmul(_powers(T[small], orders.max()), np.swapaxes(coef, 1, 2))
    for i in np.nonzero(~small)[0]:
        out[i] = ode_basis(float(kappas[i]), T[i], deriv)
    return out


def _bases_of(ks, h, t, deriv: int = 0) -> np.ndarray:
    """:func:`ode_bases` of ``k * h`` for each wavenumber ``k`` of ``ks``: (len(ks), len(h), p, 4), ``t`` (p,) or one
    row per interval (len(h), p). One batch for all of them; one per wavenumber where ``h`` is a single interval
    (numpy's stacked product of one matrix rounds otherwise than of several: the numbers of one at a time)."""
    k = np.asarray(ks, dtype=np.float64)
    if len(h) == 1:
        return np.stack([ode_bases(kj * h, t, deriv) for kj in k])
    t = np.asarray(t, dtype=np.float64)
    out = ode_bases((k[:, None] * h).ravel(), t if t.ndim == 1 else np.tile(t, (len(k), 1)), deriv)
    return out.reshape((len(k), len(h)) + out.shape[1:])


def _powers(x, n: int) -> np.ndarray:
    """``x ** 0 .. x ** n`` along a new last axis."""
    out = np.empty(np.shape(x) + (n + 1,))
    out[..., 0] = 1.0
    out[..., 1:] = np.asarray(x)[..., None]
    return np.cumprod(out, axis=-1, out=out)


@lru_cache(maxsize=1)
def _unit_taylor_derivatives() -> np.ndarray:
    """f^{(j)}(0) of the canonical basis for κ = 1 (rows m = 0..3)."""
    n = _TAYLOR_TERMS + 8
    D = np.zeros((4, n))
    D[:, :4] = np.eye(4)
    for j in range(4, n):
        D[:, j] = 2 * D[:, j - 2] - D[:, j - 4]
    return D


def _taylor_table(kappa: float, deriv: int):
    """Evaluator of the canonical basis' ``deriv``-th derivative as a Taylor series.

    g_m(t; κ) = κ^{-m} G_m(κ t), so its derivatives at 0 are κ^{j-m} times
    those for κ = 1: one table serves every κ.
    """
    D1j, above, power, fact, orders = _taylor_constants(deriv)
    scale = np.where(above, float(kappa) ** power, 0.0)
    coef = D1j * scale / fact  # (4, terms)

    def evaluate(t):
        return (t[:, None] ** orders) @ coef.T
    return evaluate


@lru_cache(maxsize=4)
def _taylor_constants(deriv: int):
    """What :func:`_taylor_table` needs for every κ: a mesh's operators ask for thousands of tables."""
    j = np.arange(deriv, deriv + _TAYLOR_TERMS + 1)
    m = np.arange(4)[:, None]
    fact = np.cumprod(np.concatenate([[1.0], np.arange(1, _TAYLOR_TERMS + 1)]))
    return (_unit_taylor_derivatives()[:, j], j[None, :] >= m, np.maximum(j[None, :] - m, 0), fact,
            np.arange(_TAYLOR_TERMS + 1)[None, :])


def interval_steps(sub, n_intervals: int) -> tuple:
    """Steps per interval: ``sub`` (an int: every interval; or one int per interval) as a tuple of ``n_intervals``."""
    steps = (int(sub),) * n_intervals if np.ndim(sub) == 0 else tuple(int(s) for s in sub)
    if len(steps) != n_intervals:
        raise LayoutError(f"{len(steps)} subdivisions given for {n_intervals} intervals")
    if min(steps, default=1) < 1:
        raise LayoutError(f"resolution subdivisions must be >= 1, got {min(steps)}")
    return steps


def sampling_key(sub):
    """``sub`` (an int or one per interval) in a hashable form for the operator caches."""
    return int(sub) if np.ndim(sub) == 0 else tuple(int(s) for s in sub)


def subdivide(params, sub) -> np.ndarray:
    """``params`` (increasing) with interval i cut into ``sub[i]`` equal steps (``sub`` an int: each the same)."""
    params = np.asarray(params, dtype=np.float64)
    steps = np.array(interval_steps(sub, len(params) - 1))
    # each interval's start plus its length times j / s, j = 0 .. s - 1: a mesh's operators ask for this often
    interval = np.repeat(np.arange(len(steps)), steps)
    j = np.arange(len(interval)) - np.repeat(np.cumsum(steps) - steps, steps)
    return np.append(params[interval] + np.diff(params)[interval] * j / steps[interval], params[-1])


def sample_v(n_points: int, sub_v) -> np.ndarray:
    """The output columns' curve parameters in [0, π]: ``sub_v`` steps per point interval (an int: each the
    same, the points evenly spaced as :func:`numpy.linspace` places them; or one int per interval)."""
    if np.ndim(sub_v) == 0:
        interval_steps(sub_v, n_points - 1)
        return np.linspace(0.0, np.pi, (n_points - 1) * int(sub_v) + 1)
    return subdivide(np.linspace(0.0, np.pi, n_points), sub_v)


@dataclass(frozen=True)
class Grid:
    """Output sampling of the (u, v) domain.

    ``u`` has ``sub_u`` steps per curve interval and ``v`` has ``sub_v`` steps
    per sample interval (each an int, or one int per interval), so every curve
    point is a grid vertex: with int steps ``u[i * sub_u] == knots[i]`` and
    ``v[j * sub_v] == v_j``.
    """

    u: np.ndarray
    v: np.ndarray
    sub_u: int | tuple
    sub_v: int | tuple


def output_grid(knots: np.ndarray, n_points: int, sub_u, sub_v) -> Grid:
    """Grid with ``sub_u`` rows per curve interval and ``sub_v`` columns per point interval (ints, or one
    int per interval: :func:`subdivide`)."""
    return Grid(subdivide(knots, sub_u), sample_v(n_points, sub_v), sampling_key(sub_u), sampling_key(sub_v))


def _check(knots, assembly):
    if assembly not in ASSEMBLIES:
        raise LayoutError(f"unknown assembly {assembly!r}; use one of {', '.join(ASSEMBLIES)}")
    if np.any(np.diff(knots) <= 0):
        raise LayoutError("curve parameters must increase strictly")
    if assembly == "patches" and (len(knots) - 1) % 3:
        raise LayoutError(f"the patches assembly needs 3m+1 curves (4, 7, ..., 31, 34), got {len(knots)}")


#: A break piece's u-slope at its rims as a share of the adjoining run's. Beyond an opening's corners the
#: rims lie a tenth of a millimetre apart while the runs travel millimetres per interval: with the runs'
#: full slope the piece would loop back between them and fold the mesh; this share keeps it monotone.
BREAK_SLOPE = 0.04
#: Curve intervals each run between breaks needs (its two not-a-knot conditions must differ).
MIN_RUN = 3


def break_fits(K: int, b: int) -> bool:
    """Whether interval ``b`` of K curves can be a break: :data:`MIN_RUN` intervals on either side."""
    return MIN_RUN <= b <= K - 2 - MIN_RUN


def _check_breaks(K: int, breaks: tuple):
    b = np.asarray(breaks, dtype=np.int64)
    if len(b) and (not all(break_fits(K, x) for x in b) or np.any(np.diff(b) < MIN_RUN + 1)):
        raise LayoutError(f"breaks {tuple(breaks)} must leave at least {MIN_RUN} curve intervals on each side of "
                          f"each break ({K} curves)")


@lru_cache(maxsize=512)
def _smooth_coefficients(knots: tuple, k: float, breaks: tuple = (), break_slope: float = BREAK_SLOPE) -> np.ndarray:
    """Per-interval basis coefficients (4(K-1), K) of the C2 interpolant.

    At a break ``b`` (the interval between curves b and b+1) C2 is released
    at both curves, and the runs of intervals on either side get not-a-knot
    ends instead: C1 everywhere, C2 within each run.
    """
    # Uncached: this function keeps its own, and one-wavenumber stacks would push out the surfaces' whole ones.
    return _smooth_coefficient_stack.__wrapped__(knots, (k,), breaks, break_slope)[0]


@lru_cache(maxsize=64)
def _smooth_coefficient_stack(knots: tuple, ks: tuple, breaks: tuple = (),
                              break_slope: float = BREAK_SLOPE) -> np.ndarray:
    """:func:`_smooth_coefficients` of each wavenumber of ``ks``, (len(ks), 4(K-1), K): a surface's modes and
    remainder ask for them together, so their bases are one batch and their systems one stacked solve (the same
    numbers as one at a time)."""
    u = np.array(knots)
    K = len(u)
    _check_breaks(K, breaks)
    ends = {c for b in breaks for c in (b, b + 1)}
    h = np.diff(u)
    n = 4 * (K - 1)
    k = np.array(ks, dtype=np.float64)
    A = np.zeros((len(k), n, n))
    B = np.zeros((n, K))
    # (len(ks), K-1, 4, 2, 4): each interval's basis, its derivatives 0-3, at its two ends
    phi = np.stack([_bases_of(k, h, (0.0, 1.0), d) / (h ** d)[:, None, None] for d in range(4)], axis=2)
    I = np.arange(K - 1)
    corners = 4 * I[:, None] + np.arange(4)
    A[:, 2 * I[:, None], corners], B[2 * I, I] = phi[:, :, 0, 0], 1  # each interval through its two curves
    A[:, 2 * I[:, None] + 1, corners], B[2 * I + 1, I + 1] = phi[:, :, 0, 1], 1
    # the joins at inner curves: (curve, derivative) C1 at a break's rims, C2 elsewhere; then not-a-knot: third
    # derivative continuous at the second and last-but-one curves of each run
    joins = [(i, d) for i in range(1, K - 1) for d in ((1,) if i in ends else (1, 2))]
    bounds = [0, *sorted(ends), K - 1]
    if K >= 4:
        joins += [(i, 3) for first, last in zip(bounds[0::2], bounds[1::2]) for i in (first + 1, last - 1)]
    i, d = np.array(joins, dtype=np.int64).reshape(-1, 2).T
    # Into and out of a break piece the u-slope shrinks to break_slope of the run's: the same tangent
    # direction (so no crease), but the piece no longer overshoots where its rims nearly meet.
    at_break = np.zeros(K + 1, bool)  # by curve: np.isin costs more than the whole test
    at_break[list(breaks)] = True
    above = np.where(at_break[i] & (d < 3), break_slope, 1.0)[:, None]
    below = np.where(at_break[i - 1] & (d < 3), break_slope, 1.0)[:, None]
    rows = 2 * (K - 1) + np.arange(len(i))[:, None]
    A[:, rows, 4 * i[:, None] - 4 + np.arange(4)] = phi[:, i - 1, d, 1] * above
    A[:, rows, 4 * i[:, None] + np.arange(4)] = -phi[:, i, d, 0] * below
    if K < 4:  # natural ends
        r = 2 * (K - 1) + len(i)
        A[:, r, 0:4] = phi[:, 0, 2, 0]
        A[:, r + 1, n - 4:n] = phi[:, -1, 2, 1]
    return np.linalg.solve(A, np.broadcast_to(B, (len(k), n, K)))


@lru_cache(maxsize=512)
def _patch_coefficients(knots: tuple, k: float) -> list:
    """Per-patch basis coefficients (4, 4) mapping its four curves' values."""
    u = np.array(knots)
    out = []
    for p in range(0, len(u) - 1, 3):
        uu = u[p:p + 4]
        H = uu[-1] - uu[0]
        t = (uu - uu[0]) / H
        out.append(np.linalg.inv(ode_basis(k * H, t, 0)))
    return out


def _pieces(knots: tuple, k: float, assembly: str, breaks: tuple, break_slope: float = BREAK_SLOPE) -> list:
    """The assembly's pieces: (first curve, height H, its curves' local u in [0, 1], basis coefficients, columns).

    ``smooth``: one piece per curve interval, whose coefficients (4, K) read all
    K curves; ``patches``: one per patch of 4 curves, whose (4, 4) read its own.
    """
    u = np.array(knots)
    if assembly == "smooth":
        C = _smooth_coefficients(knots, k, breaks, break_slope)
        h = np.diff(u)
        ends = np.array([0.0, 1.0])
        return [(i, h[i], ends, C[4 * i:4 * i + 4], slice(None)) for i in range(len(u) - 1)]
    pieces = []
    for p, Cp in enumerate(_patch_coefficients(knots, k)):
        a = 3 * p
        H = u[a + 3] - u[a]
        pieces.append((a, H, (u[a:a + 4] - u[a]) / H, Cp, slice(a, a + 4)))
    return pieces


@lru_cache(maxsize=512)
def mode_operator(knots: tuple, k: float, sub_u, assembly: str = "smooth", deriv: int = 0,
                  breaks: tuple = (), break_slope: float = BREAK_SLOPE) -> np.ndarray:
    """Matrix (n_u, K) taking the K curve values of one mode to its values on the output rows.

    ``deriv=1`` gives d/du instead. At a curve shared by two pieces, the row
    uses the piece below it (the value is the same either way). ``breaks``
    only affect the ``smooth`` assembly.
    """
    _check(np.array(knots), assembly)
    K = len(knots)
    steps = interval_steps(sub_u, K - 1)
    if assembly == "smooth":
        return _smooth_rows(knots, (k,), steps, deriv, breaks, break_slope)[0]
    rows = []
    for a, H, tk, C, cols in _pieces(knots, k, assembly, breaks, break_slope):
        t = subdivide(tk, steps[a:a + len(tk) - 1])[:-1]
        if a + len(tk) - 1 == K - 1:
            t = np.append(t, 1.0)
        M = np.zeros((len(t), K))
        M[:, cols] = ode_basis(k * H, t, deriv) / H ** deriv @ C
        rows.append(M)
    return np.vstack(rows)


@lru_cache(maxsize=64)  # as many as surface_operator keeps: 7 wavenumbers' rows each
def mode_operators(knots: tuple, ks: tuple, sub_u, assembly: str = "smooth", deriv: int = 0, breaks: tuple = (),
                   break_slope: float = BREAK_SLOPE) -> np.ndarray:
    """:func:`mode_operator` of each wavenumber of ``ks``, (len(ks), n_u, K): a surface's modes and remainder
    evaluated together (the smooth assembly's bases one batch per step count; the same numbers)."""
    if assembly != "smooth":
        return np.stack([mode_operator(knots, k, sub_u, assembly, deriv, breaks, break_slope) for k in ks])
    _check(np.array(knots), assembly)
    return _smooth_rows(knots, ks, interval_steps(sub_u, len(knots) - 1), deriv, breaks, break_slope)


def _smooth_rows(knots: tuple, ks: tuple, steps: tuple, deriv: int, breaks: tuple, break_slope: float) -> np.ndarray:
    """:func:`mode_operators` of the smooth assembly: the intervals of each step count evaluated together, for
    every wavenumber."""
    K = len(knots)
    h = np.diff(np.array(knots))
    k = np.array(ks, dtype=np.float64)
    C = _smooth_coefficient_stack(knots, tuple(ks), breaks, break_slope).reshape(len(k), K - 1, 4, K)
    steps = np.array(steps)
    start = np.concatenate([[0], np.cumsum(steps)])
    M = np.empty((len(k), start[-1] + 1, K))
    # the products a wavenumber at a time, as for one (numpy's small stacked products round otherwise)
    for s in np.unique(steps):
        i = np.nonzero(steps == s)[0]
        B = _bases_of(k, h[i], np.arange(s) / s, deriv) / (h[i] ** deriv)[:, None, None]
        for j in range(len(k)):
            M[j, (start[i][:, None] + np.arange(s)).ravel()] = np.matmul(B[j], C[j, i]).reshape(-1, K)
    for j, kj in enumerate(k):  # the last curve, from the piece above
        M[j, -1] = ode_bases(kj * h[-1:], (1.0,), deriv)[0] / h[-1] ** deriv @ C[j, -1]
    return M


@lru_cache(maxsize=512)
def knot_slopes(knots: tuple, k: float, assembly: str = "smooth", breaks: tuple = ()) -> tuple[np.ndarray, np.ndarray]:
    """d/du at each curve from the piece above and from the piece below.

    Returns two (K, K) matrices (rows for the first/last curve repeat the one
    side that exists). Their difference shows creases at shared curves.
    """
    _check(np.array(knots), assembly)
    K = len(knots)
    above, below = np.zeros((K, K)), np.zeros((K, K))
    for a, H, tk, C, cols in _pieces(knots, k, assembly, breaks):
        d = ode_basis(k * H, tk, 1) / H @ C
        for j in range(len(tk)):
            if j < len(tk) - 1:
                below[a + j, cols] = d[j]
            if j > 0:
                above[a + j, cols] = d[j]
    above[0], below[K - 1] = below[0], above[K - 1]
    return above, below


def cubic_spline_operator(x: np.ndarray, xe: np.ndarray, deriv: int = 0) -> np.ndarray:
    """Matrix (len(xe), len(x)): the not-a-knot cubic spline through values at ``x``, at ``xe``.

    Written out (second-derivative form) so that meshing a face needs numpy only.
    """
    x, xe = np.asarray(x, np.float64), np.asarray(xe, np.float64)
    n = len(x)
    if n < 4:
        raise LayoutError(f"a not-a-knot spline needs at least 4 points, got {n}")
    h = np.diff(x)
    A, B = np.zeros((n, n)), np.zeros((n, n))
    for i in range(1, n - 1):  # C2: moments m from the values y (B maps y to the right-hand side)
        A[i, i - 1:i + 2] = h[i - 1], 2 * (h[i - 1] + h[i]), h[i]
        B[i, i - 1:i + 2] = 6 / h[i - 1], -6 / h[i - 1] - 6 / h[i], 6 / h[i]
    for row, i in ((0, 1), (n - 1, n - 2)):  # not-a-knot: third derivative continuous at x_1 and x_{n-2}
        A[row, i - 1:i + 2] = 1 / h[i - 1], -1 / h[i - 1] - 1 / h[i], 1 / h[i]
    Mm = np.linalg.solve(A, B)  # moments per unit value
    k = np.clip(np.searchsorted(x, xe, side="right") - 1, 0, n - 2)
    hk, a, b = h[k], x[k + 1] - xe, xe - x[k]
    Y = np.eye(n)
    if deriv == 0:
        return (Mm[k] * (a ** 3 / (6 * hk))[:, None] + Mm[k + 1] * (b ** 3 / (6 * hk))[:, None]
                + (Y[k] / hk[:, None] - Mm[k] * (hk / 6)[:, None]) * a[:, None]
                + (Y[k + 1] / hk[:, None] - Mm[k + 1] * (hk / 6)[:, None]) * b[:, None])
    if deriv == 1:
        return (-Mm[k] * (a ** 2 / (2 * hk))[:, None] + Mm[k + 1] * (b ** 2 / (2 * hk))[:, None]
                - (Y[k] / hk[:, None] - Mm[k] * (hk / 6)[:, None])
                + (Y[k + 1] / hk[:, None] - Mm[k + 1] * (hk / 6)[:, None]))
    raise ValueError(f"deriv must be 0 or 1, got {deriv}")


@lru_cache(maxsize=64)
def residual_v_operator(n_points: int, sub_v, deriv: int = 0) -> np.ndarray:
    """Matrix (n_v, J): cubic spline (not-a-knot) through the J samples in v."""
    return cubic_spline_operator(np.linspace(0.0, np.pi, n_points), sample_v(n_points, sub_v), deriv)


@dataclass(frozen=True)
class SurfaceOperator:
    """The PDE solve for one layout and grid as precomputed matrices.

    ``planes(coefficients, residual)`` is then four small matrix products. A
    blend of B surfaces with v-dependent weights (:func:`confined_operator`) is
    one operator too: B blocks of modes, their weights folded into the v factors.
    """

    modes: np.ndarray  # (N+1, n_u, K), or (B, N+1, n_u, K): curve values of mode n → rows
    cos_nv: np.ndarray  # (n_v, B·(N+1)): cos(n v) or its v-derivative (times each block's weight)
    remainder_u: np.ndarray  # (n_u, K), or (B, n_u, K)
    remainder_v: np.ndarray  # (n_v, B·J)

    def apply(self, coefficients: np.ndarray, residual: np.ndarray) -> np.ndarray:
        """(K, N+1, c) coefficients and (K, J, c) residual → (n_u, n_v, c) surface.

        ``c`` is 3 for one face; stacking several along it solves them all at once.
        """
        return np.ascontiguousarray(self.planes(coefficients, residual).transpose(1, 2, 0))

    def planes(self, coefficients: np.ndarray, residual: np.ndarray, reuse=None, dtype=np.float64) -> np.ndarray:
        """(K, N+1, c) coefficients and (K, J, c) residual → the surface as (c, n_u, n_v) planes, one per
        coordinate of each surface: what a computation over the grid's rows and columns reads whole (no strided
        copy of an interleaved grid). The u factors are made per plane and row, so the v factors' products write
        the planes as they are.

        ``reuse``: a list that keeps the products' two buffers between calls (empty at first, or flat buffers the
        caller made; others are made where either is too small or of another dtype): the planes returned are
        then written over the last call's (in the first buffer; the second, at least as large, is scratch until the
        next call). Many solves on one grid or several (a face's keys, a batch at a time) fault in fresh pages for each
        otherwise (issue #35); the same products, so the same numbers.

        ``dtype``: ``np.float32`` solves in float32 (:meth:`_planes32`), for a caller that only screens the values
        (the resolution choice).
        """
        if np.dtype(dtype) == np.float32:
            return self._planes32(coefficients, residual, [] if reuse is None else reuse)
        F, Ru = self._u_factors(coefficients, residual)
        _, _, v_modes, v_remainder = self._plane_factors
        c, n_u, _ = F.shape
        rows = c * n_u
        if reuse is None:
            X = Ru.reshape(rows, -1) @ v_remainder
            X += F.reshape(rows, -1) @ v_modes
            return X.reshape(c, n_u, -1)
        size = rows * v_modes.shape[1]
        if len(reuse) < 2 or any(b.size < size or b.dtype != v_modes.dtype for b in reuse[:2]):
            reuse[:] = [np.empty(size, v_modes.dtype) for _ in range(2)]
        X, product = (b[:size].reshape(rows, -1) for b in reuse)
        np.matmul(Ru.reshape(rows, -1), v_remainder, out=X)
        X += np.matmul(F.reshape(rows, -1), v_modes, out=product)
        return X.reshape(c, n_u, -1)

    def _planes32(self, coefficients, residual, reuse):
        """:meth:`planes` in float32 (the data and the factors rounded to it, the factors once per operator): the u
        factors written side by side into the second buffer (the remainder's a block at a time, then the modes'),
        then one product with the v factors stacked, into the first: a third less work than two products added
        (one pass over the planes). Values within float32's rounding of the products (a few 1e-7 of a key's
        largest), about half the float64 solve's cost."""
        modes_u, remainder_u, v_factors = self._factors32
        K, J, c = residual.shape
        n1, _, n_u, b = modes_u.shape
        rows, width = c * n_u, v_factors.shape[0]
        size = rows * v_factors.shape[1]
        if (len(reuse) < 2 or any(b.dtype != np.float32 for b in reuse[:2]) or reuse[0].size < size
                or reuse[1].size < max(size, rows * width)):
            reuse[:] = [np.empty(size, np.float32), np.empty(max(size, rows * width), np.float32)]
        U = reuse[1][:rows * width].reshape(c, n_u, width)
        res = np.ascontiguousarray(np.transpose(residual, (2, 0, 1)), dtype=np.float32)  # (c, K, J)
        for i, block in enumerate(remainder_u):  # (n_u, K) @ (c, K, J): its J columns of each plane's rows
            np.matmul(block, res, out=U[:, :, i * J:(i + 1) * J])
        F = np.matmul(np.transpose(coefficients, (1, 2, 0)).astype(np.float32, copy=False),
                      modes_u.reshape(n1, K, n_u * b))  # (n1, c, n_u b)
        np.copyto(U[:, :, b * J:].reshape(c, n_u, n1, b), F.reshape(n1, c, n_u, b).transpose(1, 2, 0, 3))
        X = np.matmul(U.reshape(rows, width), v_factors, out=reuse[0][:size].reshape(rows, -1))
        return X.reshape(c, n_u, -1)

    def at_nodes(self, coefficients, residual, nodes) -> np.ndarray:
        """The surface at some grid nodes alone, (len(nodes), c): ``nodes`` are flat indices ``u * n_v + v`` of
        the (n_u, n_v) grid, increasing. :meth:`apply`'s values there (to rounding: the two sums of a node are
        one here) at the cost of the nodes read, one product per grid row: a head binding reads half its face's
        grid."""
        nodes = np.asarray(nodes, dtype=np.int64)
        F, Ru = self._u_factors(coefficients, residual)
        c, n_u, _ = F.shape
        n_v = self._node_factors.shape[0]
        if len(nodes) and (nodes[0] < 0 or nodes[-1] >= n_u * n_v or np.any(np.diff(nodes) <= 0)):
            raise LayoutError(f"grid nodes must be increasing flat indices below {n_u * n_v}")
        rows, cols = np.divmod(nodes, n_v)
        U = np.concatenate([Ru, F], axis=2)  # each plane's and row's u factors, as the v factors' columns
        Vn = self._node_factors[cols]
        out = np.empty((len(nodes), c))
        starts = np.searchsorted(rows, np.arange(n_u + 1))
        for u in np.nonzero(np.diff(starts))[0]:
            s = slice(starts[u], starts[u + 1])
            np.matmul(Vn[s], U[:, u].T, out=out[s])
        return out

    def _u_factors(self, coefficients, residual):
        """The u factors of :meth:`planes` per plane and row: the modes' F (c, n_u, (N+1) B) and the remainder's
        Ru (c, n_u, B J), their columns in the rows' order of the v factors."""
        K, J, c = residual.shape
        modes_u, remainder_u, _, _ = self._plane_factors
        n1, _, n_u, b = modes_u.shape
        F = np.matmul(np.transpose(coefficients, (1, 2, 0)), modes_u.reshape(n1, K, n_u * b))  # (n1, c, n_u b)
        F = F.reshape(n1, c, n_u, b).transpose(1, 2, 0, 3).reshape(c, n_u, n1 * b)
        Ru = np.matmul(remainder_u, np.ascontiguousarray(np.transpose(residual, (2, 0, 1))))  # (c, n_u b, J)
        return F, Ru.reshape(c, n_u, b * J)

    @cached_property
    def _factors32(self):
        """:meth:`_planes32`' factors, in float32: the modes (N+1, K, n_u, B), the remainder's of each block (n_u, K),
        and the v factors stacked (B J + (N+1) B, n_v): the remainder's rows, then the modes'."""
        modes_u, remainder_u, v_modes, v_remainder = self._plane_factors
        b = modes_u.shape[3]
        blocks = remainder_u.reshape(-1, b, remainder_u.shape[1])
        return (modes_u.astype(np.float32), [np.ascontiguousarray(blocks[:, i], np.float32) for i in range(b)],
                np.concatenate([v_remainder, v_modes]).astype(np.float32))

    @cached_property
    def _node_factors(self):
        """:meth:`at_nodes`' v factors, (n_v, B J + (N+1) B): at each column, the remainder's and the modes'."""
        _, _, v_modes, v_remainder = self._plane_factors
        return np.ascontiguousarray(np.concatenate([v_remainder, v_modes]).T)

    @cached_property
    def _plane_factors(self):
        """:meth:`planes`' factors: the modes (N+1, K, n_u, B), the remainder's (n_u B, K) and the v factors of
        each, (N+1) B and B J rows by n_v, their rows in the same (mode, block) and (block, sample) order."""
        modes = self.modes if self.modes.ndim == 4 else self.modes[None]
        rem = self.remainder_u if self.remainder_u.ndim == 3 else self.remainder_u[None]
        b, n1, n_u, K = modes.shape
        cos = self.cos_nv.reshape(-1, b, n1).transpose(0, 2, 1).reshape(-1, n1 * b)  # its columns as F's
        return (np.ascontiguousarray(modes.transpose(1, 3, 2, 0)),
                np.ascontiguousarray(rem.transpose(1, 0, 2)).reshape(n_u * b, K),
                np.ascontiguousarray(cos.T), np.ascontiguousarray(self.remainder_v.T))


@lru_cache(maxsize=64)
def surface_operator(knots: tuple, n_points: int, n_modes: int, a: float, w: float, sub_u, sub_v,
                     assembly: str = "smooth", deriv: tuple = (0, 0), breaks: tuple = (),
                     break_slope: float = BREAK_SLOPE) -> SurfaceOperator:
    """Cached :class:`SurfaceOperator` (see :func:`solve_surface` for the arguments)."""
    du, dv = deriv
    v = sample_v(n_points, sub_v)
    n = np.arange(n_modes + 1)
    # d^dv/dv^dv of cos(n v): cos for dv = 0, -n sin for dv = 1.
    cos_nv = np.cos(np.outer(v, n)) if dv == 0 else -np.sin(np.outer(v, n)) * n
    rows = mode_operators(knots, (*(a * m for m in n), w), sub_u, assembly, du, breaks, break_slope)
    return SurfaceOperator(rows[:-1], cos_nv, rows[-1], residual_v_operator(n_points, sub_v, dv))


def mode_values(knots: tuple, k: float, u: np.ndarray, deriv: int = 0, breaks: tuple = (),
                break_slope: float = BREAK_SLOPE) -> np.ndarray:
    """Matrix (len(u), K): one mode of the smooth assembly on the curves ``knots``, at any parameters ``u``."""
    return mode_value_stack(knots, (k,), u, deriv, breaks, break_slope)[0]


def mode_value_stack(knots: tuple, ks: tuple, u: np.ndarray, deriv: int = 0, breaks: tuple = (),
                     break_slope: float = BREAK_SLOPE) -> np.ndarray:
    """:func:`mode_values` of each wavenumber of ``ks``, (len(ks), len(u), K): their bases one batch."""
    kn = np.array(knots)
    h = np.diff(kn)
    k = np.array(ks, dtype=np.float64)
    C = _smooth_coefficient_stack(tuple(knots), tuple(ks), tuple(breaks), break_slope).reshape(len(k), -1, 4, len(kn))
    i = np.clip(np.searchsorted(kn, u, side="right") - 1, 0, len(kn) - 2)
    t = (u - kn[i]) / h[i]
    B = _bases_of(k, h[i], t[:, None], deriv)[:, :, 0] / (h[i] ** deriv)[:, None]  # (len(ks), len(u), 4)
    return np.stack([np.matmul(B[j][:, None], C[j][i])[:, 0] for j in range(len(k))])  # as one at a time


@lru_cache(maxsize=64)
def merged_operator(knots: tuple, n_points: int, n_modes: int, a: float, w: float, sub_u, sub_v,
                    deriv: tuple, breaks: tuple, merged: int, break_slope: float = BREAK_SLOPE) -> SurfaceOperator:
    """The smooth surface with break ``merged``'s two rim curves made one (their mean, at their mean
    parameter): no break piece there. On the rows and columns of the surface with the break, so the two
    can be blended (:func:`solve_surface`'s ``confine``)."""
    K, b = len(knots), merged
    km = (*knots[:b], 0.5 * (knots[b] + knots[b + 1]), *knots[b + 2:])
    bm = tuple(x - 1 if x > b else x for x in breaks if x != b)
    P = np.delete(np.eye(K), b + 1, axis=0)  # curves → merged curves
    P[b, b] = P[b, b + 1] = 0.5
    u = output_grid(np.array(knots), n_points, sub_u, sub_v).u
    base = surface_operator(knots, n_points, n_modes, a, w, sub_u, sub_v, "smooth", deriv, breaks, break_slope)
    values = mode_value_stack(km, (*(a * m for m in range(n_modes + 1)), w), u, deriv[0], bm, break_slope)
    rows = [v @ P for v in values]
    return SurfaceOperator(np.stack(rows[:-1]), base.cos_nv, rows[-1], base.remainder_v)


def solve_surface(coefficients, residual, knots, a=1.0, w=None, sub_u=4, sub_v=4,
                  assembly="smooth", deriv=(0, 0), breaks=(), break_slope=BREAK_SLOPE, confine=(), planes=False,
                  nodes=None, reuse=None, dtype=np.float64):
    """Evaluate the PDE surface (or a derivative) on the output grid.

    Parameters
    ----------
    coefficients : (K, N+1, 3) array
        Fourier coefficients ``a_n`` of the curves (or (K, N+1, 3m) for m
        surfaces solved together).
    residual : (K, J, 3) array
        Curve points minus their Fourier series (or (K, J, 3m)).
    knots : (K,) array
        Curve parameters ``u_i``, increasing from 0 to 1.
    a : float
        Smoothing parameter of the PDE (> 0).
    w : float, optional
        Wavenumber of the remainder term; default ``a (N + 1)``.
    sub_u, sub_v : int or sequence of int
        Output rows per curve interval and columns per sample interval: one
        count for all, or one per interval (:func:`subdivide`).
    assembly : {'smooth', 'patches'}
    deriv : (int, int)
        Derivative order in u and in v (each 0 or 1).
    breaks : tuple of int
        Curve intervals the ``smooth`` assembly solves apart (see the module
        notes); from :meth:`pdeface.surface.layout.CurveLayout.breaks`.
    break_slope : float
        A break piece's u-slope at its rims as a share of the runs' (:data:`BREAK_SLOPE`).
    confine : tuple of (int, array, array)
        ``(break, weight, d weight/dv)`` on the output columns: the break applies where the weight is 1;
        where it is 0 (beyond an opening's corners) the surface is the one with that break's rims merged
        (:func:`merged_operator`), C2 across them, blended in between. Fixed weights: still linear.

    planes : bool
        Return (3, n_u, n_v) coordinate planes (3m for m surfaces: :meth:`SurfaceOperator.planes`).
    reuse : list, optional
        With ``planes``: :meth:`SurfaceOperator.planes`' buffers, kept between calls (the planes returned are
        written over the last call's).
    dtype : numpy dtype
        With ``planes``: ``np.float32`` solves in float32 (:meth:`SurfaceOperator.planes`), for a screen.
    nodes : (p,) int array, optional
        Flat grid indices ``u * n_v + v``, increasing: the surface there alone, (p, 3) ((p, 3m)), the values
        of the whole grid's (:meth:`SurfaceOperator.at_nodes`).

    Returns
    -------
    (n_u, n_v, 3) array
        The surface's grid; with ``planes``, (3, n_u, n_v) (3m, n_u, n_v) its coordinate planes instead; with
        ``nodes``, (p, 3) ((p, 3m)) its nodes.
    """
    dtype = np.dtype(dtype if planes and nodes is None else np.float64)
    if dtype not in (np.float32, np.float64):
        raise ValueError(f"the surface is solved in float32 or float64, not {dtype}")
    coefficients = np.asarray(coefficients, dtype=dtype)
    residual = np.asarray(residual, dtype=dtype)
    if not a > 0:
        raise LayoutError(f"smoothing parameter a must be > 0, got {a}")
    K, N1 = coefficients.shape[:2]
    kn = tuple(float(x) for x in knots)
    if len(kn) != K or residual.shape[0] != K:
        raise LayoutError(f"{K} curves of coefficients but {len(kn)} curve parameters and "
                          f"{residual.shape[0]} residual rows")
    w = a * N1 if w is None else w
    args = (kn, residual.shape[1], N1 - 1, float(a), float(w), sampling_key(sub_u), sampling_key(sub_v))
    br = tuple(int(b) for b in breaks)
    if assembly != "smooth" or not confine:
        op = surface_operator(*args, assembly, tuple(deriv), br, float(break_slope))
    else:
        key = tuple((int(b), tuple(np.asarray(wt, float)), tuple(np.asarray(sl, float))) for b, wt, sl in confine)
        op = confined_operator(*args, tuple(deriv), br, float(break_slope), key)
    if nodes is not None:
        return op.at_nodes(coefficients, residual, nodes)
    return op.planes(coefficients, residual, reuse, dtype) if planes else op.apply(coefficients, residual)


@lru_cache(maxsize=16)
def confined_operator(knots: tuple, n_points: int, n_modes: int, a: float, w: float, sub_u, sub_v,
                      deriv: tuple, breaks: tuple, break_slope: float, confine: tuple) -> SurfaceOperator:
    """The smooth surface with each break of ``confine`` (``(break, weights, d weights/dv)``, tuples on the
    output columns) blended into its merged surface where its weight is below 1, as one operator:
    ``X + Σ (1 - w_b) (M_b - X)``, with ``- w_b' (M_b - X)`` at v-derivative order 0 added for d/dv."""
    du, dv = deriv
    args = (knots, n_points, n_modes, a, w, sub_u, sub_v)
    base = surface_operator(*args, "smooth", deriv, breaks, break_slope)
    # d/dv: the product rule's - w' (M - X) takes the v factors at dv = 0 (the modes are the same).
    flat = surface_operator(*args, "smooth", (du, 0), breaks, break_slope) if dv else None
    modes, cos_nv, rem_u, rem_v = [base.modes], [base.cos_nv], [base.remainder_u], [base.remainder_v]
    for b, weight, slope in confine:
        merged = merged_operator(*args, deriv, breaks, b, break_slope)
        keep, slope = 1.0 - np.array(weight)[:, None], np.array(slope)[:, None]
        modes.append(merged.modes - base.modes)
        rem_u.append(merged.remainder_u - base.remainder_u)
        cos_nv.append(keep * base.cos_nv - (slope * flat.cos_nv if dv else 0.0))
        rem_v.append(keep * base.remainder_v - (slope * flat.remainder_v if dv else 0.0))
    return SurfaceOperator(np.stack(modes), np.hstack(cos_nv), np.stack(rem_u), np.hstack(rem_v))
