"""Polygon meshes as plain arrays.

A :class:`Mesh` holds vertices ``V (n, 3)`` and polygons of any size stored
flat (``face_indices`` with ``face_counts``), so triangles, quads and n-gons
mix freely. Optional per-corner UVs and normals follow the same layout.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .errors import MeshError
from .geometry import column_extent, cross3, degrees_from_cos, row_dots, row_norms, triangle_cross, unit_rows
from .landmark_scheme import JAW_LEFT_ANGLE, JAW_RIGHT_ANGLE


@dataclass
class Mesh:
    """A polygon mesh.

    Attributes
    ----------
    vertices : (n, 3) float64 array
        Vertex positions.
    face_counts : (m,) int array
        Number of corners of each polygon (>= 3).
    face_indices : (sum(face_counts),) int array
        Vertex index of every polygon corner, polygon after polygon.
    uvs : (t, 2) float array or None
        Texture coordinates.
    face_uv_indices : int array like ``face_indices`` or None
        UV index of every polygon corner.
    normals : (k, 3) float array or None
        Normals read from a file.
    face_normal_indices : int array like ``face_indices`` or None
        Normal index of every polygon corner.
    material_names : list of str
        Material names in order of first use (OBJ ``usemtl``).
    face_materials : (m,) int array or None
        Index into ``material_names`` per polygon.
    """

    vertices: np.ndarray
    face_counts: np.ndarray
    face_indices: np.ndarray
    uvs: np.ndarray | None = None
    face_uv_indices: np.ndarray | None = None
    normals: np.ndarray | None = None
    face_normal_indices: np.ndarray | None = None
    material_names: list = field(default_factory=list)
    face_materials: np.ndarray | None = None
    mtllib: str | None = None

    @classmethod
    def from_faces(cls, vertices, faces, uvs=None) -> "Mesh":
        """Build a mesh from ``V (n, 3)`` and uniform polygons ``F (m, k)``.

        When ``uvs (n, 2)`` is given, each corner uses its vertex's UV.
        """
        V = np.asarray(vertices, dtype=np.float64)
        F = np.asarray(faces, dtype=np.int64)
        if F.ndim != 2 or F.shape[1] < 3:
            raise MeshError(f"faces must be an (m, k>=3) array, got shape {F.shape}")
        counts = np.full(len(F), F.shape[1], dtype=np.int64)
        idx = F.reshape(-1)
        mesh = cls(V, counts, idx)
        if uvs is not None:
            mesh.uvs = np.asarray(uvs, dtype=np.float64)
            mesh.face_uv_indices = idx.copy()
        mesh.validate()
        return mesh

    @property
    def face_starts(self) -> np.ndarray:
        """Offset of each polygon's first corner in ``face_indices``."""
        return np.concatenate([[0], np.cumsum(self.face_counts)[:-1]]).astype(np.int64)

    def validate(self, name: str = "mesh") -> "Mesh":
        """Check shapes, index ranges and finiteness; raise :class:`MeshError`."""
        V = self.vertices
        if V.ndim != 2 or V.shape[1] != 3:
            raise MeshError(f"{name}: vertices must be (n, 3), got {V.shape}")
        if len(V) == 0:
            raise MeshError(f"{name}: has no vertices")
        if len(self.face_counts) == 0:
            raise MeshError(f"{name}: has no faces")
        bad = ~np.isfinite(V).all(axis=1)
        if bad.any():
            raise MeshError(f"{name}: vertex {int(np.argmax(bad))} is not finite (NaN or inf)")
        if (self.face_counts < 3).any():
            raise MeshError(f"{name}: face {int(np.argmax(self.face_counts < 3))} has fewer than 3 corners")
        if int(self.face_counts.sum()) != len(self.face_indices):
            raise MeshError(f"{name}: face_counts do not add up to face_indices")
        if self.face_indices.min() < 0 or self.face_indices.max() >= len(V):
            raise MeshError(f"{name}: a face refers to a vertex outside 0..{len(V) - 1}")
        return self

    def same_topology(self, other: "Mesh") -> bool:
        """Whether ``other`` has this mesh's vertex count and polygon corners (the same mesh, posed)."""
        return len(other.vertices) == len(self.vertices) and np.array_equal(other.face_indices, self.face_indices)

    def triangles(self) -> tuple[np.ndarray, np.ndarray]:
        """Fan-triangulate every polygon: triangles and quads from their first corner; an n-gon of five or more from
        the corner whose fan's worst triangle is the best (:meth:`fan_apexes`).

        Returns
        -------
        T : (t, 3) int array
            Triangle vertex indices.
        polygon : (t,) int array
            Index of the polygon each triangle came from.
        """
        counts, starts, idx = self.face_counts, self.face_starts, self.face_indices
        ntri = counts - 2
        polygon = np.repeat(np.arange(len(counts)), ntri)
        k = np.arange(len(polygon)) - np.repeat(np.cumsum(ntri) - ntri, ntri)
        s, n, apex = starts[polygon], counts[polygon], self.fan_apexes()[polygon]
        T = np.stack([idx[s + apex], idx[s + (apex + k + 1) % n], idx[s + (apex + k + 2) % n]], axis=1)
        return T, polygon

    def fan_apexes(self) -> np.ndarray:
        """Per polygon, the corner its fan starts from: 0 for triangles and quads; for an n-gon of five or more (to
        :data:`FAN_SEARCH_CORNERS`), the corner whose fan's worst triangle (area signed along the polygon's Newell
        normal, over the sum of its squared edges) is the best. A hexagon left by
        dissolving the edge between two quads has two corners on straight sides: its fan from the first corner made
        a sliver of three points in a line and a chord across both quads, through their neighbours' surface. The sign
        makes a corner whose fan flips a triangle lose (a concave polygon's convex corner; a pinched polygon's
        repeated vertex); where no corner does better than a degenerate triangle, the first corner wins."""
        counts, starts, idx = self.face_counts, self.face_starts, self.face_indices
        apex = np.zeros(len(counts), np.int64)
        for n in np.unique(counts[(counts >= 5) & (counts <= FAN_SEARCH_CORNERS)]):
            rows = np.nonzero(counts == n)[0]
            P = self.vertices[idx[starts[rows, None] + np.arange(n)]]  # (m, n, 3)
            normal = np.cross(P, np.roll(P, -1, axis=1)).sum(1)  # Newell's: twice the polygon's vector area
            normal /= np.maximum(np.linalg.norm(normal, axis=1, keepdims=True), 1e-300)
            worst = np.full((len(rows), n), np.inf)  # per polygon and apex
            for k in range(1, n - 1):  # every apex's k-th triangle at once
                A, B, C = P, np.roll(P, -k, axis=1), np.roll(P, -k - 1, axis=1)
                area = np.einsum("mnj,mj->mn", np.cross(B - A, C - A), normal)  # negative: flipped
                edges = ((B - A) ** 2).sum(2) + ((C - B) ** 2).sum(2) + ((A - C) ** 2).sum(2)
                worst = np.minimum(worst, area / np.maximum(edges, 1e-300))
            apex[rows] = np.argmax(worst, axis=1)  # ties: the first corner, as before
        return apex


