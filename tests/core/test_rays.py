"""The cylinder rays' candidate search (issue #35): the same pairs and hits as trying every triangle."""
import numpy as np
import pytest
from pdeface.geometry import (
    cast_cylinder_rays,
    cylinder_coords,
    cylinder_ray_candidates,
    ray_triangle,
)


def bumpy_cylinder(n_around, n_up, rng, radius=60.0):
    """A closed-round, open-ended bumpy cylinder around the y axis (a stand-in head): (V, T)."""
    a = np.linspace(-np.pi, np.pi, n_around, endpoint=False)
    h = np.linspace(-80, 80, n_up)
    A, H = np.meshgrid(a, h, indexing="ij")
    R = radius + 3 * np.sin(3 * A) * np.cos(H / 20) + rng.normal(0, 0.5, A.shape)
    V = np.stack([R * np.sin(A), H, R * np.cos(A)], -1).reshape(-1, 3)
    idx = np.arange(n_around * n_up).reshape(n_around, n_up)
    nxt = np.roll(idx, -1, axis=0)
    q = np.stack([idx[:, :-1], nxt[:, :-1], nxt[:, 1:], idx[:, 1:]], -1).reshape(-1, 4)
    return V, np.concatenate([q[:, [0, 1, 2]], q[:, [0, 2, 3]]])


def brute_pairs(V, T, axis_z, theta, height):
    """Every (ray, triangle) whose (angle, height) box holds the ray, of triangles not wrapping round the back
    of the axis nor touching it: the pairs the search must give."""
    th, y, r = cylinder_coords(V, axis_z)
    ok = (np.ptp(th[T], axis=1) < np.pi / 2) & (r[T].min(axis=1) > 1e-9)
    inside = ((th[T].min(1) <= theta[:, None]) & (theta[:, None] <= th[T].max(1))
              & (y[T].min(1) <= height[:, None]) & (height[:, None] <= y[T].max(1)) & ok)
    return set(zip(*np.nonzero(inside)))


def brute_hits(V, T, axis_z, theta, height):
    """The farthest hit of each ray, trying every triangle but those wrapping round the back of the axis (the
    search leaves them out: rays cast forwards never meet them): radius, NaN where it misses."""
    th, _, r = cylinder_coords(V, axis_z)
    T = T[(np.ptp(th[T], axis=1) < np.pi / 2) & (r[T].min(axis=1) > 1e-9)]
    q, t_ = (a.ravel() for a in np.meshgrid(np.arange(len(theta)), np.arange(len(T)), indexing="ij"))
    o = np.stack([np.zeros(len(q)), height[q], np.full(len(q), axis_z)], 1)
    d = np.stack([np.sin(theta[q]), np.zeros(len(q)), np.cos(theta[q])], 1)
    hit, _, _, t = ray_triangle(o, d, V[T[t_, 0]], V[T[t_, 1]], V[T[t_, 2]])
    radius = np.full(len(theta), np.nan)
    for qi, ti in zip(q[hit], t[hit]):
        if not ti <= radius[qi]:
            radius[qi] = ti
    return radius


@pytest.mark.parametrize("n_around,n_up", [(12, 6), (40, 25), (90, 7)])
def test_candidates_and_hits_are_those_of_every_triangle(rng, n_around, n_up):
    """Coarse and fine, long and flat triangles: the grid gives exactly the brute-force pairs, and the cast
    the same farthest hits."""
    V, T = bumpy_cylinder(n_around, n_up, rng)
    theta = rng.uniform(-np.pi, np.pi, 300)
    height = rng.uniform(-90, 90, 300)  # some above and below the mesh: misses
    rays, tris = cylinder_ray_candidates(V, T, 5.0, theta, height)
    assert len(set(zip(rays, tris))) == len(rays)  # no pair twice
    assert set(zip(rays, tris)) == brute_pairs(V, T, 5.0, theta, height)
    # by ray, then triangle: the cast keeps the first of two equally far hits, so the order is part of the answer
    assert (np.lexsort((tris, rays)) == np.arange(len(rays))).all()
    radius = cast_cylinder_rays(V, T, 5.0, theta, height)[0]
    expected = brute_hits(V, T, 5.0, theta, height)
    assert np.isnan(expected).any() and np.isfinite(expected).sum() > 200
    np.testing.assert_allclose(radius, expected, rtol=1e-12)


