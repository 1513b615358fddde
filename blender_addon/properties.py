"""Properties: what a PDE face object carries, and the scene's PDE Face settings."""
import bpy
from bpy.props import (
    BoolProperty,
    CollectionProperty,
    EnumProperty,
    FloatProperty,
    FloatVectorProperty,
    IntProperty,
    PointerProperty,
    StringProperty,
)
from pdeface.animation.sequence import METHOD_SEQUENCE, MODES
from pdeface.errors import PdeFaceError
from pdeface.muscles.placement import MUSCLE_NAMES
from pdeface.presets import MIXERS
from pdeface.stream.player import MODES as PLAYBACK_MODES
from pdeface.units import UNITS_MM

from .face import active_face
from .keys import PRESET_MIXER
from .muscles import write_muscle_key

MIXER_ITEMS = [(PRESET_MIXER, "Preset", "Each preset's own mixer (sum unless it names another); AUs alone: sum")] + \
    [(m, m.capitalize(), text) for m, text in MIXERS.items()]
SEQUENCE_PATHS = {"via_neutral": ("Via neutral", "neutral → expression → neutral → next"),
                  "direct": ("Direct", "expression → expression")}
PLAYBACK = {"live": ("Live", "Head for the newest packet"), "queue": ("Queue", "Play every packet in turn (the FAS player)")}


class PDEFACE_PG_key(bpy.types.PropertyGroup):
    """A shape key this add-on made and keeps up to date."""

    # name: the shape key's name (PropertyGroup's own name)
    kind: EnumProperty(items=[("AU", "AU", ""), ("EXPRESSION", "Expression", ""), ("MIX", "Mix", "")])
    au_key: StringProperty(description="AU key, e.g. 12 or 12L")
    region: StringProperty(description="upper, lower or eyes_head")
    label: StringProperty()
    mark: StringProperty(description="Fingerprint of the coordinates we last wrote: a key whose coordinates "
                                     "no longer match is the user's")


class PDEFACE_PG_part(bpy.types.PropertyGroup):
    """One more object of the user's head (eyes, teeth as objects of their own)."""

    obj: PointerProperty(type=bpy.types.Object)


class PDEFACE_PG_face(bpy.types.PropertyGroup):
    """Per object: set on PDE faces, and on the user's objects they drive."""

    is_face: BoolProperty(default=False)
    model_data: StringProperty(description="The face model file (base64), so the .blend is self-contained")
    resolution: StringProperty(default="default")
    source: PointerProperty(type=bpy.types.Object, description="The scan this face was fitted to")
    parts: CollectionProperty(type=PDEFACE_PG_part, description="Other objects of the user's head it drives")
    head_keys: BoolProperty(default=False, description="Put the AU and expression keys on the user's objects too")
    rig_face: PointerProperty(type=bpy.types.Object, description="On a user's object: the PDE face driving it")
    linked: BoolProperty(default=False, description="On a face driving the user's objects: the fitted mesh's keys "
                                                    "are the controls, the face's and the other parts' follow them")
    keys: CollectionProperty(type=PDEFACE_PG_key)


_muscles_shown = {}  # face name → the activations its PDE Muscles key shows


#: How often (seconds) the muscle sliders are looked at.
MUSCLES_POLL_S = 0.1


def muscles_tick():
    """The muscle sliders pose the active face live, in a key of their own: a timer that looks at
    them, not the property's update callback (Blender 4.2 crashes at exit with that one, as with a
    poll callback, below; and setting a property does not always tag the depsgraph for a handler).
    A problem cannot be reported from here: it is shown in the panel instead."""
    scene = bpy.context.scene
    if scene is None:
        return MUSCLES_POLL_S
    settings = scene.pdeface
    obj = active_face(bpy.context)
    values = tuple(round(v, 6) for v in settings.muscles)
    if obj is None or _muscles_shown.get(obj.name, (0.0,) * len(MUSCLE_NAMES)) == values:
        return MUSCLES_POLL_S
    _muscles_shown[obj.name] = values
    try:
        note = write_muscle_key(obj, list(values))
    except PdeFaceError as exc:
        note = str(exc)
    if settings.muscle_note != note:
        settings.muscle_note = note
    return MUSCLES_POLL_S


