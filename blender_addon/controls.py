"""One control per key on a head of several objects: the fitted mesh's key drives the others' of its name.

A head rigged from several objects (skin, eyes, teeth apart) carries the same keys on each of them
and on its hidden PDE face. The fitted mesh (the face's ``source``, the skin) holds the controls: its
AU, expression and pose keys are plain shape keys, so sliders, presets, keyframes, the live link and
exporters (glTF and FBX carry a mesh's own shape-key animation) work on them as on any key. Every
other object's key of the same name follows it through a driver (type ``AVERAGE`` of one variable:
no Python runs, and nothing is keyframed twice). A custom property per AU on a head root would need
a driver on the skin too, and its animation would live where exporters do not look.

A key that has a driver already keeps it unless the driver is ours (:data:`DRIVER_VAR`).
"""
import bpy

from .face import user_objects

#: The name of the one variable of our drivers: how a driver of ours is told from the user's.
DRIVER_VAR = "pdeface_control"


def _value_path(name):
    return f'key_blocks["{bpy.utils.escape_identifier(name)}"].value'


def _is_ours(fcurve, control_keys):
    variables = fcurve.driver.variables
    return len(variables) == 1 and variables[0].name == DRIVER_VAR and variables[0].targets[0].id == control_keys


def followers(face):
    """``(control, [followers])``: the fitted mesh and the face and other objects following its keys,
    or ``(None, [])`` when the face drives no objects of the user's."""
    users = [o for o in user_objects(face) if o.pdeface.keys]
    if not users or users[0] is not face.pdeface.source:
        return None, []
    return users[0], [face] + users[1:]


def link(face, names=None):
    """Drive the followers' keys (our keys named in ``names``, all of ours if None) by the control's.

    Marks the face ``linked`` (poses and keyframes then go to the control alone). Returns
    ``(linked, left alone)``: how many drivers were made, and how many keys kept a driver of the user's.
    """
    control, others = followers(face)
    if control is None:
        return 0, 0
    control_keys = control.data.shape_keys
    made = kept = 0
    for o in others:
        keys = o.data.shape_keys
        if keys is None:
            continue
        ours = [e.name for e in o.pdeface.keys if names is None or e.name in names]
        for name in ours:
            if name not in keys.key_blocks or name not in control_keys.key_blocks:
                continue
            path = _value_path(name)
            fc = keys.animation_data.drivers.find(path) if keys.animation_data else None
            if fc is not None:
                kept += not _is_ours(fc, control_keys)
                continue
            driver = keys.driver_add(path).driver
            driver.type = "AVERAGE"
            var = driver.variables.new()
            var.name, var.type = DRIVER_VAR, "SINGLE_PROP"
            var.targets[0].id_type = "KEY"
            var.targets[0].id = control_keys
            var.targets[0].data_path = path
            made += 1
    face.pdeface.linked = True
    return made, kept
