"""The landmark renderer as it was before issue #35, kept only as bench_landmarks' baseline.

:func:`before_path` swaps it into :mod:`pdeface.landmarks` for a block: the power-of-two block rasteriser with
a lexsort z-buffer, every skin raster rendered again from the skin triangles, ``np.cross`` normals summed by
``np.add.at`` (once per detect now: the renders share them), scipy's grey closing by a disc footprint; and
:func:`cold_seconds` times a fresh process finding landmarks both ways, the old one importing all of
``mediapipe.solutions`` (matplotlib with it). The landmarks found are the same, bit for bit.
"""
from __future__ import annotations

import subprocess
import sys
from contextlib import contextmanager

import numpy as np
from pdeface.geometry import unit_rows
from pdeface.landmarks import pipeline, render
from pdeface.landmarks.render import Raster

from scripts.bench.benchlib import installed_env

_CHUNK = 2_000_000


def triangle_cross(V, T):
    P = V[T]
    return np.cross(P[:, 1] - P[:, 0], P[:, 2] - P[:, 0])


def vertex_normals(V, T):
    n = triangle_cross(V, T)
    out = np.zeros_like(V, dtype=np.float64)
    for c in range(3):
        np.add.at(out, T[:, c], n)
    return unit_rows(out)


def disc_closing(img, r):
    """scipy's grey closing by the disc's footprint, as before."""
    from scipy.ndimage import grey_closing

    yy, xx = np.mgrid[-r:r + 1, -r:r + 1]
    return grey_closing(img, footprint=xx ** 2 + yy ** 2 <= r * r)


class _TwoPassRaster(Raster):
    """A raster whose skin-only raster is rendered again, as before."""

    def showing(self, only):
        return rasterise(self._V, self._T[np.asarray(only, bool)], self.view)


def rasterise(V, T, view, keep_fragments=False):
    V, T = np.asarray(V, np.float64), np.asarray(T, np.int64)
    n = view.size
    px, py, pz = view.project(V)
    tx, ty = px[T], py[T]
    x0, y0 = np.ceil(tx.min(1)).astype(np.int64), np.ceil(ty.min(1)).astype(np.int64)
    x1, y1 = np.floor(tx.max(1)).astype(np.int64), np.floor(ty.max(1)).astype(np.int64)
    on = (x1 >= np.maximum(x0, 0)) & (y1 >= np.maximum(y0, 0)) & (x0 < n) & (y0 < n)
    x0, y0 = np.clip(x0, 0, n - 1), np.clip(y0, 0, n - 1)
    x1, y1 = np.clip(x1, 0, n - 1), np.clip(y1, 0, n - 1)
    span = np.maximum(x1 - x0, y1 - y0) + 1
    group = np.ceil(np.log2(np.maximum(span, 1))).astype(np.int64)
    tri = np.full(n * n, -1, np.int64)
    bary = np.zeros((n * n, 3))
    pieces = []
    for g in np.unique(group[on]):
        side = 1 << int(g)
        ids = np.nonzero(on & (group == g))[0]
        step = max(1, _CHUNK // (side * side))
        oy, ox = np.divmod(np.arange(side * side), side)
        for s in range(0, len(ids), step):
            t = ids[s:s + step]
            gx = x0[t, None] + ox[None]
            gy = y0[t, None] + oy[None]
            a, b, c = (np.stack([tx[t, k], ty[t, k]], 1) for k in range(3))
            d = (b[:, 1] - c[:, 1]) * (a[:, 0] - c[:, 0]) + (c[:, 0] - b[:, 0]) * (a[:, 1] - c[:, 1])
            with np.errstate(divide="ignore", invalid="ignore"):
                l0 = ((b[:, 1] - c[:, 1])[:, None] * (gx - c[:, 0, None])
                      + (c[:, 0] - b[:, 0])[:, None] * (gy - c[:, 1, None])) / d[:, None]
                l1 = ((c[:, 1] - a[:, 1])[:, None] * (gx - c[:, 0, None])
                      + (a[:, 0] - c[:, 0])[:, None] * (gy - c[:, 1, None])) / d[:, None]
                l2 = 1 - l0 - l1
                inside = (l0 >= 0) & (l1 >= 0) & (l2 >= 0) & (gx <= x1[t, None]) & (gy <= y1[t, None])
            inside &= (np.abs(d) > 1e-12)[:, None]
            r, k = np.nonzero(inside)
            w = np.stack([l0[r, k], l1[r, k], l2[r, k]], 1)
            tt = t[r]
            z = (w * pz[T[tt]]).sum(1)
            pieces.append((gy[r, k] * n + gx[r, k], z, tt, w))
    if pieces:
        pix, z, tt, w = (np.concatenate(p) for p in zip(*pieces))
        order = np.lexsort((-z, pix))
        first = np.ones(len(order), bool)
        first[1:] = pix[order][1:] != pix[order][:-1]
        keep = order[first]
        tri[pix[keep]] = tt[keep]
        bary[pix[keep]] = w[keep]
    raster = _TwoPassRaster(view, tri.reshape(n, n), bary.reshape(n, n, 3))
    raster._V, raster._T = V, T
    return raster


@contextmanager
def before_path():
    """:mod:`pdeface.landmarks` renders as before #35 inside the block."""
    swaps = [(pipeline, "rasterise", rasterise), (render, "vertex_normals", vertex_normals),
             (pipeline, "vertex_normals", vertex_normals), (render, "triangle_cross", triangle_cross),
             (render, "disc_closing", disc_closing)]
    saved = [(mod, name, getattr(mod, name)) for mod, name, _ in swaps]
    try:
        for mod, name, fn in swaps:
            setattr(mod, name, fn)
        yield
    finally:
        for mod, name, fn in saved:
            setattr(mod, name, fn)


#: A fresh process finding the landmarks of one ICT head (cm) from scratch; prints the seconds of the landmark
#: modules' and MediaPipe's import, the detector's loading, detect itself, all three, and their CPU seconds.
_COLD = """
import time
from contextlib import nullcontext
from pdeface.assets import load_head, load_head_shapes
mesh, _ = load_head()
V, T = mesh.vertices + load_head_shapes()[HEAD], mesh.triangles()[0]
t, c = time.perf_counter(), time.process_time()
from pdeface.landmarks.detector import Detector, _mediapipe
from pdeface.landmarks.pipeline import detect
if BEFORE:
    from mediapipe.python.solutions import face_detection, face_mesh  # as before: every solution, matplotlib too
    from scripts.bench.baseline_landmarks import before_path
else:
    _mediapipe()
t1 = time.perf_counter()
with before_path() if BEFORE else nullcontext(), Detector() as det:
    t2 = time.perf_counter()
    detect(V, T, "cm", detector=det)
    t3 = time.perf_counter()
print(t1 - t, t2 - t1, t3 - t2, t3 - t, time.process_time() - c)
"""


def cold_seconds(head, repeat=3):
    """Median seconds, before #35 and now, of a fresh process finding the landmarks of ``head`` (an ICT identity)
    from scratch, run alternately: ``{"before": {"import", "load", "detect", "total", "cpu"}, "now": {...}}``."""
    keys = ("import", "load", "detect", "total", "cpu")
    runs = {"before": [], "now": []}
    for _ in range(repeat):
        for name, seconds in runs.items():
            code = _COLD.replace("HEAD", repr(head)).replace("BEFORE", str(name == "before"))
            out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True,
                                 env=installed_env())
            seconds.append([float(x) for x in out.stdout.split()[-5:]])
    return {name: dict(zip(keys, np.median(np.array(r), axis=0).tolist())) for name, r in runs.items()}
