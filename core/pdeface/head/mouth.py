"""The inside of the mouth: whether a head has one, and a simple mouth bag for a head that has none (issue #40).

A head made without a mouth inside (a game character, a sculpt's shell) shows the inside of its own head when
a key opens the lips. :func:`mouth_bag` makes a closed, dark-to-be bag behind the lips (an ellipsoid sized from
the landmarks, its vertices outside the skin around it pulled in); given to the binding as part kind ``mouth``
(:mod:`pdeface.head.parts`), it hangs from the lips: :func:`lower_share` of each vertex turns with the jaw, the
rest moves with the upper lip, so an opened mouth shows the bag, stretched between the lips, never a hole. The
user's mesh is not changed: the bag is an object of its own (the add-on's *Add Mouth Bag*).
"""
from __future__ import annotations

import numpy as np

from ..geometry import ClosestPoint, smoothstep, triangle_cross, unit_rows
from ..landmark_scheme import LIP_LOWER_INNER, LIP_UPPER_INNER, MOUTH_CORNERS
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
