"""Facial Deformation Tables: the quadratic model, the pupil frame, regions, files, fit/apply/classify."""
import gzip
import json
from dataclasses import replace

import numpy as np
import pytest
from pdeface.assets import load_ict_shapes
from pdeface.au.aureport import MotionProbe
from pdeface.au.expressions import mix
from pdeface.au.ict import au_offsets
from pdeface.au.modelfile import load_face
from pdeface.cli import main
from pdeface.errors import LandmarkError, ModelFormatError, PdeFaceError
from pdeface.fdt import quadratic
from pdeface.fdt.deform import NeutralFace, classify, fdt_curves, fdt_descriptor
from pdeface.fdt.regions import (
    N_REGIONS,
    REACH,
    PupilFrame,
    normalise_2d,
    opening_sides,
    region_weights,
    seed_distances,
)
from pdeface.fdt.table import FDT, generic, load_fdt, load_generic_fdts, parse_fdts, read_fdt, write_fdts
from pdeface.io.meshio import read_obj, write_obj
from pdeface.mesh import Mesh
from pdeface.surface.model import model_landmarks


@pytest.mark.parametrize("model", quadratic.MODELS)
def test_known_quadratic_recovered_exactly(model, rng):
    P = rng.uniform(-2, 2, size=(200, 3))
    truth = quadratic.identity(model) + rng.normal(scale=0.05, size=len(quadratic.PARAMETERS[model]))
    Q = quadratic.transform(model, truth, P)
    assert np.abs(Q - P).max() > 0.01  # it does move them
    np.testing.assert_allclose(quadratic.fit(model, P, Q), truth, atol=1e-9)
    np.testing.assert_allclose(quadratic.transform(model, quadratic.identity(model), P), P, atol=1e-12)


@pytest.mark.parametrize("model", quadratic.MODELS)
def test_hard_regions_fit_as_the_papers_independent_normal_equations(model, rng):
    P = rng.uniform(-2, 2, size=(600, 3))
    region = rng.integers(0, 4, len(P))
    W = np.eye(4)[region]
    Q = P + rng.normal(scale=0.05, size=P.shape)
    joint = quadratic.BlendedEquations(model, P, W).solve(Q)
    for r in range(4):
        np.testing.assert_allclose(joint[r], quadratic.fit(model, P[region == r], Q[region == r]), atol=1e-9)


@pytest.mark.parametrize("model", quadratic.MODELS)
def test_blended_regions_are_recovered_exactly(model, rng):
    """Points moved by several regions' transforms blended with weights: the joint fit finds each transform."""
    P = rng.uniform(-2, 2, size=(800, 3))
    W = rng.dirichlet(np.full(3, 0.5), size=len(P))
    truth = quadratic.identity(model) + rng.normal(scale=0.05, size=(3, len(quadratic.PARAMETERS[model])))
    Q = P + sum(W[:, [r]] * (quadratic.transform(model, truth[r], P) - P) for r in range(3))
    np.testing.assert_allclose(quadratic.BlendedEquations(model, P, W).solve(Q), truth, atol=1e-8)


def test_fit_refuses_points_that_cannot_determine_it(rng):
    P = np.zeros((50, 3))
    P[:, 0] = rng.uniform(-1, 1, 50)  # all on a line
    with pytest.raises(PdeFaceError, match="do not determine"):
        quadratic.fit("2d", P, P)
    with pytest.raises(PdeFaceError, match="do not determine"):
        quadratic.fit("3d", P[:5], P[:5])


def test_paper_normalisation_2d_is_invariant(rng):
    pts = rng.normal(size=(30, 2))
    p1, p2 = np.array([-0.8, 0.1]), np.array([1.1, 0.3])
    ref = normalise_2d(pts, p1, p2)
    np.testing.assert_allclose(normalise_2d([p1, p2], p1, p2), [[-1, 0], [1, 0]], atol=1e-12)
    a, s, t = 0.7, 3.5, np.array([10.0, -4.0])
    R = np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])
    move = lambda X: s * np.asarray(X) @ R.T + t  # noqa: E731
    np.testing.assert_allclose(normalise_2d(move(pts), move(p1), move(p2)), ref, atol=1e-12)
    with pytest.raises(LandmarkError, match="coincide"):
        normalise_2d(pts, p1, p1)


