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

from ..geometry import triangle_cross
from ..mesh import connected_components, cotan_laplacian, edge_face_pairs, turn_degrees

#: Edges turning by less than this at rest are flat; a key folds one that then turns by more than FOLD_DEG
#: (below the issue's 40°: a margin for the other keys' shapes and poses that mix them).
FLAT_DEG = 20.0
FOLD_DEG = 35.0
#: A key is left as bound while it folds at most this share of the mesh's edges, or FOLD_MIN edges (the issue's
#: 0.1 % and 2, counted over FOLD_DEG: every sweep smooths the key's own motion too, a lid's closing, a lip's lift).
FOLD_SHARE = 0.001
FOLD_MIN = 2
#: Most relaxation sweeps per key, and how far each moves a vertex towards its neighbours' mean.
RELAX_STEPS = 60
RELAX_RATE = 0.5
#: While a key still folds, its relaxed set grows by a ring every GROW_EVERY sweeps, up to ZONE_RINGS rings
#: from the first folded edges.
GROW_EVERY = 8
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
        pairs = pairs[turn_degrees(V, self.T, pairs) < FLAT_DEG]
        self.faces, local = np.unique(pairs, return_inverse=True)  # the triangles at flat edges
        self.pairs = local.reshape(pairs.shape)
        self.cos_fold = np.cos(np.radians(FOLD_DEG))
        self.budget = max(FOLD_MIN, int(FOLD_SHARE * len(edge_face_pairs(self.T))))
        # Cotangent weights (clamped positive): on ICT's dense, stretched lip and lid rims the plain mean of
        # the neighbours folded them further (AU27's skin folds 22 -> 82); these follow the surface's shape.
        L = cotan_laplacian(V, self.T)
        W = (diags(L.diagonal()) - L).tocsr()
        self.ring = W.copy()  # neighbours (for growing the relaxed set by one ring)
        self.ring.data[:] = 1.0
        self.mean = (diags(1.0 / np.maximum(np.asarray(W.sum(axis=1)).ravel(), 1e-300)) @ W).tocsr()
        self.free = ~np.asarray(pinned, bool)
        self.edge_piece = connected_components(len(V), self.T)[self.T[self.faces[self.pairs[:, 0]], 0]]
        self.piece_edges = np.bincount(self.edge_piece)

    def folded(self, D, pairs=None):
        """``(edge, key)`` indices (into ``pairs``, default all flat edges) of the flat edges folded by
        displacements ``D`` (n, k, 3)."""
        pairs = self.pairs if pairs is None else pairs
        if not len(pairs):
            return np.zeros((0,), np.int64), np.zeros((0,), np.int64)
        faces, local = np.unique(pairs, return_inverse=True)
        tri = self.T[self.faces[faces]]
        nrm = triangle_cross(self.V[:, None] + D, tri) if D.ndim == 3 else triangle_cross(self.V + D, tri)
        nrm /= np.maximum(np.linalg.norm(nrm, axis=-1, keepdims=True), 1e-300)
        local = local.reshape(pairs.shape)
        cos = (nrm[local[:, 0]] * nrm[local[:, 1]]).sum(-1)  # (e, k) or (e,)
        return np.nonzero(cos < self.cos_fold)

    def _grow(self, mask, rings=1):
        for _ in range(rings):
            mask = mask | (self.ring @ mask.astype(np.float64) > 0)
        return mask

    def relax(self, D, keys=None, budget=None, chunk=16):
        """Relax displacements ``D`` (n, k, 3) in place where they fold more than ``budget`` edges (default:
        :attr:`budget`), only ``keys`` (indices) if given; whether any key was changed."""
        budget = self.budget if budget is None else budget
        keys = np.arange(D.shape[1]) if keys is None else np.asarray(keys, np.int64)
        changed = False
        for start in range(0, len(keys), chunk):  # which keys fold (several at once: one gather)
            some = keys[start:start + chunk]
            e, k = self.folded(D[:, some])
            over, counts = np.unique(k, return_counts=True)
            for j in over[counts > budget]:
                self._relax_pieces(D[:, some[j]], e[k == j], budget)
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
        """Relax one key's displacement ``d`` (n, 3) in place, starting from its folded ``edges``."""
        n = len(self.V)
        hit = np.zeros(n, bool)
        hit[self.T[self.faces[self.pairs[edges]]].ravel()] = True
        zone = self._grow(hit, ZONE_RINGS)  # the flat edges that the relaxation can change
        corners = self.T[self.faces[self.pairs]].reshape(len(self.pairs), 6)
        pairs = self.pairs[zone[corners].any(axis=1)]
        region = self._grow(hit) & self.free
        rows = np.nonzero(zone)[0]
        best, best_d = len(self.folded(d, pairs)[0]), d[rows].copy()  # never worse than as bound
        for step in range(RELAX_STEPS):
            e = self.folded(d, pairs)[0]
            if len(e) < best:
                best, best_d = len(e), d[rows].copy()
            if len(e) <= budget:
                return len(e)
            hit[:] = False
            hit[self.T[self.faces[pairs[e]]].ravel()] = True
            region |= self._grow(hit) & self.free
            if step and not step % GROW_EVERY:  # still folding: relax a wider ring
                region = self._grow(region) & self.free & zone
            moved = np.nonzero(region)[0]
            d[moved] += RELAX_RATE * (self.mean[moved] @ d - d[moved])
        if len(self.folded(d, pairs)[0]) > best:
            d[rows] = best_d
        return best
