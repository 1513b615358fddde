"""The guided landmark editor: edit the empties, snap, re-fit and re-rig from them, the gate in the panel,
export/import of the landmarks JSON, and the empties saved with the .blend. No landmark model needed: the
landmarks come in through Import Landmarks (ICT's own, on ICT's head as a user's mesh)."""
import json

import numpy as np
import pytest

MODULE = "bl_ext.pdeface_test.pdeface"
AU12 = "AU12 Lip Corner Puller"


def addon():
    return __import__(MODULE, fromlist=["landmarks"])


def character_mesh(name):
    """A head in Blender's axes and metres, and its 68 true landmarks: ICT's generic head, or a MakeHuman
    character of the development set (not tuned on)."""
    from pdeface.mesh import Mesh

    if name == "ict":
        from pdeface.assets import load_head
        from pdeface.surface.frame import BLENDER_FROM_ICT

        mesh, lm = load_head()
        mesh.vertices = mesh.vertices @ BLENDER_FROM_ICT.T * 0.01
        return mesh, mesh.vertices[lm]
    from scripts.devset import makehuman
    from scripts.devset.characters import SPECS, build

    if not makehuman.available():
        pytest.skip("needs ../shared/data/makehuman")
    c = build(SPECS["asian-male-young-blender-m"])
    T = np.asarray(c.triangles)
    return Mesh(c.vertices, np.full(len(T), 3), T.ravel()), c.landmarks


@pytest.fixture
def head(bpy, tmp_path, request):
    """A head as a user's mesh (Blender's axes, metres, turned 25°; ICT's unless the test names another), its
    68 landmarks imported as empties from a JSON file; returns the object and the true points (object space)."""
    mesh, points = character_mesh(getattr(request, "param", "ict"))
    obj = bpy.data.objects.new("Head", addon().bridge.new_mesh("Head", mesh))
    bpy.context.collection.objects.link(obj)
    obj.rotation_euler = (0, 0, np.radians(25))
    obj.location = (1, 2, 0)
    bpy.context.view_layer.objects.active = obj
    obj.select_set(True)
    bpy.context.view_layer.update()
    path = tmp_path / "truth.json"
    path.write_text(json.dumps({"points": points.tolist()}))
    assert bpy.ops.pdeface.import_landmarks(filepath=str(path)) == {"FINISHED"}
    return obj, points


class Layout:
    """A stand-in for a panel's layout that records what is drawn: labels, operators and icons."""

    def __init__(self, drawn=None):
        self.drawn = [] if drawn is None else drawn

    def __getattr__(self, name):  # column, row, box, label, operator, template_icon, prop, ...
        def draw(*args, **kwargs):
            self.drawn.append((name, args, kwargs))
            return Layout(self.drawn)
        return draw

    def texts(self, kind):
        return [kw.get("text", args[0] if args else "") for name, args, kw in self.drawn if name == kind]


def draw_panel(bpy, panel):
    layout = Layout()
    panel.draw(type("Panel", (), {"layout": layout})(), bpy.context)
    return layout


def key_displacement(obj, name):
    """Per vertex, how far the key moves it from the basis (object space)."""
    kb = obj.data.shape_keys.key_blocks
    co = np.array([v.co for v in kb[name].data])
    base = np.array([v.co for v in kb["Basis"].data])
    return np.linalg.norm(co - base, axis=1), base


def model_landmarks(face):
    """The landmarks the fitted PDE face keeps (its model's, face frame), back in the user's object space."""
    model = addon().bridge.face_model(face)
    return (model.landmarks / model.frame.scale) @ model.frame.rotation + model.frame.origin


def corner_pull(obj, at):
    """How far the AU12 key moves the mesh's vertices nearest to the points ``at`` (object space)."""
    d, base = key_displacement(obj, AU12)
    return np.array([d[np.argmin(np.linalg.norm(base - p, axis=1))] for p in at])


