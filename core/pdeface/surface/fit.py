"""Fit a PDE face model to a neutral mesh, and mesh the PDE surface.

The pipeline: landmarks → face frame and unit → curve layout → curve points
(material points on the mesh) → Fourier series + residual → :class:`FaceModel`.
Meshing solves the PDE on a grid and maps it back to the mesh's own space.
"""
from __future__ import annotations

import numpy as np

from ..errors import LandmarkError, LayoutError, MeshError
from ..geometry import (
    ClosestPoint,
    any_corner,
    column_extent,
    every_corner,
    in_box,
    row_norms,
    triangle_cross,
    unit_rows,
)
from ..mesh import (
    Mesh,
    border_vertices,
    butterfly_step,
    connected_components,
    facing_forward,
    require_usable_triangles,
    seam_welds,
)
from ..threads import bounded
from .fourier import fit_fourier
from .frame import FACE_REACH_MM, face_frame, feature_points
from .grid import grid_faces, surface_grid
from .layout import DEFAULT_CURVES, check_sizes, place_curves
from .model import FaceModel
from .pde import output_grid
from .rims import band_triangles, follow_rims
from .sampling import mesh_resolution


class UsedVertices:
    """The vertices triangles ``T`` of ``V`` use (``used``: their indices; ``V``: their positions; ``T``: the triangles
    on them), their search tree and the triangles' longest edges: built once per fit (a 200k-vertex head's tree and
    edges cost 0.06 s), searched by :func:`skin_vertices` and :func:`check_on_mesh`. A stray vertex no triangle uses
    (even a non-finite one) is not among them."""

    def __init__(self, V: np.ndarray, T: np.ndarray):
        from scipy.spatial import cKDTree  # scipy is heavy: only fitting and reports need it

        T = np.asarray(T, np.int64).reshape(-1, 3)
        corner = np.zeros(len(V), bool)
        corner[T.ravel()] = True
        self.used = np.flatnonzero(corner)
        self.V = np.asarray(V, np.float64)[self.used]
        self.T = (np.cumsum(corner) - 1)[T]
        # Distances and sorted balls only: an unbalanced tree answers the same, built in half the time.
        self.tree = cKDTree(self.V, balanced_tree=False, compact_nodes=False)
        self.edge = longest_edges(self.V, self.T)

    def closest(self, P):
        """:func:`closest_on_nearby` of points ``P`` on the triangles: ``(distance, tri, bary, point)``, ``tri``
        indexing ``T``."""
        return closest_on_nearby(self.V, self.T, P, self.tree, self.edge)


def skin_vertices(V: np.ndarray, T: np.ndarray, points: np.ndarray, pieces: np.ndarray | None = None,
                  search: UsedVertices | None = None) -> np.ndarray:
    """Mask of the vertices of the connected pieces that lie under ``points`` (the landmarks).

    Separate pieces (eyeballs, teeth) are left out; copies an exporter split along
    seams join their piece (:func:`pdeface.mesh.seam_welds`). Eyelashes and other strips often
    share the lids' vertex positions: where several pieces are equally near a
    point, the largest is the skin. A point on the skin between its vertices (a lid margin's point)
    may lie nearer to an eyeball's vertex than to the skin's: the piece of the nearest triangle
    counts too, the largest again. ``pieces``: the connected pieces' labels of ``(V, T)`` where ``T``'s seams are
    already joined (the binding's), so none are welded again; ``search``: ``UsedVertices(V, T)`` where built already.
    """
    search = UsedVertices(V, T) if search is None else search
    used, Vu = search.used, search.V  # the mesh's size from its triangles: a stray vertex far away must not set it
    extent = column_extent(Vu) if len(used) else np.zeros(3)
    lab = pieces
    if lab is None:
        rep = seam_welds(V, T, tol=1e-6 * float(np.linalg.norm(extent)))  # split along UV seams: still one piece
        lab = connected_components(len(V), rep[T])[rep]
    sizes = np.bincount(lab)
    dist, _ = search.tree.query(points)
    on = T[search.closest(points)[1], 0]
    scale = float(extent.max()) or 1.0
    labels = set()
    for p, d, t in zip(points, dist, on):
        near = [*used[search.tree.query_ball_point(p, d + 1e-6 * scale)], t]
        labels.add(int(lab[max(near, key=lambda i: sizes[lab[i]])]))
    return np.isin(lab, list(labels))


