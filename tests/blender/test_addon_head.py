"""The user's own head in Blender: keys on their objects, driven like the PDE face, nothing of theirs lost."""
import json
import time

import numpy as np
import pytest

MODULE = "bl_ext.pdeface_test.pdeface"

AU12 = "AU12 Lip Corner Puller"


def addon(name="bridge"):
    return __import__(MODULE + "." + name, fromlist=[name])


def key_blocks(obj):
    return obj.data.shape_keys.key_blocks


@pytest.fixture
def ict_head(bpy, tmp_path):
    """ICT-FaceKit's head as the user's objects: the skin with lashes and mouth, and the eyeballs apart."""
    from pdeface.assets import HEAD_PARTS, load_head
    from pdeface.mesh import Mesh

    mesh, lm = load_head()
    cut = HEAD_PARTS["eyeball_left"], HEAD_PARTS["lacrimal_fluid_left"]
    starts = np.r_[0, np.cumsum(mesh.face_counts)]
    polys = [mesh.face_indices[starts[k]:starts[k + 1]] for k in range(len(mesh.face_counts))]
    in_eyes = np.array([cut[0] <= p[0] < cut[1] for p in polys])

    def part(keep, offset):
        ps = [p - offset for p, k in zip(polys, keep) if k]
        used = np.unique(np.concatenate(ps))
        remap = np.full(len(mesh.vertices), -1)
        remap[used] = np.arange(len(used))
        return Mesh(mesh.vertices[used + offset], np.array([len(p) for p in ps]),
                    remap[np.concatenate(ps)]), used + offset

    head_mesh, head_idx = part(~in_eyes, 0)
    eye_mesh, eye_idx = part(in_eyes, 0)
    objs = []
    for name, m in (("Head", head_mesh), ("Eyes", eye_mesh)):
        me = addon().new_mesh(name, m)
        obj = bpy.data.objects.new(name, me)
        bpy.context.collection.objects.link(obj)
        objs.append(obj)
    head_obj, eyes = objs
    eyes.location = (0.0, 0.0, 0.0)
    remap = {int(v): i for i, v in enumerate(head_idx)}
    g = head_obj.vertex_groups.new(name="landmarks")
    for i, v in enumerate(lm):
        g.add([remap[int(v)]], (i + 1) / 68, "REPLACE")
    bpy.context.scene.pdeface.landmark_source = "GROUP"
    bpy.context.view_layer.update()
    for o in objs:
        o.select_set(True)
    bpy.context.view_layer.objects.active = head_obj
    return head_obj, eyes, head_idx, eye_idx


def test_fit_puts_every_key_on_the_users_objects(bpy, ict_head, tmp_path):
    head, eyes, head_idx, eye_idx = ict_head
    assert bpy.ops.pdeface.fit_to_selected() == {"FINISHED"}
    face = head.pdeface.rig_face
    assert bpy.context.active_object == head and face.hide_get() and eyes.pdeface.rig_face == face
    for obj in (head, eyes):
        assert AU12 in key_blocks(obj) and "Expr happy" in key_blocks(obj) and "AU63 Eyes Up" in key_blocks(obj)
    # the keys at weight 1 are `pdeface pose --mesh` on the same head, to float32 precision
    from pdeface.assets import load_head
    from pdeface.head.bind import HeadBinding
    mesh, _ = load_head()
    model = addon().face_model(face)
    b = HeadBinding(model, mesh.vertices, mesh.triangles()[0])
    want = mesh.vertices + b.pose_displacement({"12": 1.0})
    got = addon().key_coords(key_blocks(head)[AU12])
    np.testing.assert_allclose(got, want[head_idx], atol=1e-5)
    happy = addon("keys").all_presets(bpy.context.scene)["happy"]
    from pdeface.presets import resolve_preset
    w, _ = resolve_preset(happy, {d.key for d in model.descriptors})
    want = mesh.vertices + b.pose_displacement(w, happy.mixer)
    np.testing.assert_allclose(addon().key_coords(key_blocks(head)["Expr happy"]), want[head_idx], atol=1e-5)
    up = addon().key_coords(key_blocks(eyes)["AU63 Eyes Up"]) - addon().key_coords(key_blocks(eyes)["Basis"])
    assert np.linalg.norm(up, axis=1).max() > 0.3  # cm: the eyeballs turn


