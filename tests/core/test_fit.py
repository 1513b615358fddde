import numpy as np
import pytest
from pdeface.errors import LandmarkError, MeshError
from pdeface.geometry import ClosestPoint
from pdeface.surface.fit import face_mesh, fit_face
from pdeface.surface.grid import surface_grid
from pdeface.surface.report import accuracy_report
from pdeface.surface.sampling import mesh_resolution, parse_resolution


def test_fit_is_accurate_on_the_ict_scan(scan, fitted):
    mesh, T, _ = scan
    model, _ = fitted
    r = accuracy_report(model, mesh.vertices, T)
    # issue #2 targets for the ICT neutral, smooth assembly (see scripts/bench/bench_fit.py)
    assert r["mean_mm"] <= 0.15 and r["p95_mm"] <= 0.6 and r["max_mm"] <= 3.0
    assert r["seam_max_deg"] <= 0.01
    # Skin normals by area (target 8°); per vertex the eye and nostril rings dominate.
    assert r["normal_p95_deg"] <= 8.0 < 12.0 < r["normal_p95_vertex_deg"]
    assert r["n_visible"] > 4000 and r["n_occluded"] > 0
    p = accuracy_report(model, mesh.vertices, T, "patches")
    assert p["seam_max_deg"] > 1.0  # the original patches crease where they meet


def test_mesh_drops_onto_the_scan_in_its_own_frame(scan, fitted):
    mesh, T, _ = scan
    model, _ = fitted
    pde = face_mesh(model)
    # in ICT's frame and unit (cm): every PDE vertex lies near the scan surface
    d = ClosestPoint(mesh.vertices, T).query(pde.vertices)[0]
    assert np.median(d) < 0.01  # cm
    rows, cols = mesh_resolution(model)  # steps per curve and per point interval, chosen for this face
    assert len(rows) == model.layout.n_curves - 1 and len(cols) == 36
    assert pde.vertices.shape == ((sum(rows) + 1) * (sum(cols) + 1), 3) and (pde.face_counts == 4).all()
    uniform = face_mesh(model, "4,4")
    assert uniform.vertices.shape == (((model.layout.n_curves - 1) * 4 + 1) * (36 * 4 + 1), 3)
    assert len(np.unique(pde.vertices.round(9), axis=0)) == len(pde.vertices)  # no duplicated seam vertices
    uv = pde.uvs[pde.face_uv_indices]
    assert uv.min() >= 0 and uv.max() <= 1
    # vertex order depends only on layout and resolution
    again = face_mesh(model)
    np.testing.assert_array_equal(again.face_indices, pde.face_indices)
    orig = face_mesh(model, "original", "patches")
    assert orig.vertices.shape == (((model.layout.n_curves - 1) * 10 + 1) * 37, 3)


def test_the_methods_31_curves_give_its_10_patches(scan):
    mesh, T, idx = scan
    model, _ = fit_face(mesh.vertices, T, mesh.vertices[idx], unit="cm", n_curves=31)
    assert model.layout.n_curves == 31 and len(model.layout.breaks()) == 2
    orig = face_mesh(model, "original", "patches")  # 10 patches of 4 curves, 31 rows each
    assert orig.vertices.shape == ((10 * 30 + 1) * 37, 3)
    r = accuracy_report(model, mesh.vertices, T)
    assert r["p95_mm"] <= 0.6 and r["seam_max_deg"] <= 0.01


def test_fit_in_another_pose_and_unit_gives_the_same_face(scan, fitted, rng):
    mesh, T, idx = scan
    model, _ = fitted
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    q *= np.sign(np.linalg.det(q))
    V = mesh.vertices * 10 @ q.T + 100  # mm, rotated, moved
    m2, _ = fit_face(V, T, V[idx])
    assert m2.frame.unit == "mm"
    np.testing.assert_allclose(surface_grid(m2), surface_grid(model), atol=1e-6)
    np.testing.assert_allclose(face_mesh(m2).vertices, face_mesh(model).vertices * 10 @ q.T + 100, atol=1e-6)


def test_fit_rejects_bad_input(scan):
    mesh, T, idx = scan
    V = mesh.vertices.copy()
    with pytest.raises(MeshError, match="finite"):
        fit_face(np.where(np.arange(len(V))[:, None] == 5, np.nan, V), T, V[idx])
    with pytest.raises(MeshError, match="no faces"):
        fit_face(V, np.zeros((0, 3), int), V[idx])
    with pytest.raises(LandmarkError):
        fit_face(V, T, V[idx][:60])


