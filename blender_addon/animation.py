"""Keyframes on our shape keys: a pose, a sequence of presets, a timeline or tracker file.

Keyframes go on the head's controls (:func:`.face.pose_objects`: the fitted mesh,
whose keys the face's and the other objects' follow); only our keys' animation
is ever cleared, the user's own keys keep theirs.
"""
import bpy
from pdeface.animation.sequence import sequence_keys
from pdeface.animation.timeline import load_timeline
from pdeface.animation.trackers import import_au
from pdeface.errors import PdeFaceError
from pdeface.presets import resolve_preset

from . import compat
from .face import pose_objects, rig_objects
from .keys import au_key_names, expression_key_name, expression_key_names, managed, set_pose


def scene_fps(scene):
    """The scene's frame rate (frames per second)."""
    return scene.render.fps / scene.render.fps_base


def keyframe_pose(obj, frame):
    """Keyframe every PDE key of the head's controls at ``frame``; returns how many."""
    keys = [k for o in pose_objects(obj) for k in managed(o)]
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
    unknown = [n for n in names if n not in presets]
    if unknown:
        raise PdeFaceError(f"unknown preset(s): {', '.join(unknown)}")
    if channels == "KEY":
        keys = expression_key_names(obj, names)
        lacking = [expression_key_name(n) for n in names if n not in keys]
        if lacking:
            raise PdeFaceError(f"no {lacking[0]!r} shape key: build shape keys first")
        poses = [{keys[n]: 1.0} for n in names]
    else:
        by_au = au_key_names(obj)
        poses = []
        for n in names:
            w, _ = resolve_preset(presets[n], set(by_au))
            poses.append({by_au[k]: v for k, v in w.items()})
    frames = sequence_keys(poses, start, hold, blend, mode)
    for o in pose_objects(obj):
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
    keys keep theirs; ours it does not name rest at 0 from its first frame,
    values only: no keyframe is added to keys it does not name) and ``scene``'s frame range becomes the timeline's; with
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
        set_pose(obj, {})  # a new animation starts from itself alone, not from the pose the file was saved in
    prefs = bpy.context.preferences.edit
    saved = prefs.keyframe_new_interpolation_type
    try:
        for key in timeline.keys:
            # New keys take the user-preference interpolation: the one way that works on 4.2-5.0.
            prefs.keyframe_new_interpolation_type = key.interpolation.upper()
            values = {by_au[a]: w for a, w in key.aus.items() if a in by_au}
            values.update({by_preset[p]: w for p, w in key.presets.items() if p in by_preset})
            for o in pose_objects(obj):
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
    if fmt == "timeline" or (fmt == "auto" and path.lower().endswith(".json")):
        return load_timeline(path), 0, [], []
    r = import_au(path, fmt, fps, hold, smooth, reduce, capture_fps=capture_fps)
    return r.timeline, r.dropped, r.unknown, r.notes
