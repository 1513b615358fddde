"""The jaw's sides, where the jawline is a contour seen edge on: their depth from ICT's generic head, then where its
side of the face laid onto the skin puts them.

The jaw points 0-3 and 13-16 lie where the side of the face turns away from the viewer. A frontal detector
places them well across (x) and in height (y), but their depth along the contour is what a ray grazing the cheek
happens to hit first. So each keeps its height and takes the depth ICT's generic head (the convention the map
follows) gives it behind the eye centres; its side then comes from the skin, the first surface met coming in from
just outside the found point at that height and depth.

Lower down (2-4, 12-14) the jaw's own depth may say otherwise: a long chin or a heavy jaw carries the lower
sides back with it. There the template's depth behind the jaw point beside the chin (6, 10; it faces the viewer,
so the detector sees its depth) counts instead, where it disagrees with the eyes' by more than ICT's own heads
ever make them (:data:`AGREE`). On MakeHuman's development set (each character annotated in ICT's convention) the
true depths of points 2-4 behind the eye centres spread 0.07-0.11 eye distances (standard deviation), behind
points 6 and 10 0.02-0.05; at the upper ends (0, 1) the eyes are the better reference (0.03-0.05 against
0.08-0.10). On ICT's heads the two agree (within 0.015) and points 4 and 12 keep the detector's depth (at the
template's, identity019's jaw came nearer ICT's own, but the fit's AU capture fell 0.003-0.009 on two heads).

The jaw angles (5, 11) keep the detector's depth: taken behind 6 and 10 as well, they come nearer the truth on
most characters, but on one stylised character the jaw then passes the gate 13.7 % of the eye distance off.

Where along the contour the sides sit (how high, how far back) the detector guesses from the face's oval, on a
render with no ear or hairline to go by: on MakeHuman's development set its heights lie 0.05-0.08 eye distances
(rms) from the truth's, whose jaw ends spread from 0.1 below to 0.2 above the eye centres (higher where the jaw's
angle lies farther back). So then (:func:`jaw_sides_from_template`), per side, ICT's generic head's side of the
face (the cheek, the jaw and its angle: more than :data:`SIDE` from the midline, :data:`BAND` about the eyes, in
front of :data:`DEPTH`) is posed and scaled by the found eye corners, nose and mouth corners, then registered
rigidly onto the skin by iterated closest points (the anchors stay in the fit, holding it to the face); ICT's jaw
points 0-4 and 12-16 carried along and taken to the nearest skin point replace the found ones where the two
disagree by more than ICT's own heads make them (:data:`DISAGREE`, faded). On the development set (offline, on
the detector's output) the jaw's median error against the registered skin points falls from 6.6 to 4.2 % of the
eye distance, against the annotated vertices from 7.4 to 6.3 % (their grain: a perfect point scores 5.3 % there).
The anchors' pose does most of it (no iterations: 4.8 and 7.0 %, unfaded); point-to-plane iterations, which slide
farther along the skin, scored 4.6-7.1 % against the skin points as the anchors' weight went from 3 to 0.3.
Unfaded, ICT's held-out heads' AU capture fell 0.016 on one (their found jaw points, trained on ICT, are nearer
their own than the generic head's sides laid onto them).

The jaw's angles (5, 11) last (:func:`jaw_angles_from_neighbours`): a frontal detector sees the angle edge on, where
the lower border turns up into the ramus, so its depth (and with it how far back along the contour it lies) is the
grazing ray's guess: on the development set the found angles lay a median 0.06 eye distances too far forward (up to
0.22), the worst of the jaw's points against the registered skin points (6.5/7.2 %). The points around each angle
are seen better: up the ramus (2-4, after the steps above) and along the lower border to the chin (6-8, facing the
viewer). Where the lines through them meet is the angle, so ICT's generic head's six points, laid onto those six by
a similarity, carry its own angle there, taken to the nearest skin point, wherever that and the found one disagree by
more than ICT's heads make them (:data:`ANGLE_DISAGREE`, faded). Development set, angles against the skin points
6.5/7.2 -> 3.9/3.9 % (with the skin points themselves as the six: 2.6); fewer points (4 and 6 alone) left the
border's line unsaid and scored 9.3/8.4.

The chin last (:func:`chin_on_profile`): the detector put MakeHuman's chin point (8) low, on the chin's underside
(a median 0.04 eye distances below and 0.04 behind the registered skin point). Seen straight on, down the profile
from the fold under the lower lip, the pogonion is the forward-most point, and ICT's chin point lies 0.089 eye
distances behind it (its identities 0.072-0.101, MakeHuman's true ones 0.05-0.10, the found ones up to 0.23): 8 goes
there, and the chin's sides (7, 9) where ICT's points around them (the angles, 6, 10 and the new 8) carry them;
the points beside the chin (6, 10) too, where a slip along the jawline left one far from where the angle and the
chin's points on its side carry it (:data:`BESIDE_CHIN`).
Development set: the chin's points against the skin points 4.6/5.4/4.5 -> 2.6/2.3/2.9 %, the jaw median against the
vertices 6.2 -> 6.0 %. On their own slices 7 and 9 have no such mark (ICT's own lie 0.045-0.079 behind the
slice's forward-most point).
"""
from __future__ import annotations

