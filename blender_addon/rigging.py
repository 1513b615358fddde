"""Rigging the user's head: a PDE face fitted to it and every key put on its objects; ICT's head as a demo.

Rigging spans two rooms (the face fitted in :mod:`.face`, the keys built in
:mod:`.keys`), so it sits above both.
"""
import math
from itertools import pairwise

import bpy
import numpy as np
from mathutils import Vector
from pdeface.assets import HEAD_PARTS, ICT_NOTICE, load_head
from pdeface.errors import PdeFaceError
from pdeface.head.mouth import above_line, lip_cut

from . import bridge, compat, head
from .face import fit_face_object, read_landmarks, show_user_objects, user_objects
from .keys import all_presets, build_keys, mark_ours, ours

#: Colours of the demo head's parts (ICT-FaceKit part name prefix → material name, RGBA).
HEAD_MATERIALS = {"eyeball": ("PDE Eye", (0.85, 0.83, 0.8, 1.0)), "teeth": ("PDE Teeth", (0.9, 0.86, 0.75, 1.0)),
                  "gums": ("PDE Mouth", (0.55, 0.2, 0.2, 1.0)), "mouth": ("PDE Mouth", (0.55, 0.2, 0.2, 1.0)),
                  "eyelashes": ("PDE Lashes", (0.03, 0.02, 0.015, 1.0)),
                  # ICT's shading helpers over the eyes (for Unreal's shaders): invisible here
                  "lacrimal": ("PDE Clear", (1.0, 1.0, 1.0, 0.0)), "eye_blend": ("PDE Clear", (1.0, 1.0, 1.0, 0.0)),
                  "eye_occlusion": ("PDE Clear", (1.0, 1.0, 1.0, 0.0))}

#: The mouth bag's material (name, RGBA): the dark inside of an open mouth.
MOUTH_BAG_MATERIAL = ("PDE Mouth Bag", (0.06, 0.015, 0.015, 1.0))

#: The iris on ICT's eyeball UVs, which put the front of each eye at (0.5, 0.5): radius in UV units of
#: the pupil, the iris and the dark ring at its rim, and the iris colour. UVs travel with the vertices,
#: so the iris turns with the gaze keys.
IRIS = {"pupil": 0.035, "iris": 0.085, "rim": 0.01, "colour": (0.22, 0.33, 0.42, 1.0)}
#: ICT's lashes are cards drawn for an alpha texture it does not ship: thin dark strands across
#: their UV's u (this many per UV unit), the card between them clear.
LASH_STRANDS, LASH_COVER = 120.0, 0.12


def _node(tree, kind, **inputs):
    node = tree.nodes.new(kind)
    for name, value in inputs.items():
        if name == "operation":
            node.operation = value
        else:
            node.inputs[name].default_value = value
    return node


def _uv_part(tree, index):
    """The node output of UV coordinate ``index`` (0: u, 1: v)."""
    uv = tree.nodes.new("ShaderNodeTexCoord")
    xyz = tree.nodes.new("ShaderNodeSeparateXYZ")
    tree.links.new(uv.outputs["UV"], xyz.inputs[0])
    return xyz.outputs[index]


def shade_eye(mat, sclera):
    """Iris and pupil on the eyeball's UVs (:data:`IRIS`), around the front of each eye."""
    tree = mat.node_tree
    uv = tree.nodes.new("ShaderNodeTexCoord")
    dist = _node(tree, "ShaderNodeVectorMath", operation="DISTANCE")
    dist.inputs[1].default_value = (0.5, 0.5, 0.0)
    tree.links.new(uv.outputs["UV"], dist.inputs[0])
    ramp = tree.nodes.new("ShaderNodeValToRGB")
    scale = 2 * IRIS["iris"]  # the ramp spans 0 to twice the iris radius
    r, g, b, a = IRIS["colour"]
    stops = [(0.0, (0.01, 0.01, 0.01, 1)), (IRIS["pupil"] * 0.9, (0.01, 0.01, 0.01, 1)),
             (IRIS["pupil"] * 1.1, (r * 0.6, g * 0.6, b * 0.6, 1)), (IRIS["iris"] - IRIS["rim"], (r, g, b, a)),
             (IRIS["iris"], (r * 0.3, g * 0.3, b * 0.3, 1)), (IRIS["iris"] + 0.008, sclera)]
    elements = ramp.color_ramp.elements
    while len(elements) < len(stops):
        elements.new(0.5)
    for e, (pos, colour) in zip(elements, stops):
        e.position, e.color = pos / scale, colour
    scaled = _node(tree, "ShaderNodeMath", operation="DIVIDE")
    scaled.inputs[1].default_value = scale
    tree.links.new(dist.outputs["Value"], scaled.inputs[0])
    tree.links.new(scaled.outputs[0], ramp.inputs["Fac"])
    bsdf = tree.nodes["Principled BSDF"]
    tree.links.new(ramp.outputs["Color"], bsdf.inputs["Base Color"])
    bsdf.inputs["Roughness"].default_value = 0.15  # a wet eye: a highlight on the cornea