def longest_edges(V: np.ndarray, T: np.ndarray) -> np.ndarray:
    """Each triangle's longest edge: its diameter (a point on it lies within this of each corner)."""
    a, b, c = V[T[:, 0]], V[T[:, 1]], V[T[:, 2]]
    return np.maximum(np.maximum(row_norms(b - a), row_norms(c - b)), row_norms(a - c))


#: Up to this many points (the landmarks), :func:`closest_on_nearby` looks for the vertices near them in balls around
#: each; more (a face's grid) cover the face: all vertices in their box are looked at.
FEW_POINTS = 256


def closest_on_nearby(V, T, P, tree=None, edge=None):
    """:meth:`pdeface.geometry.ClosestPoint.query` of points ``P`` on triangles ``T`` of ``V``, built on only the
    triangles that can hold a point's nearest: a corner within the points' farthest nearest-vertex distance plus
    the triangle's longest edge (triangles longer than 99 % of them are all kept). For a few thousand points on a
    100k-vertex head all triangles' search trees cost 0.2 s.

    Every vertex of ``V`` must be a corner of ``T``; ``tree``: a ``cKDTree`` of ``V`` where one is built already;
    ``edge``: :func:`longest_edges` of ``(V, T)`` where known. Each answer is as near as the whole mesh's or nearer
    (the search is exact on the fine, even meshes it is meant for). Returns ``(distance, tri, bary, point)``,
    ``tri`` indexing ``T``.
    """
    from scipy.spatial import cKDTree

    V, T, P = np.asarray(V, np.float64), np.asarray(T, np.int64), np.asarray(P, np.float64).reshape(-1, 3)
    if len(T) == 0 or len(P) == 0 or not (np.isfinite(V).all() and np.isfinite(P).all()):
        return ClosestPoint(V, T).query(P)
    tree = cKDTree(V, balanced_tree=False, compact_nodes=False) if tree is None else tree  # for distances only
    gap, nearest = tree.query(P)
    reach = float(gap.max()) * (1 + 1e-9) + (longest_edges(V, T) if edge is None else edge)
    bound = float(np.percentile(reach, 99))
    # each vertex's distance to its nearest point, inf past the bound (outside the points' balls or box: not searched)
    apart = np.full(len(V), np.inf)
    if len(P) <= FEW_POINTS:
        looked = np.unique(np.concatenate([np.asarray(ball, np.int64) for ball in tree.query_ball_point(P, bound)]))
    else:
        looked = np.flatnonzero(in_box(V, P.min(axis=0) - bound, P.max(axis=0) + bound))
    apart[looked] = cKDTree(P).query(V[looked], distance_upper_bound=bound * (1 + 1e-9))[0]
    near = np.minimum(np.minimum(apart[T[:, 0]], apart[T[:, 1]]), apart[T[:, 2]]) <= reach
    keep = np.flatnonzero(near | (reach > bound))
    corner = np.zeros(len(V), bool)
    corner[T[keep].ravel()] = True
    local = np.cumsum(corner) - 1  # each point's nearest vertex is a corner of a kept triangle: its search is done
    dist, tri, bary, point = ClosestPoint(V[corner], local[T[keep]]).query(P, nearest=local[nearest])
    return dist, keep[tri], bary, point


def skin_triangles(V: np.ndarray, T: np.ndarray, points: np.ndarray, search: UsedVertices | None = None) -> np.ndarray:
    """Triangles of the skin: the pieces under ``points`` (see :func:`skin_vertices`)."""
    return T[skin_vertices(V, T, points, search=search)[T[:, 0]]]


