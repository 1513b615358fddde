"""The MakeHuman development set, the unit estimate and the landmark gate (issue #39)."""
import json

import numpy as np
import pytest
from pdeface.assets import load_head, load_head_shapes
from pdeface.au.modelfile import load_face, save_model
from pdeface.cli import main
from pdeface.io.meshio import write_mesh
from pdeface.landmark_scheme import INNER_LIPS, LOWER_LIDS, MIRROR, eye_distance
from pdeface.landmarks import available as mediapipe_available
from pdeface.landmarks.gate import Verdict, check, require
from pdeface.mesh import Mesh
from pdeface.rigid import rotation_vector_matrix
from pdeface.surface.fit import fit_face
from pdeface.surface.frame import UNITS_MM, estimate_unit, face_frame

from scripts.devset import annotate, makehuman
from scripts.devset.characters import (
    ANNOTATION,
    SPECS,
    UNIT_MM,
    annotated_indices,
    annotated_points,
    annotated_skin_points,
    build,
)

needs_makehuman = pytest.mark.skipif(not makehuman.available(), reason="needs ../shared/data/makehuman")
needs_mediapipe = pytest.mark.skipif(not mediapipe_available(), reason='needs pip install "pdeface[landmarks]"')


@pytest.fixture(scope="module")
def ict():
    mesh, lm = load_head()
    return mesh, mesh.triangles()[0], lm, load_head_shapes()


@needs_makehuman
def test_the_annotated_vertices_are_skin_mirror_each_other_and_read_top_down():
    base = makehuman.read_base()
    idx = annotated_indices()
    assert len(idx) == 68 and len(set(idx.tolist())) == 68
    skin = makehuman.triangles(base.group_quads("body"))
    assert np.isin(idx, np.unique(skin)).all()
    L = annotated_points(base.vertices)
    assert np.allclose(L, base.vertices[idx])  # the vertices themselves
    assert np.abs(L - L[list(MIRROR)] * [-1, 1, 1]).max() < 1e-6  # the base mesh is symmetric in x
    y = L[:, 1]
    assert y[17:27].mean() > y[36:48].mean() > y[33] > y[48:68].mean() > y[8]
    assert L[45, 0] > L[42, 0] > 0 > L[39, 0] > L[36, 0]  # +x is the subject's left (the scheme's left eye)


@needs_makehuman
def test_the_set_covers_what_the_issue_asks():
    specs = list(SPECS.values())
    assert len(specs) >= 20
    assert {"m", "cm", "in", "dm"} <= {s.unit for s in specs}
    assert {"T", "A"} <= {s.pose for s in specs if s.body} and any(s.body and s.head_turn for s in specs)
    assert {"decimate", "voxel"} <= {s.remesh for s in specs}
    assert {"none", "merged", "separate"} <= {s.eyeballs for s in specs}
    assert any(s.mouth_open == 0.2 for s in specs) and any(s.style and max(s.style.values()) >= 1.5 for s in specs)
    assert len({next(iter(s.identity), "base").split("-")[0] for s in specs}) >= 4


@needs_makehuman
def test_a_character_carries_its_landmarks_through_units_axes_and_remeshing():
    base = makehuman.read_base()
    dm = build(SPECS["base-dm"])
    assert np.allclose(dm.landmarks, annotated_points(base.vertices))
    assert dm.mm_per_unit == 100.0 and 55 < dm.eye_distance * dm.mm_per_unit < 70
    sep = build(SPECS["eyes-teeth-separate-in"])
    assert set(sep.parts) == {"l-eye", "r-eye", "upper-teeth", "lower-teeth", "tongue"}
    assert sep.mm_per_unit == UNIT_MM["in"]
    # The landmarks sit on the character's own surface, remeshed or not.
    from pdeface.geometry import ClosestPoint

    dec = build(SPECS["decimated-cm"])
    assert 2500 < len(dec.vertices) < 3500
    d = ClosestPoint(dec.vertices, dec.triangles).query(dec.landmarks)[0]
    assert d.max() < 1e-9
    assert ClosestPoint(dm.vertices, dm.triangles).query(dm.landmarks)[0].max() < 1e-3
    body = build(SPECS["body-A-turn40-m"])
    assert np.ptp(body.vertices[:, 1]) * body.mm_per_unit > 1400  # a whole body, metres, +y up
    # The head turned 40°: the eye line turns 40° about the vertical.
    r, l = body.landmarks[36:42].mean(0), body.landmarks[42:48].mean(0)
    assert np.degrees(np.arctan2(-(l - r)[2], (l - r)[0])) == pytest.approx(40, abs=2)


@needs_makehuman
def test_a_voxel_remeshed_face_faces_the_way_its_original_does():
    """Every quad of the voxel remesher faces out, as a remesher's do (its y-facing quads had faced in: the
    face's shading, and the detector's reading of it, turned inside out under the nose, brows and lips)."""
    from dataclasses import replace

    from pdeface.geometry import ClosestPoint

    vox = build(SPECS["voxel-m"])
    orig = build(replace(SPECS["voxel-m"], remesh="none"))

    def normals(V, T):
        n = np.cross(V[T[:, 1]] - V[T[:, 0]], V[T[:, 2]] - V[T[:, 0]])
        return n / np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-30)

    V, T = vox.vertices, vox.triangles
    centres = V[T].mean(1)
    _, tri, _, _ = ClosestPoint(orig.vertices, orig.triangles).query(centres)
    agree = np.einsum("ij,ij->i", normals(V, T), normals(orig.vertices, orig.triangles)[tri])
    eyes = vox.eye_distance
    face = np.linalg.norm(centres - vox.landmarks[30], axis=1) < 1.2 * eyes  # the face around the nose tip
    assert face.sum() > 1000
    assert np.mean(agree[face] < 0) < 0.03  # 0.27 before; the rest: folds of the projection in the ears


@needs_makehuman
@needs_mediapipe
def test_on_the_voxel_remeshed_character_the_found_landmarks_give_its_unit():
    """Found on the voxel remesh as on the original mesh (its inside-out quads had put the nose and mouth
    a quarter of the eye distance off and the unit 38 % off)."""
    from pdeface.landmarks.headfind import detect_anywhere

    ch = build(SPECS["voxel-m"])
    found = detect_anywhere(ch.vertices, ch.triangles)
    assert found.mm_per_unit == pytest.approx(ch.mm_per_unit, rel=0.1)
    err = np.linalg.norm(found.points - ch.landmarks, axis=1) / ch.eye_distance
    assert np.median(err[27:36]) < 0.1 and np.median(err[48:68]) < 0.1  # nose, mouth


@needs_makehuman
@pytest.mark.parametrize("name", ["base-dm", "asian-female-old-in", "stylised-nose-mouth-cm", "game-unit-168mm",
                                  "african-asian-female-young-mm", "african-male-old-m"])
def test_the_unit_is_estimated_from_the_face_at_any_scale(name):
    ch = build(SPECS[name])
    unit, mm = estimate_unit(ch.landmarks)
    assert mm == pytest.approx(ch.mm_per_unit, rel=0.10)
    assert unit == (ch.spec.unit if ch.spec.unit in UNITS_MM else "estimated")


@needs_makehuman
def test_the_unit_is_within_10_percent_on_every_character_where_it_snaps_to_no_name():
    """At 0.01, 3.16 and 100,000 mm per unit (none of mm, cm, dm, m, in within 30 %) the estimate is the face's own:
    within 10 % on each of the development set's characters (stylised, bodies, remeshed), from its true landmarks."""
    for name, spec in SPECS.items():
        ch = build(spec)
        for mm in (0.01, 10 ** 0.5, 1e5):
            unit, estimate = estimate_unit(ch.landmarks * ch.mm_per_unit / mm)
            assert unit == "estimated" and estimate == pytest.approx(mm, rel=0.10), name


