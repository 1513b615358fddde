"""Folds and cracks of a PDE face mesh, counted the way a viewer sees them.

A mesh edge is a **fold** when the two faces meeting there turn by more than a
given angle (30° by default) and it lies outside the eye, mouth and nostril
openings (their landmark polygons in the frontal view, grown by a third about
their centres, at rest and, for a posed face, where its lids and lips have
moved), where the lids and lips are meant to part. Distance and seam
figures do not see folds; a render shows them first.
"""
from __future__ import annotations

import numpy as np

from ..errors import MeshError
from ..geometry import degrees_from_cos, unit_rows

#: Landmark polygons of the openings (Multi-PIE, 0-based): eyes, outer lips, the nose's underside.
OPENINGS = {"eye_right": list(range(36, 42)), "eye_left": list(range(42, 48)), "mouth": list(range(48, 60)),
            "nostrils": [30, 31, 32, 33, 34, 35]}
#: Openings are grown by this fraction about their centres.
GROW = 1 / 3
#: A fold this near (mm) a fold of the fitted scan itself, in the same pose, lies on a crease the face has.
CREASE_MM = 3.0


def _inside(x, y, polygon) -> np.ndarray:
    """Even-odd test of 2-D points ``x``, ``y`` against a closed ``polygon`` (m, 2): an edge at a time, its
    crossing's x made only for the points whose row it crosses (many points: the resolution choice's grids).
    Each crossing is the same arithmetic as :func:`_inside_each`'s, so the same mask."""
    inside = np.zeros(len(x), bool)
    following = np.roll(polygon, -1, axis=0)
    for (x0, y0), (x1, y1) in zip(polygon, following):
        crosses = np.flatnonzero((y0 > y) != (y1 > y))
        if len(crosses):
            xc = x0 + (y[crosses] - y0) * (x1 - x0) / (y1 - y0)
            inside[crosses[x[crosses] < xc]] ^= True
    return inside


def _inside_each(x, y, polygons) -> np.ndarray:
    """Even-odd test of each 2-D point ``x``, ``y`` against its own closed polygon (points, m, 2), vectorised over
    points and edges (few points: a pose's edges)."""
    x, y = x[:, None], y[:, None]
    x0, y0 = polygons[..., 0], polygons[..., 1]
    following = np.roll(polygons, -1, axis=-2)  # each edge, as a row over the points
    x1, y1 = following[..., 0], following[..., 1]
    crosses = (y0 > y) != (y1 > y)
    with np.errstate(divide="ignore", invalid="ignore"):
        xc = x0 + (y - y0) * (x1 - x0) / (y1 - y0)
    return (crosses & (x < xc)).sum(axis=1) % 2 == 1


def _grown_openings(sets, grow):
    """Each opening's polygon of known landmarks grown about its centre, for each landmark set ``sets``
    (sets, 68, 3): (sets, openings, m, 2), an opening with fewer corners than the most padded by repeating its
    last (an edge of no length crosses no row, so the even-odd test is the polygon's own); None where no opening
    has 3 known corners."""
    grown = []
    for idx in OPENINGS.values():
        poly = sets[:, idx, :2]
        poly = poly[:, np.isfinite(poly).all(axis=(0, 2))]
        if poly.shape[1] >= 3:
            centre = poly.mean(axis=1, keepdims=True)
            grown.append(centre + (1 + grow) * (poly - centre))
    if not grown:
        return None
    out = np.empty((len(sets), len(grown), max(g.shape[1] for g in grown), 2))
    for o, g in enumerate(grown):
        out[:, o, :g.shape[1]] = g
        out[:, o, g.shape[1]:] = g[:, -1:]
    return out


#: At most this many points (landmarks) are searched for by brute force (and on a grid, by its tiles); more, by a tree.
FEW_POINTS = 100
#: Rows and columns of a grid's tiles in :func:`nearest_vertices`' search of a grid.
TILE = 8
#: Squared distances (mm²) nearer than this to the nearest one are searched for as before (over every vertex): a
#: tile's search sums in another order, a difference of ~1e-11 mm² on a face.
TIE_MM2 = 1e-6