def check_landmarks_on_mesh(V_face, L_face, reach_mm=20.0):
    """Refuse landmarks that lie off the mesh (a point moved by hand, landmarks of another mesh).

    Each landmark must be within ``reach_mm`` of a mesh vertex (face frame, mm).
    """
    from scipy.spatial import cKDTree


    def nearest(V):  # each landmark's distance to its nearest vertex of V (inf where there is none)
        dist = np.full(len(L_face), np.inf)
        if len(V) and near.any():
            dist[near] = cKDTree(V, balanced_tree=False, compact_nodes=False).query(L_face[near])[0]  # same distances
        return dist

    near = np.isfinite(L_face).all(axis=1)
    # Only the vertices in the landmarks' box widened by the reach can be within it (a coordinate that overflowed
    # into the face frame, 1e308 in the file, or NaN is in no box): a 200k head's tree in a third of the time.
    lo, hi = L_face[near].min(axis=0, initial=np.inf) - reach_mm, L_face[near].max(axis=0, initial=-np.inf) + reach_mm
    dist = nearest(V_face[in_box(V_face, lo, hi)])
    if dist.max() > reach_mm:
        dist = nearest(V_face[np.isfinite(V_face).all(axis=1)])  # how far they lie, for the message
        worst = int(np.argmax(dist))
        raise LandmarkError(f"landmark {worst} lies {dist[worst]:.3g} mm from the mesh (limit {reach_mm:g} mm): "
                            "are these this mesh's landmarks, in its unit?")


def reachable_triangles(V_face: np.ndarray, T: np.ndarray) -> np.ndarray:
    """The triangles whose corners all lie within :data:`FACE_REACH_MM` of the nose tip (face frame)."""
    return T[every_corner(row_norms(V_face) <= FACE_REACH_MM, T)]


#: A skin whose median edge is longer than this fraction of the curves' median spacing is read off a
#: butterfly-subdivided copy (:func:`refined_skin`), subdivided until its edges are under
#: :data:`FINE_EDGE` of the spacing, at most :data:`MAX_REFINE` times. MediaPipe's 468-point face
#: (7.8 mm edges, curves 4.8 mm apart) gets two steps; ICT's scans (2.8 mm) none.
COARSE_EDGE = 1.0
FINE_EDGE = 0.5
MAX_REFINE = 2


def refined_skin(V_face, skin, layout):
    """A coarse skin made fine enough to read curves off: ``(S, V_fine, T_fine)``.

    On a low-poly face the curves would follow its flat facets (ripples, and the facets' own
    error). Butterfly subdivision (:func:`pdeface.mesh.butterfly_step`) interpolates the vertices
    with a smooth surface; ``S`` (fine × original vertices) keeps every curve point linear in the
    original mesh. Only triangles near the band (its heights ± 10 mm) are refined. ``S`` is None
    when the skin is fine already (then ``V_fine`` is ``V_face``, ``T_fine`` is ``skin``).
    """
    import scipy.sparse as sp


    V_face = np.asarray(V_face, np.float64)
    spacing = float(np.median(-np.diff(layout.ray_heights(), axis=0)))
    S, T = None, skin
    for _ in range(MAX_REFINE):
        V = V_face if S is None else S @ V_face
        y = V[:, 1]
        centre_y = (y[T[:, 0]] + y[T[:, 1]] + y[T[:, 2]]) / 3  # the centres' heights (a 100k head's: 0.05 s)
        near = (centre_y > layout.heights.min() - 10) & (centre_y < layout.heights.max() + 10)
        a, b, c = (V[T[near, k]] for k in range(3))  # every edge of each triangle: a 100k head's in 0.02 s
        sides = [row_norms(b - a), row_norms(c - b), row_norms(a - c)]
        edge = float(np.median(np.concatenate(sides))) if near.any() else 0.0
        if edge <= (COARSE_EDGE if S is None else FINE_EDGE) * spacing:
            break
        step, fine = butterfly_step(len(V), T[near])
        S = step if S is None else step @ S
        T = np.concatenate([fine, T[~near]])
    if S is None:
        return None, V_face, skin
    return sp.csr_matrix(S), S @ V_face, T


def chord_knots(points: np.ndarray) -> np.ndarray:
    """Curve parameters in [0, 1] by mean chord length between consecutive curves."""
    gaps = np.linalg.norm(np.diff(points, axis=0), axis=2).mean(axis=1)
    if np.any(gaps <= 0):
        raise MeshError("two boundary curves coincide; the mesh or landmarks are degenerate")
    u = np.concatenate([[0.0], np.cumsum(gaps)])
    return u / u[-1]


