"""Second-degree rubber-sheet transforms of one region (Obaid et al. 2009, eqs. 1-2).

The paper's 2-D model, in normalised coordinates::

    x' = a₁x² + a₂xy + a₃y² + a₄x + a₅y + a₆
    y' = b₁x² + b₂xy + b₃y² + b₄x + b₅y + b₆

fitted by least squares through the normal equations ``M P = N`` (M = ΦᵀΦ,
N = Φᵀx' with Φ the rows ``[x², xy, y², x, y, 1]``), 12 parameters a region.

Two 3-D extensions keep depth (the lips' push, the cheeks' bulge):

``3d``
    x', y', z' each a full quadratic in (x, y, z): 10 terms, 30 parameters.
``3d-surface``
    the 2-D model for x', y' and the depth change quadratic in the same
    surface parameters: ``z' = z + c₁x² + c₂xy + c₃y² + c₄x + c₅y + c₆``
    (18 parameters; its first 12 are the 2-D model's, fitted the same way).

``scripts/bench/bench_fdt.py`` measures both: ``3d`` captures more of every AU's motion
(README, "Facial Deformation Tables"), so it is the default.
"""
from __future__ import annotations

import numpy as np

from ..errors import PdeFaceError

#: Parameter names per model, in the paper's order (a: x', b: y', c: z').
_XY_TERMS = ("x²", "xy", "y²", "x", "y", "1")
_XYZ_TERMS = ("x²", "y²", "z²", "xy", "xz", "yz", "x", "y", "z", "1")
PARAMETERS = {
    "2d": tuple(f"{c}{i}" for c in "ab" for i in range(1, 7)),
    "3d": tuple(f"{c}{i}" for c in "abc" for i in range(1, 11)),
    "3d-surface": tuple(f"{c}{i}" for c in "abc" for i in range(1, 7)),
}
MODELS = tuple(PARAMETERS)
#: Terms of each parameter group, and the identity transform's parameters.
TERMS = {"2d": _XY_TERMS, "3d": _XYZ_TERMS, "3d-surface": _XY_TERMS}


def design(model: str, P) -> np.ndarray:
    """Rows of basis terms (n, 6 or 10) at normalised points ``P`` (n, 3)."""
    P = np.asarray(P, np.float64)
    x, y = P[:, 0], P[:, 1]
    if model == "3d":
        z = P[:, 2]
        return np.stack([x * x, y * y, z * z, x * y, x * z, y * z, x, y, z, np.ones_like(x)], axis=1)
    if model not in PARAMETERS:
        raise PdeFaceError(f"unknown FDT model {model!r}; use one of {', '.join(MODELS)}")
    return np.stack([x * x, x * y, y * y, x, y, np.ones_like(x)], axis=1)


def identity(model: str) -> np.ndarray:
    """Parameters of the transform that moves nothing."""
    p = np.zeros(len(PARAMETERS[model]))
    t = len(TERMS[model])
    p[TERMS[model].index("x")] = 1
    p[t + TERMS[model].index("y")] = 1
    if model == "3d":
        p[2 * t + TERMS[model].index("z")] = 1  # 3d-surface keeps z' = z + c·φ: its c are zero at rest
    return p


#: Output coordinates of each model, and those it gives as absolute positions (the paper's x' = ...,
#: y' = ...); the others (3d-surface's z) as a change.
OUTPUTS = {"2d": 2, "3d": 3, "3d-surface": 3}
ABSOLUTE = {"2d": [0, 1], "3d": [0, 1, 2], "3d-surface": [0, 1]}


def _targets(model, P, Q, share=None):
    """What each parameter group is fitted to: x', y' (and z' − z or z'), with the absolute
    coordinates weighed by ``share`` (a point's summed region weights; 1 by default)."""
    T = (Q - P)[:, :OUTPUTS[model]]
    cols = ABSOLUTE[model]
    T[:, cols] += P[:, cols] if share is None else share[:, None] * P[:, cols]
    return T