from functools import lru_cache

import numpy as np

from ..assets import generic_head_geometry
from ..geometry import ClosestPoint, ray_triangle, similarity, smoothstep
from ..landmark_scheme import eye_distance
from ..mesh import connected_components
from ..surface.frame import face_frame
from .register import carried, ict_landmarks, settle_on_skin
from .render import View, back_project, column_depths

#: The jaw points taken to the template's depth behind the eyes. The chin's (6-10) face the viewer, their ray hits
#: them squarely; the angles (5, 11) keep the detector's depth (see the module's docstring).
UPPER_JAW = (0, 1, 2, 3, 13, 14, 15, 16)
#: The lower sides, each with the jaw point beside the chin on its side whose depth may count instead (points 4
#: and 12 are moved only then).
BEHIND_CHIN = {2: 6, 3: 6, 4: 6, 12: 10, 13: 10, 14: 10}
#: How far (eye distances) the depths behind the eyes and behind the chin's point may disagree before the chin's
#: begins to count, and where it counts alone (ICT's held-out heads: at most 0.015; MakeHuman's characters: a
#: median 0.08).
AGREE = (0.02, 0.04)
#: How far outside the found point (eye distances) the ray into the side of the face starts, and how far in from
#: there it may meet the skin; met nowhere, the point stays.
OUTSIDE, REACH = 0.2, 0.4


def template_depths(template68) -> np.ndarray:
    """How far behind the eye centres each landmark of ``template68 (68, 3)`` lies (eye distances)."""
    f = face_frame(template68)
    F = f.to_face(template68) / (eye_distance(template68) * f.scale)
    return F[36:48, 2].mean() - F[:, 2]


