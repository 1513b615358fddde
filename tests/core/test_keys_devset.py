"""AU keys on development characters other artists' heads stand for (issue #40)."""
import json
from functools import lru_cache

import numpy as np
import pytest
from pdeface.au.modelfile import load_face, load_model
from pdeface.au.retarget import curve_map, retarget
from pdeface.cli import main
from pdeface.facs import au_number
from pdeface.geometry import ClosestPoint
from pdeface.head import bind
from pdeface.head import folds as fold_relax
from pdeface.head.bind import GAZE_AUS, HeadBinding, descriptor_motion_args
from pdeface.head.mouth import head_mouth_bag, mouth_bag
from pdeface.head.parts import CODE, EYEBALL_IOD
from pdeface.io.meshio import write_mesh
from pdeface.mesh import Mesh, connected_components
from pdeface.presets import key_poses
from pdeface.rig import load_keys
from pdeface.surface.fit import fit_face

from scripts.bench.bench_keys_devset import (
    LIDS,
    LIP_LOWER_INNER,
    LIP_UPPER_INNER,
    edge_face_pairs,
    eyes_of,
    turn_degrees,
)
from scripts.devset import makehuman
from scripts.devset.characters import SPECS, Spec, build, decimate

needs_makehuman = pytest.mark.skipif(not makehuman.available(), reason="needs ../shared/data/makehuman")


@lru_cache(maxsize=2)
def rig(name):
    """(character's joined V, T, L, retargeted model, binding): fitted and bound in memory, its landmarks given
    (bench_keys_devset binds the model read back from its bytes, its landmarks its own: the same to rounding,
    test_pdeface_rig_binds_with_the_landmarks_the_benchmarks_bind_with)."""
    ch = build(SPECS[name])
    (V, T), L = ch.joined(), ch.landmarks
    model, _ = fit_face(V, T, L)
    model = retarget(load_face("default"), model)
    return V, T, L, model, HeadBinding(model, V, T, landmarks=L)


def lid_closure(V, L, model, binding, key="45"):
    d = {x.key: x for x in model.descriptors}[key]
    f = model.frame
    Vf, Lf = f.to_face(V), f.to_face(L)
    posed = f.to_face(V + binding.displacement(*descriptor_motion_args(d)))
    near = np.array([np.argmin(np.linalg.norm(Vf - p, axis=1)) for p in Lf])
    rest, _ = eyes_of(Lf)
    moved, _ = eyes_of(posed[near])
    return {s: 1 - np.linalg.norm(moved[s][0] - moved[s][1]) / np.linalg.norm(rest[s][0] - rest[s][1]) for s in LIDS}


@needs_makehuman
def test_descriptors_reach_the_lids_on_a_face_whose_curves_are_spread_otherwise():
    # This MakeHuman identity has its upper lid's rim on another curve than ICT's: the blink must still close
    # the lids (it opened them, -0.15, when curve i was carried onto curve i).
    V, _, L, model, b = rig("asian-male-young-blender-m")
    source = load_face("default")
    where = curve_map(source.layout, model.layout)
    assert where is not None
    for (a, k), (a_s, k_s) in zip(model.layout.opening_curves(), source.layout.opening_curves()):
        assert a == a_s and where[k] == k_s and where[k + 1] == k_s + 1  # rims onto rims
    closure = lid_closure(V, L, model, b)
    assert min(closure.values()) >= 0.8, closure  # issue #40's target
    assert abs(closure["L"] - closure["R"]) < 0.1 * max(closure.values())


@needs_makehuman
def test_the_base_annotated_in_icts_convention_has_icts_curves_and_blinks():
    V, _, L, model, b = rig("base-dm")  # its landmarks placed as ICT's are: its rims on ICT's curves
    assert curve_map(load_face("default").layout, model.layout) is None
    closure = lid_closure(V, L, model, b)
    assert min(closure.values()) >= 0.8, closure
    assert abs(closure["L"] - closure["R"]) < 0.1 * max(closure.values())


def test_faces_with_the_same_curves_keep_their_descriptors():
    source = load_face("default")
    assert curve_map(source.layout, source.layout) is None
    moved = retarget(source, source)
    for a, b in zip(source.descriptors, moved.descriptors):
        assert np.allclose(a.points(), b.points())


@needs_makehuman
def test_empty_sockets_get_no_gaze_keys_and_eyeballs_in_the_mesh_are_never_skin():
    *_, model, b = rig("base-dm")  # empty sockets
    kept = b.bindable(model.descriptors)
    assert not b.parts.eyes and {au_number(d.key) for d in kept}.isdisjoint(GAZE_AUS)
    assert len(kept) == len(model.descriptors) - sum(au_number(d.key) in GAZE_AUS for d in model.descriptors)
    assert any("no gaze keys" in n for n in b.notes)
    V, T, _, model, b = rig("eyes-teeth-merged-cm")  # eyeballs as pieces of the one mesh
    assert set(b.parts.eyes) == {"eye_L", "eye_R"} and b.bindable(model.descriptors) == list(model.descriptors)
    lab = connected_components(len(V), T)
    for side in ("eye_L", "eye_R"):
        pieces = np.unique(lab[b.parts.mask(side)])
        assert len(pieces) and (b.parts.kind[np.isin(lab, pieces)] == CODE[side]).all()  # no piece half skin
        _, radius = b.parts.eyes[side]
        assert EYEBALL_IOD[0] < 2 * radius / b.eye_distance < EYEBALL_IOD[1]  # sized as an eyeball


@needs_makehuman
def test_rig_and_all_keys_leave_out_gaze_keys_on_a_head_without_eyeballs(tmp_path, capsys):
    V, T, L, *_ = rig("base-dm")  # empty sockets
    write_mesh(tmp_path / "head.obj", Mesh.from_faces(V, T))
    (tmp_path / "head.json").write_text(json.dumps({"points": L.tolist()}))
    gaze = {f"AU{a}" for a in GAZE_AUS}
    assert main(["rig", str(tmp_path / "head.obj"), "--landmarks", str(tmp_path / "head.json"), "--no-presets",
                 "-o", str(tmp_path / "rig")]) == 0
    out, err = capsys.readouterr()
    names = load_keys(tmp_path / "rig/keys.npz")["names"]
    assert len(names) > 50 and gaze.isdisjoint(names)
    assert set(json.loads(out)["keys"]["left_out"]) == gaze
    assert sum("no gaze keys" in line for line in err.splitlines()) == 1  # the one-line note
    assert main(["pose", str(tmp_path / "rig/rigged.npz"), "--all-keys", "--mesh", str(tmp_path / "head.obj"),
                 "--landmarks", str(tmp_path / "head.json"), "-o", str(tmp_path / "keys")]) == 0
    out, err = capsys.readouterr()
    written = json.loads(out)
    assert written["aus"] == [n for n in names if n.startswith("AU")] and "no gaze keys" in err
    assert not any((tmp_path / "keys" / f"{g}.obj").exists() for g in gaze)


