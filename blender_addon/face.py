"""The PDE face object: which one is active, the user's objects it drives, making it and fitting it.

A PDE face is a mesh object carrying its face model (``obj.pdeface``). Fitted
to the user's mesh with *keys on my mesh*, it drives that mesh (its
``source``) and the other objects of the head (``parts``): each points back
with ``rig_face``, and the face itself is hidden as their reference.

Each function reads Blender data, calls pdeface, writes back and returns what
it did; errors are ``PdeFaceError``s raised before anything is written. The
shape keys live in :mod:`.keys`, above this module.
"""
import math

import bmesh
import bpy
import numpy as np
from pdeface.assets import DEFAULT, DEFAULT_FACE, asset_path
from pdeface.au.modelfile import load_face, model_from_bytes
from pdeface.au.retarget import retarget as retarget_descriptors
from pdeface.errors import LandmarkError, PdeFaceError
from pdeface.io.files import read_bytes
from pdeface.surface.fit import face_mesh, fit_face
from pdeface.surface.frame import landmark_points
from pdeface.surface.frame import read_landmarks as read_landmark_file
from pdeface.surface.sampling import mesh_resolution, parse_resolution, resolution_text

from . import bridge, head, landmarks

#: The hidden reference face of a rigged head is meshed this coarsely (steps per interval) unless the user
#: asks for a resolution: nobody sees it, the head's keys come from the model (its binding samples the
#: surface itself), and at the adaptive resolution its mesh and keys made up most of a saved .blend
#: (57–235 k vertices × 83 keys: 49–223 MB, issue #40).
REFERENCE_RESOLUTION = "1,1"
#: Faces made before the default resolution adapted to the face (issue #16) stored ``"default"`` for its
#: then 4 rows and columns per interval; their meshes keep them.
LEGACY_DEFAULT = "4,4"


# ------------------------------------------------------------------ which objects

def active_face(context):
    """The active PDE face: the active object, or the face driving the active user's object; else None."""
    obj = context.active_object
    if obj is None or obj.type != "MESH":
        return None
    if obj.pdeface.is_face:
        return obj
    rig = obj.pdeface.rig_face
    return rig if rig is not None and rig.pdeface.is_face else None


def user_objects(face):
    """The user's objects this face drives (the fitted mesh first, then the other parts), if it drives them."""
    if not face.pdeface.head_keys:
        return []
    objs = [face.pdeface.source] + [p.obj for p in face.pdeface.parts]
    return [o for o in objs if o is not None and o.type == "MESH" and o.pdeface.rig_face == face]


def key_owner(context):
    """Whose keys the sliders show: the head's controls (:func:`pose_objects`) when the rest follows them,
    else the active user's object when it carries ours, else the active face."""
    obj = context.active_object
    face = active_face(context)
    if face is not None and face.pdeface.linked:
        return pose_objects(face)[0]
    return obj if face is not None and obj is not face and obj.pdeface.keys else face


def rig_objects(face):
    """The face and the user's objects carrying its keys."""
    return [face] + [o for o in user_objects(face) if o.pdeface.keys]


def pose_objects(face):
    """What poses, sliders and keyframes set: the fitted mesh alone when the face and the head's other
    objects follow its keys by drivers (:mod:`.controls`), else every object of :func:`rig_objects`
    (a face saved before the drivers, until its keys are rebuilt)."""
    users = user_objects(face)
    if face.pdeface.linked and users and users[0].pdeface.keys and users[0] is face.pdeface.source:
        return users[:1]
    return rig_objects(face)


def face_resolution(obj):
    """The steps ``obj``'s mesh was built with, as :func:`new_face_object` stored them: keys added later
    land on the same vertices though the model's default would now choose others."""
    return LEGACY_DEFAULT if obj.pdeface.resolution == "default" else obj.pdeface.resolution


# ------------------------------------------------------------------ making a face

