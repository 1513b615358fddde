"""Waters muscles: each type moves points as its equation says; placement, calibration, the table, the FAS mixers."""
import json

import numpy as np
import pytest
from pdeface.au.modelfile import load_face
from pdeface.errors import LandmarkError, ModelFormatError, PdeFaceError
from pdeface.muscles.aus import (
    MuscleBasis,
    MuscleTable,
    activation_vector,
    mix_activations,
    parse_activations,
    parse_table,
)
from pdeface.muscles.model import Jaw, LinearMuscle, Sheet, Sphincter
from pdeface.muscles.placement import MUSCLE_NAMES, place_muscles
from pdeface.surface.model import model_landmarks

from scripts.build.build_muscles import save_fields, table_to_json


def test_linear_muscle_pulls_along_its_line_towards_the_head_and_stops_at_its_fall_off():
    m = LinearMuscle("m", head=np.zeros(3), insertion=np.array([0, -40.0, 0]), zone_deg=30, fall_start=40,
                     fall_end=60, pull_mm=5.0)
    P = np.array([[0, -40.0, 0], [0, -20.0, 0], [0, -70.0, 0], [30, -40.0, 0], [0, 10.0, 0], [0, 0, 0]])
    D = m.displacement(P)
    np.testing.assert_allclose(D[0], [0, 5.0, 0], atol=1e-12)  # at Rs on the line: the full pull, towards the head
    assert 0 < D[1, 1] < 5 and D[1, 0] == 0  # nearer the head: less (cos ramp), same direction
    np.testing.assert_allclose(D[2:], 0, atol=1e-12)  # beyond Rf, outside the zone, behind the head, at the head
    off = m.displacement(np.array([[10.0, -40, 0]]))[0]  # inside the zone, off the line: less, still towards the head
    assert 0 < np.linalg.norm(off) < 5 and np.dot(off, -np.array([10.0, -40, 0])) > 0


def test_sphincters_close_on_their_centre_or_axis():
    mouth = Sphincter("o", np.zeros(3), (20.0, 10.0), 0.5)
    D = mouth.displacement(np.array([[10.0, 0, 0], [0, 5.0, 0], [0, 0, 0], [30.0, 0, 0]]))
    assert D[0, 0] < 0 and D[1, 1] < 0 and abs(D[0, 1]) < 1e-12  # towards the centre
    np.testing.assert_allclose(D[2:], 0, atol=1e-12)  # the centre and beyond the ellipse stay
    eye = Sphincter("e", np.zeros(3), (20.0, 10.0), 0.5, to_axis=True)
    D = eye.displacement(np.array([[10.0, 5.0, 0], [10.0, -5.0, 0]]))
    assert D[0, 1] < 0 < D[1, 1] and np.all(D[:, 0] == 0)  # lids close on the horizontal axis: a squint


def test_sheet_pulls_its_fibres_towards_its_edge():
    s = Sheet("s", np.zeros(3), np.array([0, -1.0, 0]), 20.0, 10.0, 4.0)
    D = s.displacement(np.array([[0, -20.0, 0], [0, -10.0, 0], [0, 5.0, 0], [15.0, -20, 0], [0, -40.0, 0]]))
    np.testing.assert_allclose(D[0], [0, 4.0, 0], atol=1e-12)
    assert 0 < D[1, 1] < 4
    np.testing.assert_allclose(D[2:], 0, atol=1e-12)  # behind the edge, beyond the width, past the fibres
    nose = Sheet("n", np.zeros(3), np.array([1.0, 0, 0]), 10.0, 5.0, 2.0, mirrored=True)
    D = nose.displacement(np.array([[10.0, 0, 0], [-10.0, 0, 0]]))
    np.testing.assert_allclose(D, [[-2, 0, 0], [2, 0, 0]], atol=1e-12)  # both wings towards the midline


def test_jaw_turns_the_chin_down_and_back_and_leaves_the_upper_face():
    jaw = Jaw("jaw", np.array([0, 0, -80.0]), 20.0, lip_lower_y=-50, mouth_y=-40)
    D = jaw.displacement(np.array([[0, -80.0, 10], [0, 20.0, 10]]))
    assert D[0, 1] < 0 and D[0, 2] < 0
    np.testing.assert_allclose(D[1], 0)


