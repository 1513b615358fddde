"""Our shape keys: the presets they are built from, building them, and posing the face with them.

One key per AU (kind ``AU``) and per preset or FDT (``EXPRESSION``) on the
face, and the same keys on the user's objects it drives (see :mod:`.head`; poses set
the fitted mesh's keys, the others follow them: :mod:`.controls`); a
pose the keys cannot add up to (the average and max mixers, the muscles) goes
into a key of its own (``MIX``) set to 1.

Keys this add-on made are listed on each object (``obj.pdeface.keys``) with a
fingerprint of what was written; the user's own keys, drivers and keyframes are
never deleted or renamed, and a key of ours the user changed becomes theirs.
"""
import bpy
import numpy as np
from pdeface.au.expressions import ShapeBasis
from pdeface.errors import PdeFaceError
from pdeface.facs import au_number, catalogue
from pdeface.fdt.deform import fdt_aus, fdt_curves
from pdeface.head.bind import JAW_AUS
from pdeface.posing import pose_curves
from pdeface.presets import PRESETS, choose_mixer, merged_presets, resolve_preset
from pdeface.surface.fit import face_mesh

from . import bridge, controls, head
from .face import face_resolution, pose_objects, user_objects

#: The key a mixed (not linear) pose is written into.
MIX_KEY = "PDE Mix"
#: The scene's mixer choice that defers to each preset's own mixer.
PRESET_MIXER = "PRESET"


# ------------------------------------------------------------------ presets

def all_presets(scene):
    """Built-in presets plus the scene's user preset file (if set; a broken file raises)."""
    path = bpy.path.abspath(scene.pdeface.presets_file) if scene else ""
    return merged_presets([path] if path else [])


_preset_items = []  # Blender needs the enum items kept alive


def preset_items(self, context):
    """Enum items of every preset (built-in ones only while the user's file is broken)."""
    _preset_items.clear()
    try:
        names = list(all_presets(context.scene if context else None))
    except Exception:  # a broken user file must not break the UI; the operators report it
        names = list(PRESETS)
    _preset_items.extend((n, n.replace("_", " "), "") for n in names)
    return _preset_items


def scene_mixer(settings):
    """The mixer the scene asks for, or None to defer to each preset's own."""
    return None if settings.mixer == PRESET_MIXER else settings.mixer


# ------------------------------------------------------------------ names and entries

def au_key_name(descriptor):
    """``AU12 Lip Corner Puller``, ``AU12L Lip Corner Puller``."""
    return f"AU{descriptor.key} {descriptor.name}"


def expression_key_name(preset_name):
    return f"Expr {preset_name}"


def fdt_key_name(fdt):
    """``FDT happy (3d)``."""
    return f"FDT {fdt.name} ({fdt.model})"


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


# ------------------------------------------------------------------ writing keys

def _is_ours(key_block, entry) -> bool:
    """Our key still: made by us and holding what we wrote (an entry from before marks counts as ours)."""
    return not entry.mark or entry.mark == bridge.fingerprint(bridge.key_coords(key_block))


def ours(obj) -> set:
    """Names of our keys on ``obj`` that still hold what we last wrote."""
    return {e.name for e, kb in managed(obj) if _is_ours(kb, e)}


def mark_ours(obj, names):
    """Our keys ``names`` on ``obj`` marked as holding what they hold now: after a change of the mesh's topology
    that changed no key's shape (a cut), they stay ours."""
    for e, kb in managed(obj):
        if e.name in names:
            e.mark = bridge.fingerprint(bridge.key_coords(kb))


def _write_key(key_block, entry, coords):
    coords = np.asarray(coords, np.float32)
    key_block.slider_min, key_block.slider_max = 0.0, 1.0
    bridge.set_key_coords(key_block, coords)
    entry.mark = bridge.fingerprint(coords)


