"""The lid points (37, 38, 40, 41, 43, 44, 46, 47) on the front edge of the lid margin.

The map puts a lid point about where the lid's edge is seen straight on, and the snap takes it to the nearest
skin point. But the margin curls back into the socket (MakeHuman's lids turn 5 % of the eye distance backwards
within the next 0.5 % down): a lid point found 1 % of the eye distance too far into the opening lands on the
curl, 5-7 % behind the true point, on the lid's back. ICT's convention (and the gate's check) puts it on the
margin's front edge. So a lid point lying more than :data:`DEEPER` behind the lid's front (the most forward pixel
of its column, in a straight-on view of the skin, on the lid's side within :data:`REACH`) moves along the column
to the last pixel before the surface drops more than :data:`DROP` behind that front: the edge the opening begins
at. A point stays where the column shows no such drop within reach (an eyeball in the skin filling the opening, a
closed eye), or where the climb from it onto the lid meets a step (lashes fused into the skin stand out in front).
On the development set the eyes' median error against the registered skin points falls from 3.3 to 2.4 % of the
eye distance (upper lids 37/44 from 5.5/4.3 to 1.8/1.6); on ICT's held-out heads no point moves.

The outer eye corners go to the lateral end of the eye's opening where one shows
(:func:`outer_corners_at_opening_end`, before the brows, whose region the eye corners pose), and later all four come
forward onto the skin seen straight on where the snap left them deep in the crease behind it
(:func:`corners_on_skin_front`, after the brows; see each, and the order in :mod:`.pipeline`).
"""
from __future__ import annotations

import numpy as np

from ..landmark_scheme import UPPER_LIDS, eye_distance
from ..surface.frame import face_frame
from .render import Raster, View, back_project, closed_depth, column_depths, depth_map, pixel_boxes, rasterise

#: How far (eye distances) along its column a lid point may move, either way.
REACH = 0.04
#: How far (eye distances) behind the lid's front the margin's curl begins.
DROP = 0.015
#: How far (eye distances) behind the lid's front a lid point must lie to move: on ICT's heads the found points
#: lie on the margin's rounded edge, 0.01-0.02 behind the front above it (where ICT's own are).
DEEPER = 0.03
#: A step between neighbouring pixels (eye distances) that the climb from a lid point onto its lid's front does
#: not take: lashes fused into the skin hang 0.1-0.15 in front of it, the margin's curl rises 0.03 a pixel.
JUMP = 0.08
#: Pixels across each eye's straight-on view, and its half-width (eye distances): about 0.003 a pixel.
SIZE, HALF = 256, 0.4
#: Each eye's landmarks (its view is centred on them) and its lid points.
EYES = ((range(36, 42), (37, 38), (40, 41)), (range(42, 48), (43, 44), (46, 47)))
#: Each eye's corners.
CORNERS = ((36, 39), (42, 45))
#: How far (eye distances) behind the skin seen straight on at its place an eye corner may lie. True corners (ICT's
#: convention, registered onto MakeHuman's 24 characters) lie up to 0.024 under the lids' fold there, a median 0.00;
#: the snap's nearest skin point to a mapped corner in the crease lies 0.037-0.26 behind it on 11 of them.
CORNER_HIDDEN = 0.03


def _margin_row(column, r0, z0, upper, reach, deeper, drop, jump):
    """The row of ``column`` (depths, -inf where nothing is seen) where the lid's front ends, for a lid point at
    row ``r0`` and depth ``z0``; None where nothing is seen at ``r0``, where the climb from it onto the lid meets
    a step of more than ``jump`` within twice ``reach`` rows (the point is on lashes or beside a hole), where it
    is on the front already (less than ``deeper`` behind it), or where the front does not end within ``reach``
    rows. ``upper``: the opening is below (larger rows)."""
    step = 1 if upper else -1  # from the lid towards the opening
    n = len(column)
    if not np.isfinite(column[r0]):
        return None
    k = r0  # climb from the point onto the lid, along the surface, twice the reach
    while 0 <= k - step < n and abs(r0 - (k - step)) <= 2 * reach and abs(column[k - step] - column[k]) <= jump:
        k -= step
    if abs(r0 - k) < 2 * reach:
        return None  # a step over ``jump`` on the way: lashes standing out in front of the lid, not the lid
    climbed = np.arange(r0 - step * reach, r0 + step, step)
    start = int(climbed[np.argmax(column[climbed])])
    front = column[start]
    if front - z0 < deeper:
        return None
    rows = np.arange(start, np.clip(r0 + step * reach, -1, n), step)
    drops = np.flatnonzero(~(column[rows] >= front - drop))  # -inf (nothing seen) is a drop too
    return int(rows[drops[0] - 1]) if len(drops) else None


def _eye_views(points):
    """``(eye distance, face frame's rotation, views)``: each eye seen straight on (the face frame's front, its up)
    about its ring's middle, :data:`HALF` eye distances either way, :data:`SIZE` pixels square."""
    R = face_frame(points).rotation
    eyes = eye_distance(points)
    return eyes, R, [View.looking(R[2], R[1], points[list(ring)].mean(0), HALF * eyes, SIZE) for ring, _, _ in EYES]