@needs_makehuman
def test_pdeface_rig_binds_with_the_landmarks_the_benchmarks_bind_with(tmp_path, capsys):
    """``pdeface rig`` binds its rigged model as read back from its file, with the landmarks the file carries: all 68
    it was fitted with, unrounded, so its keys are those of ``HeadBinding(model, V, T, landmarks=L)``, as the
    benchmarks bind (to the frame's rounding in its file, ~1e-15 mm, and the keys file's float32). decimated-cm's rims
    merged at the middle need the inner lips' sides (61, 63, 65, 67): a file that kept 24 landmarks, to 0.1 mm, left
    them out and its AU27 took the upper lip down with the jaw (-0.25 eye distances; -0.03 given the 68)."""
    ch = build(SPECS["decimated-cm"])
    write_mesh(tmp_path / "head.obj", Mesh.from_faces(ch.vertices, ch.triangles))
    (tmp_path / "head.json").write_text(json.dumps({"points": ch.landmarks.tolist()}))
    assert main(["rig", str(tmp_path / "head.obj"), "--landmarks", str(tmp_path / "head.json"), "--no-presets",
                 "-o", str(tmp_path / "rig")]) == 0
    capsys.readouterr()
    keys = load_keys(tmp_path / "rig/keys.npz")
    rigged = load_model(tmp_path / "rig/rigged.npz")
    V, T, L = keys["vertices"], keys["triangles"], keys["landmarks"]
    assert np.isfinite(rigged.landmarks).all() and np.allclose(rigged.landmarks, rigged.frame.to_face(L), atol=1e-9)
    given = HeadBinding(rigged, V, T, landmarks=L)
    poses = key_poses(rigged, {}, descriptors=given.bindable(rigged.descriptors))
    assert list(poses) == keys["names"]
    deltas = np.asarray(given.pose_displacements(list(poses.values())), np.float32)
    largest = np.abs(deltas).max()
    assert np.abs(deltas - keys["deltas"]).max() <= 1e-6 * largest, np.abs(deltas - keys["deltas"]).max() / largest


@needs_makehuman
def test_the_lip_and_eye_corners_fold_less_and_the_mouth_opens_as_wide(monkeypatch):
    V, T, L, model, smoothed = rig("base-dm")
    # the seam smoother alone (the folds' relaxation: test_head_folds)
    monkeypatch.setattr(fold_relax, "RELAX_STEPS", 0)
    monkeypatch.setattr(bind, "STEPS_NOT_JAW", 0)
    monkeypatch.setattr(bind, "SEAM_STEPS", 0)
    raw = HeadBinding(model, V, T, landmarks=L)
    f = model.frame
    Vf, Lf = f.to_face(V), f.to_face(L)
    pairs = edge_face_pairs(T)
    flat = (turn_degrees(Vf, T, pairs) < 20) & smoothed.parts.mask("skin")[T[pairs]].all(axis=(1, 2))
    near = [np.argmin(np.linalg.norm(Vf - Lf[i], axis=1)) for i in (LIP_UPPER_INNER, LIP_LOWER_INNER)]
    descr = {d.key: d for d in model.descriptors}
    # The blink's seams fold less by 0.8 on the by-eye annotation, by 49/57 on the ICT-convention one (issue #39)
    for key, most in (("27", 0.8), ("12", 0.8), ("45", 0.9)):
        args = descriptor_motion_args(descr[key])
        posed = {n: f.to_face(V + b.displacement(*args)) for n, b in (("raw", raw), ("smoothed", smoothed))}
        folds = {n: int((flat & (turn_degrees(P, T, pairs) > 40)).sum()) for n, P in posed.items()}
        assert folds["smoothed"] < most * folds["raw"], (key, folds)
        gap = {n: P[near[0], 1] - P[near[1], 1] for n, P in posed.items()}
        assert abs(gap["smoothed"] - gap["raw"]) < 0.01 * smoothed.eye_distance, (key, gap)


@needs_makehuman
@pytest.mark.parametrize("identity", ["asian-female-old", "african-male-old"])
def test_a_prominent_chin_opens_the_mouth_below_the_upper_lip(identity):
    """AU27 on a stylised chin of identities the fix was not tuned on (asian-male-old's was): the lips touch at
    rest, and a lip's rim once climbed onto the other lip (asian-female-old's upper rim), or the head prior gave the
    upper inner lip ICT's lower lip's drop (african-male-old: 0.12 eye distances) (issue #40)."""
    from pdeface.surface.layout import ANCHOR_NAMES

    ch = build(Spec(f"stylised-chin-{identity}", {identity: 1.0}, unit="cm",
                    style={"chin/chin-prominent-incr": 2.0, "cheek/l-cheek-bones-incr": 2.0,
                           "cheek/r-cheek-bones-incr": 2.0}))
    V, T, L = ch.vertices, ch.triangles, ch.landmarks
    model = retarget(load_face("default"), fit_face(V, T, L)[0])
    binding = HeadBinding(model, V, T, landmarks=L)
    f = model.frame
    Vf, Lf = f.to_face(V), f.to_face(L)
    middle = Lf[[LIP_UPPER_INNER, LIP_LOWER_INNER], 1].mean()
    # Each lip's rim curve on its own side of the mouth's middle line, at the face's midline.
    C = model.curve_points(model.coefficients, model.residual)
    k = next(k for a, k in model.layout.opening_curves() if ANCHOR_NAMES[a] == "mouth_top")
    j = np.argmin(np.abs(C[k, :, 0]))
    assert C[k, j, 1] > middle > C[k + 1, j, 1], (C[k:k + 2, j, 1], middle)
    # The upper lip stays, the lower one follows the jaw.
    d = {x.key: x for x in model.descriptors}["27"]
    posed = f.to_face(V + binding.displacement(*descriptor_motion_args(d)))
    up, lo = (np.argmin(np.linalg.norm(Vf - Lf[i], axis=1)) for i in (LIP_UPPER_INNER, LIP_LOWER_INNER))
    ed = binding.eye_distance
    assert abs(posed[up, 1] - Vf[up, 1]) <= 0.08 * ed
    assert (posed[up, 1] - posed[lo, 1]) - (Vf[up, 1] - Vf[lo, 1]) >= 0.25 * ed


