"""Keyframe timing for expression sequences (the method's keyframe animation).

``via_neutral`` (the method's): neutral → expression → neutral → next
expression; ``direct``: expression → expression. Each expression blends in
over ``blend`` frames and holds for ``hold`` frames.
"""
from __future__ import annotations

from ..errors import PdeFaceError

MODES = ("via_neutral", "direct")
#: The method's demonstration order, then the remaining basic expressions.
METHOD_SEQUENCE = ["happy", "sad", "fear", "disgust", "surprise", "anger"]


def sequence_keys(poses, start=1, hold=12, blend=12, mode="via_neutral"):
    """Keyframes for a sequence of poses.

    Parameters
    ----------
    poses : list of dict
        Each pose maps channel names (shape keys) to weights.
    start, hold, blend : int
        First frame, frames each pose is held, frames between poses.
    mode : {'via_neutral', 'direct'}

    Returns
    -------
    list of (frame, dict)
        Every keyframe sets every channel used anywhere in the sequence
        (0 where the pose does not use it), so channels never drift.
    """
    if mode not in MODES:
        raise PdeFaceError(f"unknown sequence mode {mode!r}; use one of {', '.join(MODES)}")
    if hold < 0 or blend < 1:
        raise PdeFaceError(f"hold must be >= 0 and blend >= 1 frames, got hold={hold}, blend={blend}")
    if not poses:
        raise PdeFaceError("the sequence is empty")
    channels = sorted({c for p in poses for c in p})
    full = [{c: float(p.get(c, 0.0)) for c in channels} for p in poses]
    neutral = {c: 0.0 for c in channels}
    keys, f = [(start, neutral)], start
    for i, pose in enumerate(full):
        f += blend
        keys.append((f, pose))
        if hold:
            f += hold
            keys.append((f, pose))
        if mode == "via_neutral" or i == len(full) - 1:
            f += blend
            keys.append((f, neutral))
            if mode == "via_neutral" and hold and i < len(full) - 1:
                f += hold
                keys.append((f, neutral))
    return keys