def shade_lashes(mat):
    """Thin strands (:data:`LASH_STRANDS`) across the lash cards' u; the rest of each card clear."""
    tree = mat.node_tree
    wave = _node(tree, "ShaderNodeMath", operation="MULTIPLY")
    wave.inputs[1].default_value = LASH_STRANDS
    tree.links.new(_uv_part(tree, 0), wave.inputs[0])
    frac = _node(tree, "ShaderNodeMath", operation="FRACT")
    tree.links.new(wave.outputs[0], frac.inputs[0])
    strand = _node(tree, "ShaderNodeMath", operation="LESS_THAN")
    strand.inputs[1].default_value = LASH_COVER
    tree.links.new(frac.outputs[0], strand.inputs[0])
    tree.links.new(strand.outputs[0], tree.nodes["Principled BSDF"].inputs["Alpha"])


def head_parts(context, src):
    """The other objects of ``src``'s head: the other selected meshes, else (``src`` selected alone) the
    other meshes of the collection it is in, when that is a collection of its own (not the scene's)."""
    def usable(o):
        return o is not src and o.type == "MESH" and not o.pdeface.is_face
    selected = [o for o in context.view_layer.objects.selected if usable(o)]
    if selected:
        return selected
    own = [c for c in src.users_collection if c is not context.scene.collection]
    return [o for o in own[0].objects if usable(o)] if len(own) == 1 else []


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


def plain_material(name, colour):
    """The material ``name``, made once of one ``colour`` (RGBA): an existing one (maybe the user's edit) is kept as
    it is."""
    mat = bpy.data.materials.get(name)
    if mat is None:
        mat = bpy.data.materials.new(name)
        mat.diffuse_color = colour
        compat.use_nodes(mat)
        bsdf = mat.node_tree.nodes.get("Principled BSDF")
        if bsdf is not None:
            bsdf.inputs["Base Color"].default_value = colour
            bsdf.inputs["Alpha"].default_value = colour[3]
    return mat


def add_mouth_bag(context, face):
    """A mouth bag behind the lips of the head ``face`` drives (:mod:`pdeface.head.mouth`), as an object of its own
    beside the user's: dark, parented to the fitted mesh, a part of the head in vertex group ``pdeface_mouth`` (the
    jaw keys open it with the lips); every key of the head is then built again, the bag's with them. The user's
    objects are not changed but for their keys. Returns (the bag object, the keys' counts)."""
    users = user_objects(face)
    if not users:
        raise PdeFaceError(f"{face.name} drives no mesh of yours: fit it with Keys on my mesh first")
    had = [o.name for o in users if head.group_members(o, "mouth") is not None]
    if had:
        raise PdeFaceError(f"{had[0]} is already this head's mouth bag (vertex group {head.GROUP_PREFIX}mouth)")
    src = users[0]
    vertices, triangles = head.mouth_bag_of(face, bridge.face_model(face), users)
    name = f"{src.name} mouth bag"
    me = bpy.data.meshes.new(name)
    me.from_pydata(vertices.tolist(), [], triangles.tolist())
    me.polygons.foreach_set("use_smooth", np.ones(len(triangles), bool))
    me.update()
    me.materials.append(plain_material(*MOUTH_BAG_MATERIAL))
    bag = bpy.data.objects.new(name, me)
    for collection in src.users_collection:
        collection.objects.link(bag)
    bag.parent = src  # in the fitted mesh's space, moving with it
    bag.vertex_groups.new(name=head.GROUP_PREFIX + "mouth").add(list(range(len(vertices))), 1.0, "REPLACE")
    face.pdeface.parts.add().obj = bag
    bag.pdeface.rig_face = face
    counts = build_keys(face, all_presets(context.scene))
    return bag, counts