def test_ict_heads_get_their_unit_in_every_scale(ict):
    mesh, _, lm, shapes = ict
    for name in ("identity003", "identity017"):
        L = (mesh.vertices + shapes[name])[lm]
        for unit, per_cm in (("cm", 1.0), ("mm", 10.0), ("m", 0.01), ("in", 1 / 2.54), ("dm", 0.1)):
            assert estimate_unit(L * per_cm) == (unit, UNITS_MM[unit])
        assert estimate_unit(L * 10 / 168)[1] == pytest.approx(168, rel=0.1)
    for name in ["neutral"] + [f"identity{i:03d}" for i in range(20)]:  # all 21 heads, at 100 times their size
        L = (mesh.vertices + (shapes[name] if name in shapes else 0))[lm]
        assert estimate_unit(L * 100) == ("estimated", pytest.approx(0.1, rel=0.10)), name


@needs_makehuman
def test_the_base_mesh_in_decimetres_fits_instead_of_being_refused():
    ch = build(SPECS["base-dm"])
    frame = face_frame(ch.landmarks)
    assert (frame.unit, frame.scale) == ("dm", 100.0)


@needs_makehuman
def test_a_model_fitted_at_an_estimated_scale_saves_and_loads(tmp_path):
    ch = build(SPECS["game-unit-168mm"])
    model, _ = fit_face(ch.vertices, ch.triangles, ch.landmarks, n_curves=12, n_points=17)
    assert model.frame.unit == "estimated" and model.frame.scale == pytest.approx(168, rel=0.1)
    save_model(tmp_path / "f.npz", model)
    again = load_face(tmp_path / "f.npz")
    assert again.frame.unit == "estimated" and again.frame.scale == pytest.approx(model.frame.scale)


def test_true_landmarks_pass_the_gate_on_ict_turned_and_in_metres(ict):
    mesh, T, lm, _ = ict
    M = rotation_vector_matrix(np.radians([10, 30, 0])) * 0.01
    V = mesh.vertices @ M.T
    v = check(V[lm], V, T)
    assert v.passed, v.message()


@pytest.mark.parametrize("name", ["identity015", "identity019"])
def test_true_landmarks_pass_the_gate_on_ict_identities_with_lashes_over_the_lids(name, ict):
    mesh, T, lm, shapes = ict
    V = mesh.vertices + shapes[name]
    v = check(V[lm], V, T, "cm")  # the whole head: eyeballs and lashes, separate parts, in front of the lids
    assert v.passed, v.message()


@needs_makehuman
@pytest.mark.parametrize("name", ["base-dm", "parted-lips-cm", "eyes-teeth-merged-cm", "stylised-eyes-head-m",
                                  "stylised-chin-cheek-in"])
def test_true_landmarks_pass_the_gate_on_dev_characters(name):
    ch = build(SPECS[name])
    v = check(ch.landmarks, ch.vertices, ch.triangles)
    assert v.passed, v.message()


def _frame_shift(L, rows, d_face_mm, unit="cm"):
    f = face_frame(L, unit)
    out = L.copy()
    out[rows] = f.to_user(f.to_face(L[rows]) + d_face_mm)
    return out


def test_the_gate_names_the_group_and_the_check_that_fail(ict):
    mesh, T, lm, _ = ict
    V = mesh.vertices
    L = V[lm]
    eyes_mm = eye_distance(L) * 10
    cases = {
        # lower lids fallen 15 mm into the sockets, behind the lids (the issue's sculpted bust)
        ("eyes", "surface"): _frame_shift(L, LOWER_LIDS, [0, 0, -15]),
        # the right brow 25 % of the eye distance higher than the left
        ("brows", "mirror"): _frame_shift(L, list(range(17, 22)), [0, 0.25 * eyes_mm, 0]),
        # the brows 10 % of the eye distance lower, on the upper lids' fold (found so on hairless heads)
        ("brows", "height"): _frame_shift(L, list(range(17, 27)), [0, -0.1 * eyes_mm, 0]),
        # the mouth above the nose
        ("mouth", "order"): _frame_shift(L, list(range(48, 68)), [0, 60, 0]),
        # a mouth three times as wide
        ("mouth", "spacing"): np.where(np.isin(np.arange(68), range(48, 68))[:, None],
                                       L[48:68].mean(0) + 3 * (L - L[48:68].mean(0)), L),
        # one jaw point half an eye distance back along the contour (depth a frontal detector cannot see)
        ("jaw", "smooth"): _frame_shift(L, [3], [0, 0, -0.5 * eyes_mm]),
        # the jaw angles slid forward along the contour, level with the eyes (found so on MakeHuman heads)
        ("jaw", "depth"): _frame_shift(L, [5, 11], [0, 0, 0.2 * eyes_mm]),
        # the brows squeezed in from their ends by a fifth (their median point 12 % of the eye distance off)
        ("brows", "spacing"): np.where(np.isin(np.arange(68), range(17, 27))[:, None],
                                       L * [0.8, 1, 1] + [0.2 * L[27, 0], 0, 0], L),
    }
    for (group, what), P in cases.items():
        v = check(P, V, T, "cm")
        assert group in v.failures, (group, what, v.message())
        assert what in [c for c, _ in v.failures[group]], (group, what, v.message())
        with pytest.raises(Exception, match=f"{group}: .*{what}"):
            require(v)
        again = Verdict.from_json(json.loads(json.dumps(v.to_json())))  # as the add-on keeps it on the mesh
        assert again.failures == v.failures and again.message() == v.message() and not again.passed
    P = L.copy()
    P[list(INNER_LIPS)[:2]] = np.nan
    assert ("finite" in [c for c, _ in check(P).failures["mouth"]])


@needs_makehuman
@needs_mediapipe
def test_cli_stops_on_a_failing_gate_with_a_picture_and_accept_goes_on(tmp_path, capsys):
    ch = build(SPECS["stylised-chin-cheek-in"])  # its found jawline bends where no jaw does
    src = tmp_path / "mh.obj"
    write_mesh(src, Mesh.from_faces(ch.vertices, ch.triangles))
    out, img = tmp_path / "lm.json", tmp_path / "lm.png"
    code = main(["landmarks", str(src), "-o", str(out), "--image", str(img)])
    err = capsys.readouterr().err
    if code == 0:  # a detector that finds this face well: its points must then be near the annotated ones
        found = np.array(json.loads(out.read_text())["points"])
        assert np.median(np.linalg.norm(found - ch.landmarks, axis=1)) < 0.1 * ch.eye_distance
        return
    assert code == 2 and "fail the landmark gate" in err and img.exists() and not out.exists()
    assert any(f"{g}: " in err for g in ("jaw", "brows", "nose", "eyes", "mouth"))
    assert main(["landmarks", str(src), "-o", str(out), "--accept"]) == 0
    data = json.loads(out.read_text(), parse_constant=lambda c: pytest.fail(f"bare {c} in the JSON"))
    assert data["gate"]["passed"] is False and data["gate"]["failures"]
    assert main(["fit", str(src), "-o", str(tmp_path / "f.npz"), "--curves", "12", "--points", "17"]) == 2
    capsys.readouterr()
    assert main(["rig", str(src), "-o", str(tmp_path / "rig")]) == 2  # the one-go rig stops at the gate too
    assert "fail the landmark gate" in capsys.readouterr().err and not (tmp_path / "rig" / "keys.npz").exists()


