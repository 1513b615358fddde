"""Whole-head motion learned from scans: what the PDE face and its harmonic extension miss.

The harmonic extension (:mod:`pdeface.head.bind`) predicts skin beyond the PDE face from the
face's own motion alone. A scanned head moves more than that: ICT-FaceKit's mouth lining rolls
with the lips 5 cm deep, its lashes follow the lid's margin, its cheek squint pulls the whole
scalp down. :class:`HeadPrior` keeps, for each scanned AU, the **residual** (truth minus the
binding without the prior) at every vertex of the scanned head, and the AU's curve-point motion;
a PDE motion ``x`` then gets the residual of kernel ridge regression on those samples,

    r(x) = Rᵀ (G + λ·mean(diag G)·I)⁻¹ X x,   G = X Xᵀ,

linear in ``x``, so every key is still one linear shape key and mixes still add. An AU the
prior was learned from gets (nearly) its scanned residual; a new AU (a muscle AU, the user's own
scan) gets the residual of the samples it resembles, none where it resembles none.

The residuals are those of ICT's generic head averaged, vertex by vertex, with those of ten of its
identities (``scripts/build/build_head_prior.py``), so they are less one head's own.

On the user's head (:meth:`HeadPrior.on`) each vertex takes the residual of the prior head's
nearest vertices of the same part kind, after a thin-plate warp taking the user's curve points to
the prior face's (so the lips meet the lips), scaled per axis by face size as descriptors are
(:mod:`pdeface.au.retarget`); in full within :data:`NEAR_IOD` eye distances of the prior head,
fading to none at :data:`FAR_IOD` (a body, a helmet, hair far from the head: nothing).

File (``assets/ict_head_prior.npz``, built by ``scripts/build/build_head_prior.py``): ``format``,
``keys`` (S,), ``features`` (S, K, J, 3) float16 mm, ``residuals`` (S, m, 3) int16 in steps of
``step_mm`` at the vertices ``carried`` (m,) of the prior head, ``kind`` (n,) part codes,
``frame`` (4, 4) from the head asset named ``head`` to the face frame (mm), ``curve_points``
(K, J, 3), ``face_size`` (3,), ``identities`` (the ICT identities learned from besides the
generic head), ``notice``.
"""
from __future__ import annotations

import functools
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from ..assets import ICT_HEAD_PRIOR, asset_path, generic_head_geometry
from ..au.retarget import face_size
from ..errors import ModelFormatError
from ..geometry import column_bounds
from ..io.files import load_npz
from ..surface.layout import ANCHOR_NAMES
from .parts import CODE

FORMAT = "pdeface.head-prior"
#: Ridge weight λ relative to the mean squared norm of the samples' features. Measured on ICT's
#: generic head, face-region median captured by ridge, an AU left out of the samples (in them):
#: 0.001 0.898 (0.996), 0.01 0.899 (0.982), 0.1 0.892 (0.951), 1 0.886 (0.922). On the ten ICT identities the
#: prior never saw (bench_head, medians of medians, face / head): 0.01 0.949 / 0.925, 0.007 0.951 / 0.930, 0.005
#: 0.952 / 0.936, 0.003 0.952 / 0.943, 0.001 0.953 / 0.948; an AU left out (generic head and three identities)
#: within ±0.006 of 0.01's, its spill p99 median on the generic head 0.42 (0.01), 0.46 (0.003), 0.47 mm (0.001).
#: Below 0.007 stylised-eyes-head-m's AU27 folds 14 edges of its mouth's lining (the issue's limit 13; 12 at 0.007).
RIDGE = 0.007
#: A user vertex takes the prior's residual in full within this many eye distances of the warped
#: prior head, fading to none at FAR_IOD.
NEAR_IOD, FAR_IOD = 0.05, 0.15
#: Part kinds that take a residual: the soft ones. The jaw's parts turn rigidly, the skull's stay, the
#: eyeballs turn about their centres (ICT's do not move).
CARRIED_KINDS = ("skin", "follow")
#: A user vertex takes the residual of this many nearest vertices of the prior head, by inverse distance.
NEAREST = 4
#: Near the mouth a vertex is lifted this many eye distances along a fourth axis, up for the upper lip's side of
#: the mouth's middle line, down for the lower's, so it takes the residual of its own lip's prior vertices (an upper
#: inner lip deeper than ICT's took the lower lip's AU27 drop: issue #40).
LIP_SIDE_IOD = 0.1
#: Storage step of the residuals (mm).
STEP_MM = 0.01
#: Curve points the warp is anchored on: every WARP_STRIDE-th curve and point.
WARP_STRIDE = 2
#: Points warped at a time: their rows stay in cache.
WARP_BLOCK = 1024
#: Residual columns (of the samples' 3·S) mixed onto a head at a time: a few MB of float64 at once.
MIX_COLUMNS = 21
#: Head vertices mixed at a time where each takes the same number of prior vertices: their terms (4 rows of every
#: residual) stay in cache.
MIX_ROWS = 512
#: The warp's smoothing (mm, added to its kernel's diagonal): how far it may miss its anchors. ICT's ten unseen
#: identities, face / head medians without the still back of the head: 10: 0.909 / 0.875, 1: 0.949 / 0.926, 0.3:
#: 0.950 / 0.927, 0.1: 0.950 / 0.927, 0: the same (every 3rd point at 0.1: 0.951 / 0.925; every point: 0.943 / 0.918).
WARP_SMOOTHING = 0.1