def nearest_vertices(rest_vertices, points, grid=None) -> np.ndarray:
    """Index of each point's nearest rest vertex (-1 for rows with a NaN: landmarks a model does not keep).

    ``grid``: ``(n_u, n_v)`` when the vertices are a grid's, row by row: only the tiles of :data:`TILE` rows and
    columns whose box lies near enough are searched, for the same indices (where another vertex lies within
    :data:`TIE_MM2` of the nearest, every vertex is).
    """
    P = np.asarray(points, np.float64).reshape(-1, 3)
    V = np.asarray(rest_vertices, np.float64)
    known = np.isfinite(P).all(axis=1)
    nearest = np.full(len(P), -1)
    if not known.any():
        return nearest
    if grid is not None and known.sum() <= FEW_POINTS:
        found = _nearest_on_grid(V.reshape(*grid, 3), P[known])
        unsure = found < 0
        nearest[np.nonzero(known)[0][~unsure]] = found[~unsure]
        known &= nearest < 0
        if not known.any():
            return nearest
    if known.sum() <= FEW_POINTS:  # landmarks: a brute-force search (|v|² - 2 v·p per pair) is cheaper than a tree
        # (a sum over the axis of 3 is slow in numpy; the same additions in the same order)
        square = V[:, 0] ** 2 + V[:, 1] ** 2 + V[:, 2] ** 2
        nearest[known] = np.argmin(square - 2 * P[known] @ V.T, axis=1)
    else:
        from scipy.spatial import cKDTree
        nearest[known] = cKDTree(V).query(P[known])[1]
    return nearest


