"""Where the boundary curves lie on a face, placed from its landmarks.

Curves run across the face in the face frame, from the top of the forehead
(curve 0) to the chin (last curve). Each is sampled by horizontal rays cast
from a vertical axis behind the face, so points sit at fixed angles on it.

Away from the eyes, nose and mouth a curve is a horizontal section at its
*level* (height). Near them the curves bend: the curve levels are anchored at
landmark heights, and some anchors follow :class:`FeatureLine` s through
landmarks (the lips' edges, the base of the nostrils), so no curve crosses
from one lip to the other or falls into a nostril by chance.

The eyes and the mouth are *openings*: two curves run along each, one on each
lid's or lip's rim (where its skin turns into the opening, found on the mesh
by :func:`pdeface.surface.rims.follow_rims`), and the curve interval between them is a
*break* the smooth assembly solves apart (see :mod:`pdeface.surface.pde`), so the
upper lid or lip moves without dragging the lower one.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..errors import LayoutError
from ..geometry import cylinder_coords
from ..landmark_scheme import (
    BROW_LEFT,
    BROW_RIGHT,
    CHIN,
    EYE_LEFT,
    EYE_RIGHT,
    LIP_LOWER_BOTTOM,
    LIP_LOWER_INNER,
    LIP_UPPER_INNER,
    LIP_UPPER_TOP,
    MOUTH_CORNERS,
    NOSE_BOTTOM,
    NOSE_TIP,
    eye_distance,
)
from .pde import break_fits, cubic_spline_operator

#: Curves in the default layout. The method used 31 (10 patches of 4); 34 (11
#: patches of 4) is the fewest that still tile into patches of 4 and keep every
#: AU's capture on target with the smooth surface's normals within 8° of the
#: scan on the ICT neutral and its 20 identities. No 31-curve layout found did
#: both (the former one left 11° on the chin, nostrils and lower lids).
DEFAULT_CURVES = 34
#: The most curves, points per curve and Fourier modes a face can need (about 10x the defaults):
#: files claiming more are refused before anything is allocated.
MAX_CURVES, MAX_POINTS, MAX_MODES = 400, 400, 64


def check_sizes(n_curves, n_points, n_modes, where="layout", error=LayoutError):
    """Refuse curve, point or mode counts outside what a face can need (see :data:`MAX_CURVES`)."""
    for name, value, low, high in (("curves", n_curves, 4, MAX_CURVES), ("points per curve", n_points, 7, MAX_POINTS),
                                   ("modes", n_modes, 0, MAX_MODES)):
        if not low <= value <= high:
            raise error(f"{where}: {value} {name}; a face has {low} to {high}")

#: Relative curve density between successive heights, top to bottom: denser at
#: brows, eyes, nose and lips, as the method's curves are. ``eye_top`` and
#: ``eye_bottom`` (the lids' landmark heights) only shape the density; the
#: other names are the anchors the curves bend at. An opening's two anchors
#: have no curves between them. Tuned with ``DEFAULT_CURVES`` (see README,
#: "Curves and normals").
SEGMENT_DENSITY = {
    "forehead-brow": 0.7, "brow-eye_top": 1.78, "eye_top-lid_top": 3.05, "lid_top-lid_bottom": 0.0,
    "lid_bottom-eye_bottom": 3.61, "eye_bottom-nose_tip": 1.26,
    "nose_tip-nose_bottom": 3.13, "nose_bottom-lip_upper": 1.83, "lip_upper-mouth_top": 3.6,
    "mouth_top-mouth_bottom": 0.0, "mouth_bottom-lip_lower": 2.16,
    "lip_lower-chin": 1.11,
}


#: Anchors the curves bend at, by name, and the landmarks of the line each follows.
#: The lids' and the mouth's pairs start on the line through the eyes and the line
#: between the inner lips (the rims on the mesh replace them when fitting); the nose
#: line runs along the base of the nostrils; the lip lines along the lips' outer edges.
_MOUTH_LINE = ([48], [60], [61, 67], [62, 66], [63, 65], [64], [54])
_EYE_LINE = ([36], [37, 41], [38, 40], [39], [42], [43, 47], [44, 46], [45])  # corners and lid middles
FEATURE_LINES = {
    "lid_top": _EYE_LINE,
    "lid_bottom": _EYE_LINE,
    "nose_bottom": ([31], [32], [33], [34], [35]),
    "lip_upper": ([48], [49], [50], [51], [52], [53], [54]),
    "mouth_top": _MOUTH_LINE,
    "mouth_bottom": _MOUTH_LINE,
    "lip_lower": ([48], [59], [58], [57], [56], [55], [54]),
}
#: The anchors' names, top to bottom (:attr:`CurveLayout.anchors` and ``openings`` index them).
ANCHOR_NAMES = ("forehead", "brow", "lid_top", "lid_bottom", "nose_tip", "nose_bottom", "lip_upper", "mouth_top",
                "mouth_bottom", "lip_lower", "chin")
#: Openings, as (top anchor, bottom anchor): a curve runs along each rim.
#: Each maps to the knot ranges of its line where the rims are searched (the eye line
#: crosses the nose between the eyes).
OPENINGS = {("lid_top", "lid_bottom"): ((0, 3), (4, 7)), ("mouth_top", "mouth_bottom"): ((0, 6),)}
#: Height gap (mm) between an opening's two anchors, and between its rims where they meet, per opening
#: (its top anchor). Beyond the eyes' corners the two rims' curves bend differently between samples;
#: 0.1 mm apart they crossed and the strip between them folded over (35 folds at rest on the generic
#: face, 20 and 22 on identity001/002). Measured on those faces at 0.1 / 0.3 / 0.6 / 1.0 mm (both
#: openings): 35 / 10 / 8 / 1, 20 / 7 / 6 / 0, 22 / 4 / 5 / 0; at 1.0 the retargeted descriptors'
#: capture fell 0.959 → 0.950 and the worst normal p95 reached 7.9°. The lips keep 0.1: their line had
#: no folds, and 0.6 there cost the whole head's mouth AUs 1-3 points (bench_head: AU12 0.86 → 0.84).
OPENING_GAPS = {"lid_top": 0.6, "mouth_top": 0.1}
#: Beyond its ends a line's pull fades out over this fraction of its angular width.
LINE_TAPER = 0.4
#: Bent anchors keep at least this fraction of their level gap between them.
MIN_ANCHOR_GAP = 0.3


@dataclass
class FeatureLine:
    """A line on the face that one anchor follows, as heights at ray angles.

    Attributes
    ----------
    anchor : int
        Index of the anchor (in :attr:`CurveLayout.anchors`) that bends.
    theta, y : (p,) float
        Angles (increasing, radians) and heights (mm) of the line's knots.
    taper : float
        Angular width (radians) over which the bend fades out beyond the ends.
    """

    anchor: int
    theta: np.ndarray
    y: np.ndarray
    taper: float

    def pull(self, theta: np.ndarray, level: float) -> np.ndarray:
        """Height offset from ``level`` the line asks for at angles ``theta``."""
        th, y = self.theta, self.y
        inside = (theta >= th[0]) & (theta <= th[-1])
        val = np.where(theta < th[0], y[0], y[-1]).astype(np.float64)
        if len(th) >= 4:
            val[inside] = cubic_spline_operator(th, theta[inside]) @ y
        else:
            val[inside] = np.interp(theta[inside], th, y)
        beyond = np.maximum(th[0] - theta, theta - th[-1]).clip(min=0.0)
        fade = 0.5 * (1 + np.cos(np.pi * np.clip(beyond / self.taper, 0.0, 1.0)))
        return fade * (val - level)


@dataclass
class CurveLayout:
    """Curve heights, angular extents and the sampling axis (face frame, mm).

    Attributes
    ----------
    heights : (K,) float
        Height (y) of each curve, top (forehead) to bottom (chin).
    half_angles : (K,) float
        Each curve spans angles [-half, +half] (radians) around the axis.
    axis_z : float
        The vertical sampling axis is the line x = 0, z = axis_z.
    n_points : int
        Points per curve.
    centre_density : float
        0 samples evenly in angle; larger values put more points near the
        face's midline (nose, lips).
    anchors : (A,) float
        Levels (decreasing) between which the curves' bends are interpolated;
        empty for straight curves.
    lines : list of FeatureLine
        The lines bent anchors follow.
    openings : list of int
        Top anchor ``a`` of each opening (its bottom anchor is ``a + 1``).
    """

    heights: np.ndarray
    half_angles: np.ndarray
    axis_z: float
    n_points: int
    centre_density: float = 0.5
    anchors: np.ndarray = field(default_factory=lambda: np.zeros(0))
    lines: list = field(default_factory=list)
    openings: list = field(default_factory=list)

    @property
    def n_curves(self) -> int:
        return len(self.heights)

    def opening_curves(self) -> list:
        """``(a, k)`` for each opening whose rims carry curves: curve k at its top
        anchor ``a``, curve k + 1 at its bottom anchor, and enough curves on
        either side for the smooth assembly to solve them apart."""
        out = []
        for a in self.openings:
            k = np.nonzero(np.abs(self.heights - self.anchors[a]) < 1e-4)[0]
            if (len(k) and break_fits(self.n_curves, k[0])
                    and abs(self.heights[k[0] + 1] - self.anchors[a + 1]) < 1e-4):
                out.append((int(a), int(k[0])))
        return out

    def breaks(self) -> tuple:
        """Curve intervals that span an opening (see :mod:`pdeface.surface.pde`)."""
        return tuple(k for _, k in self.opening_curves())

    def sample_params(self) -> np.ndarray:
        """Curve parameter ``v_j`` in [0, π] of every point (uniform)."""
        return np.linspace(0.0, np.pi, self.n_points)

    def angles(self, v=None) -> np.ndarray:
        """(K, len(v)) ray angles of curve parameters ``v`` (default: the samples)."""
        v = self.sample_params() if v is None else np.asarray(v, dtype=np.float64)
        s = 2.0 * v / np.pi - 1.0
        b = self.centre_density
        return self.half_angles[:, None] * ((1 - b) * s + b * s ** 3)[None, :]

    def anchor_heights(self, theta) -> np.ndarray:
        """(A, len(theta)) heights of the anchors at angles ``theta``."""
        theta = np.asarray(theta, dtype=np.float64).ravel()
        Y = np.repeat(self.anchors[:, None], len(theta), axis=1)
        for line in self.lines:
            Y[line.anchor] += line.pull(theta, self.anchors[line.anchor])
        return _keep_apart(Y, -MIN_ANCHOR_GAP * np.diff(self.anchors))

    def ray_heights(self) -> np.ndarray:
        """(K, J) height of every curve point's ray."""
        if not self.lines:
            return np.repeat(self.heights[:, None], self.n_points, axis=1)
        theta = self.angles()
        s = self.anchors
        a = np.clip(np.searchsorted(-s, -self.heights, side="right") - 1, 0, len(s) - 2)
        t = ((self.heights - s[a]) / (s[a + 1] - s[a]))[:, None]
        Y = self.anchor_heights(theta).reshape(len(s), *theta.shape)
        k = np.arange(self.n_curves)
        return Y[a, k] + t * (Y[a + 1, k] - Y[a, k])

    def level(self, theta, y) -> np.ndarray:
        """The curve level through points at angles ``theta`` and heights ``y``.

        The inverse of the bend: points on curve k give ``heights[k]``.
        """
        theta, y = np.asarray(theta, np.float64).ravel(), np.asarray(y, np.float64).ravel()
        if not self.lines:
            return y.copy()
        Y, s = self.anchor_heights(theta), self.anchors
        out = np.where(y > Y[0], s[0] + (y - Y[0]), s[-1] + (y - Y[-1]))
        for a in range(len(s) - 1):
            m = (y <= Y[a]) & (y >= Y[a + 1])
            out[m] = s[a] + (y[m] - Y[a][m]) / (Y[a + 1][m] - Y[a][m]) * (s[a + 1] - s[a])
        return out

    def as_array(self) -> np.ndarray:
        """Layout packed in one float array (for model files).

        ``axis_z, n_points, centre_density``, the K heights, the K half
        angles; then, for bent curves, ``A``, the A anchors, the number of
        lines and per line ``anchor, p, taper``, p angles, p heights; then,
        when there are openings, their number and top anchors.
        """
        head = [[self.axis_z, self.n_points, self.centre_density], self.heights, self.half_angles]
        if not self.lines:
            return np.concatenate(head)
        warp = [[len(self.anchors)], self.anchors, [len(self.lines)]]
        for ln in self.lines:
            warp += [[ln.anchor, len(ln.theta), ln.taper], ln.theta, ln.y]
        if self.openings:
            warp += [[len(self.openings)], self.openings]
        return np.concatenate(head + warp)

    @classmethod
    def from_array(cls, a, n_curves: int) -> "CurveLayout":
        """Unpack :meth:`as_array` of a layout with ``n_curves`` curves.

        Raises
        ------
        LayoutError
            When the array does not hold a layout of that many curves.
        """
        a = np.asarray(a, dtype=np.float64)
        k = int(n_curves)
        if len(a) < 3 + 2 * k:
            raise LayoutError(f"layout has {len(a)} values, a layout of {k} curves needs at least {3 + 2 * k}")
        lay = cls(a[3:3 + k].copy(), a[3 + k:3 + 2 * k].copy(), float(a[0]), int(round(a[1])), float(a[2]))
        rest = a[3 + 2 * k:]
        if not len(rest):
            return lay
        try:
            n_a = int(rest[0])
            lay.anchors = rest[1:1 + n_a].copy()
            pos, n_lines = 2 + n_a, int(rest[1 + n_a])
            for _ in range(n_lines):
                anchor, p, taper = int(rest[pos]), int(rest[pos + 1]), float(rest[pos + 2])
                th, y = rest[pos + 3:pos + 3 + p].copy(), rest[pos + 3 + p:pos + 3 + 2 * p].copy()
                if len(y) != p or p < 2 or not 0 <= anchor < n_a or not taper > 0 or np.any(np.diff(th) <= 0):
                    raise LayoutError("layout's feature line is malformed")
                lay.lines.append(FeatureLine(anchor, th, y, taper))
                pos += 3 + 2 * p
            if pos < len(rest):
                n_o = int(rest[pos])
                lay.openings = [int(x) for x in rest[pos + 1:pos + 1 + n_o]]
                if len(lay.openings) != n_o or n_o < 1 or not all(0 <= x < n_a - 1 for x in lay.openings):
                    raise LayoutError("layout's openings are malformed")
                pos += 1 + n_o
        except IndexError:
            raise LayoutError("layout's feature lines are cut short") from None
        if pos != len(rest) or n_a < 2 or np.any(np.diff(lay.anchors) >= 0):
            raise LayoutError("layout's anchors or feature lines are malformed")
        return lay


