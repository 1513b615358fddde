"""Where the boundary curves lie on a face, placed from its landmarks.

Curves are horizontal sections of the face in the face frame, from the top of
the forehead (curve 0) to the chin (last curve). Each is sampled by rays cast
from a vertical axis behind the face, so points sit at fixed angles on it.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .errors import LayoutError
from .frame import eye_distance
from .geometry import cylinder_coords

#: Relative curve density between the anchor heights, top to bottom: denser at
#: brows, eyes, nose and lips, as the method's curves are.
SEGMENT_DENSITY = {
    "forehead-brow": 0.7, "brow-eye_top": 1.55, "eye_top-eye_bottom": 2.95, "eye_bottom-nose_tip": 1.3,
    "nose_tip-nose_bottom": 2.85, "nose_bottom-lip_upper": 1.5, "lip_upper-mouth": 4.0, "mouth-lip_lower": 2.45,
    "lip_lower-chin": 0.85,
}


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
    """

    heights: np.ndarray
    half_angles: np.ndarray
    axis_z: float
    n_points: int
    centre_density: float = 0.5

    @property
    def n_curves(self) -> int:
        return len(self.heights)

    def sample_params(self) -> np.ndarray:
        """Curve parameter ``v_j`` in [0, π] of every point (uniform)."""
        return np.linspace(0.0, np.pi, self.n_points)

    def angles(self, v=None) -> np.ndarray:
        """(K, len(v)) ray angles of curve parameters ``v`` (default: the samples)."""
        v = self.sample_params() if v is None else np.asarray(v, dtype=np.float64)
        s = 2.0 * v / np.pi - 1.0
        b = self.centre_density
        return self.half_angles[:, None] * ((1 - b) * s + b * s ** 3)[None, :]

    def as_array(self) -> np.ndarray:
        """Layout packed in one float array (for model files)."""
        return np.concatenate([[self.axis_z, self.n_points, self.centre_density], self.heights, self.half_angles])

    @classmethod
    def from_array(cls, a) -> "CurveLayout":
        a = np.asarray(a, dtype=np.float64)
        k = (len(a) - 3) // 2
        return cls(a[3:3 + k].copy(), a[3 + k:].copy(), float(a[0]), int(round(a[1])), float(a[2]))


def place_curves(landmarks_face: np.ndarray, n_curves: int = 31, n_points: int = 37,
                 forehead: float = 2.0, side_margin: float = 0.92) -> CurveLayout:
    """Place the curve layout from the 68 landmarks given in the face frame (mm).

    Parameters
    ----------
    landmarks_face : (68, 3) array
        Landmarks in the face frame (see :func:`pdeface.frame.face_frame`).
    n_curves, n_points : int
        Number of curves and of points per curve.
    forehead : float
        Top curve height above the brows, in units of the brow-to-eye distance.
    side_margin : float
        Fraction of the jawline's angular width the curves span.
    """
    if n_curves < 4:
        raise LayoutError(f"need at least 4 curves, got {n_curves}")
    if n_points < 7:
        raise LayoutError(f"need at least 7 points per curve, got {n_points}")
    L = np.asarray(landmarks_face, dtype=np.float64)
    axis_z = -1.75 * eye_distance(L)
    brow, eye = L[17:27, 1].mean(), L[36:48, 1].mean()
    lid_top, lid_bottom = L[[37, 38, 43, 44], 1].mean(), L[[40, 41, 46, 47], 1].mean()
    # Lids barely apart (a blink, a squint) still get their band of curves.
    gap = max(lid_top - lid_bottom, 0.25 * (brow - eye))
    chin, lip_lower = L[8, 1], L[57, 1]
    anchors = {
        "forehead": brow + forehead * (brow - eye), "brow": brow, "eye_top": eye + 0.5 * gap,
        "eye_bottom": eye - 0.5 * gap, "nose_tip": L[30, 1],
        "nose_bottom": L[33, 1], "lip_upper": L[51, 1], "mouth": L[[62, 66], 1].mean(),
        "lip_lower": lip_lower, "chin": chin + 0.08 * (lip_lower - chin),
    }
    ys = np.array(list(anchors.values()))
    if not (np.diff(ys) < 0).all():
        order = " > ".join(anchors)
        raise LayoutError(f"landmark heights are not in face order ({order}); check the landmarks and their order")
    density = np.array(list(SEGMENT_DENSITY.values()))
    # Curves at equal steps of the density-weighted height.
    measure = np.concatenate([[0.0], np.cumsum(-np.diff(ys) * density)])
    heights = np.interp(np.linspace(0, measure[-1], n_curves), measure, ys)
    # Angular extent from the jawline (landmarks 0-8 right, 8-16 left).
    th, y, _ = cylinder_coords(L, axis_z)
    half = []
    for side in (np.arange(0, 9), np.arange(16, 7, -1)):
        o = np.argsort(y[side])
        half.append(np.abs(np.interp(heights, y[side][o], th[side][o])))
    half = side_margin * 0.5 * (half[0] + half[1])
    # Never narrower than the mouth, so the chin curves cover the chin.
    half = np.maximum(half, 1.5 * np.abs(th[[48, 54]]).mean())
    return CurveLayout(heights, half, float(axis_z), int(n_points))