def test_pupil_frame_is_invariant_to_pose_scale_and_unit(scan, rng, rotation):
    mesh, _, idx = scan
    V = mesh.vertices
    frame = PupilFrame.from_landmarks(V[idx])
    ref = frame.normalise(V)
    pupils = frame.normalise(np.stack([V[idx[36:42]].mean(0), V[idx[42:48]].mean(0)]))
    np.testing.assert_allclose(pupils, [[-1, 0, 0], [1, 0, 0]], atol=1e-12)
    R, s, t = rotation, 10.0, rng.normal(size=3) * 50  # cm → mm, turned and moved
    W = s * V @ R.T + t
    np.testing.assert_allclose(PupilFrame.from_landmarks(W[idx]).normalise(W), ref, atol=1e-9)
    np.testing.assert_allclose(frame.to_source(ref), V, atol=1e-9)


def test_region_weights_partition_blend_and_fade(scan):
    mesh, _, idx = scan
    frame = PupilFrame.from_landmarks(mesh.vertices[idx])
    L = frame.normalise(mesh.vertices[idx])
    xy = np.stack(np.meshgrid(np.linspace(-2.5, 2.5, 120), np.linspace(-3.5, 2.5, 140)), -1).reshape(-1, 2)
    W = region_weights(xy, L)
    total = W.sum(1)
    assert W.shape == (len(xy), N_REGIONS) and (W >= 0).all()
    nearest = seed_distances(xy, L).min(1)
    near_face = nearest <= REACH[0]
    assert near_face.mean() > 0.3
    np.testing.assert_allclose(total[near_face], 1.0, atol=1e-12)  # a partition of unity on the face
    assert total[nearest >= REACH[1]].max() == 0 and (nearest >= REACH[1]).any()  # nothing moves beyond it
    # Continuous away from the openings' own lines: neighbouring samples differ little.
    grid = W.reshape(140, 120, N_REGIONS)
    sides = opening_sides(xy, L).reshape(140, 120, -1)
    same = (sides[:, 1:] == sides[:, :-1]).all(-1)
    assert np.abs(grid[:, 1:] - grid[:, :-1]).max(-1)[same].max() < 0.6
    hard = region_weights(xy, L, blend=0)  # one region each
    assert set(np.unique(hard.max(1)[near_face])) == {1.0}


def test_lips_never_take_each_others_motion(scan):
    """Inside the mouth's span a point above the mouth line has no weight of the lower lip or chin."""
    mesh, _, idx = scan
    frame = PupilFrame.from_landmarks(mesh.vertices[idx])
    L = frame.normalise(mesh.vertices[idx])
    knots = np.array([L[48, :2], L[[62, 66], :2].mean(0), L[54, :2]])
    x = np.array([0.0, 0.0, 0.3, 0.3])
    pts = np.column_stack([x, np.interp(x, knots[:, 0], knots[:, 1]) + [0.005, -0.005, 0.005, -0.005]])
    W = region_weights(pts, L)
    assert W[[0, 2]][:, [12, 15]].max() == 0  # above: no lower lip (13) or chin (16)
    assert W[[1, 3]][:, 11].max() == 0  # below: no upper lip (12)


def test_paper_table_i_smiles_on_the_default_face():
    """The paper's generic smile (its Table I, 2-D) lifts and widens the mouth corners of the default face."""
    face = load_face("default")
    smile = load_fdt("paper-smile")
    assert smile.model == "2d" and smile.mean.shape == (16, 12) and smile.subjects == 12
    C, R = fdt_curves(face, smile)
    X0 = face.curve_points().reshape(-1, 3)
    D = (face.curve_points(face.coefficients + C, face.residual + R).reshape(-1, 3) - X0)
    L = model_landmarks(face)
    at = {k: D[np.argmin(np.linalg.norm(X0 - L[k], axis=1))] for k in (48, 54, 22)}
    for corner, outward in ((48, -1), (54, 1)):
        assert at[corner][1] > 3.0  # up, mm
        assert at[corner][0] * outward > 3.0  # out
    assert np.linalg.norm(at[22]) < np.linalg.norm(at[48]) / 2  # the brows move much less


