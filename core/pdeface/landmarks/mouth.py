"""The inner lip corners (60, 64), where the lips' inner surfaces meet: the deepest point of the lip line.

The map places the inner lip corners from the face mesh's points on the lips' front; on MakeHuman's development
set they land 0.04-0.10 eye distances in front of the true corners (the commissure, where the upper and the lower
lip's inner surfaces meet, lies in the crease behind). Seen straight on, the lip line from each inner corner out to
its outer corner (48, 54) is a groove that deepens into the commissure: each inner corner moves to the deepest
point of that line (from a little inside the found corner out to the outer one), as long as it lies no more than
:data:`REACH` behind the found corner (deeper, the line crosses an opening: the slit of parted lips, the mouth).
A corner with nothing seen more than :data:`DEEPER` deeper stays: on ICT's heads the found corners already lie in the
crease (the true ones often hidden behind the lips' fronts). On the development set the inner corners' error falls
from 8.5 to 5.6 % of the eye distance (median over the characters; better on 18, worse on 1); ICT's stay.

The module also holds the other steps on the lips, each with its own docstring, run in this order after the one
above: :func:`inner_lips_in_seam` (the inner lip line's middles and the mouth corners into the seam of closed
lips), :func:`mouth_corners_at_seam_end` (the mouth corners where the seam ends) and
:func:`inner_lip_corners_inset` (inner corners beside or lateral of the outer ones, 0.05 in from them) and
:func:`lower_lip_on_its_edge` (the lower lip's middle points up onto its edge from the curve under it) and
:func:`lower_inner_lips_under_the_slit` (the lower lip's inner points under the slit of parted lips), then
:func:`lower_lip_sides_at_ict_drop` (the lower lip's sides up from under the lip to ICT's drop below the chord) and
:func:`upper_lip_on_its_edge` (the upper lip's outer points down onto its edge from the curve above it).
:data:`REACH` and :data:`DEEPER` serve the first two as well.
"""
from __future__ import annotations

from functools import lru_cache

import numpy as np

from ..geometry import ClosestPoint
from ..landmark_scheme import LIP_LOWER_BOTTOM, MOUTH_CORNER_LEFT, MOUTH_CORNER_RIGHT, eye_distance
from ..surface.frame import face_frame
from .register import ict_landmarks
from .render import View, back_project, column_depths, depth_map, pixel_boxes, rasterise

#: Each inner corner and its outer corner.
CORNERS = ((60, 48), (64, 54))
#: How far inwards (towards the lips' middle) of the found inner corner the line starts (eye distances).
INSIDE = 0.02
#: How far behind the found inner corner (eye distances) the line's deepest point may lie.
REACH = 0.06
#: How much deeper than the found inner corner (eye distances) the line's deepest point must lie for the corner to
#: move: on ICT's heads (the map's own) the found corners lie 0-0.016 in front of it, and moving them there puts
#: some 0.04 eye distances to the side; on MakeHuman's characters 0.02-0.06.
DEEPER = 0.02
#: Pixels across the straight-on mouth view, and its half-width (eye distances): about 0.005 eye distances a pixel.
SIZE, HALF = 384, 1.0


def _mouth_view(points):
    """``(eye distance, view)``: the mouth seen straight on (the face frame's front), :data:`HALF` eye distances
    each way from the mouth's landmarks' centre, :data:`SIZE` pixels across."""
    R = face_frame(points).rotation
    eyes = eye_distance(points)
    return eyes, View.looking(R[2], R[1], points[48:68].mean(0), HALF * eyes, SIZE)