@pytest.mark.parametrize("head", ["ict", "makehuman"], indirect=True)
def test_edit_three_points_snap_refit_and_the_keys_follow(bpy, head):
    lms_mod = addon().landmarks
    obj, true = head
    lms = lms_mod.empties(obj)
    assert lms is not None and np.allclose(lms_mod.empty_points(obj), true, atol=1e-6)
    assert bpy.ops.pdeface.fit_to_selected() == {"FINISHED"}
    assert obj.get(lms_mod.GATE_PROP) == "" and lms_mod.failing_groups(obj) == []
    first_face = obj.pdeface.rig_face
    # The user drags three mouth empties: both corners 4 mm up and the lower lip's bottom 3 mm down, a little in
    # front of the surface (a drag in a front view), then snaps them back onto it.
    moves = {48: (0, -0.002, 0.004), 54: (0, -0.002, 0.004), 57: (0, -0.002, -0.003)}
    for i, (dx, dy, dz) in moves.items():
        lms[i].location.x += dx
        lms[i].location.y += dy
        lms[i].location.z += dz
    bpy.context.view_layer.objects.active = lms[48]
    assert bpy.ops.pdeface.snap_landmarks() == {"FINISHED"}
    edited = lms_mod.empty_points(obj)
    V = addon().bridge.vertices(obj.data)
    for i in moves:  # on the surface (within the mesh's spacing), moved the way they were dragged
        assert np.min(np.linalg.norm(V - edited[i], axis=1)) < 0.003
        assert np.sign(edited[i, 2] - true[i, 2]) == np.sign(moves[i][2]) and abs(edited[i, 2] - true[i, 2]) > 0.0015
    untouched = [i for i in range(68) if i not in moves]
    assert np.allclose(edited[untouched], true[untouched], atol=1e-6)
    corners = [48, 54]
    before = corner_pull(obj, edited[corners]) - corner_pull(obj, true[corners])
    bpy.context.view_layer.objects.active = obj
    assert bpy.ops.pdeface.fit_to_selected() == {"FINISHED"}
    face = obj.pdeface.rig_face
    assert face is not None and face != first_face and face.pdeface.source == obj
    # The fitted face's mouth corners and lower lip are the edited ones (its model keeps them, 0.1 mm steps)...
    assert np.abs(model_landmarks(face)[[48, 54, 57]] - edited[[48, 54, 57]]).max() < 2e-4
    # ...and the AU12 key on the user's mesh follows: it now pulls hardest at the edited corners.
    after = corner_pull(obj, edited[corners]) - corner_pull(obj, true[corners])
    print(f"AU12 pull at the edited corners minus at the old ones (mm): before {before * 1000}, after {after * 1000}")
    assert (after > before + 0.0005).all() and (after > 0).all(), (before, after)
    assert AU12 in obj.data.shape_keys.key_blocks


def test_export_writes_the_empties_and_refuses_to_overwrite(bpy, head, tmp_path):
    from pdeface.surface.frame import read_landmarks

    lms_mod = addon().landmarks
    obj, _ = head
    lms_mod.empties(obj)[30].location.y -= 0.001
    bpy.context.view_layer.update()
    path = tmp_path / "edited.json"
    assert bpy.ops.pdeface.export_landmarks(filepath=str(path)) == {"FINISHED"}
    _, points = read_landmarks(path)  # the CLI's reader
    assert np.allclose(points, lms_mod.empty_points(obj), atol=1e-9)
    path.write_text("mine")
    with pytest.raises(RuntimeError, match="exists; tick Overwrite"):
        bpy.ops.pdeface.export_landmarks(filepath=str(path))
    assert path.read_text() == "mine"
    assert bpy.ops.pdeface.export_landmarks(filepath=str(path), overwrite=True, indices=True) == {"FINISHED"}
    idx, _ = read_landmarks(path)
    assert len(idx) == 68 and np.linalg.norm(
        addon().bridge.vertices(obj.data)[idx] - lms_mod.empty_points(obj), axis=1).max() < 0.003