def test_a_head_without_eyeballs_gets_no_gaze_keys(bpy, ict_head, monkeypatch):
    head, eyes, *_ = ict_head
    bpy.data.objects.remove(eyes)  # empty sockets
    head.select_set(True)
    bpy.context.view_layer.objects.active = head
    reported, rigging = [], addon("rigging")
    build = rigging.build_keys
    monkeypatch.setattr(rigging, "build_keys", lambda *a: reported.append(build(*a)) or reported[-1])
    for asked in ("binding_notes", "binding_warnings"):  # build_keys's binding says both: not bound again to ask
        monkeypatch.setattr(addon("face"), asked, lambda face: pytest.fail("bound again for its notes"))
    assert bpy.ops.pdeface.fit_to_selected() == {"FINISHED"}
    monkeypatch.undo()
    names = set(key_blocks(head).keys())
    assert AU12 in names and not any(n.startswith(("AU61 ", "AU62 ", "AU63 ", "AU64 ")) for n in names)
    notes = addon("face").binding_notes(head.pdeface.rig_face)
    assert sum("no gaze keys" in n for n in notes) == 1 and reported[0]["notes"] == notes  # the operator reports them


def test_panel_operations_drive_the_users_mesh(bpy, ict_head):
    head, eyes, *_ = ict_head
    assert bpy.ops.pdeface.fit_to_selected() == {"FINISHED"}
    assert bpy.ops.pdeface.apply_preset(preset="happy", mode="KEY") == {"FINISHED"}
    assert key_blocks(head)["Expr happy"].value == 1.0 and key_blocks(eyes)["Expr happy"].value == 1.0
    assert bpy.ops.pdeface.apply_preset(preset="surprise", mode="AUS", weight=0.5) == {"FINISHED"}
    assert key_blocks(head)["AU1 Inner Brow Raiser"].value == pytest.approx(0.5)
    assert bpy.ops.pdeface.keyframe_pose() == {"FINISHED"}
    fcurves = addon("compat").fcurves_of(head.data.shape_keys)
    assert any("AU1 Inner Brow Raiser" in fc.data_path for fc in fcurves)
    bpy.context.scene.pdeface.mixer = "max"
    assert bpy.ops.pdeface.apply_preset(preset="happy", mode="AUS") == {"FINISHED"}
    assert key_blocks(head)["PDE Mix"].value == 1.0  # a non-linear mix: one key of its own, on the user's head too
    mix = addon().key_coords(key_blocks(head)["PDE Mix"]) - addon().key_coords(key_blocks(head)["Basis"])
    assert np.abs(mix).max() > 0.1


def test_rebuild_keeps_the_users_keys_drivers_and_modifiers(bpy, ict_head):
    head, eyes, *_ = ict_head
    head.shape_key_add(name="Basis", from_mix=False)
    mine = head.shape_key_add(name="Frown mine", from_mix=False)
    co = addon().key_coords(mine) + 0.05
    addon().set_key_coords(mine, co)
    mine.value = 0.3
    mine.keyframe_insert("value", frame=5)
    drv = key_blocks(head)["Frown mine"].driver_add("slider_max").driver
    drv.expression = "1.5"
    head.modifiers.new("Sub", "SUBSURF")
    uv_before = [tuple(d.uv) for d in head.data.uv_layers[0].data] if head.data.uv_layers else []
    assert bpy.ops.pdeface.fit_to_selected() == {"FINISHED"}
    assert bpy.ops.pdeface.build_shape_keys() == {"FINISHED"}  # a rebuild
    kb = key_blocks(head)
    assert kb[0].name == "Basis" and "Frown mine" in kb and AU12 in kb
    np.testing.assert_allclose(addon().key_coords(kb["Frown mine"]), co, atol=1e-6)
    assert head.data.shape_keys.animation_data.drivers[0].driver.expression == "1.5"
    assert [m.name for m in head.modifiers] == ["Sub"]
    assert uv_before == ([tuple(d.uv) for d in head.data.uv_layers[0].data] if head.data.uv_layers else [])
    bpy.context.scene.frame_set(5)
    assert kb["Frown mine"].value == pytest.approx(0.3)


def test_part_overrides_from_vertex_groups(bpy, ict_head):
    head, eyes, *_ = ict_head
    g = eyes.vertex_groups.new(name="pdeface_rest")
    g.add(list(range(len(eyes.data.vertices))), 1.0, "REPLACE")
    assert bpy.ops.pdeface.fit_to_selected() == {"FINISHED"}
    kb = key_blocks(eyes)
    up = addon().key_coords(kb["AU63 Eyes Up"]) - addon().key_coords(kb["Basis"])
    assert np.abs(up).max() == 0  # the user said the eyeballs do not move


