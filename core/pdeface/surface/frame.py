"""Landmarks, feature points, the normalised face frame and mesh units.

The 68 Multi-PIE landmarks (as vertex indices or xyz) give the method's 19
feature points and a face frame: nose tip at the origin, looking +z, up +y,
millimetres. :class:`FaceFrame` maps between the user's space and that frame.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import LandmarkError
from ..io.files import load_json
from ..landmark_scheme import (
    CHIN,
    EYE_LEFT,
    EYE_RIGHT,
    FEATURE_POINTS,
    JAW_LEFT_END,
    JAW_RIGHT_END,
    NOSE_BRIDGE_TOP,
    NOSE_TIP,
    eye_centres,
    eye_distance,
)
from ..units import ESTIMATED, UNITS_MM, parse_unit

#: Rotation taking ICT-FaceKit's axes (+z front, +y up) to Blender's (-y front, +z up): ``V @ BLENDER_FROM_ICT.T``.
BLENDER_FROM_ICT = np.array([[1.0, 0, 0], [0, 0, -1], [0, 1, 0]])

#: The face's sizes the unit is estimated from (:func:`estimate_mm_per_unit`): the landmark groups whose means are
#: measured apart, and the size (mm) of a face of the middle size. Of 16 sizes (eye centres, eye corners, eye, mouth and
#: nose widths, nose length, the jaw's ends and angles, eyes, brows, nasion and nose to chin), alone and in pairs and
#: threes, these two vary least in millimetres over ICT-FaceKit's 21 heads and MakeHuman's 32 characters (the
#: development set's 24 and bench_gate's 8), true and found landmarks (MakeHuman's faces are about 9 % smaller than
#: ICT's at the same eye distance, and vary more). The sizes sit between the two: the estimate lies under ICT's true
#: millimetres per unit by 6.8 % (median; at most 8.0 %: larger faces), over MakeHuman's by 1.4-1.9 % (median; the worst
#: a held-out round face, 8.8 % under; the game unit's 2.0 %, as before). Before, the median over eye centres, eyes to
#: mouth, nose length, mouth width and outer eye corners at ICT's sizes scaled to 63 mm between the eyes lay 17 % over
#: MakeHuman's small faces (asian-female-old). See docs/measurements/units.md.
FACE_SIZES_MM = {"eyes to mouth": ([*EYE_RIGHT, *EYE_LEFT], [48, 51, 54, 57], 69.2),
                 "jaw width": ([JAW_RIGHT_END], [JAW_LEFT_END], 131.8)}
#: An estimate this close (ratio) to a named unit is that unit: units are at least 2.5 times apart.
UNIT_SNAP = 1.3
#: Eye-centre distances a face may have (a small child's to a giant caricature's), in mm.
EYE_DISTANCE_RANGE_MM = (20.0, 200.0)
#: No point of a face, and no change of one an AU makes, lies farther than this from the nose tip (face frame,
#: mm): a fit leaves out triangles beyond it (a vertex an exporter left far away), and models, descriptors and
#: landmark maps holding values past it are refused (a residual of -6.5e11 would be posed for minutes).
FACE_REACH_MM = 1000.0



def read_landmarks(path):
    """Read a landmarks JSON file.

    The file holds ``{"indices": [68 ints]}`` (vertex indices, 0-based) or
    ``{"points": [[x, y, z], ... 68]}``; with both, the points are used.

    Returns
    -------
    indices : (68,) int array or None
    points : (68, 3) float array or None
    """

    return parse_landmarks(load_json(path, LandmarkError), str(path))


def parse_landmarks(data, name="landmarks"):
    """Validate landmark data given as a dict (see :func:`read_landmarks`)."""
    if not isinstance(data, dict) or not ({"indices", "points"} & set(data)):
        raise LandmarkError(f"{name}: expected an object with 'indices' or 'points'")
    if "indices" in data and "points" in data:
        # Both (as ``pdeface landmarks`` writes): the exact points win; the indices must still be valid.
        parse_landmarks({"indices": data["indices"]}, name)
        return parse_landmarks({"points": data["points"]}, name)
    if "indices" in data:
        idx = data["indices"]
        if not isinstance(idx, list) or not all(isinstance(i, int) and not isinstance(i, bool) for i in idx):
            raise LandmarkError(f"{name}: 'indices' must be a list of integers")
        if len(idx) != 68:
            raise LandmarkError(f"{name}: 'indices' needs 68 entries (Multi-PIE), got {len(idx)}")
        if not all(0 <= i < 2**31 for i in idx):
            raise LandmarkError(f"{name}: 'indices' must be vertex numbers from 0")
        return np.array(idx, dtype=np.int64), None
    pts = data["points"]
    try:
        arr = np.array(pts, dtype=np.float64)
    except (TypeError, ValueError):
        raise LandmarkError(f"{name}: 'points' must be a list of [x, y, z]") from None
    if arr.shape != (68, 3):
        raise LandmarkError(f"{name}: 'points' must be 68 [x, y, z] triples, got shape {arr.shape}")
    if not np.isfinite(arr).all():
        raise LandmarkError(f"{name}: 'points' contains NaN or inf")
    return None, arr


def landmark_points(vertices, indices=None, points=None):
    """The 68 landmark positions, from vertex indices or given xyz."""
    if indices is not None:
        indices = np.asarray(indices)
        if len(indices) != 68:
            raise LandmarkError(f"need 68 landmark indices, got {len(indices)}")
        if indices.min() < 0 or indices.max() >= len(vertices):
            raise LandmarkError(f"landmark index out of range 0..{len(vertices) - 1}")
        return np.asarray(vertices, dtype=np.float64)[indices]
    if points is None:
        raise LandmarkError("landmarks needed: give vertex indices or points")
    points = np.asarray(points, dtype=np.float64)
    if points.shape != (68, 3) or not np.isfinite(points).all():
        raise LandmarkError(f"need 68 finite landmark points, got shape {points.shape}")
    return points


def feature_points(landmarks68: np.ndarray) -> np.ndarray:
    """The 19 feature points (:data:`FEATURE_NAMES` order) from 68 landmarks."""
    L = np.asarray(landmarks68, dtype=np.float64)
    return np.array([L[ids].mean(axis=0) for ids in FEATURE_POINTS.values()])


def estimate_mm_per_unit(landmarks68: np.ndarray) -> float:
    """Millimetres per mesh unit from the face's size: the geometric mean over :data:`FACE_SIZES_MM` of each size
    over the same size measured on the landmarks (a face 10 % smaller than the middle one reads 10 % off)."""
    L = np.asarray(landmarks68, dtype=np.float64)
    sizes = np.array([np.linalg.norm(L[a].mean(0) - L[b].mean(0)) for a, b, _ in FACE_SIZES_MM.values()])
    if not (sizes > 0).all() or not eye_distance(L) > 0:
        raise LandmarkError("the eyes, mouth or jaw ends coincide: cannot estimate the unit")
    return float(np.exp(np.mean(np.log([mm for _, _, mm in FACE_SIZES_MM.values()] / sizes))))


def estimate_unit(landmarks68: np.ndarray) -> tuple[str, float]:
    """The mesh unit and millimetres per unit, from the face's size (:func:`estimate_mm_per_unit`): a named
    unit within :data:`UNIT_SNAP` of the estimate, else :data:`ESTIMATED` at the estimate (any scale)."""
    mm = estimate_mm_per_unit(landmarks68)
    unit = min(UNITS_MM, key=lambda u: abs(np.log(mm / UNITS_MM[u])))
    if abs(np.log(mm / UNITS_MM[unit])) <= np.log(UNIT_SNAP):
        return unit, UNITS_MM[unit]
    return ESTIMATED, mm


@dataclass
class FaceFrame:
    """Rigid frame plus scale from the user's mesh space to the face frame.

    ``face = scale * (user - origin) @ rotation.T``: nose tip at the origin,
    +x towards the subject's left, +y up, +z forward, millimetres.
    """

    rotation: np.ndarray  # (3, 3), rows are the face axes in user space
    origin: np.ndarray  # (3,) nose tip in user space
    scale: float  # millimetres per user unit
    unit: str

    def to_face(self, P: np.ndarray) -> np.ndarray:
        """User space → face frame (mm)."""
        return self.scale * (np.asarray(P, dtype=np.float64) - self.origin) @ self.rotation.T

    def to_user(self, P: np.ndarray) -> np.ndarray:
        """Face frame (mm) → user space."""
        return np.asarray(P, dtype=np.float64) @ self.rotation / self.scale + self.origin

    def to_user_vectors(self, D: np.ndarray) -> np.ndarray:
        """Displacements in the face frame (mm) → user space."""
        return np.asarray(D, dtype=np.float64) @ self.rotation / self.scale

    def matrix(self) -> np.ndarray:
        """4×4 homogeneous matrix user → face."""
        M = np.eye(4)
        M[:3, :3] = self.scale * self.rotation
        M[:3, 3] = -self.scale * self.rotation @ self.origin
        return M


def face_frame(landmarks68: np.ndarray, unit: str | None = None) -> FaceFrame:
    """The normalised face frame of a face from its 68 landmarks.

    Parameters
    ----------
    landmarks68 : (68, 3) array
        Landmark positions in the mesh's own space.
    unit : str or float, optional
        Mesh unit, a name or millimetres per unit (:func:`~pdeface.units.parse_unit`); estimated from the face's
        size when None (:func:`estimate_unit`: any scale).

    Raises
    ------
    LandmarkError
        For a unit that is none, or degenerate landmarks.
    """
    L = np.asarray(landmarks68, dtype=np.float64)
    if L.shape != (68, 3) or not np.isfinite(L).all():
        raise LandmarkError(f"need 68 finite landmarks, got shape {L.shape}")
    unit, scale = estimate_unit(L) if unit is None else parse_unit(unit)
    eyes_mm = eye_distance(L) * scale
    if not EYE_DISTANCE_RANGE_MM[0] <= eyes_mm <= EYE_DISTANCE_RANGE_MM[1]:
        raise LandmarkError(f"the eyes are {eyes_mm:.3g} mm apart in unit {unit!r}; a face's are "
                            f"{EYE_DISTANCE_RANGE_MM[0]}-{EYE_DISTANCE_RANGE_MM[1]} mm: check the unit and the "
                            "landmarks")
    right, left = eye_centres(L)
    x = left - right  # right eye → left eye
    up = L[NOSE_BRIDGE_TOP] - L[CHIN]  # chin → nose bridge
    nx = np.linalg.norm(x)
    if nx == 0 or np.linalg.norm(up) == 0:
        raise LandmarkError("landmarks are degenerate (eyes or chin/nose bridge coincide)")
    x /= nx
    y = up - x * (up @ x)
    ny = np.linalg.norm(y)
    if ny < 1e-9 * np.linalg.norm(up):
        raise LandmarkError("landmarks are degenerate: the eye line is parallel to the face's vertical")
    y /= ny
    z = np.cross(x, y)
    frame = FaceFrame(np.stack([x, y, z]), L[NOSE_TIP].copy(), scale, unit)
    # A mirrored landmark order would put the nose tip behind the eyes.
    if (frame.to_face(L[[*EYE_RIGHT, *EYE_LEFT]]).mean(0)[2]) > 0:
        raise LandmarkError("landmarks look mirrored or out of order: the eyes are in front of the nose tip")
    return frame