def place_curves(landmarks_face: np.ndarray, n_curves: int = DEFAULT_CURVES, n_points: int = 37,
                 forehead: float = 2.0, side_margin: float = 0.92, follow_lips: bool = True) -> CurveLayout:
    """Place the curve layout from the 68 landmarks given in the face frame (mm).

    Parameters
    ----------
    landmarks_face : (68, 3) array
        Landmarks in the face frame (see :func:`pdeface.surface.frame.face_frame`).
    n_curves, n_points : int
        Number of curves and of points per curve.
    forehead : float
        Top curve height above the brows, in units of the brow-to-eye distance.
    side_margin : float
        Fraction of the jawline's angular width the curves span.
    follow_lips : bool
        Bend the curves along the lips, the nostrils' base and the eyes (see
        :data:`FEATURE_LINES`) and put a curve on each side of the mouth
        line and each lid (:data:`OPENINGS`); False gives straight
        horizontal sections.
    """
    check_sizes(n_curves, n_points, 0)
    L = np.asarray(landmarks_face, dtype=np.float64)
    axis_z = -1.75 * eye_distance(L)
    brow, eye = L[[*BROW_RIGHT, *BROW_LEFT], 1].mean(), L[[*EYE_RIGHT, *EYE_LEFT], 1].mean()
    lid_top, lid_bottom = L[[37, 38, 43, 44], 1].mean(), L[[40, 41, 46, 47], 1].mean()
    # Lids barely apart (a blink, a squint) still get their band of curves.
    gap = max(lid_top - lid_bottom, 0.25 * (brow - eye))
    chin, lip_lower, mouth = L[CHIN, 1], L[LIP_LOWER_BOTTOM, 1], L[[LIP_UPPER_INNER, LIP_LOWER_INNER], 1].mean()
    anchors = dict(zip(ANCHOR_NAMES, (
        brow + forehead * (brow - eye), brow, eye + 0.5 * OPENING_GAPS["lid_top"], eye - 0.5 * OPENING_GAPS["lid_top"],
        L[NOSE_TIP, 1], L[NOSE_BOTTOM, 1], L[LIP_UPPER_TOP, 1], mouth + 0.5 * OPENING_GAPS["mouth_top"], mouth - 0.5 * OPENING_GAPS["mouth_top"],
        lip_lower,
        chin + 0.08 * (lip_lower - chin))))
    ys = np.array(list(anchors.values()))
    # Density breakpoints: the anchors and the lids' heights, in SEGMENT_DENSITY's order.
    levels = {**anchors, "eye_top": eye + 0.5 * gap, "eye_bottom": eye - 0.5 * gap}
    order = list(dict.fromkeys(n for seg in SEGMENT_DENSITY for n in seg.split("-")))
    yd = np.array([levels[n] for n in order])
    if not (np.diff(yd) < 0).all():
        raise LayoutError(f"landmark heights are not in face order ({' > '.join(order)}); "
                          "check the landmarks and their order")
    density = np.array(list(SEGMENT_DENSITY.values()))
    # Curves at equal steps of the density-weighted height.
    measure = np.concatenate([[0.0], np.cumsum(-np.diff(yd) * density)])
    heights = np.interp(np.linspace(0, measure[-1], n_curves), measure, yd)
    names = list(ANCHOR_NAMES)
    openings = [names.index(top) for top, _ in OPENINGS] if follow_lips else []
    for a in openings:
        _snap_to_opening(heights, ys, yd, measure, a)
    # Angular extent from the jawline (landmarks 0-8 right, 8-16 left).
    th, y, _ = cylinder_coords(L, axis_z)
    half = []
    for side in (np.arange(0, 9), np.arange(16, 7, -1)):
        o = np.argsort(y[side])
        half.append(np.abs(np.interp(heights, y[side][o], th[side][o])))
    half = side_margin * 0.5 * (half[0] + half[1])
    # Never narrower than the mouth, so the chin curves cover the chin.
    half = np.maximum(half, 1.5 * np.abs(th[MOUTH_CORNERS]).mean())
    layout = CurveLayout(heights, half, float(axis_z), int(n_points))
    if follow_lips:
        layout.anchors, layout.openings = ys, openings
        offset = ({top: 0.5 * OPENING_GAPS[top] for top, _ in OPENINGS}
                  | {bottom: -0.5 * OPENING_GAPS[top] for top, bottom in OPENINGS})
        for name, groups in FEATURE_LINES.items():
            t, yy, _ = cylinder_coords(np.array([L[g].mean(axis=0) for g in groups]), axis_z)
            o = np.argsort(t)
            if np.any(np.diff(t[o]) <= 0):
                raise LayoutError(f"the {name} landmarks do not run across the face; check the landmarks")
            layout.lines.append(FeatureLine(names.index(name), t[o], yy[o] + offset.get(name, 0.0),
                                            LINE_TAPER * (t[o][-1] - t[o][0])))
    return layout


