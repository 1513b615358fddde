import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[2]
MODULE = "bl_ext.pdeface_test.pdeface"


def evaluated_vertices(bpy, obj):
    dg = bpy.context.evaluated_depsgraph_get()
    ev = obj.evaluated_get(dg)
    me = ev.to_mesh()
    co = np.empty(len(me.vertices) * 3, np.float32)
    me.vertices.foreach_get("co", co)
    ev.to_mesh_clear()
    return co.reshape(-1, 3).astype(np.float64)


def key_blocks(obj):
    return obj.data.shape_keys.key_blocks


def test_manifest_validates():
    import importlib.util
    from pathlib import Path
    tool = next(Path(importlib.util.find_spec("bpy").origin).parent.glob("*/scripts/addons_core/bl_pkg/cli/blender_ext.py"))
    res = subprocess.run([sys.executable, str(tool), "validate", str(ROOT / "blender_addon")], capture_output=True, text=True)
    assert res.returncode == 0 and "Success" in res.stdout, res.stdout + res.stderr


def test_default_face_and_its_shape_keys(bpy, face):
    from pdeface.au.modelfile import load_face
    from pdeface.surface.sampling import mesh_resolution, parse_resolution
    model = load_face("default")
    rows, cols = mesh_resolution(model)  # the default's steps, chosen for this face, kept on the object
    assert parse_resolution(face.pdeface.resolution) == (rows, cols)
    assert face.pdeface.is_face and len(face.data.vertices) == (sum(rows) + 1) * (sum(cols) + 1)
    assert all(p.use_smooth for p in face.data.polygons[:50])
    assert face.data.materials[0].name.startswith("PDE Skin")
    kb = key_blocks(face)
    assert kb[0].name == "Basis" and len(kb) == 1 + len(model.descriptors) + 10
    assert "AU12 Lip Corner Puller" in kb and "AU12L Lip Corner Puller" in kb and "Expr happy" in kb
    assert "Expr disgust_9_17" in kb
    for k in kb[1:]:
        assert (k.slider_min, k.slider_max, k.value) == (0.0, 1.0, 0.0)
    # the panel's AU list: labelled and grouped
    entries = {e.name: e for e in face.pdeface.keys}
    assert entries["AU12 Lip Corner Puller"].region == "lower" and entries["AU1 Inner Brow Raiser"].region == "upper"
    assert entries["AU61 Eyes Turn Left"].region == "eyes_head"


@pytest.mark.parametrize("key", ["12", "1", "30L", "45R"])
def test_au_slider_reproduces_pdeface_pose(bpy, face, key):
    from pdeface.au.modelfile import load_face
    from pdeface.posing import pose_curves
    from pdeface.surface.fit import face_mesh
    model = load_face("default")
    d = next(x for x in model.descriptors if x.key == key)
    key_blocks(face)[f"AU{key} {d.name}"].value = 1.0
    C, R = pose_curves(model, {key: 1.0})
    expect = face_mesh(model, coefficients=C, residual=R).vertices
    assert np.abs(evaluated_vertices(bpy, face) - expect).max() < 1e-5


def test_presets_as_keys_or_weights_without_double_counting(bpy, face):
    kb = key_blocks(face)
    assert bpy.ops.pdeface.apply_preset(preset="happy", mode="AUS") == {"FINISHED"}
    assert kb["AU12 Lip Corner Puller"].value == 1.0 and kb["AU6 Cheek Raiser"].value == pytest.approx(0.3)
    as_weights = evaluated_vertices(bpy, face)
    bpy.ops.pdeface.apply_preset(preset="happy", mode="KEY")
    assert kb["Expr happy"].value == 1.0
    assert kb["AU12 Lip Corner Puller"].value == 0.0  # the expression key already holds it
    np.testing.assert_allclose(evaluated_vertices(bpy, face), as_weights, atol=1e-5)
    bpy.ops.pdeface.apply_preset(preset="sad", mode="AUS")
    assert kb["Expr happy"].value == 0.0 and kb["AU15 Lip Corner Depressor"].value == 1.0
    assert bpy.ops.pdeface.reset_pose() == {"FINISHED"}
    assert all(k.value == 0.0 for k in kb[1:])


