"""Ray casting and closest-point queries on triangle meshes (numpy + scipy).

All functions take ``V (n, 3)`` and triangles ``T (t, 3)`` in the face frame.
"""
from __future__ import annotations

from functools import cached_property

import numpy as np


def cylinder_coords(P: np.ndarray, axis_z: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Angle, height and radius of points around the vertical axis ``x=0, z=axis_z``.

    The angle is 0 straight ahead (+z) and positive towards +x.
    """
    dx, dz = P[:, 0], P[:, 2] - axis_z
    return np.arctan2(dx, dz), P[:, 1].copy(), np.hypot(dx, dz)


def cross3(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """:func:`numpy.cross` of 3-vectors along the last axis (broadcast): the same numbers, a third of the time (no
    axis shuffling; the binding's keys turn thousands of normals each)."""
    out = np.empty(np.broadcast_shapes(u.shape, v.shape), np.result_type(u, v))
    out[..., 0] = u[..., 1] * v[..., 2] - u[..., 2] * v[..., 1]
    out[..., 1] = u[..., 2] * v[..., 0] - u[..., 0] * v[..., 2]
    out[..., 2] = u[..., 0] * v[..., 1] - u[..., 1] * v[..., 0]
    return out


def triangle_cross(V: np.ndarray, T: np.ndarray) -> np.ndarray:
    """Cross product of each triangle's two edges from its first corner: the normal times twice the area."""
    P = V[T]
    return cross3(P[:, 1] - P[:, 0], P[:, 2] - P[:, 0])


def every_corner(mask: np.ndarray, T: np.ndarray) -> np.ndarray:
    """Whether all three corners of each triangle of ``T`` have ``mask`` (per vertex): corner by corner, 6x faster
    than ``mask[T].all(axis=1)`` (a reduction over an axis of 3 is slow in numpy)."""
    return mask[T[:, 0]] & mask[T[:, 1]] & mask[T[:, 2]]


def any_corner(mask: np.ndarray, T: np.ndarray) -> np.ndarray:
    """Whether any corner of each triangle of ``T`` has ``mask`` (per vertex), corner by corner."""
    return mask[T[:, 0]] | mask[T[:, 1]] | mask[T[:, 2]]


def column_bounds(X: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(X.min(axis=0), X.max(axis=0))`` of points ``X (n, d)``, column by column: the same numbers, 10-20x faster
    (numpy reduces down the columns of a short-rowed array slowly: 0.8 ms each for a 27k-vertex head)."""
    X = np.asarray(X)
    return (np.array([X[:, k].min() for k in range(X.shape[1])], X.dtype),
            np.array([X[:, k].max() for k in range(X.shape[1])], X.dtype))


def column_extent(X: np.ndarray) -> np.ndarray:
    """``numpy.ptp(X, axis=0)``: each column's largest less its smallest (:func:`column_bounds`')."""
    lo, hi = column_bounds(X)
    return hi - lo


def in_box(P: np.ndarray, lo, hi) -> np.ndarray:
    """Whether each point of ``P (n, 3)`` lies in the box ``lo <= p <= hi`` (NaN in none), coordinate by
    coordinate: 5x faster than ``((P >= lo) & (P <= hi)).all(axis=1)``."""
    lo, hi = np.broadcast_to(lo, 3), np.broadcast_to(hi, 3)
    inside = (P[:, 0] >= lo[0]) & (P[:, 0] <= hi[0])
    for k in (1, 2):
        inside &= (P[:, k] >= lo[k]) & (P[:, k] <= hi[k])
    return inside


def smoothstep(t) -> np.ndarray:
    """0 at t ≤ 0, 1 at t ≥ 1, 3t² − 2t³ between (C1 at both ends): the project's fades and ramps."""
    t = np.clip(t, 0.0, 1.0)
    return t * t * (3 - 2 * t)


def degrees_from_cos(cos) -> np.ndarray:
    """Angles (degrees) from their cosines, clipped to [-1, 1] first: a dot product of unit vectors can round
    past 1."""
    return np.degrees(np.arccos(np.clip(cos, -1.0, 1.0)))


def row_norms(X: np.ndarray) -> np.ndarray:
    """Lengths of the rows (vectors along the last axis): :func:`numpy.linalg.norm`'s numbers (the same sums in the
    same order), for 3-vectors 5× faster (no reduction over a short axis)."""
    X = np.asarray(X)
    if X.shape[-1] != 3 or not np.issubdtype(X.dtype, np.floating):
        return np.linalg.norm(X, axis=-1)
    s = X[..., 0] * X[..., 0]
    s += X[..., 1] * X[..., 1]
    s += X[..., 2] * X[..., 2]
    return np.sqrt(s)


def median_edge(P: np.ndarray, T: np.ndarray) -> float:
    """The median length of the triangles ``T``' edges (each edge once per triangle it bounds)."""
    a, b = P[T.ravel()], P[np.roll(T, -1, axis=1).ravel()]
    return float(np.median(row_norms(b - a)))


def row_dots(A: np.ndarray, B: np.ndarray) -> np.ndarray:
    """Dot products of the rows of ``A`` and ``B`` (n, 3): ``(A * B).sum(1)``'s numbers (the same sums in the same
    order) without numpy's slow reduction over an axis of 3."""
    d = A[:, 0] * B[:, 0]
    d += A[:, 1] * B[:, 1]
    d += A[:, 2] * B[:, 2]
    return d


def unit_rows(X: np.ndarray) -> np.ndarray:
    """Rows (vectors along the last axis) scaled to unit length (zero rows stay zero)."""
    return X / np.maximum(row_norms(X)[..., None], 1e-300)


#: Most cells along each axis of the ray-casting grid: the grid covers the rays, never the mesh's raw extent,
#: so a stray vertex far away cannot size it, and a triangle's cells stay under this squared.
MAX_GRID_CELLS = 512


def cylinder_ray_candidates(V, T, axis_z, theta, height) -> tuple[np.ndarray, np.ndarray]:
    """(ray, triangle) pairs worth a hit test for rays cast from a vertical axis.

    The pairs are each ray with every triangle whose (angle, height) box holds the ray's (angle, height), in
    ascending order of ray, then triangle: they include every hit, since a triangle's box holds every point a ray
    from the axis can meet on it. Triangles outside the rays' box, wrapping round the back of the axis, or
    touching it, never meet the rays and are left out. Triangles are binned into a uniform (angle, height) grid
    over the rays' own box (cells about twice a triangle's median extent, at most :data:`MAX_GRID_CELLS` along
    each axis); a triangle none of whose cells holds a ray is dropped before it is binned (a few thousand rays
    meet a few thousand of a 200k-vertex head's triangles), and a ray is paired with the rest of its cell's.
    """
    theta = np.asarray(theta, dtype=np.float64).ravel()
    height = np.asarray(height, dtype=np.float64).ravel()
    none = np.zeros(0, np.int64)
    if len(theta) == 0 or len(T) == 0:
        return none, none
    q_ok = np.isfinite(theta) & np.isfinite(height)  # a ray that is not finite meets nothing
    if not q_ok.any():
        return none, none
    th, y, r = cylinder_coords(V, axis_z)
    qlo = np.array([theta[q_ok].min(), height[q_ok].min()])
    qhi = np.array([theta[q_ok].max(), height[q_ok].max()])
    # A triangle with a corner not finite, or on the axis, is out; with finite corners its box is finite. Corner by
    # corner, one coordinate at a time: reductions over an axis of 3 (or 2) are slow in numpy.
    bad = ~(np.isfinite(th) & np.isfinite(y)) | ~(r > 1e-9)
    a, b, c = T[:, 0], T[:, 1], T[:, 2]
    ta, tb, tc = th[a], th[b], th[c]
    lo_th, hi_th = np.minimum(np.minimum(ta, tb), tc), np.maximum(np.maximum(ta, tb), tc)
    ya, yb, yc = y[a], y[b], y[c]
    lo_y, hi_y = np.minimum(np.minimum(ya, yb), yc), np.maximum(np.maximum(ya, yb), yc)
    ok = ~(bad[a] | bad[b] | bad[c])
    ok &= hi_th - lo_th < np.pi / 2
    ok &= (hi_th >= qlo[0]) & (lo_th <= qhi[0]) & (hi_y >= qlo[1]) & (lo_y <= qhi[1])
    cand = np.flatnonzero(ok)
    if len(cand) == 0:
        return none, none
    lo_th, hi_th, lo_y, hi_y = lo_th[cand], hi_th[cand], lo_y[cand], hi_y[cand]
    size = np.maximum(np.maximum([np.median(hi_th - lo_th) * 2.0, np.median(hi_y - lo_y) * 2.0],
                                 (qhi - qlo) / MAX_GRID_CELLS), 1e-9)
    ncell = np.minimum(np.floor((qhi - qlo) / size), MAX_GRID_CELLS).astype(np.int64) + 1

    def cell_of(x, axis):  # clipped as floats first: no integer overflow however far a point lies
        x = (x - qlo[axis]) / size[axis]
        return np.floor(np.clip(x, 0, ncell[axis] - 1, out=x)).astype(np.int64)

    q_th, q_y = theta[q_ok], height[q_ok]
    # the rays per cell summed over every cell below and left of it: a box of cells holds a ray when its corners'
    # sums differ
    rays_below = np.zeros((ncell[0] + 1, ncell[1] + 1), np.int64)
    np.add.at(rays_below, (cell_of(q_th, 0) + 1, cell_of(q_y, 1) + 1), 1)
    rays_below = rays_below.cumsum(0).cumsum(1)
    i0, i1, j0, j1 = cell_of(lo_th, 0), cell_of(hi_th, 0) + 1, cell_of(lo_y, 1), cell_of(hi_y, 1) + 1
    held = np.flatnonzero(rays_below[i1, j1] - rays_below[i0, j1] - rays_below[i1, j0] + rays_below[i0, j0])
    if len(held) == 0:
        return none, none
    cand, lo_th, hi_th, lo_y, hi_y = cand[held], lo_th[held], hi_th[held], lo_y[held], hi_y[held]
    while True:  # many huge triangles would fill many cells each: coarsen the grid (a few doublings at most)
        i0, j0 = cell_of(lo_th, 0), cell_of(lo_y, 1)
        span_i, span_j = cell_of(hi_th, 0) - i0 + 1, cell_of(hi_y, 1) - j0 + 1
        reps = span_i * span_j
        if reps.sum() <= 16 * len(cand) + 2 ** 22:
            break
        size = size * 2
        ncell = np.minimum(np.floor((qhi - qlo) / size), MAX_GRID_CELLS).astype(np.int64) + 1
    tid = np.repeat(np.arange(len(cand)), reps)
    k = np.arange(len(tid)) - np.repeat(np.cumsum(reps) - reps, reps)
    cell = (i0[tid] + k % span_i[tid]) * ncell[1] + j0[tid] + k // span_i[tid]
    order = np.argsort(cell, kind="stable")
    cell, tid = cell[order], tid[order]
    qcell = np.where(q_ok, cell_of(np.where(q_ok, theta, qlo[0]), 0) * ncell[1]
                     + cell_of(np.where(q_ok, height, qlo[1]), 1), -1)
    start = np.searchsorted(cell, qcell, "left")
    counts = np.where(q_ok, np.searchsorted(cell, qcell, "right") - start, 0)
    rays = np.repeat(np.arange(len(theta)), counts)
    pos = np.arange(len(rays)) - np.repeat(np.cumsum(counts) - counts, counts) + np.repeat(start, counts)
    box = tid[pos]
    # only the triangles whose box holds the ray's point: the grid's cells hold many more
    at_th, at_y = theta[rays], height[rays]
    inside = (lo_th[box] <= at_th) & (at_th <= hi_th[box]) & (lo_y[box] <= at_y) & (at_y <= hi_y[box])
    return rays[inside], cand[box[inside]]


def ray_triangle(origins, directions, A, B, C, eps=1e-9):
    """Möller–Trumbore hit test of ray i against triangle (A[i], B[i], C[i]).

    Returns
    -------
    hit : (m,) bool
    u, v : (m,) float, barycentric weights of B and C at the hit
    t : (m,) float, distance along the (unit) direction
    """
    e1, e2 = B - A, C - A
    p = np.cross(directions, e2)
    det = np.einsum("ij,ij->i", e1, p)
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = 1.0 / det
        s = origins - A
        u = np.einsum("ij,ij->i", s, p) * inv
        q = np.cross(s, e1)
        v = np.einsum("ij,ij->i", directions, q) * inv
        t = np.einsum("ij,ij->i", e2, q) * inv
    hit = (np.abs(det) > 1e-15) & (u >= -eps) & (v >= -eps) & (u + v <= 1 + eps) & (t > 0)
    return hit, u, v, t


def _ray_directions(theta):
    return np.stack([np.sin(theta), np.zeros(len(theta)), np.cos(theta)], 1)


def cast_cylinder_rays(V, T, axis_z, theta, height, batch=200_000):
    """Outermost hit of horizontal rays cast from a vertical axis outwards.

    Ray ``q`` starts on the axis at height ``height[q]`` and points along angle
    ``theta[q]``. The hit farthest from the axis is the one a viewer outside
    sees first.

    Returns
    -------
    radius : (q,) float, NaN where the ray misses
    tri : (q,) int, hit triangle or -1
    bary : (q, 3) float, barycentric weights of the hit in ``tri``
    facing : (q,) float, cosine between the triangle normal and the ray
        (> 0: the hit surface faces outwards, as skin seen from outside does)
    """
    theta = np.asarray(theta, dtype=np.float64).ravel()
    height = np.asarray(height, dtype=np.float64).ravel()
    nq = len(theta)
    radius = np.full(nq, np.nan)
    tri = np.full(nq, -1, dtype=np.int64)
    bary = np.zeros((nq, 3))
    facing = np.zeros(nq)
    if nq == 0 or len(T) == 0:
        return radius, tri, bary, facing
    rays, tris = cylinder_ray_candidates(V, T, axis_z, theta, height)
    for b in range(0, len(rays), batch):
        qid, t_ = rays[b:b + batch], tris[b:b + batch]
        o = np.stack([np.zeros(len(qid)), height[qid], np.full(len(qid), axis_z)], 1)
        hit, u, v, t = ray_triangle(o, _ray_directions(theta[qid]), V[T[t_, 0]], V[T[t_, 1]], V[T[t_, 2]])
        qid, t_, u, v, t = qid[hit], t_[hit], u[hit], v[hit], t[hit]
        # Keep the farthest hit per ray: sort by (ray, -t) and take each ray's first. Where two hits tie
        # (twin triangles on the same three vertices wound both ways, as vertex clustering and some
        # exports leave them), the one facing outwards wins: the other's inside would stop the ray.
        front = np.einsum("ij,ij->i", triangle_cross(V, T[t_]), _ray_directions(theta[qid])) > 0
        order = np.lexsort((~front, -np.round(t, 6), qid))
        qid, t_, u, v, t = qid[order], t_[order], u[order], v[order], t[order]
        first = np.ones(len(qid), bool)
        first[1:] = qid[1:] != qid[:-1]
        qid, t_, u, v, t = qid[first], t_[first], u[first], v[first], t[first]
        better = np.isnan(radius[qid]) | (t > radius[qid])
        qid, t_, u, v, t = qid[better], t_[better], u[better], v[better], t[better]
        radius[qid], tri[qid] = t, t_
        bary[qid] = np.stack([1 - u - v, u, v], 1)
    hit = tri >= 0
    if hit.any():
        n = unit_rows(triangle_cross(V, T[tri[hit]]))
        facing[hit] = np.einsum("ij,ij->i", n, _ray_directions(theta[hit]))
    return radius, tri, bary, facing


def similarity(A, B, scale=True):
    """Scale ``s``, rotation ``R`` and shift ``t`` with ``B ≈ s A Rᵀ + t`` (Umeyama; ``s = 1`` when not
    ``scale``: the rigid fit), least squares over the rows finite in both."""
    ok = np.isfinite(A).all(1) & np.isfinite(B).all(1)
    A, B = A[ok], B[ok]
    ca, cb = A.mean(0), B.mean(0)
    a, b = A - ca, B - cb
    U, S, Vt = np.linalg.svd(b.T @ a)
    D = np.diag([1.0, 1.0, np.sign(np.linalg.det(U @ Vt))])
    R = U @ D @ Vt
    s = float((S * np.diag(D)).sum() / (a ** 2).sum()) if scale else 1.0
    return s, R, cb - s * ca @ R.T


def closest_point_on_triangles(P, A, B, C):
    """Closest point to each ``P[i]`` on triangle ``(A[i], B[i], C[i])``.

    Returns the points and their barycentric weights (Ericson's region test).
    """
    ab, ac, ap = B - A, C - A, P - A
    d1, d2 = np.einsum("ij,ij->i", ab, ap), np.einsum("ij,ij->i", ac, ap)
    bp = P - B
    d3, d4 = np.einsum("ij,ij->i", ab, bp), np.einsum("ij,ij->i", ac, bp)
    cp = P - C
    d5, d6 = np.einsum("ij,ij->i", ab, cp), np.einsum("ij,ij->i", ac, cp)
    va = d3 * d6 - d5 * d4
    vb = d5 * d2 - d1 * d6
    vc = d1 * d4 - d3 * d2
    w = np.zeros((len(P), 3))
    with np.errstate(divide="ignore", invalid="ignore"):
        denom = va + vb + vc
        v_in, w_in = vb / denom, vc / denom
        w[:] = np.stack([1 - v_in - w_in, v_in, w_in], 1)
        # Edge regions.
        tab = d1 / (d1 - d3)
        m = (vc <= 0) & (d1 >= 0) & (d3 <= 0)
        w[m] = np.stack([1 - tab[m], tab[m], np.zeros(m.sum())], 1)
        tac = d2 / (d2 - d6)
        m = (vb <= 0) & (d2 >= 0) & (d6 <= 0)
        w[m] = np.stack([1 - tac[m], np.zeros(m.sum()), tac[m]], 1)
        tbc = (d4 - d3) / ((d4 - d3) + (d5 - d6))
        m = (va <= 0) & ((d4 - d3) >= 0) & ((d5 - d6) >= 0)
        w[m] = np.stack([np.zeros(m.sum()), 1 - tbc[m], tbc[m]], 1)
    # Vertex regions last: they override the edge tests at the corners.
    w[(d1 <= 0) & (d2 <= 0)] = (1, 0, 0)
    w[(d3 >= 0) & (d4 <= d3)] = (0, 1, 0)
    w[(d6 >= 0) & (d5 <= d6)] = (0, 0, 1)
    w = np.nan_to_num(w, nan=1 / 3)
    Q = w[:, :1] * A + w[:, 1:2] * B + w[:, 2:] * C
    return Q, w


#: Points :meth:`ClosestPoint.query` works on at a time.
QUERY_BLOCK = 1024


class ClosestPoint:
    """Closest-point queries on a triangle mesh.

    Candidates are the triangles around the ``k`` nearest vertices and
    triangle centroids, which is exact for the fine, even meshes used here. ``balanced=False``: the search trees
    built without balancing (half the time on a sheet, as the PDE face's grid; the same answers but where two
    vertices or centroids lie exactly as near, which a mesh without repeated points never meets).
    """

    def __init__(self, V, T, k=8, balanced=True):
        from scipy.spatial import cKDTree  # imported here: meshing a face must not pay for scipy

        self.V, self.T = np.asarray(V, dtype=np.float64), np.asarray(T, dtype=np.int64)
        self.k = k
        self._tree_options = {} if balanced else {"balanced_tree": False, "compact_nodes": False}
        from scipy.sparse import csr_matrix

        V, T = self.V, self.T
        self.centroids = V[T[:, 0]] + V[T[:, 1]]  # V[T].mean(axis=1)'s sums in its order, a third of the time
        self.centroids += V[T[:, 2]]
        self.centroids /= 3
        self.tree = cKDTree(self.centroids, **self._tree_options)
        nv = len(self.V)
        # the corners sorted by vertex, each vertex's in their order (a stable sort): the transpose's counting sort
        corners = csr_matrix((np.ones(T.size, np.int8), T.ravel(), np.arange(T.size + 1)), shape=(T.size, nv)).tocsc()
        self._vt = corners.indices // 3  # triangles sorted by corner vertex
        self._vstart = corners.indptr.astype(np.int64)

    @cached_property
    def vtree(self):
        """A search tree of the vertices, built on first use (a caller that knows each point's nearest vertex needs
        none)."""
        from scipy.spatial import cKDTree

        return cKDTree(self.V, **self._tree_options)

    def query(self, P, nearest=None):
        """Closest points on the mesh; ``nearest``: each point's nearest vertex where already found (a query of
        :attr:`vtree`).

        Returns
        -------
        distance : (p,) float
        tri : (p,) int
        bary : (p, 3) float
        point : (p, 3) float
        """
        P = np.asarray(P, dtype=np.float64)
        if nearest is not None:
            nearest = np.asarray(nearest, np.int64)
        if len(P) <= QUERY_BLOCK:
            return self._query_block(P, nearest)
        # Block by block of points (each point's answer is its own): the candidates' temporaries stay in cache and
        # in the heap, not fresh pages (ICT's binding's 6.5k points: 21 MB of them, 5.3k page faults on their own;
        # the binding's whole count fell 10.4k -> 7.6-7.9k, docs/design/head.md)
        out = np.empty(len(P)), np.empty(len(P), np.int64), np.empty((len(P), 3)), np.empty((len(P), 3))
        for start in range(0, len(P), QUERY_BLOCK):
            block = slice(start, start + QUERY_BLOCK)
            for whole, part in zip(out, self._query_block(P[block], None if nearest is None else nearest[block])):
                whole[block] = part
        return out

    def _query_block(self, P, nearest):
        """:meth:`query` of the points ``P`` (float64), ``nearest`` an int64 array or None."""
        k = min(self.k, len(self.T))
        _, ct = self.tree.query(P, k=k)
        ct = ct.reshape(len(P), -1)
        nv = self.vtree.query(P, k=1)[1] if nearest is None else nearest
        # Triangles around the nearest vertex (a few, padded with the first centroid hit).
        deg = self._vstart[nv + 1] - self._vstart[nv]
        maxdeg = int(deg.max()) if len(deg) else 0
        ring = np.repeat(ct[:, :1], maxdeg, axis=1)
        for j in range(maxdeg):
            has = deg > j
            ring[has, j] = self._vt[self._vstart[nv[has]] + j]
        cand = np.concatenate([ct, ring], axis=1)
        npt, nc = cand.shape
        # Each point's distinct candidates tested once (the ring is mostly among the centroids' triangles: 9 of 14),
        # their distances put back in every place each held: the first nearest in the candidates' order, as before.
        order = np.argsort(cand, axis=1, kind="stable")
        ranked = np.take_along_axis(cand, order, axis=1)
        new = np.ones((npt, nc), bool)
        new[:, 1:] = ranked[:, 1:] != ranked[:, :-1]
        pair = np.cumsum(new.ravel()) - 1  # each ranked place's distinct (point, triangle)
        point, tri = np.nonzero(new)[0], ranked[new]
        Pr = P[point]
        Q, w = closest_point_on_triangles(Pr, self.V[self.T[tri, 0]], self.V[self.T[tri, 1]], self.V[self.T[tri, 2]])
        du = row_norms(Q - Pr)
        d = np.empty((npt, nc))
        np.put_along_axis(d, order, du[pair].reshape(npt, nc), axis=1)
        slot = np.empty((npt, nc), np.int64)
        np.put_along_axis(slot, order, pair.reshape(npt, nc), axis=1)
        best = slot[np.arange(npt), np.argmin(d, axis=1)]
        return du[best], tri[best], w[best], Q[best]
