"""The Blender side of a PDE face: its object, its shape keys, poses and keyframes.

Operators, the live link, the render script and tests all call these functions;
each reads Blender data, calls pdeface, writes back, and returns what it did
(operators turn that into reports). Errors are ``PdeFaceError``s naming the
problem, raised before anything is written.

Shape keys this add-on made are listed on the face (``obj.pdeface.keys``); the
user's own keys, drivers and keyframes are never deleted or renamed.
"""
import math

import bpy
import numpy as np

from . import bridge, compat

MIX_KEY = "PDE Mix"
#: The muscle panel's live pose.
MUSCLE_KEY = "PDE Muscles"
#: The scene's mixer choice that defers to each preset's own mixer.
PRESET_MIXER = "PRESET"


def _pd():
    """The pdeface modules used here (imported on first use: the fit pulls in scipy)."""
    import pdeface.assets
    import pdeface.au.expressions
    import pdeface.au.facs
    import pdeface.au.retarget
    import pdeface.fdt.deform
    import pdeface.head.bind
    import pdeface.io.modelfile
    import pdeface.muscles.aus
    import pdeface.surface.fit
    import pdeface.surface.frame
    import pdeface.surface.sampling
    return pdeface


def error(message):
    from pdeface.errors import PdeFaceError
    return PdeFaceError(message)


# ------------------------------------------------------------------ the face object and its keys

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
    """Whose keys the sliders show: the active user's object when it carries ours, else the active face."""
    obj = context.active_object
    face = active_face(context)
    return obj if face is not None and obj is not face and obj.pdeface.keys else face


def rig_objects(face):
    """The face and the user's objects carrying its keys: what poses and keyframes go to."""
    return [face] + [o for o in user_objects(face) if o.pdeface.keys]


def au_key_name(descriptor):
    """``AU12 Lip Corner Puller``, ``AU12L Lip Corner Puller``."""
    return f"AU{descriptor.key} {descriptor.name}"


def expression_key_name(preset_name):
    return f"Expr {preset_name}"


def managed(obj, kind=None):
    """(entry, key block) of our shape keys still present on the object (of ``kind`` AU/EXPRESSION/MIX)."""
    blocks = obj.data.shape_keys.key_blocks if obj.data.shape_keys else {}
    return [(e, blocks[e.name]) for e in obj.pdeface.keys if e.name in blocks and (kind is None or e.kind == kind)]


def au_key_names(obj):
    """``{AU key: shape key name}`` of the face's AU keys (``"12L"`` → ``"AU12L Lip Corner Puller"``)."""
    return {e.au_key: e.name for e, _ in managed(obj, "AU")}


def expression_key_names(obj, preset_names):
    """``{preset: shape key name}`` for the presets whose expression key the face has."""
    ours = {e.name for e, _ in managed(obj, "EXPRESSION")}
    return {p: expression_key_name(p) for p in preset_names if expression_key_name(p) in ours}


#: Faces made before the default resolution adapted to the face (issue #16) stored ``"default"`` for its
#: then 4 rows and columns per interval; their meshes keep them.
LEGACY_DEFAULT = "4,4"


def face_resolution(obj):
    """The steps ``obj``'s mesh was built with, as :func:`new_face_object` stored them: keys added later
    land on the same vertices though the model's default would now choose others."""
    return LEGACY_DEFAULT if obj.pdeface.resolution == "default" else obj.pdeface.resolution


def new_face_object(context, name, model, resolution, matrix=None, source=None, data=None):
    """A PDE face object for ``model`` (linked, selected and active); ``data``: the model file's bytes."""
    pd = _pd()
    steps = pd.surface.sampling.mesh_resolution(model, resolution)
    mesh = bridge.new_mesh(name, pd.surface.fit.face_mesh(model, steps))
    obj = bpy.data.objects.new(name, mesh)
    context.collection.objects.link(obj)
    if matrix is not None:
        obj.matrix_world = matrix
    obj.pdeface.is_face = True
    obj.pdeface.resolution = pd.surface.sampling.resolution_text(*steps)
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
    from pdeface.io.files import read_bytes

    pd = _pd()
    pd.surface.sampling.parse_resolution(resolution)
    path = bpy.path.abspath(model_path) if model_path else pd.assets.asset_path(pd.assets.DEFAULT_FACE)
    data = read_bytes(path)
    model = pd.io.modelfile.model_from_bytes(data, str(path))
    obj = new_face_object(context, "PDE Face", model, resolution, data=data)
    obj.rotation_euler = (math.pi / 2, 0.0, 0.0)  # the face frame's +y up becomes Blender's +Z up
    context.view_layer.update()  # matrix_world follows now, not after the next depsgraph update
    return obj