def test_nonlinear_mixer_goes_into_its_own_key(bpy, face):
    from pdeface.au.modelfile import load_face
    from pdeface.posing import pose_curves
    from pdeface.presets import PRESETS, resolve_preset
    from pdeface.surface.fit import face_mesh
    model = load_face("default")
    bpy.context.scene.pdeface.mixer = "max"
    bpy.ops.pdeface.apply_preset(preset="fear", mode="AUS")
    kb = key_blocks(face)
    assert kb["PDE Mix"].value == 1.0 and kb["AU1 Inner Brow Raiser"].value == 0.0
    w, _ = resolve_preset(PRESETS["fear"], {d.key for d in model.descriptors})
    C, R = pose_curves(model, w, "max")
    np.testing.assert_allclose(evaluated_vertices(bpy, face), face_mesh(model, coefficients=C, residual=R).vertices, atol=1e-5)


def test_rebuild_keeps_the_users_keys_and_keyframes(bpy, face):
    kb = key_blocks(face)
    mine = face.shape_key_add(name="Smirk", from_mix=False)
    co = np.array([v.co[:] for v in mine.data]) + 0.1
    mine.data.foreach_set("co", co.astype(np.float32).ravel())
    for frame, value in ((1, 0.0), (10, 0.8)):
        mine.value = value
        mine.keyframe_insert("value", frame=frame)
    ours = kb["AU12 Lip Corner Puller"]
    for frame, value in ((1, 0.0), (20, 1.0)):
        ours.value = value
        ours.keyframe_insert("value", frame=frame)
    # the user's own key under a name we would make
    face.shape_key_remove(kb["Expr sad"])
    entry = next(i for i, e in enumerate(face.pdeface.keys) if e.name == "Expr sad")
    face.pdeface.keys.remove(entry)
    theirs = face.shape_key_add(name="Expr sad", from_mix=False)
    theirs_co = np.array([v.co[:] for v in theirs.data])
    n_keys = len(kb)
    assert bpy.ops.pdeface.build_shape_keys() == {"FINISHED"}
    assert len(kb) == n_keys and "Smirk" in kb
    np.testing.assert_allclose(np.array([v.co[:] for v in kb["Smirk"].data]), co, atol=1e-6)
    np.testing.assert_allclose(np.array([v.co[:] for v in kb["Expr sad"].data]), theirs_co, atol=1e-6)
    scene = bpy.context.scene
    scene.frame_set(10)
    assert kb["Smirk"].value == pytest.approx(0.8)
    scene.frame_set(20)
    assert kb["AU12 Lip Corner Puller"].value == pytest.approx(1.0)


def test_keyframe_pose_and_animate_sequence(bpy, face):
    kb = key_blocks(face)
    scene = bpy.context.scene
    scene.frame_set(5)
    kb["AU12 Lip Corner Puller"].value = 0.7
    assert bpy.ops.pdeface.keyframe_pose() == {"FINISHED"}
    scene.frame_set(6)
    assert kb["AU12 Lip Corner Puller"].value == pytest.approx(0.7)
    assert bpy.ops.pdeface.animate_sequence(presets="happy,sad", start=10, hold=4, blend=6,
                                            mode="via_neutral", channels="KEY") == {"FINISHED"}
    expect = {10: (0, 0), 16: (1, 0), 20: (1, 0), 26: (0, 0), 30: (0, 0), 36: (0, 1), 40: (0, 1), 46: (0, 0)}
    for frame, (happy, sad) in expect.items():
        scene.frame_set(frame)
        assert (kb["Expr happy"].value, kb["Expr sad"].value) == pytest.approx((happy, sad), abs=1e-6), frame
    assert scene.frame_end >= 46
    bpy.ops.pdeface.animate_sequence(presets="happy,sad", start=100, hold=0, blend=5, mode="direct", channels="AUS")
    scene.frame_set(105)
    assert kb["AU12 Lip Corner Puller"].value == pytest.approx(1.0)
    scene.frame_set(110)
    assert kb["AU15 Lip Corner Depressor"].value == pytest.approx(1.0) and kb["AU12 Lip Corner Puller"].value == 0


