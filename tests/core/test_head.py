"""The whole head: parts, the binding, its figures on ICT heads, pose --mesh, bad input."""
import json

import numpy as np
import pytest
from pdeface.assets import HEAD_PARTS, load_head, load_head_shapes
from pdeface.au.ict import FACE_VERTICES, au_offsets
from pdeface.au.modelfile import load_face
from pdeface.au.retarget import retarget
from pdeface.cli import main
from pdeface.errors import MeshError, PdeFaceError
from pdeface.head.bind import HeadBinding
from pdeface.head.parts import CODE, classify_parts, parse_overrides, skin_mask
from pdeface.head.report import head_report
from pdeface.io.meshio import read_obj
from pdeface.mesh import seam_welds
from pdeface.rigid import jaw_motion, rigid_displacement, rotation_vector, rotation_vector_matrix
from pdeface.surface.fit import fit_face


def part_range(name):
    names = list(HEAD_PARTS)
    i = names.index(name)
    end = HEAD_PARTS[names[i + 1]] if i + 1 < len(names) else 26719
    return np.arange(HEAD_PARTS[name], end)


@pytest.fixture(scope="module")
def head():
    mesh, lm = load_head()
    return mesh, mesh.triangles()[0], lm, load_head_shapes()


def rig(V, T, lm):
    model, _ = fit_face(V, T, V[lm])
    return retarget(load_face("default"), model)


@pytest.fixture(scope="module")
def generic(head):
    mesh, T, lm, _ = head
    model = rig(mesh.vertices, T, lm)
    return model, HeadBinding(model, mesh.vertices, T)


def test_parts_of_an_ict_head(head, generic):
    mesh, _, _, _ = head
    kind = generic[1].parts.kind
    for name in ("face", "head_and_neck", "mouth_socket", "eye_socket_left", "eye_socket_right"):
        assert (kind[part_range(name)] == CODE["skin"]).all(), name
    assert (kind[part_range("eyeball_left")] == CODE["eye_L"]).all()
    assert (kind[part_range("eyeball_right")] == CODE["eye_R"]).all()
    for name in ("eyelashes_left", "eyelashes_right", "lacrimal_fluid_left", "eye_occlusion_right"):
        assert (kind[part_range(name)] == CODE["follow"]).all(), name  # never taken for skin
    from pdeface.mesh import connected_components
    teeth = part_range("teeth")
    lab = connected_components(len(mesh.vertices), mesh.triangles()[0])
    kinds = [set(kind[lab == c]) for c in np.unique(lab[teeth])]
    assert len(kinds) == 32 and all(len(k) == 1 for k in kinds)  # each tooth moves whole
    assert sum(k == {CODE["jaw"]} for k in kinds) == 16 and sum(k == {CODE["skull"]} for k in kinds) == 16
    centre, radius = generic[1].parts.eyes["eye_L"]
    assert 10 < radius < 16 and centre[0] > 0  # mm; the subject's left is +x


def test_the_films_on_the_eyes_are_icts_tear_and_occlusion_meshes_and_not_relaxed(generic):
    # Left out of the folds' relaxation (issue #35): hidden under the lids, ICT's own blink crumples them.
    from pdeface.head.bind import descriptor_motion_args

    model, b = generic
    named = np.concatenate([part_range(f"{part}_{side}") for part in ("lacrimal_fluid", "eye_occlusion")
                            for side in ("left", "right")])
    assert b.films[named].all() and b.films.sum() == len(named)  # the lashes, the eyes' blend meshes: not films
    blink = next(d for d in model.descriptors if d.key == "45")
    D = b.face_motions([descriptor_motion_args(blink)[:4]]).transpose(1, 0, 2)  # (n, 1, 3), as the keys relax it
    bound = D.copy()
    assert b._folds.relax(D)  # the blink folds the lids' margins: relaxed there
    np.testing.assert_array_equal(D[b.films], bound[b.films])
    assert np.abs(D - bound).max() > 0.01  # cm