def inner_lip_corners_at_seam_end(V, T, points) -> np.ndarray:
    """``points (68, 3)`` with the inner lip corners (:data:`CORNERS`) moved to the deepest point of the lip line
    on the skin ``(V, T)`` (see the module's docstring); a corner stays where no pixel of the line is seen
    :data:`DEEPER` deeper.

    Parameters
    ----------
    V, T : arrays
        The mesh and the skin's triangles.
    points : (68, 3) array
        Landmarks on the skin, the mesh's space.
    """
    out = np.array(points, np.float64)
    eyes, view = _mouth_view(out)
    x, y, z = view.project(out)
    px = view.pixel
    yy, xx = np.mgrid[:SIZE, :SIZE]
    lines = {}
    for inner, outer in CORNERS:
        a, b = np.array([x[inner], y[inner]]), np.array([x[outer], y[outer]])
        length = float(np.linalg.norm(b - a))
        if length == 0:
            continue
        u = (b - a) / length
        along = (xx - a[0]) * u[0] + (yy - a[1]) * u[1]
        across = np.abs((yy - a[1]) * u[0] - (xx - a[0]) * u[1])
        lines[inner] = (along >= -INSIDE * eyes / px) & (along <= length) & (across <= 1.0)
    if not lines:
        return out
    raster = rasterise(V, T, view, near=np.logical_or.reduce(list(lines.values())))
    depth = depth_map(V, T, raster)
    for inner, line in lines.items():
        d = np.where(line & (depth >= z[inner] - REACH * eyes), depth, np.inf)
        k = int(np.argmin(d))
        if not d.flat[k] < z[inner] - DEEPER * eyes:
            continue  # the corner is in the crease already (or hidden behind the lips, as ICT's)
        P = back_project(V, T, raster, np.array([k % SIZE], float), np.array([k // SIZE], float), reach=1)[0][0]
        if np.isfinite(P).all():
            out[inner] = P
    return out


#: The inner lip line's middle points: the upper lip's (61-63) and the lower lip's (65-67).
INNER_MIDDLES = (61, 62, 63, 65, 66, 67)
#: The mouth's (outer) corners: in the seam's column too (both families' true corners lie at its deepest point).
OUTER_CORNERS = (48, 54)
#: How far up and down (eye distances) of a found inner lip point its column is searched for the seam.
SEAM_REACH = 0.04


def inner_lips_in_seam(V, T, points) -> np.ndarray:
    """``points (68, 3)`` with the inner lip line's middle points (:data:`INNER_MIDDLES`) and the mouth's corners
    (:data:`OUTER_CORNERS`) moved to the seam of closed lips: the deepest point of their column, seen straight on,
    within :data:`SEAM_REACH` up and down. A point stays where that column shows an opening (anything more than
    :data:`REACH` behind the found point: a slit between the lips, as on ICT's heads, parted lips, the mouth) or
    nothing :data:`DEEPER` deeper.

    The face mesh's inner lip points lie on the lips' fronts, in front of the seam where the lips meet and where
    ICT's convention puts them (on the development set a median 0.02 eye distances in front). There the middles'
    error against the registered skin points falls from 3.6-4.3 to 2.3-3.1 % of the eye distance (median over
    the characters; better on 15 characters, worse on 3). The seam's bottom lies a little deeper and lower than
    the upper lip's registered middles, and where a slit opens between the lips the convention differs (ICT puts
    the middles on the lips' fronts, the development set on the slit's walls): those columns keep their points,
    so on ICT's held-out heads no point moves. The mouth's corners, found 0.02-0.03 eye distances above and in
    front of the commissure, come down into it (48 and 54: from 3.6 and 5.4 to 2.8 and 4.1 %).

    Parameters
    ----------
    V, T : arrays
        The mesh and the skin's triangles.
    points : (68, 3) array
        Landmarks on the skin, the mesh's space.
    """
    out = np.array(points, np.float64)
    eyes, view = _mouth_view(out)
    x, y, z = view.project(out)
    px = view.pixel
    reach = round(SEAM_REACH * eyes / px)
    cols = {j: view.nearest_pixel(x[j]) for j in (*OUTER_CORNERS, *INNER_MIDDLES)}
    r0s = [view.nearest_pixel(y[j]) for j in cols]  # searched within reach, back_project a row more
    raster, depth = column_depths(V, T, view, list(cols.values()), (min(r0s) - reach - 1, max(r0s) + reach + 1))
    for j, c in cols.items():
        r0 = view.nearest_pixel(y[j])
        rows = np.arange(max(r0 - reach, 0), min(r0 + reach, SIZE - 1) + 1)
        d = depth[rows, c]
        if not (d >= z[j] - REACH * eyes).all():
            continue  # an opening in the column: a slit between the lips (ICT's), parted lips, no seam to find
        k = int(np.argmin(d))
        if not d[k] < z[j] - DEEPER * eyes:
            continue
        P = back_project(V, T, raster, np.array([float(c)]), np.array([float(rows[k])]), reach=1)[0][0]
        if np.isfinite(P).all():
            out[j] = P
    return out


#: How far (eye distances) in from its outer corner an inner lip corner lies, seen straight on: ICT's 21 heads
#: 0.048-0.051, MakeHuman's 24 characters (registered) 0.030-0.072; and how far behind the outer corner (ICT's
#: 0.005-0.013).
INSET, INSET_BEHIND = 0.05, 0.01
#: The insets a found inner corner may have and stay: outside them it is no inner corner (the map's corner
#: lateral of the outer one, or the seam's end found in the commissure, at the outer corner itself).
INSET_RANGE = (0.02, 0.09)
#: How far (eye distances) in front of its outer corner a found inner corner may lie and stay: true ones lie from
#: 0.013 to 0.005 behind it (ICT's 21 heads) and from 0.032 behind to 0.018 in front (MakeHuman's 24 characters);
#: the face mesh's corners left on the lips' front, where the commissure's groove is too shallow for
#: :func:`inner_lip_corners_at_seam_end`, 0.028-0.095 in front (and up to 0.07 above).
INSET_FRONT = 0.025


def inner_lip_corners_inset(V, T, points, closest: ClosestPoint | None = None) -> np.ndarray:
    """``points (68, 3)`` with each inner lip corner (:data:`CORNERS`) whose inset from its outer corner, across the
    face, lies outside :data:`INSET_RANGE` put :data:`INSET` in from the outer corner (at its own height,
    :data:`INSET_BEHIND` behind), on the nearest skin point; and each lying more than :data:`INSET_FRONT` in front of
    its outer corner put there as well, at the outer corner's height (its own is the lips' front's).

    On the development set the found inner corners lie from 0.08 eye distances lateral of their outer corners to
    0.11 in from them (the truth: 0.03-0.07); the worst (15-19 % of the eye distance off) are corners the map put
    lateral of the outer one. The corners found in front (6, on 5 characters) go from a median 8.2 to 2.1 % of the
    eye distance from the registered skin points (game-unit's 60: 15.1 to 2.8; better on all 6). On ICT's held-out
    heads no corner moves.

    Parameters
    ----------
    V, T : arrays
        The mesh and the skin's triangles.
    points : (68, 3) array
        Landmarks on the skin, the mesh's space (the outer corners are trusted).
    closest : ClosestPoint, optional
        On ``(V, T)``, when already built.
    """
    out = np.array(points, np.float64)
    R = face_frame(out).rotation
    eyes = eye_distance(out)
    for (inner, outer), side in zip(CORNERS, (1, -1)):  # 48 on the face's -x side: its inner corner at larger x
        inset = side * (out[inner] - out[outer]) @ R[0] / eyes
        in_front = (out[inner] - out[outer]) @ R[2] > INSET_FRONT * eyes
        if INSET_RANGE[0] <= inset <= INSET_RANGE[1] and not in_front:
            continue
        closest = ClosestPoint(V, T) if closest is None else closest
        height = 0.0 if in_front else (out[inner] - out[outer]) @ R[1]
        out[inner] = closest.query((out[outer] + eyes * (side * INSET * R[0] - INSET_BEHIND * R[2])
                                    + height * R[1])[None])[3][0]
    return out


#: How far (eye distances) either way along the lip line a mouth's corner is looked for, from the found one.
CORNER_REACH = 0.10
#: The seam is a groove where its deepest point lies :data:`GROOVE` (eye distances) behind the lips
#: :data:`GROOVE_WIDE` above and below it.
GROOVE, GROOVE_WIDE = 0.004, 0.02
#: A corner moves only this far (eye distances) or more along the line: ICT's true corners lie 0.01-0.015 in from
#: where their shallow groove fades.
CORNER_MOVE = 0.02


def _groove_end(depth, c, r, side, reach, wide, groove, opening):
    """Column and row of the lip seam's lateral end (``side``: +1 towards larger columns) near the corner at
    ``(c, r)``: the seam's deepest row followed column by column from ``reach`` columns inside to ``reach`` outside,
    a row at a time; its end is the last column from ``c`` outwards where it is still a groove (or, where ``c`` is
    beyond the groove, the first such column inwards), and where a slit between the lips shows the mouth's inside
    there (a groove deeper than ``opening``), the first column outwards where the slit has closed. None where the
    seam leaves the picture or the slit does not close within ``reach``."""
    n = depth.shape[0]
    seam, rows = [], np.arange(r - 3, r + 4)
    for k in range(-reach, reach + 1):
        cc = c + side * k
        if not (0 <= cc < n and rows.min() - wide >= 0 and rows.max() + wide < n):
            return None
        rr = int(rows[np.argmin(depth[rows, cc])])
        deep = min(depth[rr - wide, cc], depth[rr + wide, cc]) - depth[rr, cc]
        seam.append((k, rr, deep > groove, deep <= opening))
        rows = np.arange(rr - 1, rr + 2)
    end = None
    for i in range(reach, len(seam)):  # outwards from the found corner
        if not seam[i][2]:
            break
        end = i
    if end is None:
        end = next((i for i in range(reach - 1, -1, -1) if seam[i][2]), None)
    while end is not None and not seam[end][3]:  # the slit's inside: out to where the lips meet
        end = end + 1 if end + 1 < len(seam) else None
    return None if end is None else (c + side * seam[end][0], seam[end][1])


def mouth_corners_at_seam_end(V, T, points) -> np.ndarray:
    """``points (68, 3)`` with the mouth's corners (48, 54) at the lateral end of the seam between the lips, seen
    straight on: the seam's deepest point followed along the lip line out from each found corner (or back in) as
    long as it is a groove (:data:`GROOVE`), within :data:`CORNER_REACH`; where a slit between the lips shows
    the mouth's inside there (the seam more than :data:`REACH` behind the lips), out to where the lips meet. A corner
    stays where it would move less than :data:`CORNER_MOVE`, or where no such end is found (or its point lies
    farther than 1.5 :data:`CORNER_REACH`: the mouth's inside seen between parted lips).

    The map puts the mouth's corners up to 0.13 eye distances inside the commissure on MakeHuman's development
    set (54 more than 48); the commissure is where the seam between closed lips ends.

    Parameters
    ----------
    V, T : arrays
        The mesh and the skin's triangles.
    points : (68, 3) array
        Landmarks on the skin, the mesh's space.
    """
    out = np.array(points, np.float64)
    eyes, view = _mouth_view(out)
    x, y, _ = view.project(out)
    px = view.pixel
    reach, wide = round(CORNER_REACH * eyes / px), max(1, round(GROOVE_WIDE * eyes / px))
    near = pixel_boxes(SIZE, [(c - reach - 1, c + reach + 1, r - 2 * reach - wide, r + 2 * reach + wide)
                              for c, r in (map(int, np.round((x[j], y[j]))) for j in OUTER_CORNERS)])
    raster = rasterise(V, T, view, near=near)
    depth = depth_map(V, T, raster)
    for j, side in zip(OUTER_CORNERS, (-1, 1)):  # 48 towards smaller columns (the view's x is the face's)
        c, r = int(np.round(x[j])), int(np.round(y[j]))
        end = _groove_end(depth, c, r, side, reach, wide, GROOVE * eyes, REACH * eyes)
        if end is None or abs(end[0] - c) * px < CORNER_MOVE * eyes:
            continue
        P = back_project(V, T, raster, np.array([float(end[0])]), np.array([float(end[1])]), reach=1)[0][0]
        if np.isfinite(P).all() and np.linalg.norm(P - out[j]) <= 1.5 * CORNER_REACH * eyes:  # not the mouth's inside
            out[j] = P
    return out


#: The lower lip's outer middle points, each with the inner lip point above it (where its column's seam is).
LOWER_LIP = {56: 65, 57: 66, 58: 67}
#: How far (eye distances) behind the lower lip's front, in its column seen straight on, its middle points lie:
#: ICT's 21 heads 0.005-0.010 (56, 58) and 0.009-0.014 (57); MakeHuman's registered points 0.003-0.022.
LIP_EDGE_BEHIND = 0.01
#: A lower lip point this far (eye distances) or more behind its column's lip front is on the curve under the lip.
LIP_CURVE_BEHIND = 0.02
#: The upper lip's outer points (49-53), each with the inner lip point below it (where its column's seam is).
UPPER_LIP = {49: 61, 50: 61, 51: 62, 52: 63, 53: 63}
#: How far (eye distances) behind the upper lip's front, in its column seen straight on, its outer points lie: ICT's
#: 21 heads 0-0.005 (51 0.0016-0.0052, the others within 0.0014); MakeHuman's registered points 0-0.014 (median
#: 0.001-0.005).
UPPER_LIP_EDGE_BEHIND = 0.002
#: An upper lip point this far (eye distances) or more behind its column's lip front is on the curve above the lip
#: (ICT's true points lie at most 0.0052 behind it, the found ones on its held-out heads too).
UPPER_LIP_CURVE_BEHIND = 0.008


def _lip_edges(V, T, points, pairs, curve, behind, side) -> np.ndarray:
    """``points (68, 3)`` with each outer lip point of ``pairs`` (``{outer: inner}``) lying ``curve`` or more behind
    its lip's front, in its column seen straight on, moved along the column towards the seam to where the profile
    lies ``behind`` the front: the lip's edge. ``side``: +1 for the lower lip (the points below the seam), -1 for the
    upper. The lip's front is the column's most forward point between the seam (the deepest point within
    :data:`SEAM_REACH` of the inner point) and the found point; a point stays where its column shows no such front
    between the seam and it, or no profile falling that far behind it on the point's side."""
    out = np.array(points, np.float64)
    eyes, view = _mouth_view(out)
    x, y, z = view.project(out)
    reach = round(SEAM_REACH * eyes / view.pixel)
    cols = {j: view.nearest_pixel(x[j]) for j in pairs}
    ys = [view.nearest_pixel(y[k]) for j, inner in pairs.items() for k in (j, inner)]
    # From the seam (within reach of the inner points) to the found points, and a row more for back_project.
    raster, depth = column_depths(V, T, view, list(cols.values()), (min(ys) - reach - 1, max(ys) + reach + 1))
    for j, inner in pairs.items():
        d = depth[:, cols[j]]
        ri, rj = (view.nearest_pixel(y[k]) for k in (inner, j))
        near = np.arange(max(ri - reach, 0), min(ri + reach, SIZE - 1) + 1)
        seam = int(near[np.argmin(d[near])])  # -inf (a slit between parted lips) counts as deepest
        if side * (rj - seam) <= 1:
            continue
        rows = np.arange(seam + side, rj + side, side)
        top = int(rows[np.argmax(d[rows])])
        front = d[top]
        if not front - z[j] >= curve * eyes:
            continue
        edge = front - behind * eyes
        path = np.arange(top, rj + side, side)  # from the front out to the found point
        fallen = np.flatnonzero(~(d[path] >= edge))
        if not len(fallen):
            continue
        r = int(path[fallen[0]])
        share = (d[r - side] - edge) / (d[r - side] - d[r]) if np.isfinite(d[r]) else 0.0  # between the rows
        P = back_project(V, T, raster, np.array([float(cols[j])]), np.array([r - side + side * share]), reach=1)[0][0]
        if np.isfinite(P).all():
            out[j] = P
    return out


def lower_lip_on_its_edge(V, T, points) -> np.ndarray:
    """``points (68, 3)`` with the lower lip's middle points (:data:`LOWER_LIP`) lying :data:`LIP_CURVE_BEHIND` or
    more behind the lower lip's front, in their column seen straight on, moved up the column to where the profile
    lies :data:`LIP_EDGE_BEHIND` behind that front: the lip's lower edge, not the curve under it.

    The lower lip's front is the column's most forward point between the seam (the deepest point within
    :data:`SEAM_REACH` of the inner lip point above) and the found point. The face mesh puts these points 0.02-0.08
    eye distances behind it on MakeHuman's development set, up to 0.08 too low, where the lip turns back towards
    the chin (56-58 against the registered skin points: median 3.6-3.9 % of the eye distance, p90 7.3-8.7). A point
    stays where its column shows no such front below the seam, or no profile falling that far behind it above the
    point; on ICT's held-out heads the points already lie on the edge, and stay.

    Parameters
    ----------
    V, T : arrays
        The mesh and the skin's triangles.
    points : (68, 3) array
        Landmarks on the skin, the mesh's space (the inner lip points are trusted).
    """
    return _lip_edges(V, T, points, LOWER_LIP, LIP_CURVE_BEHIND, LIP_EDGE_BEHIND, 1)


def upper_lip_on_its_edge(V, T, points) -> np.ndarray:
    """``points (68, 3)`` with the upper lip's outer points (:data:`UPPER_LIP`) lying :data:`UPPER_LIP_CURVE_BEHIND`
    or more behind the upper lip's front, in their column seen straight on, moved down the column to where the
    profile lies :data:`UPPER_LIP_EDGE_BEHIND` behind that front: the lip's upper edge (the vermilion border), not
    the curve above it towards the nose.

    The upper lip's front is the column's most forward point between the found point and the seam (the deepest
    point within :data:`SEAM_REACH` of the inner lip point below). On ICT's heads the true points and the found ones
    lie within 0.0052 eye distances behind it, and stay; the face mesh puts some of MakeHuman's 0.008-0.03 behind it,
    up to 0.05 too high. A point stays where its column shows no such front above the seam, or no profile falling
    that far behind it below the point (one found below the front, on the lip, stays too). On the development set 36
    points move on 13 characters (better by more than 1 % of the eye distance on 18, worse on 6, against the
    registered skin points: the worse where the true border lies high on a full lip, 0.009-0.014 behind the front);
    the inner median over the characters goes from 3.10 to 2.99 %.

    Parameters
    ----------
    V, T : arrays
        The mesh and the skin's triangles.
    points : (68, 3) array
        Landmarks on the skin, the mesh's space (the inner lip points are trusted).
    """
    return _lip_edges(V, T, points, UPPER_LIP, UPPER_LIP_CURVE_BEHIND, UPPER_LIP_EDGE_BEHIND, -1)


#: How far (eye distances) above the slit's lower edge a lower inner lip point may lie and stay: ICT's true ones lie
#: within a pixel of it (0.005), the face mesh's on parted lips 0.1 above.
SLIT_EDGE = 0.01


def lower_inner_lips_under_the_slit(V, T, points) -> np.ndarray:
    """``points (68, 3)`` with each of the lower lip's inner points (65-67) that lies above or inside an opening
    between the lips (a slit of parted lips), in its column seen straight on, moved down to the slit's lower edge:
    the first row under it, on the lower lip. An opening is what lies more than :data:`REACH` behind the lower lip's
    front (its outer middle point under the inner one, :data:`LOWER_LIP`), between the two points' rows. A point
    stays where its column shows no opening down to the lower lip's outer point (closed lips; the point already on
    the lower lip), or where it lies within :data:`SLIT_EDGE` of the slit's lower edge.

    The face mesh reads parted lips (a slit 0.1 eye distances high) as nearly closed: it puts the lower lip's inner
    points with the upper lip's, on the slit's top edge (parted-lips: 10-12 % of the eye distance too high, then
    1-4 %). On the development set the points moved (14, on 10 characters) go from a median 4.6 to 2.2 % of the eye
    distance from the registered skin points (better on all 14); the inner p95 (median over the characters) falls
    from 9.2 to 8.9 %. On ICT's held-out heads no point moves.

    Parameters
    ----------
    V, T : arrays
        The mesh and the skin's triangles.
    points : (68, 3) array
        Landmarks on the skin, the mesh's space (the lower lip's outer middle points are trusted).
    """
    out = np.array(points, np.float64)
    eyes, view = _mouth_view(out)
    x, y, z = view.project(out)
    inner_of = {inner: outer for outer, inner in LOWER_LIP.items()}
    cols = {j: view.nearest_pixel(x[j]) for j in inner_of}
    spans = {j: tuple(view.nearest_pixel(y[i]) for i in (j, k)) for j, k in inner_of.items()}
    # From the inner points down to the outer ones, and the row under them that back_project reads.
    raster, depth = column_depths(V, T, view, list(cols.values()),
                                  (min(s[0] for s in spans.values()), max(s[1] for s in spans.values()) + 1))
    for j, k in inner_of.items():
        rj, rk = spans[j]
        rows = np.arange(rj, rk + 1)  # down from the inner point to the lower lip's outer one
        opening = np.flatnonzero(~(depth[rows, cols[j]] >= z[k] - REACH * eyes))  # -inf (nothing seen) too
        if not len(opening) or rows[opening[-1]] >= rk:
            continue
        r = float(rows[opening[-1]] + 1)
        if (r - y[j]) * view.pixel <= SLIT_EDGE * eyes:
            continue  # on the edge already
        P = back_project(V, T, raster, np.array([float(cols[j])]), np.array([r]), reach=1)[0][0]
        if np.isfinite(P).all():
            out[j] = P
    return out


#: The lower lip's sides, each with the mouth corner its chord starts at; the chord ends at the lower lip's middle
#: (``LIP_LOWER_BOTTOM``).
LOWER_LIP_SIDES = {55: MOUTH_CORNER_LEFT, 59: MOUTH_CORNER_RIGHT}
#: How much lower (eye distances) than ICT's drop below its chord a lower lip side may lie and stay (one higher stays
#: by any amount: MakeHuman's true sides lie higher on average): ICT's 20
#: identities' true sides lie within 0.004 of the generic head's drop (0.039-0.047), the found ones on its 6 held-out
#: heads within 0.0033; MakeHuman's true ones at 0.011-0.063 (mean 0.036), the found ones a median 0.026 lower.
SIDE_DROP_OFF = 0.01
#: How much lower than ICT's (eye distances) a lower lip side may lie and move: beyond, the chord is what is off (lips
#: parted 0.2 eye distances: the lower lip's middle hangs with the jaw, and a side's drop below it reads 0.1-0.3).
SIDE_DROP_MAX = 0.05


def lower_lip_drops(points, view: View | None = None) -> np.ndarray:
    """How far (eye distances) each of :data:`LOWER_LIP_SIDES` lies below the chord from its mouth corner to the
    lower lip's middle (57), at its own place across, seen straight on (in the mouth's view, :func:`_mouth_view`).
    """
    eyes, view = _mouth_view(points) if view is None else (eye_distance(points), view)
    x, y, _ = view.project(points)
    drops = []
    for j, corner in LOWER_LIP_SIDES.items():
        share = (x[j] - x[corner]) / (x[LIP_LOWER_BOTTOM] - x[corner])
        chord = y[corner] + share * (y[LIP_LOWER_BOTTOM] - y[corner])
        drops.append((y[j] - chord) * view.pixel / eyes)  # rows count down
    return np.array(drops)


@lru_cache(maxsize=1)
def ict_lower_lip_drop() -> float:
    """How far (eye distances) the lower lip's sides lie below the chord from the mouth corner to the lower lip's
    middle on ICT's generic head (:func:`lower_lip_drops`, both sides' mean: 0.043)."""
    return float(lower_lip_drops(ict_landmarks()).mean())


def lower_lip_sides_at_ict_drop(V, T, points) -> np.ndarray:
    """``points (68, 3)`` with each lower lip side (:data:`LOWER_LIP_SIDES`) that lies lower than ICT's drop below
    the chord from its mouth corner to the lower lip's middle (:func:`lower_lip_drops`, :func:`ict_lower_lip_drop`)
    by more than :data:`SIDE_DROP_OFF` and at most :data:`SIDE_DROP_MAX`, moved up its column, seen straight on, to
    ICT's drop.

    On ICT's 20 identities that drop is the same within 0.004 eye distances; the face mesh puts MakeHuman's lower
    lip sides on the curve under the lip, a median 0.026 eye distances lower than the true ones, where the lip's edge
    (the feature the middle points go to, :func:`lower_lip_on_its_edge`) fades out towards the corners. On the
    development set 55/59 against the registered skin points go from a median 4.0/4.0 to 3.7/3.4 % of the eye
    distance (better by more than 1 % on 11 points, worse on none). A side higher than ICT's stays (MakeHuman's true
    sides lie higher on average: moved down, every one came out worse), as does one lower by more than
    :data:`SIDE_DROP_MAX` (the chord's end is off) or one with nothing seen at its new place; on ICT's held-out heads
    none moves.

    Parameters
    ----------
    V, T : arrays
        The mesh and the skin's triangles.
    points : (68, 3) array
        Landmarks on the skin, the mesh's space (the mouth corners and the lower lip's middle are trusted).
    """
    out = np.array(points, np.float64)
    eyes, view = _mouth_view(out)
    lower = dict(zip(LOWER_LIP_SIDES, lower_lip_drops(out, view) - ict_lower_lip_drop()))
    moving = [j for j, o in lower.items() if SIDE_DROP_OFF < o <= SIDE_DROP_MAX]
    if not moving:
        return out
    x, y, _ = view.project(out)
    cols = x[moving]
    rows = y[moving] - np.array([lower[j] for j in moving]) * eyes / view.pixel  # up: rows count down
    at = [(view.nearest_pixel(c), view.nearest_pixel(r)) for c, r in zip(cols, rows)]
    near = pixel_boxes(view.size, [(c - 2, c + 2, r - 2, r + 2) for c, r in at])  # about the new places alone
    P = back_project(V, T, rasterise(V, T, view, near=near), cols, rows, reach=1)[0]
    for j, p in zip(moving, P):
        if np.isfinite(p).all():
            out[j] = p
    return out
