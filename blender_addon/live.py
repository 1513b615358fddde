"""The live link: a pdeface stream Player fed on its own threads, applied from a Blender timer.

Socket work never touches Blender data; ``tick`` (run by ``bpy.app.timers`` at
up to 60 Hz, or called directly) reads the player's pose and writes the shape
keys, recording keyframes when asked.
"""
import time

import bpy

from . import bridge
from .operators import MIX_KEY, managed, set_pose, write_mix_key

_state = {"player": None, "address": None, "face": None, "t0": 0.0, "frame0": 1, "record": False, "hz": 60.0, "mixer": "sum",
          "applied": 0}


def running() -> bool:
    return _state["player"] is not None


def start(obj, role="LISTEN", host="127.0.0.1", port=5000, mode="live", rules=False, record=False, hz=60.0,
          mixer="sum", transition=0.25):
    """Start the player for face ``obj``; returns the address it listens on (or connects to)."""
    from pdeface.stream.player import Player
    from pdeface.stream.rules import AUBlender

    stop()
    player = Player(mode=mode, transition=transition, blender=AUBlender.load() if rules else None)
    if role == "LISTEN":
        address = tuple(player.listen(host, port))
    else:
        player.connect(host, port)
        address = (host, port)
    scene = bpy.context.scene
    _state.update(player=player, address=address, face=obj.name, t0=time.monotonic(), frame0=scene.frame_current, record=record,
                  hz=min(max(hz, 1.0), 60.0), mixer=mixer, applied=0)
    if not bpy.app.timers.is_registered(_timer):
        bpy.app.timers.register(_timer, first_interval=0.0, persistent=True)
    return address


def stop():
    player = _state["player"]
    _state["player"] = None
    if bpy.app.timers.is_registered(_timer):
        bpy.app.timers.unregister(_timer)
    if player is not None:
        player.close()


def status() -> dict:
    player = _state["player"]
    if player is None:
        return {"running": False}
    return {"running": True, "address": _state["address"], "applied": _state["applied"], **player.stats.as_dict()}


def tick():
    """Apply the player's current pose to the face's shape keys (and record it)."""
    player = _state["player"]
    obj = bpy.data.objects.get(_state["face"] or "")
    if player is None or obj is None or not obj.pdeface.is_face:
        stop()
        return
    pose = player.pose()
    keys = managed(obj)
    if _state["mixer"] == "sum":
        names = {e.au_key: e.name for e, _ in keys if e.kind == "AU"}
        set_pose(obj, {names[k]: w for k, w in pose.items() if k in names})
        touched = [kb for e, kb in keys if e.kind == "AU"]
    else:
        write_mix_key(obj, bridge.face_model(obj), pose, _state["mixer"])
        touched = [kb for e, kb in managed(obj) if e.name == MIX_KEY]
    _state["applied"] += 1
    if _state["record"]:
        scene = bpy.context.scene
        fps = scene.render.fps / scene.render.fps_base
        frame = _state["frame0"] + round((time.monotonic() - _state["t0"]) * fps)
        for kb in touched:
            kb.keyframe_insert("value", frame=frame)
    obj.data.update()


def _timer():
    if _state["player"] is None:
        return None
    try:
        tick()
    except ReferenceError:  # the face was deleted
        stop()
        return None
    return 1.0 / _state["hz"]