@needs_makehuman
@pytest.mark.parametrize("name", ["body-A-cm", "body-T-m", "body-T-turn40-blender-cm", "body-A-turn40-m"])
def test_the_head_of_a_body_is_found_first_in_any_pose_and_axes(name, ict):
    from pdeface.landmarks.headfind import head_candidates

    ch = build(SPECS[name])
    best = head_candidates(ch.vertices, ch.triangles)[0]
    kept = ch.vertices[best.vertices]
    for i in (30, 8):  # the nose tip and the chin are in the head: their nearest vertices are kept
        nearest = np.linalg.norm(ch.vertices - ch.landmarks[i], axis=1).min()
        assert np.linalg.norm(kept - ch.landmarks[i], axis=1).min() == nearest
    up = np.array([0, 0, 1.0]) if ch.spec.axes == "blender" else np.array([0, 1.0, 0])
    assert best.up @ up > 0.95
    assert len(best.vertices) < 0.4 * len(ch.vertices)                        # the head, not the body
    mesh, T, _, _ = ict
    assert head_candidates(mesh.vertices, T) == []                            # a head is searched as it is


@needs_makehuman
@needs_mediapipe
def test_landmarks_of_a_turned_body_come_back_in_the_whole_mesh(ict):
    from pdeface.landmarks.headfind import detect_anywhere

    ch = build(SPECS["body-T-turn40-blender-cm"])
    found = detect_anywhere(ch.vertices, ch.triangles)
    assert found.view.startswith("head cut out")
    # indices in the whole mesh: each the nearest vertex, within an edge (5 mm here) of its point
    assert np.linalg.norm(ch.vertices[found.indices] - found.points, axis=1).max() < 0.15 * ch.eye_distance
    assert found.skin.shape == (len(ch.triangles),)
    # Found near the truth (the nose tip), at the body's own scale.
    assert np.linalg.norm(found.points[30] - ch.landmarks[30]) < 0.2 * ch.eye_distance
    assert found.mm_per_unit == pytest.approx(ch.mm_per_unit, rel=0.1)


@needs_makehuman
@needs_mediapipe
@pytest.mark.parametrize("name", ["stylised-eyes-head-m", "parted-lips-cm"])
def test_found_eye_and_mouth_points_stay_on_the_outer_surface_over_sockets_and_parted_lips(name):
    from pdeface.landmarks.headfind import detect_anywhere

    ch = build(SPECS[name])  # empty eye sockets; lips parted
    found = detect_anywhere(ch.vertices, ch.triangles)
    e = np.linalg.norm(found.points - ch.landmarks, axis=1) / ch.eye_distance
    # The nearest surface point put them in the socket or the lip slit, 0.5-1.1 eye distances off.
    assert e[36:48].max() < 0.2 and e[48:68].max() < 0.25, (e[36:48].max(), e[48:68].max())
    failures = check(found.points, ch.vertices, ch.triangles[found.skin]).failures  # the gate's surface check
    assert not [c for g in ("eyes", "mouth") for c, _ in failures.get(g, []) if c == "surface"], failures


@needs_makehuman
@pytest.mark.skipif(not annotate.ICT.joinpath("generic_neutral_mesh.obj").is_file(), reason="needs ICT-FaceKit")
def test_the_annotation_is_icts_generic_face_registered_onto_the_base():
    """The committed annotation is what scripts/devset/annotate.py makes, and sits where ICT's heads have them."""
    Vs, Ts, Ls, ict = annotate.ict_face()
    Vt, Tt, head = annotate.makehuman_head()
    Th = Tt[head[Tt].all(1)]
    X, residuals = annotate.register(Vs, Ts, Ls, Vt, Th, log=lambda *_: None)
    assert residuals[-1][1] < 0.002 and residuals[-1][1] < residuals[0][1]  # the face lies on the skin
    *_, to_skin = annotate.symmetric_points(X[Ls], Vt, Th)
    assert to_skin.max() < 0.02 * annotate.eye_distance(X[Ls])  # the registered landmarks lie on the skin
    idx, to_vertex = annotate.symmetric_vertices(X[Ls], Vt, Th)
    assert (idx == annotated_indices()).all()  # the committed annotation is the registration's
    assert np.median(to_vertex) < 0.05 * annotate.eye_distance(X[Ls])
    committed = annotated_points(makehuman.read_base().vertices)
    # Where the conventions differed, the annotation now lies among ICT's own heads (eye distances, ±0.02).
    heads = [Vs[Ls]] + [(Vs + ict.shape(f"identity{i:03d}"))[Ls] for i in range(20)]
    ict_stats = [annotate.statistics(L) for L in heads]
    ours = annotate.statistics(committed)
    for name in ["inner brows above the eye centres", "upper lids above the eye corners",
                 "lower lids below the eye corners", "upper-lid points' spread over eye width",
                 "inner lip line width (60-64)", "inner lip corners inside the mouth corners",
                 "jaw ends (0, 16) behind the eye centres"]:
        vals = [s[name] for s in ict_stats]
        assert min(vals) - 0.02 <= ours[name] <= max(vals) + 0.02, (name, ours[name], min(vals), max(vals))


@needs_makehuman
@pytest.mark.skipif(not annotate.ICT.joinpath("generic_neutral_mesh.obj").is_file(), reason="needs ICT-FaceKit")
def test_a_character_is_annotated_on_its_own_shape_not_with_the_bases_vertices_carried():
    """MakeHuman's young-woman target slides the base's brow vertices up the forehead: carried through it, they
    sit far above where ICT's heads have brows; annotated on the character's own shape (what the committed
    annotation holds), they sit among ICT's heads again."""
    from scripts.devset.characters import shape

    name = "caucasian-female-young-cm"
    Vs, Ts, Ls, ict = annotate.ict_face()
    _, Tt, head = annotate.makehuman_head()
    V = shape(SPECS[name])
    idx, corners, weights = annotate.annotate_shape(V, Vs, Ts, Ls, Tt[head[Tt].all(1)])
    assert (idx == annotated_indices(name)).all()  # the committed annotation is the registration's on its shape
    on_skin = np.einsum("ij,ijk->ik", weights, V[corners])
    # The committed points are the registration's to its rounding, which grows where the skin barely holds a point:
    # scipy 1.17 moved point 57 (the lower lip's middle) 1e-4 eye distances from the release that made the
    # annotation, and one BLAS thread instead of two moves 30 and 29 (the nose's tip and the bridge above it) 7e-4
    # and 5e-4; every other point moves 1.2e-5 at most, either way. Each is held to about ten times its own, far
    # below the 0.1 the carried ones are off.
    tolerance = np.full(68, 1e-4)
    tolerance[[29, 30, 57]] = 1e-3
    off = np.abs(annotated_skin_points(V, name) - on_skin).max(axis=1) / eye_distance(on_skin)
    assert (off <= tolerance).all(), {i: off[i] for i in np.flatnonzero(off > tolerance)}
    ch = build(SPECS[name])
    assert np.allclose(ch.landmarks, V[idx] * 10)  # the character (decimetres to cm) carries them
    heads = [Vs[Ls]] + [(Vs + ict.shape(f"identity{i:03d}"))[Ls] for i in range(20)]
    stat = "inner brows above the eye centres"
    ict_brows = np.mean([annotate.statistics(L)[stat] for L in heads])
    own, carried = annotate.statistics(V[idx])[stat], annotate.statistics(V[annotated_indices()])[stat]
    assert abs(own - ict_brows) < 0.05 and carried - ict_brows > 0.1  # carried: 0.15 eye distances too high