#: Colours of the demo head's parts (ICT-FaceKit part name prefix → material name, RGBA).
HEAD_MATERIALS = {"eyeball": ("PDE Sclera", (0.85, 0.83, 0.8, 1.0)), "teeth": ("PDE Teeth", (0.9, 0.86, 0.75, 1.0)),
                  "gums": ("PDE Mouth", (0.55, 0.2, 0.2, 1.0)), "mouth": ("PDE Mouth", (0.55, 0.2, 0.2, 1.0)),
                  "eyelashes": ("PDE Lashes", (0.05, 0.04, 0.03, 1.0)),
                  # ICT's shading helpers over the eyes (for Unreal's shaders): invisible here
                  "lacrimal": ("PDE Clear", (1.0, 1.0, 1.0, 0.0)), "eye_blend": ("PDE Clear", (1.0, 1.0, 1.0, 0.0)),
                  "eye_occlusion": ("PDE Clear", (1.0, 1.0, 1.0, 0.0))}


def add_ict_head(context, retarget=True):
    """ICT-FaceKit's whole generic head as the user's mesh, fitted and rigged: every key on it.

    Returns the head object (active); its PDE face is hidden as the reference.
    """
    pd = _pd()
    mesh, lm = pd.assets.load_head()
    obj = bpy.data.objects.new("ICT Head", bridge.new_mesh("ICT Head", mesh))
    context.collection.objects.link(obj)
    obj.rotation_euler = (math.pi / 2, 0.0, 0.0)  # ICT's +y up becomes Blender's +Z up
    obj["pdeface_notice"] = pd.assets.ICT_NOTICE
    obj.data.materials.append(bridge.skin_material())
    starts = np.array(list(pd.assets.HEAD_PARTS.values()))
    names = list(pd.assets.HEAD_PARTS)
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
    face_obj, model, _ = fit_face_object(context, obj, mesh.vertices[lm], unit="cm", retarget=retarget,
                                         keys_on_mesh=True)
    build_keys(face_obj, all_presets(context.scene))
    show_user_objects(context, face_obj)
    context.view_layer.update()
    return obj


def read_landmarks(settings, obj):
    """68 landmark positions (object space) from the scene's chosen source, and a note on where they came from.

    ``AUTO``: the mesh's landmark empties (found before, maybe nudged), else its
    vertex group of 68, else found now (and shown as empties).
    """
    pd = _pd()
    from pdeface.errors import LandmarkError

    from . import landmarks
    if settings.landmark_source == "AUTO":
        points = landmarks.empty_points(obj)
        if points is not None:
            return points, f"landmarks from the empties of {obj.name}"
        group = obj.vertex_groups.get(settings.landmark_group)
        if group is None:
            unit = None if settings.unit == "AUTO" else settings.unit
            points, found, seconds = landmarks.find(bpy.context, obj, unit)
            return points, landmarks.summary(obj, found, seconds)
    return _listed_landmarks(settings, obj, pd, LandmarkError), None