def test_keys_are_one_pose_each_and_linear_on_the_skin(generic):
    model, b = generic
    by_key = {d.key: d for d in model.descriptors}
    for key in ("12", "27", "45L", "63"):
        np.testing.assert_allclose(b.pose_displacement({key: 1.0}), b.descriptor_displacement(by_key[key]), atol=1e-9)
    # all at once (what the add-on does) is the same as one by one, jaw, gaze and mixes included
    chosen = [by_key[k] for k in ("12", "27", "45L", "63")]
    for one, many in zip([b.descriptor_displacement(d) for d in chosen], b.descriptor_displacements(chosen)):
        np.testing.assert_allclose(many, one, atol=1e-6)  # cm: the prior is float32 (#35)
    poses = [({"12": 0.5, "26": 1.0}, "sum"), ({"1": 1.0, "61": 0.5}, "max")]
    for (w, mixer), many in zip(poses, b.pose_displacements(poses)):
        np.testing.assert_allclose(many, b.pose_displacement(w, mixer), atol=1e-6)
    skin = b.skin[np.setdiff1d(np.arange(len(b.skin)), np.concatenate([g for *_, g in b.eyes.values()]))]
    skin = np.setdiff1d(skin, b._fading)  # the back of the head: each pose's motion capped at STILL_MM
    half = b.pose_displacement({"12": 0.5, "4": 1.0})
    both = 0.5 * b.descriptor_displacement(by_key["12"]) + b.descriptor_displacement(by_key["4"])
    np.testing.assert_allclose(half[skin], both[skin], atol=1e-6)  # the skin's binding is linear (lids: off the eyes)
    from pdeface.head.bind import STILL_MM

    behind = np.linalg.norm(half[b._fading] - both[b._fading], axis=1) * b.frame.scale
    assert behind.max() <= 3 * STILL_MM  # mixed there, within the caps of the keys mixed (and of the pose)


def _same_motions(got, want):
    """Whether two lists of ``(delta_coefficients, delta_residual, jaw, gaze, lids)`` hold the same numbers."""
    return len(got) == len(want) and all(
        len(g) == len(w) and all(np.array_equal(a, b) if isinstance(a, np.ndarray) else a == b for a, b in zip(g, w))
        for g, w in zip(got, want))


def test_a_descriptor_moves_as_itself_and_a_pose_as_its_mix(generic):
    # The one rule the add-on's keys, the development set's benches and renders follow (motion_args).
    from pdeface.head.bind import descriptor_motion_args
    from pdeface.presets import every_pose

    model, b = generic
    by_key = {d.key: d for d in model.descriptors}
    poses = every_pose(model)
    preset = next(n for n in poses if n != "neutral" and not n.startswith("AU"))
    got = b.motion_args([(poses[preset], "max"), by_key["27"], by_key["45L"], ({"12": 0.5, "61": 1.0}, "sum")])
    want = [b.pose_motion_args(poses[preset], "max"), descriptor_motion_args(by_key["27"]),
            descriptor_motion_args(by_key["45L"]), b.pose_motion_args({"12": 0.5, "61": 1.0}, "sum")]
    assert _same_motions(got, want)
    assert got[1][2] and got[3][3] == {61: 1.0}  # the jaw and the gaze came with them
    # every_pose's names: AU<key> the descriptor itself (not its weight-1 mix), a preset summed; in the names' order
    named = b.every_pose_motion_args([preset, "AU27", "AU45L"])
    assert _same_motions(named, [b.pose_motion_args(poses[preset], "sum"), *want[1:3]])
    with pytest.raises(KeyError):
        b.every_pose_motion_args(["AU27", "no such pose"])


