"""Where an opening's rims lie on the mesh: the curves on either side of the mouth and the eyes.

The lips meet in a crease. Walking down the upper lip towards the slit, its
skin turns away from the viewer and rolls into the mouth; the lower lip does
the same walking up. A lip's *rim* is the last place its skin still faces the
viewer (as :func:`pdeface.surface.report.band_vertices` counts skin as visible), or
where the skin ends (the lid margins, with the eyeball left out of the skin).
One curve runs along each rim, so every visible vertex of a lip or lid lies on
its own side of the pair, and the strip between the rims spans the opening.
"""
from __future__ import annotations

import copy

import numpy as np

from ..errors import LayoutError
from ..geometry import cast_cylinder_rays, every_corner
from .layout import ANCHOR_NAMES, OPENING_GAPS, OPENINGS, CurveLayout, FeatureLine

#: Skin seen more obliquely than this (cosine between normal and ray, ~72°) faces away.
FACING_MIN_COS = 0.3
#: Height step (mm) of the rays walking towards a rim.
RIM_STEP_MM = 0.05
#: A radius change larger than this (mm) between two steps leaves the lip's skin.
RIM_JUMP_MM = 0.5
#: A rim may lie this far (mm) past the opening's middle line (ICT's touching lips: 0.15 mm; a stylised chin's
#: lower rim on the upper lip: 1.7 mm).
RIM_CROSS_MM = 0.3
#: A rim's knot nearer a span's end knot (a corner) than this share of the rays' spacing there is left out: a ray a
#: thousandth of a radian inside an inner eye corner made a near-double knot whose spline swung the eye line 213 mm
#: down between the eyes, and every anchor below with it (a MakeHuman head's mouth curves on its chin, issue #40).
RIM_KNOT_GAP = 0.25


def follow_rims(layout: CurveLayout, V_face: np.ndarray, T: np.ndarray) -> CurveLayout:
    """A copy of ``layout`` whose opening curves lie on the rims of ``V_face``.

    At each point of an opening's top curve within its spans (between the
    mouth corners; between each eye's corners) rays walk down from halfway to
    the anchor above until the next ray would meet skin facing away, no skin,
    or another surface; the bottom rim likewise walking up. Where the two rims
    meet (towards the corners) they sit the opening's
    :data:`pdeface.surface.layout.OPENING_GAPS` apart around their middle. The lines' knots outside the spans (the
    corners) stay at the landmarks.

    Parameters
    ----------
    layout : CurveLayout
        From :func:`pdeface.surface.layout.place_curves`.
    V_face : (n, 3) array
        Mesh vertices in the face frame (mm).
    T : (t, 3) int array
        Skin triangles.

    Returns
    -------
    CurveLayout

    Raises
    ------
    LayoutError
        When the layout's openings are not those of :data:`pdeface.surface.layout.OPENINGS`.
    """
    out = copy.deepcopy(layout)
    if layout.openings and len(layout.openings) != len(OPENINGS):
        raise LayoutError(f"layout has {len(layout.openings)} openings; rims are found for the {len(OPENINGS)} "
                          "of pdeface.surface.layout.OPENINGS (a layout from place_curves)")
    spans = dict(zip(layout.openings, OPENINGS.values()))
    # every walk lies between its anchors above and below: the rest of the mesh is never cast on
    reach = {a: layout.anchor_heights(layout.angles()[k])[[a - 1, a, a + 1, a + 2]] for a, k in layout.opening_curves()}
    if reach:
        T = band_triangles(V_face, T, min(Y.min() for Y in reach.values()), max(Y.max() for Y in reach.values()))
    for a, k in layout.opening_curves():
        top = next(i for i, ln in enumerate(out.lines) if ln.anchor == a)
        bottom = next(i for i, ln in enumerate(out.lines) if ln.anchor == a + 1)
        line, lower = out.lines[top], out.lines[bottom]
        keep = np.ones(len(line.theta), bool)  # the seed's knots outside the spans (ends included)
        th_k, theta, up, lo = layout.angles()[k], [], [], []
        band = band_triangles(V_face, T, reach[a].min(), reach[a].max())
        for s0, s1 in spans[a]:
            keep[s0 + 1:s1] = False
            clear = RIM_KNOT_GAP * np.gradient(th_k)  # the rays' spacing there
            th = th_k[(th_k > line.theta[s0] + clear) & (th_k < line.theta[s1] - clear)]
            Y = layout.anchor_heights(th)
            rims = _rims(V_face, band, layout.axis_z, th, Y[a - 1], Y[a], Y[a + 1], Y[a + 2],
                         OPENING_GAPS[ANCHOR_NAMES[a]])
            theta.append(th), up.append(rims[0]), lo.append(rims[1])
        t = np.concatenate([line.theta[keep], *theta])
        o = np.argsort(t)
        out.lines[top] = FeatureLine(a, t[o], np.concatenate([line.y[keep], *up])[o], line.taper)
        out.lines[bottom] = FeatureLine(a + 1, t[o], np.concatenate([lower.y[keep], *lo])[o], lower.taper)
    return out


def band_triangles(V, T, lo, hi):
    """The triangles of ``T`` reaching heights (``V[:, 1]``) between ``lo`` and ``hi``, in their order: the only ones
    rays cast from the vertical axis at those heights can meet (:func:`pdeface.geometry.cast_cylinder_rays` answers
    the same on them, its triangles indexing them). Cut once, a 100k-vertex head's other triangles are not gone
    through again at each cast."""
    y = np.asarray(V)[:, 1]
    below, above = y < lo, y > hi
    return T[~(every_corner(below, T) | every_corner(above, T))]


def _rims(V, T, axis_z, th, y_above, y_top, y_bottom, y_below, gap):
    """Heights of the upper and lower rim at angles ``th``; ``gap`` apart where they meet."""
    mid = 0.5 * (y_top + y_bottom)
    up, lo = mid + 0.5 * gap, mid - 0.5 * gap
    walks = [np.arange(mid[c] + 0.5 * (y_above[c] - mid[c]), mid[c] - 0.5 * (mid[c] - y_below[c]), -RIM_STEP_MM)
             for c in range(len(th))]
    # every column's walk cast at once: one candidate grid for all of them
    r_all, _, _, facing_all = cast_cylinder_rays(V, T, axis_z, np.repeat(th, [len(w) for w in walks]),
                                                 np.concatenate(walks) if walks else np.zeros(0))
    ends = np.cumsum([0] + [len(w) for w in walks])
    for c, ys in enumerate(walks):
        r, facing = r_all[ends[c]:ends[c + 1]], facing_all[ends[c]:ends[c + 1]]
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
        if ys[i] - ys[j] >= gap:
            # A rim past the opening's middle line (the landmarks') by more than RIM_CROSS_MM stops on it: on lips
            # that touch at rest, one lip's skin running on into the other's at the same depth, the lower walk went
            # on up the upper lip, and AU27 pulled the upper lip down with the jaw (a stylised chin: issue #40).
            up[c] = ys[i] if ys[i] >= up[c] - RIM_CROSS_MM else up[c]
            lo[c] = ys[j] if ys[j] <= lo[c] + RIM_CROSS_MM else lo[c]
        else:  # no slit here: the lips meet
            m = 0.5 * (ys[i] + ys[j])
            up[c], lo[c] = m + 0.5 * gap, m - 0.5 * gap
    return up, lo