@needs_makehuman
def test_the_inner_lip_landmarks_lie_on_their_own_lip():
    """Where the lips touch, the registered inner-lip point's nearest vertex may be the other lip's, or the lip's
    inside behind its rim that a remesh merges with the other lip: the upper inner lip (61-63) stays on the upper
    lip's vertices, the lower (65-67) on the lower's, and the middles stay two vertices on the characters the keys
    are measured on (stylised-nose-mouth-cm had both middles on one lower-lip vertex, decimated-cm both near one)."""
    lower = annotate.lower_lip_side()
    names = [None, *json.loads(ANNOTATION.read_text())["characters"]]
    for name in names:
        idx = annotated_indices(name)
        assert not lower[idx[list(annotate.UPPER_INNER)]].any() and lower[idx[list(annotate.LOWER_INNER)]].all(), name
    for name in ("stylised-nose-mouth-cm", "decimated-cm", "base-dm"):
        ch = build(SPECS[name])
        near = [np.argmin(np.linalg.norm(ch.vertices - ch.landmarks[i], axis=1)) for i in (62, 66)]
        assert near[0] != near[1], name  # bench_keys_devset's AU27 lip gap is measurable
        assert ch.landmarks[62, 1] > ch.landmarks[66, 1] - 0.01 * ch.eye_distance, name  # upper above lower


@needs_makehuman
@pytest.mark.parametrize("name", ["base-dm", "caucasian-female-young-cm", "decimated-cm"])
def test_the_registered_skin_points_lie_on_the_skin_beside_their_vertices(name):
    """bench_devset's second truth: the registered landmarks before the snap to a vertex, on the character's skin
    (a remeshed one's new surface), carried like the vertices, near them (the snap moves a point at most to its
    triangle's far corner), and mirror images left to right."""
    from pdeface.geometry import ClosestPoint

    ch = build(SPECS[name])
    S, L, ed = ch.skin_landmarks, ch.landmarks, ch.eye_distance
    assert S.shape == (68, 3)
    assert ClosestPoint(ch.vertices, ch.triangles).query(S)[0].max() < 1e-4 * ed  # on the skin (a quad: its halves)
    apart = np.linalg.norm(S - L, axis=1) / ed
    assert apart.max() < 0.25 and np.median(apart) > 0  # near, and not the vertices themselves
    if ch.spec.remesh == "none":
        assert np.abs(S - S[list(MIRROR)] * [-1, 1, 1]).max() < 0.005 * ed


def test_jaw_point_errors_split_along_and_across_the_jawline(ict):
    """bench_devset's per jaw point figure: a jaw point slid along the true jawline counts along (+ toward the chin
    on either side), one pushed off it across."""
    from scripts.bench.bench_devset import jaw_point_errors

    mesh, _, lm, _ = ict
    true = mesh.vertices[lm].astype(np.float64)
    eyes = eye_distance(true)
    found = true.copy()
    step = 0.05 * eyes
    for j in (3, 13):  # toward the chin: from 3 to 4, and from 13 to 12
        toward = true[j + 1 if j < 8 else j - 1] - true[j - 1 if j < 8 else j + 1]
        found[j] += step * toward / np.linalg.norm(toward)
    out = face_frame(true).rotation[2]  # forward: across the jawline at the chin
    found[8] += step * out
    along, across = jaw_point_errors(found, true, eyes)
    assert along[3] == pytest.approx(5.0, abs=0.5) and along[13] == pytest.approx(5.0, abs=0.5)
    assert across[3] < 1.0 and across[13] < 1.0
    assert abs(along[8]) < 0.5 and across[8] == pytest.approx(5.0, abs=0.5)
    unmoved = [j for j in range(17) if j not in (3, 8, 13)]
    assert np.allclose(along[unmoved], 0) and np.allclose(across[unmoved], 0)


@needs_makehuman
@pytest.mark.parametrize("name", ["base-dm", "asian-female-old-in", "caucasian-male-old-dm-eyes",
                                  "stylised-nose-mouth-cm", "body-A-cm"])
def test_the_jaws_lower_sides_come_back_to_the_characters_own_depth(name, monkeypatch):
    # MakeHuman's jaws reach back farther or less far than ICT's: the lower sides (2-4, 12-14) of the registered
    # skin points, slid 0.15 eye distances forward or back on the skin, come back near their own depth from the
    # chin's points (6, 10), where the eyes' template depth alone leaves them 0.09-0.15 off on these characters.
    from pdeface.geometry import ClosestPoint
    from pdeface.landmarks import contour

    ch = build(SPECS[name])
    V, T, L = ch.vertices, ch.triangles, ch.skin_landmarks
    rows = list(contour.BEHIND_CHIN)
    f, eyes = face_frame(L), eye_distance(L)
    F = f.to_face(L[rows])
    F[:, 2] += np.resize([0.15, -0.15], len(rows)) * eyes * f.scale
    slid = L.copy()
    slid[rows] = ClosestPoint(V, T).query(f.to_user(F))[3]

    def off(P):  # the sides' median distance from their own (eye distances)
        return np.median(np.linalg.norm(P[rows] - L[rows], axis=1)) / eyes

    placed = off(contour.upper_jaw_at_template_depth(V, T, slid))
    monkeypatch.setattr(contour, "BEHIND_CHIN", {})  # the eyes' template depth alone
    eyes_only = off(contour.upper_jaw_at_template_depth(V, T, slid))
    assert off(slid) > 0.1 and placed < 0.035 and eyes_only > 2 * placed, (off(slid), placed, eyes_only)


@needs_makehuman
@pytest.mark.parametrize("name", ["base-dm", "asian-female-old-in", "caucasian-male-old-dm-eyes",
                                  "stylised-nose-mouth-cm", "body-A-cm"])
def test_the_jaws_sides_slid_along_the_contour_come_back_to_the_characters_own(name):
    # How high along the contour MakeHuman's jaw sides lie differs from character to character (the true jaw ends
    # from 0.1 below to 0.2 above the eye centres): the sides (0-4, 12-16) of the registered skin points, slid 0.15
    # eye distances up or down on the skin, come back near their own once ICT's sides are laid onto the skin.
    from pdeface.geometry import ClosestPoint
    from pdeface.landmarks import contour

    ch = build(SPECS[name])
    V, T, L = ch.vertices, ch.triangles, ch.skin_landmarks
    rows = list(contour.SIDES[0] + contour.SIDES[1])
    f, eyes = face_frame(L), eye_distance(L)
    F = f.to_face(L[rows])
    F[:, 1] += np.resize([0.15, -0.15], len(rows)) * eyes * f.scale
    slid = L.copy()
    slid[rows] = ClosestPoint(V, T).query(f.to_user(F))[3]

    def off(P):  # the sides' median distance from their own (eye distances)
        return np.median(np.linalg.norm(P[rows] - L[rows], axis=1)) / eyes

    placed = contour.jaw_sides_from_template(V, T, slid)
    assert off(slid) > 0.1 and off(placed) < 0.045, (off(slid), off(placed))


@needs_makehuman
@pytest.mark.parametrize("name", ["caucasian-male-old-dm-eyes", "stylised-parted-decimated-dm", "asian-female-old-in",
                                  "body-T-m"])