def new_face_object(context, name, model, resolution, matrix=None, source=None, data=None):
    """A PDE face object for ``model`` (linked, selected and active); ``data``: the model file's bytes."""
    steps = mesh_resolution(model, resolution)
    mesh = bridge.new_mesh(name, face_mesh(model, steps))
    obj = bpy.data.objects.new(name, mesh)
    context.collection.objects.link(obj)
    if matrix is not None:
        obj.matrix_world = matrix
    obj.pdeface.is_face = True
    obj.pdeface.resolution = resolution_text(*steps)
    obj.pdeface.source = source
    bridge.store_model(obj, model, data)
    mesh.materials.append(bridge.skin_material())
    for o in context.view_layer.objects:
        o.select_set(False)
    obj.select_set(True)
    context.view_layer.objects.active = obj
    return obj


def add_face(context, model_path="", resolution="default"):
    """The bundled face (or the model file at ``model_path``) as a new PDE face object, +Z up."""
    parse_resolution(resolution)
    path = bpy.path.abspath(model_path) if model_path else asset_path(DEFAULT_FACE)
    data = read_bytes(path)
    model = model_from_bytes(data, str(path))
    obj = new_face_object(context, "PDE Face", model, resolution, data=data)
    obj.rotation_euler = (math.pi / 2, 0.0, 0.0)  # the face frame's +y up becomes Blender's +Z up
    context.view_layer.update()  # matrix_world follows now, not after the next depsgraph update
    return obj


# ------------------------------------------------------------------ fitting a face to the user's mesh

def read_landmarks(settings, obj):
    """68 landmark positions (object space) from the scene's chosen source, and a note on where they came from.

    ``AUTO``: the mesh's landmark empties (found before, maybe nudged), else its
    vertex group of 68, else found now (and shown as empties).
    """
    if settings.landmark_source == "AUTO":
        points = landmarks.empty_points(obj)
        if points is not None:
            return points, f"landmarks from the empties of {obj.name}"
        group = obj.vertex_groups.get(settings.landmark_group)
        if group is None:
            points, found, seconds = landmarks.find(bpy.context, obj, chosen_unit(settings))
            return points, landmarks.summary(obj, found, seconds)
    return _listed_landmarks(settings, obj), None


def check_landmarks(settings, obj, points, unit=None, accept=False):
    """The gate's word on the landmarks :func:`read_landmarks` gave, before the fit, as the CLI's: the whole gate on
    the mesh's empties (found or edited), its look at the mesh alone (eyes open) on landmarks the user listed.
    Returns a note on a failure ``accept`` lets by; raises :class:`~pdeface.landmarks.gate.LandmarkGateError`."""
    origin = landmark_origin(settings, obj)  # (after read_landmarks: a find made the empties)
    if origin == landmarks.EMPTIES:
        return landmarks.gated(obj, points, unit, accept)
    return landmarks.at_rest(obj, points, origin, unit, accept)


def landmark_origin(settings, obj):
    """Where the next Fit on ``obj`` reads its landmarks from, in words (as :func:`read_landmarks` chooses, after a
    find): :data:`.landmarks.EMPTIES`, the vertex group, the JSON file or the selected vertices. A gate verdict
    keeps it, and the panel shows the verdict only while it is the same."""
    source = settings.landmark_source
    if source == "AUTO":
        if landmarks.empties(obj) is not None or obj.vertex_groups.get(settings.landmark_group) is None:
            return landmarks.EMPTIES
        source = "GROUP"
    if source == "GROUP":
        return f"vertex group {settings.landmark_group!r}"
    if source == "FILE":
        return f"file {settings.landmark_file!r}"
    return "the selected vertices"


def chosen_unit(settings):
    """The unit the settings name: None (estimated from the face's size), a unit's name, or millimetres per unit
    (Blender keeps the number in float32: 0.01 typed is 0.009999999776; read to 7 significant digits, as typed but
    for the last digit of a few 7-digit numbers)."""
    if settings.unit == "AUTO":
        return None
    return float(f"{settings.unit_mm:.7g}") if settings.unit == "CUSTOM" else settings.unit


