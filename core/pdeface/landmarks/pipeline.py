"""Find the 68 landmarks on a head mesh: render, detect, back-project, map.

1. **Search.** The mesh is rendered from the six axis directions; each image
   is read in four rolls (0, 90, 180, 270°) by the face detector, so heads in
   any axis convention, turned or lying, and whole bodies are found; where
   none shows a face, from the 20 directions between them (a head pitched 45°).
2. **Zoom.** The best face is rendered again, filling the image; the face
   mesh's 468 points are cast back onto the mesh.
   Each roll of the zoom is read, and the reading that best fits the map's
   template (a similarity fit) gives the face's pose.
3. **Frontal.** The face is rendered straight on and turned a little
   (:data:`FRONTAL_TURNS`); each render's 468 points are cast onto the skin
   (the parts most of them hit: lashes, eyeballs and helper geometry in front
   of the skin are looked through) and averaged.
4. **Map.** The shipped affine map turns 468 points into the 68 Multi-PIE
   landmarks, snapped onto the skin. Confidence per landmark group falls with
   the group's spread over the frontal renders and with rays that missed skin.
5. **Refine.** Groups the face mesh places by its learned faces, not by the
   surface, are taken to surface features: the upper jaw's depth, the lids' margin
   (:mod:`.eyes`), the brow ridge, the lip line's seam (:mod:`.mouth`), the
   subnasale and the bridge's middle (:mod:`.nose`), the chin's point on its profile
   (:mod:`.contour`).
"""
from __future__ import annotations

import itertools
import warnings
from concurrent.futures import Future
from dataclasses import dataclass, field

import numpy as np

from ..errors import LandmarkError
from ..geometry import ClosestPoint
from ..mesh import connected_components, triangle_arrays, vertex_normals
from ..rigid import rotation_vector_matrix
from ..surface.frame import estimate_unit
from ..threads import bounded
from ..units import parse_unit
from .brows import brows_from_upper_face, nasion_from_midline_strip
from .contour import (
    chin_on_profile,
    jaw_angles_from_neighbours,
    jaw_sides_from_template,
    upper_jaw_at_template_depth,
)
from .detector import Detector
from .eyes import corners_on_skin_front, lids_on_margin, outer_corners_at_opening_end
from .facemap import GROUPS, LandmarkMap, robust_similarity, shipped_map
from .mouth import (
    inner_lip_corners_at_seam_end,
    inner_lip_corners_inset,
    inner_lips_in_seam,
    lower_inner_lips_under_the_slit,
    lower_lip_on_its_edge,
    lower_lip_sides_at_ict_drop,
    mouth_corners_at_seam_end,
    upper_lip_on_its_edge,
)
from .nose import bridge_at_ict_shares, nose_bottom_at_subnasale
from .render import Raster, View, back_project, closed_depth, depth_map, marked, rasterise, shade

#: The search's view directions (towards the viewer) with an up vector each.
SEARCH_AXES = {"+z": ((0, 0, 1), (0, 1, 0)), "-y": ((0, -1, 0), (0, 0, 1)), "+x": ((1, 0, 0), (0, 1, 0)),
               "-x": ((-1, 0, 0), (0, 1, 0)), "-z": ((0, 0, -1), (0, 1, 0)), "+y": ((0, 1, 0), (0, 0, 1))}


def _between_axes() -> dict:
    """The view directions between :data:`SEARCH_AXES`: the cube's 12 edges, then its 8 corners (named by their
    axes, ``+y+z``), each with an up vector across it."""
    dirs = [d for d in itertools.product((-1, 0, 1), repeat=3) if sorted(map(abs, d)) in ([0, 1, 1], [1, 1, 1])]
    return {"".join(f"{'+-'[v < 0]}{axis}" for v, axis in zip(d, "xyz") if v):
            (np.array(d) / np.linalg.norm(d), min(((0, 1, 0), (0, 0, 1), (1, 0, 0)), key=lambda u: abs(np.dot(u, d))))
            for d in sorted(dirs, key=lambda d: sum(map(abs, d)))}