def test_own_fdt_captures_most_of_an_au_and_is_a_linear_key(scan, fitted):
    mesh, T, idx = scan
    model, _ = fitted
    shapes = load_ict_shapes()
    V = mesh.vertices
    face = NeutralFace(V, T, V[idx])
    probe = MotionProbe(model, V, T)
    for key, floor in (("12", 0.8), ("27", 0.75)):
        fit = face.fit(V + au_offsets(key, shapes), "3d", key)
        C, R = fdt_curves(model, fit.fdt)
        assert probe.measure(C, R, au_offsets(key, shapes))["captured"] > floor
        C2, _ = fdt_curves(model, fit.fdt, weight=0.5)
        np.testing.assert_allclose(C2, 0.5 * C, atol=1e-12)
        d = fdt_descriptor(model, fit.fdt)
        assert d.key == key and d.source.startswith("fdt 3d") and len(d.curves) > 0
        dC, _ = mix({d.key: d}, {d.key: 1.0})
        np.testing.assert_allclose(dC[d.curves], C[d.curves], atol=1e-12)
    two_d = face.fit(V + au_offsets("12", shapes), "2d").fdt
    assert np.abs(fdt_curves(model, two_d)[0][..., 2]).max() < 1e-9  # the 2-D table never moves depth
    surface = face.fit(V + au_offsets("12", shapes), "3d-surface").fdt
    np.testing.assert_allclose(surface.as_2d().mean, two_d.mean, atol=1e-9)  # its x', y' are the paper's
    with pytest.raises(PdeFaceError, match="not named by an AU"):
        fdt_descriptor(model, load_fdt("happy"))


def test_blend_zero_is_the_papers_fit_region_by_region(scan):
    mesh, T, idx = scan
    shapes = load_ict_shapes()
    V = mesh.vertices
    face = NeutralFace(V, T, V[idx], blend=0)
    fit = face.fit(V + au_offsets("12", shapes), "2d")
    assert fit.fdt.blend == 0
    for r, rows in fit.members.items():
        np.testing.assert_allclose(fit.fdt.mean[r], quadratic.fit("2d", fit.neutral[rows], fit.posed[rows]),
                                   atol=1e-9)
    blended = NeutralFace(V, T, V[idx]).fit(V + au_offsets("12", shapes), "2d").fdt
    assert blended.blend == 0.2 and not np.allclose(blended.mean, fit.fdt.mean, atol=1e-3)
    with pytest.raises(PdeFaceError, match="blends"):
        generic([fit.fdt, blended])


def test_neutral_face_checks_its_input(scan):
    mesh, T, idx = scan
    face = NeutralFace(mesh.vertices, T, mesh.vertices[idx])
    with pytest.raises(PdeFaceError, match="same vertices"):
        face.fit(mesh.vertices[:-1])
    bad = mesh.vertices.copy()
    bad[face.keep[0]] = np.nan
    with pytest.raises(PdeFaceError, match="NaN"):
        face.fit(bad)
    with pytest.raises(PdeFaceError, match="too few"):  # landmarks away from the mesh: regions left empty
        NeutralFace(mesh.vertices, T, mesh.vertices[idx] * 3)


def test_generic_mean_and_sigma(rng):
    a = FDT("x", "2d", rng.normal(size=(16, 12)))
    b = FDT("x", "2d", rng.normal(size=(16, 12)))
    g = generic([a, b])
    np.testing.assert_allclose(g.mean, (a.mean + b.mean) / 2)
    np.testing.assert_allclose(g.sigma, np.abs(a.mean - b.mean) / 2)
    assert g.subjects == 2
    with pytest.raises(PdeFaceError, match="models"):
        generic([a, FDT("x", "3d", np.zeros((16, 30)))])


def test_files_round_trip_and_table_i_csv(tmp_path, rng):
    t = FDT("happy", "3d", rng.normal(size=(16, 30)), np.abs(rng.normal(size=(16, 30))), 20, "test", "n")
    for name in ("t.fdt.json", "t.json.gz"):
        write_fdts(tmp_path / name, [t])
        back = read_fdt(tmp_path / name)
        np.testing.assert_allclose(back.mean, t.mean, atol=1e-4)
        assert (back.name, back.model, back.subjects, back.notice) == ("happy", "3d", 20, "n")
    write_fdts(tmp_path / "t.csv", [FDT("s", "2d", t.mean[:, :12])])
    rows = (tmp_path / "t.csv").read_text().splitlines()
    assert rows[0] == "region,a1,a2,a3,a4,a5,a6,b1,b2,b3,b4,b5,b6" and rows[16].startswith("16,") and len(rows) == 17
    with pytest.raises(PdeFaceError, match="no 2-D part"):
        t.as_2d()