def test_the_jaws_angles_slid_forward_along_the_contour_come_back_to_the_characters_own(name):
    # The detector put MakeHuman's jaw angles a median 0.06 eye distances too far forward along the contour (up to
    # 0.22): the angles (5, 11) of the registered skin points, slid 0.15 eye distances forward on the skin, come back
    # near their own, placed by the points around them (ICT's proportions, on characters the map never saw).
    from pdeface.landmarks import contour

    ch = build(SPECS[name])
    V, T, L = ch.vertices, ch.triangles, ch.skin_landmarks
    rows, eyes = list(contour.ANGLES), eye_distance(L)
    slid = _moved_in_face_frame(V, T, L, rows, (0, 0, 0.15))

    def off(P):  # the angles' distance from their own (eye distances)
        return np.linalg.norm(P[rows] - L[rows], axis=1) / eyes

    placed = contour.jaw_angles_from_neighbours(V, T, slid)
    assert off(slid).min() > 0.1 and off(placed).max() < 0.06, (off(slid), off(placed))


@needs_makehuman
@pytest.mark.parametrize("name", ["caucasian-male-old-dm-eyes", "game-unit-168mm", "head-turn40-m", "body-A-cm"])
def test_the_chins_points_slid_down_come_back_to_the_characters_own(name):
    # The detector put MakeHuman's chin points low, under the chin's front (its point 8 a median 0.04 eye distances
    # low and 0.04 back): the chin's points (7-9) of the registered skin points, slid 0.1 eye distances down on the
    # skin, come back near their own, 8 on the profile as far behind the pogonion as ICT's (MakeHuman's own lie
    # 0.05-0.10 behind it, ICT's 0.089), 7 and 9 carried by the points around them.
    from pdeface.landmarks import contour

    ch = build(SPECS[name])
    V, T, L = ch.vertices, ch.triangles, ch.skin_landmarks
    rows, eyes = [7, contour.CHIN, 9], eye_distance(L)
    slid = _moved_in_face_frame(V, T, L, rows, (0, -0.1, 0))

    def off(P):  # the chin's points' distance from their own (eye distances)
        return np.linalg.norm(P[rows] - L[rows], axis=1) / eyes

    placed = contour.chin_on_profile(V, T, slid)
    assert off(slid).min() > 0.05 and off(placed).max() < 0.035, (off(slid), off(placed))


def _moved_in_face_frame(V, T, L, rows, shift):
    """``L`` with ``rows`` moved by ``shift`` (x, y, z: eye distances in the face frame), then onto the surface
    ``(V, T)``."""
    from pdeface.geometry import ClosestPoint

    f, eyes = face_frame(L), eye_distance(L)
    F = f.to_face(L[rows])
    F += np.asarray(shift, np.float64) * eyes * f.scale
    moved = L.copy()
    moved[rows] = ClosestPoint(V, T).query(f.to_user(F))[3]
    return moved


@needs_makehuman
def test_lid_points_on_the_margins_curl_come_back_to_its_front_edge():
    # MakeHuman's lid margins curl back into the empty sockets: a lid point found a little into the opening
    # lands on the curl, behind the lid (as the map's did, 0.05-0.07 eye distances); it comes back to the
    # margin's front edge.
    from pdeface.landmark_scheme import UPPER_LIDS
    from pdeface.landmarks.eyes import lids_on_margin

    ch = build(SPECS["base-dm"])
    L, eyes = ch.skin_landmarks, ch.eye_distance
    moved = _moved_in_face_frame(ch.vertices, ch.triangles, L, UPPER_LIDS, (0, -0.01, -0.06))
    f = face_frame(L)
    behind = (f.to_face(L) - f.to_face(moved))[UPPER_LIDS, 2] / (eyes * f.scale)
    back = lids_on_margin(ch.vertices, ch.triangles, moved)
    before, after = (np.linalg.norm(P[UPPER_LIDS] - L[UPPER_LIDS], axis=1) / eyes for P in (moved, back))
    assert behind.min() > 0.03 and after.max() < 0.015, (behind, before, after)
    others = np.setdiff1d(np.arange(68), UPPER_LIDS)
    assert np.array_equal(back[others], moved[others])  # only the lid points move
    assert np.abs(lids_on_margin(ch.vertices, ch.triangles, L) - L).max() < 0.01 * eyes  # on the edge: stay


@needs_makehuman
def test_eye_corners_sunk_into_the_crease_come_forward_onto_the_skin_in_front():
    # The snap takes a mapped eye corner to its nearest skin point: in a deep crease its back wall, behind the
    # lids' fold (found 0.04-0.26 eye distances behind the true corners). Pushed 0.06 back and onto the skin, the
    # corners come forward onto the skin seen straight on, near the registered points; true corners stay.
    from pdeface.landmarks.eyes import CORNERS, corners_on_skin_front

    rows = [j for pair in CORNERS for j in pair]
    ch = build(SPECS["base-dm"])
    L, eyes = ch.skin_landmarks, ch.eye_distance
    moved = _moved_in_face_frame(ch.vertices, ch.triangles, L, rows, (0, 0, -0.06))
    f = face_frame(L)
    behind = (f.to_face(L) - f.to_face(moved))[rows, 2] / (eyes * f.scale)
    back = corners_on_skin_front(ch.vertices, ch.triangles, moved)
    before, after = (np.linalg.norm(P[rows] - L[rows], axis=1) / eyes for P in (moved, back))
    assert behind.min() > 0.05 and after.max() < 0.025, (behind, before, after)
    others = np.setdiff1d(np.arange(68), rows)
    assert np.array_equal(back[others], moved[others])  # only the corners move
    assert np.array_equal(corners_on_skin_front(ch.vertices, ch.triangles, L), L)  # on the skin's front: stay


@needs_makehuman
def test_inner_lip_middles_on_the_lips_front_go_back_into_the_seam_of_closed_lips():
    # The face mesh's inner lip points lie on the lips' fronts; moved 0.03 eye distances forward onto the closed
    # lips, the middles go back into the seam, nearer the registered points (the seam's bottom lies a little
    # behind them: the middle column's deepest); over the slit of parted lips they stay.
    from pdeface.landmarks.mouth import INNER_MIDDLES, inner_lips_in_seam

    rows = list(INNER_MIDDLES)
    for name, closed in (("african-male-old-m", True), ("parted-lips-cm", False)):
        ch = build(SPECS[name])
        L, eyes = ch.skin_landmarks, ch.eye_distance
        moved = _moved_in_face_frame(ch.vertices, ch.triangles, L, rows, (0, 0, 0.03))
        back = inner_lips_in_seam(ch.vertices, ch.triangles, moved)
        others = np.setdiff1d(np.arange(68), rows)
        assert np.array_equal(back[others], moved[others])  # only the middles move
        if not closed:
            assert np.array_equal(back, moved)
            continue
        f = face_frame(L)
        deeper = (f.to_face(moved) - f.to_face(back))[rows, 2] / (eyes * f.scale)
        before, after = (np.linalg.norm(P[rows] - L[rows], axis=1) / eyes for P in (moved, back))
        assert deeper.min() > 0.02 and np.median(after) < 0.5 * np.median(before) and after.max() < 0.045, (
            deeper, before, after)