def lids_on_margin(V, T, points) -> np.ndarray:
    """``points (68, 3)`` with the lid points moved to the front edge of the lid margin on the skin ``(V, T)``
    (see the module's docstring).

    Parameters
    ----------
    V, T : arrays
        The mesh and the skin's triangles.
    points : (68, 3) array
        Landmarks on the skin, the mesh's space.
    """
    out = np.array(points, np.float64)
    eyes, _, views = _eye_views(out)
    for (ring, upper, lower), view in zip(EYES, views):
        x, y, z = view.project(out)
        cols = {j: view.nearest_pixel(x[j]) for j in (*upper, *lower)}
        r0 = {j: view.nearest_pixel(y[j]) for j in cols}
        reach = round(REACH * eyes / view.pixel)  # _margin_row reads twice it either way, back_project a row more
        raster, depth = column_depths(V, T, view, list(cols.values()),
                                      (min(r0.values()) - 2 * reach - 1, max(r0.values()) + 2 * reach + 1))
        for j, c in cols.items():
            r = _margin_row(depth[:, c], r0[j], z[j], j in UPPER_LIDS, reach, DEEPER * eyes, DROP * eyes, JUMP * eyes)
            if r is None:
                continue
            P = back_project(V, T, raster, np.array([float(c)]), np.array([float(r)]), reach=1)[0][0]
            if np.isfinite(P).all():
                out[j] = P
    return out


def corners_on_skin_front(V, T, points) -> np.ndarray:
    """``points (68, 3)`` with each eye corner (:data:`CORNERS`) lying more than :data:`CORNER_HIDDEN` behind the skin
    ``(V, T)`` seen straight on (the face frame's front) at its place moved onto that skin, the point seen there.

    The map's corner, in the crease where the lids meet, is taken to its nearest skin point; in a deep crease that
    is the crease's back wall or the socket behind the lids' fold, 4-26 % of the eye distance behind the skin seen
    in front of it (stylised-nose-mouth's 45: 20 % from the true corner). Seen straight on from where it was found,
    the corner is the skin in front. On the development set the corners moved (16 of 96, on 11 characters) go from
    a median 7.0 to 3.0 % of the eye distance from the registered skin points (worse on 2, by 2.7 and 3.3: true
    corners under a fold overhanging them by 0.02); the eyes' p95 falls from 7.2 to 6.1 % (median over the
    characters). On ICT's held-out heads no corner moves.

    Parameters
    ----------
    V, T : arrays
        The mesh and the skin's triangles.
    points : (68, 3) array
        Landmarks on the skin, the mesh's space.
    """
    out = np.array(points, np.float64)
    eyes, R, views = _eye_views(out)
    for view, corners in zip(views, CORNERS):
        x, y, _ = view.project(out)
        j = list(corners)
        spots = [(c - 1, c + 1, r - 1, r + 1) for c, r in zip(np.round(x[j]).astype(int), np.round(y[j]).astype(int))]
        raster = rasterise(V, T, view, near=pixel_boxes(SIZE, spots))  # the pixels back_project reads, no more
        P = back_project(V, T, raster, x[j], y[j], reach=1)[0]
        for k, Pk in zip(j, P):
            if np.isfinite(Pk).all() and (Pk - out[k]) @ R[2] > CORNER_HIDDEN * eyes:
                out[k] = Pk
    return out


#: Each eye's outer corner, its inner corner and its lid points.
OUTER_CORNERS = ((36, 39, (37, 38, 40, 41)), (45, 42, (43, 44, 46, 47)))
#: The eye's opening seen straight on: pixels more than :data:`OPENING_DEPTH` (eye distances) behind the face's
#: front closed over them by a disc of radius :data:`OPENING_RADIUS` (wider than the lids' opening is high).
OPENING_RADIUS, OPENING_DEPTH = 0.08, 0.03
#: How far (eye distances) above and below the eye's landmarks its opening is looked for first (drawing the rows
#: there and the closing's reach around them, not the whole picture); where it runs on farther, in the whole picture.
OPENING_BAND = 0.05
#: How far (eye distances) from the opening's end an outer corner may lie and stay: ICT's true corners lie up to 0.02
#: from it (their lids meet a little beyond the opening seen straight on).
OPENING_END_SLACK = 0.03
#: How far (eye distances) from the opening's end an outer corner may lie and still go there: MakeHuman's found
#: corners lay at most 0.09 from it; farther, the opening ran on into something else (a crease, a groove joined to
#: the slit on a stylised or low-poly socket) and the corner stays.
OPENING_END_REACH = 0.12


