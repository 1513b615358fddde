"""The live link: a pdeface stream Player fed on its own threads, applied from a Blender timer.

Socket work never touches Blender data; ``tick`` (run by ``bpy.app.timers`` at
up to 60 Hz, or called directly) reads the player's pose and writes the shape
keys, recording keyframes when asked.
"""
import time

import bpy
from pdeface.errors import PdeFaceError
from pdeface.presets import choose_mixer
from pdeface.stream.player import Player
from pdeface.stream.rules import AUBlender

from .animation import scene_fps
from .keys import managed, pose_aus

LOOPBACK = ("127.0.0.1", "localhost", "::1")

_state = {"player": None, "address": None, "face": None, "t0": 0.0, "frame0": 1, "record": False, "hz": 60.0,
          "mixer": "sum", "applied": 0}


def running() -> bool:
    return _state["player"] is not None


def start(obj, role="LISTEN", host="127.0.0.1", port=5000, mode="live", rules=False, record=False, hz=60.0,
          mixer=None, allow_remote=False, transition=0.25, token=""):
    """Start the player for face ``obj``; returns the address it listens on (or connects to).

    Listening on an address other than loopback needs ``allow_remote``. ``mixer``
    None is ``sum`` (the AU keys themselves). ``token``: the shared secret a sender
    must present to end or stop the player (empty: only this user, from this machine).
    """
    if role == "LISTEN" and host not in LOOPBACK and not allow_remote:
        raise PdeFaceError(f"listening on {host} opens the player to the network: tick 'Allow remote' to do that")
    if not managed(obj, "AU"):
        raise PdeFaceError("build shape keys first")
    mixer = choose_mixer(mixer)
    pose_aus(obj, {}, mixer)  # the mix key is checked to be ours here, once (the timer does not)
    stop()
    player = Player(mode=mode, transition=transition, blender=AUBlender.load() if rules else None, token=token or None)
    try:
        if role == "LISTEN":
            address = tuple(player.listen(host, port))
        else:
            player.connect(host, port)
            address = (host, port)
    except OSError as exc:
        player.close()
        raise PdeFaceError(f"cannot {role.lower()} on {host}:{port}: {exc.strerror or exc}") from None
    scene = bpy.context.scene
    _state.update(player=player, address=address, face=obj.name, t0=time.monotonic(), frame0=scene.frame_current,
                  record=record, hz=min(max(hz, 1.0), 60.0), mixer=mixer, applied=0)
    if not bpy.app.timers.is_registered(_timer):
        bpy.app.timers.register(_timer, first_interval=0.0, persistent=True)
    return address


def stop() -> int:
    """Stop the player (if running); returns how many packets it received."""
    player = _state["player"]
    _state["player"] = None
    if bpy.app.timers.is_registered(_timer):
        bpy.app.timers.unregister(_timer)
    if player is None:
        return 0
    player.close()
    return player.stats.packets


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
    touched = pose_aus(obj, player.pose(), _state["mixer"], check=False)
    _state["applied"] += 1
    if _state["record"]:
        scene = bpy.context.scene
        frame = _state["frame0"] + round((time.monotonic() - _state["t0"]) * scene_fps(scene))
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
