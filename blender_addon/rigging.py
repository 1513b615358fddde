"""Rigging the user's head: a PDE face fitted to it and every key put on its objects; ICT's head as a demo.

Rigging spans two rooms (the face fitted in :mod:`.face`, the keys built in
:mod:`.keys`), so it sits above both.
"""
import math

import bpy
import numpy as np
from pdeface.assets import HEAD_PARTS, ICT_NOTICE, load_head

from . import bridge, compat
from .face import fit_face_object, show_user_objects
from .keys import all_presets, build_keys

#: Colours of the demo head's parts (ICT-FaceKit part name prefix → material name, RGBA).
HEAD_MATERIALS = {"eyeball": ("PDE Sclera", (0.85, 0.83, 0.8, 1.0)), "teeth": ("PDE Teeth", (0.9, 0.86, 0.75, 1.0)),
                  "gums": ("PDE Mouth", (0.55, 0.2, 0.2, 1.0)), "mouth": ("PDE Mouth", (0.55, 0.2, 0.2, 1.0)),
                  "eyelashes": ("PDE Lashes", (0.05, 0.04, 0.03, 1.0)),
                  # ICT's shading helpers over the eyes (for Unreal's shaders): invisible here
                  "lacrimal": ("PDE Clear", (1.0, 1.0, 1.0, 0.0)), "eye_blend": ("PDE Clear", (1.0, 1.0, 1.0, 0.0)),
                  "eye_occlusion": ("PDE Clear", (1.0, 1.0, 1.0, 0.0))}


def fit_and_rig(context, src, landmarks, unit=None, resolution="default", retarget=True, progress=None, parts=()):
    """Fit a PDE face to mesh object ``src`` and put every AU and expression key on it and on ``parts``.

    As :func:`.face.fit_face_object` with its keys on the user's mesh; then, when the
    model has AU descriptors (retargeted), :func:`.keys.build_keys` with the scene's
    presets, the face hidden as the reference and ``src`` active.
    ``progress(step, message)`` is called before each of the four steps.
    Returns (face object, model, sampler, the keys' counts or None without descriptors).
    """
    obj, model, sampler = fit_face_object(context, src, landmarks, unit, resolution, retarget, progress, parts,
                                          keys_on_mesh=True)
    if not model.descriptors:
        return obj, model, sampler, None
    if progress is not None:
        progress(4, "binding your mesh and building its shape keys")
    counts = build_keys(obj, all_presets(context.scene))
    show_user_objects(context, obj)
    return obj, model, sampler, counts


def add_head_mesh(context, name, mesh, landmarks, unit=None, y_up=True, retarget=True):
    """A head read from a file (a pdeface Mesh) as the user's mesh, fitted and rigged: every key on it.

    ``landmarks``: its 68 landmark positions; ``y_up``: the file's +Y is up (OBJ,
    glTF), turned to Blender's +Z as Blender's own importers do. Returns the head
    object (active); its PDE face is hidden as the reference.
    """
    obj = bpy.data.objects.new(name, bridge.new_mesh(name, mesh))
    context.collection.objects.link(obj)
    if y_up:
        obj.rotation_euler = (math.pi / 2, 0.0, 0.0)
    obj.data.materials.append(bridge.skin_material())
    context.view_layer.update()
    fit_and_rig(context, obj, landmarks, unit=unit, retarget=retarget)
    context.view_layer.update()
    return obj


def add_ict_head(context, retarget=True):
    """ICT-FaceKit's whole generic head as the user's mesh, fitted and rigged: every key on it.

    Returns the head object (active); its PDE face is hidden as the reference.
    """
    mesh, lm = load_head()
    obj = bpy.data.objects.new("ICT Head", bridge.new_mesh("ICT Head", mesh))
    context.collection.objects.link(obj)
    obj.rotation_euler = (math.pi / 2, 0.0, 0.0)  # ICT's +y up becomes Blender's +Z up
    obj["pdeface_notice"] = ICT_NOTICE
    obj.data.materials.append(bridge.skin_material())
    starts = np.array(list(HEAD_PARTS.values()))
    names = list(HEAD_PARTS)
    slots = {}
    for prefix, (mat_name, colour) in HEAD_MATERIALS.items():
        if mat_name not in slots:
            mat = bpy.data.materials.get(mat_name) or bpy.data.materials.new(mat_name)
            mat.diffuse_color = colour
            compat.use_nodes(mat)
            bsdf = mat.node_tree.nodes.get("Principled BSDF")
            if bsdf is not None:
                bsdf.inputs["Base Color"].default_value = colour
                bsdf.inputs["Alpha"].default_value = colour[3]
            obj.data.materials.append(mat)
            slots[mat_name] = len(obj.data.materials) - 1
    first = mesh.face_indices[np.r_[0, np.cumsum(mesh.face_counts)[:-1]]]
    part = np.array(names)[np.searchsorted(starts, first, side="right") - 1]
    index = np.zeros(len(first), np.int32)
    for prefix, (mat_name, _) in HEAD_MATERIALS.items():
        index[np.char.startswith(part.astype(str), prefix)] = slots[mat_name]
    obj.data.polygons.foreach_set("material_index", index)
    obj.data.polygons.foreach_set("use_smooth", np.ones(len(first), bool))
    context.view_layer.update()
    fit_and_rig(context, obj, mesh.vertices[lm], unit="cm", retarget=retarget)
    context.view_layer.update()
    return obj