def test_resolution_parsing():
    assert parse_resolution("original") == (10, 1)
    assert parse_resolution("3,5") == (3, 5)
    with pytest.raises(MeshError, match="resolution"):
        parse_resolution("big")
    with pytest.raises(MeshError, match="1..64"):
        parse_resolution((0, 4))


def test_profiles_are_written(tmp_path, scan, fitted):
    mesh, T, _ = scan
    model, _ = fitted
    accuracy_report(model, mesh.vertices, T, profiles_png=tmp_path / "p.png", profiles_csv=tmp_path / "p.csv")
    assert (tmp_path / "p.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    rows = (tmp_path / "p.csv").read_text().splitlines()
    assert rows[0].startswith("cut,i,angle_deg") and len(rows) == 1 + 3 * 60
    cuts = {r.split(",")[0] for r in rows[1:]}
    assert cuts == {"horizontal", "vertical", "diagonal"}
    diff = np.array([float(r.split(",")[-1]) for r in rows[1:] if r.split(",")[-1] != "nan"])
    assert np.median(np.abs(diff)) < 0.5  # mm: the PDE profile follows the scan's


def test_butterfly_step_interpolates_and_keeps_cubics():
    """Old vertices stay; on a regular grid the new edge points of a cubic height field lie on it (the
    butterfly's cubic precision), where plain midpoints miss by the surface's bend."""
    from pdeface.mesh import butterfly_step

    n = 9
    x, y = np.meshgrid(np.arange(n, dtype=float), np.arange(n, dtype=float))
    f = lambda x, y: 0.05 * x ** 3 - 0.1 * x * y + 0.2 * y ** 2  # noqa: E731
    V = np.stack([x.ravel(), y.ravel(), f(x, y).ravel()], 1)
    i = (np.arange(n - 1)[:, None] * n + np.arange(n - 1)[None, :]).ravel()
    T = np.concatenate([np.stack([i, i + 1, i + n + 1], 1), np.stack([i, i + n + 1, i + n], 1)])  # regular: valence 6
    S, T_fine = butterfly_step(len(V), T)
    P = S @ V
    np.testing.assert_array_equal(P[:len(V)], V)
    assert len(T_fine) == 4 * len(T) and T_fine.max() == len(P) - 1
    inner = (P[:, :2].min(1) >= 2) & (P[:, :2].max(1) <= n - 3)  # full stencils there
    new = np.arange(len(P)) >= len(V)
    np.testing.assert_allclose(P[new & inner, 2], f(P[new & inner, 0], P[new & inner, 1]), atol=1e-12)
    edges_mid = 0.5 * (V[T[:, 0]] + V[T[:, 1]])
    assert np.abs(edges_mid[:, 2] - f(edges_mid[:, 0], edges_mid[:, 1])).max() > 0.01  # midpoints miss


def test_a_low_poly_face_is_read_off_a_smooth_surface():
    """MediaPipe's 468-point face (7.8 mm edges, curves 4.8 mm apart) is read off two butterfly steps: the
    curves stay linear in its own vertices, and the PDE face lies nearer the true (full-resolution) scan than
    the low-poly mesh's own facets do (read off the facets: median 0.32 mm, against the facets' 0.22)."""
    from pdeface.assets import load_low_poly_face, load_neutral_scan

    low, L = load_low_poly_face()
    T = low.triangles()[0]
    model, sampler = fit_face(low.vertices, T, L, unit="cm")
    assert sampler.matrix.shape[1] == len(low.vertices)
    np.testing.assert_allclose(sampler.sample(model.frame.to_face(low.vertices)), model.curve_points(), atol=0.05)
    scan, _ = load_neutral_scan()
    truth = ClosestPoint(scan.vertices, scan.triangles()[0])
    P = face_mesh(model).vertices
    P = P[ClosestPoint(low.vertices, T).query(P)[0] < 0.1]  # over the low-poly mesh (cm)
    b = np.array([[1 / 3, 1 / 3, 1 / 3], [0.5, 0.25, 0.25], [0.25, 0.5, 0.25], [0.25, 0.25, 0.5]])
    facets = np.einsum("pk,tkc->tpc", b, low.vertices[T]).reshape(-1, 3)
    assert np.median(truth.query(P)[0]) < np.median(truth.query(facets)[0])