#: An n-gon of at most this many corners fans from its best corner (:meth:`Mesh.fan_apexes`); a larger one (a cap, a
#: fuzzer's) from its first, as the search's cost grows with the corners squared.
FAN_SEARCH_CORNERS = 64


def vertex_normals(V: np.ndarray, T: np.ndarray, only=None) -> np.ndarray:
    """Area-weighted unit vertex normals of a triangle mesh; ``only``: these vertices' alone, (len(only), 3) (the
    same numbers, from their triangles alone)."""
    if only is not None:
        touches = np.zeros(len(V), bool)
        touches[only] = True
        return vertex_normals(V, np.asarray(T)[touches[T].any(axis=1)])[only]
    n = triangle_cross(V, T)
    # bincount sums in input order: corner 0 of every triangle, then 1, then 2 (as np.add.at did, 5x slower).
    corners = np.asarray(T).T.ravel()
    flat = n.reshape(len(n), int(np.prod(n.shape[1:])))
    out = np.stack([np.bincount(corners, np.tile(flat[:, j], 3), minlength=len(V)) for j in range(flat.shape[1])], 1)
    return unit_rows(out.reshape((len(V),) + n.shape[1:]))


def edge_face_pairs(T: np.ndarray) -> np.ndarray:
    """The two triangles at each interior edge of a triangle mesh, (e, 2) (edges with other than two
    triangles are left out)."""
    T = np.asarray(T, np.int64)
    if len(T) == 0:
        return np.zeros((0, 2), np.int64)
    a, b = T.T.ravel(), T[:, [1, 2, 0]].T.ravel()  # the edges (0, 1), (1, 2), (2, 0) of every triangle in turn
    key = np.minimum(a, b) * (int(T.max()) + 1) + np.maximum(a, b)  # an edge's ends sorted, as one number
    face = np.tile(np.arange(len(T)), 3)
    order = np.argsort(key, kind="stable")
    key, face = key[order], face[order]
    start = np.flatnonzero(np.r_[True, key[1:] != key[:-1]])  # each edge's first place (np.unique's, without a sort)
    two = np.diff(np.r_[start, len(key)]) == 2
    return np.stack([face[start[two]], face[start[two] + 1]], 1)