GOOD = {"format": "pdeface.fdt", "version": 1, "name": "x", "model": "2d", "mean": [[0.0] * 12] * 16}


@pytest.mark.parametrize("change, message", [
    ({"format": "other"}, "not a pdeface FDT"),
    ({"version": 9}, "version 9"),
    ({"model": "4d"}, "model '4d' unknown"),
    ({"name": ""}, "'name'"),
    ({"mean": [[0.0] * 12] * 15}, "16 regions"),
    ({"mean": [[0.0] * 11] * 16}, "12 parameters"),
    ({"mean": [["a"] * 12] * 16}, "not a finite number"),
    ({"mean": "no"}, "rows of numbers"),
    ({"sigma": [[-1.0] * 12] * 16}, "negative"),
    ({"subjects": 0}, "positive integer"),
    ({"parameters": ["a1"]}, "parameters"),
    ({"blend": -1}, "'blend'"),
    ({"blend": "wide"}, "'blend'"),
])
def test_malformed_fdt_files_get_clear_errors(tmp_path, change, message):
    p = tmp_path / "bad.fdt.json"
    p.write_text(json.dumps({**GOOD, **change}))
    with pytest.raises(ModelFormatError, match=message):
        read_fdt(p)


def test_broken_files(tmp_path):
    (tmp_path / "a.json").write_text("{not json")
    with pytest.raises(ModelFormatError, match="not valid JSON"):
        read_fdt(tmp_path / "a.json")
    (tmp_path / "b.json.gz").write_bytes(b"plain")
    with pytest.raises(ModelFormatError, match="gzip"):
        read_fdt(tmp_path / "b.json.gz")
    with pytest.raises(ModelFormatError, match="non-empty list"):
        parse_fdts({"format": "pdeface.fdts", "version": 1, "fdts": []})
    write_fdts(tmp_path / "two.json", [FDT("a", "2d", np.zeros((16, 12))), FDT("b", "2d", np.zeros((16, 12)))])
    with pytest.raises(ModelFormatError, match="holds 2 FDTs"):
        read_fdt(tmp_path / "two.json")


def test_bundled_generic_tables():
    tables = load_generic_fdts("3d")
    face = load_face("default")
    for d in face.descriptors:  # every bundled AU ICT has truth for (not the muscle-made), and the six expressions
        if d.source == "muscle":
            continue
        assert d.key in tables and tables[d.key].subjects == 20 and tables[d.key].sigma is not None
    for name in ("happy", "sad", "disgust", "surprise", "anger", "fear"):
        assert name in tables and name in load_generic_fdts("2d")
    assert "ICT-FaceKit" in tables["happy"].notice


def test_classify_names_a_smile_happy(scan):
    mesh, T, idx = scan
    V = mesh.vertices
    shapes = load_ict_shapes()
    six = [load_fdt(n) for n in ("happy", "sad", "disgust", "surprise", "anger", "fear")]
    face = NeutralFace(V, T, V[idx])
    for w in (0.5, 1.0):
        posed = V + w * (au_offsets("12", shapes) + 0.3 * au_offsets("6", shapes))
        ranking = classify(face.fit(posed, "3d"), six)
        assert ranking[0]["name"] == "happy"
        assert ranking[0]["distance"] < ranking[1]["distance"] and 0 < ranking[0]["intensity"] <= 1.25
        assert len(ranking[0]["regions"]) == 16 and 0 <= ranking[0]["inside"] <= 1
    with pytest.raises(PdeFaceError, match="does not move"):
        classify(face.fit(V), six)


def run(capsys, *args):
    code = main([str(a) for a in args])
    out = capsys.readouterr()
    return code, out.out, out.err