def test_the_24_muscles_placed_on_the_default_face():
    face = load_face("default")
    muscles = place_muscles(model_landmarks(face))
    assert [m.name for m in muscles] == list(MUSCLE_NAMES) and len(MUSCLE_NAMES) == 24
    kinds = [m.kind for m in muscles]
    assert kinds.count("linear") == 18 and kinds.count("sphincter") == 3 and kinds.count("sheet") == 2
    right, left = muscles[MUSCLE_NAMES.index("zygomatic_major_R")], muscles[MUSCLE_NAMES.index("zygomatic_major_L")]
    assert right.insertion[0] < 0 < left.insertion[0]  # the subject's right is −x
    np.testing.assert_allclose(right.head * [-1, 1, 1], left.head, atol=3.0)  # a near-symmetric face
    from pdeface.surface.grid import surface_grid
    skin = surface_grid(face, 2, 2).reshape(-1, 3)
    for m in muscles:
        if m.kind == "linear" and m.head[1] < skin[:, 1].max() - 10:  # (the frontalis' are above the face)
            front = skin[np.argmin(np.linalg.norm(skin[:, :2] - m.head[:2], axis=1))]
            assert m.head[2] < front[2] - 3, m.name
    L = model_landmarks(face)
    L[48] = np.nan
    with pytest.raises(LandmarkError, match="48"):
        place_muscles(L)


def test_calibration_recovers_known_activations():
    face = load_face("default")
    basis = MuscleBasis(face, MuscleTable({}))  # Waters' fields, default shapes
    assert not basis.learned and basis.fields is basis.waters
    truth = np.zeros(24)
    truth[[MUSCLE_NAMES.index(n) for n in ("zygomatic_major_R", "zygomatic_major_L", "orbicularis_oris")]] = \
        [0.8, 0.7, -0.3]
    np.testing.assert_allclose(basis.calibrate(basis.displacement(truth)), truth, atol=1e-6)
    d = basis.descriptor("12", truth)
    assert d.key == "12" and d.source == "muscle" and len(d.curves) > 0


def test_fas_mixers_on_the_papers_worked_example():
    """The FAS paper's Tables 2 and 3: three AUs' activations of three muscles, averaged and maximised."""
    names = ["zygomatic_major_L", "depressor_anguli_oris_L", "frontalis_inner_L"]
    rows = {"a": [1.2, 0.8, 0.0], "b": [0.0, 0.2, 0.0], "c": [0.6, 1.4, 0.9]}
    table = {k: activation_vector(dict(zip(names, v))) for k, v in rows.items()}
    idx = [MUSCLE_NAMES.index(n) for n in names]
    avg = mix_activations(table, {"a": 1, "b": 1, "c": 1}, "muscle-average")[idx]
    mx = mix_activations(table, {"a": 1, "b": 1, "c": 1}, "muscle-max")[idx]
    np.testing.assert_allclose(avg, [0.9, 0.8, 0.9])  # zygomatic: (1.2 + 0.6) / 2 AUs that use it
    np.testing.assert_allclose(mx, [1.2, 1.4, 0.9])
    half = mix_activations(table, {"a": 0.5}, "muscle-max")[idx]
    np.testing.assert_allclose(half, [0.6, 0.4, 0.0])  # AU weights scale the activations first
    with pytest.raises(PdeFaceError, match="no AU"):
        mix_activations(table, {"d": 1}, "muscle-max")
    with pytest.raises(PdeFaceError, match="no muscle"):
        activation_vector({"bicep": 1})
    with pytest.raises(PdeFaceError, match="outside"):
        activation_vector({"jaw": -1})


def test_table_file_is_validated():
    table = {"12": np.linspace(0, 1, 24) * 0 + 0.5}
    good = table_to_json(table, {"12": "calibrated"})
    back = parse_table(json.loads(json.dumps(good)))
    np.testing.assert_allclose(back.activations["12"], 0.5)
    assert back.hows["12"] == "calibrated"
    for change, message in (({"format": "x"}, "not a pdeface muscle table"), ({"version": 3}, "version"),
                            ({"muscles": ["a"]}, "24 muscles"), ({"aus": {}}, "non-empty"),
                            ({"aus": {"12": {"activations": [0.5] * 23}}}, "24 finite"),
                            ({"aus": {"12": {"activations": [5.0] * 24}}}, "outside"),
                            ({"aus": {"foo": {"activations": [0.0] * 24}}}, "not an AU key"),
                            ({"geometry": {"zygomatic_major": {"zone": "wide"}}}, "geometry"),
                            ({"geometry": {"biceps": {}}}, "geometry"), ({"fields": "../x.npz"}, "beside"),
                            ({"fields": 3}, "beside"), ({"fields": "none.npz"}, "not found")):
        with pytest.raises(ModelFormatError, match=message):
            parse_table({**good, **change})
    assert parse_table({**good, "version": 1}).fields is None  # the first format: Waters' fields alone