def test_the_binding_fans_ngons_as_the_core_does(bpy):
    """The binding's triangles are ``pdeface rig``'s: each n-gon fanned from its best corner at the rest shape
    (they were fanned from its first corner on zero coordinates, where every corner scored the same)."""
    from pdeface.mesh import Mesh

    from tests.core.test_unseen2 import _hexagons

    V, quads, hexes = _hexagons()
    polygons = quads + hexes
    pde = Mesh(V, np.array([len(p) for p in polygons]), np.concatenate(polygons))
    obj = bpy.data.objects.new("Hexagons", addon().new_mesh("Hexagons", pde))
    bpy.context.collection.objects.link(obj)
    obj.location, obj.rotation_euler = (1.0, 2.0, 3.0), (0.3, 0.0, 1.0)  # the fan is chosen in its own space
    bpy.context.view_layer.update()
    core = Mesh(addon().vertices(obj.data), pde.face_counts, pde.face_indices)
    assert core.fan_apexes()[len(quads):].any()  # some hexagon fans from a corner other than its first
    T = addon("head")._joined([obj])[1]
    assert np.array_equal(T, core.triangles()[0])


def test_a_mesh_without_a_face_loses_nothing(bpy, tmp_path):
    bpy.ops.mesh.primitive_uv_sphere_add(radius=10)
    ball = bpy.context.active_object
    s = bpy.context.scene.pdeface
    s.landmark_source = "FILE"
    pts = np.array([[np.cos(a) * 9, np.sin(a) * 9, 0.0] for a in np.linspace(0, 6, 68)])
    (tmp_path / "lm.json").write_text(json.dumps({"points": pts.tolist()}))
    s.landmark_file = str(tmp_path / "lm.json")
    n = len(bpy.data.objects)
    with pytest.raises(RuntimeError):
        bpy.ops.pdeface.fit_to_selected()
    assert len(bpy.data.objects) == n and ball.data.shape_keys is None


def test_live_link_and_tracker_import_drive_the_users_head(bpy, ict_head, tmp_path):
    import socket

    head, eyes, *_ = ict_head
    assert bpy.ops.pdeface.fit_to_selected() == {"FINISHED"}
    s = bpy.context.scene.pdeface
    s.live_port, s.live_mode = 0, "queue"
    assert bpy.ops.pdeface.live_start() == {"FINISHED"}  # the user's head is active
    link = addon("live")
    try:
        sock = socket.create_connection(tuple(link.status()["address"]), timeout=5)
        sock.sendall(b"{12}")
        deadline = time.monotonic() + 5
        while key_blocks(head)[AU12].value < 1.0:  # the timer's work, called directly (no event loop headless)
            assert time.monotonic() < deadline
            link.tick()
            time.sleep(0.02)
        bpy.context.view_layer.update()  # the eyes' key follows the head's by a driver: evaluated on redraw
        assert key_blocks(eyes)[AU12].value == 1.0
        sock.close()
    finally:
        bpy.ops.pdeface.live_stop()
    timeline = {"format": "pdeface.timeline", "version": 1, "fps": 24,
                "keys": [{"frame": 1, "aus": {"4": 0.0}}, {"frame": 12, "aus": {"4": 1.0}}]}
    (tmp_path / "t.json").write_text(json.dumps(timeline))
    assert bpy.ops.pdeface.import_au(filepath=str(tmp_path / "t.json"), format="timeline") == {"FINISHED"}
    bpy.context.scene.frame_set(12)
    assert key_blocks(head)["AU4 Brow Lowerer"].value == pytest.approx(1.0)