def _listed_landmarks(settings, obj, pd, LandmarkError):
    V = bridge.vertices(obj.data)
    if settings.landmark_source == "FILE":
        path = bpy.path.abspath(settings.landmark_file)
        if not path:
            raise LandmarkError("choose a landmarks JSON file")
        idx, pts = pd.surface.frame.read_landmarks(path)
        return pd.surface.frame.landmark_points(V, idx, pts)
    if settings.landmark_source in ("GROUP", "AUTO"):
        group = obj.vertex_groups.get(settings.landmark_group)
        if group is None:
            raise LandmarkError(f"{obj.name} has no vertex group {settings.landmark_group!r}")
        members = [(g.weight, v.index) for v in obj.data.vertices for g in v.groups if g.group == group.index]
        if len(members) != 68:
            raise LandmarkError(f"vertex group {group.name!r} has {len(members)} vertices; it needs the 68 landmarks")
        return V[[i for _, i in sorted(members)]]
    import bmesh
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
    head in ``parts`` (eyes, teeth ...): :func:`build_keys` puts its keys on
    them, the face is hidden as their reference and ``src`` stays active.
    A vertex group ``pdeface_skin`` on ``src`` names the skin to fit.
    ``progress(step, message)`` is called before each of the three steps.
    """
    pd = _pd()
    step = progress or (lambda i, msg: None)
    V = bridge.vertices(src.data)
    T, _ = bridge.triangles(src.data)
    if len(T) == 0:
        raise error(f"{src.name} has no faces")
    from .head import group_members
    skin, listed = None, group_members(src, "skin")
    if listed is not None:
        skin = np.zeros(len(V), bool)
        skin[listed] = True
    step(1, "fitting curves")
    model, sampler = pd.surface.fit.fit_face(V, T, landmarks, unit=unit, source=src.name, skin=skin)
    step(2, "retargeting AU descriptors")
    if retarget:
        model = pd.au.retarget.retarget(pd.assets.load_face(pd.assets.DEFAULT), model)
    step(3, "building the face")
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
    from . import head
    users = user_objects(face)
    return head.binding(face, bridge.face_model(face), users)[0].notes if users else []


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


# ------------------------------------------------------------------ presets

def all_presets(scene):
    """Built-in presets plus the scene's user preset file (if set; a broken file raises)."""
    pd = _pd()
    presets = dict(pd.au.expressions.PRESETS)
    path = bpy.path.abspath(scene.pdeface.presets_file) if scene else ""
    if path:
        presets.update({p.name: p for p in pd.au.expressions.load_presets(path)})
    return presets


_preset_items = []  # Blender needs the enum items kept alive


def preset_items(self, context):
    """Enum items of every preset (built-in ones only while the user's file is broken)."""
    _preset_items.clear()
    try:
        names = list(all_presets(context.scene if context else None))
    except Exception:  # a broken user file must not break the UI; the operators report it
        names = list(_pd().au.expressions.PRESETS)
    _preset_items.extend((n, n.replace("_", " "), "") for n in names)
    return _preset_items


def scene_mixer(settings):
    """The mixer the scene asks for, or None to defer to each preset's own."""
    return None if settings.mixer == PRESET_MIXER else settings.mixer


# ------------------------------------------------------------------ shape keys

def _is_ours(key_block, entry) -> bool:
    """Our key still: made by us and holding what we wrote (an entry from before marks counts as ours)."""
    return not entry.mark or entry.mark == bridge.fingerprint(bridge.key_coords(key_block))


def _write_key(key_block, entry, coords):
    coords = np.asarray(coords, np.float32)
    key_block.slider_min, key_block.slider_max = 0.0, 1.0
    bridge.set_key_coords(key_block, coords)
    entry.mark = bridge.fingerprint(coords)


class KeyWriter:
    """Writes our shape keys on one object: made or updated in place; a user's key of our name is left alone."""

    def __init__(self, obj):
        from pdeface.au.facs import catalogue

        self.obj = obj
        if obj.data.shape_keys is None:
            obj.shape_key_add(name="Basis", from_mix=False)
        self.blocks = obj.data.shape_keys.key_blocks
        self.entries = {e.name: e for e in obj.pdeface.keys}
        self.catalogue = catalogue()
        self.counts = {"made": 0, "updated": 0, "skipped": 0}

    def put(self, name, coords, kind, au_key="", label=""):
        from pdeface.au.facs import au_number

        blocks, entries = self.blocks, self.entries
        if name in blocks and (name not in entries or not _is_ours(blocks[name], entries[name])):
            self.counts["skipped"] += 1  # the user's own key of that name (perhaps made after deleting ours)
            return
        kb = blocks.get(name)
        if kb is None:
            kb = self.obj.shape_key_add(name=name, from_mix=False)
            kb.value = 0.0  # new keys start at 1 in Blender 5.0
            self.counts["made"] += 1
        else:
            self.counts["updated"] += 1
        e = entries.get(name)
        if e is None:
            e = self.obj.pdeface.keys.add()
            e.name = name
            entries[name] = e
        _write_key(kb, e, coords)
        e.kind, e.au_key, e.label = kind, au_key, label or name
        e.region = self.catalogue[au_number(au_key)].region if au_key else ""


