"""Boundary-curve points as material points on a mesh.

Every curve point is a fixed linear combination of mesh vertices: a ray hit is
a triangle with barycentric weights; a point whose ray misses the skin (eye
opening, mouth slit, nostril) is filled smoothly from its neighbours on the
curve grid, and one beyond the mesh's edge is extrapolated from them. The whole sampler is one sparse matrix ``S`` and
``curves = S @ V``, so it reads the same points off any mesh of the same
topology, exactly and linearly.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.sparse.linalg import splu, spsolve

from ..errors import LayoutError
from ..geometry import ClosestPoint, cast_cylinder_rays, cylinder_coords
from ..landmark_scheme import LIP_UPPER_TOP, NOSE_TIP, NOSE_WING_LEFT, NOSE_WING_RIGHT
from .layout import CurveLayout

#: Status codes of curve points. BEYOND: a miss beyond the mesh's edge (its run of filled points
#: reaches the curve grid's border), where the scan cannot support the curve.
HIT, MISS, BACKFACING, CAVITY, GRAZING, BEYOND = 0, 1, 2, 3, 4, 5
STATUS_NAMES = {HIT: "hit", MISS: "miss", BACKFACING: "back-facing", CAVITY: "cavity", GRAZING: "grazing",
                BEYOND: "beyond the edge"}


@dataclass
class CurveSampler:
    """Curve points of a layout as a sparse linear map from mesh vertices.

    Attributes
    ----------
    matrix : scipy.sparse.csr_matrix, shape (K*J, n_vertices)
        ``matrix @ V`` gives the curve points, curve after curve.
    status : (K, J) int array
        :data:`HIT`, or why the point was filled (:data:`MISS`,
        :data:`BACKFACING`, :data:`CAVITY`, :data:`GRAZING`) or extrapolated (:data:`BEYOND`).
    shape : (K, J)
    groove_mix : scipy.sparse.csr_matrix, shape (K*J, K*J), optional
        How the points in too narrow a groove were drawn towards their neighbours' chord
        (``matrix = groove_mix @ matrix on the skin``, :func:`place_samples`); None where none was.
    """

    matrix: sp.csr_matrix
    status: np.ndarray
    shape: tuple
    groove_mix: sp.csr_matrix | None = None

    def sample(self, V: np.ndarray) -> np.ndarray:
        """Curve points ``(K, J, 3)`` read off vertices ``V`` of the same topology."""
        V = np.asarray(V, dtype=np.float64)
        if V.ndim != 2 or V.shape[1] != 3 or len(V) != self.matrix.shape[1]:
            raise LayoutError(f"mesh has {len(V)} vertices; the curves were placed on one with {self.matrix.shape[1]}")
        return np.asarray(self.matrix @ V).reshape(*self.shape, 3)

    def summary(self) -> dict:
        """Count of points per status name."""
        return {STATUS_NAMES[k]: int((self.status == k).sum()) for k in STATUS_NAMES}

    def beyond_curves(self, share: float = 0.5) -> np.ndarray:
        """Indices of the curves more than ``share`` of whose points lie beyond the mesh's edge."""
        return np.nonzero((self.status == BEYOND).mean(axis=1) > share)[0]


def _cavities(radius: np.ndarray, valid: np.ndarray, depth, window: int) -> np.ndarray:
    """Points lying ``depth`` (a number, or one per point) below the chord between valid points up to
    ``window`` away.

    A pocket behind an opening (eye socket, mouth) is deep both along the
    curve and across curves; the skin's own folds (beside the nose, under it)
    are deep in one direction only, so both must agree.
    """
    K, J = radius.shape
    both = []
    r = np.where(valid, radius, np.nan)
    depth = np.broadcast_to(np.asarray(depth, np.float64), (K, J))
    for axis in (0, 1):
        out = np.zeros_like(valid)
        R, D = (r, depth) if axis == 1 else (r.T, depth.T)
        n = R.shape[1]
        for da in range(1, window + 1):
            for db in range(1, window + 1):
                if da + db > n - 1:
                    continue
                lo, hi = R[:, :n - da - db], R[:, da + db:]
                chord = lo + (hi - lo) * (da / (da + db))
                mid = R[:, da:n - db]
                with np.errstate(invalid="ignore"):
                    deep = mid < chord - D[:, da:n - db]
                deep = np.nan_to_num(deep, nan=False).astype(bool)
                if axis == 1:
                    out[:, da:n - db] |= deep
                else:
                    out.T[:, da:n - db] |= deep
        both.append(out)
    return both[0] & both[1] & valid