class PDEFACE_PG_settings(bpy.types.PropertyGroup):
    """Per scene: the panel's settings."""

    mixer: EnumProperty(name="Mixer", items=MIXER_ITEMS, default=PRESET_MIXER)
    preset_mode: EnumProperty(
        name="Apply as", default="AUS",
        items=[("AUS", "AU weights", "Set the preset's AU keys (expression keys go to 0)"),
               ("KEY", "Expression key", "Set the preset's own key (its AU keys go to 0, no double counting)")])
    au_filter: StringProperty(name="Filter", description="Show AUs whose label contains this text",
                              options={"TEXTEDIT_UPDATE"})
    landmark_source: EnumProperty(
        name="Landmarks", default="AUTO",
        items=[("AUTO", "Automatic", "The mesh's landmark empties (Find Landmarks, nudged or not), else its "
                                     "vertex group 'landmarks', else found now (needs the landmark model)"),
               ("GROUP", "Vertex group", "68 vertices of a vertex group, ordered by weight ((i+1)/68)"),
               ("SELECTED", "Selected vertices", "68 vertices selected in Multi-PIE order"),
               ("FILE", "JSON file", "{\"indices\": [...]} or {\"points\": [...]}")])
    landmark_group: StringProperty(name="Group", default="landmarks")
    landmark_file: StringProperty(name="File", subtype="FILE_PATH")
    unit: EnumProperty(name="Unit", default="AUTO",
                       items=[("AUTO", "Estimate", "From the face's size (any scale)")] + [(u, u, "") for u in UNITS_MM]
                       + [("CUSTOM", "mm per unit", "A number of millimetres per unit (a head modelled 100 times its "
                                                    "size: 0.01)")])
    unit_mm: FloatProperty(name="mm per unit", default=1.0, min=1e-9, soft_min=1e-4, soft_max=1e4, precision=4,
                           description="Millimetres per unit of the mesh (Unit: mm per unit)")
    presets_file: StringProperty(name="User presets", subtype="FILE_PATH",
                                 description="JSON file of user presets (pdeface.preset / pdeface.presets)")
    sequence: StringProperty(name="Sequence", default=",".join(METHOD_SEQUENCE))
    sequence_hold: IntProperty(name="Hold", default=12, min=0)
    sequence_blend: IntProperty(name="Blend", default=12, min=1)
    sequence_mode: EnumProperty(name="Path", default="via_neutral",
                                items=[(m, *SEQUENCE_PATHS[m]) for m in MODES])
    sequence_channels: EnumProperty(name="Animate", default="KEY",
                                    items=[("KEY", "Expression keys", ""), ("AUS", "AU keys", "")])
    # No poll= filter here: a poll callback on this pointer crashes Blender 4.2 at exit (found by the
    # 4.2 test run); pdeface.transfer_texture checks the choice instead.
    texture_source: PointerProperty(type=bpy.types.Object, name="Scan")
    texture_method: EnumProperty(name="UVs", default="CLOSEST",
                                 items=[("CLOSEST", "From scan", "Closest point on the scan, as the method does"),
                                        ("ATLAS", "Fresh atlas", "Unwrap the PDE face with xatlas")])
    weight: FloatProperty(name="Weight", default=1.0, min=0.0, max=1.0)
    live_role: EnumProperty(name="Role", default="LISTEN",
                            items=[("LISTEN", "Listen", "Wait for a sender"), ("CONNECT", "Connect", "Connect to a sender")])
    live_host: StringProperty(name="Host", default="127.0.0.1")
    live_port: IntProperty(name="Port", default=5000, min=0, max=65535)
    live_allow_remote: BoolProperty(name="Allow remote", default=False,
                                    description="Listen on an address other than this machine's loopback")
    live_token: StringProperty(name="Token", default="", subtype="PASSWORD",
                               description="A shared secret: only senders that present it may end or stop the "
                                           "player or send JSON lines (empty: only you, from this machine)")
    live_mode: EnumProperty(name="Playback", default="live",
                            items=[(m, *PLAYBACK[m]) for m in PLAYBACK_MODES])
    live_rules: BoolProperty(name="AU blender rules", default=False, description="Apply the co-occurrence rules")
    live_record: BoolProperty(name="Record keyframes", default=False)
    live_hz: FloatProperty(name="Rate", default=60.0, min=1.0, max=60.0, description="Pose updates per second")
    muscles: FloatVectorProperty(name="Muscles", size=len(MUSCLE_NAMES), default=(0.0,) * len(MUSCLE_NAMES),
                                 min=-1.0, max=2.0,
                                 description="Contract (> 0) or relax (< 0) each muscle: the face follows live")
    muscle_au: StringProperty(name="AU", default="13", description="The AU to record the muscles as: 13, 13L, 46R")
    muscle_replace: BoolProperty(name="Replace", default=False,
                                 description="Record over an AU the face has already (its scan descriptor too)")
    muscle_note: StringProperty(description="Why the muscles cannot pose the face, or pose it with Waters' "
                                            "fields alone (shown in the panel)")


_classes = (PDEFACE_PG_key, PDEFACE_PG_part, PDEFACE_PG_face, PDEFACE_PG_settings)


def register():
    for c in _classes:
        bpy.utils.register_class(c)
    bpy.types.Object.pdeface = PointerProperty(type=PDEFACE_PG_face)
    bpy.types.Scene.pdeface = PointerProperty(type=PDEFACE_PG_settings)
    bpy.app.timers.register(muscles_tick, first_interval=MUSCLES_POLL_S, persistent=True)


def unregister():
    if bpy.app.timers.is_registered(muscles_tick):
        bpy.app.timers.unregister(muscles_tick)
    _muscles_shown.clear()
    del bpy.types.Scene.pdeface
    del bpy.types.Object.pdeface
    for c in reversed(_classes):
        bpy.utils.unregister_class(c)