@pytest.mark.parametrize("source", ["GROUP", "SELECTED", "FILE"])
def test_fit_to_selected(bpy, scan_object, tmp_path, source):
    import bmesh
    obj, idx = scan_object
    obj.location = (5.0, 0.0, 1.0)
    s = bpy.context.scene.pdeface
    s.landmark_source = source
    if source == "GROUP":
        g = obj.vertex_groups.new(name="landmarks")
        for i, v in enumerate(idx):
            g.add([int(v)], (i + 1) / 68, "REPLACE")
    elif source == "SELECTED":
        bm = bmesh.new()
        bm.from_mesh(obj.data)
        bm.verts.ensure_lookup_table()
        for v in idx:
            bm.verts[int(v)].select = True
            bm.select_history.add(bm.verts[int(v)])
        bm.to_mesh(obj.data)
        bm.free()
    else:
        (tmp_path / "lm.json").write_text(json.dumps({"indices": idx.tolist()}))
        s.landmark_file = str(tmp_path / "lm.json")
    assert bpy.ops.pdeface.fit_to_selected() == {"FINISHED"}
    # The keys go on the user's mesh, which stays active; the PDE face is its hidden reference.
    assert bpy.context.active_object == obj
    pde = obj.pdeface.rig_face
    assert pde is not None and pde.pdeface.is_face and pde.pdeface.source == obj and pde.hide_get()
    assert tuple(pde.location) == pytest.approx((5.0, 0.0, 1.0))
    from pdeface.geometry import ClosestPoint
    addon = __import__(MODULE, fromlist=["bridge"])
    T, _ = addon.bridge.triangles(obj.data)
    d = ClosestPoint(addon.bridge.vertices(obj.data), T).query(addon.bridge.vertices(pde.data))[0]
    assert np.median(d) < 0.01  # cm: drops onto the scan
    assert "AU12 Lip Corner Puller" in key_blocks(pde) and "AU12 Lip Corner Puller" in key_blocks(obj)
    smile = addon.bridge.key_coords(key_blocks(obj)["AU12 Lip Corner Puller"])
    rest = addon.bridge.key_coords(key_blocks(obj)["Basis"])
    assert np.linalg.norm(smile - rest, axis=1).max() > 0.5  # cm: the user's own mesh smiles
    assert bpy.ops.pdeface.build_shape_keys() == {"FINISHED"}  # works with the user's mesh active


def test_fit_without_keys_on_the_mesh_leaves_it_alone(bpy, scan_object, tmp_path):
    obj, idx = scan_object
    s = bpy.context.scene.pdeface
    s.landmark_source = "FILE"
    (tmp_path / "lm.json").write_text(json.dumps({"indices": idx.tolist()}))
    s.landmark_file = str(tmp_path / "lm.json")
    assert bpy.ops.pdeface.fit_to_selected(keys_on_mesh=False) == {"FINISHED"}
    pde = bpy.context.active_object
    assert pde is not obj and pde.pdeface.is_face and pde.pdeface.source == obj
    assert obj.data.shape_keys is None and obj.pdeface.rig_face is None
    assert bpy.ops.pdeface.build_shape_keys() == {"FINISHED"}
    assert obj.data.shape_keys is None and "AU12 Lip Corner Puller" in key_blocks(pde)


def test_transfer_texture(bpy, face, scan_object):
    obj, _ = scan_object
    image = bpy.data.images.new("skin", 8, 8)
    mat = bpy.data.materials.new("scan")
    if mat.node_tree is None:  # always has one from Blender 5.0
        mat.use_nodes = True
    tex = mat.node_tree.nodes.new("ShaderNodeTexImage")
    tex.image = image
    obj.data.materials.append(mat)
    bpy.context.view_layer.objects.active = face
    bpy.context.scene.pdeface.texture_source = obj
    assert bpy.ops.pdeface.transfer_texture(method="CLOSEST") == {"FINISHED"}
    uv = face.data.uv_layers["Scan UV"]
    assert face.data.uv_layers.active == uv
    got = np.array([d.uv[:] for d in uv.data])
    assert 0 <= got.min() and got.max() <= 1 and got.std() > 0.05
    assert any(n.type == "TEX_IMAGE" and n.image == image for n in face.data.materials[0].node_tree.nodes)
    assert "UVMap" in face.data.uv_layers  # the parametric UVs are kept
    assert bpy.ops.pdeface.transfer_texture(method="ATLAS") == {"FINISHED"}
    atlas = np.array([d.uv[:] for d in face.data.uv_layers["Atlas UV"].data])
    assert 0 <= atlas.min() and atlas.max() <= 1