@needs_makehuman
@pytest.mark.parametrize("name", ["base-dm", "parted-lips-cm"])
def test_outer_eye_corners_on_the_upper_lid_go_to_the_end_of_the_eyes_opening(name):
    # The face mesh puts an outer eye corner up to 0.09 eye distances up and forward on the upper lid: moved 0.05 up
    # and 0.03 forward onto the skin, the outer corners go to the lateral end of the eye's opening, near the
    # registered corners; nothing else moves, and true corners stay.
    from pdeface.landmarks.eyes import outer_corners_at_opening_end

    ch = build(SPECS[name])
    L, eyes, rows = ch.skin_landmarks, ch.eye_distance, [36, 45]
    moved = _moved_in_face_frame(ch.vertices, ch.triangles, L, rows, (0, 0.05, 0.03))
    back = outer_corners_at_opening_end(ch.vertices, ch.triangles, moved)
    before, after = (np.linalg.norm(P[rows] - L[rows], axis=1) / eyes for P in (moved, back))
    assert before.min() > 0.05 and after.max() < 0.02, (before, after)
    others = np.setdiff1d(np.arange(68), rows)
    assert np.array_equal(back[others], moved[others])
    assert np.array_equal(outer_corners_at_opening_end(ch.vertices, ch.triangles, L), L)


@needs_makehuman
@pytest.mark.parametrize("name", ["base-dm", "parted-lips-cm"])
def test_the_brows_are_posed_by_the_outer_eye_corners_at_the_openings_end(name):
    # The brows are read off ICT's head laid onto the found eyes and nose: outer corners left up and forward on the
    # upper lid (as the face mesh puts them) tilt it, so the pipeline takes them to the opening's end first. Raised
    # 0.08 and put 0.03 forward, they move the brows over 0.003 eye distances from those the true corners give;
    # taken to the opening's end first, a third of that at most.
    import inspect

    from pdeface.landmarks import pipeline
    from pdeface.landmarks.brows import BROWS, brows_from_upper_face
    from pdeface.landmarks.eyes import outer_corners_at_opening_end

    source = inspect.getsource(pipeline.detect)
    assert source.index("outer_corners_at_opening_end(") < source.index("brows_from_upper_face(")
    ch = build(SPECS[name])
    V, T, L, eyes, rows = ch.vertices, ch.triangles, ch.skin_landmarks, ch.eye_distance, list(BROWS)
    own = brows_from_upper_face(V, T, L)
    raised = _moved_in_face_frame(V, T, L, [36, 45], (0, 0.08, 0.03))
    tilted = brows_from_upper_face(V, T, raised)
    posed = brows_from_upper_face(V, T, outer_corners_at_opening_end(V, T, raised))
    off_tilted, off_posed = (np.linalg.norm(P[rows] - own[rows], axis=1).max() / eyes for P in (tilted, posed))
    assert off_tilted > 0.003 and off_posed < off_tilted / 3, (off_tilted, off_posed)


@needs_makehuman
@pytest.mark.parametrize("name", ["asian-female-old-in", "eyes-teeth-separate-in", "body-T-m"])
def test_brows_from_the_upper_face_lie_near_the_characters_own(name):
    # ICT's head laid onto a character's own eyes and nose carries its brows, lifted 0.1 eye distances up the forehead
    # first, back to within 5 % of the eye distance of the character's registered ones (median; 8 % at most), on
    # low-nasion characters, where ICT's brow region registered onto the skin slid up the forehead, and on a body
    # whose brows it pinched in alike.
    from pdeface.landmarks.brows import BROWS, brows_from_upper_face

    ch = build(SPECS[name])
    L, rows = ch.skin_landmarks, list(BROWS)
    moved = _moved_in_face_frame(ch.vertices, ch.triangles, L, rows, (0, 0.1, 0))
    back = brows_from_upper_face(ch.vertices, ch.triangles, moved)
    off = np.linalg.norm(back[rows] - L[rows], axis=1) / ch.eye_distance
    assert np.median(off) < 0.05 and off.max() < 0.08, off


@needs_makehuman
def test_an_outer_eye_corner_far_from_the_openings_end_stays():
    # Farther than OPENING_END_REACH from the opening's end the opening is not this corner's (a crease or a groove
    # joined to the slit): a corner put 0.2 eye distances up on the lid's skin stays where it is, the other goes.
    from pdeface.landmarks.eyes import OPENING_END_REACH, outer_corners_at_opening_end

    ch = build(SPECS["base-dm"])
    L, eyes = ch.skin_landmarks, ch.eye_distance
    moved = _moved_in_face_frame(ch.vertices, ch.triangles, L, [36], (0, 0.2, 0.03))
    moved = _moved_in_face_frame(ch.vertices, ch.triangles, moved, [45], (0, 0.05, 0.03))
    assert np.linalg.norm(moved[36] - L[36]) / eyes > OPENING_END_REACH
    back = outer_corners_at_opening_end(ch.vertices, ch.triangles, moved)
    assert np.array_equal(back[36], moved[36])
    assert np.linalg.norm(back[45] - L[45]) / eyes < 0.02


@needs_makehuman
@pytest.mark.parametrize("name", ["parted-lips-cm", "eyes-teeth-separate-in"])
def test_the_eyes_opening_looked_for_about_the_eye_is_the_whole_pictures(name):
    # outer_corners_at_opening_end draws the rows about the eye, not the whole picture: the same opening (and
    # raster there); a band that cuts the opening asks for the whole picture.
    from pdeface.landmark_scheme import eye_distance
    from pdeface.landmarks.eyes import EYES, HALF, SIZE, _opening_part
    from pdeface.landmarks.render import View
    from pdeface.surface.frame import face_frame

    ch = build(SPECS[name])
    L = ch.skin_landmarks
    R, eyes = face_frame(L).rotation, eye_distance(L)
    for ring, upper, lower in EYES:
        view = View.looking(R[2], R[1], L[list(ring)].mean(0), HALF * eyes, SIZE)
        x, y, _ = view.project(L)
        cx, cy = (int(np.round(c[[*upper, *lower]].mean())) for c in (x, y))
        whole_raster, whole = _opening_part(ch.vertices, ch.triangles, view, cx, cy, eyes)
        assert whole is not None and 1000 < whole.sum() < 0.2 * SIZE ** 2  # an opening between the lids
        rows = np.flatnonzero(whole.any(1))
        raster, part = _opening_part(ch.vertices, ch.triangles, view, cx, cy, eyes, (rows[0] - 1, rows[-1] + 1))
        assert np.array_equal(part, whole)
        near = slice(rows[0] - 4, rows[-1] + 5)  # what back_project may read beside the opening
        assert np.array_equal(raster.tri[near], whole_raster.tri[near])
        assert _opening_part(ch.vertices, ch.triangles, view, cx, cy, eyes, (cy, cy))[1] is False


@needs_makehuman
def test_lower_inner_lip_points_on_the_slits_top_edge_go_down_under_the_slit():
    # The face mesh reads parted lips as nearly closed and puts the lower lip's inner points (65-67) with the upper
    # lip's, on the slit's top edge: put there, they go down under the slit, onto the lower lip, near the registered
    # points; true points stay (beside a slit, and on closed lips).
    from pdeface.landmarks.mouth import lower_inner_lips_under_the_slit

    rows = [65, 66, 67]
    ch = build(SPECS["parted-lips-cm"])
    L, eyes = ch.skin_landmarks, ch.eye_distance
    moved = L.copy()
    moved[rows] = L[[63, 62, 61]]  # the upper lip's inner points above them
    back = lower_inner_lips_under_the_slit(ch.vertices, ch.triangles, moved)
    before, after = (np.linalg.norm(P[rows] - L[rows], axis=1) / eyes for P in (moved, back))
    assert before.min() > 0.1 and after.max() < 0.02, (before, after)
    others = np.setdiff1d(np.arange(68), rows)
    assert np.array_equal(back[others], moved[others])  # only the lower inner points move
    assert np.abs(lower_inner_lips_under_the_slit(ch.vertices, ch.triangles, L) - L).max() < 0.015 * eyes
    closed = build(SPECS["base-dm"])
    assert np.array_equal(lower_inner_lips_under_the_slit(closed.vertices, closed.triangles, closed.skin_landmarks),
                          closed.skin_landmarks)


