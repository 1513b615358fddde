"""The user's own head in Blender: AU and expression keys on their objects, driven by a PDE face.

A PDE face fitted to the user's mesh keeps it as its ``source``, and any other
selected objects of the head (eyes, teeth, lashes as objects of their own) as
``parts``; each of them points back with ``rig_face``. The face's model binds
all of them at once (:class:`pdeface.head.bind.HeadBinding`, in the source's
object space), and each object gets the same keys as the face, under the same
names; the fitted mesh's keys are the controls, the others follow them by drivers (:mod:`.controls`),
so every slider, preset, keyframe and the live link drive them all.

Vertex groups ``pdeface_skin``, ``pdeface_jaw``, ``pdeface_eye_L`` ... (one per
kind of :data:`pdeface.head.parts.KINDS`) override the automatic parts. The
user's basis, other keys, drivers, modifiers, UVs and materials are never
touched.
"""
import numpy as np
from pdeface.head.bind import HeadBinding
from pdeface.head.mouth import head_mouth_bag
from pdeface.head.parts import KINDS

from . import bridge

GROUP_PREFIX = "pdeface_"
_bindings = {}  # face name → (fingerprint, binding): reused by the mix key at 60 Hz


def rest_coords(obj) -> np.ndarray:
    """The object's rest shape (object space): its reference key if it has keys, else its mesh."""
    keys = obj.data.shape_keys
    if keys is not None:
        return bridge.key_coords(keys.reference_key).astype(np.float64)
    return bridge.vertices(obj.data)


def _to_space(src, obj) -> np.ndarray:
    """4×4 matrix from ``obj``'s object space to ``src``'s."""
    return np.array(src.matrix_world.inverted() @ obj.matrix_world)


def group_members(obj, kind):
    """Indices of the vertices in ``obj``'s vertex group ``pdeface_<kind>`` (weight > 0), or None without one."""
    g = obj.vertex_groups.get(GROUP_PREFIX + kind)
    if g is None:
        return None
    return [v.index for v in obj.data.vertices for e in v.groups if e.group == g.index and e.weight > 0]


def _overrides(objs, starts) -> dict:
    out = {}
    for obj, start in zip(objs, starts):
        for kind in KINDS:
            idx = group_members(obj, kind)
            if idx is not None:
                out.setdefault(kind, []).extend(start + i for i in idx)
    return out


def _joined(users):
    """``(V, T, per-object vertices, starts)``: ``users``' rest shapes joined in the first's object space."""
    src = users[0]
    parts_V, parts_T, starts = [], [], []
    n = 0
    for obj in users:
        M = _to_space(src, obj)
        rest = rest_coords(obj)
        V = rest @ M[:3, :3].T + M[:3, 3]
        T = bridge.polygon_triangles(obj.data, rest)
        parts_V.append(V)
        parts_T.append(T + n)
        starts.append(n)
        n += len(V)
    return np.concatenate(parts_V), np.concatenate(parts_T), parts_V, starts


def binding(face, model, users):
    """The head binding of ``users`` (cached while their shapes and the model stay the same)."""
    src = users[0]
    V, T, parts_V, starts = _joined(users)
    overrides = _overrides(users, starts)
    kinds = sorted(overrides)
    key = bridge.fingerprint(V, T, face.pdeface.model_data, ",".join(kinds), *(overrides[k] for k in kinds))
    layout = [(obj, start, len(pv), np.linalg.inv(_to_space(src, obj))[:3, :3]) for obj, start, pv in
              zip(users, starts, parts_V)]
    cached = _bindings.get(face.name)
    if cached is not None and cached[0] == key:
        return cached[1], layout
    b = HeadBinding(model, V, T, overrides=overrides or None)
    _bindings[face.name] = (key, b)
    return b, layout


def mouth_bag_of(face, model, users):
    """A mouth bag for the head of ``users`` (:func:`pdeface.head.mouth.head_mouth_bag`): ``(vertices in the fitted
    mesh's object space, triangles)``."""
    b, _ = binding(face, model, users)
    return head_mouth_bag(b, _joined(users)[1])


