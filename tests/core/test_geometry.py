"""Closest points on triangle meshes (pdeface.geometry)."""
import numpy as np
from pdeface.geometry import ClosestPoint, closest_point_on_triangles


def _bumpy_grid(n_u=30, n_v=40, seed=0):
    """A regular grid of quads, each split in two triangles, on a bumpy sheet (as the PDE face's reads are)."""
    rng = np.random.default_rng(seed)
    u, v = np.meshgrid(np.linspace(0, 3, n_u), np.linspace(0, 4, n_v), indexing="ij")
    V = np.stack([u, v, 0.3 * np.sin(2 * u) * np.cos(3 * v) + 0.01 * rng.normal(size=u.shape)], -1).reshape(-1, 3)
    r, c = np.meshgrid(np.arange(n_u - 1), np.arange(n_v - 1), indexing="ij")
    i = (r * n_v + c).ravel()
    Q = np.stack([i, i + n_v, i + n_v + 1, i + 1], axis=1)
    return V, np.concatenate([Q[:, [0, 1, 2]], Q[:, [0, 2, 3]]])


def _brute_force(V, T, P):
    """Every point's distance to every triangle: the smallest."""
    Pr = np.repeat(P, len(T), axis=0)
    Tt = np.tile(T, (len(P), 1))
    Q, _ = closest_point_on_triangles(Pr, V[Tt[:, 0]], V[Tt[:, 1]], V[Tt[:, 2]])
    return np.linalg.norm(Q - Pr, axis=1).reshape(len(P), len(T)).min(axis=1)


def test_closest_point_is_the_nearest_of_all_triangles_and_consistent():
    V, T = _bumpy_grid()
    rng = np.random.default_rng(1)
    P = np.concatenate([rng.uniform([0, 0, -0.2], [3, 4, 0.2], (300, 3)),  # near the sheet
                        V[rng.integers(0, len(V), 20)],  # on its vertices
                        (V[T[:20, 0]] + V[T[:20, 2]]) / 2])  # on its quads' diagonals: two triangles as near
    closest = ClosestPoint(V, T)
    d, tri, bary, point = closest.query(P)
    assert np.allclose(d, _brute_force(V, T, P), rtol=0, atol=1e-12)
    assert np.allclose(np.einsum("pc,pcx->px", bary, V[T[tri]]), point, atol=1e-12)
    assert np.allclose(np.linalg.norm(point - P, axis=1), d, atol=1e-12)
    assert np.allclose(bary.sum(1), 1) and (bary >= -1e-12).all()
    # the nearest vertices handed in give the same answer as those it finds itself
    nearest = closest.vtree.query(P)[1]
    for got, want in zip(closest.query(P, nearest), (d, tri, bary, point)):
        assert np.array_equal(got, want)
    # unbalanced trees (the PDE face's grid's): the same answers
    for got, want in zip(ClosestPoint(V, T, balanced=False).query(P), (d, tri, bary, point)):
        assert np.array_equal(got, want)


def test_closest_points_block_by_block_are_each_points_own(monkeypatch):
    """Points queried a block at a time (ClosestPoint.QUERY_BLOCK: its temporaries in cache, not fresh pages) get the
    answers each gets alone, bit for bit: blocks of every size, one cut between a vertex's ring of many triangles
    and one of few (the ring's width differs from block to block), with and without their nearest vertices."""
    import pdeface.geometry as geometry

    V, T = _bumpy_grid()
    T = np.concatenate([T, np.stack([np.zeros(12, int), np.arange(1, 13), np.arange(2, 14)], 1)])  # a wide fan at 0
    rng = np.random.default_rng(3)
    P = np.concatenate([rng.uniform([0, 0, -0.2], [3, 4, 0.2], (200, 3)), V[:1] + 1e-3])
    closest = ClosestPoint(V, T)
    nearest = closest.vtree.query(P)[1]
    alone = [np.concatenate(parts) for parts in zip(*(closest.query(P[i:i + 1]) for i in range(len(P))))]
    for block in (1, 7, 64, len(P) - 1, len(P)):
        monkeypatch.setattr(geometry, "QUERY_BLOCK", block)
        for got in (closest.query(P), closest.query(P, nearest)):
            assert all(a.dtype == b.dtype and np.array_equal(a, b) for a, b in zip(got, alone))