#: Where no axis view shows a face (a head pitched 45° between two axes: the face detector misses a face
#: turned ~40° from the view), the views between them; the four rolls of each cover the rest.
SEARCH_BETWEEN = _between_axes()
#: Pixels of the search renders and of the zoomed and frontal face renders.
SEARCH_SIZE, FACE_SIZE = 512, 384
#: Half-width of the frontal render in the template's mm (the face about half the image across).
FRONTAL_HALF_MM = 130.0
#: A search can stop early at a face this sure.
SURE = 0.6
#: How far (mm) behind what a ray hits first it may still find the skin (lashes and eyeballs are in front).
SKIN_REACH_MM = 12.0
#: The frontal renders' turns from straight on (rotation vector, degrees: pitch, yaw, roll).
FRONTAL_TURNS = ((0, 0, 0), (0, 10, 0), (0, -10, 0), (8, 0, 0))
#: A group's median spread (mm) over the frontal renders, where the map records none for it: the spread at
#: which its confidence is 1/√2 (and 1/2 at twice it).
SPREAD_MM = 1.0
#: Candidates (surest first) whose zoomed face mesh is checked against the template, and the residual that
#: ends the check early.
MAX_CANDIDATES, GOOD_RESIDUAL_MM = 4, 6.0
#: Residual (mm RMS) of the 468 points against the template beyond which they are not a face.
MAX_RESIDUAL_MM = 12.0
#: Openings in the face seen straight on (an empty eye socket, the slit of parted lips) are pixels more than
#: ``OPENING_DEPTH_MM`` behind the face's front closed over them (the depth map's closing by a disc of radius
#: ``OPENING_RADIUS_MM``: wider than a lip slit or a lid opening is high); at 4 mm, the lid margins of an ICT head
#: clustered at 3 mm counted as inside the sockets (eye corners 6 mm off).
OPENING_RADIUS_MM, OPENING_DEPTH_MM = 9.0, 5.0
#: A landmark keeps its nearest surface point when the straight-on ray finds the outer surface this near it.
SNAP_AGREES_MM = 2.0


@dataclass
class FoundLandmarks:
    """Landmarks found on a mesh.

    ``points`` (68, 3) are exact surface points, ``indices`` (68,) the nearest
    skin vertices; ``confidence`` per group in [0, 1], from ``spread_mm``, the
    group's median spread over the frontal renders; ``score`` the face
    detector's; ``view`` the search direction and roll the face was found in;
    ``mesh_points`` (468, 3) the face mesh's points on the skin, averaged over
    the frontal renders (``view_points``, one row each); ``residual_mm`` the
    face-mesh points' RMS distance from the template after a similarity fit;
    ``mm_per_unit`` the scale found (or the given unit's).
    """

    points: np.ndarray
    indices: np.ndarray
    confidence: dict
    spread_mm: dict
    score: float
    view: str
    residual_mm: float
    mm_per_unit: float
    skin: np.ndarray = field(repr=False, default=None)
    mesh_points: np.ndarray = field(repr=False, default=None)
    view_points: np.ndarray = field(repr=False, default=None)
    images: dict = field(repr=False, default_factory=dict)

    def to_json(self) -> dict:
        """The landmarks file (``indices`` and ``points``, with how sure each group is)."""
        return {"indices": self.indices.tolist(), "points": np.round(self.points, 6).tolist(),
                "confidence": {k: round(v, 3) for k, v in self.confidence.items()},
                "spread_mm": {k: round(v, 3) for k, v in self.spread_mm.items()},
                "detector_score": round(self.score, 3), "view": self.view,
                "residual_mm": round(self.residual_mm, 2), "mm_per_unit": round(self.mm_per_unit, 6),
                "source": "pdeface landmarks (MediaPipe face mesh, Apache-2.0; map fitted on ICT-FaceKit, MIT)"}

    def least_sure(self) -> str:
        """The landmark group of the lowest confidence."""
        return min(self.confidence, key=self.confidence.get)

    def marked_image(self) -> np.ndarray:
        """The frontal render (RGB) with the landmarks marked; needs ``detect(..., keep_images=True)``."""
        x, y, _ = self.images["view"].project(self.points)
        return marked(self.images["frontal"], np.stack([x, y], 1))


