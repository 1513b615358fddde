"""Landmarks without clicks in Blender: Find Landmarks, empties to nudge, Fit on its own, and the model's install."""
import json
import sys

import numpy as np
import pytest
from pdeface.landmarks import available

MODULE = "bl_ext.pdeface_test.pdeface"

needs_mediapipe = pytest.mark.skipif(not available(), reason='needs pip install "pdeface[landmarks]"')


@pytest.fixture
def head_object(bpy):
    """ICT's generic head as a user's mesh: Blender's axes, metres, turned 25° by its object transform."""
    from pdeface.assets import load_head
    from pdeface.surface.frame import BLENDER_FROM_ICT

    addon = __import__(MODULE, fromlist=["bridge"])
    mesh, lm = load_head()
    mesh.vertices = mesh.vertices @ BLENDER_FROM_ICT.T * 0.01
    obj = bpy.data.objects.new("Head", addon.bridge.new_mesh("Head", mesh))
    bpy.context.collection.objects.link(obj)
    obj.rotation_euler = (0, 0, np.radians(25))
    obj.location = (1, 2, 0)
    bpy.context.view_layer.objects.active = obj
    obj.select_set(True)
    obj.vertex_groups.new(name="my group")
    obj.shape_key_add(name="Basis")
    obj.shape_key_add(name="my key")
    return obj, mesh.vertices[lm]


@needs_mediapipe
def test_find_landmarks_shows_empties_and_fit_uses_them_nudged(bpy, head_object):
    addon = __import__(MODULE, fromlist=["landmarks"])
    obj, true = head_object
    assert bpy.ops.pdeface.find_landmarks() == {"FINISHED"}
    lms = addon.landmarks.empties(obj)
    assert lms is not None and all(e.parent == obj for e in lms)
    found = addon.landmarks.empty_points(obj)
    err = np.linalg.norm(found - true, axis=1) * 1000
    assert np.median(err[17:]) < 2.0 and np.median(err[:17]) < 6.0
    # The user nudges the chin 2 mm down; Fit (Automatic) uses the empties as they are now.
    lms[8].location.z -= 0.002
    before = [e.name for e in lms]
    assert bpy.context.scene.pdeface.landmark_source == "AUTO"
    assert bpy.ops.pdeface.fit_to_selected() == {"FINISHED"}
    assert [e.name for e in addon.landmarks.empties(obj)] == before  # not found again
    assert addon.landmarks.empty_points(obj)[8] == pytest.approx(found[8] - [0, 0, 0.002])
    pde = obj.pdeface.rig_face
    assert pde is not None and pde.pdeface.source == obj
    # The user's own group and key are still there, beside the AU keys.
    assert "my group" in obj.vertex_groups and "my key" in obj.data.shape_keys.key_blocks
    assert "AU12 Lip Corner Puller" in obj.data.shape_keys.key_blocks


@needs_mediapipe
def test_fit_with_no_landmarks_finds_them_itself(bpy, head_object):
    addon = __import__(MODULE, fromlist=["landmarks"])
    obj, _ = head_object
    assert addon.landmarks.empties(obj) is None
    assert bpy.ops.pdeface.fit_to_selected(keys_on_mesh=False) == {"FINISHED"}
    assert addon.landmarks.empties(obj) is not None
    assert obj.pdeface.rig_face is None and bpy.context.active_object.pdeface.is_face


def test_without_the_model_fit_says_how_to_install_it(bpy, head_object, monkeypatch):
    from pdeface.landmarks import detector

    def missing():
        raise detector.MissingDependencyError(detector.INSTALL_HINT)

    monkeypatch.setattr(detector, "_mediapipe", missing)
    obj, _ = head_object
    with pytest.raises(RuntimeError, match="Install Landmark Model"):
        bpy.ops.pdeface.fit_to_selected()
    assert obj.pdeface.rig_face is None and len(bpy.data.objects) == 1  # nothing made


