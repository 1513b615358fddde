"""Where an opening's rims lie on the mesh: the curves on either side of the mouth.

The lips meet in a crease. Walking down the upper lip towards the slit, its
skin turns away from the viewer and rolls into the mouth; the lower lip does
the same walking up. A lip's *rim* is the last place its skin still faces the
viewer (as :func:`pdeface.report.band_vertices` counts skin as visible). One
curve runs along each rim, so every visible vertex of a lip lies on that lip's
side of the pair, and the thin strip between the rims spans the slit.
"""
from __future__ import annotations

import copy

import numpy as np

from .geometry import cast_cylinder_rays
from .layout import OPENING_GAP, CurveLayout, FeatureLine

#: Skin seen more obliquely than this (cosine between normal and ray, ~72°) faces away.
FACING_MIN_COS = 0.3
#: Height step (mm) of the rays walking towards a rim.
RIM_STEP_MM = 0.05
#: A radius change larger than this (mm) between two steps leaves the lip's skin.
RIM_JUMP_MM = 0.5


def follow_rims(layout: CurveLayout, V_face: np.ndarray, T: np.ndarray) -> CurveLayout:
    """A copy of ``layout`` whose opening curves lie on the rims of ``V_face``.

    At each point of an opening's top curve (within its line's ends) rays walk
    down from halfway to the anchor above until the next ray would meet skin
    facing away or another surface; the bottom rim likewise walking up. Where
    the two rims meet (towards the mouth corners) they sit
    :data:`pdeface.layout.OPENING_GAP` apart around their middle. The lines'
    ends stay at the landmarks.

    Parameters
    ----------
    layout : CurveLayout
        From :func:`pdeface.layout.place_curves`.
    V_face : (n, 3) array
        Mesh vertices in the face frame (mm).
    T : (t, 3) int array
        Skin triangles.

    Returns
    -------
    CurveLayout
    """
    out = copy.deepcopy(layout)
    for a, k in layout.opening_curves():
        top = next(i for i, ln in enumerate(out.lines) if ln.anchor == a)
        bottom = next(i for i, ln in enumerate(out.lines) if ln.anchor == a + 1)
        line = out.lines[top]
        th = layout.angles()[k]
        th = th[(th > line.theta[0]) & (th < line.theta[-1])]
        if not len(th):
            continue
        Y = layout.anchor_heights(th)
        up, lo = _rims(V_face, T, layout.axis_z, th, Y[a - 1], Y[a], Y[a + 1], Y[a + 2])
        lower = out.lines[bottom]
        out.lines[top] = FeatureLine(a, np.r_[line.theta[0], th, line.theta[-1]],
                                     np.r_[line.y[0], up, line.y[-1]], line.taper)
        out.lines[bottom] = FeatureLine(a + 1, np.r_[lower.theta[0], th, lower.theta[-1]],
                                        np.r_[lower.y[0], lo, lower.y[-1]], lower.taper)
    return out


def _rims(V, T, axis_z, th, y_above, y_top, y_bottom, y_below):
    """Heights of the upper and lower rim at angles ``th``."""
    mid = 0.5 * (y_top + y_bottom)
    up, lo = mid + 0.5 * OPENING_GAP, mid - 0.5 * OPENING_GAP
    for c in range(len(th)):
        ys = np.arange(mid[c] + 0.5 * (y_above[c] - mid[c]), mid[c] - 0.5 * (mid[c] - y_below[c]), -RIM_STEP_MM)
        r, _, _, facing = cast_cylinder_rays(V, T, axis_z, np.full(len(ys), th[c]), ys)
        ok = np.isfinite(r) & (facing >= FACING_MIN_COS)
        step_ok = np.abs(np.diff(r)) <= RIM_JUMP_MM  # False across NaN too
        if not ok[0] or not ok[-1]:
            continue  # not on skin where the walk starts: keep the landmark line
        i = 0
        while i + 1 < len(ys) and ok[i + 1] and step_ok[i]:
            i += 1
        j = len(ys) - 1
        while j > 0 and ok[j - 1] and step_ok[j - 1]:
            j -= 1
        if ys[i] - ys[j] >= OPENING_GAP:
            up[c], lo[c] = ys[i], ys[j]
        else:  # no slit here: the lips meet
            m = 0.5 * (ys[i] + ys[j])
            up[c], lo[c] = m + 0.5 * OPENING_GAP, m - 0.5 * OPENING_GAP
    return up, lo