def _framing(V, forward, up, size, margin=1.05):
    view = View.looking(forward, up, np.zeros(3), 1.0, size)
    q = V @ view.rotation.T
    lo, hi = q.min(0), q.max(0)
    centre = ((lo + hi) / 2) @ view.rotation
    return View(view.rotation, centre, float(max(hi[:2] - lo[:2]) / 2 * margin), size)


def search(V, T, detector: Detector, size=SEARCH_SIZE, normals=None):
    """Views (rolled upright) of the faces the detector is sure of, surest first: (view, name, detection).

    Every roll of a direction is read; the search stops after a direction with
    a face scoring :data:`SURE`. A detector may also score a face upside down,
    so the caller checks candidates with the face mesh (:func:`detect`).

    Raises
    ------
    LandmarkError
        When no view shows a face, or the best view shows two.
    """
    tried, found = [], []
    for name, (forward, up) in [*SEARCH_AXES.items(), *SEARCH_BETWEEN.items()]:
        if name in SEARCH_BETWEEN and found:
            break  # the in-between views only where no axis view showed a face
        base = _framing(V, forward, up, size)
        img = shade(V, T, rasterise(V, T, base), normals=normals)
        for k in range(4):
            faces = detector.faces(np.rot90(img, k))
            label = f"{name} roll {90 * k}"
            tried.append((label, faces[0].score if faces else 0.0))
            if faces and faces[0].score >= detector.min_score:
                found.append((base.rolled(k), label, faces))
        if found and max(f[2][0].score for f in found) >= SURE:
            break
    if not found:
        top = max(tried, key=lambda t: t[1])
        raise LandmarkError(f"no face found: rendered from {len(tried) // 4} directions in 4 rolls each "
                            f"({len(tried)} images); best detector score {top[1]:.2f} ({top[0]}) < "
                            f"{detector.min_score}. Is the face part of this mesh and open to view? "
                            "Give the landmarks by hand instead.")
    found.sort(key=lambda f: -f[2][0].score)
    view, name, faces = found[0]
    sure = [d for d in faces if d.score >= detector.min_score]
    if len(sure) > 1 and not _overlap(sure[0].box, sure[1].box):
        raise LandmarkError(f"two faces found in view {name} (scores {sure[0].score:.2f}, {sure[1].score:.2f}): "
                            "landmarks are found on one head at a time; select or export one head")
    return [(v, n, f[0]) for v, n, f in found]


def _overlap(a, b):
    w = min(a[2], b[2]) - max(a[0], b[0])
    h = min(a[3], b[3]) - max(a[1], b[1])
    return w > 0 and h > 0


def zoom(view: View, box, size=FACE_SIZE, fill=0.5) -> View:
    """A view of the same direction centred on a detected box, the box ``fill`` of the image across."""
    cx, cy = (box[0] + box[2]) / 2, (box[1] + box[3]) / 2
    s = view.size / 2
    a, b = (cx + 0.5) / s - 1, 1 - (cy + 0.5) / s
    centre = view.centre + view.half * (a * view.rotation[0] + b * view.rotation[1])
    half = view.half * max(box[2] - box[0], box[3] - box[1]) / view.size / fill
    return View(view.rotation, centre, half, size)


def frontal(template, s, R, t, turn=np.eye(3), size=FACE_SIZE) -> View:
    """A frontal view of the face whose template pose is ``(s, R, t)`` (mesh = s · template · Rᵀ + t), or one
    turned by ``turn`` (a rotation in the template's frame) about the face's middle."""
    centre = s * template.mean(0) @ R.T + t
    Rt = R @ turn
    return View.looking(Rt[:, 2], Rt[:, 1], centre, s * FRONTAL_HALF_MM, size)


