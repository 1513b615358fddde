"""A head in several objects (skin, gums, teeth, eyes apart): one control per key, and a small saved file."""
import numpy as np
import pytest

MODULE = "bl_ext.pdeface_test.pdeface"
AU27 = "AU27 Mouth Stretch"
#: ICT's head split as heads are usually exported (HEAD_PARTS prefixes per object).
OBJECTS = {"Skin": ("face", "head_and_neck", "mouth_socket", "eye_socket", "eyelashes"), "Gums": ("gums",),
           "Teeth": ("teeth",), "Eyes": ("eyeball", "lacrimal", "eye_blend", "eye_occlusion")}


def addon(name="bridge"):
    return __import__(MODULE + "." + name, fromlist=[name])


@pytest.fixture
def split_head(bpy):
    """ICT's head as four objects, the skin active with its landmarks as a vertex group."""
    from pdeface.assets import load_head, split_head

    mesh, lm = load_head()
    objs = {}
    for name, (m, used) in split_head(mesh, OBJECTS).items():
        obj = bpy.data.objects.new(name, addon().new_mesh(name, m))
        bpy.context.collection.objects.link(obj)
        obj.select_set(True)
        objs[name] = obj
    skin_idx = split_head(mesh, {"Skin": OBJECTS["Skin"]})["Skin"][1]
    g = objs["Skin"].vertex_groups.new(name="landmarks")
    for i, v in enumerate(np.searchsorted(skin_idx, lm)):
        g.add([int(v)], (i + 1) / 68, "REPLACE")
    bpy.context.scene.pdeface.landmark_source = "GROUP"
    bpy.context.view_layer.objects.active = objs["Skin"]
    bpy.context.view_layer.update()
    return objs


def evaluated(bpy, obj):
    dg = bpy.context.evaluated_depsgraph_get()
    return addon().vertices(obj.evaluated_get(dg).data)


def test_one_control_moves_every_part_and_the_file_stays_small(bpy, split_head, tmp_path):
    objs = split_head
    skin, teeth = objs["Skin"], objs["Teeth"]
    assert bpy.ops.pdeface.fit_to_selected() == {"FINISHED"}
    face = skin.pdeface.rig_face
    assert face.pdeface.linked and all(o.pdeface.rig_face == face for o in objs.values())
    rest = {n: evaluated(bpy, o) for n, o in objs.items()}
    # the slider: the skin's AU27 key alone is set, every part follows
    assert addon("face").key_owner(bpy.context) == skin
    skin.data.shape_keys.key_blocks[AU27].value = 1.0
    bpy.context.view_layer.update()
    moved = {n: np.linalg.norm(evaluated(bpy, o) - rest[n], axis=1).max() for n, o in objs.items()}
    assert moved["Skin"] > 2.0 and moved["Teeth"] > 1.0 and moved["Gums"] > 1.0  # cm: the jaw opens, teeth with it
    assert teeth.data.shape_keys.key_blocks[AU27].value == pytest.approx(1.0)
    # presets and keyframes set the one control; the parts follow by their drivers
    assert bpy.ops.pdeface.apply_preset(preset="happy", mode="KEY") == {"FINISHED"}
    assert bpy.ops.pdeface.keyframe_pose() == {"FINISHED"}
    fcurves = addon("compat").fcurves_of(skin.data.shape_keys)
    assert any("Expr happy" in fc.data_path for fc in fcurves)
    assert addon("compat").fcurves_of(teeth.data.shape_keys) is None
    bpy.context.scene.frame_set(1)
    assert teeth.data.shape_keys.key_blocks["Expr happy"].value == pytest.approx(1.0)
    assert teeth.data.shape_keys.key_blocks[AU27].value == 0.0
    # a rebuild keeps one driver per key, and the user's driver on a key of ours stays theirs
    mine = objs["Eyes"].data.shape_keys.driver_add('key_blocks["AU1 Inner Brow Raiser"].value').driver
    mine.expression = "0.25"
    assert bpy.ops.pdeface.build_shape_keys() == {"FINISHED"}
    drivers = objs["Eyes"].data.shape_keys.animation_data.drivers
    assert len({fc.data_path for fc in drivers}) == len(drivers)
    assert drivers.find('key_blocks["AU1 Inner Brow Raiser"].value').driver.expression == "0.25"
    # saved: the head's own keys (float32 xyz per vertex and key) and a small constant, not a dense hidden face
    path = tmp_path / "head.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(path), compress=False)
    n_keys = len(skin.data.shape_keys.key_blocks)
    own = sum(len(o.data.vertices) for o in objs.values()) * n_keys * 12
    size = path.stat().st_size
    print(f"saved {size / 1e6:.1f} MB, the head's keys {own / 1e6:.1f} MB")
    assert size <= 1.1 * own + 8e6


def test_a_head_is_the_selected_objects_or_its_collection(bpy):
    rigging = addon("rigging")
    head = bpy.data.collections.new("Head")
    bpy.context.scene.collection.children.link(head)
    objs = []
    for name in ("Skin", "Teeth", "Eyes"):
        bpy.ops.mesh.primitive_cube_add()
        obj = bpy.context.active_object
        obj.name = name
        for c in obj.users_collection:
            c.objects.unlink(obj)
        head.objects.link(obj)
        objs.append(obj)
    skin, teeth, eyes = objs
    for o in bpy.context.view_layer.objects:
        o.select_set(o is skin)
    assert set(rigging.head_parts(bpy.context, skin)) == {teeth, eyes}  # selected alone: its collection
    teeth.select_set(True)
    assert rigging.head_parts(bpy.context, skin) == [teeth]  # else what is selected
    other = bpy.data.collections.new("Props")
    bpy.context.scene.collection.children.link(other)
    other.objects.link(skin)  # in two collections: which is the head is not clear
    teeth.select_set(False)
    assert rigging.head_parts(bpy.context, skin) == []