def fdt_key_name(fdt):
    """``FDT happy (3d)``."""
    return f"FDT {fdt.name} ({fdt.model})"


def _change_targets(obj, model, delta, jaw):
    """``[(object, coords)]``: the face and the user's objects it drives (bound as the head) under a
    change ``delta`` = (dC, dR) of the face's curves."""
    pd = _pd()
    from . import head
    dC, dR = delta
    coords = pd.surface.fit.face_mesh(model, face_resolution(obj), coefficients=model.coefficients + dC,
                                      residual=model.residual + dR).vertices
    if len(coords) != len(obj.data.vertices):
        raise error(f"{obj.name} has {len(obj.data.vertices)} vertices, its model meshes to {len(coords)}: "
                    "the mesh was edited; add the face again")
    return [(obj, coords)] + head.change_coords(obj, model, dC, dR, jaw, user_objects(obj))


def _write_change_keys(obj, model, delta, jaw, name, kind, au_key="", label=""):
    """One key, ``name``, for a change ``delta`` of the face's curves on the face and the user's objects
    (:func:`_change_targets`). Returns the :class:`KeyWriter` counts."""
    targets = _change_targets(obj, model, delta, jaw)
    counts = {"made": 0, "updated": 0, "skipped": 0, "objects": len(targets)}
    for o, c in targets:
        w = KeyWriter(o)
        w.put(name, c, kind, au_key, label)
        o.data.update()
        for k in w.counts:
            counts[k] += w.counts[k]
    return counts


def add_fdt_key(obj, fdt):
    """One shape key of a Facial Deformation Table on the face and on the user's objects it drives.

    The table deforms the face model's curves (:func:`pdeface.fdt.deform.fdt_curves`), so the
    key is linear like the AU keys; kind EXPRESSION, so poses, sequences and resets treat it as
    one. Returns ``{"name", "made", "updated", "skipped", "objects"}``.
    """
    pd = _pd()
    model = bridge.face_model(obj)
    jaw = bool(set(pd.fdt.deform.fdt_aus(fdt.name)) & set(pd.head.bind.JAW_AUS))
    name = fdt_key_name(fdt)
    counts = _write_change_keys(obj, model, pd.fdt.deform.fdt_curves(model, fdt), jaw, name, "EXPRESSION",
                                label=f"FDT {fdt.name} ({fdt.model}, {fdt.subjects} subject(s))")
    return {"name": name, **counts}


def preset_poses(model, presets):
    """``[(preset name, label, weights, mixer)]`` of the presets this model has AUs for."""
    pd = _pd()
    available = {d.key for d in model.descriptors}
    out = []
    for name, preset in presets.items():
        weights, _ = pd.au.expressions.resolve_preset(preset, available)
        if weights:
            out.append((name, f"{name} ({preset.description})", weights, preset.mixer))
    return out


def build_keys(obj, presets):
    """Basis = neutral PDE face; one key per AU and per preset, updated in place when present.

    When the face drives the user's objects (:func:`user_objects`), they get the
    same keys (see :mod:`.head`). A key of the user's with one of our names is
    left alone. Returns ``{"made", "updated", "skipped", "aus", "expressions", "objects"}``.
    """
    pd = _pd()
    model = bridge.face_model(obj)
    if not model.descriptors:
        raise error(f"{obj.name}'s model carries no AU descriptors")
    basis = pd.au.expressions.ShapeBasis(model, face_resolution(obj), dtype=np.float64)
    if len(basis.neutral) != len(obj.data.vertices):
        raise error(f"{obj.name} has {len(obj.data.vertices)} vertices, its model meshes to {len(basis.neutral)}: "
                    "the mesh was edited; add the face again")
    poses = preset_poses(model, presets)
    expressions = []  # every input computed before anything is written
    for name, label, weights, mixer in poses:
        if mixer == "sum":
            coords = basis.vertices(basis.weights_matrix(weights))[0]
        else:
            C, R = pd.au.expressions.pose_curves(model, weights, mixer)
            coords = pd.surface.fit.face_mesh(model, face_resolution(obj), coefficients=C, residual=R).vertices
        expressions.append((name, label, coords))
    from . import head
    users = user_objects(obj)
    head_keys = head.head_keys(obj, model, poses, users, au_key_name, expression_key_name) if users else []

    writer = KeyWriter(obj)
    bridge.set_key_coords(obj.data.shape_keys.reference_key, basis.neutral)
    obj.data.vertices.foreach_set("co", basis.neutral.astype(np.float32).ravel())
    for i, d in enumerate(model.descriptors):
        writer.put(au_key_name(d), basis.neutral + basis.deltas[i].reshape(-1, 3), "AU", d.key, d.label)
    for name, label, coords in expressions:
        writer.put(expression_key_name(name), coords, "EXPRESSION", label=label)
    obj.data.update()
    counts = dict(writer.counts)
    for user, keys in head_keys:
        w = KeyWriter(user)
        for name, coords, kind, au_key, label in keys:
            w.put(name, coords, kind, au_key, label)
        user.data.update()
        for k in counts:
            counts[k] += w.counts[k]
    return {**counts, "aus": len(model.descriptors), "expressions": len(expressions), "objects": 1 + len(head_keys)}