@needs_makehuman
def test_lips_joined_in_the_mesh_open_below_the_upper_lip_and_say_so():
    """A voxel remesh of an identity the fix was not tuned on (voxel-m's was): the lips are one surface, so AU27
    cannot part them; the lower lip follows the jaw, the upper lip stays, the skin between stretches without new
    folds, and a binding note says why (issue #40)."""
    ch = build(Spec("voxel-caucasian-female-young", {"caucasian-female-young": 1.0}, remesh="voxel"))
    V, T, L = ch.vertices, ch.triangles, ch.landmarks
    model = retarget(load_face("default"), fit_face(V, T, L)[0])
    binding = HeadBinding(model, V, T, landmarks=L)
    assert binding.lips_one_line
    assert any("lips are joined" in n for n in binding.notes)
    f = model.frame
    Vf, Lf = f.to_face(V), f.to_face(L)
    ed = binding.eye_distance
    d = {x.key: x for x in model.descriptors}["27"]
    posed = f.to_face(V + binding.displacement(*descriptor_motion_args(d)))
    middle = Lf[[LIP_UPPER_INNER, LIP_LOWER_INNER], 1].mean()
    upper = np.argmin(np.linalg.norm(Vf - [0, middle + 0.08 * ed, Lf[LIP_UPPER_INNER, 2]], axis=1))
    lower = np.argmin(np.linalg.norm(Vf - Lf[57], axis=1))  # the lower lip's outer middle
    assert abs(posed[upper, 1] - Vf[upper, 1]) <= 0.08 * ed
    assert Vf[lower, 1] - posed[lower, 1] >= 0.25 * ed
    pairs = edge_face_pairs(T)
    new_folds = (turn_degrees(Vf, T, pairs) < 20) & (turn_degrees(posed, T, pairs) > 40)
    assert new_folds.sum() <= 0.001 * len(pairs)


@needs_makehuman
def test_lip_rims_a_decimation_merged_follow_their_own_lips(monkeypatch):
    """A decimated identity the fix was not tuned on (decimated-cm's upper lip sank 0.24 eye distances in AU27: its
    rim vertex, merged with the lower lip's, followed the jaw): each inner lip's rim follows its own lip, the mouth
    opens wider than when they were free, the upper lip stays and no key folds past the issue's limit."""
    ch = build(Spec("decimated-asian-male-old", {"asian-male-old": 1.0}, remesh="decimate"))
    V, T, L = ch.vertices, ch.triangles, ch.landmarks
    model = retarget(load_face("default"), fit_face(V, T, L)[0])
    f = model.frame
    Vf, Lf = f.to_face(V), f.to_face(L)
    args = descriptor_motion_args({x.key: x for x in model.descriptors}["27"])
    up, lo = (np.argmin(np.linalg.norm(Vf - Lf[i], axis=1)) for i in (LIP_UPPER_INNER, LIP_LOWER_INNER))
    pairs = edge_face_pairs(T)

    def opened(binding):
        posed = f.to_face(V + binding.displacement(*args))
        folds = ((turn_degrees(Vf, T, pairs) < 20) & (turn_degrees(posed, T, pairs) > 40)).sum()
        ed = binding.eye_distance
        return ((posed[up, 1] - Vf[up, 1]) / ed, ((posed[up, 1] - posed[lo, 1]) - (Vf[up, 1] - Vf[lo, 1])) / ed,
                folds)

    b = HeadBinding(model, V, T, landmarks=L)
    assert any("lips are joined" in n for n in b.notes) and not b.lips_one_line
    rise, gap, folds = opened(b)
    assert abs(rise) <= 0.08 and gap >= 0.25 and folds <= max(2, 0.001 * len(pairs))
    monkeypatch.setattr(bind, "_merged_rims", lambda *a: (np.zeros(0, np.int64),) * 2)  # as it was: rims free
    assert opened(HeadBinding(model, V, T, landmarks=L))[1] < gap - 0.1


def clustered_ict(cell, identity=None):
    """(V, T, L, retargeted model) of ICT's head (``identity`` added) clustered on a grid of ``cell`` cm
    (``scripts.bench.benchlib.clustered``), each landmark at its nearest vertex."""
    from pdeface.assets import load_head, load_head_shapes
    from scipy.spatial import cKDTree

    from scripts.bench.benchlib import clustered

    mesh, lm = load_head()
    V, T = mesh.vertices, mesh.triangles()[0]
    if identity:
        V = V + load_head_shapes()[identity]
    V, T, L = *clustered(V, T, cell), V[lm]
    L = V[cKDTree(V).query(L)[1]]
    return V, T, L, retarget(load_face("default"), fit_face(V, T, L)[0])


def au27_lips(binding, V, L):
    """AU27's (upper inner lip's rise, inner lips' gap's growth), in eye distances, at the landmarks' nearest
    vertices (two), and the posed head (face frame)."""
    f = binding.model.frame
    Vf, Lf = f.to_face(V), f.to_face(L)
    by_key = {x.key: x for x in binding.model.descriptors}
    posed = f.to_face(V + binding.displacement(*descriptor_motion_args(by_key["27"])))
    up, lo = (np.argmin(np.linalg.norm(Vf - Lf[i], axis=1)) for i in (LIP_UPPER_INNER, LIP_LOWER_INNER))
    assert up != lo
    ed = binding.eye_distance
    return (posed[up, 1] - Vf[up, 1]) / ed, ((posed[up, 1] - posed[lo, 1]) - (Vf[up, 1] - Vf[lo, 1])) / ed, posed


@pytest.mark.parametrize("identity", [None, "identity008"])
def test_lips_a_clustering_joined_beside_their_middles_open_in_a_jaw_drop(identity):
    """ICT's head clustered on a 0.42 cm grid (bench_rig's 8.7k head; identity008 clustered the same way, not tuned
    on) joins the lips 0.07 eye distances beside their middles, a way longer than the short one: taken for lips
    apart, the upper lip sank with the jaw and AU27 opened a slot (gap 0.09 and 0.06 eye distances). Joined, the
    binding says so, each rim follows its own lip, and AU27 opens as a jaw drop without folding past the issue's
    limit."""
    V, T, L, model = clustered_ict(0.42, identity)
    binding = HeadBinding(model, V, T, landmarks=L)
    assert any("lips are joined" in n for n in binding.notes) and not binding.lips_one_line
    rise, gap, posed = au27_lips(binding, V, L)
    assert abs(rise) <= 0.08 and gap >= 0.25
    pairs = edge_face_pairs(T)
    new_folds = (turn_degrees(model.frame.to_face(V), T, pairs) < 20) & (turn_degrees(posed, T, pairs) > 40)
    assert new_folds.sum() <= 0.001 * len(pairs)


