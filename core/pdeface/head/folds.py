"""Keys that do not crease the user's mesh: each key's motion relaxed where it would fold an edge (issue #40).

A key folds an edge when its two triangles, nearly flat at rest (turning by less than ``FLAT_DEG``), turn by
more than ``FOLD_DEG`` in the key. On the MakeHuman development set and ICT's head the folds sit where one
motion meets another across a few vertices: the inner lips' rim against the lining, the lid margins, the
jaw's split gums (turned against the fixed upper ones), lashes anchored on different lid vertices. There the
key's displacement steps from one vertex to the next; :class:`FoldRelax` smooths it (each vertex towards its
neighbours' mean displacement, cotangent weights) on the folded edges' vertices and one ring around them, until no
edge folds, it folds no fewer for ``STALL_STEPS`` sweeps or ``RELAX_STEPS`` have run. Elsewhere the key is left
exactly as bound. Every key is screened at once, and every key's folding pieces relaxed side by side (issue #35: the
27k-vertex head's 72 keys).
"""
from __future__ import annotations

import numpy as np

from ..geometry import unit_rows
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
#: A job (a key's piece) that has not folded fewer edges for STALL_STEPS sweeps stops (ICT's split gums: no fewer
#: after 19 sweeps of 60; at 3 * GROW_EVERY african-male-old's AU27 stopped at 16 edges over 40°, 12 at 5 *).
STALL_STEPS = 5 * GROW_EVERY
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
        from scipy.sparse import csr_matrix, diags

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
        W.eliminate_zeros()
        W.sort_indices()
        self.mean = (diags(1.0 / np.maximum(np.asarray(W.sum(axis=1)).ravel(), 1e-300)) @ W).tocsr()
        self.mean.sort_indices()
        self.free = ~np.asarray(pinned, bool)
        self.ball_centre, self.ball_radius = np.zeros((len(V), 3)), np.zeros(len(V))  # none: keep_outside
        self.corners = self.T[self.faces[self.pairs]].reshape(len(self.pairs), 6)
        # Each vertex's flat edges (the screen's and the zones' look-up), and each edge's triangles' corners.
        self.vertex_pairs = csr_matrix((np.ones(self.corners.size, bool), (self.corners.ravel(), np.repeat(
            np.arange(len(self.pairs)), 6))), shape=(len(V), len(self.pairs)))
        length = np.linalg.norm(V[self.T] - V[np.roll(self.T, 1, axis=1)], axis=2).ravel()  # each corner's edge
        self.edge_length = np.bincount(self.T.ravel(), length, len(V)) / np.maximum(np.bincount(self.T.ravel(), minlength=len(V)), 1)
        self.edge_piece = connected_components(len(V), self.T)[self.T[self.faces[self.pairs[:, 0]], 0]]
        self.piece_edges = np.bincount(self.edge_piece)

    def folded(self, d):
        """The flat edges (indices into :attr:`pairs`) that displacement ``d`` (n, 3) folds."""
        return self.folded_keys(d[:, None])[0]

    def folded_keys(self, D, keys=None):
        """Per key of ``D`` (n, k, 3) (only ``keys``, indices, if given): the flat edges (indices into :attr:`pairs`,
        ascending) its displacement folds.

        Only edges at a vertex whose motion is off its neighbours' mean by SCREEN of its edges' length are
        measured: a fold is a crease in the motion, a smooth motion (most of every key) folds nothing. All keys
        are screened at once (one sparse product), and only the edges at creased vertices measured.
        """
        keys = np.arange(D.shape[1]) if keys is None else np.asarray(keys, np.int64)
        every = len(keys) == D.shape[1] and (keys == np.arange(D.shape[1])).all()
        n, k, n_pairs = len(self.V), len(keys), len(self.pairs)
        Dk = D if every else D.take(keys, axis=1)  # (D[:, keys] is laid out key-major: slow to flatten)
        Dk = np.ascontiguousarray(Dk).reshape(n, 3 * k)
        off = (self.mean @ Dk - Dk).reshape(n, k, 3)
        bent_v, bent_key = np.nonzero(np.einsum("nkc,nkc->nk", off, off) > (SCREEN * self.edge_length[:, None]) ** 2)
        pair, at = _rows_gather(self.vertex_pairs, bent_v)
        ids = np.unique(bent_key[at] * n_pairs + pair)  # (key, edge) at a creased vertex, each once
        slot, pair = np.divmod(ids, n_pairs)
        faces, pair_faces = np.unique(slot[:, None] * len(self.faces) + self.pairs[pair], return_inverse=True)
        face_slot, face = np.divmod(faces, len(self.faces))
        tri = self.T[self.faces[face]]  # (f, 3): each (key, triangle) once
        X = self.V[tri] + Dk.reshape(n, k, 3)[tri, face_slot[:, None]]
        nrm = unit_rows(np.cross(X[:, 1] - X[:, 0], X[:, 2] - X[:, 0]))
        pair_faces = pair_faces.reshape(-1, 2)
        fold = (nrm[pair_faces[:, 0]] * nrm[pair_faces[:, 1]]).sum(-1) < self.cos_fold
        return np.split(pair[fold], np.searchsorted(slot[fold], np.arange(1, k)))

    def relax(self, D, keys=None, budget=None, steps=None):
        """Relax displacements ``D`` (n, k, 3) in place where they fold more than ``budget`` edges (default:
        :attr:`budget`), only ``keys`` (indices) if given, in at most ``steps`` sweeps (default: RELAX_STEPS);
        whether any key was changed.

        Each key is relaxed piece by piece of the mesh, each piece to its share of ``budget`` (by its flat edges):
        a lash strip folding does not smooth the lid under it. Every (key, piece) is worked on at once.
        """
        budget = self.budget if budget is None else budget
        keys = np.arange(D.shape[1]) if keys is None else np.asarray(keys, np.int64)
        if not len(keys):
            return False
        share = budget * self.piece_edges / max(self.piece_edges.sum(), 1)
        jobs, changed = [], False
        for key, edges in zip(keys, self.folded_keys(D, keys)):
            if len(edges) <= budget:
                continue
            changed = True
            piece = self.edge_piece[edges]
            labels, counts = np.unique(piece, return_counts=True)
            jobs += [(key, edges[piece == label], int(share[label]))
                     for label, count in zip(labels, counts) if count > share[label]]
        if jobs:
            self._relax_jobs(D, jobs, RELAX_STEPS if steps is None else steps)
        return changed

    def _relax_jobs(self, D, jobs, steps=RELAX_STEPS):
        """Relax ``jobs`` ``(key, folded edges of one piece, budget)`` of ``D`` (n, k, 3) in place; per job the
        folds left (never more than as bound).

        Each job works on the vertices within ZONE_RINGS of its folded edges alone (and two rings around them, read
        only), sweep after sweep until it folds at most its budget. The jobs' vertices are laid side by side as
        (job, vertex) ids, so every sweep of all of them is one sparse product and one pass over their triangles.
        """
        from scipy.sparse import csr_matrix

        n, n_pairs = len(self.V), len(self.pairs)
        key_of = np.array([key for key, _, _ in jobs])
        budgets = np.array([b for _, _, b in jobs])
        seeds = [j * n + self.T[self.faces[self.pairs[e]]].ravel() for j, (_, e, _) in enumerate(jobs)]
        hit = np.unique(np.concatenate(seeds))
        zone = self._rings(hit, ZONE_RINGS, len(jobs))
        cols = self._rings(zone, 2, len(jobs))  # the zone and two rings around it (its edges' far corners), sorted
        job, vertex = np.divmod(cols, n)
        m = len(cols)
        # The neighbours' mean among the jobs' vertices: each job's block of the mesh's.
        pos, row = _rows_entries(self.mean, vertex)
        nb = job[row] * n + self.mean.indices[pos]
        at = np.minimum(np.searchsorted(cols, nb), m - 1)
        inside = cols[at] == nb
        mean = csr_matrix((self.mean.data[pos[inside]], (row[inside], at[inside])), shape=(m, m))
        ring = mean.copy()
        ring.data[:] = 1.0
        movable = self.free[vertex] & np.isin(cols, zone, assume_unique=True)
        # The flat edges with a corner in a zone, their triangles (each once) in local indices.
        pair, row = _rows_gather(self.vertex_pairs, zone % n)
        vpairs = np.unique(zone[row] // n * n_pairs + pair)
        pair_job, pair = np.divmod(vpairs, n_pairs)
        faces, pair_faces = np.unique(pair_job[:, None] * len(self.T) + self.faces[self.pairs[pair]],
                                      return_inverse=True)
        pair_faces = pair_faces.reshape(-1, 2)
        face_job, face = np.divmod(faces, len(self.T))
        tri = np.searchsorted(cols, face_job[:, None] * n + self.T[face])  # (f, 3) local
        X, dl = self.V[vertex], D[vertex, key_of[job]]
        nrm = np.zeros((len(faces), 3))
        fold = np.zeros(len(pair_job), bool)
        row_faces = csr_matrix((np.ones(tri.size), (tri.ravel(), np.repeat(np.arange(len(faces)), 3))),
                               shape=(m, len(faces)))
        pair_of = np.repeat(np.arange(len(pair_job)), 2)
        face_pairs = csr_matrix((np.ones(pair_faces.size), (pair_faces.ravel(), pair_of)),
                                shape=(len(faces), len(pair_job)))

        def folded(rows):  # the folds once ``rows`` moved: only their triangles' edges measured again
            at = _once(_rows_gather(row_faces, rows)[0], len(nrm))
            P = X[tri[at]] + dl[tri[at]]
            nrm[at] = unit_rows(np.cross(P[:, 1] - P[:, 0], P[:, 2] - P[:, 0]))
            at = _once(_rows_gather(face_pairs, at)[0], len(fold))
            fold[at] = (nrm[pair_faces[at, 0]] * nrm[pair_faces[at, 1]]).sum(-1) < self.cos_fold
            return np.bincount(pair_job[fold], minlength=len(jobs))

        ball = np.nonzero(self.ball_radius[vertex] > 0)[0]  # rows kept out of an eyeball
        in_ball = np.zeros(m, bool)
        in_ball[ball] = True
        mark = np.zeros(m, bool)
        mark[np.searchsorted(cols, np.concatenate(seeds))] = True
        region = (mark | (ring @ mark.astype(np.float64) > 0)) & movable
        count = folded(np.arange(m))
        best, best_d = count.copy(), dl.copy()  # never worse than as bound
        since = np.zeros(len(jobs), np.int64)  # sweeps since each job's best
        was = None
        for step in range(steps):
            live = (count > budgets) & (since < STALL_STEPS)
            if not live.any():
                break
            if was is None or (live != was).any():  # a job done: the sweeps work on the others alone
                was = live
                rows = np.nonzero(live[job])[0]
                ring_live, mean_live = ring[rows], mean[rows]
            mark[:] = False
            mark[tri[pair_faces[fold & live[pair_job]]].ravel()] = True
            region[rows] |= (mark[rows] | (ring_live @ mark.astype(np.float64) > 0)) & movable[rows]
            if step and not step % GROW_EVERY:  # still folding: relax a wider ring
                region[rows] |= (ring_live @ region.astype(np.float64) > 0) & movable[rows]
            moved = region[rows]
            dl[rows[moved]] += RELAX_RATE * (mean_live[moved] @ dl - dl[rows[moved]])
            moved = rows[moved]
            self._keep_out(X, dl, vertex, moved[in_ball[moved]])
            count = folded(moved)
            better = count < best
            since = np.where(better, 0, since + live)
            if better.any():
                rows_better = better[job]
                best_d[rows_better] = dl[rows_better]
                best = np.minimum(best, count)
        D[vertex, key_of[job]] = best_d
        return best

    def keep_outside(self, vertices, centre, radius):
        """Keep ``vertices`` (indices) out of the ball ``centre``, ``radius`` (an eyeball: the lids over it) while
        relaxing: a relaxed lid folded again where the eyeball's guard pushed it back out (a glance down)."""
        self.ball_centre[vertices] = centre
        self.ball_radius[vertices] = radius

    def _keep_out(self, X, d, vertex, rows):
        """Rows ``rows`` of displacements ``d`` (of vertices ``vertex``, at rest ``X``) inside their ball put back on
        its surface, in place."""
        c, r = self.ball_centre[vertex[rows]], self.ball_radius[vertex[rows], None]
        p = X[rows] + d[rows] - c
        rho = np.linalg.norm(p, axis=1, keepdims=True)
        d[rows] = np.where(rho < r, c + p * (r / np.maximum(rho, 1e-12)) - X[rows], d[rows])

    def _rings(self, ids, rings, jobs):
        """(job, vertex) ids ``ids`` and every id within ``rings`` rings of them (the same job's), sorted."""
        n = len(self.V)
        seen = np.zeros(jobs * n, bool)
        seen[ids] = True
        frontier = ids
        for _ in range(rings):
            nb, row = _rows_gather(self.mean, frontier % n)
            new = frontier[row] // n * n + nb
            new = new[~seen[new]]
            seen[new] = True
            frontier = _once(new, len(seen))
        return np.flatnonzero(seen)


def _once(idx, size):
    """The distinct values of ``idx`` (all below ``size``), sorted: a mask's, no sort."""
    mask = np.zeros(size, bool)
    mask[idx] = True
    return np.flatnonzero(mask)


def _rows_entries(A, rows):
    """``(positions, slots)``: where the entries of CSR ``A``'s ``rows`` lie in its ``indices``/``data`` (row by row),
    and each entry's slot in ``rows``."""
    starts, counts = A.indptr[rows], np.diff(A.indptr)[rows]
    slot = np.repeat(np.arange(len(rows)), counts)
    return starts[slot] + np.arange(len(slot)) - (np.cumsum(counts) - counts)[slot], slot


def _rows_gather(A, rows):
    """``(columns, slots)`` of every entry of CSR ``A``'s ``rows`` (each entry's slot in ``rows``)."""
    pos, slot = _rows_entries(A, rows)
    return A.indices[pos], slot