def _in_object_space(displacement, back):
    """A displacement in the source's space turned into an object's by its 3×3 ``back``: as it is where ``back`` is
    the identity (the fitted mesh itself; the product gives the same numbers, in ~20 ms more for a head's 82 keys)."""
    return displacement if np.array_equal(back, np.eye(3)) else displacement @ back.T


def _shares(layout, displacement, rests):
    """Per object: ``(object, its rest coordinates plus its share of displacement)`` (source space → object space),
    float64 as computed."""
    for (obj, s, n, back), rest in zip(layout, rests):
        yield obj, rest + _in_object_space(displacement[s:s + n], back)


def _split(layout, displacement):
    """:func:`_shares` as float32, as Blender keeps them (a whole head's 82 keys are held until written: half the
    memory)."""
    rests = [rest_coords(obj) for obj, *_ in layout]
    return [(obj, coords.astype(np.float32)) for obj, coords in _shares(layout, displacement, rests)]


def _split_into(layout, displacement, rests, held, key):
    """:func:`_shares` written into each object's block of keys ``held[object name][key]`` (the same float32 numbers:
    the float64 sum cast on assignment)."""
    for obj, coords in _shares(layout, displacement, rests):
        held[obj.name][key] = coords


#: Keys displaced per batch: a whole head's 82 keys in float64 at once, with the solve's temporaries, peaked
#: ~150 MB over the float32 keys themselves (issue #35: the ICT head's rig 779 → 626 MB in batches of 24, and
#: ~50 MB less in batches of 12, at the same CPU time within this machine's noise).
KEY_BATCH = 12


def head_keys(face, model, poses, users, au_name, expression_name):
    """Every AU and expression key of the user's objects, ``[(object, [(name, coords, kind, au_key, label)])]``,
    and the binding (its notes say what it decided: parts found, eyeballs missing ...).

    ``poses`` are ``(preset, label, weights, mixer)``; ``au_name(descriptor)`` and
    ``expression_name(preset)`` name the keys. Nothing is written here.
    """
    b, layout = binding(face, model, users)
    rests = [rest_coords(obj) for obj, *_ in layout]
    per_object = {obj.name: (obj, []) for obj, *_ in layout}
    keyed = b.bindable(model.descriptors)  # no gaze keys on a head without eyeballs (its notes say so)
    keys = [(au_name(d), "AU", d.key, d.label) for d in keyed]
    keys += [(expression_name(name), "EXPRESSION", "", label) for name, label, _, _ in poses]
    motions = b.motion_args([*keyed, *((weights, mixer) for _, _, weights, mixer in poses)])
    # Each object's keys in one block (82 keys of a 27k-vertex head: 26 MB): one allocation the system takes back
    # whole once written, before Blender evaluates its own copy of them (scattered key by key, they stayed resident in
    # the heap half of the time: the rig's peak 458 or 488 MB; issue #35)
    held = {obj.name: np.empty((len(keys), n, 3), np.float32) for obj, _, n, _ in layout}
    for start in range(0, len(motions), KEY_BATCH):  # a few batches: each one solve, float64 only while solved
        moved = b.displacements(motions[start:start + KEY_BATCH])
        for i, D in enumerate(moved, start):
            _split_into(layout, D, rests, held, i)
        del moved
    for obj_name, (_, out) in per_object.items():
        out.extend((name, coords, kind, au_key, label) for (name, kind, au_key, label), coords in
                   zip(keys, held[obj_name]))
    return list(per_object.values()), b


def change_coords(face, model, delta_coefficients, delta_residual, jaw, users):
    """``[(object, coordinates)]`` of the user's objects under a change of the face's curves (an FDT key)."""
    if not users:
        return []
    b, layout = binding(face, model, users)
    return _split(layout, b.displacement(delta_coefficients, delta_residual, jaw=jaw))


def pose_coords(face, model, weights, mixer, users):
    """``[(object, coordinates)]`` of the user's objects posed with AU ``weights`` (the mix key)."""
    if not users:
        return []
    b, layout = binding(face, model, users)
    return _split(layout, b.pose_displacement(weights, mixer))
