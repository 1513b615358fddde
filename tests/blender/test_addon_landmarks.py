"""Landmarks without clicks in Blender: Find Landmarks, empties to nudge, Fit on its own, and the model's install."""
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
