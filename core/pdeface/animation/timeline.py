"""Animation timelines: AU weights and presets over time.

File format (JSON)::

    {"format": "pdeface.timeline", "version": 1, "fps": 24, "frame_start": 1,
     "keys": [
       {"time": 0.0, "aus": {}},
       {"time": 0.5, "aus": {"12": 0.8, "6": "C"}, "interpolation": "bezier"},
       {"frame": 30, "presets": {"happy": 1.0}},
       {"time": 2.0, "presets": ["sad"], "interpolation": "linear"}
     ]}

Each key has ``time`` (seconds from ``frame_start``) or ``frame`` (absolute),
and AU weights (``aus``: keys ``12``, ``AU12``, ``12L``; weights in [0, 1] or
FACS letters) and/or presets (``presets``: names, or name → weight).
``interpolation`` (``constant``, ``linear``, ``bezier``; default ``bezier``)
says how the key eases into the next. A channel a key does not mention is 0
at that key, so every key is a whole pose. Keys must be in time order.
"""
from __future__ import annotations

import json
import math
from dataclasses import dataclass, field

from ..errors import ModelFormatError, PdeFaceError
from ..facs import parse_au_key, parse_weight, split_au_key
from ..io.files import atomic_open, load_json
from .sequence import sequence_keys

FORMAT = "pdeface.timeline"
#: The highest frame rate a timeline may have.
MAX_FPS = 1000
#: The longest timeline or recording read (a day): a time past it is a broken file, not a take.
MAX_SECONDS = 24 * 3600
#: The furthest frame from 0 a timeline may key (a day at the highest rate).
MAX_FRAME = MAX_SECONDS * MAX_FPS
INTERPOLATIONS = ("constant", "linear", "bezier")


@dataclass
class Key:
    frame: int
    aus: dict = field(default_factory=dict)
    presets: dict = field(default_factory=dict)
    interpolation: str = "bezier"


@dataclass
class Timeline:
    fps: float
    keys: list
    frame_start: int = 1

    @property
    def frame_end(self) -> int:
        return max(k.frame for k in self.keys)

    def channels(self) -> tuple[list, list]:
        """AU keys and preset names used anywhere."""
        aus = sorted({a for k in self.keys for a in k.aus}, key=split_au_key)
        presets = sorted({p for k in self.keys for p in k.presets})
        return aus, presets


def timeline_from_json(obj, where="timeline") -> Timeline:
    """Validate a timeline object; errors name the key and field."""
    if not isinstance(obj, dict) or obj.get("format") != FORMAT:
        raise ModelFormatError(f"{where}: field 'format' must be {FORMAT!r}")
    if not isinstance(obj.get("version"), int) or obj["version"] > 1:
        raise ModelFormatError(f"{where}: field 'version' must be 1")
    fps = obj.get("fps", 24)
    if isinstance(fps, bool) or not isinstance(fps, (int, float)) or not math.isfinite(fps) or not 0 < fps <= MAX_FPS:
        raise ModelFormatError(f"{where}: field 'fps' must be a number in (0, {MAX_FPS}]")
    start = obj.get("frame_start", 1)
    if not isinstance(start, int) or isinstance(start, bool) or abs(start) > MAX_FRAME:
        raise ModelFormatError(f"{where}: field 'frame_start' must be an integer within ±{MAX_FRAME}")
    items = obj.get("keys")
    if not isinstance(items, list) or not items:
        raise ModelFormatError(f"{where}: field 'keys' must be a non-empty list")
    keys = []
    for i, k in enumerate(items):
        at = f"{where}: keys[{i}]"
        if not isinstance(k, dict):
            raise ModelFormatError(f"{at} must be an object")
        if ("time" in k) == ("frame" in k):
            raise ModelFormatError(f"{at} needs exactly one of 'time' (seconds) or 'frame'")
        if "time" in k:
            t = k["time"]
            if isinstance(t, bool) or not isinstance(t, (int, float)) or not 0 <= t <= MAX_SECONDS:
                raise ModelFormatError(f"{at}: field 'time' must be a number of seconds in [0, {MAX_SECONDS}]")
            frame = start + int(round(t * fps))
        else:
            frame = k["frame"]
            if not isinstance(frame, int) or isinstance(frame, bool) or abs(frame) > MAX_FRAME:
                raise ModelFormatError(f"{at}: field 'frame' must be an integer within ±{MAX_FRAME}")
        aus = k.get("aus", {})
        if not isinstance(aus, dict):
            raise ModelFormatError(f"{at}: field 'aus' must be an object of AU → weight")
        try:
            aus = {parse_au_key(a): parse_weight(w, f"AU{a}") for a, w in aus.items()}
        except PdeFaceError as exc:
            raise ModelFormatError(f"{at}: field 'aus': {exc}") from None
        presets = k.get("presets", {})
        if isinstance(presets, list) and all(isinstance(p, str) for p in presets):
            presets = {p: 1.0 for p in presets}
        if not isinstance(presets, dict) or not all(isinstance(p, str) for p in presets):
            raise ModelFormatError(f"{at}: field 'presets' must be a list of names or an object name → weight")
        try:
            presets = {p: parse_weight(w, f"preset {p}") for p, w in presets.items()}
        except PdeFaceError as exc:
            raise ModelFormatError(f"{at}: field 'presets': {exc}") from None
        interp = k.get("interpolation", "bezier")
        if not isinstance(interp, str) or interp not in INTERPOLATIONS:
            raise ModelFormatError(f"{at}: field 'interpolation' must be one of {', '.join(INTERPOLATIONS)}")
        if keys and frame <= keys[-1].frame:
            raise ModelFormatError(f"{at}: frame {frame} is not after the previous key's frame {keys[-1].frame}")
        keys.append(Key(frame, aus, presets, interp))
    return Timeline(float(fps), keys, start)


def timeline_to_json(t: Timeline) -> dict:
    keys = []
    for k in t.keys:
        item = {"frame": k.frame}
        if k.aus:
            item["aus"] = {a: round(w, 4) for a, w in k.aus.items()}
        if k.presets:
            item["presets"] = {p: round(w, 4) for p, w in k.presets.items()}
        if k.interpolation != "bezier":
            item["interpolation"] = k.interpolation
        keys.append(item)
    return {"format": FORMAT, "version": 1, "fps": t.fps, "frame_start": t.frame_start, "keys": keys}


def load_timeline(path) -> Timeline:

    return timeline_from_json(load_json(path), str(path))


def save_timeline(path, t: Timeline) -> None:
    """Write a timeline (atomically); one its own reader would refuse is refused here, naming why."""

    obj = timeline_to_json(t)
    timeline_from_json(obj, str(path))
    with atomic_open(path, "w", encoding="utf-8") as fh:
        json.dump(obj, fh, indent=1)


def sequence_timeline(presets, fps=24, hold=0.5, blend=0.5, mode="via_neutral") -> Timeline:
    """A timeline of presets, as :func:`pdeface.animation.sequence.sequence_keys` times them; ``neutral`` is the
    rest pose (no key of its own)."""
    frames = sequence_keys([{} if p == "neutral" else {p: 1.0} for p in presets], 1, int(round(hold * fps)), max(1, int(round(blend * fps))), mode)
    return Timeline(fps, [Key(f, {}, {p: w for p, w in pose.items() if w > 0}) for f, pose in frames], 1)