def test_cli_fit_mean_apply_classify(tmp_path, capsys, scan):
    mesh, _, idx = scan
    shapes = load_ict_shapes()
    write_obj(tmp_path / "n.obj", mesh)
    write_obj(tmp_path / "smile.obj", replace(mesh, vertices=mesh.vertices + au_offsets("12", shapes)))
    (tmp_path / "l.json").write_text(json.dumps({"indices": idx.tolist()}))
    code, out, err = run(capsys, "fdt", "fit", tmp_path / "n.obj", tmp_path / "smile.obj", "--landmarks",
                         tmp_path / "l.json", "--name", "12", "-o", tmp_path / "s.fdt.json")
    assert code == 0 and json.loads(out)["model"] == "3d", err
    assert run(capsys, "fdt", "fit", tmp_path / "n.obj", tmp_path / "smile.obj", "--landmarks", tmp_path / "l.json",
               "--2d", "-o", tmp_path / "s.csv")[0] == 0
    assert (tmp_path / "s.csv").read_text().startswith("region,a1")
    code, out, _ = run(capsys, "fdt", "mean", tmp_path / "s.fdt.json", tmp_path / "s.fdt.json", "-o", tmp_path / "m.fdt.json")
    assert code == 0 and json.loads(out)["subjects"] == 2
    assert run(capsys, "fdt", "apply", "default", tmp_path / "m.fdt.json", "-o", tmp_path / "face.obj")[0] == 0
    assert run(capsys, "fdt", "apply", "default", "happy", "--weight", "0.5", "-o", tmp_path / "happy.obj")[0] == 0
    neutral = read_obj(tmp_path / "face.obj")
    assert len(neutral.vertices) == len(read_obj(tmp_path / "happy.obj").vertices)
    code, out, _ = run(capsys, "fdt", "classify", "default", tmp_path / "smile.obj", "--json")
    assert code == 0 and json.loads(out)["best"] == "happy"
    code, _, err = run(capsys, "fdt", "apply", "default", "nonsense", "-o", tmp_path / "x.obj")
    assert code == 2 and "neither an FDT file nor a bundled FDT" in err
    with pytest.raises(SystemExit) as exc:  # refused at parse time
        run(capsys, "fdt", "apply", "default", "happy", "--weight", "2", "-o", tmp_path / "x.obj")
    assert exc.value.code == 2 and "argument --weight: '2' is not in [0, 1]" in capsys.readouterr().err
    (tmp_path / "bad.fdt.json").write_text("[]")
    code, _, err = run(capsys, "fdt", "apply", "default", tmp_path / "bad.fdt.json", "-o", tmp_path / "x.obj")
    assert code == 2 and "JSON object" in err
    assert not (tmp_path / "x.obj").exists()
    mesh2 = Mesh.from_faces(mesh.vertices[:100], np.array([[0, 1, 2]]))
    write_obj(tmp_path / "small.obj", mesh2)
    code, _, err = run(capsys, "fdt", "fit", tmp_path / "n.obj", tmp_path / "small.obj", "--landmarks",
                       tmp_path / "l.json", "-o", tmp_path / "y.fdt.json")
    assert code == 2 and "same vertices" in err


def test_bundle_is_gzip_json():
    from pdeface.assets import GENERIC_FDTS, asset_path
    data = json.loads(gzip.decompress(asset_path(GENERIC_FDTS).read_bytes()))
    assert data["format"] == "pdeface.fdts" and {t["model"] for t in data["fdts"]} == {"2d", "3d"}


def test_fdt_of_a_posed_face_model_reproduces_its_pose():
    """From a face model and AU weights (its PDE surface neutral against posed), applied back to the model."""
    from pdeface.fdt.deform import fdt_curve_displacement, fit_fdt_model

    face = load_face("default")
    fit = fit_fdt_model(face, {"12": 1.0}, name="12")
    assert fit.fdt.name == "12" and fit.fdt.model == "3d"
    d = next(d for d in face.descriptors if d.key == "12")
    C, R = d.dense()
    truth = face.curve_points(face.coefficients + C, face.residual + R) - face.curve_points()
    moved = np.linalg.norm(truth, axis=-1) > 0.5
    got = fdt_curve_displacement(face, fit.fdt)
    err = np.linalg.norm(got - truth, axis=-1)[moved]
    assert 1 - np.sqrt((err ** 2).mean()) / np.sqrt((np.linalg.norm(truth, axis=-1)[moved] ** 2).mean()) > 0.7