def _factor(M, n_points, n_terms, where):
    from scipy.linalg import LinAlgError, cho_factor

    scale = np.sqrt(np.diag(M))
    if n_points < n_terms or not (scale > 0).all() or np.linalg.cond(M / np.outer(scale, scale)) > 1e12:
        raise PdeFaceError(f"{where}: {n_points} points do not determine a quadratic of {n_terms} terms a "
                           "coordinate (too few, or all on a line or plane)")
    try:
        return cho_factor(M)
    except LinAlgError:
        raise PdeFaceError(f"{where}: the normal equations are singular") from None


class NormalEquations:
    """One region's normal matrix ``M = ΦᵀΦ`` (the paper's), factored once: it depends on the neutral only."""

    def __init__(self, model: str, P, where="region"):
        self.model = model
        self.P = np.asarray(P, np.float64)
        self.Phi = design(model, self.P)
        self.factor = _factor(self.Phi.T @ self.Phi, len(self.P), self.Phi.shape[1], where)

    def solve(self, Q) -> np.ndarray:
        """Parameters taking the points to ``Q``: ``M p = N``, ``N = Φᵀ·target``, per output coordinate."""
        from scipy.linalg import cho_solve

        return cho_solve(self.factor, self.Phi.T @ _targets(self.model, self.P, np.asarray(Q, np.float64))).T.ravel()


class BlendedEquations:
    """All regions' transforms fitted together as they are applied: blended at their borders.

    A point p with region weights w_k(p) moves by ``Σ_k w_k(p) (T_k(p) − p)``
    (:func:`~pdeface.fdt.deform.fdt_displacement`); the least-squares fit of that
    to the observed motion couples neighbouring regions only through the points
    they share. With a hard partition (one weight 1 per point) it falls apart
    into the paper's independent per-region normal equations (:class:`NormalEquations`).
    """

    def __init__(self, model: str, P, W, names=None):
        self.model = model
        self.P = np.asarray(P, np.float64)
        W = np.asarray(W, np.float64)
        self.share = W.sum(axis=1)
        Phi = design(model, self.P)
        self.n_regions, self.n_terms = W.shape[1], Phi.shape[1]
        self.A = (W[:, :, None] * Phi[:, None, :]).reshape(len(Phi), -1)
        M = self.A.T @ self.A
        for k in range(self.n_regions):  # a region the points cannot determine, named
            block = slice(k * self.n_terms, (k + 1) * self.n_terms)
            _factor(M[block, block], int((W[:, k] > 0.5).sum()), self.n_terms, names[k] if names else f"region {k + 1}")
        self.factor = _factor(M, len(Phi), self.A.shape[1], "the regions together")

    def solve(self, Q) -> np.ndarray:
        """(regions, parameters) taking the points to ``Q``."""
        from scipy.linalg import cho_solve

        X = cho_solve(self.factor, self.A.T @ _targets(self.model, self.P, np.asarray(Q, np.float64), self.share))
        return X.reshape(self.n_regions, self.n_terms, -1).transpose(0, 2, 1).reshape(self.n_regions, -1)


def fit(model: str, P, Q, where="region") -> np.ndarray:
    """Parameters of the transform taking normalised points ``P`` (n, 3) to ``Q`` (n, 3).

    Solves the normal equations ``M P = N`` per output coordinate (the paper's
    method). Raises when the points cannot determine the transform.
    """
    return NormalEquations(model, P, where).solve(Q)


def transform(model: str, params, P) -> np.ndarray:
    """Normalised points ``P`` (n, 3) moved by the transform ``params``."""
    P = np.asarray(P, np.float64)
    Phi = design(model, P)
    A = np.asarray(params, np.float64).reshape(-1, Phi.shape[1])
    Q = P.copy()
    if model == "3d":
        return Phi @ A.T
    Q[:, :2] = Phi @ A[:2].T
    if model == "3d-surface":
        Q[:, 2] += Phi @ A[2]
    return Q
