"""The inside of the mouth: whether a head has one, and a simple mouth bag for a head that has none (issue #40).

A head made without a mouth inside (a game character, a sculpt's shell) shows the inside of its own head when
a key opens the lips. :func:`mouth_bag` makes a closed, dark-to-be bag behind the lips (an ellipsoid sized from
the landmarks, its vertices outside the skin around it pulled in); given to the binding as part kind ``mouth``
(:mod:`pdeface.head.parts`), it hangs from the lips: :func:`lower_share` of each vertex turns with the jaw, the
rest moves with the upper lip, so an opened mouth shows the bag, stretched between the lips, never a hole. The
user's mesh is not changed: the bag is an object of its own (the add-on's *Add Mouth Bag*).

Lips joined in the mesh (a voxel remesh) cannot part; :func:`cut_lips` cuts them open along the line between them,
for a new fit, where the user asks for it.
"""
from __future__ import annotations

from itertools import pairwise

import numpy as np

from ..errors import MeshError
from ..geometry import ClosestPoint, smoothstep, triangle_cross, unit_rows
from ..landmark_scheme import LIP_LOWER_INNER, LIP_UPPER_INNER, MOUTH_CORNERS
from ..landmark_scheme import eye_distance as eye_distance_of  # bindings name theirs eye_distance
from ..mesh import border_vertices
from .parts import mouth_line

#: A head has no mouth inside where its skin has a border (an open edge) within INSIDE_BORDER_IOD eye distances of
#: both inner lips' middles: the lips open onto the inside of the head (a lining joins them to the mouth's depths;
#: the holes a decimation left in one lie 0.2 away).
INSIDE_BORDER_IOD = 0.08
#: The bag's half-axes (eye distances): beyond the mouth corners sideways, up and down from the mouth line, and
#: back from just behind the inner lips (BAG_FRONT_IOD).
BAG_SIDE_IOD = 0.05
BAG_HALF_HEIGHT_IOD = 0.15
BAG_HALF_DEPTH_IOD = 0.25
BAG_FRONT_IOD = 0.02
#: Rings and segments of the bag's sphere; how many times its vertices outside the skin are pulled in.
BAG_RINGS, BAG_SEGMENTS = 14, 28
BAG_PULLS = 12
#: ... until they lie this far (eye distances) inside it.
BAG_MARGIN_IOD = 0.03
#: The bag's vertices turn with the jaw below the mouth line and move with the upper lip above it, blended over
#: this many eye distances either side (its front wall stretches there when the mouth opens).
BLEND_IOD = 0.15


def has_mouth_inside(P, T, Lf, eye_distance) -> bool:
    """Whether the skin ``P`` (face frame), triangles ``T``, goes on behind the lips (a mouth's lining): no open
    edge of it near both inner lips' middles (landmarks 62 and 66). Lips joined in the mesh count as a mouth inside
    here: the binding says what they need."""
    border = P[border_vertices(len(P), T)]
    if not len(border):
        return True
    reach = INSIDE_BORDER_IOD * eye_distance
    return not all(np.linalg.norm(border - Lf[i], axis=1).min() < reach for i in (LIP_UPPER_INNER, LIP_LOWER_INNER))


def _ellipsoid(centre, axes):
    """A closed UV ellipsoid: (vertices, outward triangles)."""
    rings, segs = BAG_RINGS, BAG_SEGMENTS
    theta = np.linspace(0, np.pi, rings + 1)[1:-1]
    phi = np.linspace(0, 2 * np.pi, segs, endpoint=False)
    t, p = np.meshgrid(theta, phi, indexing="ij")
    unit = np.c_[np.sin(t).ravel() * np.cos(p).ravel(), np.cos(t).ravel(), np.sin(t).ravel() * np.sin(p).ravel()]
    V = np.r_[[[0, 1, 0]], unit, [[0, -1, 0]]] * axes + centre
    top, bottom = 0, len(V) - 1
    ring = lambda i: 1 + i * segs + np.arange(segs)
    nxt = lambda r: np.roll(r, -1)
    T = [np.c_[np.full(segs, top), nxt(ring(0)), ring(0)]]
    for i in range(rings - 2):
        a, b = ring(i), ring(i + 1)
        T += [np.c_[a, nxt(a), nxt(b)], np.c_[a, nxt(b), b]]
    last = ring(rings - 2)
    T.append(np.c_[last, nxt(last), np.full(segs, bottom)])
    T = np.concatenate(T)
    # Outward: each triangle's normal away from the centre.
    flip = (triangle_cross(V, T) * (V[T].mean(1) - centre)).sum(1) < 0
    T[flip] = T[flip][:, ::-1]
    return V, T