def face_points(V, T, detector: Detector, view: View | Raster, img=None, normals=None):
    """The face mesh's 468 points in one view, cast onto the mesh.

    Returns points (468, 3), their triangles, their pixels (468, 2) and the
    image; points, triangles and pixels are None when the face mesh finds no face.
    """
    raster = view if isinstance(view, Raster) else rasterise(V, T, view)
    img = shade(V, T, raster, normals=normals) if img is None else img
    px = detector.mesh_points(img)
    if px is None:
        return None, None, None, img
    P, tri, _ = back_project(V, T, raster, px[:, 0], px[:, 1])
    return P, tri, px, img


def first_pass(V, T, detector: Detector, template, candidates, normals=None):
    """The face's pose from the zoomed face mesh of the first candidate that fits the template within
    :data:`GOOD_RESIDUAL_MM`, or else of the best fitting one: ``(name, score, (s, R, t), residual)``,
    or None when the face mesh finds no face.

    Each zoomed render is read in its four rolls: the detector may have found the face upside down, and the
    face mesh is only right the right way up.
    """
    best = None
    for view, name, found in candidates[:MAX_CANDIDATES]:
        raster = rasterise(V, T, zoom(view, found.box))
        img = shade(V, T, raster, normals=normals)
        readings = [detector.mesh_points_later(np.rot90(img, k)) for k in range(4)]  # each cast as the next is read
        for k, reading in enumerate(readings):
            px = reading.result()
            if px is None:
                continue
            P, _, _ = back_project(V, T, raster.rolled(k), px[:, 0], px[:, 1])
            s, R, t, residual = robust_similarity(template, P)
            if best is None or residual < best[3]:
                best = (name, found.score, (s, R, t), residual)
        if best is not None and best[3] <= GOOD_RESIDUAL_MM:
            break
    return best


def skin_triangles(V, T, tri, share=0.05):
    """Triangles of the connected parts that at least ``share`` of the cast points hit (the face's skin)."""

    labels = connected_components(len(V), T)
    hit = labels[T[tri[tri >= 0], 0]]
    parts, counts = np.unique(hit, return_counts=True)
    skin_parts = parts[counts >= share * max(len(tri), 1)]
    return np.isin(labels[T[:, 0]], skin_parts)


def on_skin(V, Ts, skin_raster: Raster, px, P_any, reach, closest):
    """Cast the pixels again onto the skin triangles ``Ts`` only (``skin_raster`` shows them alone).

    A ray may pass lashes or an eyeball in front of the skin, but not go on
    more than ``reach`` (mesh units) behind what it hit first: a ray between
    closed lips would otherwise find the inside of the back of the head. Rays
    without such a skin hit take the skin point nearest their first hit
    (``closest``, a :class:`~pdeface.geometry.ClosestPoint` on the skin).
    Returns points (468, 3) and which rays hit skin directly.
    """
    P, tri, _ = back_project(V, Ts, skin_raster, px[:, 0], px[:, 1])
    behind = np.einsum("ij,j->i", P_any - P, skin_raster.view.rotation[2])
    P[~(behind <= reach)] = np.nan
    miss = ~np.isfinite(P).all(1) & np.isfinite(P_any).all(1)
    if miss.any():
        P[miss] = closest.query(P_any[miss])[3]
    return P, np.isfinite(P).all(1) & ~miss