def cut_lips_open(context, face):
    """Cut the fused lips of the mesh ``face`` was fitted to open along the line between them
    (:func:`pdeface.head.mouth.lip_cut`: its edges split, the upper side lifted a little), then fit and rig it again
    with the inner lips' landmarks on either side of the cut; the old face is removed. A change of the user's
    topology, made only by this operator: their keys, UVs and materials carry over (our keys are built again).
    Returns (the new face, the number of vertices the cut added)."""
    import bmesh

    users = user_objects(face)
    src = face.pdeface.source
    if not users or users[0] is not src:
        raise PdeFaceError(f"{face.name} drives no mesh of yours: fit it with Keys on my mesh first")
    model = bridge.face_model(face)
    if not any(w.startswith("the lips are joined") for w in head.binding(face, model, users)[0].warnings):
        raise PdeFaceError(f"{src.name}'s lips are not joined in the mesh: nothing to cut")
    points, _ = read_landmarks(context.scene.pdeface, src)
    me = src.data
    V = head.rest_coords(src)
    E = np.empty(2 * len(me.edges), np.int32)
    me.edges.foreach_get("vertices", E)
    path, lifted, points = lip_cut(V, E.reshape(-1, 2), points, model.frame)
    kept = ours(src)
    bm = bmesh.new()
    try:
        bm.from_mesh(me)
        bm.verts.ensure_lookup_table()
        bmesh.ops.split_edges(bm, edges=[bm.edges.get((bm.verts[a], bm.verts[b])) for a, b in pairwise(path)])
        bm.verts.ensure_lookup_table()
        co = np.array([v.co for v in bm.verts])
        Vf = model.frame.to_face(V)
        size = float(np.ptp(V, axis=0).max())
        for i, target in zip(path[1:-1], lifted):
            for v in (bm.verts[j] for j in np.nonzero(np.linalg.norm(co - V[i], axis=1) < 1e-7 * size)[0]):
                centre = model.frame.to_face(np.array([list(f.calc_center_median()) for f in v.link_faces]))
                if len(centre) and above_line(Vf, path, centre).mean() > 0.5:  # the upper lip's copy: lifted
                    step = target - V[i]
                    v.co = v.co + Vector(step)
                    for layer in bm.verts.layers.shape.values():
                        v[layer] = v[layer] + Vector(step)
        bm.to_mesh(me)
    finally:
        bm.free()
    me.update()
    mark_ours(src, kept)
    added = len(me.vertices) - len(V)
    unit = model.frame.scale  # the unit the face was fitted in (its millimetres per unit), whatever the scene says now
    name = face.name
    new, _, _, _ = fit_and_rig(context, src, points, unit=unit, parts=users[1:])
    old_mesh = face.data
    bpy.data.objects.remove(face)
    if old_mesh.users == 0:
        bpy.data.meshes.remove(old_mesh)
    new.name = name
    return new, added


def _head_object(context, name, mesh, y_up=True):
    """A new object of ``mesh`` in the scene with the skin material; a +Y-up file turned to Blender's +Z up,
    as Blender's own importers do."""
    obj = bpy.data.objects.new(name, bridge.new_mesh(name, mesh))
    context.collection.objects.link(obj)
    if y_up:
        obj.rotation_euler = (math.pi / 2, 0.0, 0.0)
    obj.data.materials.append(bridge.skin_material())
    return obj


def add_head_mesh(context, name, mesh, landmarks, unit=None, y_up=True, retarget=True):
    """A head read from a file (a pdeface Mesh) as the user's mesh, fitted and rigged: every key on it.

    ``landmarks``: its 68 landmark positions; ``y_up``: the file's +Y is up (OBJ,
    glTF), turned to Blender's +Z as Blender's own importers do. Returns the head
    object (active); its PDE face is hidden as the reference.
    """
    obj = _head_object(context, name, mesh, y_up)
    context.view_layer.update()
    fit_and_rig(context, obj, landmarks, unit=unit, retarget=retarget)
    context.view_layer.update()
    return obj


def add_ict_head(context, retarget=True):
    """ICT-FaceKit's whole generic head as the user's mesh, fitted and rigged: every key on it.

    Returns the head object (active); its PDE face is hidden as the reference.
    """
    mesh, lm = load_head()
    obj = _head_object(context, "ICT Head", mesh)  # ICT's +y up becomes Blender's +Z up
    obj["pdeface_notice"] = ICT_NOTICE
    starts = np.array(list(HEAD_PARTS.values()))
    names = list(HEAD_PARTS)
    slots = {}
    for prefix, (mat_name, colour) in HEAD_MATERIALS.items():
        if mat_name not in slots:
            made = bpy.data.materials.get(mat_name) is None
            mat = plain_material(mat_name, colour)
            if made and prefix == "eyeball":
                shade_eye(mat, colour)
            elif made and prefix == "eyelashes":
                shade_lashes(mat)
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