def test_keys_read_the_pde_grid_at_the_nodes_read_alone(generic):
    """The keys evaluate the PDE grid at the nodes the covered skin reads (half ICT's face's grid): every read of
    every extension lies among them, and the skin moves as it does when the whole grid is solved (to rounding)."""
    from pdeface.head.bind import READ_BREAK_SLOPE, descriptor_motion_args
    from pdeface.surface.grid import surface_grid

    model, b = generic
    nodes, slot = b._read_nodes
    n_grid = b.read_grid.shape[1]
    assert 0 < len(nodes) < 0.7 * n_grid and (slot[nodes] == np.arange(len(nodes))).all()
    for ext in (b._extension(False), b._extension(True)):
        assert np.isin(ext.read.indices, nodes).all() and np.isin(ext.load.indices, nodes).all()
    by_key = {d.key: d for d in model.descriptors}
    motions = [descriptor_motion_args(by_key[k])[:4] for k in ("12", "45L", "27")]
    got = b.face_motions(motions, with_prior=False)
    C, R = (np.concatenate([m[i] for m in motions], axis=2) for i in (0, 1))
    G = surface_grid(model, *b.resolution, coefficients=C, residual=R, break_slope=READ_BREAK_SLOPE,
                     confine=False).reshape(n_grid, -1)
    for jaw, keys in ((False, [0, 1]), (True, [2])):
        ext = b._extension(jaw)
        fixed, free = ext.solve(G)
        for i in keys:
            for rows, want in ((ext.fixed, fixed), (ext.free, free)):
                want = want[:, 3 * i:3 * i + 3]
                np.testing.assert_allclose(got[i, b.skin[rows]], want, rtol=0, atol=1e-12 * np.abs(want).max())


def test_the_extension_writes_its_solution_into_the_keys_rows(generic):
    """:meth:`_Extension.write` (fixed rows block by block, right-hand sides from the loaded rows alone, SOLVE_COLUMNS
    columns at a time, a last block narrower) writes exactly :meth:`_Extension.solve`'s values, and no other row."""
    from pdeface.head.bind import SOLVE_COLUMNS

    _, b = generic
    nodes, slot = b._read_nodes
    G = np.random.default_rng(5).normal(size=(len(nodes), SOLVE_COLUMNS + 30))
    for jaw in (False, True):
        ext = b._extension(jaw).on_nodes(slot)
        assert 0 < len(ext._loaded()) < len(ext.free)
        out = np.full((len(b.V), G.shape[1]), np.nan)
        ext.write(G, out, b.skin)
        blocks = [ext.solve(G[:, s:s + SOLVE_COLUMNS]) for s in range(0, G.shape[1], SOLVE_COLUMNS)]
        fixed, free = (np.hstack([block[i] for block in blocks]) for i in (0, 1))
        for rows, want in ((ext.fixed, fixed), (ext.free, free)):
            assert np.array_equal(out[b.skin[rows]], want)
        untouched = np.ones(len(b.V), bool)
        untouched[b.skin] = False
        assert np.isnan(out[untouched]).all() and not np.isnan(out[b.skin]).any()


def test_rest_region_never_moves(head, generic):
    mesh, _, lm, _ = head
    _, b = generic
    chin_y = b.Vf[lm[8], 1]
    below = b.Vf[:, 1] < chin_y - 50  # mm: 5 cm below the chin
    back = (b.Vf[:, 2] < b.hinge[2] - 40) & (b.parts.kind == CODE["skin"])  # the back of the skull
    rest = np.zeros(len(b.V), bool)
    rest[b.skin[b.rest]] = True
    assert rest[back].mean() > 0.95
    for d in b.model.descriptors:
        D = b.descriptor_displacement(d)
        assert np.abs(D[below]).max() == 0 and np.abs(D[rest]).max() == 0, d.key