def _keep_apart(Y: np.ndarray, gaps: np.ndarray) -> np.ndarray:
    """Heights nearest ``Y`` (A, q) (least squares, per column) whose rows stay ``gaps`` (A-1,) apart.

    Bent anchors never cross. Where lines converge (mouth and eye corners) several
    may crowd at once, so this is the exact projection: with ``Z = Y + Σ gaps``
    it must not increase down the rows, which is isotonic regression,
    ``Z'_a = min_{i≤a} max_{j≥a} mean(Z_i..Z_j)``. Uncrowded anchors stay put,
    and two that crowd meet the gap around their middle.
    """
    c = np.concatenate([[0.0], np.cumsum(gaps)])[:, None]
    Z = Y + c
    crowded = (np.diff(Z, axis=0) > 0).any(axis=0)  # only these columns move
    if not crowded.any():
        return Y
    Zc, A = Z[:, crowded], len(Z)
    S = np.vstack([np.zeros((1, Zc.shape[1])), np.cumsum(Zc, axis=0)])
    i, j = np.triu_indices(A)
    mean = np.empty((A, A, Zc.shape[1]))
    mean[i, j] = (S[j + 1] - S[i]) / (j - i + 1)[:, None]
    out = Y.copy()
    out[:, crowded] = np.stack([mean[:a + 1, a:].max(axis=1).min(axis=0) for a in range(A)]) - c
    return out


def _snap_to_opening(heights, ys, yd, measure, a):
    """Put curves on an opening's two anchors ``a``, ``a + 1``, in place.

    The curves between the anchors around it are spread again, by density,
    above and below the pair. Too few curves there: the heights stay.
    """
    above, below = np.nonzero(heights > ys[a - 1])[0], np.nonzero(heights < ys[a + 2])[0]
    if not len(above) or not len(below):
        return
    above, below = above[-1], below[0]
    m = below - above - 1
    if m < 2:
        return
    top, bottom = ys[a], ys[a + 1]
    M = lambda y: np.interp(-y, -yd, measure)  # noqa: E731
    H = lambda q: np.interp(q, measure, yd)  # noqa: E731
    wu, wl = M(top) - M(heights[above]), M(heights[below]) - M(bottom)
    cu = int(round((m - 2) * wu / (wu + wl)))
    cl = m - 2 - cu
    heights[above + 1:below] = np.concatenate([H(np.linspace(M(heights[above]), M(top), cu + 2)[1:-1]), [top, bottom],
                                               H(np.linspace(M(bottom), M(heights[below]), cl + 2)[1:-1])])