def test_true_lid_and_inner_lip_points_stay_on_ict_heads(ict):
    # ICT's lid points lie on a thick margin's rounded edge, its eye corners on the skin's front, its inner lip points
    # in front of a slit between the lips, its subnasale at the profile's deepest point under the nose, its bridge's
    # middle at the generic head's shares of the nasion-to-tip chord, its lips' middles on their edges, its
    # lower lip's sides at the generic head's drop below the chord from the mouth corner to the lip's middle: no
    # step moves the true landmarks of a held-out identity (its skin alone, without eyeballs and lashes) by more than
    # a pixel or two.
    from pdeface.landmarks.eyes import corners_on_skin_front, lids_on_margin, outer_corners_at_opening_end
    from pdeface.landmarks.mouth import (
        inner_lip_corners_inset,
        inner_lips_in_seam,
        lower_inner_lips_under_the_slit,
        lower_lip_on_its_edge,
        lower_lip_sides_at_ict_drop,
        mouth_corners_at_seam_end,
        upper_lip_on_its_edge,
    )
    from pdeface.landmarks.nose import bridge_at_ict_shares, nose_bottom_at_subnasale
    from pdeface.mesh import connected_components

    mesh, T, lm, shapes = ict
    V = mesh.vertices + shapes["identity015"]
    labels = connected_components(len(V), T)
    skin = T[np.isin(labels[T[:, 0]], labels[lm])]
    L = V[lm]
    for step in (lids_on_margin, corners_on_skin_front, outer_corners_at_opening_end, inner_lips_in_seam,
                 nose_bottom_at_subnasale, inner_lip_corners_inset, mouth_corners_at_seam_end, bridge_at_ict_shares,
                 lower_lip_on_its_edge, upper_lip_on_its_edge, lower_inner_lips_under_the_slit,
                 lower_lip_sides_at_ict_drop):
        moved = np.linalg.norm(step(V, skin, L) - L, axis=1) * 10  # mm
        assert moved.max() < 0.5, (step.__name__, moved.max())


@needs_makehuman
@pytest.mark.parametrize("name", ["base-dm", "african-male-old-m"])
def test_the_nose_bottom_found_too_high_comes_down_to_the_subnasale(name):
    # On MakeHuman's long noses the face mesh puts the nose's bottom 0.03-0.04 eye distances too high, on the
    # columella; it comes down to the profile's deepest point under the nose, with the nostrils' bottom beside it.
    from pdeface.landmarks.nose import BESIDE, nose_bottom_at_subnasale

    ch = build(SPECS[name])
    L, eyes, rows = ch.skin_landmarks, ch.eye_distance, [33, *BESIDE]
    moved = _moved_in_face_frame(ch.vertices, ch.triangles, L, rows, (0, 0.04, 0))
    back = nose_bottom_at_subnasale(ch.vertices, ch.triangles, moved)
    before, after = (np.linalg.norm(P[rows] - L[rows], axis=1) / eyes for P in (moved, back))
    assert before.min() > 0.03 and (after < 0.75 * before).all() and after.max() < 0.03, (before, after)
    others = np.setdiff1d(np.arange(68), rows)
    assert np.array_equal(back[others], moved[others])  # only the nose's bottom moves


@needs_makehuman
@pytest.mark.parametrize("name", ["base-dm", "african-male-old-m"])
def test_the_bridge_middle_found_near_the_nasion_comes_down_to_icts_shares(name):
    # The face mesh puts the bridge's middle (28, 29) nearer the nasion on MakeHuman's long noses (0.28-0.34 and
    # 0.59-0.66 of the chord from 27 to 30, ICT's 0.33 and 0.65): moved up the bridge, they come back down onto the
    # profile at ICT's shares, near the registered points (which lie at 0.35-0.41 and 0.66-0.73); nothing else moves.
    from pdeface.geometry import ClosestPoint
    from pdeface.landmarks.nose import BRIDGE_MIDDLE, bridge_at_ict_shares, ict_bridge_shares

    ch = build(SPECS[name])
    L, eyes, rows = ch.skin_landmarks, ch.eye_distance, list(BRIDGE_MIDDLE)
    moved = _moved_in_face_frame(ch.vertices, ch.triangles, L, rows, (0, 0.05, -0.02))
    back = bridge_at_ict_shares(ch.vertices, ch.triangles, moved)
    before, after = (np.linalg.norm(P[rows] - L[rows], axis=1) / eyes for P in (moved, back))
    assert before.min() > 0.04 and (after < 0.75 * before).all() and after.max() < 0.035, (before, after)
    chord = L[30] - L[27]
    assert np.allclose((back[rows] - L[27]) @ chord / (chord @ chord), ict_bridge_shares(), atol=0.005)
    assert (ClosestPoint(ch.vertices, ch.triangles).query(back[rows])[0] < 0.002 * eyes).all()  # on the skin
    others = np.setdiff1d(np.arange(68), rows)
    assert np.array_equal(back[others], moved[others])


@needs_makehuman
@pytest.mark.parametrize("name", ["base-dm", "eyes-teeth-merged-cm"])
def test_lower_lip_points_found_on_the_curve_under_the_lip_come_up_to_its_edge(name):
    # The face mesh puts the lower lip's middle (56-58) up to 0.08 eye distances behind the lip's front, low on the
    # curve under the lip; moved there, they come back up their column to the lip's edge, near the registered
    # points; the registered points (on the edge) stay; nothing else moves.
    from pdeface.landmarks.mouth import LOWER_LIP, lower_lip_on_its_edge

    ch = build(SPECS[name])
    L, eyes, rows = ch.skin_landmarks, ch.eye_distance, list(LOWER_LIP)
    assert np.array_equal(lower_lip_on_its_edge(ch.vertices, ch.triangles, L), L)
    moved = _moved_in_face_frame(ch.vertices, ch.triangles, L, rows, (0, -0.05, -0.03))
    back = lower_lip_on_its_edge(ch.vertices, ch.triangles, moved)
    before, after = (np.linalg.norm(P[rows] - L[rows], axis=1) / eyes for P in (moved, back))
    assert before.min() > 0.035 and (after < 0.5 * before).all() and after.max() < 0.03, (before, after)
    others = np.setdiff1d(np.arange(68), rows)
    assert np.array_equal(back[others], moved[others])


@needs_makehuman
@pytest.mark.parametrize("name", ["base-dm", "caucasian-male-old-dm-eyes"])
def test_upper_lip_points_found_on_the_curve_above_the_lip_come_down_to_its_edge(name):
    # The face mesh puts the upper lip's outer points (49-53) of some characters up to 0.05 eye distances too high,
    # 0.008-0.03 behind the lip's front on the curve above it towards the nose; moved there, they come back down
    # their column to the lip's edge, near the registered points; the registered points stay; nothing else moves.
    from pdeface.landmarks.mouth import UPPER_LIP, upper_lip_on_its_edge

    ch = build(SPECS[name])
    L, eyes, rows = ch.skin_landmarks, ch.eye_distance, list(UPPER_LIP)
    assert np.array_equal(upper_lip_on_its_edge(ch.vertices, ch.triangles, L), L)
    moved = _moved_in_face_frame(ch.vertices, ch.triangles, L, rows, (0, 0.04, -0.01))
    back = upper_lip_on_its_edge(ch.vertices, ch.triangles, moved)
    before, after = (np.linalg.norm(P[rows] - L[rows], axis=1) / eyes for P in (moved, back))
    assert before.min() > 0.03 and (after < 0.5 * before).all() and after.max() < 0.015, (before, after)
    others = np.setdiff1d(np.arange(68), rows)
    assert np.array_equal(back[others], moved[others])