def frontal_readings(V, T, skin, detector: Detector, m: LandmarkMap, pose, first=None, closest=None, normals=None):
    """The face mesh's points on the skin from each frontal render (:data:`FRONTAL_TURNS`), each read as it
    is and mirrored (the mirrored reading's points renumbered by ``m.mirror``, which cancels any left-right
    bias of the face mesh). ``first``: a straight-on render's raster, image, pixels (already read) and skin
    raster (:meth:`~pdeface.landmarks.render.Raster.showing` the skin). ``closest``: a
    :class:`~pdeface.geometry.ClosestPoint` on the skin triangles, when already built; ``normals``: the mesh's
    vertex normals, for :func:`~pdeface.landmarks.render.shade`.
    Returns points (readings, 468, 3) and which rays hit skin directly (readings, 468)."""

    Ts = T[skin]
    closest = ClosestPoint(V, Ts) if closest is None else closest
    reach = SKIN_REACH_MM * pose[0]
    Ps, direct = [], []

    def cast(readings):
        for reading, r, sr, mirrored in readings:
            px = reading.result()
            if px is None:
                continue
            P_any, _, _ = back_project(V, T, r, px[:, 0], px[:, 1])
            P, hit = on_skin(V, Ts, sr, px, P_any, reach, closest)
            if mirrored:
                P, hit = P[m.mirror], hit[m.mirror]
            Ps.append(P)
            direct.append(hit)

    # Each render's readings are cast after the next render is drawn: MediaPipe reads them meanwhile.
    last = []
    for k, turn in enumerate(FRONTAL_TURNS):
        view = frontal(m.template, *pose, rotation_vector_matrix(np.radians(turn)))
        if k == 0 and first is not None:
            raster, img, px, skin_raster = first
        else:
            raster, img, px = rasterise(V, T, view, keep_fragments=True), None, None
            skin_raster = raster.showing(skin)  # the skin alone, from the same pass
        img = shade(V, T, raster, normals=normals) if img is None else img
        readings = []
        for mirrored in (False, True) if m.mirror is not None else (False,):
            r, sr = (raster.flipped(), skin_raster.flipped()) if mirrored else (raster, skin_raster)
            if px is None or mirrored:
                reading = detector.mesh_points_later(np.fliplr(img) if mirrored else img)
            else:
                reading = Future()
                reading.set_result(px)
            readings.append((reading, r, sr, mirrored))
        cast(last)
        last = readings
    cast(last)
    return np.stack(Ps), np.stack(direct)