def test_the_back_of_the_head_fades_still_but_a_face_mask_keeps_its_motion(head, generic):
    from pdeface.head.bind import STILL_BELOW_CHIN_IOD, still_weight

    _, _, lm, _ = head
    _, b = generic
    P, Lf, ed = b.Vf[b.skin], b.Vf[lm], b.eye_distance
    w = still_weight(b.Vf, P, Lf, ed)
    assert np.isfinite(w).all() and (w[lm] == 1).all()
    depth = P[:, 2].max() - P[:, 2].min()
    back = b.Vf[:, 2] < P[:, 2].max() - 0.6 * depth
    assert (w[back] == 0).all()  # the back of the skull
    assert (w[b.Vf[:, 1] < Lf[8, 1] - STILL_BELOW_CHIN_IOD[1] * ed] == 0).all()  # the neck
    # There each key moves at most STILL_MM: ICT's smile still moves the skin before its ears, no further.
    from pdeface.head.bind import STILL_MM

    by_key = {d.key: d for d in b.model.descriptors}
    for key in ("12", "27"):
        moved = np.linalg.norm(b.descriptor_displacement(by_key[key])[back & b.parts.mask("skin")], axis=1) * 10
        assert 0.5 * STILL_MM < moved.max() <= STILL_MM + 1e-9, key  # mm
    # The bundled face model keeps no nose tip landmark: its binding's keys are finite and fade as well.
    assert np.isfinite(b.descriptor_displacement(b.model.descriptors[0])).all()
    # A face mask (no back of the head) keeps every vertex's motion.
    mask = P[P[:, 2] > Lf[33, 2] - 0.8 * ed]
    assert (still_weight(mask, mask, Lf, ed) == 1).all()


def test_jaw_turns_the_lower_teeth_and_gaze_the_eyeballs(generic):
    model, b = generic
    by_key = {d.key: d for d in model.descriptors}
    jaw = b.parts.mask("jaw")
    skull = b.parts.mask("skull")
    D = b.descriptor_displacement(by_key["27"]) * 10  # mm
    assert np.linalg.norm(D[jaw], axis=1).mean() > 15 and np.abs(D[skull]).max() == 0
    assert np.abs(b.descriptor_displacement(by_key["12"])[jaw]).max() == 0  # a smile leaves the jaw
    eye = b.parts.mask("eye_L")
    up = face_frame_displacement(b, by_key["63"])
    centre, _ = b.parts.eyes["eye_L"]
    front = eye & (b.Vf[:, 2] > centre[2] + 10)
    assert up[front, 1].mean() > 3  # the cornea turns up
    moved = b.Vf[eye] + up[eye]
    np.testing.assert_allclose(np.linalg.norm(moved - centre, axis=1), np.linalg.norm(b.Vf[eye] - centre, axis=1),
                               atol=1e-6)  # a rotation about the centre


def face_frame_displacement(b, descriptor):
    return b.frame.to_face(b.V + b.descriptor_displacement(descriptor)) - b.Vf


def test_lids_stay_outside_the_eyeballs(generic):
    model, b = generic
    by_key = {d.key: d for d in model.descriptors}
    for name, (centre, radius, _, guard) in b.eyes.items():
        for key in ("45", "7", "64"):
            P = b.Vf[b.skin[guard]] + face_frame_displacement(b, by_key[key])[b.skin[guard]]
            assert np.linalg.norm(P - centre, axis=1).min() >= radius - 1e-6, (name, key)


@pytest.mark.parametrize("identity", [None, 7])
def test_figures_on_ict_heads(head, identity):
    """Every vertex against ICT-FaceKit's truth (bench_head.py runs all 20 identities)."""
    mesh, T, lm, shapes = head
    V = mesh.vertices if identity is None else mesh.vertices + shapes[f"identity{identity:03d}"]
    model = rig(V, T, lm)
    b = HeadBinding(model, V, T)
    face = np.arange(len(V)) < FACE_VERTICES
    keys = ("12", "4", "27", "20", "45")
    rep = head_report(b, {k: au_offsets(k, shapes) for k in keys}, {"face": face, "head": np.ones(len(V), bool)})
    # Measured with the bundled head prior (bench_head.py), generic / identity007 over the face region:
    # AU12 0.97 / 0.94, AU4 1.00 / 0.97, AU27 0.96 / 0.84 (without the prior AU12 0.86, AU27 0.69-0.76). The still
    # back of the head (issue #40) takes AU12 to 0.92 / 0.93: ICT's smile moves the skin before its ears (capped there
    # at bind.STILL_MM; zeroed, the generic head's AU12 fell to 0.89).
    assert rep["12"]["face"] > 0.9 and rep["4"]["face"] > 0.95 and rep["27"]["face"] > 0.8
    assert np.median([r["face"] for r in rep.values()]) > 0.9 and np.median([r["head"] for r in rep.values()]) > 0.85
    # The old way, reading the mask at each vertex's closest point, got AU27 0.54 over the same vertices.
    jaw = {"jaw": b.parts.mask("jaw")}
    assert head_report(b, {"27": au_offsets("27", shapes)}, jaw)["27"]["jaw"] > 0.9