@pytest.mark.parametrize("head", ["ict", "makehuman"], indirect=True)
def test_a_gate_failure_leaves_the_scene_editable_with_the_failing_group(bpy, head):
    lms_mod = addon().landmarks
    obj, true = head
    lms = lms_mod.empties(obj)
    for i in (50, 51, 52):  # three upper-lip points pushed 1 cm into the mouth (the face looks down -Y)
        lms[i].location.y += 0.01
    with pytest.raises(RuntimeError, match="mouth: surface"):
        bpy.ops.pdeface.fit_to_selected()
    assert obj.pdeface.rig_face is None and not any(o.pdeface.is_face for o in bpy.data.objects)
    assert lms_mod.empties(obj) is not None and lms_mod.failing_groups(obj) == ["mouth"]
    assert "mouth" in obj[lms_mod.GATE_PROP] and "surface" in obj[lms_mod.GATE_PROP]
    mouth = bpy.data.collections[f"{lms_mod.COLLECTION} mouth"]
    assert mouth.color_tag == lms_mod.FAILING_TAG and bpy.data.collections[f"{lms_mod.COLLECTION} eyes"].color_tag \
        == lms_mod.GROUP_TAGS["eyes"]
    assert all(e.select_get() and e.empty_display_type == "CUBE" for e in lms[48:68])
    assert lms[50].empty_display_size == pytest.approx(2 * lms[36].empty_display_size)
    assert not any(e.select_get() for e in lms[:48])
    # The Landmarks panel shows the failing group, the gate's line, the scheme and Accept anyway; also when a
    # landmark empty is the active object (the user dragging it).
    bpy.context.view_layer.objects.active = lms[50]
    panel = bpy.types.PDEFACE_PT_landmarks
    assert panel.poll(bpy.context)
    layout = draw_panel(bpy, panel)
    labels = layout.texts("label")
    assert "Landmark gate: mouth failed" in labels and any("surface" in t for t in labels)
    assert "Accept anyway and Fit" in layout.texts("operator")
    assert {"pdeface.snap_landmarks", "pdeface.export_landmarks", "pdeface.import_landmarks"} <= {
        args[0] for name, args, _ in layout.drawn if name == "operator"}
    assert any(name == "template_icon" for name, _, _ in layout.drawn)  # the scheme (its icon id is 0 headless)
    bpy.context.view_layer.objects.active = obj
    assert "Accept anyway and Fit" in draw_panel(bpy, bpy.types.PDEFACE_PT_face).texts("operator")
    assert bpy.ops.pdeface.fit_to_selected(accept=True) == {"FINISHED"}
    assert obj.pdeface.rig_face is not None
    # Put back and fitted again: the gate passes and the highlight goes.
    for i in (50, 51, 52):
        lms[i].location = true[i]
    bpy.context.view_layer.objects.active = obj
    assert bpy.ops.pdeface.fit_to_selected() == {"FINISHED"}
    assert lms_mod.failing_groups(obj) == [] and mouth.color_tag == lms_mod.GROUP_TAGS["mouth"]
    assert lms[50].empty_display_type == "SPHERE" and lms[50].empty_display_size == lms[36].empty_display_size


def _mouth_refused(bpy, lms_mod, obj):
    """Push three upper-lip empties 1 cm into the mouth and Fit: the gate fails the mouth. Returns the empties."""
    lms = lms_mod.empties(obj)
    for i in (50, 51, 52):
        lms[i].location.y += 0.01
    with pytest.raises(RuntimeError, match="mouth: surface"):
        bpy.ops.pdeface.fit_to_selected()
    return lms


def test_the_empties_verdict_shows_only_while_the_fit_reads_them(bpy, head, tmp_path):
    """The gate fails the edited empties; switched to a JSON file, the panels call that verdict stale (no failing
    group, no Accept anyway) and name both sources; switched back, it shows. The file's landmarks fitted, its verdict
    replaces the empties' and their highlight goes (it is not theirs)."""
    lms_mod, settings = addon().landmarks, bpy.context.scene.pdeface
    obj, _ = head
    lms = _mouth_refused(bpy, lms_mod, obj)
    assert lms_mod.verdict_source(obj) == lms_mod.EMPTIES
    panels = (bpy.types.PDEFACE_PT_face, bpy.types.PDEFACE_PT_landmarks)
    assert all("Landmark gate: mouth failed" in draw_panel(bpy, p).texts("label") for p in panels)
    settings.landmark_source, settings.landmark_file = "FILE", str(tmp_path / "truth.json")  # the fixture's file
    given = f"file {settings.landmark_file!r}"
    for panel in panels:
        layout = draw_panel(bpy, panel)
        labels = layout.texts("label")
        assert not any(t.startswith("Landmark gate:") for t in labels)
        assert "Accept anyway and Fit" not in layout.texts("operator")
        assert f"it judged {lms_mod.EMPTIES}; Fit checks {given}" in labels
    settings.landmark_source = "AUTO"
    assert all("Landmark gate: mouth failed" in draw_panel(bpy, p).texts("label") for p in panels)
    settings.landmark_source = "FILE"
    assert bpy.ops.pdeface.fit_to_selected(keys_on_mesh=False) == {"FINISHED"}
    assert lms_mod.verdict_source(obj) == given and lms_mod.failing_groups(obj) == []
    assert lms[50].empty_display_type == "SPHERE" and not lms[50].select_get()