def test_install_goes_to_the_extension_folder_without_touching_blenders_numpy(bpy):
    addon = __import__(MODULE, fromlist=["landmarks"])
    target = addon.landmarks.site_dir(create=True)
    cmd = addon.landmarks.install_command(target)
    assert cmd[:3] == [sys.executable, "-m", "pip"] and cmd[cmd.index("--target") + 1] == target
    assert "--no-deps" in cmd and any(c.startswith("mediapipe==0.10.") for c in cmd)
    assert not any(c.split("=")[0].split("<")[0].split(">")[0] == "numpy" for c in cmd)
    assert "pdeface_test" in target and target.startswith(bpy.utils.resource_path("USER"))
    addon.landmarks.add_site()
    assert sys.path.index(target) > sys.path.index(next(p for p in sys.path if p.endswith("site-packages")))


def given_head(bpy, source, tmp_path, head="ict-expression"):
    """A head of ``scripts/devset/unseen.py`` as a user's mesh (Blender's axes, metres): ``ict-expression`` (ICT's
    identity 004, its eyes closed), ``expression-at-rest`` (a MakeHuman character, its eyes closed), or ``open``
    (ICT's identity 004 at rest); its 68 landmarks given through ``source`` (the nearest vertices where the source
    lists vertices)."""
    import bmesh
    from pdeface.mesh import Mesh
    from pdeface.surface.frame import BLENDER_FROM_ICT

    from scripts.devset import makehuman
    from scripts.devset.unseen import BUILDERS

    addon = __import__(MODULE, fromlist=["bridge"])
    if head == "open":
        from pdeface.assets import load_head, load_head_shapes

        mesh, lm = load_head()
        V, T = mesh.vertices + load_head_shapes()["identity004"], mesh.triangles()[0]
        L = V[lm]
    else:
        if head == "expression-at-rest" and not makehuman.available():
            pytest.skip("needs ../shared/data/makehuman")
        V, T, L, _ = BUILDERS[head]()
    V, L = (X @ BLENDER_FROM_ICT.T * 0.01 for X in (V, L))  # both builders' heads are in centimetres
    obj = bpy.data.objects.new("Blink", addon.bridge.new_mesh("Blink", Mesh(V, np.full(len(T), 3), T.ravel())))
    bpy.context.collection.objects.link(obj)
    bpy.context.view_layer.objects.active = obj
    obj.select_set(True)
    settings = bpy.context.scene.pdeface
    settings.landmark_source = source
    lm = [int(np.argmin(np.linalg.norm(V - p, axis=1))) for p in L]
    if source == "FILE":
        path = tmp_path / "lm.json"
        path.write_text(json.dumps({"points": L.tolist()}))
        settings.landmark_file = str(path)
    elif source == "SELECTED":  # picked one by one in Edit Mode: the selection history
        bm = bmesh.new()
        bm.from_mesh(obj.data)
        bm.verts.ensure_lookup_table()
        for i in lm:
            bm.verts[i].select = True
            bm.select_history.add(bm.verts[i])
        bm.to_mesh(obj.data)
        bm.free()
    else:  # a vertex group ordered by weight; AUTO reads it too when the mesh has no landmark empties
        group = obj.vertex_groups.new(name=settings.landmark_group)
        for k, i in enumerate(lm):
            group.add([i], (k + 1) / 68, "REPLACE")
    return obj


@pytest.mark.parametrize("source, head", [("FILE", "ict-expression"), ("GROUP", "ict-expression"),
                                          ("SELECTED", "ict-expression"), ("AUTO", "ict-expression"),
                                          ("FILE", "expression-at-rest")])