def test_bad_input_reports_an_error_and_loses_nothing(bpy, scan_object, tmp_path):
    obj, idx = scan_object
    s = bpy.context.scene.pdeface
    n_objects = len(bpy.data.objects)
    s.landmark_source = "GROUP"
    with pytest.raises(RuntimeError, match="no vertex group"):
        bpy.ops.pdeface.fit_to_selected()
    g = obj.vertex_groups.new(name="landmarks")
    g.add([int(v) for v in idx[:10]], 1.0, "REPLACE")
    with pytest.raises(RuntimeError, match="has 10 vertices"):
        bpy.ops.pdeface.fit_to_selected()
    s.landmark_source = "FILE"
    (tmp_path / "bad.json").write_text("{ nope")
    s.landmark_file = str(tmp_path / "bad.json")
    with pytest.raises(RuntimeError, match="not valid JSON"):
        bpy.ops.pdeface.fit_to_selected()
    s.landmark_source = "SELECTED"
    with pytest.raises(RuntimeError, match="0 vertices selected"):
        bpy.ops.pdeface.fit_to_selected()
    # a mesh that is not a face
    bpy.ops.mesh.primitive_plane_add(size=10)
    s.landmark_source = "FILE"
    (tmp_path / "lm.json").write_text(json.dumps({"points": (np.random.default_rng(0).random((68, 3)) * 10).tolist()}))
    s.landmark_file = str(tmp_path / "lm.json")
    with pytest.raises(RuntimeError):
        bpy.ops.pdeface.fit_to_selected()
    assert len(bpy.data.objects) == n_objects + 1  # only the plane we added
    # operators on a face need a face
    with pytest.raises(RuntimeError, match="context is incorrect|PDE face"):
        bpy.ops.pdeface.build_shape_keys()
    bpy.ops.pdeface.add_default_face(shape_keys=False)
    with pytest.raises(RuntimeError, match="no 'Expr happy' shape key"):
        bpy.ops.pdeface.apply_preset(preset="happy", mode="KEY")
    with pytest.raises(RuntimeError, match="choose the scan"):
        bpy.ops.pdeface.transfer_texture(method="CLOSEST")
    s.texture_source = bpy.context.active_object  # a PDE face is no scan
    with pytest.raises(RuntimeError, match="is a PDE face"):
        bpy.ops.pdeface.transfer_texture(method="CLOSEST")
    s.texture_source = None
    s.presets_file = str(tmp_path / "bad.json")
    with pytest.raises(RuntimeError, match="not valid JSON"):
        bpy.ops.pdeface.build_shape_keys()
    assert bpy.context.active_object.data.shape_keys is None or len(key_blocks(bpy.context.active_object)) <= 1


def addon_module(name):
    return __import__(MODULE + "." + name, fromlist=[name])


def shape_key_coords(obj):
    return {kb.name: np.array([d.co[:] for d in kb.data]) for kb in key_blocks(obj)}


def test_scripting_api_and_operators_make_the_same_face(bpy):
    # The operators only parse, call the add-on's rooms and report: both paths give the same mesh and keys.
    fm, keys, animation = addon_module("face"), addon_module("keys"), addon_module("animation")
    assert bpy.ops.pdeface.add_default_face() == {"FINISHED"}
    by_operator = bpy.context.active_object
    obj = fm.add_face(bpy.context)
    result = keys.build_keys(obj, keys.all_presets(bpy.context.scene))
    assert result["made"] == len(key_blocks(by_operator)) - 1 and result["skipped"] == 0
    np.testing.assert_array_equal(np.array([v.co[:] for v in obj.data.vertices]),
                                  np.array([v.co[:] for v in by_operator.data.vertices]))
    a, b = shape_key_coords(obj), shape_key_coords(by_operator)
    assert a.keys() == b.keys()
    for name in a:
        np.testing.assert_array_equal(a[name], b[name], err_msg=name)
    # posing: the operator with the scene's settings, the function with the same arguments
    bpy.context.scene.pdeface.mixer = "max"
    bpy.context.view_layer.objects.active = by_operator
    assert bpy.ops.pdeface.apply_preset(preset="fear", mode="AUS") == {"FINISHED"}
    presets = keys.all_presets(bpy.context.scene)
    assert keys.apply_preset(obj, "fear", presets["fear"], "AUS", 1.0, "max")[0] == "max"
    np.testing.assert_array_equal(evaluated_vertices(bpy, obj), evaluated_vertices(bpy, by_operator))
    # keyframes
    assert bpy.ops.pdeface.animate_sequence(presets="happy,sad", start=1, hold=2, blend=3, mode="direct",
                                            channels="AUS") == {"FINISHED"}
    animation.animate_sequence(bpy.context.scene, obj, ["happy", "sad"], presets, 1, 2, 3, "direct", "AUS")
    for frame in (1, 4, 6, 9, 11):
        bpy.context.scene.frame_set(frame)
        np.testing.assert_array_equal(evaluated_vertices(bpy, obj), evaluated_vertices(bpy, by_operator))


