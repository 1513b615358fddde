"""Keys that do not crease the user's mesh: each key's motion relaxed where it would fold an edge (issue #40).

A key folds an edge when its two triangles, nearly flat at rest (turning by less than ``FLAT_DEG``), turn by
more than ``FOLD_DEG`` in the key. On the MakeHuman development set and ICT's head the folds sit where one
motion meets another across a few vertices: the inner lips' rim against the lining, the lid margins, the
jaw's split gums (turned against the fixed upper ones), lashes anchored on different lid vertices. There the
key's displacement steps from one vertex to the next; :class:`FoldRelax` smooths it (each vertex towards its
neighbours' mean displacement, cotangent weights) on the folded edges' vertices and one ring around them, key by key, until no
edge folds or ``RELAX_STEPS`` have run. Elsewhere the key is left exactly as bound.
"""
from __future__ import annotations

import numpy as np

from ..geometry import triangle_cross, unit_rows
from ..mesh import connected_components, cotan_laplacian, edge_face_pairs, turn_degrees

#: Edges turning by less than this at rest are flat; a key folds one that then turns by more than FOLD_DEG
#: (below the issue's 40°: a margin for the other keys' shapes and poses that mix them).
FLAT_DEG = 20.0
FOLD_DEG = 35.0
#: The issue's limit: a key may fold this share of the mesh's edges, or LIMIT_MIN edges (over 40°).
LIMIT_SHARE = 0.001
LIMIT_MIN = 2
#: A key over it is relaxed until it folds at most this share, or FOLD_MIN edges (over FOLD_DEG: a margin for
#: the poses that mix keys); every sweep smooths the key's own motion too (a lid's closing, a lip's lift).
FOLD_SHARE = 0.0005
FOLD_MIN = 1
#: Most relaxation sweeps per key, and how far each moves a vertex towards its neighbours' mean.
RELAX_STEPS = 60
RELAX_RATE = 0.5
#: While a key still folds, its relaxed set grows by a ring every GROW_EVERY sweeps, up to ZONE_RINGS rings
#: from the first folded edges.
GROW_EVERY = 8
#: Folds are looked for only at vertices whose motion is off their neighbours' mean by this share of their
#: edges' length (a crease of 35° across an edge puts its ends about 0.3 off).
SCREEN = 0.05
ZONE_RINGS = 10