def _outside(X, skin, centre, margin=0.0):
    """Which points ``X`` lie outside the skin around them, or within ``margin`` of it: beyond their closest skin
    point, seen from the bag's ``centre`` (the skin's normal there turned away from it: any winding)."""
    V, T = skin
    _, tri, _, Q = ClosestPoint(V, T).query(X)
    n = unit_rows(triangle_cross(V, T[tri]))
    n *= np.sign((n * (Q - centre)).sum(1))[:, None]
    return ((X - Q) * n).sum(1) > -margin


def mouth_bag(Vf, T, skin, Lf, eye_distance):
    """A mouth bag behind the lips of a head (face frame): ``(vertices (b, 3), triangles (t, 3))``.

    Parameters
    ----------
    Vf : (n, 3) array
        The head's vertices in the face frame (mm).
    T : (m, 3) int array
    skin : (n,) bool array
        The head's skin (the bag is kept within it).
    Lf : (68, 3) array
        The landmarks in the face frame (the mouth corners and inner lips' middles read: a model file keeps those).
    eye_distance : float
    """
    corners = Lf[MOUTH_CORNERS]
    front = Lf[[*MOUTH_CORNERS, LIP_UPPER_INNER, LIP_LOWER_INNER], 2].min() - BAG_FRONT_IOD * eye_distance
    axes = np.array([np.ptp(corners[:, 0]) / 2 + BAG_SIDE_IOD * eye_distance, BAG_HALF_HEIGHT_IOD * eye_distance,
                     BAG_HALF_DEPTH_IOD * eye_distance])
    centre = np.array([corners[:, 0].mean(), mouth_line(Lf), front - axes[2]])
    V, Tb = _ellipsoid(centre, axes)
    Ts = T[skin[T].all(axis=1)]
    for _ in range(BAG_PULLS):  # its vertices outside the skin around it pulled in towards its middle
        out = _outside(V, (Vf, Ts), centre, BAG_MARGIN_IOD * eye_distance) if len(Ts) else np.zeros(len(V), bool)
        if not out.any():
            break
        V[out] = centre + 0.85 * (V[out] - centre)
    return V, Tb


def lower_share(Xf, Lf, eye_distance) -> np.ndarray:
    """How much of the jaw's turn each mouth-bag vertex ``Xf`` (face frame) takes, 0 above the mouth line to 1
    below it (the rest of its motion is the upper lip's)."""
    band = BLEND_IOD * eye_distance
    return smoothstep((mouth_line(Lf) + band - Xf[:, 1]) / (2 * band))


def head_mouth_bag(binding, triangles):
    """:func:`mouth_bag` for the head a :class:`~pdeface.head.bind.HeadBinding` was made for (its ``triangles``):
    ``(vertices in the head's space and unit, triangles)``."""
    Vb, Tb = mouth_bag(binding.Vf, triangles, binding.parts.mask("skin"), binding.face_landmarks,
                       binding.eye_distance)
    return binding.frame.to_user(Vb), Tb


#: The lip line's path weighs each edge's length by 1 + LINE_PULL × its distance (eye distances) from the mouth's
#: line through the corners and the inner lips' middle: it keeps to the groove between fused lips.
LINE_PULL = 40.0
#: A cut's upper side is lifted this far (eye distances): coincident, the binding would join the two sides again
#: as a seam's copies.
CUT_OPEN_IOD = 0.005