@dataclass
class HeadPrior:
    """Residual motion of a scanned head per scanned AU, and the AUs' curve-point motion.

    Attributes
    ----------
    keys : list of str
        AU keys of the samples.
    features : (S, K, J, 3) array
        Each sample's curve-point motion (face frame of the prior face, mm).
    residuals : (S, n, 3) float32 array
        Truth minus the prior-free binding at every vertex of the prior head (mm).
    vertices : (n, 3) array
        The prior head in its face frame (mm), with ``triangles`` (t, 3) and part ``kind`` (n,).
    curve_points : (K, J, 3) array
        The prior face's curve points; ``face_size`` (3,) mm.
    identities : tuple of int
        ICT-FaceKit identities whose heads it was learned from besides the generic one (residuals
        averaged vertex by vertex).
    """

    keys: list
    features: np.ndarray
    residuals: np.ndarray
    vertices: np.ndarray
    triangles: np.ndarray
    kind: np.ndarray
    curve_points: np.ndarray
    face_size: np.ndarray
    ridge: float = RIDGE
    notice: str = ""
    identities: tuple = ()

    @property
    def layout(self) -> tuple:
        return self.curve_points.shape[:2]

    def without(self, keys) -> HeadPrior:
        """The prior without the samples ``keys`` (to measure AUs it never saw)."""
        keep = np.array([k not in set(keys) for k in self.keys])
        return replace(self, keys=[k for k, m in zip(self.keys, keep) if m], features=self.features[keep],
                       residuals=self.residuals[keep])

    def solver(self) -> np.ndarray:
        """(S, K·J·3): a motion's sample weights ``α = solver @ x`` (kernel ridge); solved once per prior (every
        head bound reads it; read-only)."""
        built_on = (self.features, self.ridge)
        cached = self.__dict__.get("_solver")  # not a field: replace() starts without it
        if cached is None or any(a is not b for a, b in zip(cached[0], built_on)):
            X = self.features.reshape(len(self.features), -1)
            G = X @ X.T
            lam = self.ridge * np.trace(G) / max(len(G), 1)
            solver = np.linalg.solve(G + lam * np.eye(len(G)), X)
            solver.flags.writeable = False
            cached = self.__dict__["_solver"] = built_on, solver
        return cached[1]

    def _kind_tree(self, name, mouth, lift):
        """``(vertices, tree)``: the prior head's vertices of part kind ``name`` on its triangles of that kind, and
        a k-d tree of them lifted by their side of the mouth (``mouth``: its top rim curve, ``lift`` mm; see
        :func:`_lip_side`) (None when there are none); built once per prior and mouth (every head bound reads them)."""
        from scipy.spatial import cKDTree

        trees = self.__dict__.setdefault("_kind_trees", {})  # not a field: replace() starts without it
        built_on = (self.vertices, self.triangles, self.kind)
        key = (name, mouth, lift)
        if key not in trees or any(a is not b for a, b in zip(trees[key][0], built_on)):
            tri = self.triangles[(self.kind[self.triangles] == CODE[name]).all(axis=1)]
            verts = np.unique(tri)
            X = self.vertices[verts]
            X = np.c_[X, lift * _lip_side(X, self.curve_points, mouth)]
            trees[key] = built_on, verts, (cKDTree(X) if len(verts) else None)
        return trees[key][1:]

    def on(self, model, vertices, kind, reach=None, eye_distance=None):
        """The prior carried to a user's head; None when its face has another curve layout.

        Parameters
        ----------
        model : FaceModel
            The user's face (fitted on the head).
        vertices : (p, 3) array
            The head's vertices in the user's face frame (mm).
        kind : (p,) int array
            Their part codes (:data:`pdeface.head.parts.KINDS`).
        reach : (p,) array in [0, 1], optional
            How much of the residual each vertex may take (0: a vertex that never moves).
        eye_mm : float, optional
            The user's eye distance (mm), for the fade; the face frame's 65 mm by default.

        Returns
        -------
        PriorOnHead or None
        """
        from scipy.sparse import csr_matrix

        X_user = model.curve_points()
        if X_user.shape[:2] != self.layout:
            return None
        ratio = face_size(model) / self.face_size
        eye_distance = 65.0 if eye_distance is None else float(eye_distance)
        near, far = NEAR_IOD * eye_distance, FAR_IOD * eye_distance
        s = WARP_STRIDE
        src, dst = X_user[::s, ::s].reshape(-1, 3), self.curve_points[::s, ::s].reshape(-1, 3)
        warp = _warp(src, dst, WARP_SMOOTHING)
        V = np.asarray(vertices, np.float64)
        candidate = np.isin(kind, [CODE[k] for k in CARRIED_KINDS])
        if reach is not None:
            candidate &= np.asarray(reach) > 0
        # Only vertices near the prior head (scaled to the user's face) can take anything.
        lo, hi = column_bounds(self.vertices)
        lo, hi = lo * ratio - far, hi * ratio + far
        lo, hi = np.minimum(lo, hi), np.maximum(lo, hi)
        for k in range(3):  # axis by axis: a reduction over an axis of 3 is slow in numpy
            candidate &= (V[:, k] > lo[k]) & (V[:, k] < hi[k])
        idx = np.nonzero(candidate)[0]
        W = V[idx] + warp(V[idx]) if len(idx) else np.zeros((0, 3))
        mouth = next((k for a, k in model.layout.opening_curves() if ANCHOR_NAMES[a] == "mouth_top"), None)
        lift = LIP_SIDE_IOD * eye_distance / float(np.mean(ratio))  # in the prior head's size
        W = np.c_[W, lift * _lip_side(V[idx], X_user, mouth)]
        rows, cols, vals = [], [], []
        weight = np.zeros(len(idx))
        for name in CARRIED_KINDS:
            mine = np.nonzero(kind[idx] == CODE[name])[0]
            verts, tree = self._kind_tree(name, mouth, lift)
            if not len(mine) or tree is None:
                continue
            # Inverse-distance weights of the 4 nearest vertices: as good as the closest point on the
            # triangles (face median within 0.004 on three identities) at a third of the time.
            dist, near_k = tree.query(W[mine], k=NEAREST)
            w = 1.0 / np.maximum(dist, 1e-3) ** 2
            rows.append(np.repeat(mine, NEAREST))
            cols.append(verts[near_k].ravel())
            vals.append((w / w.sum(axis=1, keepdims=True)).ravel())
            weight[mine] = np.clip((far - dist[:, 0]) / (far - near), 0.0, 1.0)
        weight = weight * weight * (3 - 2 * weight)  # smoothstep: no crease where the fade starts
        if reach is not None:
            weight = weight * np.asarray(reach, np.float64)[idx]
        rows, cols, vals = (np.concatenate(a) if a else np.zeros(0, t) for a, t in
                            ((rows, np.int64), (cols, np.int64), (vals, np.float64)))
        keep = np.nonzero(weight > 0)[0]
        mix = csr_matrix((vals * weight[rows], (rows, cols)), shape=(len(idx), len(self.vertices)))[keep]
        # Mixed and scaled to the user's face once for all keys: a key is then one dense product.
        S = len(self.keys)
        used = np.zeros(len(self.vertices), bool)  # np.unique's, without its sort
        used[mix.indices] = True
        used = np.flatnonzero(used)
        # (used, 3, S): gathered, not a cached per-vertex copy of every residual (40 MB held for good; issue #35)
        residuals = np.moveaxis(self.residuals, 0, -1).take(used, axis=0)  # rows: see load_prior
        residuals *= ratio[:, None].astype(np.float32)  # in place: the gather is a copy (a 15 MB one less)
        residuals = _mixed(mix[:, used], residuals.reshape(len(used), 3 * S)).reshape(-1, S)
        return PriorOnHead(idx[keep], residuals, self.solver(), ratio)