def test_an_older_blends_verdict_on_the_empties_shows_while_it_is_theirs(bpy, head):
    """A .blend saved before verdicts named their source: the empties' failure shows, with Accept anyway, while its
    digest is still the empties'; once they move, it reads as stale."""
    lms_mod = addon().landmarks
    obj, _ = head
    lms = _mouth_refused(bpy, lms_mod, obj)
    del obj[lms_mod.GATE_SOURCE_PROP]  # as an older add-on saved it
    panels = (bpy.types.PDEFACE_PT_face, bpy.types.PDEFACE_PT_landmarks)
    for panel in panels:
        layout = draw_panel(bpy, panel)
        assert "Landmark gate: mouth failed" in layout.texts("label")
        assert "Accept anyway and Fit" in layout.texts("operator")
    lms[50].location.y -= 0.005
    bpy.context.view_layer.update()
    assert lms_mod.verdict_source(obj) is None and lms_mod.failing_groups(obj, lms_mod.EMPTIES) == []
    for panel in panels:
        labels = draw_panel(bpy, panel).texts("label")
        assert "The landmark gate's last failure is stale" in labels and not any(
            t.startswith("Landmark gate:") for t in labels)


def test_the_empties_are_saved_with_the_blend_and_the_scheme_shows_beside_the_head(bpy, head, tmp_path):
    lms_mod = addon().landmarks
    obj, _ = head
    lms_mod.empties(obj)[8].location.z -= 0.002
    bpy.context.view_layer.update()
    points = lms_mod.empty_points(obj)
    assert bpy.ops.pdeface.show_landmark_scheme() == {"FINISHED"}
    ref = bpy.data.objects["Head landmark scheme"]
    assert ref.empty_display_type == "IMAGE" and ref.data.size[0] > 0
    assert ref.matrix_world.translation.x > max((obj.matrix_world @ e.matrix_world.translation).x
                                                for e in lms_mod.empties(obj)) - 1
    path = tmp_path / "edited.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(path))
    bpy.ops.wm.read_homefile(use_empty=True)
    bpy.ops.wm.open_mainfile(filepath=str(path))
    obj = bpy.data.objects["Head"]
    assert np.allclose(lms_mod.empty_points(obj), points, atol=1e-6)
    assert all(e.users_collection[0].name == f"{lms_mod.COLLECTION} {lms_mod.GROUP_OF[i]}"
               for i, e in enumerate(lms_mod.empties(obj)))


def test_find_landmarks_reports_the_gate_and_leaves_the_empties_to_edit(bpy, head, monkeypatch):
    """The detector (stood in for: the gate is what is tested) puts three lower-lip points inside the mouth."""
    from types import SimpleNamespace

    lms_mod = addon().landmarks
    obj, true = head
    bad = true.copy()
    bad[[56, 57, 58], 1] += 0.01
    found = SimpleNamespace(points=bad, confidence=dict.fromkeys(lms_mod.GROUPS, 0.9), view="-y roll 0", skin=None)
    monkeypatch.setattr(lms_mod, "detect_anywhere", lambda V, T, unit: found)
    assert bpy.ops.pdeface.find_landmarks() == {"FINISHED"}  # a warning, not an error: the empties are the work
    assert np.allclose(lms_mod.empty_points(obj), bad, atol=1e-6)
    assert lms_mod.failing_groups(obj) == ["mouth"] and "mouth: surface" in obj[lms_mod.GATE_PROP]
    assert lms_mod.empties(obj)[57].select_get()


def test_fit_reuses_the_gate_of_find_landmarks_until_a_point_or_the_mesh_changes(bpy, head, monkeypatch):
    from types import SimpleNamespace

    lms_mod = addon().landmarks
    obj, true = head
    bad = true.copy()
    bad[[56, 57, 58], 1] += 0.01  # three lower-lip points inside the mouth
    found = SimpleNamespace(points=bad, confidence=dict.fromkeys(lms_mod.GROUPS, 0.9), view="-y roll 0", skin=None)
    monkeypatch.setattr(lms_mod, "detect_anywhere", lambda V, T, unit: found)
    assert bpy.ops.pdeface.find_landmarks() == {"FINISHED"}
    judged, check = [], lms_mod.check
    monkeypatch.setattr(lms_mod, "check", lambda *a, **k: judged.append(1) or check(*a, **k))
    with pytest.raises(RuntimeError, match="mouth: surface"):  # Find's verdict, not judged again
        bpy.ops.pdeface.fit_to_selected()
    assert judged == [] and lms_mod.failing_groups(obj) == ["mouth"]
    lms = lms_mod.empties(obj)
    for i in (56, 57, 58):  # put back: judged again, and passes
        lms[i].location = true[i]
    bpy.context.view_layer.update()
    assert lms_mod.gated(obj, lms_mod.empty_points(obj)) is None and judged == [1]
    assert lms_mod.gated(obj, lms_mod.empty_points(obj)) is None and judged == [1]  # the same points: reused
    obj.data.vertices[0].co.x += 0.001  # the mesh edited: judged again
    assert lms_mod.gated(obj, lms_mod.empty_points(obj)) is None and judged == [1, 1]
