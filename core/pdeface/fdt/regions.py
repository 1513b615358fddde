"""The pupil-normalised frame and the 16 muscle regions of a Facial Deformation Table.

Obaid et al. (2009) normalise every face by its pupils p₁, p₂ (the subject's
right and left eye centres here: means of landmarks 36-41 and 42-47): the
midpoint m goes to the origin, p₁p₂ onto the x-axis, and the scale puts p₁ at
(−1, 0) and p₂ at (1, 0). :func:`normalise_2d` is exactly that, for points in a
frontal image. :class:`PupilFrame` is its 3-D extension: the same origin, axis
and scale, with +y from the chin towards the nose bridge (landmarks 8 → 27,
made orthogonal to the eye line) and +z out of the face, so a mesh in any
pose, unit and handedness-preserving rotation lands in the same coordinates.

The paper draws its 16 regions (its Fig. 4) from the facial muscles but gives
no coordinates; :data:`REGIONS` places them from landmarks. Each region owns a
few *seed* points (landmark means, some shifted by a fixed amount in the
normalised frame); a point belongs to the region of its nearest seed (a
Voronoi partition of the face), and near a border it blends the neighbouring
regions' motion smoothly (:func:`region_weights`). Only landmarks a saved face
model keeps are used (:func:`available_landmarks`).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import LandmarkError
from ..geometry import smoothstep
from ..landmark_scheme import CHIN, NOSE_BRIDGE_TOP, eye_centres


@dataclass(frozen=True)
class Region:
    """One FDT region: its number (1-16, the paper's), name, muscles, and seeds.

    ``seeds`` are ``(landmark indices, (dx, dy))``: the mean of those landmarks
    shifted by (dx, dy) pupil half-distances in the normalised frame.
    """

    number: int
    name: str
    muscles: str
    seeds: tuple


def _mirror(seeds):
    """The subject's left side's seeds from the right side's (Multi-PIE landmark symmetry)."""
    pairs = {0: 16, 5: 11, 8: 8, 17: 26, 21: 22, 27: 27, 30: 30, 31: 35, 33: 33, 36: 45, 37: 44, 38: 43, 39: 42,
             40: 47, 41: 46, 48: 54, 51: 51, 57: 57, 62: 62, 66: 66}
    return tuple((tuple(pairs[i] for i in ids), (-dx, dy)) for ids, (dx, dy) in seeds)


_FOREHEAD_R = (((17,), (0.0, 0.0)), ((21,), (0.0, 0.0)), ((17, 21), (0.0, 0.0)), ((17,), (0.0, 0.55)),
               ((21,), (0.0, 0.55)), ((17, 21), (0.0, 1.1)))
_BROW_R = (((37, 38), (0.0, 0.0)), ((37, 38), (0.0, 0.15)), ((36, 37), (0.0, 0.05)), ((38, 39), (0.0, 0.05)))
_LOWER_LID_R = (((40, 41), (0.0, 0.0)), ((40, 41), (0.0, -0.12)), ((36, 41), (0.0, -0.05)), ((39, 40), (0.0, -0.05)))
_CHEEK_R = (((36,), (0.0, -0.8)), ((0,), (0.35, -0.2)), ((36, 48), (-0.3, 0.0)), ((40, 41), (0.0, -0.5)))
_CORNER_R = (((48,), (0.0, 0.0)), ((48,), (-0.25, 0.0)), ((5,), (0.3, 0.15)))

#: The 16 regions, numbered as the paper's Table I; pairs are (subject's right, left).
REGIONS = (
    Region(1, "forehead and brow right", "frontalis (right belly), corrugator (lateral)", _FOREHEAD_R),
    Region(2, "forehead and brow left", "frontalis (left belly), corrugator (lateral)", _mirror(_FOREHEAD_R)),
    Region(3, "glabella", "procerus, corrugator supercilii (medial)", (((21, 22), (0.0, 0.0)), ((27,), (0.0, 0.0)))),
    Region(4, "upper lid right", "orbicularis oculi (upper, palpebral), levator palpebrae superioris", _BROW_R),
    Region(5, "upper lid left", "orbicularis oculi (upper, palpebral), levator palpebrae superioris",
           _mirror(_BROW_R)),
    Region(6, "lower lid right", "orbicularis oculi (lower, palpebral and orbital)", _LOWER_LID_R),
    Region(7, "lower lid left", "orbicularis oculi (lower, palpebral and orbital)", _mirror(_LOWER_LID_R)),
    Region(8, "nose bridge", "procerus (lower), nasalis (transverse)", (((27, 30), (0.0, 0.0)),)),
    Region(9, "nose wings and tip", "nasalis (alar), levator labii superioris alaeque nasi",
           (((30,), (0.0, 0.0)), ((31,), (0.0, 0.0)), ((33,), (0.0, 0.0)), ((35,), (0.0, 0.0)))),
    Region(10, "cheek right", "zygomaticus major and minor, levator labii superioris, buccinator", _CHEEK_R),
    Region(11, "cheek left", "zygomaticus major and minor, levator labii superioris, buccinator", _mirror(_CHEEK_R)),
    Region(12, "upper lip", "orbicularis oris (upper), levator labii (insertions)",
           (((51,), (0.0, 0.0)), ((33, 51), (0.0, 0.0)), ((62,), (0.0, 0.0)), ((48, 51), (0.0, 0.0)),
            ((51, 54), (0.0, 0.0)))),
    Region(13, "lower lip", "orbicularis oris (lower), depressor labii inferioris",
           (((57,), (0.0, 0.0)), ((66,), (0.0, 0.0)), ((48, 57), (0.0, 0.0)), ((54, 57), (0.0, 0.0)))),
    Region(14, "mouth corner right", "risorius, depressor anguli oris, zygomaticus major (insertion)", _CORNER_R),
    Region(15, "mouth corner left", "risorius, depressor anguli oris, zygomaticus major (insertion)",
           _mirror(_CORNER_R)),
    Region(16, "chin", "mentalis", (((8,), (0.0, 0.0)), ((8, 57), (0.0, 0.0)))),
)
N_REGIONS = len(REGIONS)

#: The openings (eyes, mouth): inside an opening's span (between its corners), a point above it
#: never takes the motion of the regions below, nor one below that of the regions above, however
#: close (a closed mouth's lips touch). Opening → (spans as landmark pairs, the line's landmark
#: groups per span, 0-based regions above, 0-based regions below).
OPENINGS = {
    "eyes": ((((36,), (37, 38, 40, 41), (39,)), ((42,), (43, 44, 46, 47), (45,))), (3, 4), (5, 6)),
    "mouth": ((((48,), (62, 66), (54,)),), (11,), (12, 15)),
}

#: Inside an opening's span, the two sides keep apart fully from this far (pupil half-distances) from
#: its corners; at the corners themselves they meet.
OPENING_TAPER = 0.15
#: Width (pupil half-distances) over which neighbouring regions' motions blend.
BLEND = 0.2
#: A point farther than REACH[0] from every seed starts to fade out of the table's motion, and beyond
#: REACH[1] does not move: the quadratics are fitted on the face and grow without bound outside it.
REACH = (0.55, 0.95)


def available_landmarks() -> tuple:
    """Landmarks the regions read: those a saved face model keeps, with its feature points'."""
    return tuple(sorted({i for r in REGIONS for ids, _ in r.seeds for i in ids} | set(range(36, 48)) | {8, 27}))


def normalise_2d(points, p1, p2) -> np.ndarray:
    """The paper's pupil normalisation of 2-D points (n, 2).

    Translate the pupils' midpoint to the origin, rotate p₁p₂ onto the x-axis,
    scale so that p₁ = (−1, 0) and p₂ = (1, 0).
    """
    P = np.asarray(points, np.float64)
    p1, p2 = np.asarray(p1, np.float64), np.asarray(p2, np.float64)
    d = p2 - p1
    half = np.hypot(*d) / 2
    if not half > 0:
        raise LandmarkError("the two pupils coincide: cannot normalise")
    c, s = d / (2 * half)
    R = np.array([[c, s], [-s, c]])  # rotation by −θ
    return (P - (p1 + p2) / 2) @ R.T / half


@dataclass(frozen=True)
class PupilFrame:
    """Similarity transform to the pupil-normalised frame: ``n = scale · R (p − origin)``."""

    origin: np.ndarray
    rotation: np.ndarray  # rows: the frame's axes in the source space
    scale: float  # 1 / pupil half-distance (source units)

    @classmethod
    def from_landmarks(cls, landmarks68) -> "PupilFrame":
        """The frame of a face from its 68 landmarks (rows 8, 27, 36-47 are read)."""
        L = np.asarray(landmarks68, np.float64)
        need = [8, 27, *range(36, 48)]
        if L.shape != (68, 3) or not np.isfinite(L[need]).all():
            raise LandmarkError("the pupil frame needs 68 landmarks (x, y, z) with the eyes, nose bridge and chin")
        p1, p2 = eye_centres(L)
        x = p2 - p1
        half = np.linalg.norm(x) / 2
        if not half > 0:
            raise LandmarkError("the two pupils coincide: cannot normalise")
        x /= 2 * half
        up = L[NOSE_BRIDGE_TOP] - L[CHIN]
        y = up - x * (up @ x)
        if not np.linalg.norm(y) > 1e-9 * np.linalg.norm(up):
            raise LandmarkError("the chin-to-nose-bridge line is parallel to the eye line")
        y /= np.linalg.norm(y)
        return cls((p1 + p2) / 2, np.stack([x, y, np.cross(x, y)]), 1.0 / half)

    def normalise(self, P) -> np.ndarray:
        """Source points → normalised frame."""
        return self.scale * (np.asarray(P, np.float64) - self.origin) @ self.rotation.T

    def to_source(self, N) -> np.ndarray:
        """Normalised points → source space."""
        return np.asarray(N, np.float64) @ self.rotation / self.scale + self.origin

    def vectors_to_source(self, D) -> np.ndarray:
        """Normalised displacements → source space."""
        return np.asarray(D, np.float64) @ self.rotation / self.scale


def region_seeds(normalised_landmarks) -> tuple[np.ndarray, np.ndarray]:
    """Seed points (s, 2) in the normalised frame and the region index (0-15) of each."""
    L = np.asarray(normalised_landmarks, np.float64)
    pts, owner = [], []
    for k, r in enumerate(REGIONS):
        for ids, shift in r.seeds:
            pts.append(L[list(ids), :2].mean(0) + shift)
            owner.append(k)
    pts = np.array(pts)
    if not np.isfinite(pts).all():
        raise LandmarkError(f"the FDT regions need landmarks {', '.join(map(str, available_landmarks()))}")
    return pts, np.array(owner)


def opening_sides(points_xy, normalised_landmarks) -> np.ndarray:
    """(n, 2) side of each point for the eyes and the mouth: +1 above the opening's line inside its
    span, −1 below, 0 outside the span (the line runs through the corners and the lids' or lips' middle)."""
    return _openings(points_xy, normalised_landmarks)[0]


def _openings(points_xy, normalised_landmarks):
    """Sides (see :func:`opening_sides`) and how firmly each applies: 0 at the corners, 1 from
    :data:`OPENING_TAPER` inside them (the two sides meet at a corner)."""
    P = np.asarray(points_xy, np.float64)
    L = np.asarray(normalised_landmarks, np.float64)
    sides = np.zeros((len(P), len(OPENINGS)), np.int64)
    firm = np.zeros((len(P), len(OPENINGS)))
    for c, (spans, _, _) in enumerate(OPENINGS.values()):
        for groups in spans:
            knots = np.array([L[list(g), :2].mean(0) for g in groups])
            inside = (P[:, 0] > knots[0, 0]) & (P[:, 0] < knots[-1, 0])
            line = np.interp(P[:, 0], knots[:, 0], knots[:, 1])
            sides[inside, c] = np.where(P[inside, 1] >= line[inside], 1, -1)
            firm[inside, c] = smoothstep(np.minimum(P[inside, 0] - knots[0, 0], knots[-1, 0] - P[inside, 0])
                                         / OPENING_TAPER)
    return sides, firm


def seed_distances(points_xy, normalised_landmarks, sides=None) -> np.ndarray:
    """(n, 16) distance from each point (normalised x, y) to each region's nearest seed.

    A region across an opening from the point (:data:`OPENINGS`; ``sides`` as
    :func:`opening_sides` gives them, computed from the landmarks when None) is at infinity.
    """
    P = np.asarray(points_xy, np.float64)[:, :2]
    D = _distances(P, normalised_landmarks)
    sides = opening_sides(P, normalised_landmarks) if sides is None else np.asarray(sides)
    return _exclude(D, sides)


def _distances(P, normalised_landmarks):
    seeds, owner = region_seeds(normalised_landmarks)
    d = np.linalg.norm(P[:, None, :] - seeds[None], axis=2)
    D = np.full((len(d), N_REGIONS), np.inf)
    for k in range(N_REGIONS):
        D[:, k] = d[:, owner == k].min(axis=1)
    return D


def _exclude(D, sides):
    D = D.copy()
    for c, (_, above, below) in enumerate(OPENINGS.values()):
        D[np.ix_(sides[:, c] > 0, below)] = np.inf
        D[np.ix_(sides[:, c] < 0, above)] = np.inf
    return D


def assign_regions(points_xy, normalised_landmarks, sides=None) -> np.ndarray:
    """Region index (0-15) of each point; −1 beyond the face (farther than ``REACH[0]`` from any seed)."""
    D = seed_distances(points_xy, normalised_landmarks, sides)
    k = D.argmin(axis=1)
    k[D.min(axis=1) > REACH[0]] = -1
    return k


def _soft(D, blend):
    Dmin = D.min(axis=1, keepdims=True)
    W = np.exp(-(D - Dmin) / blend) if blend > 0 else (D == Dmin).astype(np.float64)
    return W / W.sum(axis=1, keepdims=True), Dmin[:, 0]


def region_weights(points_xy, normalised_landmarks, blend=None, sides=None) -> np.ndarray:
    """(n, 16) weights of each region's motion at each point: a soft nearest-region partition.

    ``w_k = exp(−(D_k − D_min) / blend) / Σ_j exp(−(D_j − D_min) / blend) · fade(D_min)`` with
    ``D_k`` the distance to region k's nearest seed: continuous across every border (no tear where
    two regions' transforms disagree). Across an opening (:data:`OPENINGS`) a point takes none of
    the other side's regions, firmly from :data:`OPENING_TAPER` inside the corners and less towards
    them, so the lips and lids part inside the opening and meet smoothly at its corners. The motion
    fades to zero beyond the face (:data:`REACH`). ``blend`` defaults to :data:`BLEND`; 0 gives the
    hard partition. ``sides`` overrides the sides read from the landmarks (the PDE face's rim
    curves know theirs: :func:`pdeface.fdt.deform.curve_sides`).
    """
    P = np.asarray(points_xy, np.float64)[:, :2]
    blend = BLEND if blend is None else blend
    own_sides, firm = _openings(P, normalised_landmarks)
    sides = own_sides if sides is None else np.asarray(sides)
    D = _distances(P, normalised_landmarks)
    W, Dmin = _soft(D, blend)
    W_apart, _ = _soft(_exclude(D, sides), blend)
    e = firm.max(axis=1, keepdims=True)
    if blend == 0:  # one region a point, as :func:`assign_regions`
        e = (e > 0).astype(np.float64)
    W = (1 - e) * W + e * W_apart
    return W * (1 - smoothstep((Dmin - REACH[0]) / (REACH[1] - REACH[0])))[:, None]
