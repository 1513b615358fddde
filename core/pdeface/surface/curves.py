"""Boundary-curve points as material points on a mesh.

Every curve point is a fixed linear combination of mesh vertices: a ray hit is
a triangle with barycentric weights; a point whose ray misses the skin (eye
opening, mouth slit, nostril, beyond the mesh edge) is filled smoothly from its
neighbours on the curve grid. The whole sampler is one sparse matrix ``S`` and
``curves = S @ V``, so it reads the same points off any mesh of the same
topology, exactly and linearly.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.sparse.linalg import splu

from ..errors import LayoutError
from ..geometry import ClosestPoint, cast_cylinder_rays
from .layout import OPENING_GAP, CurveLayout

#: Status codes of curve points.
HIT, MISS, BACKFACING, CAVITY, GRAZING = 0, 1, 2, 3, 4
STATUS_NAMES = {HIT: "hit", MISS: "miss", BACKFACING: "back-facing", CAVITY: "cavity", GRAZING: "grazing"}


@dataclass
class CurveSampler:
    """Curve points of a layout as a sparse linear map from mesh vertices.

    Attributes
    ----------
    matrix : scipy.sparse.csr_matrix, shape (K*J, n_vertices)
        ``matrix @ V`` gives the curve points, curve after curve.
    status : (K, J) int array
        :data:`HIT`, or why the point was filled (:data:`MISS`,
        :data:`BACKFACING`, :data:`CAVITY`, :data:`GRAZING`).
    shape : (K, J)
    """

    matrix: sp.csr_matrix
    status: np.ndarray
    shape: tuple
    #: The matrix before :func:`join_rims` (the points as cast on the skin), or None.
    cast: sp.csr_matrix | None = None

    def sample(self, V: np.ndarray, cast=False) -> np.ndarray:
        """Curve points ``(K, J, 3)`` read off vertices ``V`` of the same topology (``cast``: as cast on the
        skin, before the rims were joined)."""
        V = np.asarray(V, dtype=np.float64)
        if V.ndim != 2 or V.shape[1] != 3 or len(V) != self.matrix.shape[1]:
            raise LayoutError(f"mesh has {len(V)} vertices; the curves were placed on one with {self.matrix.shape[1]}")
        M = self.cast if cast and self.cast is not None else self.matrix
        return np.asarray(M @ V).reshape(*self.shape, 3)

    def summary(self) -> dict:
        """Count of points per status name."""
        return {STATUS_NAMES[k]: int((self.status == k).sum()) for k in STATUS_NAMES}


def _cavities(radius: np.ndarray, valid: np.ndarray, depth: float, window: int) -> np.ndarray:
    """Points lying ``depth`` below the chord between valid points up to ``window`` away.

    A pocket behind an opening (eye socket, mouth) is deep both along the
    curve and across curves; the skin's own folds (beside the nose, under it)
    are deep in one direction only, so both must agree.
    """
    K, J = radius.shape
    both = []
    r = np.where(valid, radius, np.nan)
    for axis in (0, 1):
        out = np.zeros_like(valid)
        R = r if axis == 1 else r.T
        n = R.shape[1]
        for da in range(1, window + 1):
            for db in range(1, window + 1):
                if da + db > n - 1:
                    continue
                lo, hi = R[:, :n - da - db], R[:, da + db:]
                chord = lo + (hi - lo) * (da / (da + db))
                mid = R[:, da:n - db]
                with np.errstate(invalid="ignore"):
                    deep = mid < chord - depth
                deep = np.nan_to_num(deep, nan=False).astype(bool)
                if axis == 1:
                    out[:, da:n - db] |= deep
                else:
                    out.T[:, da:n - db] |= deep
        both.append(out)
    return both[0] & both[1] & valid


def _fill_weights(valid: np.ndarray) -> sp.csr_matrix:
    """Harmonic fill: each invalid grid node as a weighted mean of valid ones.

    Returns ``W`` of shape (K*J, K*J) with identity rows for valid nodes.
    """
    K, J = valid.shape
    n = K * J
    idx = np.arange(n).reshape(K, J)
    rows, cols = [], []
    for a, b in ((idx[:, :-1], idx[:, 1:]), (idx[:-1, :], idx[1:, :])):
        rows += [a.ravel(), b.ravel()]
        cols += [b.ravel(), a.ravel()]
    A = sp.csr_matrix((np.ones(sum(len(r) for r in rows)), (np.concatenate(rows), np.concatenate(cols))), shape=(n, n))
    L = sp.diags(np.asarray(A.sum(1)).ravel()) - A  # graph Laplacian of the curve grid
    v, h = valid.ravel(), ~valid.ravel()
    if not h.any():
        return sp.identity(n, format="csr")
    vi, hi = np.nonzero(v)[0], np.nonzero(h)[0]
    # L_hh x_h = -L_hv x_v  →  x_h = -L_hh^{-1} L_hv x_v
    sol = -splu(L[h][:, h].tocsc()).solve(L[h][:, v].toarray())
    r, c = np.nonzero(np.abs(sol) >= 1e-9)
    return sp.csr_matrix((np.r_[np.ones(len(vi)), sol[r, c]], (np.r_[vi, hi[r]], np.r_[vi, vi[c]])), shape=(n, n))


def place_samples(V_face: np.ndarray, T: np.ndarray, layout: CurveLayout,
                  cavity_depth: float = 16.0, cavity_window: int = 6, min_facing: float = 0.25,
                  min_hit_fraction: float = 0.75) -> CurveSampler:
    """Cast the layout's rays on a mesh and build its curve sampler.

    Parameters
    ----------
    V_face : (n, 3) array
        Mesh vertices in the face frame (mm).
    T : (t, 3) int array
        Triangles of the skin surface to sample.
    layout : CurveLayout
    cavity_depth : float
        A hit this far (mm) below its neighbours' chord is taken to be inside
        an opening (eye socket, mouth, nostril) and filled instead. Deep-set
        eyes put the inner eye corners' skin 12-16 mm below it: at 12 mm
        they were filled over and missed by up to 3.9 mm.
    min_facing : float
        A hit on skin seen more obliquely than this (cosine between its normal
        and the ray) is filled too: it is a nostril or lip wall seen edge-on,
        where a small shift of the ray moves the point a long way.
    min_hit_fraction : float
        Fewer usable hits than this fraction raises :class:`LayoutError`.
    """
    K, J = layout.n_curves, layout.n_points
    theta = layout.angles()
    height = layout.ray_heights()
    radius, tri, bary, facing = cast_cylinder_rays(V_face, T, layout.axis_z, theta.ravel(), height.ravel())
    status = np.full(K * J, HIT)
    status[tri < 0] = MISS
    status[(tri >= 0) & (facing <= 0)] = BACKFACING
    status[(tri >= 0) & (facing > 0) & (facing < min_facing)] = GRAZING
    status = status.reshape(K, J)
    cav = _cavities(radius.reshape(K, J), status == HIT, cavity_depth, cavity_window)
    status[cav] = CAVITY
    valid = status == HIT
    frac = valid.mean()
    if frac < min_hit_fraction:
        raise LayoutError(
            f"only {frac:.0%} of the curve points landed on the face (need {min_hit_fraction:.0%}); "
            "check the landmarks, their order and the mesh unit")
    n = len(V_face)
    rows = np.repeat(np.arange(K * J), 3)
    hit_tri = np.where(tri >= 0, tri, 0)
    S = sp.csr_matrix((np.where(valid.ravel()[:, None], bary, 0).ravel(), (rows, T[hit_tri].ravel())), shape=(K * J, n))
    S.eliminate_zeros()
    S = _fill_weights(valid) @ S
    return CurveSampler(sp.csr_matrix(S), status, (K, J))


def joined_rims(layout: CurveLayout, b: int) -> np.ndarray:
    """Columns (J,) beyond the corners of the opening at break ``b``: its rims' rays are
    :data:`~pdeface.surface.layout.OPENING_GAP` apart."""
    H = layout.ray_heights()
    return np.abs(H[b] - H[b + 1]) < 1.5 * OPENING_GAP  # (the bent lines vary it by a few µm)


def join_rims(sampler: CurveSampler, layout: CurveLayout, V_face: np.ndarray) -> CurveSampler:
    """The sampler with each opening's two rims made one smooth line beyond the opening's corners.

    There the rims' rays lie :data:`~pdeface.surface.layout.OPENING_GAP` apart in
    height, and on steep skin (the eye's outer corner) the lower one lands
    deeper, so the strip between them would stand up from the face and crease
    it. Instead both rims sit at their mean, stepped apart along the line from
    the curve above to the curve below (its length at rest scaled to the gap):
    a fixed linear combination of the rows, so every pose sampled through it
    gets the same treatment.
    """
    P = sampler.sample(V_face)
    M = sampler.matrix.tolil()
    K, J = sampler.shape
    for b in layout.breaks():
        if b < 1 or b + 2 >= K:
            continue
        for j in np.nonzero(joined_rims(layout, b))[0]:
            row = lambda k: sampler.matrix[k * J + j]  # noqa: E731
            span = np.linalg.norm(P[b + 2, j] - P[b - 1, j])
            if span <= 0:
                continue
            mean = 0.5 * (row(b) + row(b + 1))
            step = (OPENING_GAP / span) * (row(b + 2) - row(b - 1))
            M[b * J + j] = mean - 0.5 * step
            M[(b + 1) * J + j] = mean + 0.5 * step
    return CurveSampler(sp.csr_matrix(M), sampler.status, sampler.shape, sampler.matrix)


def project_samples(points: np.ndarray, V: np.ndarray, T: np.ndarray, status=None) -> CurveSampler:
    """A sampler for a mesh of another topology: closest points to ``points``.

    Parameters
    ----------
    points : (K, J, 3) array
        Curve points (e.g. read off the neutral mesh), aligned to ``V``.
    V, T : arrays
        The other mesh (same frame as ``points``).
    status : (K, J) array, optional
        Status to carry over (filled points are re-filled on the new mesh).
    """
    K, J, _ = points.shape
    status = np.full((K, J), HIT) if status is None else np.asarray(status)
    valid = status == HIT
    _, tri, bary, _ = ClosestPoint(V, T).query(points.reshape(-1, 3))
    rows = np.repeat(np.arange(K * J), 3)
    S = sp.csr_matrix((np.where(valid.ravel()[:, None], bary, 0).ravel(), (rows, T[tri].ravel())), shape=(K * J, len(V)))
    S.eliminate_zeros()
    return CurveSampler(sp.csr_matrix(_fill_weights(valid) @ S), status.copy(), (K, J))