def set_pose(obj, values, kinds=("AU", "EXPRESSION", "MIX")):
    """Set our keys of ``kinds``: those named in ``values`` to their value, the others to 0.

    On the face and on every user's object it drives (same key names).
    """
    for o in rig_objects(obj):
        for e, kb in managed(o):
            if e.kind in kinds:
                kb.value = values.get(e.name, 0.0)


def _put_pose_key(targets, name, label, check=True):
    """Write a pose into a key of its own (kind MIX) on each ``(object, coords)``; refused, before
    anything is written, where a key of that name is the user's."""
    for o, _ in targets:
        kb = o.data.shape_keys.key_blocks.get(name) if o.data.shape_keys else None
        entry = next((e for e in o.pdeface.keys if e.name == name), None)
        if kb is not None and (entry is None or (check and not _is_ours(kb, entry))):
            raise error(f"a shape key named {name!r} on {o.name} is yours; rename it to use this")
    for o, coords in targets:
        if o.data.shape_keys is None:
            o.shape_key_add(name="Basis", from_mix=False)
        kb = o.data.shape_keys.key_blocks.get(name)
        entry = next((e for e in o.pdeface.keys if e.name == name), None)
        if kb is None:
            kb = o.shape_key_add(name=name, from_mix=False)
            kb.value = 0.0
        if entry is None:
            entry = o.pdeface.keys.add()
            entry.name, entry.kind, entry.label = name, "MIX", label
        _write_key(kb, entry, coords)


def write_mix_key(obj, model, weights, mixer, check=True):
    """Average and max are not linear: the mixed pose goes into one key of its own, set to 1.

    ``check=False`` skips reading the key back to see it is still ours (the live link checks once,
    at its start, not 60 times a second).
    """
    pd = _pd()
    from . import head
    if obj.data.shape_keys is None:
        raise error("build shape keys first")
    C, R = pd.au.expressions.pose_curves(model, weights, mixer)
    targets = [(obj, pd.surface.fit.face_mesh(model, face_resolution(obj), coefficients=C, residual=R).vertices)]
    targets += [(o, coords) for o, coords in head.pose_coords(obj, model, weights, mixer, user_objects(obj))
                if o.pdeface.keys]
    _put_pose_key(targets, MIX_KEY, "mixed pose", check)
    set_pose(obj, {MIX_KEY: 1.0})


# ------------------------------------------------------------------ muscles

def write_muscle_key(obj, activations):
    """The face (and the user's objects it drives) posed by muscle activations, in the key
    :data:`MUSCLE_KEY` of its own, set to 1 and the other keys to 0: the muscle panel's live view.
    Returns a note for the panel: empty, or why the muscles' learned fields are not used."""
    aus = _pd().muscles.aus
    if obj.data.shape_keys is None:
        raise error("build shape keys first")
    model = bridge.face_model(obj)
    basis = aus.MuscleBasis(model)
    delta = basis.curves(np.asarray(activations, np.float64))
    targets = [(o, c) for o, c in _change_targets(obj, model, delta, aus.turns_jaw(activations))
               if o is obj or o.pdeface.keys]
    _put_pose_key(targets, MUSCLE_KEY, "muscles")
    set_pose(obj, {MUSCLE_KEY: 1.0})
    return "" if basis.learned else "Waters' fields alone: the learned ones were made for another curve layout"