class FoldRelax:
    """The relaxation of keys on one mesh: its flat edges and its neighbour map, made once.

    Parameters
    ----------
    V : (n, 3) array
        Rest positions (any frame; the keys' displacements in the same one).
    T : (t, 3) int array
    pinned : (n,) bool array
        Vertices whose motion is never changed (eyeballs: rigid; parts that never move).
    """

    def __init__(self, V, T, pinned):
        from scipy.sparse import diags

        self.V, self.T = V, np.asarray(T, np.int64)
        pairs = edge_face_pairs(self.T)
        self.budget = max(FOLD_MIN, int(FOLD_SHARE * len(pairs)))
        self.limit = max(LIMIT_MIN, int(LIMIT_SHARE * len(pairs)))
        pairs = pairs[turn_degrees(V, self.T, pairs) < FLAT_DEG]
        self.faces, local = np.unique(pairs, return_inverse=True)  # the triangles at flat edges
        self.pairs = local.reshape(pairs.shape)
        self.cos_fold = np.cos(np.radians(FOLD_DEG))
        # Cotangent weights (clamped positive): on ICT's dense, stretched lip and lid rims the plain mean of
        # the neighbours folded them further (AU27's skin folds 22 -> 82); these follow the surface's shape.
        L = cotan_laplacian(V, self.T)
        W = (diags(L.diagonal()) - L).tocsr()
        self.ring = W.copy()  # neighbours (for growing the relaxed set by one ring)
        self.ring.data[:] = 1.0
        self.mean = (diags(1.0 / np.maximum(np.asarray(W.sum(axis=1)).ravel(), 1e-300)) @ W).tocsr()
        self.free = ~np.asarray(pinned, bool)
        self.corners = self.T[self.faces[self.pairs]].reshape(len(self.pairs), 6)
        length = np.linalg.norm(V[self.T] - V[np.roll(self.T, 1, axis=1)], axis=2).ravel()  # each corner's edge
        self.edge_length = np.bincount(self.T.ravel(), length, len(V)) / np.maximum(np.bincount(self.T.ravel(), minlength=len(V)), 1)
        self.edge_piece = connected_components(len(V), self.T)[self.T[self.faces[self.pairs[:, 0]], 0]]
        self.piece_edges = np.bincount(self.edge_piece)

    def folded(self, d):
        """The flat edges (indices into :attr:`pairs`) that displacement ``d`` (n, 3) folds.

        Only edges at a vertex whose motion is off its neighbours' mean by SCREEN of its edges' length are
        measured: a fold is a crease in the motion, a smooth motion (most of every key) folds nothing.
        """
        bent = np.linalg.norm(self.mean @ d - d, axis=1) > SCREEN * self.edge_length
        some = np.nonzero(bent[self.corners].any(axis=1))[0]
        if not len(some):
            return some
        faces, at = np.unique(self.pairs[some], return_inverse=True)
        nrm = unit_rows(triangle_cross(self.V + d, self.T[self.faces[faces]]))
        at = at.reshape(-1, 2)
        return some[(nrm[at[:, 0]] * nrm[at[:, 1]]).sum(-1) < self.cos_fold]

    def _grow(self, mask, rings=1):
        for _ in range(rings):
            mask = mask | (self.ring @ mask.astype(np.float64) > 0)
        return mask

    def relax(self, D, keys=None, budget=None):
        """Relax displacements ``D`` (n, k, 3) in place where they fold more than ``budget`` edges (default:
        :attr:`budget`), only ``keys`` (indices) if given; whether any key was changed."""
        budget = self.budget if budget is None else budget
        changed = False
        for key in range(D.shape[1]) if keys is None else keys:
            edges = self.folded(D[:, key])
            if len(edges) > budget:
                self._relax_pieces(D[:, key], edges, budget)
                changed = True
        return changed

    def _relax_pieces(self, d, edges, budget):
        """Relax one key's folds piece by piece of the mesh, each piece to its share of ``budget`` (by its flat
        edges): a lash strip folding does not smooth the lid under it."""
        piece = self.edge_piece[edges]
        share = budget * self.piece_edges / max(self.piece_edges.sum(), 1)
        labels, counts = np.unique(piece, return_counts=True)
        for label, count in zip(labels, counts):
            if count > share[label]:
                self._relax_key(d, edges[piece == label], int(share[label]))

    def _relax_key(self, d, edges, budget):
        """Relax one key's displacement ``d`` (n, 3) in place, starting from its folded ``edges``; the folds
        left. Works on the vertices within ZONE_RINGS of them alone (and the rings around, read only)."""
        hit = np.zeros(len(self.V), bool)
        hit[self.T[self.faces[self.pairs[edges]]].ravel()] = True
        zone = self._grow(hit, ZONE_RINGS)
        cols = np.nonzero(self._grow(zone, 2))[0]  # the zone and two rings around it (its edges' far corners)
        local = np.full(len(self.V), -1)
        local[cols] = np.arange(len(cols))
        ring, mean = self.ring[cols][:, cols], self.mean[cols][:, cols]
        movable = self.free[cols] & zone[cols]
        faces, pair_faces = np.unique(self.pairs[zone[self.corners].any(axis=1)], return_inverse=True)
        tri = local[self.T[self.faces[faces]]]  # the triangles at the zone's flat edges
        pair_faces = pair_faces.reshape(-1, 2)
        X, dl = self.V[cols], d[cols]

        def folded():
            nrm = triangle_cross(X + dl, tri)
            nrm /= np.maximum(np.linalg.norm(nrm, axis=-1, keepdims=True), 1e-300)
            return np.nonzero((nrm[pair_faces[:, 0]] * nrm[pair_faces[:, 1]]).sum(-1) < self.cos_fold)[0]

        def grow(mask):
            return mask | (ring @ mask.astype(np.float64) > 0)

        at = np.zeros(len(cols), bool)
        at[local[self.T[self.faces[self.pairs[edges]]].ravel()]] = True
        region = grow(at) & movable
        e = folded()
        best, best_d = len(e), dl.copy()  # never worse than as bound
        for step in range(RELAX_STEPS):
            if len(e) <= budget:
                break
            at[:] = False
            at[tri[pair_faces[e]].ravel()] = True
            region |= grow(at) & movable
            if step and not step % GROW_EVERY:  # still folding: relax a wider ring
                region = grow(region) & movable
            moved = np.nonzero(region)[0]
            dl[moved] += RELAX_RATE * (mean @ dl - dl)[moved]
            e = folded()
            if len(e) < best:
                best, best_d = len(e), dl.copy()
        d[cols] = best_d
        return best