def beyond_edge(filled: np.ndarray) -> np.ndarray:
    """Filled grid points whose run of filled points (4-connected) reaches the grid's border."""
    from scipy import ndimage

    labels, _ = ndimage.label(filled)
    rim = np.unique(np.concatenate([labels[0], labels[-1], labels[:, 0], labels[:, -1]]))
    return np.isin(labels, rim[rim > 0])


def _bending(K: int, J: int, touches) -> sp.csr_matrix:
    """Second-difference stencils of a K×J grid (along rows, along columns, and the twist) that
    include a node of ``touches`` (flat bool): ``|B x|²`` is the grid's thin-plate energy there."""
    idx = np.arange(K * J).reshape(K, J)
    twist = 2 ** 0.5  # the mixed term counts twice in the thin-plate energy
    stencils = [((idx[:, :-2], idx[:, 1:-1], idx[:, 2:]), (1.0, -2.0, 1.0)),
                ((idx[:-2], idx[1:-1], idx[2:]), (1.0, -2.0, 1.0)),
                ((idx[:-1, :-1], idx[:-1, 1:], idx[1:, :-1], idx[1:, 1:]), (twist, -twist, -twist, twist))]
    rows, cols, vals, n = [], [], [], 0
    for nodes, weights in stencils:
        nodes = [a.ravel() for a in nodes]
        keep = np.logical_or.reduce([touches[a] for a in nodes])
        m = int(keep.sum())
        for a, w in zip(nodes, weights):
            rows.append(n + np.arange(m))
            cols.append(a[keep])
            vals.append(np.full(m, w))
        n += m
    return sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(n, K * J))