def test_skin_under_an_openings_strip_follows_its_rim(head):
    """identity002's lips meet where the mouth's break strip (the surface between the two lip rims) lies
    closest to them: read from the strip, the upper lip's edge got a blend of both lips (AU10 captured 0.785,
    the lip's edge moving 1.6 mm of its 5). Skin under a strip follows its rim instead, like hidden skin."""
    mesh, T, lm, shapes = head
    V = mesh.vertices + shapes["identity002"]
    b = HeadBinding(rig(V, T, lm), V, T)
    face = np.arange(len(V)) < FACE_VERTICES
    rep = head_report(b, {k: au_offsets(k, shapes) for k in ("10", "27")}, {"face": face})
    # Measured (bench_head.py): AU10 0.785 -> 0.883, AU27 0.866 -> 0.937; spill p99 at most 0.28 mm anywhere.
    assert rep["10"]["face"] > 0.85 and rep["27"]["face"] > 0.9
    assert max(r["spill_p99_mm"] for r in rep.values()) < 0.3


def test_a_body_in_metres_moves_only_its_face(head):
    mesh, T, lm, _ = head
    V = mesh.vertices / 100  # metres
    box = np.array([[x, y, z] for x in (-0.2, 0.2) for y in (-0.9, -0.3) for z in (-0.1, 0.1)])
    quads = np.array([[0, 1, 3, 2], [4, 6, 7, 5], [0, 4, 5, 1], [2, 3, 7, 6], [0, 2, 6, 4], [1, 5, 7, 3]])
    tris = np.concatenate([quads[:, [0, 1, 2]], quads[:, [0, 2, 3]]]) + len(V)
    Vb, Tb = np.concatenate([V, box]), np.concatenate([T, tris])
    model = rig(Vb, Tb, lm)
    assert model.frame.unit == "m"
    b = HeadBinding(model, Vb, Tb)
    assert (b.parts.kind[len(V):] == CODE["rest"]).all()
    D = np.stack([b.descriptor_displacement(d) for d in model.descriptors if d.key in ("27", "12", "20")])
    assert np.abs(D[:, len(V):]).max() == 0
    assert np.linalg.norm(D[:, :len(V)], axis=2).max() > 0.01  # 1 cm: the jaw opens


def test_pose_mesh_keeps_the_file_but_its_positions(tmp_path, head, capsys):
    mesh, T, lm, _ = head
    lines = [f"v {x:.6f} {y:.6f} {z:.6f} 0.5 0.5 0.5\n" for x, y, z in mesh.vertices]
    lines += [f"vt {u:.6f} {v:.6f}\n" for u, v in mesh.uvs]
    lines.insert(0, "# a user's head\nmtllib head.mtl\no Head\n")
    starts = np.r_[0, np.cumsum(mesh.face_counts)]
    fi, fu = mesh.face_indices + 1, mesh.face_uv_indices + 1
    for k in range(len(mesh.face_counts)):
        if k in (0, 9230):
            lines.append(f"g part{k}\nusemtl skin{k}\ns 1\n")
        lines.append("f " + " ".join(f"{a}/{b}" for a, b in zip(fi[starts[k]:starts[k + 1]], fu[starts[k]:starts[k + 1]])) + "\n")
    src = tmp_path / "head.obj"
    src.write_text("".join(lines))
    (tmp_path / "lm.json").write_text(json.dumps({"indices": lm.tolist()}))
    assert main(["fit", str(src), "--landmarks", str(tmp_path / "lm.json"), "-o", str(tmp_path / "f.npz")]) == 0
    assert main(["retarget", str(tmp_path / "f.npz"), "-o", str(tmp_path / "rig.npz")]) == 0
    out = tmp_path / "smile.obj"
    assert main(["pose", str(tmp_path / "rig.npz"), "--mesh", str(src), "--au", "12=1", "-o", str(out)]) == 0
    before, after = src.read_text().splitlines(), out.read_text().splitlines()
    assert len(before) == len(after)
    assert [a for a in before if not a.startswith("v ")] == [b for b in after if not b.startswith("v ")]
    assert all(b.split()[4:] == ["0.5", "0.5", "0.5"] for b in after if b.startswith("v "))
    posed = read_obj(out)
    assert np.array_equal(posed.face_indices, mesh.face_indices) and np.allclose(posed.uvs, mesh.uvs, atol=1e-6)
    # the key at weight 1 (what the add-on writes) is this pose to the file's 6 decimals
    from pdeface.au.modelfile import load_face as lf
    model = lf(str(tmp_path / "rig.npz"))
    b = HeadBinding(model, read_obj(src).vertices, T)
    key = b.descriptor_displacement(next(d for d in model.descriptors if d.key == "12"))
    np.testing.assert_allclose(posed.vertices, read_obj(src).vertices + key, atol=1e-5)
    assert np.linalg.norm(key, axis=1).max() > 0.5  # cm


