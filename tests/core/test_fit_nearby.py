"""The fit's shortcuts on big meshes answer as the whole mesh does (issue #35: the fit <= 1 s at 100k vertices).

``closest_on_nearby`` builds its search on the triangles near the points only; ``band_triangles`` cuts the skin to
the rays' heights before casting. Both are checked against the whole mesh on ICT's scan and MakeHuman's base
mesh (scripts/devset), with a stray long triangle added, so the shortcut's edge cases are met.
"""
import numpy as np
import pytest
from pdeface.errors import LandmarkError
from pdeface.geometry import ClosestPoint, any_corner, cast_cylinder_rays, every_corner, in_box
from pdeface.mesh import border_vertices, connected_components
from pdeface.surface.fit import FEW_POINTS, check_landmarks_on_mesh, closest_on_nearby
from pdeface.surface.frame import face_frame
from pdeface.surface.layout import place_curves
from pdeface.surface.rims import band_triangles

from scripts.devset import makehuman
from scripts.devset.characters import annotated_points


def ict():
    from pdeface.assets import load_neutral_scan

    mesh, idx = load_neutral_scan()
    return mesh.vertices, mesh.triangles()[0], mesh.vertices[idx], "cm"


def human():
    if not makehuman.available():
        pytest.skip("needs ../shared/data/makehuman")
    base = makehuman.read_base()
    return base.vertices, makehuman.triangles(base.group_quads("body")), annotated_points(base.vertices), None


def in_face_frame(V, T, L, unit):
    frame = face_frame(L, unit)
    used = np.unique(T)
    keep = np.zeros(len(V), bool)
    keep[used] = True
    return frame.to_face(V[used]), (np.cumsum(keep) - 1)[T], frame.to_face(L)