@pytest.mark.parametrize("head", ["ict-0.5", "ict-0.5-identity009", "caucasian-female-old-4000"])
def test_the_upper_rim_of_merged_lips_follows_its_own_lip_where_the_mouth_line_runs_under_the_lower(head, monkeypatch):
    """ICT's head clustered on a 0.5 cm grid joins its lips by the short way, their rims held each with its lip
    (:func:`pdeface.head.bind._merged_rims`, split at the mouth line); its corners turn down, so the mouth line runs
    under the lower lip's rim, and the upper rim, anchored on the lower lip's skin above that line, sank with the jaw
    (AU27: upper lip -0.60 eye distances, gap -0.04). Anchored on its own lip (told apart half-way between the inner
    lips), it stays and AU27 opens. identity009 clustered the same way and a MakeHuman head decimated to 4,000
    vertices (not tuned on) sank the same."""
    if head.startswith("ict"):
        V, T, L, model = clustered_ict(0.5, head.removeprefix("ict-0.5").removeprefix("-") or None)
    elif makehuman.available():
        V, T, L, model = decimated("caucasian-female-old", 4000)
    else:
        pytest.skip("needs ../shared/data/makehuman")
    binding = HeadBinding(model, V, T, landmarks=L)
    assert any("lips are joined" in n for n in binding.notes) and not binding.lips_one_line
    rise, gap, _ = au27_lips(binding, V, L)
    assert rise > -0.1 and gap >= 0.25, (rise, gap)  # -0.08 and 0.48 on ICT's
    from pdeface.head.parts import mouth_line

    monkeypatch.setattr(bind, "_inner_lips_between", lambda P, Lf: np.full(len(P), mouth_line(Lf)))  # as it was
    rise, gap, _ = au27_lips(HeadBinding(model, V, T, landmarks=L), V, L)
    assert rise < -0.3 and gap < 0.1, (rise, gap)


def _along(points, share):
    """The point ``share`` of the way along the polyline ``points`` (by length)."""
    at = np.r_[0, np.cumsum(np.linalg.norm(np.diff(points, axis=0), axis=1))]
    return np.array([np.interp(share * at[-1], at, points[:, k]) for k in range(3)])


@lru_cache(maxsize=2)
def decimated(name, vertices):
    """(V, T, L, retargeted model) of ``name`` (a development character, or a MakeHuman identity) decimated to about
    ``vertices`` (the development set's vertex clustering; its characters take about 3,000)."""
    from scripts.devset import characters

    decimate = characters.decimate
    characters.decimate = lambda V, T, target: decimate(V, T, vertices)
    try:
        ch = build(SPECS.get(name) or Spec(f"decimated-{name}", {name: 1.0}, remesh="decimate"))
    finally:
        characters.decimate = decimate
    (V, T), L = ch.joined(), ch.landmarks
    return V, T, L, retarget(load_face("default"), fit_face(V, T, L)[0])


def new_folds(binding, V, T, key):
    """The edges ``key`` (a descriptor's) newly folds past the issue's 40 degrees, and the issue's limit."""
    model = binding.model
    f = model.frame
    posed = f.to_face(V + binding.displacement(*descriptor_motion_args({x.key: x for x in model.descriptors}[key])))
    pairs = edge_face_pairs(T)
    flat = turn_degrees(f.to_face(V), T, pairs) < 20
    return int((flat & (turn_degrees(posed, T, pairs) > 40)).sum()), max(2, int(0.001 * len(pairs)))


@needs_makehuman
@pytest.mark.parametrize("name, vertices", [("decimated-cm", 3000), ("caucasian-female-young", 3500)])
def test_a_decimated_mouth_opens_its_lower_lip_along_its_width_not_as_a_beak(name, vertices, monkeypatch):
    """Lips a decimation joined at their rims (decimated-cm; caucasian-female-young decimated to 3,500 vertices, not
    tuned on): AU27 takes the lower lip down along its width, the points a third of the way to each corner (half way
    between its inner and outer line) by at least 0.8 of its middle's drop, the upper lip staying; it folds no more
    edges than with the lower lip left to the folds' relaxation, which lifted its thirds towards the rims held with
    the upper lip (a pointed V: decimated-cm's thirds 0.64 and 0.72 of its middle's drop)."""
    V, T, L, model = decimated(name, vertices)
    f = model.frame
    Vf, Lf = f.to_face(V), f.to_face(L)
    args = descriptor_motion_args({x.key: x for x in model.descriptors}["27"])
    outer, inner = Lf[[48, 59, 58, 57, 56, 55, 54]], Lf[[60, 67, 66, 65, 64]]
    lip = [np.argmin(np.linalg.norm(Vf - (_along(outer, s) + _along(inner, s)) / 2, axis=1))
           for s in (1 / 3, 0.5, 2 / 3)]
    up = np.argmin(np.linalg.norm(Vf - Lf[LIP_UPPER_INNER], axis=1))

    def opened(binding):
        posed = f.to_face(V + binding.displacement(*args))
        ed = binding.eye_distance
        return (Vf[lip, 1] - posed[lip, 1]) / ed, (posed[up, 1] - Vf[up, 1]) / ed, new_folds(binding, V, T, "27")

    b = HeadBinding(model, V, T, landmarks=L)
    assert any("lips are joined" in n for n in b.notes) and not b.lips_one_line
    drop, rise, (folds, limit) = opened(b)
    assert drop[1] >= 0.25 and min(drop[0], drop[2]) >= 0.8 * drop[1], drop
    assert abs(rise) <= 0.08 and folds <= limit
    monkeypatch.setattr(bind, "_lower_lip", lambda P, *a: np.zeros(len(P), bool))  # as it was: relaxed
    was, _, (folds_was, _) = opened(HeadBinding(model, V, T, landmarks=L))
    assert min(was[0], was[2]) < 0.8 * was[1] and folds <= folds_was, (was, folds_was)


@needs_makehuman
def test_a_decimated_mouths_jaw_keys_that_do_not_part_the_lips_relax_them_freely(monkeypatch):
    """asian-female-young decimated (its lips' rims merged; not tuned on): AU29 thrusts the jaw forward without
    parting the lips, so its folds' relaxation moves the inner lips' middles and the lower lip the keys that open the
    mouth keep (kept, AU29 folded 13 edges there, past the issue's limit of 8; now 1)."""
    V, T, L, model = decimated("asian-female-young", 3000)
    b = HeadBinding(model, V, T, landmarks=L)
    assert any("lips are joined" in n for n in b.notes) and not b.lips_one_line
    folds, limit = new_folds(b, V, T, "29")
    assert folds <= limit
    monkeypatch.setattr(bind, "PARTED_IOD", -np.inf)  # as it was: every jaw key keeps them
    assert new_folds(HeadBinding(model, V, T, landmarks=L), V, T, "29")[0] > max(folds, limit)