def test_bad_input(tmp_path, head, capsys):
    mesh, T, lm, _ = head
    model = load_face("default")
    with pytest.raises(MeshError, match="fitted on this head"):  # a model fitted on another mesh
        HeadBinding(model, mesh.vertices + [0, 0, 30.0], T)
    with pytest.raises(MeshError, match="unknown part kind"):
        parse_overrides({"teeth": [1, 2]})
    with pytest.raises(MeshError, match="list of vertex indices"):
        parse_overrides({"jaw": [1, "x"]})
    assert skin_mask({"skin": [1, 3]}, 5).tolist() == [False, True, False, True, False]
    assert skin_mask({"jaw": [1]}, 5) is None and skin_mask({"skin": []}, 5) is None
    for bad in ([5], [-1]):  # out of range or negative: an error naming the kind, not a traceback or a wrap-around
        with pytest.raises(MeshError, match="'skin': vertex index out of range"):
            skin_mask({"skin": bad}, 5)
    with pytest.raises(MeshError, match="out of range"):
        HeadBinding(model, mesh.vertices, T, overrides={"jaw": [10 ** 7]})
    (tmp_path / "bad.json").write_text("{ nope")
    code = main(["pose", "default", "--mesh", "head", "--au", "12=1", "--parts", str(tmp_path / "bad.json"),
                 "-o", str(tmp_path / "o.obj")])
    assert code != 0 and "not valid JSON" in capsys.readouterr().err and not (tmp_path / "o.obj").exists()
    nan = mesh.vertices.copy()
    nan[5] = np.nan
    with pytest.raises(MeshError, match="finite"):
        HeadBinding(model, nan, T)
    model.landmarks = None
    with pytest.raises(PdeFaceError, match="no landmarks"):
        HeadBinding(model, mesh.vertices, T)


def test_overrides_and_the_parts_command(tmp_path, head, capsys):
    mesh, T, lm, _ = head
    out = tmp_path / "parts.json"
    assert main(["parts", "head", "-o", str(out)]) == 0
    parts = json.loads(out.read_text())
    assert set(parts) <= set(CODE) and len(parts["follow"]) == 2080
    # the user says the lashes are rigid props: they then never move
    lashes = np.concatenate([part_range("eyelashes_left"), part_range("eyelashes_right")]).tolist()
    model = load_face("default")
    b = HeadBinding(model, mesh.vertices, T, overrides={"rest": lashes})
    blink = next(d for d in model.descriptors if d.key == "45")
    assert np.abs(b.descriptor_displacement(blink)[lashes]).max() == 0