class KeyWriter:
    """Writes our shape keys on one object: made or updated in place; a user's key of our name is left alone."""

    def __init__(self, obj):
        self.obj = obj
        if obj.data.shape_keys is None:
            obj.shape_key_add(name="Basis", from_mix=False)
        self.blocks = obj.data.shape_keys.key_blocks
        self.entries = {e.name: e for e in obj.pdeface.keys}
        self.catalogue = catalogue()
        self.counts = {"made": 0, "updated": 0, "skipped": 0}

    def put(self, name, coords, kind, au_key="", label=""):
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


def change_targets(obj, model, delta, jaw):
    """``[(object, coords)]``: the face and the user's objects it drives (bound as the head) under a
    change ``delta`` = (dC, dR) of the face's curves."""
    dC, dR = delta
    coords = face_mesh(model, face_resolution(obj), coefficients=model.coefficients + dC,
                       residual=model.residual + dR).vertices
    if len(coords) != len(obj.data.vertices):
        raise PdeFaceError(f"{obj.name} has {len(obj.data.vertices)} vertices, its model meshes to {len(coords)}: "
                           "the mesh was edited; add the face again")
    return [(obj, coords)] + head.change_coords(obj, model, dC, dR, jaw, user_objects(obj))


def write_change_keys(obj, model, delta, jaw, name, kind, au_key="", label=""):
    """One key, ``name``, for a change ``delta`` of the face's curves on the face and the user's objects
    (:func:`change_targets`). Returns the :class:`KeyWriter` counts."""
    targets = change_targets(obj, model, delta, jaw)
    counts = {"made": 0, "updated": 0, "skipped": 0, "objects": len(targets)}
    for o, c in targets:
        w = KeyWriter(o)
        w.put(name, c, kind, au_key, label)
        o.data.update()
        for k in w.counts:
            counts[k] += w.counts[k]
    if obj.pdeface.linked:
        controls.link(obj, {name})
    return counts


def add_fdt_key(obj, fdt):
    """One shape key of a Facial Deformation Table on the face and on the user's objects it drives.

    The table deforms the face model's curves (:func:`pdeface.fdt.deform.fdt_curves`), so the
    key is linear like the AU keys; kind EXPRESSION, so poses, sequences and resets treat it as
    one. Returns ``{"name", "made", "updated", "skipped", "objects"}``.
    """
    model = bridge.face_model(obj)
    jaw = bool(set(fdt_aus(fdt.name)) & set(JAW_AUS))
    name = fdt_key_name(fdt)
    counts = write_change_keys(obj, model, fdt_curves(model, fdt), jaw, name, "EXPRESSION",
                               label=f"FDT {fdt.name} ({fdt.model}, {fdt.subjects} subject(s))")
    return {"name": name, **counts}


def preset_poses(model, presets):
    """``[(preset name, label, weights, mixer)]`` of the presets this model has AUs for."""
    available = {d.key for d in model.descriptors}
    out = []
    for name, preset in presets.items():
        weights, _ = resolve_preset(preset, available)
        if weights:
            out.append((name, f"{name} ({preset.description})", weights, preset.mixer))
    return out


def build_keys(obj, presets):
    """Basis = neutral PDE face; one key per AU and per preset, updated in place when present.

    When the face drives the user's objects (:func:`.face.user_objects`), they get the
    same keys (see :mod:`.head`). A key of the user's with one of our names is
    left alone. Returns ``{"made", "updated", "skipped", "aus", "expressions", "objects", "notes", "warnings"}``
    (the head binding's notes, and those of them that ask the user to change something).
    """
    model = bridge.face_model(obj)
    if not model.descriptors:
        raise PdeFaceError(f"{obj.name}'s model carries no AU descriptors")
    basis = ShapeBasis(model, face_resolution(obj), dtype=np.float64)
    if len(basis.neutral) != len(obj.data.vertices):
        raise PdeFaceError(f"{obj.name} has {len(obj.data.vertices)} vertices, its model meshes to "
                           f"{len(basis.neutral)}: the mesh was edited; add the face again")
    poses = preset_poses(model, presets)
    expressions = []  # every input computed before anything is written
    for name, label, weights, mixer in poses:
        if mixer == "sum":
            coords = basis.vertices(basis.weights_matrix(weights))[0]
        else:
            C, R = pose_curves(model, weights, mixer)
            coords = face_mesh(model, face_resolution(obj), coefficients=C, residual=R).vertices
        expressions.append((name, label, coords))
    users = user_objects(obj)
    head_keys, binding = ([], None) if not users else head.head_keys(obj, model, poses, users, au_key_name,
                                                                     expression_key_name)

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
    if head_keys:
        controls.link(obj)  # one control per key: the fitted mesh's, the others follow it
    return {**counts, "aus": len(model.descriptors), "expressions": len(expressions), "objects": 1 + len(head_keys),
            "notes": list(binding.notes if binding else []), "warnings": list(binding.warnings if binding else [])}