def _mixed(mix, residuals):
    """``mix @ residuals`` (sparse (q, m) and float32 (m, c)) into float32, with no float64 copy of all the rows mixed
    nor of every residual (fresh 22 and 30 MB arrays on a 27k-vertex head; issue #35): each entry the float64 sum of
    its row's terms in the matrix's order, as scipy's product makes it (but for a row whose every term is -0, which
    residuals read from integers never are).

    Rows of as many terms each (every head vertex takes its NEAREST): MIX_ROWS rows at a time, each term a gathered
    row of residuals (numpy.take: 1.3x faster than scipy's product); others by blocks of MIX_COLUMNS columns of
    scipy's."""
    q, c = mix.shape[0], residuals.shape[1]
    out = np.empty((q, c), np.float32)
    counts = np.diff(mix.indptr)
    if q and counts[0] and (counts == counts[0]).all():
        cols, weights = mix.indices.reshape(q, -1), mix.data.reshape(q, -1)
        for start in range(0, q, MIX_ROWS):
            block = slice(start, start + MIX_ROWS)
            total = weights[block, :1] * residuals.take(cols[block, 0], axis=0)  # float32 rows × float64: float64
            for j in range(1, cols.shape[1]):
                total += weights[block, j:j + 1] * residuals.take(cols[block, j], axis=0)
            out[block] = total
        return out
    for start in range(0, c, MIX_COLUMNS):
        out[:, start:start + MIX_COLUMNS] = mix @ residuals[:, start:start + MIX_COLUMNS].astype(np.float64)
    return out