def test_rigid_helpers():
    rv = np.array([0.1, -0.3, 0.2])
    np.testing.assert_allclose(rotation_vector(rotation_vector_matrix(rv)), rv, atol=1e-12)
    rng = np.random.default_rng(1)
    P = rng.normal(size=(50, 3)) * 20 + [0, -60, 10]
    hinge = np.array([0.0, -10.0, -100.0])
    R = rotation_vector_matrix([0.3, 0.0, 0.0])
    got_rv, got_t = jaw_motion(P, rigid_displacement(P, hinge, R), hinge)  # a jaw opening about its hinge
    np.testing.assert_allclose(got_rv, [0.3, 0, 0], atol=1e-9)
    np.testing.assert_allclose(got_t, 0, atol=1e-9)
    _, got_t = jaw_motion(P, np.tile([0.0, 0.0, 2.0], (len(P), 1)), np.array([0.0, 0.0, -1e6]))
    np.testing.assert_allclose(got_t, [0, 0, 2.0], atol=1e-3)  # a slide, seen from a far hinge


def test_report_on_a_whole_head_measures_its_skin(head, generic):
    from pdeface.surface.report import accuracy_report
    mesh, T, lm, _ = head
    model, _ = fit_face(mesh.vertices, T, mesh.vertices[lm], unit="cm")
    r = accuracy_report(model, mesh.vertices, T)
    # lash strips in front of the lids and the orbit behind the eyeballs are not skin seen by the face
    assert r["max_mm"] < 3 and r["mean_mm"] < 0.15


def test_another_topology_and_unit(head):
    """Each quad split in four (another topology, 4x the faces) and the head in metres."""
    mesh, _, lm, _ = head
    starts = np.r_[0, np.cumsum(mesh.face_counts)]
    quads = np.array([mesh.face_indices[starts[k]:starts[k + 1]] for k in range(len(mesh.face_counts))
                      if mesh.face_counts[k] == 4])
    V = mesh.vertices.copy()
    edges = {}
    new = []

    def mid(a, b):
        key = (min(a, b), max(a, b))
        if key not in edges:
            edges[key] = len(V) + len(new)
            new.append((V[a] + V[b]) / 2)
        return edges[key]

    faces = []
    for a, b, c, d in quads:
        ab, bc, cd, da = mid(a, b), mid(b, c), mid(c, d), mid(d, a)
        centre = len(V) + len(new)
        new.append(V[[a, b, c, d]].mean(0))
        faces += [[a, ab, centre, da], [ab, b, bc, centre], [centre, bc, c, cd], [da, centre, cd, d]]
    Vs = np.concatenate([V, np.array(new)]) / 100  # metres
    F = np.array(faces)
    Ts = np.concatenate([F[:, [0, 1, 2]], F[:, [0, 2, 3]]])
    model = rig(Vs, Ts, lm)
    b = HeadBinding(model, Vs, Ts)
    smile = b.descriptor_displacement(next(d for d in model.descriptors if d.key == "12")) * 1000  # mm
    corner = lm[[48, 54]]
    assert np.linalg.norm(smile[corner], axis=1).min() > 5
    chin_y = b.Vf[lm[8], 1]
    assert np.abs(smile[b.Vf[:, 1] < chin_y - 50]).max() == 0


def test_landmarks_on_a_part_that_is_not_skin(head):
    mesh, T, lm, _ = head
    teeth = part_range("teeth")
    with pytest.raises(PdeFaceError):
        HeadBinding(load_face("default"), mesh.vertices, T, landmarks=mesh.vertices[teeth[:68 * 60:60]])
    with pytest.raises(MeshError, match="do not lie on skin"):  # the face's landmarks pushed 3 cm into the head
        HeadBinding(load_face("default"), mesh.vertices, T, landmarks=mesh.vertices[lm] + [0, 0, -3.0])