# ------------------------------------------------------------------ posing

def set_pose(obj, values, kinds=("AU", "EXPRESSION", "MIX")):
    """Set our keys of ``kinds``: those named in ``values`` to their value, the others to 0.

    On the head's controls (:func:`.face.pose_objects`): the others follow them.
    """
    for o in pose_objects(obj):
        for e, kb in managed(o):
            if e.kind in kinds:
                kb.value = values.get(e.name, 0.0)


def put_pose_key(targets, name, label, check=True):
    """Write a pose into a key of its own (kind MIX) on each ``(object, coords)``; refused, before
    anything is written, where a key of that name is the user's."""
    for o, _ in targets:
        kb = o.data.shape_keys.key_blocks.get(name) if o.data.shape_keys else None
        entry = next((e for e in o.pdeface.keys if e.name == name), None)
        if kb is not None and (entry is None or (check and not _is_ours(kb, entry))):
            raise PdeFaceError(f"a shape key named {name!r} on {o.name} is yours; rename it to use this")
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
    face = targets[0][0]
    if face.pdeface.linked:
        controls.link(face, {name})


def write_mix_key(obj, model, weights, mixer, check=True):
    """Average and max are not linear: the mixed pose goes into one key of its own, set to 1.

    ``check=False`` skips reading the key back to see it is still ours (the live link checks once,
    at its start, not 60 times a second).
    """
    if obj.data.shape_keys is None:
        raise PdeFaceError("build shape keys first")
    C, R = pose_curves(model, weights, mixer)
    targets = [(obj, face_mesh(model, face_resolution(obj), coefficients=C, residual=R).vertices)]
    targets += [(o, coords) for o, coords in head.pose_coords(obj, model, weights, mixer, user_objects(obj))
                if o.pdeface.keys]
    put_pose_key(targets, MIX_KEY, "mixed pose", check)
    set_pose(obj, {MIX_KEY: 1.0})


def pose_aus(obj, weights, mixer="sum", check=True):
    """Pose the face with AU ``weights``: the AU keys for ``sum``, the mix key for the others.

    Returns the shape keys written.
    """
    if mixer == "sum":
        names = au_key_names(obj)
        set_pose(obj, {names[k]: w for k, w in weights.items() if k in names})
        return [kb for o in pose_objects(obj) for _, kb in managed(o, "AU")]
    write_mix_key(obj, bridge.face_model(obj), weights, mixer, check)
    return [kb for o in pose_objects(obj) for _, kb in managed(o, "MIX")]


def apply_preset(obj, name, preset, mode="AUS", weight=1.0, mixer=None):
    """Pose the face with a preset: as its AU weights (``AUS``) or as its own key (``KEY``).

    ``mixer`` None uses the preset's own. Returns (mixer used or None for
    ``KEY``, the preset's AUs this face has no descriptor for).
    """
    if mode == "KEY":
        key = expression_key_names(obj, [name]).get(name)
        if key is None:
            raise PdeFaceError(f"no {expression_key_name(name)!r} shape key: build shape keys first")
        set_pose(obj, {key: weight})  # AU keys to 0: the expression key already holds them
        return None, []
    model = bridge.face_model(obj)
    weights, missing = resolve_preset(preset, {d.key for d in model.descriptors})
    mixer = choose_mixer(mixer, preset)
    pose_aus(obj, {k: w * weight for k, w in weights.items()}, mixer)
    return mixer, missing