@needs_makehuman
def test_a_fit_that_leaves_the_mesh_is_refused_not_rigged(monkeypatch):
    # A stylised head (prominent chin, cheek bones, forehead forward on an older man) whose curves ran off the face
    # below the brows (a rim's knot 0.001 rad inside an inner eye corner swung the eye line down): such a fit says
    # so instead of rigging keys on a surface that is not the mesh's. With the rims' knots clear of the corners it
    # fits.
    from pdeface.errors import LayoutError
    from pdeface.surface import rims

    style = {"chin/chin-prominent-incr": 2.0, "cheek/l-cheek-bones-incr": 2.0, "cheek/r-cheek-bones-incr": 2.0,
             "forehead/forehead-trans-forward": 1.5}
    head = build(Spec("chin-cheek-old-man", {"caucasian-male-old": 1.0}, style=style))
    model, _ = fit_face(head.vertices, head.triangles, head.landmarks)
    assert model.coefficients.shape[0] > 0
    monkeypatch.setattr(rims, "RIM_KNOT_GAP", 0.0)  # the knots as they were
    with pytest.raises(LayoutError, match="leaves the mesh"):
        fit_face(head.vertices, head.triangles, head.landmarks)


@needs_makehuman
def test_a_rim_knot_next_to_an_eye_corner_leaves_the_mouth_curves_on_the_mouth():
    """body-A-cm's head (caucasian-male-young): a ray 0.0009 rad inside the inner eye corner gave the lid line a
    near-double knot; its spline swung 213 mm down between the eyes, every anchor below it with it, and the mouth's
    curves lay on the chin: AU27 left the lips shut (gap 0.00 eye distances, issue #40)."""
    from pdeface.surface.layout import ANCHOR_NAMES

    ch = build(Spec("caucasian-male-young", {"caucasian-male-young": 1.0}))
    V, T, L = ch.vertices, ch.triangles, ch.landmarks
    model = retarget(load_face("default"), fit_face(V, T, L)[0])
    f = model.frame
    Vf, Lf = f.to_face(V), f.to_face(L)
    ed = eyes_of(Lf)[1]
    C = model.curve_points(model.coefficients, model.residual)
    k = next(k for a, k in model.layout.opening_curves() if ANCHOR_NAMES[a] == "mouth_top")
    j = np.argmin(np.abs(C[k, :, 0]))
    assert np.abs(C[k:k + 2, j, 1] - Lf[[LIP_UPPER_INNER, LIP_LOWER_INNER], 1]).max() < 0.05 * ed  # on the lips
    binding = HeadBinding(model, V, T, landmarks=L)
    posed = f.to_face(V + binding.displacement(*descriptor_motion_args({x.key: x for x in model.descriptors}["27"])))
    up, lo = (np.argmin(np.linalg.norm(Vf - Lf[i], axis=1)) for i in (LIP_UPPER_INNER, LIP_LOWER_INNER))
    assert (posed[up, 1] - posed[lo, 1]) - (Vf[up, 1] - Vf[lo, 1]) >= 0.25 * ed
    assert abs(posed[up, 1] - Vf[up, 1]) <= 0.08 * ed


@needs_makehuman
@pytest.mark.parametrize("name", ["body-T-turn40-blender-cm", "african-asian-female-young-mm"])
def test_the_back_of_the_head_and_a_bodys_neck_keep_still_but_the_jaw_opens(name, monkeypatch):
    """Every key and preset moves the back of the head (more than 0.6 head depths behind the nose tip) and a body
    below the neck (1.5 eye distances under the chin) at most 0.5 mm (these moved up to 0.95 and 0.71 mm); the jaw
    keys still move the chin and the skin under the jaw as before (issue #40)."""
    from pdeface.landmark_scheme import JAW_LEFT_ANGLE, JAW_RIGHT_ANGLE
    from pdeface.presets import every_pose

    from scripts.bench.bench_keys_devset import TARGETS, spill_region

    V, T, L, model, b = rig(name)
    f = model.frame
    Vf, Lf = f.to_face(V), f.to_face(L)
    ed = eyes_of(Lf)[1]
    poses = every_pose(model)
    D = b.displacements([descriptor_motion_args(d) for d in model.descriptors]
                        + [b.pose_motion_args(w, "sum") for n, w in poses.items() if n != "neutral"])
    region = spill_region(Vf, Lf, ed, body=SPECS[name].body)
    assert region.sum() > 100
    moved = max(np.linalg.norm(f.to_face(V + d)[region] - Vf[region], axis=1).max() for d in D)
    assert moved <= TARGETS["spill_mm"]
    # The jaw keys: the chin and the skin under the jaw (down to 0.75 eye distances under the chin, in front of the
    # jaw's angle) move as without the falloff.
    monkeypatch.setattr(bind, "still_weight", lambda X, *a: np.ones(len(X)))
    free = HeadBinding(model, V, T, landmarks=L)
    under_jaw = ((Vf[:, 1] < Lf[8, 1]) & (Vf[:, 1] > Lf[8, 1] - 0.75 * ed)
                 & (Vf[:, 2] > Lf[[JAW_RIGHT_ANGLE, JAW_LEFT_ANGLE], 2].max()) & b.parts.mask("skin"))
    for key in ("26", "27"):
        args = descriptor_motion_args({x.key: x for x in model.descriptors}[key])
        kept, before = b.displacement(*args), free.displacement(*args)
        assert np.linalg.norm(before[under_jaw], axis=1).max() > 0.1 * ed / f.scale
        np.testing.assert_allclose(kept[under_jaw], before[under_jaw], atol=1e-9)


