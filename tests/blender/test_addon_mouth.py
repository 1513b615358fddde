"""A head with no mouth inside: the fit warns, Add Mouth Bag adds a dark bag that opens with the jaw keys, nothing of
the user's changed but their keys (issue #40)."""
import numpy as np
import pytest

MODULE = "bl_ext.pdeface_test.pdeface"
AU27 = "AU27 Mouth Stretch"


def addon(name="bridge"):
    return __import__(MODULE + "." + name, fromlist=[name])


def evaluated(bpy, obj):
    return addon().vertices(obj.evaluated_get(bpy.context.evaluated_depsgraph_get()).data)


@pytest.fixture
def no_mouth_inside(bpy):
    """The development head whose lips open onto the inside of the head, as the user's mesh, its 68 landmarks as a
    vertex group."""
    from pdeface.mesh import Mesh

    from scripts.devset import makehuman
    from scripts.devset.characters import NO_MOUTH_INSIDE, build

    if not makehuman.available():
        pytest.skip("needs ../shared/data/makehuman")
    ch = build(NO_MOUTH_INSIDE)
    obj = bpy.data.objects.new("Game head", addon().new_mesh("Game head", Mesh.from_faces(ch.vertices, ch.triangles)))
    bpy.context.collection.objects.link(obj)
    g = obj.vertex_groups.new(name="landmarks")
    for i, p in enumerate(ch.landmarks):
        g.add([int(np.argmin(np.linalg.norm(ch.vertices - p, axis=1)))], (i + 1) / 68, "REPLACE")
    bpy.context.scene.pdeface.landmark_source = "GROUP"
    obj.select_set(True)
    bpy.context.view_layer.objects.active = obj
    bpy.context.view_layer.update()
    return obj


def test_add_mouth_bag_opens_with_the_jaw_and_leaves_the_head_as_it_was(bpy, no_mouth_inside):
    head = no_mouth_inside
    assert bpy.ops.pdeface.fit_to_selected() == {"FINISHED"}
    face = head.pdeface.rig_face
    assert any(w.startswith("no mouth inside") for w in addon("face").binding_warnings(face))  # reported as such
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