def _opening_part(V, T, view: View, cx, cy, eyes, rows=None):
    """``(raster, part)``: the eye's opening (see :func:`outer_corners_at_opening_end`) that holds pixel ``(cx, cy)``,
    a bool image; None where no opening holds it or it runs out of the picture. ``rows``: ``(first, last)``, the rows
    it is looked for in (with ``cy``), drawn with the closing's reach (twice its radius) around them: the same opening
    as in the whole picture where it stays inside them (the closing at a pixel sees no farther, and any background
    depth below the face's gives the same opening); False where it reaches their edge inside the picture."""
    from scipy.ndimage import label

    n = view.size
    radius = max(round(OPENING_RADIUS * eyes / view.pixel), 1)
    first, last = (0, n - 1) if rows is None else (max(min(rows[0], cy), 0), min(max(rows[1], cy), n - 1))
    lo, hi = max(first - 2 * radius - 1, 0), min(last + 2 * radius + 1, n - 1)
    first, last = (0 if lo == 0 else first), (n - 1 if hi == n - 1 else last)  # the picture's edge: exact up to it
    near = None
    if lo > 0 or hi < n - 1:
        near = np.zeros((n, n), bool)
        near[lo:hi + 1] = True
    raster = rasterise(V, T, view, near=near)
    depth = depth_map(V, T, Raster(view, raster.tri[lo:hi + 1], raster.bary[lo:hi + 1]))
    closed = closed_depth(depth, radius)
    if closed is None:
        return raster, None
    opening = (~np.isfinite(depth) | (depth < closed - OPENING_DEPTH * eyes))[first - lo:last - lo + 1]
    parts, _ = label(opening)
    if parts[cy - first, cx] == 0:
        return raster, None
    part = parts == parts[cy - first, cx]
    if part[:, 0].any() or part[:, -1].any() or (part[0].any() and first == 0) or (part[-1].any() and last == n - 1):
        return raster, None  # not an opening between the lids: it runs out of the eye's picture
    if part[0].any() or part[-1].any():
        return raster, False
    whole = np.zeros((n, n), bool)
    whole[first:last + 1] = part
    return raster, whole


def outer_corners_at_opening_end(V, T, points) -> np.ndarray:
    """``points (68, 3)`` with each outer eye corner (36, 45) at the lateral end of its eye's opening on the skin
    ``(V, T)`` seen straight on: the opening (an empty socket, or a separate eyeball, seen between the lids:
    :data:`OPENING_DEPTH` behind the face's front closed over it) that holds the middle of the lid points, its
    pixel farthest out along the line from the inner corner to the outer one, and the skin seen just beyond it.
    A corner stays where no opening holds the lids' middle (an eyeball in the skin, a closed eye) or where the
    opening reaches the picture's edge.

    The face mesh places the outer corners by the faces it learned; on MakeHuman's development set they land up to
    0.09 eye distances up and forward on the upper lid, or sunk behind the corner (36 and 45 a median 3.5 and 5.6 %
    of the eye distance from the registered skin points). At the opening's end: 2.0 and 2.0 % (35 of 48 moved,
    4.7 → 2.0 % median; better on 29, worse by more than 1 on 4: asian-female-old's two, voxel's and
    eyes-teeth-separate's 36, where the lids' slit runs on past the true corner); a corner within
    :data:`OPENING_END_SLACK` of it stays, and one beyond :data:`OPENING_END_REACH`. The inner corners are not moved
    so: there the opening ends at the caruncle, beside the true corner (median 2.4 → 3.8 %).

    Parameters
    ----------
    V, T : arrays
        The mesh and the skin's triangles.
    points : (68, 3) array
        Landmarks on the skin, the mesh's space (the lid points and the inner corners are trusted).
    """
    out = np.array(points, np.float64)
    eyes, _, views = _eye_views(out)
    for (ring, _, _), view, (outer, inner, lids) in zip(EYES, views, OUTER_CORNERS):
        x, y, _ = view.project(out)
        cx, cy = (view.nearest_pixel(c[list(lids)].mean()) for c in (x, y))
        margin = OPENING_BAND * eyes / view.pixel
        band = (int(np.floor(y[list(ring)].min() - margin)), int(np.ceil(y[list(ring)].max() + margin)))
        raster, part = _opening_part(V, T, view, cx, cy, eyes, band)
        if part is False:  # the opening runs on above or below the band: the whole picture
            raster, part = _opening_part(V, T, view, cx, cy, eyes)
        if part is None:
            continue
        axis = np.array([x[outer] - x[inner], y[outer] - y[inner]])
        axis /= np.linalg.norm(axis)
        rows, cols = np.nonzero(part)
        k = int(np.argmax((cols - cx) * axis[0] + (rows - cy) * axis[1]))
        P = back_project(V, T, raster, np.array([cols[k] + 1.5 * axis[0]]), np.array([rows[k] + 1.5 * axis[1]]),
                         reach=2)[0][0]  # the skin just beyond the opening's end
        if np.isfinite(P).all() and OPENING_END_SLACK < np.linalg.norm(P - out[outer]) / eyes < OPENING_END_REACH:
            out[outer] = P
    return out
