"""The map from MediaPipe's 468 face-mesh points to the 68 Multi-PIE landmarks, and its file.

Each landmark is an affine combination (weights summing to 1) of a few
face-mesh points, so the map commutes with rotation, scale and translation.
The weights were fitted on ICT-FaceKit identities whose 68 landmark vertices
are known (``scripts/build/build_landmark_map.py``); the file also keeps a template
of the 468 points in the face frame (mm), used to find the face's pose.

File format ``pdeface.landmark-map`` (JSON)::

    {"format": "pdeface.landmark-map", "version": 1, "points": 468,
     "landmarks": [{"indices": [...], "weights": [...]}, ... 68],
     "template": [[x, y, z], ... 468], "trained_on": [...],
     "spread_mm": {"jaw": ..., ...}, "mirror": [... 468], "notice": "..."}

``spread_mm`` (optional) is each landmark group's median spread over the
frontal renders on the training heads: the yardstick of the confidence.
``mirror`` (optional) pairs each face-mesh point with its mirror image, so a
mirrored render's reading can be renumbered and averaged in.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import Path

import numpy as np

from ..errors import LandmarkError
from ..geometry import similarity
from ..io.files import load_json
from ..surface.frame import FACE_REACH_MM

MAP_FORMAT = "pdeface.landmark-map"
MAP_VERSION = 1
#: The shipped map, in the package's data.
DEFAULT_MAP = Path(__file__).resolve().parent.parent / "data" / "landmark_map.json"
#: Landmark groups of the Multi-PIE 68, for confidence figures and reports.
GROUPS = {"jaw": range(0, 17), "brows": range(17, 27), "nose": range(27, 36), "eyes": range(36, 48),
          "mouth": range(48, 68)}


@dataclass
class LandmarkMap:
    """68 rows of face-mesh point indices and affine weights, and the 468-point template (mm, face frame)."""

    indices: np.ndarray
    weights: np.ndarray
    template: np.ndarray
    trained_on: list = field(default_factory=list)
    notice: str = ""
    spread_mm: dict = field(default_factory=dict)  # each group's median spread over the frontal renders when trained
    mirror: np.ndarray | None = None  # face-mesh point -> its mirror image's (an involution)

    def apply(self, P):
        """The 68 landmarks from face-mesh points ``P (468, 3)``; NaN points are left out and the rest reweighted."""
        P = np.asarray(P, np.float64)
        W = np.where(np.isfinite(P[self.indices]).all(-1), self.weights, 0.0)
        total = W.sum(1, keepdims=True)
        with np.errstate(invalid="ignore", divide="ignore"):
            W = W / total
        return np.einsum("lk,lkj->lj", W, np.nan_to_num(P[self.indices]))

    def to_json(self) -> dict:
        return {"format": MAP_FORMAT, "version": MAP_VERSION, "points": len(self.template),
                "landmarks": [{"indices": i.tolist(), "weights": np.round(w, 6).tolist()}
                              for i, w in zip(self.indices, self.weights)],
                "template": np.round(self.template, 3).tolist(), "trained_on": list(self.trained_on),
                "spread_mm": {g: round(float(v), 3) for g, v in self.spread_mm.items()},
                **({"mirror": self.mirror.tolist()} if self.mirror is not None else {}), "notice": self.notice}


def parse_map(data, name="landmark map") -> LandmarkMap:
    """Validate a landmark map given as a dict (see the module's format)."""
    if not isinstance(data, dict) or data.get("format") != MAP_FORMAT:
        raise LandmarkError(f"{name}: not a {MAP_FORMAT} file")
    if data.get("version") != MAP_VERSION:
        raise LandmarkError(f"{name}: version {str(data.get('version'))[:20]} is not supported "
                            f"(expected {MAP_VERSION})")
    try:
        template = np.array(data.get("template"), np.float64)
    except (TypeError, ValueError, OverflowError):
        template = np.zeros((0,))
    try:
        rows = data["landmarks"]
        if not isinstance(rows, list) or len(rows) != 68:
            raise LandmarkError(f"{name}: 'landmarks' must hold 68 rows")
        k = max(len(r["indices"]) for r in rows)
        idx = np.zeros((68, k), np.int64)
        w = np.zeros((68, k))
        for j, r in enumerate(rows):
            i, v = np.array(r["indices"], np.int64), np.array(r["weights"], np.float64)
            if i.shape != v.shape or i.ndim != 1 or len(i) == 0:
                raise LandmarkError(f"{name}: landmark {j} needs as many weights as indices")
            idx[j, :len(i)], w[j, :len(v)] = i, v
    except (KeyError, TypeError, ValueError, OverflowError) as exc:
        if isinstance(exc, LandmarkError):
            raise
        raise LandmarkError(f"{name}: malformed ({exc})") from None
    if template.ndim != 2 or template.shape[1] != 3 or data.get("points") != len(template):
        raise LandmarkError(f"{name}: 'template' must be 'points' rows of [x, y, z]")
    if not (np.isfinite(template).all() and np.isfinite(w).all()):
        raise LandmarkError(f"{name}: NaN or inf in the map")
    if np.abs(template).max(initial=0) > FACE_REACH_MM or np.abs(w).max(initial=0) > 1e6:
        raise LandmarkError(f"{name}: 'template' points lie past {FACE_REACH_MM:g} mm, or weights are absurd")
    if idx.min() < 0 or idx.max() >= len(template):
        raise LandmarkError(f"{name}: indices must be face-mesh points 0-{len(template) - 1}")
    if np.abs(w.sum(1) - 1).max() > 1e-4:
        raise LandmarkError(f"{name}: each landmark's weights must sum to 1")
    spread = data.get("spread_mm", {})
    if not isinstance(spread, dict) or not set(spread) <= set(GROUPS) or not all(
            isinstance(v, (int, float)) and not isinstance(v, bool) and 0 < v < 100 for v in spread.values()):
        raise LandmarkError(f"{name}: 'spread_mm' must map groups ({', '.join(GROUPS)}) to mm > 0")
    mirror = data.get("mirror")
    if mirror is not None:
        try:
            mirror = np.array(mirror, np.int64)
        except (TypeError, ValueError, OverflowError):
            mirror = np.zeros(0, np.int64)
        n = len(template)
        if mirror.shape != (n,) or mirror.min() < 0 or mirror.max() >= n or (mirror[mirror] != np.arange(n)).any():
            raise LandmarkError(f"{name}: 'mirror' must pair the {n} face-mesh points (each with its mirror image)")
    trained_on = data.get("trained_on", [])
    if not isinstance(trained_on, list) or not all(isinstance(t, str) for t in trained_on):
        raise LandmarkError(f"{name}: 'trained_on' must be a list of names")
    return LandmarkMap(idx, w, template, trained_on, str(data.get("notice", "")),
                       {g: float(v) for g, v in spread.items()}, mirror)


def read_map(path=None) -> LandmarkMap:
    """A landmark map file; the shipped one by default."""

    path = DEFAULT_MAP if path is None else path
    return parse_map(load_json(path, LandmarkError), str(path))


def shipped_map() -> LandmarkMap:
    """The shipped map (:func:`read_map`), read again only when its file changed (a rebuilt map): ``detect`` takes
    it for every mesh (reading it: 1.5-2 ms CPU a time, #35). Shared by every caller: its arrays are read-only."""
    try:
        stat = DEFAULT_MAP.stat()
    except OSError:
        return read_map()  # its error names the file
    return _map_as_stored(str(DEFAULT_MAP), stat.st_mtime_ns, stat.st_size)


@lru_cache(maxsize=1)
def _map_as_stored(path, mtime_ns, size) -> LandmarkMap:
    m = read_map(path)
    for a in (m.indices, m.weights, m.template, m.mirror):
        if isinstance(a, np.ndarray):  # a change by one caller would reach every later one: refused instead
            a.setflags(write=False)
    return m


def robust_similarity(A, B, keep=0.85, rounds=3):
    """:func:`pdeface.geometry.similarity` refitted on the best-matching ``keep`` share of rows (a few points may hit
    the wrong surface). Returns ``s, R, t`` and the RMS residual of the kept rows, in the units of ``A``."""
    ok = np.isfinite(A).all(1) & np.isfinite(B).all(1)
    use = ok.copy()
    for _ in range(rounds):
        s, R, t = similarity(np.where(use[:, None], A, np.nan), B)
        r = np.linalg.norm(s * A @ R.T + t - B, axis=1) / s
        cut = np.quantile(r[ok], keep)
        use = ok & (r <= cut)
    return s, R, t, float(np.sqrt(np.mean(r[use] ** 2)))


def fit_map(samples, template, k=6, ridge=0.05, trained_on=(), notice="", indices=None) -> LandmarkMap:
    """Fit the 68 affine combinations by constrained least squares.

    Parameters
    ----------
    samples : list of (P (468, 3), L (68, 3))
        Face-mesh points found on a head and its true landmarks, each in the face frame (mm).
    template : (468, 3) array
        Mean face-mesh points (mm, face frame); each landmark combines its ``k`` nearest template points.
    ridge : float
        Pull (per mm²) toward equal weights, which keeps the weights small and the map smooth.
    indices : (68, k) int array, optional
        The points each landmark combines, instead of the nearest ones.
    """
    P = np.stack([s[0] for s in samples])
    L = np.stack([s[1] for s in samples])
    mean_l = L.mean(0)
    if indices is None:
        idx = np.argsort(np.linalg.norm(template[None] - mean_l[:, None], axis=2), axis=1)[:, :k]
    else:
        idx = np.asarray(indices, np.int64)
        k = idx.shape[1]
    W = np.zeros((68, k))
    for j in range(68):
        X = P[:, idx[j]]                                     # (S, k, 3)
        ok = np.isfinite(X).all((1, 2)) & np.isfinite(L[:, j]).all(1)
        # Weights sum to 1, so each sample may be centred on its own candidates: the ridge then acts on
        # the local spread (mm) rather than on where the face sits.
        c = X[ok].mean(1, keepdims=True)
        A = (X[ok] - c).transpose(0, 2, 1).reshape(-1, k)    # rows: sample x coordinate
        b = (L[ok, j] - c[:, 0]).reshape(-1)
        w0 = np.full(k, 1.0 / k)
        lam = ridge * len(b)
        K = np.zeros((k + 1, k + 1))
        K[:k, :k] = 2 * (A.T @ A + lam * np.eye(k))
        K[:k, k] = K[k, :k] = 1
        rhs = np.r_[2 * (A.T @ b + lam * w0), 1.0]
        W[j] = np.linalg.solve(K, rhs)[:k]
    return LandmarkMap(idx, W, np.asarray(template, np.float64), list(trained_on), notice)