def _fill_weights(valid: np.ndarray, beyond=None) -> sp.csr_matrix:
    """Fill: each invalid grid node as a weighted mean of valid ones.

    Holes inside the scan (an eye, the mouth) are filled harmonically, a membrane across
    the opening; nodes ``beyond`` the mesh's edge by least bending (the grid's thin-plate
    energy: second differences along and across the curves and their twist, over every
    stencil that reaches a beyond node), so the surface carries on with its slope and
    spacing instead of flattening into a ledge (on the 468-point MediaPipe face, whose
    forehead ends below the band's top, the harmonic fill made 441 of its 614 folds, along
    the top and sides). The graph Laplacian's square did that too, but its border rows
    hold the slope at zero there: the last column beyond the cheek came half a step out and
    the surface turned back on itself before it (26° at rest, 48° with the brows raised).

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
    L = (sp.diags(np.asarray(A.sum(1)).ravel()) - A).tocsr()  # graph Laplacian of the curve grid
    v, h = valid.ravel(), ~valid.ravel()
    if not h.any():
        return sp.identity(n, format="csr")
    if beyond is not None and np.any(beyond):
        out = np.asarray(beyond, bool).ravel()
        B = _bending(K, J, out)
        L = (sp.diags((~out).astype(np.float64)) @ L + sp.diags(out.astype(np.float64)) @ (B.T @ B)).tocsr()
    vi, hi = np.nonzero(v)[0], np.nonzero(h)[0]
    # M_hh x_h = -M_hv x_v  →  x_h = -M_hh^{-1} M_hv x_v
    sol = -splu(L[h][:, h].tocsc()).solve(L[h][:, v].toarray())
    r, c = np.nonzero(np.abs(sol) >= 1e-9)
    return sp.csr_matrix((np.r_[np.ones(len(vi)), sol[r, c]], (np.r_[vi, hi[r]], np.r_[vi, vi[c]])), shape=(n, n))


#: Depth (mm) below its neighbours' chord at which a hit is taken for a pocket and filled (see place_samples).
CAVITY_MM = 16.0
#: The same beside and under the nose: the groove where a nose wing meets the cheek, 4-6 mm deep and
#: narrower than the curves' spacing, folded the surface over there (dark, torn-looking wings). At 6 mm the
#: fit's normals improve and its mean error grows 1 %; at 4.5 mm its largest error passed 3 mm.
NOSE_CAVITY_MM = 6.0
#: The nose band's half-width in nose-wing half-widths (the wings are landmarks 31 and 35).
NOSE_BAND_WIDTHS = 2.5
#: In the nose band a hit lies at most this far (mm) below the chord of its two neighbours on the curve;
#: deeper, it is drawn towards that chord. The alar groove is narrower than the points' spacing (3-4 mm):
#: a point landing in it, 4-5 mm below its neighbours, made a V that the surface turned through by 30-40°
#: (identity000: 34 folds at rest) while the scan spreads the groove over several edges. At 2.5 mm, 6-8 points
#: a face, the mean distance to the scan grows 0.3-1.5 %; at 3 mm it is unchanged (the V also overshot between
#: the points) but AU9 still folds on identity012; at 2 mm it is 2-4 % larger.
NOSE_GROOVE_MM = 2.5


def nose_band(layout: CurveLayout, landmarks_face: np.ndarray) -> np.ndarray:
    """(K, J) bool: the curve points beside and under the nose (from the upper lip to the nose tip,
    :data:`NOSE_BAND_WIDTHS` nose-wing half-widths either side of the midline)."""
    L = landmarks_face
    wing = np.abs(cylinder_coords(L[[NOSE_WING_RIGHT, NOSE_WING_LEFT]], layout.axis_z)[0]).max()
    H = layout.ray_heights()
    return (H > L[LIP_UPPER_TOP, 1] + 1.0) & (H < L[NOSE_TIP, 1] + 1.0) & (np.abs(layout.angles()) < NOSE_BAND_WIDTHS * wing)


def cavity_depths(layout: CurveLayout, landmarks_face: np.ndarray) -> np.ndarray:
    """(K, J) cavity depths: :data:`NOSE_CAVITY_MM` in the :func:`nose_band`, :data:`CAVITY_MM` elsewhere."""
    return np.where(nose_band(layout, landmarks_face), NOSE_CAVITY_MM, CAVITY_MM)


def groove_depths(layout: CurveLayout, landmarks_face: np.ndarray) -> np.ndarray:
    """(K, J) groove depths: :data:`NOSE_GROOVE_MM` in the :func:`nose_band`, no limit elsewhere."""
    return np.where(nose_band(layout, landmarks_face), NOSE_GROOVE_MM, np.inf)


def _groove_limit(S: sp.csr_matrix, V_face: np.ndarray, hit: np.ndarray, axis_z: float, depth) -> sp.csr_matrix:
    """``A`` (K*J × K*J) such that ``A @ S`` draws each hit lying more than ``depth`` (mm, per point) below the
    chord of its two neighbours on the curve (hits too) towards that chord, to ``depth`` below it: the point
    becomes a fixed mix of the three, so the sampler stays linear in the mesh's vertices."""
    K, J = hit.shape
    n = K * J
    r = cylinder_coords(np.asarray(S @ V_face), axis_z)[2].reshape(K, J)
    depth = np.broadcast_to(np.asarray(depth, np.float64), (K, J))[:, 1:-1]
    below = 0.5 * (r[:, :-2] + r[:, 2:]) - r[:, 1:-1]
    deep = hit[:, 1:-1] & hit[:, :-2] & hit[:, 2:] & (below > depth)
    k, j = np.nonzero(deep)
    j = j + 1
    pull = 1.0 - depth[k, j - 1] / below[k, j - 1]  # share of the way to the chord
    i = k * J + j
    keep = np.setdiff1d(np.arange(n), i)
    rows = np.r_[keep, i, i, i]
    cols = np.r_[keep, i, i - 1, i + 1]
    vals = np.r_[np.ones(len(keep)), 1.0 - pull, 0.5 * pull, 0.5 * pull]
    return sp.csr_matrix((vals, (rows, cols)), shape=(n, n))