def muscle_activations(obj, key):
    """``(activations, where)`` of AU ``key``: recorded on the face (its muscle descriptor keeps them),
    else the bundled muscle table's."""
    pd = _pd()
    key = pd.au.facs.parse_au_key(key)
    own = next((d for d in bridge.face_model(obj).descriptors if d.key == key and "activations" in d.extra), None)
    if own is not None:
        return [float(a) for a in own.extra["activations"]], "this face"
    table = pd.muscles.aus.load_table().activations
    if key not in table:
        raise error(f"AU{key} has no muscle activations (recorded or in the muscle table)")
    return [float(a) for a in table[key]], "the muscle table"


def record_muscle_au(obj, activations, key, replace=False):
    """Store muscle activations as AU ``key`` ("12", "12L"): a descriptor (source ``muscle``) in the
    face's model and its AU key on the face and the user's objects. An AU the face has already is
    replaced only when asked. Returns the descriptor."""
    pd = _pd()
    key = pd.au.facs.parse_au_key(key)
    model = bridge.face_model(obj)
    old = next((d for d in model.descriptors if d.key == key), None)
    if old is not None and not replace:
        raise error(f"{obj.name} has AU{key} already ({old.source or 'scan'}): tick Replace to record over it")
    d = pd.muscles.aus.MuscleBasis(model).descriptor(key, activations)
    d.extra["activations"] = [round(float(a), 4) for a in activations]
    model.descriptors = [x for x in model.descriptors if x.key != key] + [d]
    _write_change_keys(obj, model, d.dense(), pd.muscles.aus.turns_jaw(activations), au_key_name(d), "AU", d.key,
                       d.label)
    bridge.store_model(obj, model)
    return d


def pose_aus(obj, weights, mixer="sum", check=True):
    """Pose the face with AU ``weights``: the AU keys for ``sum``, the mix key for the others.

    Returns the shape keys written.
    """
    if mixer == "sum":
        names = au_key_names(obj)
        set_pose(obj, {names[k]: w for k, w in weights.items() if k in names})
        return [kb for o in rig_objects(obj) for _, kb in managed(o, "AU")]
    write_mix_key(obj, bridge.face_model(obj), weights, mixer, check)
    return [kb for o in rig_objects(obj) for _, kb in managed(o, "MIX")]


def apply_preset(obj, name, preset, mode="AUS", weight=1.0, mixer=None):
    """Pose the face with a preset: as its AU weights (``AUS``) or as its own key (``KEY``).

    ``mixer`` None uses the preset's own. Returns (mixer used or None for
    ``KEY``, the preset's AUs this face has no descriptor for).
    """
    pd = _pd()
    if mode == "KEY":
        key = expression_key_names(obj, [name]).get(name)
        if key is None:
            raise error(f"no {expression_key_name(name)!r} shape key: build shape keys first")
        set_pose(obj, {key: weight})  # AU keys to 0: the expression key already holds them
        return None, []
    model = bridge.face_model(obj)
    weights, missing = pd.au.expressions.resolve_preset(preset, {d.key for d in model.descriptors})
    mixer = pd.au.expressions.choose_mixer(mixer, preset)
    pose_aus(obj, {k: w * weight for k, w in weights.items()}, mixer)
    return mixer, missing


# ------------------------------------------------------------------ keyframes

def keyframe_pose(obj, frame):
    """Keyframe every PDE key (of the face and the user's objects it drives) at ``frame``; returns how many."""
    keys = [k for o in rig_objects(obj) for k in managed(o)]
    for _, kb in keys:
        kb.keyframe_insert("value", frame=frame)
    return len(keys)


def _extend_scene(scene, last_frame):
    if scene.frame_end < last_frame:
        scene.frame_end = last_frame