def test_a_head_with_its_eyes_closed_is_refused_whichever_source_gives_its_landmarks(bpy, source, head, tmp_path):
    """As the CLI with --landmarks: the gate's look at the mesh runs before the fit, an ERROR naming the check
    stops it with nothing made, the panel offers Accept anyway and Fit. On ICT's head and a MakeHuman one."""
    from tests.blender.test_addon_landmark_editor import draw_panel

    addon = __import__(MODULE, fromlist=["landmarks"])
    obj = given_head(bpy, source, tmp_path, head)
    with pytest.raises(RuntimeError, match=r"Blink and its given landmarks fail the landmark gate: eyes: closed "
                                           r"\(both eyes' lids meet .*; give the head at rest .*Accept anyway"):
        bpy.ops.pdeface.fit_to_selected()
    assert obj.pdeface.rig_face is None and len(bpy.data.objects) == 1  # nothing made, no empties
    assert addon.landmarks.failing_groups(obj) == ["eyes"] and "closed" in obj[addon.landmarks.GATE_PROP]
    layout = draw_panel(bpy, bpy.types.PDEFACE_PT_face)
    assert "Landmark gate: eyes failed" in layout.texts("label")
    assert "Accept anyway and Fit" in layout.texts("operator")


def test_accept_fits_a_head_with_its_eyes_closed_and_open_eyes_pass(bpy, tmp_path):
    addon = __import__(MODULE, fromlist=["landmarks"])
    obj = given_head(bpy, "FILE", tmp_path)
    assert bpy.ops.pdeface.fit_to_selected(accept=True, keys_on_mesh=False) == {"FINISHED"}
    assert bpy.context.active_object.pdeface.is_face and bpy.context.active_object.pdeface.source == obj
    # The same head with its eyes open: the look at the mesh passes, and the panel's line goes.
    bpy.ops.wm.read_homefile(use_empty=True)
    obj = given_head(bpy, "FILE", tmp_path, "open")
    points, _ = addon.face.read_landmarks(bpy.context.scene.pdeface, obj)
    obj[addon.landmarks.GATE_GROUPS_PROP] = "eyes"  # a failure from before the eyes were opened
    source = addon.face.landmark_origin(bpy.context.scene.pdeface, obj)
    assert addon.landmarks.at_rest(obj, points, source) is None and addon.landmarks.failing_groups(obj) == []


def test_a_given_sources_verdict_is_not_shown_as_the_empties_after_a_switch(bpy, tmp_path):
    """The look at the mesh fails a file's landmarks (eyes closed); the same points imported as empties and the
    source switched to Automatic, the panels call that verdict stale (the whole gate has not judged the empties),
    with no failing group and no Accept anyway, and the empties are not highlighted; switched back, it shows."""
    from tests.blender.test_addon_landmark_editor import draw_panel

    addon = __import__(MODULE, fromlist=["landmarks"])
    lms_mod, settings = addon.landmarks, bpy.context.scene.pdeface
    obj = given_head(bpy, "FILE", tmp_path)
    with pytest.raises(RuntimeError, match="eyes: closed"):
        bpy.ops.pdeface.fit_to_selected()
    given = f"file {settings.landmark_file!r}"
    assert lms_mod.verdict_source(obj) == given and lms_mod.failing_groups(obj, given) == ["eyes"]
    assert bpy.ops.pdeface.import_landmarks(filepath=settings.landmark_file) == {"FINISHED"}
    settings.landmark_source = "AUTO"
    assert addon.face.landmark_origin(settings, obj) == lms_mod.EMPTIES
    assert lms_mod.failing_groups(obj, lms_mod.EMPTIES) == []
    for panel in (bpy.types.PDEFACE_PT_face, bpy.types.PDEFACE_PT_landmarks):
        layout = draw_panel(bpy, panel)
        labels = layout.texts("label")
        assert not any(t.startswith("Landmark gate:") for t in labels)
        assert "Accept anyway and Fit" not in layout.texts("operator")
        assert "The landmark gate's last failure is stale" in labels
        assert f"it judged {given}; Fit checks {lms_mod.EMPTIES}" in labels
    groups = [kw.get("icon") for name, args, kw in draw_panel(bpy, bpy.types.PDEFACE_PT_landmarks).drawn
              if name == "label" and args == () and kw.get("text", "").startswith("eyes ")]
    assert groups == ["DOT"]
    assert all(e.empty_display_type == "SPHERE" for e in lms_mod.empties(obj))
    settings.landmark_source = "FILE"
    assert "Landmark gate: eyes failed" in draw_panel(bpy, bpy.types.PDEFACE_PT_face).texts("label")
