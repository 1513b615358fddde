"""A head with no mouth inside: the fit warns, Add Mouth Bag adds a dark bag that opens with the jaw keys, nothing of
the user's changed but their keys (issue #40)."""
import json
import tempfile
from pathlib import Path

import numpy as np
import pytest

MODULE = "bl_ext.pdeface_test.pdeface"
AU27 = "AU27 Mouth Stretch"


def addon(name="bridge"):
    return __import__(MODULE + "." + name, fromlist=[name])


def evaluated(bpy, obj):
    return addon().vertices(obj.evaluated_get(bpy.context.evaluated_depsgraph_get()).data)


def user_head(bpy, spec, name):
    """A development character as the user's mesh, its 68 landmarks in a JSON file, selected and active."""
    from pdeface.mesh import Mesh

    from scripts.devset import makehuman
    from scripts.devset.characters import build

    if not makehuman.available():
        pytest.skip("needs ../shared/data/makehuman")
    ch = build(spec)
    obj = bpy.data.objects.new(name, addon().new_mesh(name, Mesh.from_faces(ch.vertices, ch.triangles)))
    bpy.context.collection.objects.link(obj)
    path = Path(tempfile.mkdtemp(prefix="pdeface_mouth_")) / "landmarks.json"  # points: fused lips share a vertex
    path.write_text(json.dumps({"points": ch.landmarks.tolist()}))
    bpy.context.scene.pdeface.landmark_source = "FILE"
    bpy.context.scene.pdeface.landmark_file = str(path)
    obj.select_set(True)
    bpy.context.view_layer.objects.active = obj
    bpy.context.view_layer.update()
    return obj


@pytest.fixture
def no_mouth_inside(bpy):
    """The development head whose lips open onto the inside of the head."""
    from scripts.devset.characters import NO_MOUTH_INSIDE

    return user_head(bpy, NO_MOUTH_INSIDE, "Game head")


def test_add_mouth_bag_opens_with_the_jaw_and_leaves_the_head_as_it_was(bpy, no_mouth_inside, monkeypatch):
    head = no_mouth_inside
    built, rigging = [], addon("rigging")
    build = rigging.build_keys
    monkeypatch.setattr(rigging, "build_keys", lambda *a: built.append(build(*a)) or built[-1])
    assert bpy.ops.pdeface.fit_to_selected() == {"FINISHED"}
    monkeypatch.undo()
    face = head.pdeface.rig_face
    warnings = addon("face").binding_warnings(face)
    assert any(w.startswith("no mouth inside") for w in warnings)
    assert built[0]["warnings"] == warnings  # what the operator reports as warnings, from the one binding
    keys = head.data.shape_keys.key_blocks
    before = {n: addon().key_coords(keys[n]).copy() for n in (AU27, "AU12 Lip Corner Puller")}
    rest = addon().vertices(head.data).copy()
    assert bpy.ops.pdeface.add_mouth_bag() == {"FINISHED"}
    bag = next(p.obj for p in face.pdeface.parts if p.obj.name.endswith("mouth bag"))
    assert bag.parent == head and bag.pdeface.rig_face == face and "pdeface_mouth" in bag.vertex_groups
    assert bag.active_material.diffuse_color[0] < 0.1  # dark
    assert not any("mouth inside" in n for n in addon("face").binding_notes(face))
    # The user's mesh is as it was, and so are its keys; the bag has the same keys, driven by the head's.
    np.testing.assert_array_equal(addon().vertices(head.data), rest)
    for n, co in before.items():
        np.testing.assert_allclose(addon().key_coords(head.data.shape_keys.key_blocks[n]), co, atol=1e-5)
    shut = evaluated(bpy, bag)
    head.data.shape_keys.key_blocks[AU27].value = 1.0
    bpy.context.view_layer.update()
    assert bag.data.shape_keys.key_blocks[AU27].value == pytest.approx(1.0)
    opened = evaluated(bpy, bag)
    assert np.linalg.norm(opened - shut, axis=1).max() > 1.0  # cm: its bottom with the jaw
    # Only one bag per head; a second asks says so and adds nothing.
    n_objects = len(bpy.data.objects)
    with pytest.raises(RuntimeError, match="already this head's mouth bag"):
        bpy.ops.pdeface.add_mouth_bag()
    assert len(bpy.data.objects) == n_objects


def test_cut_lips_open_parts_fused_lips_and_keeps_the_users_keys(bpy):
    """A voxel remesh's fused lips: the fit warns; Cut Lips Open (asked for) cuts the mesh along the line between
    them, fits again with the inner lips on either side, and AU27 parts them; the user's own key carries over."""
    from scripts.devset.characters import Spec

    head = user_head(bpy, Spec("voxel-african-male-young", {"african-male-young": 1.0}, remesh="voxel"), "Voxel head")
    assert bpy.ops.pdeface.fit_to_selected() == {"FINISHED"}
    face = head.pdeface.rig_face
    assert any(w.startswith("the lips are joined") for w in addon("face").binding_warnings(face))
    mine = head.shape_key_add(name="My smirk", from_mix=False)  # the user's own key
    n, name = len(head.data.vertices), face.name
    s = bpy.context.scene.pdeface
    s.unit, s.unit_mm = "CUSTOM", 10.0  # the refit takes the unit as the fit does: cm as millimetres per unit
    assert bpy.ops.pdeface.cut_lips_open() == {"FINISHED"}
    new = head.pdeface.rig_face
    assert new.name == name and new.pdeface.is_face
    assert len(bpy.data.objects) == 2  # the head and its new face: the old face removed
    added = len(head.data.vertices) - n
    assert 3 <= added <= 40  # the lip line's inner vertices, copied
    assert "My smirk" in head.data.shape_keys.key_blocks and mine.name == "My smirk"
    notes = addon("face").binding_notes(new)
    assert not any("lips are joined" in x for x in notes) and any(x.startswith("no mouth inside") for x in notes)
    # AU27 parts the lips: the inner lips' middles (on either side of the cut) move apart by a quarter eye distance.
    model = addon().face_model(new)
    f = model.frame
    rest = addon().key_coords(head.data.shape_keys.reference_key)
    opened = addon().key_coords(head.data.shape_keys.key_blocks["AU27 Mouth Stretch"])
    X, P = f.to_face(rest.astype(float)), f.to_face(opened.astype(float))
    Lf = model.landmarks
    up, lo = (int(np.argmin(np.linalg.norm(X - Lf[i], axis=1))) for i in (62, 66))
    ed = np.linalg.norm(Lf[36:42].mean(0) - Lf[42:48].mean(0))
    assert up != lo and (P[up, 1] - P[lo, 1]) - (X[up, 1] - X[lo, 1]) >= 0.25 * ed
    assert bpy.ops.pdeface.add_mouth_bag() == {"FINISHED"}
    with pytest.raises(RuntimeError, match="not joined"):
        bpy.ops.pdeface.cut_lips_open()