def lip_line(Vf, edges, Lf, eye_distance) -> np.ndarray:
    """The vertices (in order, corner to corner) of the line between lips joined in the mesh: the shortest way over
    its ``edges`` ((e, 2) vertex pairs) from the mouth corner (landmark 48) by the inner lips' middle (62 and 66) to
    the other corner (54), kept near the mouth's line (face frame: ``Vf``, ``Lf``)."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import dijkstra
    from scipy.spatial import cKDTree

    stops = Lf[[MOUTH_CORNERS[0], LIP_UPPER_INNER, MOUTH_CORNERS[1]]].copy()
    stops[1] = Lf[[LIP_UPPER_INNER, LIP_LOWER_INNER]].mean(0)
    order = np.argsort(stops[:, 0])
    off = np.abs(Vf[:, 1] - np.interp(Vf[:, 0], stops[order, 0], stops[order, 1])) / eye_distance
    i, j = np.asarray(edges, np.int64).T
    w = np.linalg.norm(Vf[i] - Vf[j], axis=1) * (1 + LINE_PULL * (off[i] + off[j]) / 2)
    graph = coo_matrix((w, (i, j)), shape=(len(Vf), len(Vf))).tocsr()
    ends = cKDTree(Vf).query(stops)[1]
    path = [int(ends[0])]
    for a, b in pairwise(ends):
        _, before = dijkstra(graph, directed=False, indices=int(a), return_predecessors=True)
        leg, v = [], int(b)
        while v != a:
            if v < 0:
                raise MeshError("the mouth corners and the lips' middle are not joined in the mesh: no lip line to cut")
            leg.append(v)
            v = int(before[v])
        path += leg[::-1]
    return np.array(path)


def lip_cut(vertices, edges, landmarks, frame):
    """Where to cut lips joined in the mesh (a voxel remesh) open, for a new fit (:func:`cut_lips` on triangles; the
    add-on's *Cut Lips Open* on Blender's edges).

    Parameters
    ----------
    vertices : (n, 3) array
        The head (user space and unit).
    edges : (e, 2) int array
        Its edges.
    landmarks : (68, 3) array
        Its landmarks (user space).
    frame : FaceFrame
        The face frame of a face fitted to it (``model.frame``).

    Returns
    -------
    path : (k,) int array
        The lip line's vertices, corner to corner (:func:`lip_line`): the inner ones are copied, the copies take
        the upper lip's side; the two corners stay joined.
    lifted : (k - 2, 3) array
        Where the copies go (user space): lifted CUT_OPEN_IOD eye distances.
    landmarks : (68, 3) array
        The inner lips' middles (62 and 66) on the upper and the lower side of the cut: fit the face again with
        these (fitted on lips joined, the face's two lip rims lie on one line and the cut's sides move as one).
    """
    V = np.asarray(vertices, np.float64)
    Vf, Lf = frame.to_face(V), frame.to_face(np.asarray(landmarks, np.float64))
    ed = eye_distance_of(Lf)
    path = lip_line(Vf, edges, Lf, ed)
    inner = path[1:-1]
    if not len(inner):
        raise MeshError("the lip line runs straight from corner to corner: nothing to cut")
    lifted = Vf[inner] + [0.0, CUT_OPEN_IOD * ed, 0.0]
    middle = np.argmin(np.abs(Vf[inner, 0] - Lf[[LIP_UPPER_INNER, LIP_LOWER_INNER], 0].mean()))
    Lf = Lf.copy()
    Lf[LIP_UPPER_INNER], Lf[LIP_LOWER_INNER] = lifted[middle], Vf[inner[middle]]
    return path, frame.to_user(lifted), frame.to_user(Lf)


def above_line(Vf, path, points):
    """Which ``points`` (face frame) lie above the lip line ``path`` (vertices of ``Vf``): the upper lip's side."""
    order = np.argsort(Vf[path, 0])
    return points[:, 1] > np.interp(points[:, 0], Vf[path[order], 0], Vf[path[order], 1])


def cut_lips(vertices, triangles, landmarks, frame):
    """Lips joined in the mesh cut open (:func:`lip_cut`) as a new triangle mesh: ``(vertices, triangles,
    landmarks)``, the k copies after the old vertices, the triangles above the line (the upper lip's) moved onto
    them. A change of the user's topology: only where asked."""
    V, T = np.asarray(vertices, np.float64), np.asarray(triangles, np.int64)
    edges = np.concatenate([T[:, [0, 1]], T[:, [1, 2]], T[:, [2, 0]]])
    path, lifted, L = lip_cut(V, edges, landmarks, frame)
    inner = path[1:-1]
    copy_of = np.full(len(V), -1)
    copy_of[inner] = len(V) + np.arange(len(inner))
    Vf = frame.to_face(V)
    moved = above_line(Vf, path, Vf[T].mean(1)) & (copy_of[T] >= 0).any(axis=1)
    T = T.copy()
    T[moved] = np.where(copy_of[T[moved]] >= 0, copy_of[T[moved]], T[moved])
    return np.r_[V, lifted], T, L