def animate_sequence(scene, obj, names, presets, start, hold, blend, mode="via_neutral", channels="KEY"):
    """Keyframe presets ``names`` in turn (their expression keys, or their AU keys for ``AUS``).

    Returns the last keyframed frame.
    """
    from pdeface.au.sequence import sequence_keys

    pd = _pd()
    unknown = [n for n in names if n not in presets]
    if unknown:
        raise error(f"unknown preset(s): {', '.join(unknown)}")
    if channels == "KEY":
        keys = expression_key_names(obj, names)
        lacking = [expression_key_name(n) for n in names if n not in keys]
        if lacking:
            raise error(f"no {lacking[0]!r} shape key: build shape keys first")
        poses = [{keys[n]: 1.0} for n in names]
    else:
        by_au = au_key_names(obj)
        poses = []
        for n in names:
            w, _ = pd.au.expressions.resolve_preset(presets[n], set(by_au))
            poses.append({by_au[k]: v for k, v in w.items()})
    frames = sequence_keys(poses, start, hold, blend, mode)
    for o in rig_objects(obj):
        blocks = o.data.shape_keys.key_blocks
        for frame, pose in frames:
            for name, value in pose.items():
                if name in blocks:
                    kb = blocks[name]
                    kb.value = value
                    kb.keyframe_insert("value", frame=frame)
    last = frames[-1][0]
    _extend_scene(scene, last)
    set_pose(obj, {})
    scene.frame_set(scene.frame_current)
    return last


def clear_keyframes(obj):
    """Delete the keyframes of our shape keys (the user's own keys keep theirs); returns how many curves.

    On the face and on the user's objects it drives.
    """
    count = 0
    for o in rig_objects(obj):
        fcurves = compat.fcurves_of(o.data.shape_keys)
        if fcurves is None:
            continue
        ours = {f'key_blocks["{bpy.utils.escape_identifier(e.name)}"].value' for e in o.pdeface.keys}
        doomed = [fc for fc in fcurves if fc.data_path in ours]
        for fc in doomed:
            fcurves.remove(fc)
        count += len(doomed)
    return count


def apply_timeline(obj, timeline, scene=None, merge=False):
    """Keyframe the face's shape keys from a pdeface Timeline.

    By default the timeline replaces the animation of our keys (the user's own
    keys keep theirs) and ``scene``'s frame range becomes the timeline's; with
    ``merge`` its keys go in among those already there and the range only grows.
    Returns (first frame, last frame, channels the face lacks).
    """
    by_au = au_key_names(obj)
    aus, presets = timeline.channels()
    by_preset = expression_key_names(obj, presets)
    missing = [f"AU{a}" for a in aus if a not in by_au] + [p for p in presets if p not in by_preset]
    names = [by_au[a] for a in aus if a in by_au] + [by_preset[p] for p in presets if p in by_preset]
    if not merge:
        clear_keyframes(obj)
    prefs = bpy.context.preferences.edit
    saved = prefs.keyframe_new_interpolation_type
    try:
        for key in timeline.keys:
            # New keys take the user-preference interpolation: the one way that works on 4.2-5.0.
            prefs.keyframe_new_interpolation_type = key.interpolation.upper()
            values = {by_au[a]: w for a, w in key.aus.items() if a in by_au}
            values.update({by_preset[p]: w for p, w in key.presets.items() if p in by_preset})
            for o in rig_objects(obj):
                blocks = o.data.shape_keys.key_blocks
                for name in names:
                    if name in blocks:
                        kb = blocks[name]
                        kb.value = values.get(name, 0.0)
                        kb.keyframe_insert("value", frame=key.frame)
    finally:
        prefs.keyframe_new_interpolation_type = saved
    first, last = timeline.keys[0].frame, timeline.frame_end
    if scene is not None and merge:
        _extend_scene(scene, last)
    elif scene is not None:
        scene.frame_start, scene.frame_end = first, last
    return first, last, missing


def read_au_file(path, fmt="auto", fps=30.0, hold=0.5, smooth=1, reduce=0.0, capture_fps=None):
    """A timeline from a tracker file or a timeline JSON: (timeline, rows dropped, unknown channels, notes)."""
    from pdeface.io.timeline import load_timeline
    from pdeface.io.trackers import import_au

    if fmt == "timeline" or (fmt == "auto" and path.lower().endswith(".json")):
        return load_timeline(path), 0, [], []
    r = import_au(path, fmt, fps, hold, smooth, reduce, capture_fps=capture_fps)
    return r.timeline, r.dropped, r.unknown, r.notes


def scene_fps(scene):
    return scene.render.fps / scene.render.fps_base