def _listed_landmarks(settings, obj):
    """The 68 landmarks the user listed: in a JSON file, a vertex group ordered by weight, or selected in order."""
    V = bridge.vertices(obj.data)
    if settings.landmark_source == "FILE":
        path = bpy.path.abspath(settings.landmark_file)
        if not path:
            raise LandmarkError("choose a landmarks JSON file")
        idx, pts = read_landmark_file(path)
        return landmark_points(V, idx, pts)
    if settings.landmark_source in ("GROUP", "AUTO"):
        group = obj.vertex_groups.get(settings.landmark_group)
        if group is None:
            raise LandmarkError(f"{obj.name} has no vertex group {settings.landmark_group!r}")
        members = [(g.weight, v.index) for v in obj.data.vertices for g in v.groups if g.group == group.index]
        if len(members) != 68:
            raise LandmarkError(f"vertex group {group.name!r} has {len(members)} vertices; it needs the 68 landmarks")
        return V[[i for _, i in sorted(members)]]
    bm = bmesh.new()
    try:
        bm.from_mesh(obj.data)
        hist = [e.index for e in bm.select_history if isinstance(e, bmesh.types.BMVert)]
    finally:
        bm.free()
    if len(hist) != 68:
        raise LandmarkError(f"{len(hist)} vertices selected in order; select the 68 landmarks one by one in Edit Mode")
    return V[hist]


def fit_face_object(context, src, landmarks, unit=None, resolution="default", retarget=True, progress=None,
                    parts=(), keys_on_mesh=False):
    """Fit a PDE face to mesh object ``src`` and put it on it; returns (face object, model, sampler).

    ``keys_on_mesh``: the face will drive ``src`` and the other objects of the
    head in ``parts`` (eyes, teeth ...): :func:`.keys.build_keys` puts its keys
    on them, the face is hidden as their reference and ``src`` stays active.
    A vertex group ``pdeface_skin`` on ``src`` names the skin to fit.
    ``progress(step, message)`` is called before each of the three steps.
    """
    step = progress or (lambda i, msg: None)
    V = bridge.vertices(src.data)
    T, _ = bridge.triangles(src.data, loops=False)
    if len(T) == 0:
        raise PdeFaceError(f"{src.name} has no faces")
    skin, listed = None, head.group_members(src, "skin")
    if listed is not None:
        skin = np.zeros(len(V), bool)
        skin[listed] = True
    step(1, "fitting curves")
    model, sampler = fit_face(V, T, landmarks, unit=unit, source=src.name, skin=skin)
    step(2, "retargeting AU descriptors")
    if retarget:
        model = retarget_descriptors(load_face(DEFAULT), model)
    step(3, "building the face")
    if keys_on_mesh and resolution == "default":
        resolution = REFERENCE_RESOLUTION
    obj = new_face_object(context, f"PDE {src.name}", model, resolution, src.matrix_world.copy(), src)
    if keys_on_mesh:
        obj.pdeface.head_keys = True
        src.pdeface.rig_face = obj
        for p in parts:
            if p is not src and p.type == "MESH" and not p.pdeface.is_face:
                obj.pdeface.parts.add().obj = p
                p.pdeface.rig_face = obj
    return obj, model, sampler


def binding_notes(face):
    """What binding the user's objects decided (parts found, eyeballs missing ...), for the report."""
    users = user_objects(face)
    return head.binding(face, bridge.face_model(face), users)[0].notes if users else []


def binding_warnings(face):
    """The notes of :func:`binding_notes` that ask the user to change something (lips joined, no mouth inside)."""
    users = user_objects(face)
    return head.binding(face, bridge.face_model(face), users)[0].warnings if users else []


def show_user_objects(context, face):
    """Hide the PDE face (the reference) and make the user's mesh active and selected."""
    users = user_objects(face)
    if not users:
        return
    face.hide_set(True)
    face.hide_render = True
    for o in context.view_layer.objects:
        o.select_set(o in users)
    context.view_layer.objects.active = users[0]