def test_add_ict_head_is_a_rigged_character(bpy):
    assert bpy.ops.pdeface.add_ict_head() == {"FINISHED"}
    head = bpy.context.active_object
    assert "ICT-FaceKit" in head["pdeface_notice"] and len(head.data.vertices) == 26719
    n_aus = len(addon().face_model(head.pdeface.rig_face).descriptors)  # 63 from ICT + 9 muscle AUs
    assert n_aus == 72 and head.pdeface.rig_face.hide_get() and len(key_blocks(head)) == 1 + n_aus + 10
    assert {m.name for m in head.data.materials} >= {"PDE Skin", "PDE Eye", "PDE Teeth"}
    jaw = addon().key_coords(key_blocks(head)["AU27 Mouth Stretch"]) - addon().key_coords(key_blocks(head)["Basis"])
    assert np.linalg.norm(jaw, axis=1).max() > 2  # cm: the jaw opens, teeth with it
    # The iris is drawn around UV (0.5, 0.5) of each eyeball: the front of the eye at rest, turning with the gaze keys
    me = head.data
    eye = [m.name for m in me.materials].index("PDE Eye")
    on_eye = np.zeros(len(me.polygons), bool)
    on_eye[[p.index for p in me.polygons if p.material_index == eye]] = True
    corners = np.array([i for p in me.polygons if on_eye[p.index] for i in p.loop_indices])
    uv = addon().loop_uvs(me)[corners]
    centre = np.unique([me.loops[i].vertex_index for i in corners[np.linalg.norm(uv - 0.5, axis=1) < 0.01]])
    eyeballs = np.unique([me.loops[i].vertex_index for i in corners])
    frame = addon().face_model(head.pdeface.rig_face).frame
    rest = frame.to_face(addon().key_coords(key_blocks(head)["Basis"]))
    for sign in (1, -1):  # each eye: its iris centre is its most forward point (mm; the face looks along +z)
        iris, ball = centre[sign * rest[centre, 0] > 0], eyeballs[sign * rest[eyeballs, 0] > 0]
        assert len(iris) and abs(rest[iris, 2].mean() - rest[ball, 2].max()) < 0.3
    for au, axis in (("AU61 Eyes Turn Left", 0), ("AU64 Eyes Down", 1)):
        moved = frame.to_face(addon().key_coords(key_blocks(head)[au]))[centre] - rest[centre]
        assert np.abs(moved[:, axis]).min() > 3.0  # mm: both irises look aside, or down


def test_fdt_key_on_the_users_head(bpy, ict_head):
    """An FDT loaded as a key goes on the user's objects too: the head binding of the table's curve change."""
    from pdeface.assets import load_head
    from pdeface.fdt.deform import fdt_curves
    from pdeface.fdt.table import load_fdt
    from pdeface.head.bind import HeadBinding

    head, eyes, head_idx, _ = ict_head
    assert bpy.ops.pdeface.fit_to_selected() == {"FINISHED"}
    assert bpy.ops.pdeface.load_fdt(filepath="27") == {"FINISHED"}  # the jaw's AU: the lower teeth turn too
    name = "FDT 27 (3d)"
    assert name in key_blocks(head) and name in key_blocks(eyes) and name in key_blocks(head.pdeface.rig_face)
    mesh, _ = load_head()
    model = addon().face_model(head.pdeface.rig_face)
    want = mesh.vertices + HeadBinding(model, mesh.vertices, mesh.triangles()[0]).displacement(
        *fdt_curves(model, load_fdt("27")), jaw=True)
    np.testing.assert_allclose(addon().key_coords(key_blocks(head)[name]), want[head_idx], atol=1e-5)
    moved = np.linalg.norm(want - mesh.vertices, axis=1)
    assert moved.max() > 2  # cm: the chin drops
    assert bpy.ops.pdeface.apply_preset(preset="happy", mode="KEY") == {"FINISHED"}
    assert key_blocks(head)[name].value == 0.0  # an expression key: another expression's pose sets it to 0


def test_the_unit_is_estimated_named_or_millimetres_per_unit(bpy, ict_head):
    s, face = bpy.context.scene.pdeface, addon("face")
    assert s.unit == "AUTO" and face.chosen_unit(s) is None
    s.unit = "cm"
    assert face.chosen_unit(s) == "cm"
    s.unit, s.unit_mm = "CUSTOM", 0.01  # float32 in Blender: the digits typed, not 0.009999999776
    assert face.chosen_unit(s) == 0.01
    s.unit_mm = 10.0
    assert face.chosen_unit(s) == 10.0
    assert bpy.ops.pdeface.fit_to_selected(keys_on_mesh=False) == {"FINISHED"}  # ICT's head is in cm: 10 mm per unit
    s.unit_mm = 1.0  # said to be in millimetres: its eyes 6.5 mm apart, refused naming the unit
    bpy.context.view_layer.objects.active = ict_head[0]
    with pytest.raises(RuntimeError, match="eyes are .* mm apart in unit 'mm'"):
        bpy.ops.pdeface.fit_to_selected(keys_on_mesh=False)