def test_learned_fields_file_round_trip_and_checks(tmp_path):
    from pdeface.muscles.fields import LearnedFields, load_fields

    C = np.zeros((24, 4, 5, 3))
    C[3, 1, 2] = [0.5, -1.25, 2.0]
    save_fields(tmp_path / "f.npz", LearnedFields(C, np.array([90.0, 110, 100]), "notice"))
    back = load_fields(tmp_path / "f.npz")
    np.testing.assert_allclose(back.corrections, C, atol=1e-3)
    assert back.layout == (4, 5) and back.notice == "notice"
    good = table_to_json({"12": np.full(24, 0.5)}, {"12": ""}, fields="f.npz")
    assert parse_table(good, folder=tmp_path).fields.layout == (4, 5)
    np.savez(tmp_path / "bad.npz", format="pdeface.muscle-fields", muscles=np.array(MUSCLE_NAMES),
             corrections=np.full((24, 4, 5, 3), np.nan), face_size=[1.0, 1, 1])
    (tmp_path / "junk.npz").write_bytes(b"not a zip")
    for name, message in (("bad.npz", "finite"), ("junk.npz", "not a muscle fields file")):
        with pytest.raises(ModelFormatError, match=message):
            load_fields(tmp_path / name)


def test_learning_recovers_known_fields_within_each_muscles_reach():
    """Targets made by known corrections (inside the reach) and activations: the learned pair matches them
    far better than Waters' fields alone, and corrects nothing outside the reach."""
    from pdeface.muscles.fields import learn_corrections

    rng = np.random.default_rng(1)
    n_muscles, n = 24, 60
    W = rng.normal(size=(n_muscles, n))
    mask = rng.random((n_muscles, n)) < 0.3
    C_true = np.where(mask, rng.normal(size=(n_muscles, n)), 0.0)
    A_true = np.clip(rng.random((40, n_muscles)) - 0.5, 0, 2)  # sparse, within every muscle's bounds
    T = A_true @ (W + C_true)
    A0 = np.full_like(A_true, 0.2)
    C, A = learn_corrections(W, T, A0, mask, ridge=1e-6, rounds=80)
    assert np.all(C[~mask] == 0)
    rel = lambda P: np.sqrt(((P - T) ** 2).mean()) / np.sqrt((T ** 2).mean())  # noqa: E731
    from pdeface.muscles.placement import BOUNDS
    from scipy.optimize import lsq_linear
    lo, hi = np.array([BOUNDS[m] for m in MUSCLE_NAMES]).T
    waters_only = np.stack([lsq_linear(W.T, t, bounds=(lo, hi)).x for t in T]) @ W
    assert rel(A @ (W + C)) < 0.05 < 0.3 < rel(waters_only)


def test_reach_and_carrying_fields_to_another_face():
    from pdeface.muscles.fields import LearnedFields, reach_mask

    X = np.array([[0.0, 0, 0], [10, 0, 0], [30, 0, 0], [100, 0, 0]])
    W = np.zeros((24, 4, 3))
    W[0, 0] = [1.0, 0, 0]  # muscle 0 moves only the first point; the rest move nothing
    mask = reach_mask(X, W, 15.0)
    assert mask[0].tolist() == [True, True, False, False] and not mask[1:].any()
    face = load_face("default")
    from pdeface.au.retarget import face_size
    K, J = face.curve_points().shape[:2]
    learned = LearnedFields(np.ones((24, K, J, 3)), face_size(face) * [2, 1, 0.5])
    np.testing.assert_allclose(learned.on(face)[0, 0, 0], [0.5, 1, 2])  # scaled per axis by face size
    assert LearnedFields(np.ones((24, K + 1, J, 3)), face_size(face)).on(face) is None  # another layout


def run(capsys, *args):
    from pdeface.cli import main
    code = main([str(a) for a in args])
    out = capsys.readouterr()
    return code, out.out, out.err


def test_bundled_table_and_the_muscle_aus_of_the_default_face():
    from pdeface.muscles.aus import AUTHORED, load_table
    from pdeface.presets import PRESETS, resolve_preset

    table = load_table()
    face = load_face("default")
    scan_keys = {d.key for d in face.descriptors if d.source != "muscle"}
    assert scan_keys <= set(table.activations) and set(AUTHORED) <= set(table.activations)
    muscle = {d.key: d for d in face.descriptors if d.source == "muscle"}
    assert set(muscle) == set(AUTHORED)  # the AUs no scan covers; the scan's stay the default elsewhere
    weights, missing = resolve_preset(PRESETS["anger"], {d.key for d in face.descriptors})
    assert "23" in weights and "23" not in missing  # anger's main AUs 23 + 24
    basis = MuscleBasis(face)
    assert basis.learned and table.fields is not None
    for name in ("levator_anguli_oris_R", "levator_anguli_oris_L", "nasalis"):
        assert not table.fields.corrections[MUSCLE_NAMES.index(name)].any(), name
    np.testing.assert_allclose(muscle["13"].dense()[0], basis.descriptor("13", table.activations["13"]).dense()[0],
                               atol=0.05)  # mm: the model file stores coefficients to 0.01 mm steps