def _lip_side(P, curve_points, mouth):
    """+1 for points ``P`` above the mouth's middle line (midway between its rim curves ``mouth`` and ``mouth + 1``
    of ``curve_points``) within its width and a rim row's height (K·J grid's gap) of it, -1 below, 0 elsewhere or
    without a mouth."""
    if mouth is None:
        return np.zeros(len(P))
    top, bottom = curve_points[mouth], curve_points[mouth + 1]
    middle = 0.5 * (top + bottom)
    middle = middle[np.argsort(middle[:, 0])]
    height = np.interp(P[:, 0], middle[:, 0], middle[:, 1])
    span = middle[np.sort(np.nonzero(np.abs(top[:, 1] - bottom[:, 1]) > 0.05)[0]), 0]  # apart between the corners
    if not len(span):
        return np.zeros(len(P))
    reach = np.abs(curve_points[mouth - 1, :, 1] - curve_points[mouth + 2, :, 1]).max()
    inside = (P[:, 0] > span.min()) & (P[:, 0] < span.max()) & (np.abs(P[:, 1] - height) < reach)
    return np.where(inside, np.sign(P[:, 1] - height), 0.0)


def _warp(src, dst, smoothing=WARP_SMOOTHING):
    """Polyharmonic spline (kernel r, 3-D biharmonic, with an affine part) taking ``src`` to ``dst``:
    a function adding the offset at any points."""
    from scipy.spatial.distance import cdist

    n = len(src)
    A = np.zeros((n + 4, n + 4))
    A[:n, :n] = cdist(src, src) + smoothing * np.eye(n)
    A[:n, n:] = np.c_[np.ones(n), src]
    A[n:, :n] = A[:n, n:].T
    coef = np.linalg.solve(A, np.r_[dst - src, np.zeros((4, 3))])

    def offset(P):
        # WARP_BLOCK points at a time: their distances stay in cache (all at once: a fresh 37 MB array for a
        # 27k-vertex head's 14k points, 9k page faults; issue #35), the same numbers
        out = np.empty((len(P), 3))
        for start in range(0, len(P), WARP_BLOCK):
            block = P[start:start + WARP_BLOCK]
            out[start:start + WARP_BLOCK] = cdist(block, src) @ coef[:n] + np.c_[np.ones(len(block)), block] @ coef[n:]
        return out

    return offset


