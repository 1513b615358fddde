"""The muscle panel: posing the face by muscle activations, and recording them as an AU.

The sliders (``scene.pdeface.muscles``, one per muscle of
:data:`pdeface.muscles.placement.MUSCLE_NAMES`) pose the face live in a key of
their own, :data:`MUSCLE_KEY`; an activation set can be stored as an AU of the
face's model (a descriptor of source ``muscle``) with its AU key, as the FAS let
users calibrate their own AUs, and loaded back onto the sliders.
"""
import numpy as np
from pdeface.au.descriptor import replace_descriptors
from pdeface.errors import PdeFaceError
from pdeface.facs import parse_au_key
from pdeface.muscles.aus import MuscleBasis, load_table, turns_jaw

from . import bridge
from .keys import au_key_name, change_targets, put_pose_key, set_pose, write_change_keys

#: The muscle panel's live pose.
MUSCLE_KEY = "PDE Muscles"


def write_muscle_key(obj, activations):
    """The face (and the user's objects it drives) posed by muscle activations, in the key
    :data:`MUSCLE_KEY` of its own, set to 1 and the other keys to 0: the muscle panel's live view.
    Returns a note for the panel: empty, or why the muscles' learned fields are not used."""
    if obj.data.shape_keys is None:
        raise PdeFaceError("build shape keys first")
    model = bridge.face_model(obj)
    basis = MuscleBasis(model)
    delta = basis.curves(np.asarray(activations, np.float64))
    targets = [(o, c) for o, c in change_targets(obj, model, delta, turns_jaw(activations))
               if o is obj or o.pdeface.keys]
    put_pose_key(targets, MUSCLE_KEY, "muscles")
    set_pose(obj, {MUSCLE_KEY: 1.0})
    return "" if basis.learned else "Waters' fields alone: the learned ones were made for another curve layout"


def muscle_activations(obj, key):
    """``(activations, where)`` of AU ``key``: recorded on the face (its muscle descriptor keeps them),
    else the bundled muscle table's."""
    key = parse_au_key(key)
    own = next((d for d in bridge.face_model(obj).descriptors if d.key == key and "activations" in d.extra), None)
    if own is not None:
        return [float(a) for a in own.extra["activations"]], "this face"
    table = load_table().activations
    if key not in table:
        raise PdeFaceError(f"AU{key} has no muscle activations (recorded or in the muscle table)")
    return [float(a) for a in table[key]], "the muscle table"


def record_muscle_au(obj, activations, key, replace=False):
    """Store muscle activations as AU ``key`` ("12", "12L"): a descriptor (source ``muscle``) in the
    face's model and its AU key on the face and the user's objects. An AU the face has already is
    replaced only when asked. Returns the descriptor."""
    key = parse_au_key(key)
    model = bridge.face_model(obj)
    old = next((d for d in model.descriptors if d.key == key), None)
    if old is not None and not replace:
        raise PdeFaceError(f"{obj.name} has AU{key} already ({old.kind}): tick Replace to record over it")
    d = MuscleBasis(model).descriptor(key, activations)
    d.extra["activations"] = [round(float(a), 4) for a in activations]
    model.descriptors = replace_descriptors(model.descriptors, [d])
    write_change_keys(obj, model, d.dense(), turns_jaw(activations), au_key_name(d), "AU", d.key, d.label)
    bridge.store_model(obj, model)
    return d