def test_closest_point_on_a_mesh_with_fewer_triangles_than_candidates():
    V = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0.5]], float)
    T = np.array([[0, 1, 2], [1, 3, 2]])
    P = np.array([[0.2, 0.2, 1.0], [0.9, 0.9, 0.0], [2.0, 2.0, 0.0], [0.5, 0.5, 0.1]])
    d, tri, bary, point = ClosestPoint(V, T).query(P)
    assert np.allclose(d, _brute_force(V, T, P), atol=1e-12)
    assert tri[0] == 0 and np.allclose(point[0], [0.2, 0.2, 0])
    assert np.allclose(np.einsum("pc,pcx->px", bary, V[T[tri]]), point, atol=1e-12)


def test_some_vertices_normals_are_the_whole_meshs():
    from pdeface.mesh import vertex_normals

    V, T = _bumpy_grid()
    only = np.array([0, 5, 41, 600, len(V) - 1, 41])  # a corner, a border, the middle, a repeat
    assert np.array_equal(vertex_normals(V, T, only=only), vertex_normals(V, T)[only])
    assert vertex_normals(V, T, only=np.zeros(0, np.int64)).shape == (0, 3)


def test_row_dots_are_the_sums_numpy_makes():
    from pdeface.geometry import row_dots

    rng = np.random.default_rng(3)
    A, B = rng.normal(size=(1000, 3)), rng.normal(size=(1000, 3))
    assert np.array_equal(row_dots(A, B), (A * B).sum(1))


def test_cotan_laplacian_is_scipys_diagonal_less_the_clamped_weights():
    """The Laplacian with its cotangents from row_dots, row_norms and cross3 (issue #35) is the reference's bit for
    bit: on a sheet, with a vertex no triangle uses (its zero diagonal left out) and with triangles that repeat a
    corner (a stored diagonal in W)."""
    from pdeface.mesh import cotan_laplacian
    from scipy.sparse import coo_matrix, diags

    def reference(V, T):
        rows, cols, vals = [], [], []
        for k in range(3):
            i, j, o = T[:, k], T[:, (k + 1) % 3], T[:, (k + 2) % 3]
            u, v = V[i] - V[o], V[j] - V[o]
            cot = (u * v).sum(1) / np.maximum(np.linalg.norm(np.cross(u, v), axis=1), 1e-12)
            rows += [i, j]
            cols += [j, i]
            vals += [0.5 * cot, 0.5 * cot]
        n = len(V)
        W = coo_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(n, n)).tocsr()
        W.data = np.clip(W.data, 1e-6, 1e3)
        return (diags(np.asarray(W.sum(axis=1)).ravel()) - W).tocsr()

    V, T = _bumpy_grid()
    repeated = T.copy()
    repeated[:4, 2] = repeated[:4, 0]
    for V_, T_ in ((V, T), (np.r_[V, [[9.0, 9.0, 9.0]]], T), (V, repeated)):
        got, want = cotan_laplacian(V_, T_), reference(V_, T_)
        assert got.shape == want.shape
        for name in ("indptr", "indices", "data"):
            assert getattr(got, name).dtype == getattr(want, name).dtype
            assert np.array_equal(getattr(got, name), getattr(want, name))
    L = cotan_laplacian(V, T)
    assert np.allclose(L @ np.ones(len(V)), 0, atol=1e-12) and (L - L.T).count_nonzero() == 0


def test_column_bounds_are_numpys_min_and_max_down_the_columns():
    from pdeface.geometry import column_bounds, column_extent

    rng = np.random.default_rng(5)
    X = rng.normal(size=(1000, 3))
    X[7, 1] = np.nan  # a NaN: that column's bounds are NaN, as numpy's
    X[[3, 9], 2] = -0.0, 0.0
    for A in (X, X[::3], rng.integers(-5, 5, (50, 4)), X[:1]):
        lo, hi = column_bounds(A)
        for got, want in ((lo, A.min(axis=0)), (hi, A.max(axis=0))):
            assert got.dtype == want.dtype and np.array_equal(got, want, equal_nan=True)
            assert np.array_equal(np.signbit(got), np.signbit(want))
        assert np.array_equal(column_extent(A), np.ptp(A, axis=0), equal_nan=True)