def _nearest_on_grid(X, P) -> np.ndarray:
    """:func:`nearest_vertices` of points ``P`` (p, 3) on the grid ``X`` (n_u, n_v, 3), searched tile by tile: the
    index where it is sure (no other vertex within :data:`TIE_MM2`), else -1."""
    n_u, n_v, _ = X.shape
    starts = np.arange(0, n_u, TILE), np.arange(0, n_v, TILE)
    whole = n_u // TILE * TILE

    def box(extreme):  # each tile's smallest or largest coordinates: whole tiles of rows as a reshape (5x reduceat)
        rows = extreme.reduce(X[:whole].reshape(n_u // TILE, TILE, n_v, 3), axis=1)
        if whole < n_u:
            rows = np.concatenate([rows, extreme.reduce(X[whole:], axis=0)[None]])
        return extreme.reduceat(rows, starts[1], axis=1).reshape(-1, 3)
    lo, hi = box(np.minimum), box(np.maximum)
    # each tile's vertices (flat indices), -1 past the grid's edge
    r, c = np.arange(len(starts[0]) * TILE), np.arange(len(starts[1]) * TILE)
    index = np.where((r[:, None] < n_u) & (c[None, :] < n_v), r[:, None] * n_v + c[None, :], -1)
    tiles = index.reshape(len(starts[0]), TILE, len(starts[1]), TILE).transpose(0, 2, 1, 3).reshape(len(lo), -1)
    flat = X.reshape(-1, 3)
    # a tile's box bounds its vertices' squared distances below; the tile nearest by its box bounds the nearest
    # vertex's above: only tiles whose box lies within that bound can hold it
    below = 0.0
    for k in range(3):  # (p, tiles), a coordinate at a time
        gap = np.maximum(lo[:, k] - P[:, k, None], 0.0) + np.maximum(P[:, k, None] - hi[:, k], 0.0)
        below = below + gap * gap
    first = tiles[np.argmin(below, axis=1)]  # (p, TILE²)
    d = np.where(first >= 0, ((flat[first] - P[:, None]) ** 2).sum(axis=2), np.inf)
    point, tile = np.nonzero(below <= d.min(axis=1)[:, None] + TIE_MM2)
    # |v|² - 2 v·p (the brute force's measure, p's |p|² apart) at the candidate tiles' vertices
    v = tiles[tile]
    square = (flat[v] ** 2).sum(axis=2) - 2 * np.einsum("tvk,tk->tv", flat[v], P[point])
    square[v < 0] = np.inf
    cut = np.flatnonzero(np.diff(point)) + 1
    starts = np.r_[0, cut]
    best = np.minimum.reduceat(square.min(axis=1), starts)  # per point (point increases, each has a tile)
    near = np.add.reduceat((square <= best[point][:, None] + TIE_MM2).sum(axis=1), starts)
    winner = np.full(len(P), -1)
    rows, cols = np.nonzero(square == best[point][:, None])
    winner[point[rows]] = v[rows, cols]
    return np.where(near == 1, winner, -1)


def carried(rest_vertices, posed_vertices, points, nearest=None) -> np.ndarray:
    """Points carried into a pose of a mesh: each moves as its nearest rest vertex does.

    ``rest_vertices``, ``posed_vertices`` (n, 3) and ``points`` (p, 3) in one frame; rows with a NaN (the
    landmarks a model does not keep) stay unknown. ``posed_vertices`` may be many poses, (poses, n, 3): the points
    carried into each, (poses, p, 3). ``nearest``: :func:`nearest_vertices`, when carrying the
    same points into many poses. A posed face's openings are where its posed lids and
    lips are (AU27's lower lip drops past its rest polygon); the scan's creases go where the pose takes
    the skin they lie on (AU38's flared nose wings carry their grooves 2–3 mm outwards).
    """
    P = np.array(points, np.float64).reshape(-1, 3)
    nearest = nearest_vertices(rest_vertices, P) if nearest is None else nearest
    known = nearest >= 0
    moved = np.asarray(posed_vertices, np.float64) - np.asarray(rest_vertices, np.float64)
    P = np.repeat(P[None], len(moved), axis=0) if moved.ndim == 3 else P
    P[..., known, :] += moved[..., nearest[known], :]
    return P


def opening_mask(points_face, landmarks_face, grow=GROW, which=None) -> np.ndarray:
    """Which face-frame points (n, 3), or their frontal view alone (n, 2), lie inside an opening's grown landmark
    polygon (frontal view).

    A polygon is made of the landmarks that are known (a model file keeps some only: the mouth's
    corners and midpoints); an opening with fewer than 3 known is left out. ``which``: each point's
    landmark set, when ``landmarks_face`` is (sets, 68, 3) (a face's poses, tested at once; the known
    landmarks are those known in every set).
    """
    mask = np.zeros(len(points_face), bool)
    sets = np.asarray(landmarks_face)[None] if which is None else np.asarray(landmarks_face)
    grown = _grown_openings(sets, grow)
    if grown is None:
        return mask
    # in float64 whatever the points' type (a float32 column against a float64 corner stays float32 in numpy 1.x)
    x, y = (np.asarray(points_face[:, i], np.float64) for i in (0, 1))
    lo, hi = grown.min(axis=2), grown.max(axis=2)  # each polygon's bounding box: only points in it can be inside
    if which is None:  # one set, many points (the resolution choice's grids): a polygon at a time, its rows first
        for polygon, (x0, y0), (x1, y1) in zip(grown[0], lo[0], hi[0]):
            near = np.flatnonzero((y >= y0) & (y <= y1))
            near = near[(x[near] >= x0) & (x[near] <= x1)]
            mask[near] |= _inside(x[near], y[near], polygon)
        return mask
    # a set per point (a face's poses), few points: every (point, opening) pair in its box at once
    which = np.asarray(which)
    point, opening = np.nonzero(((points_face[:, None, :2] >= lo[which]) & (points_face[:, None, :2] <= hi[which]))
                                .all(axis=2))
    mask[point[_inside_each(x[point], y[point], grown[which[point], opening])]] = True
    return mask


def fold_edges(mesh, frame, landmarks_face, angle_deg=30.0, rest=None) -> dict:
    """Edges of a polygon mesh whose two faces turn by more than ``angle_deg``, outside the openings.

    Parameters
    ----------
    mesh : Mesh
        A PDE face mesh (:func:`pdeface.surface.fit.face_mesh`), in the user's space.
    frame : FaceFrame
        The face's frame (the openings are tested in its frontal view).
    landmarks_face : (68, 3) array
        Landmarks in the face frame (the model's).
    rest : Mesh, optional
        The same mesh at rest (same vertices, other positions), when ``mesh`` is a pose of it: the
        openings are then those at rest, those of the posed lids and lips (:func:`carried`), and
        the edges whose rest position lies in an opening, so an open jaw's lower lip or a closed
        eye's lid margins part where they are.

    Returns
    -------
    dict
        ``count`` (folds outside the openings), ``max_deg`` (largest turn there),
        ``inside`` (edges over the angle inside openings, allowed), and
        ``where`` ((count, 3) edge midpoints, face frame) for pictures.
    """
    V = frame.to_face(mesh.vertices)
    if rest is not None and len(rest.vertices) != len(V):
        raise MeshError(f"the rest mesh has {len(rest.vertices)} vertices, the posed one {len(V)}: a pose is "
                        "measured against the same mesh at rest")
    starts, counts, idx = mesh.face_starts, mesh.face_counts, mesh.face_indices
    # Face normals by Newell's method (planar or not), from each polygon's corners.
    normals = np.zeros((len(counts), 3))
    for k in range(int(counts.max())):
        has = counts > k
        a = idx[starts[has] + k]
        b = idx[starts[has] + (k + 1) % counts[has]]
        normals[has] += np.cross(V[a], V[b])
    normals = unit_rows(normals)
    # Each undirected edge with the faces on either side.
    face_of = np.repeat(np.arange(len(counts)), counts)
    nxt = idx[starts[face_of] + (np.arange(len(idx)) - starts[face_of] + 1) % counts[face_of]]
    lo, hi = np.minimum(idx, nxt), np.maximum(idx, nxt)
    key = lo.astype(np.int64) * len(V) + hi
    order = np.argsort(key, kind="stable")
    key, face_of, lo, hi = key[order], face_of[order], lo[order], hi[order]
    pair = np.nonzero(key[1:] == key[:-1])[0]
    f0, f1 = face_of[pair], face_of[pair + 1]
    turn = degrees_from_cos((normals[f0] * normals[f1]).sum(1))
    mid = 0.5 * (V[lo[pair]] + V[hi[pair]])
    folded = turn > angle_deg
    opening = opening_mask(mid, landmarks_face)
    if rest is not None:
        rest_V = frame.to_face(rest.vertices)
        opening |= opening_mask(mid, carried(rest_V, V, landmarks_face))
        # and the edges whose own skin lies in an opening at rest: a closed lid's margin stays the
        # opening's edge though the lids' landmark polygon has flattened to a line
        opening |= opening_mask(0.5 * (rest_V[lo[pair]] + rest_V[hi[pair]]), landmarks_face)
    outside = folded & ~opening
    return {"count": int(outside.sum()), "max_deg": float(turn[~opening].max()) if (~opening).any() else 0.0,
            "inside": int((folded & opening).sum()), "where": mid[outside]}


def off_creases(where, creases, radius=CREASE_MM) -> np.ndarray:
    """Which folds (``where``: :func:`fold_edges`' midpoints, face frame) lie farther than ``radius`` mm from
    every fold of the scan the face was fitted to (``creases``: the same on the scan in the same pose, or
    its folds at rest :func:`carried` by the pose where the scan has no such pose): the folds the PDE surface
    adds, not the nose wings' grooves or the lids' margins the scan has too."""
    from scipy.spatial import cKDTree

    where = np.asarray(where, np.float64).reshape(-1, 3)
    if len(creases) == 0:
        return np.ones(len(where), bool)
    return cKDTree(np.asarray(creases, np.float64).reshape(-1, 3)).query(where)[0] > radius