@needs_makehuman
@pytest.mark.parametrize("name", ["stylised-nose-mouth-cm", "body-A-in-eyes"])
def test_a_blink_takes_the_upper_lid_down_onto_the_lower_one_which_keeps_its_height(name):
    """The retargeted motion raised the lower lids' middles 0.07-0.16 of the rest gap (ICT's scanned blink 0.02,
    MakeHuman's eye closure 0): the upper lid stopped that much short of its travel (issue #40: 0.78 of
    MakeHuman's on stylised-nose-mouth). The lower lid keeps its height, the upper one meets it, over it."""
    V, _, L, model, b = rig(name)  # stylised-nose-mouth: no eyeballs; body-A-in-eyes: eyeballs in the mesh
    f = model.frame
    Vf, Lf = f.to_face(V), f.to_face(L)
    args = descriptor_motion_args({x.key: x for x in model.descriptors}["45"])
    before_lids = b.face_motions([args[:4]])[0]
    key = f.to_face(V + b.displacement(*args)) - Vf
    near = lambda idx: np.array([np.argmin(np.linalg.norm(Vf - Lf[i], axis=1)) for i in idx])
    for side, (upper, lower) in LIDS.items():
        up, lo = near(upper), near(lower)
        gap0 = Vf[up].mean(0) - Vf[lo].mean(0)
        rise = lambda D, lo=lo, gap0=gap0: D[lo, 1].mean() / np.linalg.norm(gap0)
        assert rise(before_lids) > 0.05, side  # the motion the lids' closing starts from raises the lower lid
        assert abs(rise(key)) < 0.03, side
        travel = np.linalg.norm(key[up].mean(0)) / np.linalg.norm(gap0)
        assert travel >= 0.85, (side, travel)
        gap = (Vf[up].mean(0) + key[up].mean(0)) - (Vf[lo].mean(0) + key[lo].mean(0))
        assert 0 < gap @ gap0 / (gap0 @ gap0) < 0.15, side  # closed, the upper lid over the lower, not through it


@needs_makehuman
def test_an_empty_sockets_cup_keeps_still_in_a_blink_that_closes_the_lids(monkeypatch):
    """Without eyeballs the skin behind where each would sit (the socket's cup) is left at rest and takes no head
    prior: the blink moved MakeHuman's cup up to 6 mm (its own eye closure keeps it still; issue #40)."""
    from pdeface.head import lids

    V, T, L, model, b = rig("asian-male-young-blender-m")  # no eyeballs; not the heads this was tuned on
    assert not b.parts.eyes
    f = model.frame
    Vf, Lf = f.to_face(V), f.to_face(L)
    args = descriptor_motion_args({x.key: x for x in model.descriptors}["45"])
    cup = np.zeros(len(V), bool)
    for centre, radius in lids.eyes_or_sockets(Lf, b.eye_distance).values():
        cup |= (np.linalg.norm(Vf - centre, axis=1) < radius + 0.1 * b.eye_distance) & (Vf[:, 2] < centre[2])
    cup[b.skin[b.covered]] = False  # the lids' own skin, under the PDE face
    cup &= b.parts.mask("skin")
    assert cup.sum() > 50
    moved = np.linalg.norm(b.displacement(*args)[cup], axis=1) * f.scale
    assert moved.max() < 0.5  # mm
    assert min(lid_closure(V, L, model, b).values()) >= 0.8
    # As it was: the cup took the lids' motion (no socket where no eyeball was found).
    monkeypatch.setattr(bind, "eyes_or_sockets", lambda Lf, ed, eyes=None: dict(eyes or {}))
    before = HeadBinding(model, V, T, landmarks=L)
    assert np.linalg.norm(before.displacement(*args)[cup], axis=1).max() * f.scale > 2.0



@needs_makehuman
def test_a_chin_raiser_does_not_fold_the_mouths_inner_corners_and_the_jaw_still_opens():
    # asian-female-old's AU17 folded 18 edges (13 allowed) at the inner lip corners: its relaxation ran out of sweeps
    # (keys that do not open the jaw now get bind.STEPS_NOT_JAW; the jaw's keep theirs: more smoothed the lips shut).
    # Its AU29 (jaw forward) stalled at 16 edges over folds.FOLD_DEG there and kept the first sweep folding 14 over 40°
    # (13 allowed); now the sweep folding fewest over 40° of those as good by FOLD_DEG (12; issue #35).
    V, T, L, model, b = rig("asian-female-old-in")
    f = model.frame
    Vf, Lf = f.to_face(V), f.to_face(L)
    pairs = edge_face_pairs(T)
    flat = turn_degrees(Vf, T, pairs) < 20
    by_key = {x.key: x for x in model.descriptors}
    for key in ("17", "15", "29"):
        posed = f.to_face(V + b.displacement(*descriptor_motion_args(by_key[key])))
        assert (flat & (turn_degrees(posed, T, pairs) > 40)).sum() <= max(2, 0.001 * len(pairs)), key
    posed = f.to_face(V + b.displacement(*descriptor_motion_args(by_key["27"])))
    up, lo = (np.argmin(np.linalg.norm(Vf - Lf[i], axis=1)) for i in (LIP_UPPER_INNER, LIP_LOWER_INNER))
    assert (posed[up, 1] - posed[lo, 1]) - (Vf[up, 1] - Vf[lo, 1]) >= 0.25 * eyes_of(Lf)[1]


@needs_makehuman
def test_a_stalled_relaxation_keeps_the_sweep_folding_fewest_edges_past_the_issues_angle(monkeypatch):
    """Of the sweeps folding as few edges over folds.FOLD_DEG, a stalled job keeps the one folding fewest over
    folds.LIMIT_DEG (asian-female-old-in's AU29 at the inner mouth corners), not the first: as many over FOLD_DEG,
    fewer over 40°, the same sweeps run."""
    V, T, _, model, b = rig("asian-female-old-in")
    f = model.frame
    Vf = f.to_face(V)
    pairs = edge_face_pairs(T)
    flat = turn_degrees(Vf, T, pairs) < 20
    args = descriptor_motion_args({x.key: x for x in model.descriptors}["29"])

    def over(degrees):
        turn = turn_degrees(f.to_face(V + b.displacement(*args)), T, pairs)
        return [int((flat & (turn > a)).sum()) for a in degrees]

    now = over((fold_relax.FOLD_DEG, fold_relax.LIMIT_DEG))
    monkeypatch.setattr(b._folds, "cos_limit", b._folds.cos_fold)  # no second measure: the first best sweep kept
    first = over((fold_relax.FOLD_DEG, fold_relax.LIMIT_DEG))
    assert now[0] == first[0] and now[1] < first[1], (now, first)
    assert now[1] <= max(2, 0.001 * len(pairs)) < first[1]


@needs_makehuman
@pytest.mark.parametrize("name, keys", [("asian-male-young-blender-m", ("17",)),
                                        ("stylised-nose-mouth-cm", ("22", "18", "27"))])