@bounded  # numpy's small products: an OpenBLAS thread beside them only spins (issue #35; MediaPipe's are its own)
def detect(V, T, unit=None, landmark_map: LandmarkMap | None = None, detector: Detector | None = None,
           keep_images=False, verbose=False) -> FoundLandmarks:
    """Find the 68 Multi-PIE landmarks on a mesh.

    Parameters
    ----------
    V : (n, 3) array
        Vertices, any unit, any orientation; a whole body is fine.
    T : (m, 3) int array
        Triangles.
    unit : str or float, optional
        The mesh unit (a name or millimetres per unit), for the mm figures; estimated from the face's size when None.
    landmark_map : LandmarkMap, optional
        The shipped map by default.
    detector : Detector, optional
        A loaded detector to reuse (its models take ~0.1 s to load).
    keep_images : bool
        Keep the frontal render and its view (for :meth:`FoundLandmarks.marked_image`).
    verbose : bool
        Let MediaPipe's own log lines through, for a detector made here (see
        :class:`~pdeface.landmarks.detector.Detector`).

    Raises
    ------
    MissingDependencyError
        Without ``mediapipe`` 0.10.x.
    LandmarkError
        No face, two faces, or points that are not a face.
    """
    V, T = triangle_arrays(V, T)
    m = landmark_map or shipped_map()
    own = detector is None
    detector = detector or Detector(verbose=verbose)
    try:
        normals = vertex_normals(V, T)  # shade's, for every render
        candidates = search(V, T, detector, normals=normals)
        first = first_pass(V, T, detector, m.template, candidates, normals)
        if first is None:
            raise LandmarkError(f"no face found: the detector saw one in {len(candidates[:MAX_CANDIDATES])} view(s) "
                                f"(best {candidates[0][1]}, score {candidates[0][2].score:.2f}) but the face mesh "
                                "found none there. Is the face part of this mesh and open to view? Give the "
                                "landmarks by hand instead.")
        name, score, pose, _ = first
        # Frontal renders: straight on (which also finds the skin and refines the pose), then turned a little;
        # their landmarks are averaged and their spread gives the confidence.
        fview = frontal(m.template, *pose)
        raster = rasterise(V, T, fview, keep_fragments=True)  # its skin is drawn from it once found
        P_any, tri, px, img = face_points(V, T, detector, raster, normals=normals)
        if P_any is None:
            raise LandmarkError(f"the face found in view {name} was lost in its frontal render")
        s, R, t, residual = robust_similarity(m.template, P_any)
        if residual > MAX_RESIDUAL_MM:
            raise LandmarkError(f"the points found in view {name} do not make a face (RMS {residual:.1f} mm from "
                                f"the template, over {MAX_RESIDUAL_MM} mm): give the landmarks by hand")
        skin = skin_triangles(V, T, tri)
        Ts = T[skin]  # the skin's triangles, for every step below
        closest, skin_raster = ClosestPoint(V, Ts), raster.showing(skin)
        Ps, direct = frontal_readings(V, T, skin, detector, m, (s, R, t), first=(raster, img, px, skin_raster),
                                      closest=closest, normals=normals)
        P2 = np.nanmean(Ps, axis=0)
        points = snapped(V, Ts, m.apply(P2), skin_raster, 1.0 / s, closest)  # their vertices found at the end
        # The upper jaw's depth along the contour from the template, not from where a grazing ray met the cheek.
        points = upper_jaw_at_template_depth(V, Ts, points)
        # The jaw's sides where ICT's side of the face laid onto the skin puts them, where the two disagree.
        points = jaw_sides_from_template(V, Ts, points, closest)
        # The jaw's angles where the points around them say, not where a ray grazing the angle met it.
        points = jaw_angles_from_neighbours(V, Ts, points, closest)
        # The lid points on the margin's front edge, not on its curl into the socket.
        points = lids_on_margin(V, Ts, points)
        # The outer eye corners at the lateral end of the eye's opening, not on the upper lid or behind the corner
        # (before the brows: the eyes pose them).
        points = outer_corners_at_opening_end(V, Ts, points)
        # The brows where ICT's head laid onto the found eyes and nose has them, not at ICT's height above the eyes.
        points = brows_from_upper_face(V, Ts, points, closest)
        # The nasion where ICT's midline between the eyes, laid onto the skin, puts it, not at the eye centres' height.
        points = nasion_from_midline_strip(V, Ts, points, closest)
        # The eye corners out of the crease's back onto the skin in front (after the brows: moved first, the brows'
        # p95 grew 0.6 % with the brow region; with the upper face, no clear gain either way).
        points = corners_on_skin_front(V, Ts, points)
        # The inner lip corners back in the commissure, not on the lips' front.
        points = inner_lip_corners_at_seam_end(V, Ts, points)
        # The inner lip line's middles and the mouth's corners in the seam of closed lips, not on the lips' fronts.
        points = inner_lips_in_seam(V, Ts, points)
        # The mouth's corners where the seam between the lips ends, not inside it.
        points = mouth_corners_at_seam_end(V, Ts, points)
        # The inner lip corners a little in from the outer ones, not beside or lateral of them.
        points = inner_lip_corners_inset(V, Ts, points, closest)
        # The lower lip's middle points on its edge, not on the curve under it.
        points = lower_lip_on_its_edge(V, Ts, points)
        # The lower lip's inner points under the slit of parted lips, not on its top edge with the upper lip's.
        points = lower_inner_lips_under_the_slit(V, Ts, points)
        # The lower lip's sides as far below the chord from the mouth corner to its middle as ICT's, not under the lip.
        points = lower_lip_sides_at_ict_drop(V, Ts, points)
        # The upper lip's outer points on its edge (the vermilion border), not on the curve above it (after the lower
        # lip's steps: moved before them, it turns the face frame they read the mouth in, and a one-pixel slit shows).
        points = upper_lip_on_its_edge(V, Ts, points)
        # The nose's bottom at the subnasale, the profile's deepest point under the nose.
        points = nose_bottom_at_subnasale(V, Ts, points, closest)
        # The bridge's middle points at ICT's shares of the nasion-to-tip chord, not nearer the nasion.
        points = bridge_at_ict_shares(V, Ts, points)
        # The chin's point as far behind the pogonion as ICT's, not under the chin where the detector put it (last:
        # the face frame the steps above take from all the points would move with it).
        points = chin_on_profile(V, Ts, points, closest)
        indices = nearest_vertices(V, Ts, points)
        # the fit's own estimate (one for both)
        mm = parse_unit(unit)[1] if unit is not None else estimate_unit(points)[1]
        spread = group_spread(m, Ps, mm)
        direct = direct.mean(0)
        # A group as steady as on the training heads scores 1/√2 of its rays' skin hits; twice as unsteady, 1/2.
        confidence = {g: float(np.mean(direct[np.unique(m.indices[list(rows)])])
                               * 0.5 ** (spread[g] / (2 * m.spread_mm.get(g, SPREAD_MM))))
                      for g, rows in GROUPS.items()}
        images = {"frontal": img, "view": fview} if keep_images else {}
        return FoundLandmarks(points, indices, confidence, spread, score, name, residual, float(mm), skin=skin,
                              mesh_points=P2, view_points=Ps, images=images)
    finally:
        if own:  # every reading asked for is used on the way here; after an error none is waited for
            detector.close(drop_queued=True)