@pytest.mark.parametrize("head", [ict, human])
@pytest.mark.parametrize("many", [False, True])
def test_closest_points_on_the_nearby_triangles_are_the_whole_meshs(head, many, rng):
    V, T, L = in_face_frame(*head())
    # a long thin triangle across the face, its corners far off: never near by its corners, but near the points
    V = np.concatenate([V, [[-400.0, 5.0, 30.0], [400.0, 5.0, 30.0], [0.0, 5.2, 30.0]]])
    T = np.concatenate([T, [[len(V) - 3, len(V) - 2, len(V) - 1]]])
    P = L + rng.normal(scale=2.0, size=L.shape)  # off the skin by a few mm, as the fitted face's grid points are
    if many:  # more points than FEW_POINTS: the vertices are looked at in the points' box, not in balls
        P = np.concatenate([P + rng.normal(scale=3.0, size=P.shape) for _ in range(FEW_POINTS // len(P) + 1)])
        assert len(P) > FEW_POINTS
    P = np.concatenate([P, [[0.0, 5.1, 30.5]]])  # nearest the long triangle
    whole = ClosestPoint(V, T).query(P)
    near = closest_on_nearby(V, T, P)
    np.testing.assert_allclose(near[0], whole[0], rtol=0, atol=1e-9)
    np.testing.assert_allclose(near[3], whole[3], rtol=0, atol=1e-6)
    assert near[1][-1] == len(T) - 1  # the long triangle, found though no corner of it is near
    assert np.abs(np.einsum("ij,ij->i", near[2], np.ones((len(P), 3))) - 1).max() < 1e-9


@pytest.mark.parametrize("head", [ict, human])
def test_rays_cast_on_the_band_of_their_heights_hit_as_on_the_whole_skin(head):
    V, T, L = in_face_frame(*head())
    layout = place_curves(L, 12, 21)
    theta, height = layout.angles().ravel(), layout.ray_heights().ravel()
    band = band_triangles(V, T, height.min(), height.max())
    assert 0 < len(band) < len(T)
    r0, t0, b0, f0 = cast_cylinder_rays(V, T, layout.axis_z, theta, height)
    r1, t1, b1, f1 = cast_cylinder_rays(V, band, layout.axis_z, theta, height)
    assert (t0 >= 0).mean() > 0.8
    np.testing.assert_array_equal(r1, r0)
    np.testing.assert_array_equal(f1, f0)
    np.testing.assert_array_equal(b1, b0)
    np.testing.assert_array_equal(np.where(t1[:, None] >= 0, band[np.maximum(t1, 0)], -1),
                                  np.where(t0[:, None] >= 0, T[np.maximum(t0, 0)], -1))  # the same triangles


def test_landmarks_off_the_mesh_are_named_with_their_distance_to_the_whole_mesh():
    """The reach is checked on the vertices in the landmarks' box only; a refusal names the farthest landmark and
    its distance to the nearest vertex of the whole mesh, outside that box too."""
    V, _, L = in_face_frame(*ict())
    check_landmarks_on_mesh(V, L)  # ICT's own landmarks lie on it
    moved = L.copy()
    moved[30] += (0.0, 0.0, 35.0)  # the nose tip 35 mm out
    moved[8] += (0.0, -500.0, 0.0)  # the chin half a metre down: its nearest vertex lies far outside the box
    far = np.linalg.norm(V[:, None] - moved[[30, 8]], axis=2).min(axis=0)
    assert 20 < far[0] < far[1]
    with pytest.raises(LandmarkError, match=f"landmark 8 lies {far[1]:.3g} mm from the mesh"):
        check_landmarks_on_mesh(V, moved)
    moved[8] = L[8]
    with pytest.raises(LandmarkError, match=f"landmark 30 lies {far[0]:.3g} mm from the mesh"):
        check_landmarks_on_mesh(V, moved)


def test_border_vertices_and_pieces_are_those_counted_edge_by_edge(rng):
    """border_vertices and connected_components (the skin's pieces) on random triangle soups with repeated and
    degenerate triangles: the vertices of edges one triangle has, and the pieces a union-find joins."""
    for _ in range(20):
        n = int(rng.integers(4, 60))
        T = rng.integers(0, n, size=(int(rng.integers(1, 50)), 3))
        T = np.concatenate([T, T[:3]])  # some twice: their edges are no border
        count = {}
        for tri in T.tolist():
            for a, b in ((tri[0], tri[1]), (tri[1], tri[2]), (tri[2], tri[0])):
                key = (min(a, b), max(a, b))
                count[key] = count.get(key, 0) + 1
        once = sorted({v for (a, b), c in count.items() if c == 1 for v in (a, b)})
        np.testing.assert_array_equal(border_vertices(n, T), once)
        parent = list(range(n))
        for a, b, c in T.tolist():
            for x, y in ((a, b), (b, c)):
                parent[_root(parent, x)] = _root(parent, y)
        lab = connected_components(n, T)
        roots = [_root(parent, v) for v in range(n)]
        assert all((lab[i] == lab[j]) == (roots[i] == roots[j]) for i in range(n) for j in range(n))


def test_corner_and_box_masks_are_numpys_reductions(rng):
    """every_corner, any_corner and in_box (the fit's triangle and box filters, written corner by corner) answer as
    ``mask[T].all/any(axis=1)`` and the box's comparisons do; a NaN point lies in no box."""
    mask = rng.random(50) < 0.7
    T = rng.integers(0, 50, size=(200, 3))
    np.testing.assert_array_equal(every_corner(mask, T), mask[T].all(axis=1))
    np.testing.assert_array_equal(any_corner(mask, T), mask[T].any(axis=1))
    P = rng.normal(size=(300, 3))
    P[::17, 1] = np.nan
    lo, hi = np.array([-1.0, -0.5, -2.0]), np.array([1.0, 0.5, 0.0])
    np.testing.assert_array_equal(in_box(P, lo, hi), ((P >= lo) & (P <= hi)).all(axis=1))
    assert not in_box(P, -np.inf, np.inf)[::17].any() and in_box(P, -np.inf, np.inf).sum() == 300 - len(P[::17])


def _root(parent, v):
    """A union-find's root of ``v``."""
    while parent[v] != v:
        v = parent[v]
    return v