def split_along_a_seam(head, generic):
    """``(V, T, seam vertices, their copies)``: the head with the skin's triangles beyond a vertical seam down the
    subject's right cheek given copies of the seam's vertices (an exporter's split where UVs break)."""
    mesh, T, lm, _ = head
    _, b = generic
    V = mesh.vertices
    skin = np.zeros(len(V), bool)
    skin[b.skin] = True
    seam_x = V[lm[2], 0] * 0.5
    tri_right = (V[T].mean(axis=1)[:, 0] < seam_x) & skin[T].all(axis=1)
    on_seam = np.unique(T[tri_right][np.isin(T[tri_right], T[~tri_right])])
    copies = np.arange(len(V), len(V) + len(on_seam))
    remap = np.arange(len(V))
    remap[on_seam] = copies
    return np.concatenate([V, V[on_seam]]), np.where(tri_right[:, None], remap[T], T), on_seam, copies


def test_the_bindings_joined_seams_classify_the_parts_as_their_own_welding_does(head, generic):
    """classify_parts on triangles whose seams the binding joined (``welded``: no second welding) finds the parts
    it finds welding them again."""
    model, b = generic
    V, T, on_seam, copies = split_along_a_seam(head, generic)
    rep = seam_welds(V, T)
    assert (rep[copies] == on_seam).all()
    Tw = rep[T]
    Tw = Tw[(Tw[:, 0] != Tw[:, 1]) & (Tw[:, 1] != Tw[:, 2]) & (Tw[:, 2] != Tw[:, 0])]
    Vf = model.frame.to_face(V)
    welded = classify_parts(Vf, Tw, b.face_landmarks, b.hinge, welded=True)
    again = classify_parts(Vf, Tw, b.face_landmarks, b.hinge)
    np.testing.assert_array_equal(welded.kind, again.kind)
    assert welded.notes == again.notes and (welded.kind[on_seam] == CODE["skin"]).all()


def test_a_head_split_along_seams_moves_in_one_piece(head, generic):
    """An exporter's copy of the head, its vertices split where UVs break: the keys match the whole head's."""
    model, b = generic
    V = head[0].vertices
    V_split, T_split, on_seam, copies = split_along_a_seam(head, generic)
    split = HeadBinding(model, V_split, T_split)
    assert f"{len(on_seam)} vertices split along seams joined" in split.notes
    d = next(x for x in model.descriptors if x.key == "12")
    want = b.descriptor_displacement(d)
    got = split.descriptor_displacement(d)
    np.testing.assert_allclose(got[:len(V)], want, atol=1e-9)
    np.testing.assert_allclose(got[copies], want[on_seam], atol=1e-9)  # no crack along the seam


def test_the_rest_region_is_the_skins_own_pieces_whole_or_split_by_an_override(head, generic):
    """The rest region reads the parts' pieces where the skin is whole ones of them (issue #35: one connected
    components search less) and the skin's own where an override cuts a piece: the same rest region as the skin's
    own components give, both times."""
    from pdeface.head.bind import REST_IOD, _rest_region
    from pdeface.mesh import connected_components
    from scipy.spatial import cKDTree

    model, b = generic
    mesh, T, _, _ = head
    Vf = b.Vf
    scalp = np.nonzero((Vf[:, 1] > b.face_landmarks[:, 1].max() + 0.3 * b.eye_distance)
                       & (Vf[:, 1] < b.face_landmarks[:, 1].max() + 0.4 * b.eye_distance))[0]
    cut = HeadBinding(model, mesh.vertices, T, overrides={"skull": scalp.tolist()})
    for bound in (b, cut):
        P = Vf[bound.skin]
        local = np.full(len(Vf), -1)
        local[bound.skin] = np.arange(len(bound.skin))
        Ts = local[T[(local[T] >= 0).all(axis=1)]]
        cover = REST_IOD * bound.eye_distance * (1 + 1e-9)
        from_covered = cKDTree(P[bound.covered]).query(P, distance_upper_bound=cover)[0]
        want = _rest_region(P, Ts, bound.covered, from_covered, bound.face_landmarks, bound.eye_distance)
        np.testing.assert_array_equal(bound.rest, want)
        own = len(np.unique(connected_components(len(P), Ts)))
        by_parts = len(np.unique(bound.parts.pieces[bound.skin]))
        assert (own > by_parts) == (bound is cut)  # the override cut the scalp's top off the face's piece