@dataclass
class PriorOnHead:
    """A :class:`HeadPrior` on one user's head: ``vertices`` (q,) take the samples' residuals
    (``residuals`` (q·3, S) float32 mm: the prior head's nearest vertices mixed, faded, scaled per axis by
    ``ratio`` to the user's face) weighted by a curve-point motion's sample weights (``solver``)."""

    vertices: np.ndarray
    residuals: np.ndarray
    solver: np.ndarray
    ratio: np.ndarray

    def leaving_out(self, prior: HeadPrior, keys) -> PriorOnHead:
        """The same transfer with the samples ``keys`` left out of ``prior`` (to measure AUs it never saw)."""
        keep = np.array([k not in set(keys) for k in prior.keys])
        return replace(self, residuals=np.ascontiguousarray(self.residuals[:, keep]),
                       solver=prior.without(keys).solver())

    def __call__(self, curve_motion) -> np.ndarray:
        """(q, 3) residual motion for a curve-point motion (K, J, 3) of the user's face (mm)."""
        return self.many([curve_motion])[:, 0]

    def many(self, curve_motions) -> np.ndarray:
        """:meth:`__call__` of several curve-point motions (a sequence, or a (k, K, J, 3) array), (q, k, 3): two matrix
        products."""
        X = np.stack([(np.asarray(x, np.float64) / self.ratio).ravel() for x in curve_motions], axis=1)
        weights = (self.solver @ X).astype(self.residuals.dtype)  # the small factor: the big one stays as it is
        return (self.residuals @ weights).reshape(len(self.vertices), 3, -1).transpose(0, 2, 1)


def load_prior(path, head_vertices, head_triangles) -> HeadPrior:
    """Read and check a prior file; ``head_vertices`` / ``head_triangles``: the head asset it names."""
    path = Path(path)
    data = load_npz(path, FORMAT, "head prior")
    try:
        keys = [str(k) for k in data["keys"]]
        F = np.asarray(data["features"], np.float64)
        Q = np.asarray(data["residuals"])
        carried = np.asarray(data["carried"], np.int64)
        kind = np.asarray(data["kind"], np.int64)
        M = np.asarray(data["frame"], np.float64)
        C = np.asarray(data["curve_points"], np.float64)
        size = np.asarray(data["face_size"], np.float64)
        step = float(data["step_mm"])
    except KeyError as exc:
        raise ModelFormatError(f"{path}: head prior file lacks {exc}") from None
    S, n = len(keys), len(head_vertices)
    problems = []
    if F.ndim != 4 or F.shape[0] != S or F.shape[1:3] != C.shape[:2] or F.shape[3] != 3 or not np.isfinite(F).all():
        problems.append(f"'features' must be finite, shaped ({S}, curves, points, 3); got {F.shape}")
    if Q.ndim != 3 or Q.shape != (S, len(carried), 3) or Q.dtype != np.int16:
        problems.append(f"'residuals' must be int16 shaped ({S}, {len(carried)}, 3); got {Q.shape} {Q.dtype}")
    if len(carried) and (carried.min() < 0 or carried.max() >= n):
        problems.append("'carried' indexes vertices the head does not have")
    if kind.shape != (n,):
        problems.append(f"'kind' must give one part code per head vertex ({n}); got {kind.shape}")
    if M.shape != (4, 4) or not np.isfinite(M).all():
        problems.append("'frame' must be a finite 4×4 matrix")
    if size.shape != (3,) or not (np.isfinite(size).all() and (size > 0).all()) or not step > 0:
        problems.append("'face_size' must be 3 positive numbers (mm) and 'step_mm' positive")
    if problems:
        raise ModelFormatError(f"{path}: " + "; ".join(problems))
    # float32: the file's 0.01 mm steps need no more, and the 63 samples on the 27k-vertex head halve to 20 MB
    # vertex-major in memory (a (S, n, 3) view of it): a head's vertices are gathered as rows (HeadPrior.on, 4× faster)
    residuals = np.zeros((n, 3, S), np.float32)
    residuals[carried] = (Q * np.float32(step)).transpose(1, 2, 0)
    residuals = residuals.transpose(2, 0, 1)
    V = np.asarray(head_vertices, np.float64) @ M[:3, :3].T + M[:3, 3]
    return HeadPrior(keys, F, residuals, V, np.asarray(head_triangles, np.int64), kind, C, size,
                     float(data.get("ridge", RIDGE)), str(data.get("notice", "")),
                     tuple(int(i) for i in data.get("identities", [])))


@functools.lru_cache(maxsize=1)
def load_head_prior():
    """The bundled whole-head motion learned from ICT-FaceKit's head (:class:`HeadPrior`;
    ``scripts/build/build_head_prior.py``). Shared: do not modify it. The head is the one the landmarks' steps read
    (:func:`~pdeface.assets.generic_head_geometry`): its file read once a process, not twice (10-14 ms each)."""
    V, T, _ = generic_head_geometry()
    return load_prior(asset_path(ICT_HEAD_PRIOR), V, T)