def upper_jaw_at_template_depth(V, T, points, template68=None) -> np.ndarray:
    """``points (68, 3)`` with the jaw's sides at the template's depth behind the eyes (:data:`UPPER_JAW`), or for
    the lower ones (:data:`BEHIND_CHIN`) behind the jaw point beside the chin where the two disagree
    (:data:`AGREE`), on the skin ``(V, T)`` at their own height (see the module's docstring).

    Parameters
    ----------
    V, T : arrays
        The mesh and the skin's triangles.
    points : (68, 3) array
        Landmarks on the skin, the mesh's space.
    template68 : (68, 3) array, optional
        The landmarks whose depths are taken; by default ICT's generic head's own (the convention the map
        follows; the map's 468-point template mapped lies up to 0.05 eye distances off them at the jaw's ends,
        which cost the fit 0.01-0.02 of AU capture on ICT's held-out heads).
    """
    out = np.array(points, np.float64)
    f = face_frame(out)
    eyes = eye_distance(out) * f.scale
    F = f.to_face(out)
    behind = template_depths(ict_landmarks() if template68 is None else template68) * eyes
    behind_eyes = F[36:48, 2].mean() - behind
    depth = F[:, 2].copy()
    depth[list(UPPER_JAW)] = behind_eyes[list(UPPER_JAW)]
    rows = list(UPPER_JAW)
    for j, ref in BEHIND_CHIN.items():
        behind_chin = F[ref, 2] - (behind[j] - behind[ref])
        w = smoothstep((abs(behind_chin - behind_eyes[j]) / eyes - AGREE[0]) / (AGREE[1] - AGREE[0]))
        depth[j] += w * (behind_chin - depth[j])
        if w > 0 and j not in rows:
            rows.append(j)
    FV = f.to_face(np.asarray(V, np.float64))
    T = np.asarray(T)
    # Only the triangles with a corner in the band of heights and depths the rays pass (a triangle reaching into
    # it from outside has a corner within an edge of it: the band is widened by the longest edge).
    edge = max(np.linalg.norm(FV[T[:, a]] - FV[T[:, b]], axis=1).max() for a, b in ((0, 1), (1, 2), (2, 0)))
    lo_b = np.array([F[rows, 1].min(), depth[rows].min()]) - edge
    hi_b = np.array([F[rows, 1].max(), depth[rows].max()]) + edge
    inside = ((FV[:, 1:] >= lo_b) & (FV[:, 1:] <= hi_b)).all(1)
    tri = FV[T[inside[T].any(1)]]
    lo = np.minimum(np.minimum(tri[:, 0], tri[:, 1]), tri[:, 2])
    hi = np.maximum(np.maximum(tri[:, 0], tri[:, 1]), tri[:, 2])
    for j in rows:
        side = np.sign(F[j, 0])
        y, z = F[j, 1], depth[j]
        near = (lo[:, 1] <= y) & (hi[:, 1] >= y) & (lo[:, 2] <= z) & (hi[:, 2] >= z) & (side * hi[:, 0] > 0)
        if not near.any():
            continue
        x0 = side * (abs(F[j, 0]) + OUTSIDE * eyes)
        k = int(near.sum())
        hit, _, _, t = ray_triangle(np.tile([x0, y, z], (k, 1)), np.tile([-side, 0.0, 0.0], (k, 1)),
                                    tri[near, 0], tri[near, 1], tri[near, 2])
        t = np.where(hit, t, np.inf).min()
        if t <= (OUTSIDE + REACH) * eyes:
            out[j] = f.to_user(np.array([[x0 - side * t, y, z]]))[0]
    return out


#: The jaw points placed, per side (the subject's right side first, as ICT numbers them: 0-4, then 16-12).
SIDES = ((0, 1, 2, 3, 4), (16, 15, 14, 13, 12))
#: ICT's side of the face: farther than ``SIDE`` from the midline, heights ``BAND`` about the eye centres, in front
#: of ``DEPTH`` behind them (eye distances; its jaw ends lie 0.84-0.89 behind the eyes, the chin 1.6-1.7 below).
#: Nearer the midline the nose and the chin's middle would hold the side to the face's front (on the development set
#: 0.45 and 0.6 scored 4.8 and 4.7 % against the skin points, 0.2-0.3 4.5-4.6 %).
SIDE, BAND, DEPTH = 0.3, (-1.9, 0.4), 1.0
#: The found landmarks that pose each side and stay in its fit: the eye corners, the nose's tip and bottom, the
#: mouth's corners.
ANCHORS = (36, 39, 42, 45, 30, 33, 48, 54)
#: At most this many of a side's vertices take part (evenly spread by their numbering).
MAX_POINTS = 600
#: How far (eye distances) a found side point and the registered one may lie apart before the registered one begins
#: to count, and where it counts alone: ICT's held-out heads' own jaw points lie a median 0.003-0.009 from the
#: generic head's sides laid onto them, MakeHuman's found ones a median 0.07 (0.02-0.04 and 0.04-0.08 scored alike).
DISAGREE = (0.03, 0.06)