def find_on_mesh(mesh, unit=None, keep_images=False, verbose=False) -> FoundLandmarks:
    """:func:`detect` on a :class:`~pdeface.mesh.Mesh` (its faces split into triangles).

    Parameters
    ----------
    mesh : Mesh
        Any head or body mesh, any unit and orientation.
    unit : str or float, optional
        The mesh unit (a name or millimetres per unit), for the mm figures; estimated from the face's size when None.
    keep_images : bool
        Keep the frontal render and its view (for :meth:`FoundLandmarks.marked_image`).
    verbose : bool
        Let MediaPipe's own log lines through (see :class:`~pdeface.landmarks.detector.Detector`).

    Returns
    -------
    FoundLandmarks
    """
    return detect(mesh.vertices, mesh.triangles()[0], unit, keep_images=keep_images, verbose=verbose)


def group_spread(m: LandmarkMap, view_points, mm=1.0) -> dict:
    """Each landmark group's median spread (mm): how far its landmarks from single frontal renders
    (``view_points (views, 468, 3)``) lie at most from their mean, over the renders that saw them."""
    L = np.stack([m.apply(P) for P in view_points])  # NaN where a render's rays all missed a landmark's points
    with np.errstate(invalid="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # a landmark no render saw stays NaN
        d = np.nanmax(np.linalg.norm(L - np.nanmean(L, 0), axis=2), 0) * mm
        return {g: float(np.nanmedian(d[list(rows)])) for g, rows in GROUPS.items()}


def outer_pixels(V, T, raster: Raster, mm_per_unit, depth=None) -> np.ndarray:
    """Pixels that show the face's outer surface, not the inside of an opening (see :data:`OPENING_DEPTH_MM`).
    ``depth``: :func:`depth_map`, when already drawn."""
    depth = depth_map(V, T, raster) if depth is None else depth
    px_mm = 2 * raster.view.half / raster.view.size * mm_per_unit
    closed = closed_depth(depth, max(round(OPENING_RADIUS_MM / px_mm), 1))
    if closed is None:
        return np.zeros(depth.shape, bool)
    return np.isfinite(depth) & (depth >= closed - OPENING_DEPTH_MM / mm_per_unit)


def onto_outer_surface(V, T, raster: Raster, L, mm_per_unit, outer=None):
    """Landmarks ``L (68, 3)`` cast along the rays of ``raster``'s view through them to the first hit on the
    outer surface ``(V, T)`` (``raster`` shows ``T``). A ray into an opening (an empty eye socket, the slit
    between the lips) takes the outer surface seen at the nearest pixel instead: the lid margin, the lip's
    edge, the lip commissure, not the socket's back or the inside of the mouth.

    Returns points (68, 3), NaN for a landmark outside the image or where nothing was seen near it, and which
    landmarks lay over an opening. ``outer``: :func:`outer_pixels`, when already drawn.
    """
    from scipy.ndimage import distance_transform_edt

    outer = outer_pixels(V, T, raster, mm_per_unit) if outer is None else outer
    n = raster.view.size
    x, y, _ = raster.view.project(L)
    inside = (x > -0.5) & (x < n - 0.5) & (y > -0.5) & (y < n - 0.5)
    P, over = np.full((len(L), 3), np.nan), np.zeros(len(L), bool)
    if not inside.any() or not outer.any():
        return P, over
    _, (iy, ix) = distance_transform_edt(~outer, return_indices=True)
    xi = np.clip(np.round(x[inside]).astype(int), 0, n - 1)
    yi = np.clip(np.round(y[inside]).astype(int), 0, n - 1)
    moved = ~outer[yi, xi]
    xs, ys = x[inside].copy(), y[inside].copy()
    xs[moved], ys[moved] = ix[yi[moved], xi[moved]], iy[yi[moved], xi[moved]]
    clean = Raster(raster.view, np.where(outer, raster.tri, -1), raster.bary)
    P[inside] = back_project(V, T, clean, xs, ys, reach=1)[0]
    over[inside] = moved & (raster.tri[yi, xi] >= 0)  # the background beside a contour is no opening
    return P, over


def hidden(V, T, raster: Raster, P, outer, depth, seen=None):
    """Which points ``P`` lie over an opening (not ``outer``) or more than ``depth`` behind what every pixel
    around them shows (the inside of closed lips behind the lips); the background hides nothing.
    ``seen``: :func:`depth_map`, when already drawn."""
    n = raster.view.size
    x, y, z = raster.view.project(P)
    seen = depth_map(V, T, raster) if seen is None else seen
    xi, yi = np.round(x).astype(int), np.round(y).astype(int)
    behind = np.full(len(P), np.inf)
    for dx in (-1, 0, 1):
        for dy in (-1, 0, 1):
            px, py = np.clip(xi + dx, 0, n - 1), np.clip(yi + dy, 0, n - 1)
            behind = np.minimum(behind, np.where(np.isfinite(seen[py, px]), seen[py, px] - z, 0.0))
    xi, yi = np.clip(xi, 0, n - 1), np.clip(yi, 0, n - 1)
    return (~outer[yi, xi] & (raster.tri[yi, xi] >= 0)) | (behind > depth)


def snap(V, T, L, raster: Raster | None = None, mm_per_unit=1.0, closest: ClosestPoint | None = None):
    """Landmarks moved onto the surface ``(V, T)`` (:func:`snapped`) and the nearest vertex of it to each."""
    points = snapped(V, T, L, raster, mm_per_unit, closest)
    return points, nearest_vertices(V, T, points)


def snapped(V, T, L, raster: Raster | None = None, mm_per_unit=1.0, closest: ClosestPoint | None = None):
    """Landmarks ``L (68, 3)`` moved onto the surface ``(V, T)``.

    Each goes to the nearest surface point, as the map was fitted (on ICT's closed heads), unless it or that
    point lies over an opening seen in ``raster`` (a straight-on view showing ``T``), or that point is hidden
    there (:func:`hidden`), and cast along the ray onto the outer surface (:func:`onto_outer_surface`) it
    lands more than :data:`SNAP_AGREES_MM` away: the nearest point of an empty socket, of the slit between
    the lips or of the inside of closed lips is its wall, where the ray finds the lid margin, the lip or the
    commissure. Contours (the jawline), where a ray grazes the surface, keep the nearest point.
    ``closest``: a :class:`~pdeface.geometry.ClosestPoint` on ``(V, T)``, when already built.
    """
    points = (ClosestPoint(V, T) if closest is None else closest).query(L)[3]
    if raster is not None:
        depth = depth_map(V, T, raster)
        outer = outer_pixels(V, T, raster, mm_per_unit, depth)
        cast, over = onto_outer_surface(V, T, raster, L, mm_per_unit, outer)
        over |= hidden(V, T, raster, points, outer, OPENING_DEPTH_MM / mm_per_unit, depth)
        use = over & np.isfinite(cast).all(1)
        use[use] = np.linalg.norm(cast[use] - points[use], axis=1) * mm_per_unit > SNAP_AGREES_MM
        points[use] = cast[use]
    return points


def nearest_vertices(V, T, points) -> np.ndarray:
    """The vertex of the surface ``(V, T)`` nearest each point."""
    from scipy.spatial import cKDTree

    used = np.unique(T)
    return used[cKDTree(V[used]).query(points)[1]]