#: How far (eye distances) the fitted face's 95th percentile may lie from its mesh, and the grid it is read on
#: (midway between the curves, every third point: a few thousand exact closest-point queries cost 0.1 s).
OFF_MESH_IOD = 0.06
OFF_MESH_STEPS = 2
OFF_MESH_STRIDE = 3


@bounded
def fit_face(vertices, triangles, landmarks, unit=None, n_curves=DEFAULT_CURVES, n_points=37, n_modes=5,
             a=1.0, assembly="smooth", source="", follow_lips=True, skin=None):
    """Fit a PDE face model to a neutral face mesh.

    Parameters
    ----------
    vertices : (n, 3) array
        Mesh vertices in the user's space and unit.
    triangles : (t, 3) int array
        Mesh triangles (see :meth:`pdeface.mesh.Mesh.triangles`).
    landmarks : (68, 3) array
        Multi-PIE landmark positions in the same space.
    unit : str or float, optional
        Mesh unit: a name or millimetres per unit (:func:`~pdeface.units.parse_unit`); estimated from the face's
        size when None (:func:`~pdeface.surface.frame.estimate_unit`).
    n_curves, n_points, n_modes : int
        Curves, points per curve, Fourier modes.
    a : float
        PDE smoothing parameter.
    assembly : {'smooth', 'patches'}
        Default assembly stored in the model.
    source : str
        Where the mesh came from (kept in the model).
    follow_lips : bool
        Bend the curves along the lips (default) or keep them horizontal
        (see :func:`pdeface.surface.layout.place_curves`).
    skin : (n,) bool array, optional
        The skin vertices; by default the pieces under the landmarks
        (:func:`skin_vertices`), leaving eyeballs, teeth and lashes out.

    Returns
    -------
    model : FaceModel
    sampler : pdeface.surface.curves.CurveSampler
        The curve points as material points of this mesh.
    """
    import scipy.sparse as sp

    check_sizes(n_curves, n_points, n_modes, "fit")
    if not n_modes < n_points:
        raise LayoutError(f"fit: {n_modes} modes need more than {n_points} points per curve")
    if not (isinstance(a, (int, float, np.floating)) and np.isfinite(a) and a > 0):
        raise LayoutError(f"fit: the smoothing parameter a must be a positive number, got {a!r}")
    V = np.asarray(vertices, dtype=np.float64)
    T = np.asarray(triangles, dtype=np.int64)
    if V.ndim != 2 or V.shape[1] != 3 or not np.isfinite(V).all():
        raise MeshError("vertices must be a finite (n, 3) array")
    if len(T) == 0:
        raise MeshError("mesh has no faces")
    require_usable_triangles(T)
    frame = face_frame(landmarks, unit)
    Vf = frame.to_face(V)
    Lf = frame.to_face(landmarks)
    check_landmarks_on_mesh(Vf, Lf)
    T = reachable_triangles(Vf, T)
    if len(T) == 0:
        raise MeshError(f"no triangle of the mesh lies within {FACE_REACH_MM:g} mm of the nose tip")
    layout = place_curves(Lf, n_curves, n_points, follow_lips=follow_lips)
    search = UsedVertices(Vf, T)
    if skin is None:
        skin = skin_triangles(Vf, T, Lf, search)
    else:
        skin = np.asarray(skin, bool)
        if skin.shape != (len(V),):
            raise MeshError(f"skin mask must have one entry per vertex ({len(V)}), got {skin.shape}")
        skin = T[every_corner(skin, T)]
        if len(skin) == 0:
            raise MeshError("the skin given has no triangles")
    # Normals all pointing inwards (a mirrored export): every ray would meet a triangle's back.
    skin = facing_forward(Vf, skin, Lf)
    from .curves import (  # scipy: loaded only when a face is fitted
        CurveSampler,
        cavity_depths,
        groove_depths,
        place_samples,
    )
    refine, Vs, skin = refined_skin(Vf, skin, layout)
    layout = follow_rims(layout, Vs, skin)
    heights = layout.ray_heights()
    sampler = place_samples(Vs, band_triangles(Vs, skin, heights.min(), heights.max()), layout,
                            cavity_depths(layout, Lf), groove_depth=groove_depths(layout, Lf))
    if refine is not None:
        sampler = CurveSampler(sp.csr_matrix(sampler.matrix @ refine), sampler.status, sampler.shape,
                               sampler.groove_mix)
    points = sampler.sample(Vf)
    coef, res = fit_fourier(points, n_modes)
    model = FaceModel(layout, chord_knots(points), coef, res, frame, feature_points(Lf), a=a,
                      assembly=assembly, source=source, status=sampler.status.copy(), landmarks=Lf)
    check_on_mesh(model, Vf, T, Lf, search)
    return model, sampler