def test_folds_the_screen_missed_or_pins_kept_are_relaxed(name, keys):
    # asian-male-young's AU17 folded 20 edges (13 allowed) at the mouth's corners, edges bent 5-18° at rest whose
    # crease moved their corners under folds.SCREEN 0.05 off their neighbours' mean: never screened, never relaxed.
    # stylised-nose-mouth's lips are joined: the upper lip and the inner lips' middles were kept as bound in every key
    # and AU22, AU18 and AU27 folded 26, 15 and 21 edges against them (now the upper lip in the jaw's keys alone).
    # The joined lips' AU27 still opens below the upper lip.
    V, T, L, model, b = rig(name)
    f = model.frame
    Vf, Lf = f.to_face(V), f.to_face(L)
    pairs = edge_face_pairs(T)
    flat = turn_degrees(Vf, T, pairs) < 20
    by_key = {x.key: x for x in model.descriptors}
    motions = [descriptor_motion_args(by_key[k]) for k in keys]
    for key, d in zip(keys, b.displacements(motions)):
        posed = f.to_face(V + d)
        assert (flat & (turn_degrees(posed, T, pairs) > 40)).sum() <= max(2, 0.001 * len(pairs)), key
        if key == "27":
            ed = eyes_of(Lf)[1]
            up, lo = (np.argmin(np.linalg.norm(Vf - Lf[i], axis=1)) for i in (51, 57))  # the outer lips' middles
            assert posed[up, 1] - Vf[up, 1] <= 0.08 * ed
            assert Vf[lo, 1] - posed[lo, 1] >= 0.25 * ed


@needs_makehuman
def test_the_blink_does_not_hang_on_rounding_in_the_face():
    # The vectorised PDE operators (4e-11 relative) once moved a lid vertex of this character off the PDE face's
    # cover, and the folds' relaxation after the lids close took 16 sweeps, not 10: AU45 closed 0.77, not 0.86.
    from dataclasses import replace

    V, T, L, model, b = rig("asian-male-young-blender-m")
    closure = lid_closure(V, L, model, b)
    rng = np.random.default_rng(0)
    for _ in range(3):
        noisy = replace(model,
                        coefficients=model.coefficients * (1 + 1e-9 * rng.standard_normal(model.coefficients.shape)),
                        residual=model.residual
                        + 1e-9 * np.abs(model.residual).max() * rng.standard_normal(model.residual.shape))
        moved = lid_closure(V, L, noisy, HeadBinding(noisy, V, T, landmarks=L))
        assert max(abs(moved[s] - closure[s]) for s in closure) < 0.01, (moved, closure)


def au27_opened(V, T, L, landmarks):
    """(binding, each landmark's vertical drop in AU27 in eye distances, new folds) of the head ``V``, ``T`` rigged
    with ``landmarks``, measured at the true landmarks ``L``."""
    model = retarget(load_face("default"), fit_face(V, T, landmarks)[0])
    b = HeadBinding(model, V, T, landmarks=landmarks)
    f = model.frame
    Vf, Lf = f.to_face(V), f.to_face(L)  # measured at the true landmarks
    posed = f.to_face(V + b.displacement(*descriptor_motion_args({x.key: x for x in model.descriptors}["27"])))
    near = np.array([np.argmin(np.linalg.norm(Vf - p, axis=1)) for p in Lf])
    drop = (posed[near, 1] - Vf[near, 1]) / b.eye_distance
    pairs = edge_face_pairs(T)
    folds = int(((turn_degrees(Vf, T, pairs) < 20) & (turn_degrees(posed, T, pairs) > 40)).sum())
    return b, drop, folds


def one_point_for_both_middles(L, offset):
    """``L`` with both inner lips' middles (62, 66) on one point, as a detector puts them where the lips touch:
    their midpoint, ``offset`` eye distances up."""
    _, ed = eyes_of(L)
    up = (L[27] - L[8]) / np.linalg.norm(L[27] - L[8])
    found = L.copy()
    found[[LIP_UPPER_INNER, LIP_LOWER_INNER]] = L[[LIP_UPPER_INNER, LIP_LOWER_INNER]].mean(0) + offset * ed * up
    return found


@needs_makehuman
@pytest.mark.parametrize("offset", [-0.04, 0.04])
def test_touching_lips_given_one_point_for_both_inner_middles_open_round(offset):
    """An identity the fix was not tuned on, its lips apart in the mesh but touching, with both inner lips' middles
    (62, 66) on one point as a detector puts them, 0.04 eye distances above or below their midpoint: the lips are not
    taken for joined, and AU27 opens the mouth as with the true landmarks (the upper lip stays, the lower lip's
    middle drops at least as far as its sides: no beak; new folds about as few), not a scalloped beak."""
    ch = build(Spec("asian-male-young-cm", {"asian-male-young": 1.0}, unit="cm"))
    V, T, L = ch.vertices, ch.triangles, ch.landmarks
    truth, drop_true, folds_true = au27_opened(V, T, L, L)
    b, drop, folds = au27_opened(V, T, L, one_point_for_both_middles(L, offset))
    assert not any("lips are joined" in n for n in truth.notes + b.notes)
    assert abs(drop[LIP_UPPER_INNER]) <= 0.08
    assert -drop[LIP_LOWER_INNER] >= max(-drop[65], -drop[67]) and -drop[LIP_LOWER_INNER] >= 0.25
    assert folds <= max(2 * folds_true, folds_true + 4), (folds, folds_true)


@needs_makehuman
@pytest.mark.parametrize("offset", [0.0, 0.01])
def test_one_point_on_lips_a_decimation_merged_opens_as_merged_rims(offset):
    """The development set's decimated head, its rims merged at the middle, given one point for both inner lips'
    middles (a detector's): split onto the two rims by the mesh (``bind._rims_merged_at``), read as merged rims as
    with the true landmarks, not as lips in one line, and AU27 drops the lower lip's middle as the true landmarks do
    (not a beak: read as one line it dropped 0.17-0.27 eye distances, its thirds 0.05-0.07), the upper lip staying."""
    ch = build(SPECS["decimated-cm"])
    V, T, L = ch.vertices, ch.triangles, ch.landmarks
    truth, drop_true, folds_true = au27_opened(V, T, L, L)
    b, drop, folds = au27_opened(V, T, L, one_point_for_both_middles(L, offset))
    assert not truth.lips_one_line and not b.lips_one_line
    assert np.array_equal(truth.face_landmarks, truth.frame.to_face(L))  # given apart: kept as given
    lips = [LIP_UPPER_INNER, LIP_LOWER_INNER]
    assert np.all(np.abs(drop[lips] - drop_true[lips]) <= 0.05), (drop[lips], drop_true[lips])
    assert -drop[LIP_LOWER_INNER] >= max(-drop[65], -drop[67])
    assert folds <= max(2 * folds_true, folds_true + 4), (folds, folds_true)