@needs_makehuman
@pytest.mark.parametrize("name", ["asian-female-old-in", "parted-lips-cm"])
def test_an_inner_lip_corner_found_beside_or_lateral_of_its_outer_corner_comes_in_from_it(name):
    # The map put asian-female-old-in's inner corner 0.08 eye distances lateral of the mouth's corner (15 % of
    # the eye distance off); one there, or at the outer corner itself (the seam's end found in the commissure),
    # comes back in from it, near the registered corner, on closed and on parted lips; one in place stays.
    from pdeface.landmarks.mouth import CORNERS, inner_lip_corners_inset

    ch = build(SPECS[name])
    L, eyes = ch.skin_landmarks, ch.eye_distance
    rows = [inner for inner, _ in CORNERS]
    assert np.array_equal(inner_lip_corners_inset(ch.vertices, ch.triangles, L), L)  # the true corners stay
    for lateral in (0.0, 0.03):  # at the outer corner, and beyond it
        moved = L.copy()
        f = face_frame(L)
        F = f.to_face(L)
        for (inner, outer), side in zip(CORNERS, (1, -1)):
            F[inner, 0] = F[outer, 0] - side * lateral * eyes * f.scale
        moved[rows] = f.to_user(F[rows])
        back = inner_lip_corners_inset(ch.vertices, ch.triangles, moved)
        before, after = (np.linalg.norm(P[rows] - L[rows], axis=1) / eyes for P in (moved, back))
        assert before.min() > 0.03 and after.max() < 0.03, (lateral, before, after)
        others = np.setdiff1d(np.arange(68), rows)
        assert np.array_equal(back[others], moved[others])  # only the inner corners move


@needs_makehuman
@pytest.mark.parametrize("name", ["base-dm", "african-male-old-m"])
def test_an_inner_lip_corner_found_on_the_lips_front_goes_back_beside_its_outer_corner(name):
    # The face mesh leaves an inner lip corner on the lips' front where the commissure's groove is shallow (found
    # 0.03-0.1 eye distances in front of its outer corner, up to 0.07 above; true ones lie at most 0.018 in front):
    # moved 0.06 forward and 0.04 up onto the lips, the inner corners come back in the commissure, near the
    # registered corners.
    from pdeface.landmarks.mouth import INSET_FRONT, inner_lip_corners_inset

    ch = build(SPECS[name])
    L, eyes, rows = ch.skin_landmarks, ch.eye_distance, [60, 64]
    moved = _moved_in_face_frame(ch.vertices, ch.triangles, L, rows, (0, 0.04, 0.06))
    f = face_frame(L)
    front = (f.to_face(moved[rows]) - f.to_face(moved[[48, 54]]))[:, 2] / (eyes * f.scale)
    back = inner_lip_corners_inset(ch.vertices, ch.triangles, moved)
    before, after = (np.linalg.norm(P[rows] - L[rows], axis=1) / eyes for P in (moved, back))
    assert front.min() > INSET_FRONT and before.min() > 0.06 and after.max() < 0.025, (front, before, after)
    others = np.setdiff1d(np.arange(68), rows)
    assert np.array_equal(back[others], moved[others])


@needs_makehuman
@pytest.mark.parametrize("name", ["caucasian-male-old-dm-eyes", "caucasian-female-young-cm"])
def test_a_mouth_corner_found_inside_the_seam_comes_out_to_where_the_seam_ends(name):
    # The map put caucasian-male-old's left mouth corner 0.1 eye distances inside the commissure, in the seam
    # between the lips; moved so (along the lip line, the lips' front), each corner comes back out to the seam's
    # end, near the registered corner; the true corners stay.
    from pdeface.landmarks.mouth import OUTER_CORNERS, mouth_corners_at_seam_end

    ch = build(SPECS[name])
    L, eyes, rows = ch.skin_landmarks, ch.eye_distance, list(OUTER_CORNERS)
    assert np.array_equal(mouth_corners_at_seam_end(ch.vertices, ch.triangles, L), L)
    moved = L.copy()
    for j, side in zip(rows, (-1, 1)):
        moved[j] = _moved_in_face_frame(ch.vertices, ch.triangles, L, [j], (-side * 0.08, 0, 0.02))[j]
    back = mouth_corners_at_seam_end(ch.vertices, ch.triangles, moved)
    before, after = (np.linalg.norm(P[rows] - L[rows], axis=1) / eyes for P in (moved, back))
    assert before.min() > 0.07 and after.max() < 0.03, (before, after)
    others = np.setdiff1d(np.arange(68), rows)
    assert np.array_equal(back[others], moved[others])  # only the corners move


@needs_makehuman
@pytest.mark.parametrize("name", ["base-dm", "african-male-old-m"])
def test_lower_lip_sides_found_on_the_curve_under_the_lip_come_up_to_icts_drop(name):
    # The face mesh puts the lower lip's sides (55, 59) 0.02-0.03 eye distances too low, under the lip; moved down
    # there, they come back up their column to ICT's drop below the chord from the mouth corner to the lower lip's
    # middle, near the registered points (whose drop lies within 0.01 of ICT's on these two), which stay. Sides
    # moved up, or down further than SIDE_DROP_MAX (where the chord's end is what is off), stay too.
    from pdeface.landmarks.mouth import (
        LOWER_LIP_SIDES,
        SIDE_DROP_MAX,
        SIDE_DROP_OFF,
        ict_lower_lip_drop,
        lower_lip_drops,
        lower_lip_sides_at_ict_drop,
    )

    ch = build(SPECS[name])
    L, eyes, rows = ch.skin_landmarks, ch.eye_distance, list(LOWER_LIP_SIDES)
    assert (np.abs(lower_lip_drops(L) - ict_lower_lip_drop()) <= SIDE_DROP_OFF).all()
    assert np.array_equal(lower_lip_sides_at_ict_drop(ch.vertices, ch.triangles, L), L)  # the true sides stay
    moved = _moved_in_face_frame(ch.vertices, ch.triangles, L, rows, (0, -0.035, 0))
    back = lower_lip_sides_at_ict_drop(ch.vertices, ch.triangles, moved)
    before, after = (np.linalg.norm(P[rows] - L[rows], axis=1) / eyes for P in (moved, back))
    assert before.min() > 0.025 and (after < 0.6 * before).all() and after.max() < 0.02, (before, after)
    assert np.allclose(lower_lip_drops(back), ict_lower_lip_drop(), atol=0.004)  # within a pixel or so of ICT's
    others = np.setdiff1d(np.arange(68), rows)
    assert np.array_equal(back[others], moved[others])  # only the sides move
    for shift in (0.03, -(SIDE_DROP_MAX + 0.03)):
        away = _moved_in_face_frame(ch.vertices, ch.triangles, L, rows, (0, shift, 0))
        lower = lower_lip_drops(away) - ict_lower_lip_drop()
        assert ((lower < -SIDE_DROP_OFF) | (lower > SIDE_DROP_MAX)).all(), (shift, lower)  # out of the band
        assert np.array_equal(lower_lip_sides_at_ict_drop(ch.vertices, ch.triangles, away), away), shift
