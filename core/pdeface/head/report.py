"""How much of each AU's true motion the head binding captures, over every part of the head.

The same ``captured`` as :mod:`pdeface.au.aureport` (``1 − RMS(d − d_true) / RMS(d_true)``
over vertices truly moving more than 0.5 mm), but over the user's whole mesh,
hidden or not, per region; and the **spill**: how far vertices that truly stay
put (moving less than 0.1 mm) are moved (99th percentile).
"""
from __future__ import annotations

import numpy as np

from ..au.aureport import MOTION_MM, captured
from ..facs import au_number
from .bind import GAZE_AUS

#: Vertices moving less than this (mm) in the truth count as still, for the spill.
STILL_MM = 0.1


def captured_over(pred, true, mask) -> tuple[float | None, int]:
    """``captured`` and vertex count over ``mask`` & truly moving (mm arrays)."""
    moving = mask & (np.linalg.norm(true, axis=1) > MOTION_MM)
    if not moving.any():
        return None, 0
    return captured(pred[moving], true[moving]), int(moving.sum())


def head_report(binding, truth: dict, regions: dict) -> dict:
    """Per AU key of ``truth``: captured per region and the spill.

    Parameters
    ----------
    binding : HeadBinding
        Of the model whose descriptors are measured.
    truth : mapping
        AU key → (n, 3) true offsets of every vertex, in the mesh's unit.
    regions : mapping
        Region name → (n,) bool mask (e.g. ``{"face": ..., "head": all}``).

    Returns
    -------
    dict
        AU key → ``{region: captured}``, ``{region + "_n": count}``,
        ``spill_p99_mm`` (over truly still vertices; the eyeballs are left
        out for gaze AUs, whose eyeballs ICT-FaceKit does not turn).
    """
    mm = binding.frame.scale
    eyes = binding.parts.mask("eye_L", "eye_R")
    out = {}
    measured = [d for d in binding.model.descriptors if d.key in truth]
    for d, D in zip(measured, binding.descriptor_displacements(measured) if measured else ()):
        pred = D * mm
        true = np.asarray(truth[d.key]) * mm
        row = {}
        for name, mask in regions.items():
            row[name], row[name + "_n"] = captured_over(pred, true, mask)
        still = np.linalg.norm(true, axis=1) < STILL_MM
        if au_number(d.key) in GAZE_AUS:
            still &= ~eyes
        row["spill_p99_mm"] = float(np.percentile(np.linalg.norm(pred[still], axis=1), 99)) if still.any() else 0.0
        out[d.key] = row
    return out