@needs_makehuman
def test_the_mouth_bag_reads_the_rims_one_found_point_was_split_onto():
    """decimated-cm given one point for both inner lips' middles: the binding's landmarks carry the two rims it split
    the point onto (two skin vertices, the upper one higher; every other landmark as given), and the mouth bag is made
    from them, not from the point (the bag centred on the mouth line the binding shares the jaw's turn about), spanning
    both rims."""
    ch = build(SPECS["decimated-cm"])
    V, T, L = ch.vertices, np.asarray(ch.triangles), ch.landmarks
    given = one_point_for_both_middles(L, 0.0)
    model = retarget(load_face("default"), fit_face(V, T, given)[0])
    b = HeadBinding(model, V, T, landmarks=given)
    f, Lf, lips = model.frame, b.face_landmarks, [LIP_UPPER_INNER, LIP_LOWER_INNER]
    others = np.setdiff1d(np.arange(len(Lf)), lips)
    assert np.array_equal(Lf[others], f.to_face(given)[others])
    skin = b.Vf[b.skin]
    upper, lower = (np.flatnonzero((skin == p).all(axis=1)) for p in Lf[lips])
    assert len(upper) == len(lower) == 1 and upper != lower and Lf[LIP_UPPER_INNER, 1] > Lf[LIP_LOWER_INNER, 1]
    bag = f.to_face(head_mouth_bag(b, T)[0])
    skin_mask = b.parts.mask("skin")
    assert np.allclose(bag, mouth_bag(b.Vf, T, skin_mask, Lf, b.eye_distance)[0], atol=1e-6 * b.eye_distance)
    assert not np.allclose(bag, mouth_bag(b.Vf, T, skin_mask, f.to_face(given), b.eye_distance)[0],
                           atol=1e-6 * b.eye_distance)
    assert bag[:, 1].max() > Lf[LIP_UPPER_INNER, 1] and bag[:, 1].min() < Lf[LIP_LOWER_INNER, 1]


def test_one_point_is_split_only_where_a_lining_lies_behind_it():
    """Lips one row of vertices (a voxel remesh's, no mouth's lining behind them) keep one point as it is; with a
    lining joined to it the point's vertex is one rim and its neighbour across the mouth line the other, the upper
    one higher."""
    # A strip of skin across the mouth line: rows at heights 1, 0 (the point's) and -1, facing forward.
    x = np.array([-1.0, 0.0, 1.0])
    P = np.array([[xi, y, 0.0] for y in (1.0, 0.0, -1.0) for xi in x])
    Ts = np.array([[0, 3, 1], [1, 3, 4], [1, 4, 2], [2, 4, 5], [3, 6, 4], [4, 6, 7], [4, 7, 5], [5, 7, 8]])
    normals = np.tile([0.0, 0.0, 1.0], (len(P), 1))
    point = P[4] + [0.0, 0.0, 0.01]
    assert bind._rims_merged_at(P, Ts, normals, 4, 4, point, 10.0) == (4, 4)  # one row: no lining
    lining = normals.copy()
    lining[4] = [0.0, 0.4, -0.9]  # faces into the mouth: the upper rim merged with the lining (decimated-cm's)
    assert bind._rims_merged_at(P, Ts, lining, 4, 4, point, 10.0) == (4, 7)
    lining[4], lining[3] = [0.0, 0.8, 0.6], [0.0, -0.5, -0.8]  # faces the upper lip: the lower lip's rim
    assert bind._rims_merged_at(P, Ts, lining, 4, 4, point, 10.0) == (1, 4)
    far = P[4] + [0.0, 0.0, 1.0]  # no vertex near the point, nor the skin (off it)
    assert bind._rims_merged_at(P, Ts, lining, 4, 4, far, 10.0) == (4, 4)


def test_a_point_between_a_coarse_mouths_vertices_is_split_onto_the_edge_across_the_mouth_line():
    """A mouth coarser than its lips (no vertex within RIMS_NEAR_IOD of the one point for both inner lips' middles):
    the point's triangle's edge across the mouth line nearest it gives the two rims, the upper one higher, where a
    lining is joined to them; a point off the skin, or no lining, keeps the point's vertex."""
    x = np.array([-1.0, 0.0, 1.0])
    P = np.array([[xi, y, 0.0] for y in (1.0, 0.0, -1.0) for xi in x])
    Ts = np.array([[0, 3, 1], [1, 3, 4], [1, 4, 2], [2, 4, 5], [3, 6, 4], [4, 6, 7], [4, 7, 5], [5, 7, 8]])
    normals = np.tile([0.0, 0.0, 1.0], (len(P), 1))
    lining = normals.copy()
    lining[3] = [0.0, 0.0, -1.0]  # faces into the head, joined to 4
    point = np.array([0.3, -0.5, 0.0])  # on triangle (4, 7, 5), 0.58 from 4 and 7: over RIMS_NEAR_IOD of 5
    ed = 0.5 / bind.RIMS_NEAR_IOD
    assert bind._rims_merged_at(P, Ts, lining, 4, 4, point, ed) == (4, 7)  # the edge 4-7, not 7-5 (as aside)
    assert bind._rims_merged_at(P, Ts, normals, 4, 4, point, ed) == (4, 4)  # no lining: one row
    assert bind._rims_merged_at(P, Ts, lining, 4, 4, point + [0.0, 0.0, 1.0], ed) == (4, 4)  # off the skin


@needs_makehuman
def test_inner_lips_nearest_one_vertex_of_a_decimated_mouth_are_read_as_its_merged_rims():
    """A character decimated to 1,800 vertices has its true inner lips' middles (0.032 eye distances apart, over
    LIP_LINE_IOD) nearest one vertex, its merged rims' with a lining behind it: once read as lips in one line, AU27
    dropped the lower lip's middle 0.31 eye distances, its outer edge (landmark 57) 0.45; read as merged rims, the
    lower lip drops as one."""
    ch = build(SPECS["african-asian-female-young-mm"])
    V, T = decimate(*ch.joined(), 1800)
    L = ClosestPoint(V, T).query(ch.landmarks)[3]
    middles = np.concatenate([L, (L[[LIP_LOWER_INNER]] + L[[57]]) / 2])  # the lower lip's middle appended
    b, drop, _ = au27_opened(V, T, middles, L)
    assert not b.lips_one_line
    assert -drop[68] >= 0.8 * -drop[57], (drop[68], drop[57])