def test_a_presets_own_mixer_unless_the_panel_names_one(bpy, face, tmp_path):
    (tmp_path / "p.json").write_text(json.dumps({"format": "pdeface.preset", "version": 1, "name": "brows",
                                                 "weights": {"1": 1, "2": 1, "4": 1}, "mixer": "average"}))
    s = bpy.context.scene.pdeface
    s.presets_file = str(tmp_path / "p.json")
    assert s.mixer == addon_module("keys").PRESET_MIXER  # the default defers to the preset
    kb = key_blocks(face)
    bpy.ops.pdeface.apply_preset(preset="brows", mode="AUS")
    assert kb["PDE Mix"].value == 1.0 and kb["AU1 Inner Brow Raiser"].value == 0.0
    s.mixer = "sum"
    bpy.ops.pdeface.apply_preset(preset="brows", mode="AUS")
    assert kb["PDE Mix"].value == 0.0 and kb["AU1 Inner Brow Raiser"].value == 1.0


def test_every_operator_reports_through_one_wrapper(bpy):
    ops = __import__(MODULE + ".operators", fromlist=["operators"])
    assert ops._classes and all(issubclass(c, ops._Operator) and "execute" not in vars(c) for c in ops._classes)


def test_manifest_declares_what_the_addon_opens():
    import tomllib
    permissions = tomllib.loads((ROOT / "blender_addon" / "blender_manifest.toml").read_text())["permissions"]
    assert {"files", "network"} <= set(permissions)  # the live link opens a TCP socket
    assert "TCP" in permissions["network"]


def test_a_user_key_under_one_of_our_old_names_is_theirs(bpy, face):
    # The user deletes our key (its entry stays in the registry) and makes their own of that name,
    # slider up to 3, keyframed at 2.5: a rebuild leaves it as it is.
    kb = key_blocks(face)
    face.shape_key_remove(kb["Expr sad"])
    theirs = face.shape_key_add(name="Expr sad", from_mix=False)
    co = np.array([v.co[:] for v in theirs.data]) + 0.2
    theirs.data.foreach_set("co", co.astype(np.float32).ravel())
    theirs.slider_max = 3.0
    theirs.value = 2.5
    theirs.keyframe_insert("value", frame=1)
    assert bpy.ops.pdeface.build_shape_keys() == {"FINISHED"}
    theirs = key_blocks(face)["Expr sad"]
    assert theirs.slider_max == 3.0
    np.testing.assert_allclose(np.array([v.co[:] for v in theirs.data]), co, atol=1e-6)
    bpy.context.scene.frame_set(1)
    assert theirs.value == pytest.approx(2.5)
    # our own keys are still rebuilt in place
    assert key_blocks(face)["Expr happy"].slider_max == 1.0


def test_a_face_keeps_the_steps_it_was_built_with(bpy, face):
    """A capture changes the model's descriptors, and with them the steps the default would choose now: the
    object's keys still land on its own vertices. A face saved before the default adapted (resolution
    "default", 4 steps per interval) keeps its 4 steps."""
    from pdeface.au.modelfile import load_face
    from pdeface.surface.fit import face_mesh
    fm, keys = addon_module("face"), addon_module("keys")
    model = load_face("default")
    stored = face.pdeface.resolution
    model.descriptors = model.descriptors[:10]  # another set of keys: another choice
    assert len(face_mesh(model).vertices) != len(face.data.vertices)
    assert len(face_mesh(model, fm.face_resolution(face)).vertices) == len(face.data.vertices)
    legacy = fm.add_face(bpy.context, resolution="4,4")
    legacy.pdeface.resolution = "default"  # as a face made by an older pdeface stored it
    assert fm.face_resolution(legacy) == "4,4" and len(legacy.data.vertices) == 19285
    result = keys.build_keys(legacy, keys.all_presets(bpy.context.scene))
    assert result["made"] == len(load_face("default").descriptors) + 10
    assert face.pdeface.resolution == stored
