"""Which skin the PDE face covers does not hang on rounding (issue #35)."""
from dataclasses import replace

import numpy as np
from pdeface.assets import load_head
from pdeface.au.modelfile import load_face
from pdeface.geometry import ClosestPoint
from pdeface.head.bind import READ_BREAK_SLOPE, RESOLUTION, _read_pde
from pdeface.landmark_scheme import eye_distance
from pdeface.mesh import vertex_normals
from pdeface.surface.grid import grid_faces, surface_grid
from pdeface.surface.model import model_landmarks


def test_skin_beyond_an_openings_rim_is_covered_the_same_under_rounding_noise():
    # Skin beyond a rim (the lids' and lips' inner sides) is closest to a point on the rim's grid line, as near the
    # strip's triangle as the skin's: 1e-9 in the face's coefficients (what the vectorised operators' 4e-11 did)
    # once moved 16-22 of ICT's head's vertices across the cover's edge, and a blink with them.
    model = load_face("default")
    mesh, _ = load_head()
    T = mesh.triangles()[0]
    Vf = model.frame.to_face(mesh.vertices)
    N = vertex_normals(Vf, T)
    ed = eye_distance(model_landmarks(model))
    # the test means something: many vertices are closest to a rim's line
    X0 = surface_grid(model, *RESOLUTION, break_slope=READ_BREAK_SLOPE, confine=False)
    nu, nv, _ = X0.shape
    Q = grid_faces(nu, nv)
    Tp = np.concatenate([Q[:, [0, 1, 2]], Q[:, [0, 2, 3]]])
    dist, tri, bary, _ = ClosestPoint(X0.reshape(-1, 3), Tp).query(Vf)
    row = (bary * (Tp[tri] // nv)).sum(1)
    rims = np.array([r for k in model.layout.breaks() for r in (k * RESOLUTION[0], (k + 1) * RESOLUTION[0])])
    on_rim = (bary.min(1) < 1e-9) & (np.abs(row[:, None] - rims).min(1) < 1e-9) & (dist < 0.05 * ed)
    assert on_rim.sum() > 100

    covered, read = _read_pde(model, Vf, N, ed, RESOLUTION)
    rng = np.random.default_rng(0)
    for _ in range(3):
        noisy = replace(model,
                        coefficients=model.coefficients * (1 + 1e-9 * rng.standard_normal(model.coefficients.shape)))
        again, read_again = _read_pde(noisy, Vf, N, ed, RESOLUTION)
        assert (again == covered).all(), np.nonzero(again != covered)[0]
        assert abs(read_again - read).max() < 1e-6  # each covered vertex reads the same grid points


def test_skin_the_read_skips_is_farther_than_the_cover():
    """The read's exact query skips skin farther than the cover and 2/3 of the grid's longest edge from every grid
    vertex (issue #35): a point of a triangle lies that near one of its corners, so none of it is within the cover;
    on ICT's head it skips hundreds of vertices the edge bound before it queried."""
    from pdeface.geometry import row_norms
    from pdeface.head.bind import COVER_IOD

    model = load_face("default")
    mesh, _ = load_head()
    Vf = model.frame.to_face(mesh.vertices)
    ed = eye_distance(model_landmarks(model))
    X0 = surface_grid(model, *RESOLUTION, break_slope=READ_BREAK_SLOPE, confine=False)
    nu, nv, _ = X0.shape
    Q = grid_faces(nu, nv)
    Tp = np.concatenate([Q[:, [0, 1, 2]], Q[:, [0, 2, 3]]])
    X = X0.reshape(-1, 3)
    longest = max(row_norms(X[Tp[:, k]] - X[Tp[:, (k + 1) % 3]]).max() for k in range(3))
    edge = row_norms(X[Tp[:, 0]] - X[Tp[:, 1]]).max()  # the bound before
    closest = ClosestPoint(X, Tp)
    dist = closest.query(Vf)[0]
    gap = closest.vtree.query(Vf)[0]
    skipped = gap >= COVER_IOD * ed + 2 / 3 * longest
    assert (dist >= gap - 2 / 3 * longest - 1e-9).all()
    assert (dist[skipped] >= COVER_IOD * ed).all()
    assert (skipped & (gap < COVER_IOD * ed + edge)).sum() > 300


def test_the_reads_box_and_reach_skip_only_skin_the_cover_leaves(monkeypatch):
    """_read_pde queries only the skin within reach of the grid's box, each no farther than the reach (issue #35):
    with every point queried without bound, the cover and the read are the same."""
    import pdeface.head.bind as bind

    model = load_face("default")
    mesh, _ = load_head()
    Vf = model.frame.to_face(mesh.vertices)
    N = vertex_normals(Vf, mesh.triangles()[0])
    ed = eye_distance(model_landmarks(model))
    covered, read = _read_pde(model, Vf, N, ed, RESOLUTION)

    class Unbounded(ClosestPoint):  # its tree answers every point, whatever bound is asked
        def __init__(self, *args, **kwargs):
            super().__init__(*args, **kwargs)
            tree = self.vtree

            class Tree:
                def __getattr__(self, name):
                    return getattr(tree, name)

                def query(self, P, distance_upper_bound=np.inf, **kw):
                    return tree.query(P, **kw)
            self.vtree = Tree()

    monkeypatch.setattr(bind, "in_box", lambda P, lo, hi: np.ones(len(P), bool))
    monkeypatch.setattr(bind, "ClosestPoint", Unbounded)
    every_covered, every_read = _read_pde(model, Vf, N, ed, RESOLUTION)
    assert covered.sum() > 1000 and (every_covered == covered).all()
    assert abs(every_read - read).max() < 1e-12