@lru_cache(maxsize=1)
def _ict_sides() -> tuple[tuple[np.ndarray, np.ndarray], np.ndarray]:
    """ICT's generic head: its two sides of the face (the skin's vertices, :data:`SIDE`, :data:`BAND`,
    :data:`DEPTH`; not the eyeballs, lashes or mouth's inside, separate parts), in :data:`SIDES`' order, and its 68
    landmarks."""
    V, T, landmarks = generic_head_geometry()
    L = V[landmarks]
    f = face_frame(L)
    F = (f.to_face(V) - f.to_face(L[36:48]).mean(0)) / (eye_distance(L) * f.scale)
    labels = connected_components(len(V), T)
    skin = np.zeros(len(V), bool)
    skin[np.unique(T)] = True
    skin &= np.isin(labels, labels[landmarks]) & (F[:, 1] > BAND[0]) & (F[:, 1] < BAND[1]) & (F[:, 2] > -DEPTH)
    sides = []
    for rows in SIDES:
        side = np.sign(F[landmarks[rows[0]], 0])
        P = V[skin & (side * F[:, 0] > SIDE)]
        sides.append(P[:: max(1, len(P) // MAX_POINTS)])
    return tuple(sides), L


def jaw_sides_from_template(V, T, points, closest: ClosestPoint | None = None) -> np.ndarray:
    """``points (68, 3)`` with the jaw's sides (:data:`SIDES`) where ICT's generic head puts them once each side of
    its face is registered onto the skin ``(V, T)``, where that and the found ones disagree (:data:`DISAGREE`; see
    the module's docstring).

    Parameters
    ----------
    V, T : arrays
        The mesh and the skin's triangles.
    points : (68, 3) array
        Landmarks on the skin, the mesh's space (the eye corners, nose and mouth corners are trusted).
    closest : ClosestPoint, optional
        On ``(V, T)``, when already built.
    """
    out = np.array(points, np.float64)
    sides, L = _ict_sides()
    anchors = list(ANCHORS)
    closest = ClosestPoint(V, T) if closest is None else closest
    s, R0, t0 = similarity(L[anchors], out[anchors])
    for rows, region in zip(SIDES, sides):
        R, t = settle_on_skin(closest, region, L[anchors], out[anchors], (s, R0, t0), eye_distance(out))
        rows = list(rows)
        registered = closest.query(s * L[rows] @ R.T + t)[3]
        gap = np.linalg.norm(registered - out[rows], axis=1) / eye_distance(out)
        w = smoothstep((gap - DISAGREE[0]) / (DISAGREE[1] - DISAGREE[0]))[:, None]
        out[rows] = np.where(w > 0, closest.query(out[rows] + w * (registered - out[rows]))[3], out[rows])
    return out


#: Each jaw angle and the jaw points around it on its side: up the ramus, then along the lower border to the chin.
ANGLES = {5: (2, 3, 4, 6, 7, 8), 11: (14, 13, 12, 10, 9, 8)}
#: How far (eye distances) the found angle and the one its neighbours place may lie apart before the placed one
#: begins to count, and where it counts alone: on ICT's 21 heads their own neighbours place their own angles within
#: 0.005; MakeHuman's found angles lie 0.01-0.2 from where their neighbours place them (median 0.04).
ANGLE_DISAGREE = (0.01, 0.02)


def jaw_angles_from_neighbours(V, T, points, closest: ClosestPoint | None = None) -> np.ndarray:
    """``points (68, 3)`` with the jaw's angles (5, 11) where ICT's generic head's angle lands once its points around
    it (:data:`ANGLES`) are laid onto the found ones by a similarity, on the skin ``(V, T)``, where that and the found
    one disagree (:data:`ANGLE_DISAGREE`; see the module's docstring).

    Parameters
    ----------
    V, T : arrays
        The mesh and the skin's triangles.
    points : (68, 3) array
        Landmarks on the skin, the mesh's space (the jaw's sides and the chin's points are trusted).
    closest : ClosestPoint, optional
        On ``(V, T)``, when already built.
    """
    out = np.array(points, np.float64)
    closest = ClosestPoint(V, T) if closest is None else closest
    for j, around in ANGLES.items():
        out[[j]] = _towards(out, [j], carried(out, [j], around, closest), ANGLE_DISAGREE, closest)
    return out


def _towards(points, rows, placed, disagree, closest: ClosestPoint) -> np.ndarray:
    """``points[rows]`` moved to ``placed`` on the skin where the two lie more than ``disagree[1]`` eye distances
    apart, part of the way from ``disagree[0]`` (faded), kept where nearer."""
    out = np.array(points[rows], np.float64)
    gap = np.linalg.norm(placed - out, axis=1) / eye_distance(points)
    w = smoothstep((gap - disagree[0]) / (disagree[1] - disagree[0]))[:, None]
    moved = w[:, 0] > 0
    if moved.any():
        out[moved] = closest.query(out[moved] + w[moved] * (placed[moved] - out[moved]))[3]
    return out


#: The chin's point (the menton, 8), the lower lip's bottom (57) above it, and the points its sides (7, 9) are
#: carried by: the angles, the points beside the chin and the chin's own.
CHIN, LOWER_LIP, AROUND_CHIN = 8, 57, (5, 6, 8, 10, 11)
#: How far below the found chin point the profile is read (eye distances): room for a chin point found high (the
#: true ones lie 0.05-0.26 below the pogonion); below the chin's silhouette the profile is the neck's (:data:`NECK_STEP`).
BELOW_CHIN = 0.25
#: A step down the profile farther back than this (eye distances) has left the chin for the neck behind it.
NECK_STEP = 0.03
#: Pixels across the straight-on view of the chin, and its half-width (eye distances).
SIZE, HALF = 384, 0.6
#: How far (eye distances) the found chin points and the placed ones may lie apart before the placed ones begin to
#: count, and where they count alone (as the angles').
CHIN_DISAGREE = (0.01, 0.02)
#: The points beside the chin (6, 10), each carried by the angle and the chin's points on its side where it lies
#: farther from there than :data:`BESIDE_DISAGREE` (eye distances, faded): they face the viewer and are mostly found
#: well (on ICT's 21 heads their own lie within 0.004 of where theirs carry them, MakeHuman's found ones a median
#: 0.015, up to 0.047), but a detector's slip along the jawline leaves one 0.05 off and takes the chin's sides with it.
BESIDE_CHIN = {6: (5, 7, 8), 10: (11, 9, 8)}
BESIDE_DISAGREE = (0.03, 0.06)


def _chin_profile(V, T, points):
    """The skin's straight-on profile down the chin's column of ``(V, T)``: ``(P, behind, eyes)``, the profile's
    points (k, 3) from the pogonion down, how far each lies behind the pogonion (eye distances) and the eye
    distance; None where the profile is not seen whole.

    The pogonion is the profile's forward-most point below the fold under the lower lip (the deepest point of the
    profile's upper half between the lower lip's bottom, 57, and the found chin point, 8)."""
    out = np.asarray(points, np.float64)
    f = face_frame(out)
    eyes = eye_distance(out)
    view = View.looking(f.rotation[2], f.rotation[1], out[[LOWER_LIP, CHIN]].mean(0), HALF * eyes, SIZE)
    x, y, _ = view.project(out)
    c = view.nearest_pixel(x[CHIN])
    top = view.nearest_pixel(y[LOWER_LIP])
    bottom = view.nearest_pixel(y[CHIN] + BELOW_CHIN * eyes / view.pixel)
    if bottom - top < 6:
        return None
    raster, depth = column_depths(V, T, view, c, rows=(top, bottom))
    d = depth[top:bottom + 1, c] / eyes
    middle = view.nearest_pixel((y[LOWER_LIP] + y[CHIN]) / 2) - top
    if not np.isfinite(d[:middle + 1]).all() or middle < 1:
        return None
    fold = int(np.argmin(d[:middle + 1]))
    below = np.where(np.isfinite(d[fold:]), d[fold:], -np.inf)
    pog = fold + int(np.argmax(below))
    rows = np.arange(pog, len(d))
    rows = rows[: np.argmax(~np.isfinite(d[rows])) or len(rows)]  # down to the profile's end, if it ends
    P = back_project(V, T, raster, np.full(len(rows), float(c)), (top + rows).astype(np.float64), reach=1)[0]
    return P, d[pog] - d[rows], eyes


#: How far ICT's generic head's chin point (8) lies behind its pogonion (eye distances; :func:`ict_chin_behind_pogonion`
#: measures it, a test holds the two together: measured in each process it cost the first head 0.05-0.15 s).
CHIN_BEHIND_POGONION = 0.0886


def ict_chin_behind_pogonion() -> float:
    """How far ICT's generic head's chin point (8) lies behind its pogonion on its straight-on profile (eye
    distances, :func:`_chin_profile`: 0.0886; its 20 identities' 0.072-0.101, median 0.087)."""
    V, T, landmarks = generic_head_geometry()
    L = V[landmarks]
    P, behind, eyes = _chin_profile(V, T, L)
    f = face_frame(L)
    return float(behind[0] + (P[0] - L[CHIN]) @ f.rotation[2] / eyes)


def chin_on_profile(V, T, points, closest: ClosestPoint | None = None) -> np.ndarray:
    """``points (68, 3)`` with the chin's point (8) on the skin ``(V, T)``'s straight-on profile as far behind the
    pogonion as ICT's (:data:`CHIN_BEHIND_POGONION`), and the chin's sides (7, 9) where ICT's, carried by the
    points around them (:data:`AROUND_CHIN`), land, where those and the found ones disagree (:data:`CHIN_DISAGREE`,
    faded); the points beside the chin (:data:`BESIDE_CHIN`) likewise where they lie far off (:data:`BESIDE_DISAGREE`),
    then 7 and 9 again (see the module's docstring).

    Parameters
    ----------
    V, T : arrays
        The mesh and the skin's triangles.
    points : (68, 3) array
        Landmarks on the skin, the mesh's space (the lower lip's bottom, the jaw's angles and the points beside the
        chin are trusted).
    closest : ClosestPoint, optional
        On ``(V, T)``, when already built.
    """
    out = np.array(points, np.float64)
    profile = _chin_profile(V, T, out)
    if profile is None:
        return out
    P, behind, _ = profile
    want = CHIN_BEHIND_POGONION
    k = int(np.argmax(behind >= want))  # the first row down from the pogonion that far back
    if behind[k] < want or k == 0:
        return out
    closest = ClosestPoint(V, T) if closest is None else closest
    if behind[k] - behind[k - 1] > NECK_STEP:  # the chin's silhouette passed: its last row
        placed = P[k - 1]
    else:
        w = (want - behind[k - 1]) / (behind[k] - behind[k - 1])
        placed = P[k - 1] + w * (P[k] - P[k - 1])
    out[[CHIN]] = _towards(out, [CHIN], placed[None], CHIN_DISAGREE, closest)
    sides = [7, 9]
    out[sides] = _towards(out, sides, carried(out, sides, AROUND_CHIN, closest), CHIN_DISAGREE, closest)
    beside = out[list(BESIDE_CHIN)]
    for j, around in BESIDE_CHIN.items():
        out[[j]] = _towards(out, [j], carried(out, [j], around, closest), BESIDE_DISAGREE, closest)
    if not np.array_equal(out[list(BESIDE_CHIN)], beside):  # the chin's sides again, by the points beside it moved
        out[sides] = _towards(out, sides, carried(out, sides, AROUND_CHIN, closest), CHIN_DISAGREE, closest)
    return out