def test_the_wink_is_one_eyes_blink_with_its_lids_tightened():
    """AU46R is authored from the calibrated AU45R and AU7R. Authored as the orbicularis oculi alone (1.6, with
    the zygomatic at 0.3), its learned correction pulled the lower lid 1.5 mm down while the upper lid closed."""
    from pdeface.muscles.aus import AUTHORED, authored_activations, load_table

    table = load_table()
    face = load_face("default")
    X = face.curve_points()
    wink = {d.key: d for d in face.descriptors}["46R"]
    D = np.zeros_like(X)
    D[wink.curves] = wink.points()
    upper = face.layout.breaks()[0]  # the eyes' upper rim; the lower rim is the next curve
    lower = upper + 1
    eye = (X[upper, :, 1] - X[lower, :, 1]) > 3  # the points where the right eye is open at rest ...
    eye &= X[upper, :, 0] < 0  # ... on the subject's right
    assert D[upper, eye, 1].min() < -6  # the upper lid closes (the scans' blink: 7.5 mm at the landmark)
    assert D[lower, eye, 1].min() > -0.3 and D[lower + 1, eye, 1].max() > 0.3  # the lower lid and skin rise
    assert np.abs(D[:, X[0, :, 0] > 10]).max() < 0.3  # the other side stays
    np.testing.assert_allclose(table.activations["46R"], authored_activations(AUTHORED["46R"], table.activations),
                               atol=1e-4)
    with pytest.raises(PdeFaceError, match="AU99"):
        authored_activations({"AU99": 1.0}, table.activations)
    with pytest.raises(PdeFaceError, match="orbicularis_oculi_R outside"):
        authored_activations({"AU45R": 1.0, "AU7R": 1.0}, table.activations)


def test_muscle_mixers_pose_a_face_through_pose_curves():
    from pdeface.au.expressions import mix
    from pdeface.muscles.aus import load_table
    from pdeface.posing import pose_curves

    face = load_face("default")
    table = load_table()
    w = {"12": 1.0, "6": 0.5}
    C, R = pose_curves(face, w, "muscle-max")
    dC, dR = MuscleBasis(face).curves(mix_activations(table.activations, w, "muscle-max"))
    np.testing.assert_allclose(C - face.coefficients, dC, atol=1e-12)
    C2, _ = pose_curves(face, w, "muscle-average")
    assert not np.allclose(C, C2)
    with pytest.raises(PdeFaceError, match="pose_curves"):
        mix({d.key: d for d in face.descriptors}, w, "muscle-max")


def test_activations_as_the_command_line_writes_them():
    assert parse_activations(["jaw=0.5", "zygomatic_major_L=-0"]) == {"jaw": 0.5, "zygomatic_major_L": 0.0}
    for item, message in (("jaw", "use MUSCLE=VALUE"), ("jaw=x", "'x' is not a number")):
        with pytest.raises(PdeFaceError, match=message):
            parse_activations([item])


def test_cli_muscles(tmp_path, capsys):
    from pdeface.io.meshio import read_obj

    code, _, err = run(capsys, "muscles", "default", "--au", "23=1", "-o", tmp_path / "a.obj")
    assert code == 0, err
    code, _, err = run(capsys, "muscles", "default", "--activation", "zygomatic_major_L=0.6", "--activation",
                       "jaw=0.5", "-o", tmp_path / "b.obj")
    assert code == 0, err
    assert run(capsys, "muscles", "default", "--au", "12=1", "--au", "6=1", "--mixer", "muscle-max",
               "-o", tmp_path / "c.obj")[0] == 0
    a, b = read_obj(tmp_path / "a.obj"), read_obj(tmp_path / "b.obj")
    assert len(a.vertices) == len(b.vertices) and not np.allclose(a.vertices, b.vertices)
    for args, message in ((["--activation", "bicep=1"], "no muscle"), (["--activation", "jaw=9"], "outside"),
                          (["--activation", "jaw"], "MUSCLE=VALUE"), (["--au", "8=1"], "no AU"), ([], "give AU")):
        code, _, err = run(capsys, "muscles", "default", *args, "-o", tmp_path / "x.obj")
        assert code == 2 and message in err, err
    assert not (tmp_path / "x.obj").exists()