def check_on_mesh(model, Vf, T, Lf, search: UsedVertices | None = None):
    """Refuse a fitted face that leaves the mesh it was fitted on (``Vf``, ``T``: face frame; ``search``:
    ``UsedVertices(Vf, T)`` where built already).

    A face whose curves could not follow the mesh (on a few stylised heads they run off tens of millimetres
    below the brows) would rig keys on the wrong surface without a word. Over ICT-FaceKit's heads, its
    468-vertex face mask and the MakeHuman development set the 95th percentile of the PDE face's distance to
    its mesh is at most 0.016 eye distances (openings included); the broken fits seen were 0.18 and 1.36.
    Where the nearest mesh point is on a border (a face mask's edge, an unlined opening) only the distance off
    that triangle's plane counts: there the face goes on past a mesh that has ended.
    """
    from ..landmark_scheme import eye_distance

    X = surface_grid(model, OFF_MESH_STEPS, OFF_MESH_STEPS).reshape(-1, 3)[::OFF_MESH_STRIDE]
    ed = eye_distance(Lf)
    search = UsedVertices(Vf, T) if search is None else search
    lo, hi = X.min(axis=0) - ed, X.max(axis=0) + ed
    if not every_corner(in_box(search.V, lo, hi), search.T).any():
        raise LayoutError("fit: the fitted face lies nowhere near the mesh")
    # only the triangles near the face's points are searched (a body, the back of a head: the fit's cost is the face's)
    dist, tri, _, at = search.closest(X)
    on = T[tri]
    # Where the mesh ends (a face mask, an unlined opening) the face may go on past it, along the surface: there
    # only its distance off the surface's plane counts. A vertex's borders are read off the triangles it is a
    # corner of (the whole mesh's edges cost 0.06 s at 100k vertices).
    hit = np.zeros(len(Vf), bool)
    hit[on.ravel()] = True
    edge = np.zeros(len(Vf), bool)
    edge[border_vertices(len(Vf), T[any_corner(hit, T)])] = True
    past = (edge & hit)[on].any(axis=1)
    n = unit_rows(triangle_cross(Vf, on[past]))
    dist[past] = np.abs(((X[past] - at[past]) * n).sum(axis=1))
    off = float(np.percentile(dist, 95))
    if off > OFF_MESH_IOD * ed:
        raise LayoutError(
            f"fit: the fitted face leaves the mesh (5 % of it lies {off / ed:.2f} eye distances or more from the "
            f"surface; a good fit stays within {OFF_MESH_IOD:g}): its curves could not follow this face; check the "
            "landmarks (pdeface landmarks --image) or report the mesh")


def face_mesh(model: FaceModel, resolution="default", assembly=None, coefficients=None, residual=None) -> Mesh:
    """The PDE face as a quad mesh in the source mesh's space and unit.

    Vertices are row-major over (u, v): row 0 is the top curve, column 0 the
    subject's right edge. The order depends only on the layout and the
    resolution's steps (:func:`pdeface.surface.sampling.mesh_resolution`: the
    default's are chosen once per model), so meshes of the same model line up
    as shape keys. UVs are the parameters: ``U = v / π``, ``V = 1 - u``.
    """
    su, sv = mesh_resolution(model, resolution)
    X = surface_grid(model, su, sv, assembly, coefficients, residual)
    n_u, n_v, _ = X.shape
    grid = output_grid(model.knots, model.layout.n_points, su, sv)
    uv = np.stack(np.meshgrid(1.0 - grid.u, grid.v / np.pi, indexing="ij")[::-1], axis=-1).reshape(-1, 2)
    return Mesh.from_faces(model.frame.to_user(X.reshape(-1, 3)), grid_faces(n_u, n_v), uvs=uv)