def test_rays_at_one_angle_and_a_mesh_far_bigger_than_the_rays(rng):
    """A rim walk (one angle, many heights) on a fine mesh: the grid covers the rays, the pairs are the same."""
    V, T = bumpy_cylinder(120, 80, rng)
    theta, height = np.full(200, 0.3), np.linspace(-10, 10, 200)
    rays, tris = cylinder_ray_candidates(V, T, 0.0, theta, height)
    assert set(zip(rays, tris)) == brute_pairs(V, T, 0.0, theta, height)
    np.testing.assert_allclose(cast_cylinder_rays(V, T, 0.0, theta, height)[0], brute_hits(V, T, 0.0, theta, height))


def test_a_stray_vertex_far_away_neither_sizes_the_grid_nor_loses_hits(rng):
    """One vertex at 1e20 (a broken export): its triangles span the whole grid at most (the grid is
    bounded: pdeface.geometry.MAX_GRID_CELLS a side), no integer overflow, and every other ray hits as before."""
    V, T = bumpy_cylinder(40, 25, rng)
    theta, height = rng.uniform(-np.pi, np.pi, 300), rng.uniform(-70, 70, 300)
    before = cast_cylinder_rays(V, T, 0.0, theta, height)[0]
    V = V.copy()
    V[len(V) // 2] = (1e20, 1e20, 1e20)
    rays, tris = cylinder_ray_candidates(V, T, 0.0, theta, height)
    assert len(rays) <= len(theta) * len(T) and set(zip(rays, tris)) == brute_pairs(V, T, 0.0, theta, height)
    after = cast_cylinder_rays(V, T, 0.0, theta, height)[0]
    touched = np.isin(np.arange(len(theta)), rays[np.isin(tris, np.nonzero((T == len(V) // 2).any(1))[0])])
    assert touched.sum() < len(theta) / 3
    np.testing.assert_allclose(after[~touched], before[~touched])


def test_no_rays_or_no_triangles():
    V = np.array([[-1.0, -1, 5], [1, -1, 5], [0, 1, 5]])
    for theta, T in ((np.zeros(0), np.array([[0, 1, 2]])), (np.zeros(2), np.zeros((0, 3), int))):
        rays, tris = cylinder_ray_candidates(V, T, 0.0, theta, np.zeros(len(theta)))
        assert len(rays) == len(tris) == 0


def test_rays_that_are_not_finite_meet_nothing_and_leave_the_others_as_they_were(rng):
    """NaN and infinite rays among finite ones: none is paired, and the finite rays' pairs are those they have
    cast alone (the triangles no ray's cell holds are dropped before binning: the rays kept must not lose theirs)."""
    V, T = bumpy_cylinder(60, 30, rng)
    theta, height = rng.uniform(-np.pi, np.pi, 200), rng.uniform(-90, 90, 200)
    alone = cylinder_ray_candidates(V, T, 5.0, theta, height)
    theta_bad, height_bad = theta.copy(), height.copy()
    theta_bad[::7], height_bad[3::11] = np.nan, np.inf
    rays, tris = cylinder_ray_candidates(V, T, 5.0, theta_bad, height_bad)
    finite = np.isfinite(theta_bad) & np.isfinite(height_bad)
    assert finite[rays].all() and not finite.all()
    kept = finite[alone[0]]
    np.testing.assert_array_equal(rays, alone[0][kept])
    np.testing.assert_array_equal(tris, alone[1][kept])