def turn_degrees(V: np.ndarray, T: np.ndarray, pairs: np.ndarray) -> np.ndarray:
    """The angle (degrees) the two triangles of each pair (:func:`edge_face_pairs`) turn by at their edge."""
    n = unit_rows(triangle_cross(V, T))
    return degrees_from_cos(row_dots(n[pairs[:, 0]], n[pairs[:, 1]]))


def connected_components(n_vertices: int, T: np.ndarray) -> np.ndarray:
    """Label of the edge-connected component of every vertex."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components as cc

    i = np.concatenate([T[:, 0], T[:, 1]])  # two edges of each triangle join its three corners
    j = np.concatenate([T[:, 1], T[:, 2]])
    graph = coo_matrix((np.ones(len(i)), (i, j)), shape=(n_vertices, n_vertices))
    return cc(graph, directed=False)[1]


def cotan_laplacian(V: np.ndarray, T: np.ndarray):
    """Cotangent Laplacian ``L = D - W`` (sparse, symmetric, positive semi-definite).

    Weights are clamped to [1e-6, 1e3] so that obtuse and sliver triangles of real
    meshes keep it an M-matrix: harmonic functions then obey the maximum principle
    (an extension never overshoots its boundary values).
    """
    from scipy.sparse import coo_matrix, diags

    T = np.asarray(T)
    corners = [V[T[:, k]] for k in range(3)]
    vals = []
    for k in range(3):  # the angle at corner k + 2 weighs edge (k, k + 1)
        o = corners[(k + 2) % 3]
        u, v = corners[k] - o, corners[(k + 1) % 3] - o
        cot = row_dots(u, v)
        cot /= np.maximum(row_norms(cross3(u, v)), 1e-12)
        cot *= 0.5
        vals += [cot, cot]
    n = len(V)
    rows = np.concatenate([T[:, 0], T[:, 1], T[:, 1], T[:, 2], T[:, 2], T[:, 0]])
    cols = np.concatenate([T[:, 1], T[:, 0], T[:, 2], T[:, 1], T[:, 0], T[:, 2]])
    W = coo_matrix((np.concatenate(vals), (rows, cols)), shape=(n, n)).tocsr()
    np.clip(W.data, 1e-6, 1e3, out=W.data)
    return (diags(np.asarray(W.sum(axis=1)).ravel()) - W).tocsr()


def border_vertices(n, T) -> np.ndarray:
    """The vertices (sorted indices) on a border of triangles ``T`` over ``n`` vertices: on an edge that only one
    triangle has."""
    from scipy.sparse import csr_matrix

    T = np.asarray(T, np.int64)
    a, b = np.concatenate([T[:, 0], T[:, 1], T[:, 2]]), np.concatenate([T[:, 1], T[:, 2], T[:, 0]])
    # each edge's triangles counted in a sparse matrix (its duplicates summed row by row: no sort of all edges)
    count = csr_matrix((np.ones(len(a), np.int32), (np.minimum(a, b), np.maximum(a, b))), shape=(n, n))
    once = count.data == 1
    border = np.zeros(n, bool)
    border[np.repeat(np.arange(n), np.diff(count.indptr))[once]] = True
    border[count.indices[once]] = True
    return np.flatnonzero(border)


def seam_welds(V: np.ndarray, T: np.ndarray, tol: float | None = None, min_piece: int | None = None,
               pieces: np.ndarray | None = None) -> np.ndarray:
    """Representative of every vertex, joining copies split along open seams.

    Exporters split vertices where UVs or normals break (FBX, glTF, many PLYs): the
    mesh then falls apart into pieces along those seams. Vertices that lie on an
    open border and coincide (within ``tol``, default 1e-6 of the mesh's size) are
    joined when both their pieces have at least ``min_piece`` vertices (default:
    1 % of the mesh, at least 50; so lash strips and eye helper meshes sewn along a
    lid's edge stay pieces of their own). ``pieces``: ``connected_components(len(V), T)`` where found already.

    Returns
    -------
    (n,) int array
        The smallest index of each vertex's group (itself when alone).
    """
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components as cc
    from scipy.spatial import cKDTree

    n = len(V)
    rep = np.arange(n)
    if len(T) == 0:
        return rep
    border = border_vertices(n, T)
    if len(border) < 2:
        return rep
    if tol is None:
        tol = 1e-6 * float(np.linalg.norm(column_extent(V)))
    pairs = cKDTree(V[border]).query_pairs(tol, output_type="ndarray")
    if len(pairs) == 0:
        return rep
    i, j = border[pairs[:, 0]], border[pairs[:, 1]]
    if min_piece is None:
        min_piece = max(50, n // 100)
    piece = connected_components(n, T) if pieces is None else pieces
    size = np.bincount(piece)
    big = (size[piece[i]] >= min_piece) & (size[piece[j]] >= min_piece)
    i, j = i[big], j[big]
    if len(i) == 0:
        return rep
    _, lab = cc(coo_matrix((np.ones(len(i)), (i, j)), shape=(n, n)), directed=False)
    first = np.full(lab.max() + 1, n)
    np.minimum.at(first, lab, np.arange(n))
    return first[lab]


#: A mesh more of whose used vertices belong to one triangle alone than this share is a triangle soup (a closed
#: surface's vertices have about six each; ICT's head and MakeHuman's, none of one alone but at a border's corner).
SOUP_SHARE = 0.5
#: A mesh more of whose edges join two triangles wound the same way along them than this share has mixed normals
#: (ICT's head and MakeHuman's: none; MakeHuman's decimated to 3k vertices 0.8 %, a voxel remesh 0.03 %).
MIXED_WINDING_SHARE = 0.05


def triangle_arrays(V, T) -> tuple[np.ndarray, np.ndarray]:
    """``(V, T)`` as float64 (n, 3) finite vertices and int64 (m, 3) triangles indexing them, or a
    :class:`~pdeface.errors.MeshError` naming which is not."""
    V, T = np.asarray(V, np.float64), np.asarray(T, np.int64)
    if V.ndim != 2 or V.shape[1] != 3 or len(V) < 3 or not np.isfinite(V).all():
        raise MeshError("vertices must be (n, 3) finite numbers")
    if T.ndim != 2 or T.shape[1] != 3 or len(T) == 0 or T.min() < 0 or T.max() >= len(V):
        raise MeshError("triangles must be (m, 3) vertex indices")
    return V, T


def require_usable_triangles(T: np.ndarray, what="the mesh"):
    """Refuse triangles ``T`` that make no surface to find landmarks on, fit or bind: a triangle soup (each corner a
    copy of its neighbours', as a flat-shaded export with split edges writes them: each triangle a piece of its own)
    or mixed normals (neighbours wound opposite ways: the renders' smooth shading cancels out and a third of the
    fit's rays meet a triangle's back).

    Raises
    ------
    MeshError
        More than :data:`SOUP_SHARE` of the used vertices belong to one triangle alone, or more than
        :data:`MIXED_WINDING_SHARE` of the edges two triangles share run the same way in both.
    """
    T = np.asarray(T, np.int64)
    uses = np.bincount(T.ravel())
    uses = uses[uses > 0]
    alone = float(np.mean(uses == 1)) if len(uses) else 0.0
    if alone > SOUP_SHARE:
        raise MeshError(f"{what} is a triangle soup: {alone:.0%} of its vertices belong to one triangle alone (its "
                        "triangles share no vertices, as a flat-shaded export with split edges writes them); merge "
                        "its vertices by distance (Blender: Mesh > Clean Up > Merge by Distance) and try again")
    a, b = T.ravel(), T[:, [1, 2, 0]].ravel()
    key = np.minimum(a, b) * (int(T.max()) + 1) + np.maximum(a, b)
    order = np.argsort(key, kind="stable")
    key, ascending = key[order], (a < b)[order]
    starts = np.flatnonzero(np.r_[True, key[1:] != key[:-1]])
    shared = starts[np.diff(np.r_[starts, len(key)]) == 2]  # edges of two triangles (not a doubled face's, a fin's)
    if len(shared) == 0:
        return
    same = float(np.mean(ascending[shared] == ascending[shared + 1]))
    if same > MIXED_WINDING_SHARE:
        raise MeshError(f"{what} has mixed normals: {same:.0%} of the edges between its triangles join two wound the "
                        "same way (one of them faces into the head); recalculate its normals outside (Blender: Mesh "
                        "> Normals > Recalculate Outside) and try again")


def facing(V: np.ndarray, T: np.ndarray, forward, front: float) -> np.ndarray:
    """``T``, each triangle's winding reversed where the triangles in front of the plane ``x · forward = front`` face
    away from ``forward`` on balance (their normals, weighted by area): a mesh whose normals all point inwards, as
    a mirrored (left-handed) export leaves them. ``T`` itself where they face forward."""
    T = np.asarray(T, np.int64)
    f = np.asarray(forward, np.float64) / np.linalg.norm(forward)
    u = np.cross(f, [1.0, 0.0, 0.0] if abs(f[0]) < 0.9 else [0.0, 1.0, 0.0])
    u /= np.linalg.norm(u)
    x, y, depth = V @ u, V @ np.cross(f, u), V @ f  # (u, f × u, f) turn as (x, y, z) do
    a, b, c = T[depth[T].sum(axis=1) > 3 * front].T  # centroids in front
    # each triangle's normal (its corners' cross product) along f: twice its area seen from f's side, signed
    seen = (x[b] - x[a]) * (y[c] - y[a]) - (y[b] - y[a]) * (x[c] - x[a])
    return T[:, ::-1] if float(seen.sum()) < 0 else T


def facing_forward(Vf: np.ndarray, T: np.ndarray, Lf: np.ndarray) -> np.ndarray:
    """:func:`facing` of a mesh in the face frame (``Vf``, +z forward) by its triangles in front of the jaw angles
    (landmarks ``Lf`` (68, 3) in the same frame): ``T`` turned outwards where a mirrored export left every normal
    pointing into the head. The fit and the head binding read the face's normals alike."""
    return facing(Vf, T, (0.0, 0.0, 1.0), float(Lf[[JAW_RIGHT_ANGLE, JAW_LEFT_ANGLE], 2].mean()))


def butterfly_step(n_vertices: int, T: np.ndarray):
    """One step of butterfly subdivision (Dyn, Levin and Gregory 1990) as a sparse matrix.

    Interpolating: the old vertices stay where they are, each edge gets a new vertex
    ``½(a + b) + ⅛(c + d) − 1/16 (e + f + g + h)`` (c, d opposite the edge; e–h the
    wings beyond them), or the midpoint where the stencil is incomplete (near a border).
    Being linear in the vertices, a curve point read off the finer mesh is still a fixed
    combination of the original vertices.

    Parameters
    ----------
    n_vertices : int
    T : (t, 3) int array

    Returns
    -------
    S : scipy.sparse.csr_matrix, shape (n_vertices + edges, n_vertices)
        New vertices are ``S @ V``; the first ``n_vertices`` rows are the identity.
    T_fine : (4 t, 3) int array
        Each triangle split in four, wound as it was.
    """
    import scipy.sparse as sp

    T = np.asarray(T, np.int64)
    n = int(n_vertices)
    a, b, c = (np.concatenate([T[:, i], T[:, (i + 1) % 3], T[:, (i + 2) % 3]]) for i in range(3))
    key = np.minimum(a, b) * n + np.maximum(a, b)  # half-edge (a, b) with c opposite
    order = np.argsort(key, kind="stable")
    keys, first, count = np.unique(key[order], return_index=True, return_counts=True)
    edge_of = np.empty(len(key), np.int64)
    edge_of[order] = np.repeat(np.arange(len(keys)), count)
    opp = np.full((len(keys), 2), -1)
    opp[:, 0] = c[order][first]
    two = count == 2
    opp[two, 1] = c[order][first[two] + 1]
    ea, eb = keys // n, keys % n

    def wing(x, y, other):
        """The vertex across edge (x, y) from ``other``; -1 where the edge is a border or missing."""
        k = np.minimum(x, y) * n + np.maximum(x, y)
        i = np.clip(np.searchsorted(keys, k), 0, len(keys) - 1)
        found = (keys[i] == k) & two[i]
        o = np.where(opp[i, 0] == other, opp[i, 1], opp[i, 0])
        return np.where(found & (x >= 0) & (y >= 0), o, -1)

    cc, dd = opp[:, 0], opp[:, 1]
    wings = np.stack([wing(ea, cc, eb), wing(eb, cc, ea), wing(ea, dd, eb), wing(eb, dd, ea)], axis=1)
    full = two & (wings >= 0).all(axis=1)
    rows = [np.arange(n), n + np.arange(len(keys)), n + np.arange(len(keys))]
    cols = [np.arange(n), ea, eb]
    vals = [np.ones(n), np.full(len(keys), 0.5), np.full(len(keys), 0.5)]
    f = np.nonzero(full)[0]
    for col, w in ((cc[f], 1 / 8), (dd[f], 1 / 8), *((wings[f, j], -1 / 16) for j in range(4))):
        rows.append(n + f)
        cols.append(col)
        vals.append(np.full(len(f), w))
    S = sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                      shape=(n + len(keys), n))
    m = n + edge_of.reshape(3, -1).T  # per triangle: edges (t0 t1), (t1 t2), (t2 t0)
    t0, t1, t2 = T[:, 0], T[:, 1], T[:, 2]
    ab, bc, ca = m[:, 0], m[:, 1], m[:, 2]
    T_fine = np.concatenate([np.stack([t0, ab, ca], 1), np.stack([ab, t1, bc], 1), np.stack([ca, bc, t2], 1),
                             np.stack([ab, bc, ca], 1)])
    return S, T_fine
