"""Keys that do not crease the user's mesh: each key's motion relaxed where it would fold an edge (issue #40).

A key folds an edge when its two triangles, nearly flat at rest (turning by less than ``FLAT_DEG``), turn by
more than ``FOLD_DEG`` in the key. On the MakeHuman development set and ICT's head the folds sit where one
motion meets another across a few vertices: the inner lips' rim against the lining, the lid margins, the
jaw's split gums (turned against the fixed upper ones), lashes anchored on different lid vertices. There the
key's displacement steps from one vertex to the next; :class:`FoldRelax` smooths it (each vertex towards its
neighbours' mean displacement, cotangent weights) on the folded edges' vertices and one ring around them, until no
edge folds, it folds no fewer for ``STALL_STEPS`` sweeps or ``RELAX_STEPS`` have run (the binding's first
relaxation looks at the folds every ``SWEEPS_PER_LOOK`` sweeps); it keeps the sweep folding fewest, of those the one
folding fewest past the issue's ``LIMIT_DEG``. Elsewhere the key is left exactly as bound. Every
key is screened at once, and every key's folding pieces relaxed side by side (issue #35: the 27k-vertex head's 72
keys).
"""
from __future__ import annotations

import numpy as np

from ..geometry import row_norms
from ..mesh import connected_components, cotan_laplacian, edge_face_pairs, turn_degrees

#: Edges turning by less than this at rest are flat; a key folds one that then turns by more than FOLD_DEG
#: (below the issue's 40°: a margin for the other keys' shapes and poses that mix them).
FLAT_DEG = 20.0
FOLD_DEG = 35.0
#: The issue's limit: a key may fold this share of the mesh's edges, or LIMIT_MIN edges (over 40°).
LIMIT_SHARE = 0.001
LIMIT_MIN = 2
LIMIT_DEG = 40.0
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
#: ... or SETTLE_STEPS where its kept sweep folds no more edges over the issue's LIMIT_DEG than its budget: only the
#: margin's (FOLD_DEG to LIMIT_DEG) are left, and chasing them through a plateau (the region growing all the while)
#: smoothed parted lips shut. african-asian-female-young-mm's AU27 folded 6 edges over 35° after 4 sweeps (6
#: allowed: done) as bound from the model in memory, 8 (2 at 36.0-36.3°; 4 over 40°) from the model read back from
#: its file (the descriptors rounded to 0.025 mm), and no fewer until sweep 38: the file's rounding moved the key
#: 9.1 mm at the lips (gap 0.47 -> 0.42 eye distances); settled, both keep sweep 4, 1.25 mm apart (the region's
#: seeds: 55 or 57 edges over 35° as bound). Settling every piece within its share of the issue's limit instead, at
#: 1-2 * GROW_EVERY ICT's jaw-sideways keys stopped at 30-31 edges over 35°, not 22 (a plateau of 17-24 sweeps), and
#: at 3 * african-male-old's AU27 stopped at 21 edges from the file, went on to 20 from memory (5.8 mm apart).
SETTLE_STEPS = 3 * GROW_EVERY
#: Folds are looked for only at vertices whose motion is off their neighbours' mean by this share of their
#: edges' length (a crease of 35° across an edge of a flat, even mesh puts its ends about 0.3 off; at 0.05 the screen
#: missed asian-male-young's AU17, 20 edges over 40° at the mouth's corners, bent 5-18° at rest, long thin
#: triangles, their corners 0.005-0.045 off; at 0.03 it finds them: 20 -> 0). ICT's 82 keys (26.7k vertices) cost 1.08
#: times the CPU they did at 0.05 (at 0.02 1.22 times).
SCREEN = 0.03
ZONE_RINGS = 10
#: The binding's first relaxation measures its folds every SWEEPS_PER_LOOK sweeps (issue #35: ICT's 72 keys' relaxation
#: 0.41 -> 0.27 s CPU; its keys move at most 0.14 mm on the skin, 0.9 mm on the lashes). The lids' second one looks at
#: every sweep: it stops at the first within the limit (each sweep opens a closed lid a little; at 2
#: asian-male-young's AU45 closure fell from 0.86 to 0.79). GROW_EVERY and STALL_STEPS must be multiples of it (the
#: region grows and a piece stalls only on sweeps that look).
SWEEPS_PER_LOOK = 2
#: The screen's and the relaxation's look-up tables (one entry per (key or job, vertex, edge or triangle) id) hold at
#: most this many entries (a mask 8 MB, an int32 table 32 MB; ICT's largest: 4.8 M): past it, on a mesh of a few
#: hundred thousand vertices, the ids are found by a sort and a binary search instead (the same ids, slower).
TABLE_MAX = 1 << 23
#: The screen works on this many floats of every key's rows at a time (a block of vertices in cache: 1 MB).
SCREEN_BLOCK = 1 << 18
assert GROW_EVERY % SWEEPS_PER_LOOK == 0 and STALL_STEPS % SWEEPS_PER_LOOK == 0 and SETTLE_STEPS % SWEEPS_PER_LOOK == 0