def place_samples(V_face: np.ndarray, T: np.ndarray, layout: CurveLayout,
                  cavity_depth=CAVITY_MM, cavity_window: int = 6, min_facing: float = 0.25,
                  min_hit_fraction: float = 0.75, groove_depth=np.inf) -> CurveSampler:
    """Cast the layout's rays on a mesh and build its curve sampler.

    Parameters
    ----------
    V_face : (n, 3) array
        Mesh vertices in the face frame (mm).
    T : (t, 3) int array
        Triangles of the skin surface to sample.
    layout : CurveLayout
    cavity_depth : float or (K, J) array
        A hit this far (mm) below its neighbours' chord is taken to be inside
        an opening (eye socket, mouth, nostril) and filled instead. Deep-set
        eyes put the inner eye corners' skin 12-16 mm below it: at 12 mm
        they were filled over and missed by up to 3.9 mm. :func:`cavity_depths`
        gives the nose band less (:data:`NOSE_CAVITY_MM`).
    groove_depth : float or (K, J) array
        A hit more than this far (mm) below the chord of its neighbours on the
        curve is drawn towards it (:func:`groove_depths`: the nose band's
        alar grooves, :data:`NOSE_GROOVE_MM`); no limit by default.
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
    status[beyond_edge(status == MISS)] = BEYOND
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
    S = _fill_weights(valid, status == BEYOND) @ S
    mix = None
    if np.isfinite(groove_depth).any():
        mix = _groove_limit(sp.csr_matrix(S), V_face, valid, layout.axis_z, groove_depth)
        S = mix @ S
    return CurveSampler(sp.csr_matrix(S), status, (K, J), mix)


def project_samples(points: np.ndarray, V: np.ndarray, T: np.ndarray, status=None, groove_mix=None) -> CurveSampler:
    """A sampler for a mesh of another topology: closest points to ``points``.

    Parameters
    ----------
    points : (K, J, 3) array
        Curve points (e.g. read off the neutral mesh), aligned to ``V``.
    V, T : arrays
        The other mesh (same frame as ``points``).
    status : (K, J) array, optional
        Status to carry over (filled points are re-filled on the new mesh).
    groove_mix : sparse (K*J, K*J), optional
        The sampler's :attr:`CurveSampler.groove_mix`: the points it drew off the skin
        are projected where they were on it, and drawn off it again the same way.
    """
    K, J, _ = points.shape
    status = np.full((K, J), HIT) if status is None else np.asarray(status)
    valid = status == HIT
    on_skin = points.reshape(-1, 3) if groove_mix is None else spsolve(sp.csc_matrix(groove_mix), points.reshape(-1, 3))
    _, tri, bary, _ = ClosestPoint(V, T).query(np.asarray(on_skin).reshape(-1, 3))
    rows = np.repeat(np.arange(K * J), 3)
    S = sp.csr_matrix((np.where(valid.ravel()[:, None], bary, 0).ravel(), (rows, T[tri].ravel())), shape=(K * J, len(V)))
    S.eliminate_zeros()
    S = _fill_weights(valid, status == BEYOND) @ S
    if groove_mix is not None:
        S = groove_mix @ S
    return CurveSampler(sp.csr_matrix(S), status.copy(), (K, J), groove_mix)