class Screen:
    """What a relaxation of every key of ``D`` screened (:attr:`bent`, (n, k) bool: the (vertex, key) off their
    neighbours' mean; :attr:`folds`: ``(ids, folded)``, the (key, flat edge) ids ``key * len(pairs) + edge`` it
    measured, ascending, and whether each folded) and the (vertex, key) pairs moved since (:meth:`moved`;
    :attr:`moved_mask`): a later relaxation of the same ``D`` screens those and their neighbours again, and measures
    only the edges at a moved pair or not measured before, not every edge of its keys (the binding's second look
    after the lids close)."""

    def __init__(self):
        self.bent, self.folds, self.moved_mask, self.pending = None, None, None, []

    def moved(self, vertices, keys):
        """Vertices ``vertices`` of keys ``keys`` (index arrays of one length) may have moved."""
        vertices, keys = np.asarray(vertices, np.int64).ravel(), np.asarray(keys, np.int64).ravel()
        self.pending.append((vertices, keys))
        if self.moved_mask is not None:
            self.moved_mask[vertices, keys] = True


class FoldRelax:
    """The relaxation of keys on one mesh: its flat edges and its neighbour map, made once.

    Parameters
    ----------
    V : (n, 3) array
        Rest positions (any frame; the keys' displacements in the same one).
    T : (t, 3) int array
    pinned : (n,) bool array
        Vertices whose motion is never changed (eyeballs: rigid; parts that never move).
    laplacian : sparse (n, n) matrix, optional
        ``cotan_laplacian(V, T)`` where already built (the binding's).
    pieces : (n,) int array, optional
        ``connected_components(len(V), T)`` where already found (the binding's parts').
    """

    def __init__(self, V, T, pinned, laplacian=None, pieces=None):
        from scipy.sparse import csr_matrix, diags

        self.V, self.T = V, np.asarray(T, np.int64)
        pairs = edge_face_pairs(self.T)
        self.budget = max(FOLD_MIN, int(FOLD_SHARE * len(pairs)))
        self.limit = max(LIMIT_MIN, int(LIMIT_SHARE * len(pairs)))
        pairs = pairs[turn_degrees(V, self.T, pairs) < FLAT_DEG]
        self.faces = _once(pairs.ravel(), len(self.T))  # the triangles at flat edges
        self.pairs = _slots(self.faces, len(self.T))[pairs]
        self.cos_fold = np.cos(np.radians(FOLD_DEG))
        self.cos_limit = np.cos(np.radians(LIMIT_DEG))
        # Cotangent weights (clamped positive): on ICT's dense, stretched lip and lid rims the plain mean of
        # the neighbours folded them further (AU27's skin folds 22 -> 82); these follow the surface's shape.
        L = cotan_laplacian(V, self.T) if laplacian is None else laplacian
        W = (diags(L.diagonal()) - L).tocsr()
        W.eliminate_zeros()
        W.sort_indices()
        # each row scaled by its sum's inverse in place of a product by a diagonal (the same numbers, sorted already)
        scale = 1.0 / np.maximum(np.asarray(W.sum(axis=1)).ravel(), 1e-300)
        self.mean = W
        self.mean.data *= np.repeat(scale, np.diff(W.indptr))
        self.mean.eliminate_zeros()  # (as the product drops a weight whose scaled value underflows)
        self._mean32 = self.mean.astype(np.float32)  # the screen's (see _screen)
        self._most_neighbours = int(np.diff(self.mean.indptr).max(initial=0))
        self.free = ~np.asarray(pinned, bool)
        self.ball_centre, self.ball_radius = np.zeros((len(V), 3)), np.zeros(len(V))  # none: keep_outside
        self.corners = np.take(self.T, self.faces[self.pairs].ravel(), axis=0).reshape(len(self.pairs), 6)
        # Each vertex's flat edges (the screen's and the zones' look-up), and each edge's triangles' corners.
        self.vertex_pairs = csr_matrix((np.ones(self.corners.size, bool), (self.corners.ravel(), np.repeat(
            np.arange(len(self.pairs)), 6))), shape=(len(V), len(self.pairs)))
        # each corner's edge (numpy.take's gathers: 3 times faster than indexing's)
        length = row_norms(np.take(V, self.T, axis=0) - np.take(V, self.T[:, [2, 0, 1]], axis=0)).ravel()
        self.edge_length = (np.bincount(self.T.ravel(), length, len(V))
                            / np.maximum(np.bincount(self.T.ravel(), minlength=len(V)), 1))
        pieces = connected_components(len(V), self.T) if pieces is None else pieces
        self.edge_piece = pieces[self.T[self.faces[self.pairs[:, 0]], 0]]
        self.piece_edges = np.bincount(self.edge_piece)

    def folded(self, d):
        """The flat edges (indices into :attr:`pairs`) that displacement ``d`` (n, 3) folds."""
        return self.folded_keys(d[:, None])[0]

    def folded_keys(self, D, keys=None, bent=None, screen=None):
        """Per key of ``D`` (n, k, 3) (only ``keys``, indices, if given): the flat edges (indices into :attr:`pairs`,
        ascending) its displacement folds; ``bent``: the screen's (n, keys) bool matrix where already known;
        ``screen``: a :class:`Screen` of ``D`` whose folds it keeps (every key measured) or reads (some).

        Only edges at a vertex whose motion is off its neighbours' mean by SCREEN of its edges' length are
        measured: a fold is a crease in the motion, a smooth motion (most of every key) folds nothing. All keys
        are screened at once (one sparse product), and only the edges at creased vertices measured.
        """
        keys = np.arange(D.shape[1]) if keys is None else np.asarray(keys, np.int64)
        every = len(keys) == D.shape[1] and (keys == np.arange(D.shape[1])).all()
        k, n_pairs = len(keys), len(self.pairs)
        bent_v, bent_key = np.divmod(np.flatnonzero(self._bent(D, keys, every) if bent is None else bent), k)
        pair, at = _rows_gather(self.vertex_pairs, bent_v)
        ids = _once(bent_key[at] * n_pairs + pair, k * n_pairs)  # (key, edge) at a creased vertex, each once
        slot, pair = np.divmod(ids, n_pairs)
        if screen is not None and screen.folds is not None:  # measured before, no corner moved since: as then
            was, was_folded = screen.folds
            key_ids = keys[slot] * n_pairs + pair
            at = np.minimum(np.searchsorted(was, key_ids), max(len(was) - 1, 0))
            kept = (was[at] == key_ids) if len(was) else np.zeros(len(ids), bool)
            # each corner's (vertex, key) read from the flat mask: faster than numpy's two-array indexing
            moved = np.take(screen.moved_mask.reshape(-1),
                            np.take(self.corners, pair, axis=0) * D.shape[1] + keys[slot][:, None])
            for corner in range(6):  # (corner by corner: a reduction over an axis of 6 is slow in numpy)
                kept &= ~moved[:, corner]
            fold = np.empty(len(ids), bool)
            fold[kept] = was_folded[at[kept]]
            measure = ~kept
            fold[measure] = self._folds_at(D, keys, slot[measure], pair[measure])
        else:
            fold = self._folds_at(D, keys, slot, pair)
            if screen is not None and every:
                screen.folds, screen.moved_mask = (ids, fold), np.zeros((len(D), k), bool)
        return np.split(pair[fold], np.searchsorted(slot[fold], np.arange(1, k)))

    def _folds_at(self, D, keys, slot, pair):
        """Whether displacements ``D`` (n, k, 3) of ``keys[slot]`` fold flat edges ``pair`` (indices into
        :attr:`pairs`), each (slot, pair) once: each (key, triangle) measured once."""
        # (triangle, key) ids, triangle-major: a triangle's keys' rows of D lie side by side (3x fewer cache misses)
        faces, pair_faces = _once_inverse(self.pairs[pair] * len(keys) + slot[:, None], len(keys) * len(self.faces))
        face, face_slot = np.divmod(faces, len(keys))
        tri = np.take(self.T, self.faces[face], axis=0)  # (f, 3): each (key, triangle) once
        X = np.take(self.V, tri, axis=0) + _rows_of(D, tri, keys[face_slot][:, None])  # the corners' positions
        X = np.ascontiguousarray(X.transpose(1, 2, 0))  # (corner, coordinate, triangle): coordinates first
        pair_faces = pair_faces.reshape(-1, 2).T
        return _cosines(_unit_normals(*X), *pair_faces) < self.cos_fold

    def _screen(self, D, keys, every):
        """``(vertices, slots in keys)`` where displacements ``D`` (n, k, 3) of ``keys`` (``every`` key, or some) are
        off their neighbours' mean by more than SCREEN of the vertex's edges' length (see :meth:`_bent`)."""
        return np.nonzero(self._bent(D, keys, every))

    def _bent(self, D, keys, every):
        """(n, len(keys)) bool: where displacements ``D`` (n, k, 3) of ``keys`` (``every`` key, or some) are off their
        neighbours' mean by more than SCREEN of the vertex's edges' length.

        In float32 (half the memory to stream), with a margin for its rounding: the few (vertex, key) within it of the
        line are measured again in float64, as a float64 screen would (the same sums in the same order): the same set.
        """
        from scipy.sparse import csr_matrix

        n, k = len(D), len(keys)
        src = (D if every else D[:, keys]).reshape(n, 3 * k)
        # Block by block of vertices (each block's rows stay in cache from one pass to the next): the float32 copy
        # and its largest value first, then the neighbours' mean, the offsets' squares and the lines.
        D32, largest = np.empty((n, 3 * k), np.float32), 0.0
        step = max(1, SCREEN_BLOCK // max(3 * k, 1))
        blocks = [slice(start, start + step) for start in range(0, n, step)]
        for block in blocks:
            rows = D32[block]
            rows[...] = src[block]
            largest = max(largest, float(rows.max(initial=0.0)), -float(rows.min(initial=0.0)))
        # float32's error in a (vertex, key)'s offset: a unit of rounding of the largest displacement per term of its
        # sum (a neighbour, itself, the cast), per axis; twice that is a wide margin
        margin = 2 * (self._most_neighbours + 3) * np.finfo(np.float32).eps * largest
        line = SCREEN * self.edge_length
        over = ((line + margin) ** 2).astype(np.float32)[:, None]
        under = (np.maximum(line - margin, 0.0) ** 2).astype(np.float32)[:, None]
        bent, near = np.empty((n, k), bool), []
        mean, at = self._mean32, self._mean32.indptr
        for block in blocks:
            start, stop = block.start, min(block.stop, n)
            # the block's rows, views of the matrix's arrays (slicing the matrix costs 0.2 ms a block)
            rows = csr_matrix((mean.data[at[start]:at[stop]], mean.indices[at[start]:at[stop]],
                               at[start:stop + 1] - at[start]), shape=(stop - start, n))
            off = rows @ D32
            off -= D32[block]
            off *= off  # the squares in place, summed axis by axis below: (x² + y²) + z², as before (2x faster)
            off = off.reshape(-1, k, 3)
            d2 = off[..., 0] + off[..., 1]
            d2 += off[..., 2]
            np.greater(d2, over[block], out=bent[block])
            # (the line's square rounds to no more than its margin's: the bent ones are all over the lower line)
            close = d2 > under[block]
            close ^= bent[block]
            near.append(np.flatnonzero(close) + block.start * k)
        near = np.concatenate([np.zeros(0, np.int64), *near])  # flat (vertex, key) ids, vertex-major
        if len(near):
            near_v, near_k = np.divmod(near, k)
            bent.reshape(-1)[near] = self._bent_exactly(D, near_v, keys[near_k])
        return bent

    def _bent_exactly(self, D, vertices, keys):
        """The float64 screen of (vertex, key) pairs of ``D`` (n, k, 3): the same sums in the same order."""
        pos, slot = _rows_entries(self.mean, vertices)
        terms = self.mean.data[pos, None] * _rows_of(D, self.mean.indices[pos], keys[slot])
        # each axis summed by bincount: entry after entry from 0, as numpy.add.at and the sparse product (4x faster)
        exact = np.stack([np.bincount(slot, terms[:, c], len(vertices)) for c in range(3)], axis=1)
        exact -= _rows_of(D, vertices, keys)
        exact = np.einsum("nc,nc->n", exact, exact)
        return exact > (SCREEN * self.edge_length[vertices]) ** 2

    def _bent_since(self, D, screen):
        """``screen``'s :attr:`~Screen.bent` brought up to ``D``: its moved pairs and their neighbours screened
        again."""
        if screen.pending:
            n = len(D)
            vertices, keys = (np.concatenate(a) for a in zip(*screen.pending))
            nb, slot = _rows_gather(self.mean, vertices)  # a vertex's screen reads its neighbours (a symmetric map)
            k = D.shape[1]  # (vertex, key) ids, vertex-major: a vertex's keys' rows of D lie side by side
            ids = _once(np.concatenate([vertices * k + keys, nb * k + keys[slot]]), k * n)
            screen.bent.reshape(-1)[ids] = self._bent_exactly(D, *np.divmod(ids, k))
            screen.pending = []
        return screen.bent

    def relax(self, D, keys=None, budget=None, steps=None, screen=None, unpinned=None, unpinned_keys=None, look=1,
              held=()):
        """Relax displacements ``D`` (n, k, 3) in place where they fold more than ``budget`` edges (default:
        :attr:`budget`), only ``keys`` (indices) if given, in at most ``steps`` sweeps (default: RELAX_STEPS; or
        (k,) ints, each key's, multiples of ``look``); whether any key was changed. ``unpinned`` (indices or a mask):
        pinned vertices that ``unpinned_keys`` (indices; default every key) may move (a pin some keys need, others
        not). The folds are measured (and each key's region grown, its best kept, its end decided) every ``look``
        sweeps (the measure costs more than a sweep; see SWEEPS_PER_LOOK). ``held``: ``(vertices, keys)`` pairs
        (indices; ``keys`` None: every key), vertices those keys relaxed here do not move (a coarse eye's closed lid
        margins in the keys that close it: the sweeps would open it again).

        Each key is relaxed piece by piece of the mesh, each piece to its share of ``budget`` (by its flat edges):
        a lash strip folding does not smooth the lid under it. Every (key, piece) is worked on at once.
        ``screen``: a :class:`Screen` of ``D``; an empty one keeps this relaxation's screen of every key and the
        pairs it moves, one kept reads it instead of screening ``D`` again.
        """
        budget = self.budget if budget is None else budget
        keys = np.arange(D.shape[1]) if keys is None else np.asarray(keys, np.int64)
        if not len(keys):
            return False
        bent = None
        if screen is not None and screen.bent is not None:
            bent = self._bent_since(D, screen)[:, keys]
        elif screen is not None and len(keys) == D.shape[1] and (keys == np.arange(D.shape[1])).all():
            bent = screen.bent = self._bent(D, keys, True)
        else:
            screen = None  # a screen of some keys: not kept
        share = budget * self.piece_edges / max(self.piece_edges.sum(), 1)
        jobs, changed = [], False
        for key, edges in zip(keys, self.folded_keys(D, keys, bent, screen)):
            if len(edges) <= budget:
                continue
            changed = True
            piece = self.edge_piece[edges]
            labels, counts = np.unique(piece, return_counts=True)
            jobs += [(key, edges[piece == label], int(share[label]))
                     for label, count in zip(labels, counts) if count > share[label]]
        if jobs:
            steps = np.broadcast_to(RELAX_STEPS if steps is None else steps, D.shape[1])
            extra = np.zeros(len(self.free), bool)
            if unpinned is not None:
                extra[unpinned] = True
            extra_keys = _key_mask(unpinned_keys, D.shape[1])
            hold = [(np.asarray(v, np.int64), _key_mask(k, D.shape[1])) for v, k in held if len(v)]
            self._relax_jobs(D, jobs, steps, screen, (extra, extra_keys), look, hold)
        return changed

    def _relax_jobs(self, D, jobs, steps, screen=None, unpinned=None, look=1, held=()):
        """Relax ``jobs`` ``(key, folded edges of one piece, budget)`` of ``D`` (n, k, 3) in place, each in at most
        ``steps`` (k,) of its key's sweeps, looking at its folds every ``look`` sweeps; per job the folds left (never
        more than as bound). ``unpinned``: ``(vertices (n,) bool, keys (k,) bool)``, pinned vertices those keys may
        move; ``held``: ``[(vertices (indices), keys (k,) bool)]``, vertices no job of those keys moves.

        Each job works on the vertices within ZONE_RINGS of its folded edges alone (and two rings around them, read
        only), sweep after sweep until it folds at most its budget or stalls (STALL_STEPS, SETTLE_STEPS). The jobs'
        vertices are laid side by side as (job, vertex) ids, so every sweep of all of them is one sparse product and
        one pass over their triangles.
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
        local = _lookup(cols, len(jobs) * n)  # (job, vertex) ids → their rows, -1 for one outside
        # The neighbours' mean among the jobs' vertices: each job's block of the mesh's.
        pos, row = _rows_entries(self.mean, vertex)
        at = local(job[row] * n + self.mean.indices[pos])
        inside = at >= 0
        # (the rows in order, each row's columns ascending as the mesh's: a canonical CSR built as it is)
        indptr = np.zeros(m + 1, np.int64)
        np.cumsum(np.bincount(row[inside], minlength=m), out=indptr[1:])
        mean = csr_matrix((self.mean.data[pos[inside]], at[inside], indptr), shape=(m, m))
        ring = mean.copy()
        ring.data[:] = 1.0
        in_zone = np.zeros(len(jobs) * n, bool)
        in_zone[zone] = True
        free = self.free[vertex]
        if unpinned is not None:
            free |= unpinned[0][vertex] & unpinned[1][key_of[job]]
        for vertices, keys in held:
            free &= ~(np.isin(vertex, vertices) & keys[key_of[job]])
        movable = free & in_zone[cols]
        # The flat edges with a corner in a zone, their triangles (each once) in local indices.
        pair, row = _rows_gather(self.vertex_pairs, zone % n)
        vpairs = _once(zone[row] // n * n_pairs + pair, len(jobs) * n_pairs)
        pair_job, pair = np.divmod(vpairs, n_pairs)
        faces, pair_faces = _once_inverse(pair_job[:, None] * len(self.T) + self.faces[self.pairs[pair]],
                                          len(jobs) * len(self.T))
        face_job, face = np.divmod(faces, len(self.T))
        tri = local(face_job[:, None] * n + self.T[face])  # (f, 3) local
        corner_rows, edge_faces = np.ascontiguousarray(tri.T), np.ascontiguousarray(pair_faces.T)  # (3, f), (2, e)
        X, dl = self.V[vertex], _rows_of(D, vertex, key_of[job])
        position = (X + dl).T.copy()  # the rows' positions (3, m), coordinates first, kept up to date as they move
        nrm = np.zeros((3, len(faces)))  # the triangles' normals, coordinates first
        fold, over = np.zeros(len(pair_job), bool), np.zeros(len(pair_job), bool)
        count = np.zeros(len(jobs), np.int64)  # folded edges per job
        count_over = np.zeros(len(jobs), np.int64)  # of them, over the LIMIT_DEG

        def touched(rows):  # the triangles at ``rows`` (their corners) and their flat edges (their triangles)
            in_rows = np.zeros(m, bool)
            in_rows[rows] = True
            at_face = in_rows[corner_rows[0]] | in_rows[corner_rows[1]] | in_rows[corner_rows[2]]
            edges = np.flatnonzero(at_face[edge_faces[0]] | at_face[edge_faces[1]])
            at = np.flatnonzero(at_face)
            return at, np.take(corner_rows, at, axis=1), edges, edge_faces[0, edges], edge_faces[1, edges]

        newly = []  # the edges that folded since the region last grew

        def folded(rows, faces, corners, edges, first, second):  # the folds once ``rows`` (touching them) moved
            position[:, rows] = (np.take(X, rows, axis=0) + np.take(dl, rows, axis=0)).T
            nrm[:, faces] = _unit_normals(*(np.take(position, c, axis=1) for c in corners))
            cos = _cosines(nrm, first, second)
            for flags, tally, limit in ((fold, count, self.cos_fold), (over, count_over, self.cos_limit)):
                now = cos < limit
                flip = now != np.take(flags, edges)
                if flip.any():  # a few edges a sweep: the tallies changed by theirs alone
                    flipped, up = edges[flip], now[flip]
                    tally[:] += np.bincount(pair_job[flipped[up]], minlength=len(jobs))
                    tally[:] -= np.bincount(pair_job[flipped[~up]], minlength=len(jobs))
                    flags[flipped] = up
                    if flags is fold:
                        newly.append(flipped[up])
            return count.copy()

        ball = np.nonzero(self.ball_radius[vertex] > 0)[0]  # rows kept out of an eyeball
        in_ball = np.zeros(m, bool)
        in_ball[ball] = True
        mark = np.zeros(m, bool)
        mark[local(np.concatenate(seeds))] = True
        region = (mark | (ring @ mark.astype(np.float64) > 0)) & movable
        count = folded(np.arange(m), *touched(np.arange(m)))
        best, best_d = count.copy(), dl.copy()  # never worse than as bound
        best_over = count_over.copy()
        since = np.zeros(len(jobs), np.int64)  # sweeps since each job's best
        was, swept = None, None
        job_steps = np.asarray(steps)[key_of]
        for step in range(0, int(job_steps.max()), look):
            stall = np.where(best_over <= budgets, SETTLE_STEPS, STALL_STEPS)  # only the margin's edges left: settled
            live = (count > budgets) & (since < stall) & (step < job_steps)
            if not live.any():
                break
            if was is None or (live != was).any():  # a job done: the sweeps work on the others alone
                was = live
                rows = np.nonzero(live[job])[0]
                swept = None
            if swept is None or not swept[-1]:  # a region holding every movable row of the live jobs is whole
                # the live jobs' folded edges' corners and their neighbours join the region (the neighbour map is
                # symmetric: a row next to a marked one is a marked one's neighbour); a few hundred rows, not all
                # (only the edges folded since it last grew: the region only grows, a job once done never lives again,
                # so the others' corners joined it already)
                edges = np.concatenate([np.zeros(0, np.int64), *newly])
                newly.clear()
                edges = edges[np.take(fold, edges) & live[pair_job[edges]]]
                marked = _once(tri[pair_faces[edges]].ravel(), m)
                grown = np.concatenate([marked, _rows_gather(ring, marked)[0]])
                region[grown[movable[grown]]] = True
                if step and not step % GROW_EVERY:  # still folding: relax a wider ring
                    region[rows] |= (ring @ region.astype(np.float64) > 0)[rows] & movable[rows]
            if swept is None or swept[0] != region.sum():  # the region only grows: its size says it changed
                moved = rows[region[rows]]
                swept = (region.sum(), moved, mean[moved], touched(moved), moved[in_ball[moved]],
                         not (movable[rows] & ~region[rows]).any())
            _, moved, mean_moved, touch, balled, _ = swept
            for _ in range(look):  # dl[moved] += RELAX_RATE * (mean_moved @ dl - dl[moved]), its rows gathered once
                rows_now = np.take(dl, moved, axis=0)
                step = mean_moved @ dl
                step -= rows_now
                step *= RELAX_RATE
                rows_now += step
                dl[moved] = rows_now
                self._keep_out(X, dl, vertex, balled)
            count = folded(moved, *touch)
            better = count < best
            since = np.where(better, 0, since + look * live)
            # As many folds over FOLD_DEG but fewer over the LIMIT_DEG is better too (its stall unchanged): a
            # job that stalls above its budget keeps the sweep it folds least by the measure (issue #35:
            # asian-female-old-in's AU29 stalled at 16 edges over 35° at the inner mouth corners, 14 over 40° as
            # first reached, 10 a few sweeps on; its limit 13).
            better |= (count == best) & (count_over < best_over)
            if better.any():  # (a job's rows outside its region are as at its last best)
                rows_better = moved[better[job[moved]]]
                best_d[rows_better] = dl[rows_better]
                best = np.where(better, count, best)
                best_over = np.where(better, count_over, best_over)
        if screen is not None:  # the rows it moved, for the screen kept
            changed = best_d != _rows_of(D, vertex, key_of[job])
            moved = changed[:, 0] | changed[:, 1] | changed[:, 2]
            screen.moved(vertex[moved], key_of[job[moved]])
        if D.flags.c_contiguous:  # the (vertex, key) rows written flat: faster than two index arrays
            D.reshape(-1, 3)[vertex * D.shape[1] + key_of[job]] = best_d
        else:
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
        if not len(rows):  # most sweeps keep no lid out of an eyeball
            return
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
            frontier = np.unique(new)  # a few thousand: a sort, not a pass over the jobs × vertices mask
        return np.flatnonzero(seen)


def _rows_of(D, vertices, keys):
    """``D[vertices, keys]`` of displacements ``D`` (n, k, 3) (index arrays broadcast together): one gather of the
    (vertex, key) rows, 3-4 times faster than numpy's two-array indexing (and numpy.take's gather of whole rows 2-3
    times faster than indexing's)."""
    return np.take(np.reshape(D, (-1, 3)), vertices * D.shape[1] + keys, axis=0)


def _unit_normals(P0, P1, P2):
    """Unit normals (3, f) of triangles with corners at ``P0``, ``P1``, ``P2`` (3, f), coordinates first:
    ``unit_rows(cross3(P1 - P0, P2 - P0))``'s numbers (the same products, sums and quotients in the same order),
    each coordinate one contiguous row: 3 times faster than rows of 3."""
    u, v = P1 - P0, P2 - P0
    n = np.empty_like(u)
    for i, j, k in ((0, 1, 2), (1, 2, 0), (2, 0, 1)):
        np.multiply(u[j], v[k], out=n[i])
        n[i] -= u[k] * v[j]
    length = n[0] * n[0]
    length += n[1] * n[1]
    length += n[2] * n[2]
    n /= np.maximum(np.sqrt(length), 1e-300)
    return n


def _cosines(N, first, second):
    """Dot products of columns ``first`` and ``second`` (index arrays) of unit normals ``N`` (3, f): ``row_dots``'
    numbers."""
    a, b = np.take(N, first, axis=1), np.take(N, second, axis=1)
    dot = a[0] * b[0]
    dot += a[1] * b[1]
    dot += a[2] * b[2]
    return dot


def _once_inverse(idx, size):
    """``(values, inverse)``: :func:`numpy.unique` of ``idx`` (all below ``size``) with ``return_inverse``, from a
    mask (no sort) and an int32 look-up table, never cleared (only the values' entries are written and read): on
    ICT's 72 keys 14 MB, 4 ms against a binary search's 19 ms (an int64 one, 29 MB, cost more in its pages than it
    saved; issue #35); past TABLE_MAX, numpy.unique's sort; ``inverse`` (int32) shaped as ``idx``."""
    if size > TABLE_MAX:
        values, inverse = np.unique(idx, return_inverse=True)
        return values, inverse.astype(np.int32).reshape(np.shape(idx))
    values = _once(idx.ravel(), size)
    return values, _slots(values, size, np.int32)[idx]


def _slots(values, size, dtype=np.int64):
    """A look-up table (``size``,) of each of the distinct ``values``' (all below ``size``) slot in them (``dtype``:
    int32 halves its pages where the slots fit)."""
    slot = np.empty(size, dtype)  # only the values' entries are read
    slot[values] = np.arange(len(values), dtype=dtype)
    return slot


def _lookup(ids, size):
    """A function of ids (an array, all below ``size``) giving each one's slot in the distinct, sorted ``ids``, -1 for
    any other value (int32): a look-up table (the relaxation's, jobs × vertices, 0.4 M entries on ICT's head, is
    1.7 MB, cheaper to fill than a binary search of its three look-ups: 13 ms of ICT's 72 keys; issue #35), past
    TABLE_MAX entries a binary search (the same slots)."""
    if size <= TABLE_MAX:
        table = np.full(size, -1, np.int32)
        table[ids] = np.arange(len(ids), dtype=np.int32)
        return table.__getitem__
    last = max(len(ids) - 1, 0)

    def search(wanted):
        if not len(ids):
            return np.full(np.shape(wanted), -1, np.int32)
        at = np.minimum(np.searchsorted(ids, wanted), last)
        return np.where(ids[at] == wanted, at, -1).astype(np.int32)

    return search


def _once(idx, size):
    """The distinct values of ``idx`` (all below ``size``), sorted: a mask's, no sort (past TABLE_MAX, a sort's)."""
    if size > TABLE_MAX:
        return np.unique(idx)
    mask = np.zeros(size, bool)
    mask[idx] = True
    return np.flatnonzero(mask)


def _rows_entries(A, rows):
    """``(positions, slots)``: where the entries of CSR ``A``'s ``rows`` lie in its ``indices``/``data`` (row by row),
    and each entry's slot in ``rows``."""
    starts = A.indptr[rows]
    counts = A.indptr[np.add(rows, 1)] - starts
    ends = np.cumsum(counts)
    # each row's entries at its start on from where they begin in the result: one repeat, no gathers by slot
    pos = np.arange(ends[-1] if len(ends) else 0, dtype=np.int64) + np.repeat(starts - (ends - counts), counts)
    return pos, np.repeat(np.arange(len(rows)), counts)


def _rows_gather(A, rows):
    """``(columns, slots)`` of every entry of CSR ``A``'s ``rows`` (each entry's slot in ``rows``)."""
    pos, slot = _rows_entries(A, rows)
    return A.indices[pos], slot


def _key_mask(keys, k) -> np.ndarray:
    """(k,) bool: the keys ``keys`` (indices), or every key where None."""
    mask = np.ones(k, bool) if keys is None else np.zeros(k, bool)
    if keys is not None:
        mask[keys] = True
    return mask
