"""A light orthographic z-buffer renderer in numpy, for finding faces in meshes.

:class:`View` is an orthographic camera; :func:`rasterise` gives, per pixel,
the nearest triangle and the barycentric weights of the point seen there;
:func:`shade` turns that into a grey image a face detector reads; and
:func:`back_project` casts exact rays through sub-pixel image points back onto
the mesh, taking its candidate triangles from the rasterised neighbourhood
(candidate search apart from the hit test, as in :mod:`pdeface.geometry`).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..geometry import ray_triangle, triangle_cross, unit_rows
from ..mesh import vertex_normals

#: Candidate (pixel, triangle) pairs evaluated at once while rasterising.
_CHUNK = 2_000_000


@dataclass
class View:
    """An orthographic camera looking along ``-rotation[2]``.

    Parameters
    ----------
    rotation : (3, 3) array
        Rows: the image's right, up, and the direction towards the viewer, in mesh coordinates.
    centre : (3,) array
        The mesh point at the image centre.
    half : float
        Half the width of the (square) image, in mesh units.
    size : int
        Image width and height in pixels.
    """

    rotation: np.ndarray
    centre: np.ndarray
    half: float
    size: int

    @classmethod
    def looking(cls, forward, up, centre, half, size):
        """A view whose viewer looks along ``-forward`` (sees the side ``forward`` points to), ``up`` upwards."""
        back = np.asarray(forward, np.float64) / np.linalg.norm(forward)
        up = np.asarray(up, np.float64) - back * (back @ up)
        up /= np.linalg.norm(up)
        return cls(np.stack([np.cross(up, back), up, back]), np.asarray(centre, np.float64), float(half), int(size))

    def rolled(self, k: int) -> "View":
        """The view whose image is ``np.rot90(image, k)`` of this one's (k quarter turns anticlockwise)."""
        right, up, back = self.rotation
        for _ in range(k % 4):
            right, up = -up, right
        return View(np.stack([right, up, back]), self.centre, self.half, self.size)

    def flipped(self) -> "View":
        """The view whose image is ``np.fliplr(image)`` of this one's (a mirror: its right points left)."""
        return View(self.rotation * [[-1], [1], [1]], self.centre, self.half, self.size)

    def project(self, P):
        """Pixel x (right), pixel y (down) and depth (larger: nearer the viewer) of points ``P (n, 3)``."""
        q = (np.asarray(P, np.float64) - self.centre) @ self.rotation.T
        s = self.size / 2
        return (q[:, 0] / self.half + 1) * s - 0.5, (1 - q[:, 1] / self.half) * s - 0.5, q[:, 2]

    def rays(self, x, y):
        """Origins (in front of everything within ``4 * half``) and unit directions of rays through pixels."""
        s = self.size / 2
        a = (np.asarray(x, np.float64) + 0.5) / s - 1
        b = 1 - (np.asarray(y, np.float64) + 0.5) / s
        R = self.rotation
        o = self.centre + self.half * (a[:, None] * R[0] + b[:, None] * R[1] + 4 * R[2])
        return o, np.broadcast_to(-R[2], o.shape).copy()


@dataclass
class Raster:
    """What each pixel sees: triangle (-1 for background) and barycentric weights, row 0 at the top."""

    view: View
    tri: np.ndarray
    bary: np.ndarray

    def rolled(self, k: int) -> "Raster":
        """This raster seen in :meth:`View.rolled` ``(k)``, without rendering again."""
        return Raster(self.view.rolled(k), np.rot90(self.tri, k), np.rot90(self.bary, k, axes=(0, 1)))

    def flipped(self) -> "Raster":
        """This raster seen in :meth:`View.flipped`, without rendering again."""
        return Raster(self.view.flipped(), self.tri[:, ::-1], self.bary[:, ::-1])


def rasterise(V, T, view: View) -> Raster:
    """The nearest triangle and barycentric weights at every pixel centre.

    Triangles are grouped by the size of their pixel box (powers of two) so
    that each group's candidate pixels form one fixed-size block per triangle;
    the nearest candidate per pixel wins.
    """
    V, T = np.asarray(V, np.float64), np.asarray(T, np.int64)
    n = view.size
    px, py, pz = view.project(V)
    tx, ty = px[T], py[T]
    x0, y0 = np.ceil(tx.min(1)).astype(np.int64), np.ceil(ty.min(1)).astype(np.int64)
    x1, y1 = np.floor(tx.max(1)).astype(np.int64), np.floor(ty.max(1)).astype(np.int64)
    on = (x1 >= np.maximum(x0, 0)) & (y1 >= np.maximum(y0, 0)) & (x0 < n) & (y0 < n)
    # Clip boxes to the image so that a huge triangle costs no more than the image.
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
    return Raster(view, tri.reshape(n, n), bary.reshape(n, n, 3))


def shade(V, T, raster: Raster, background=0.0) -> np.ndarray:
    """An 8-bit grey image (h, w) of the raster: smooth normals lit from the viewer's side, a little from above.

    Back faces are shaded as front ones (a mesh's normals may point either way).
    """
    N = vertex_normals(np.asarray(V, np.float64), np.asarray(T, np.int64))
    seen = raster.tri >= 0
    n = np.einsum("pk,pkj->pj", raster.bary[seen], N[T[raster.tri[seen]]])
    R = raster.view.rotation
    # Left-right symmetric light: a sideways light would shift what the face mesh sees as the midline.
    light = unit_rows((R[2] + 0.35 * R[1])[None])[0]
    lit = np.abs(unit_rows(n) @ light)
    img = np.full(raster.tri.shape, float(background))
    img[seen] = 0.12 + 0.88 * lit
    return np.round(np.clip(img, 0, 1) * 255).astype(np.uint8)


def back_project(V, T, raster: Raster, x, y, allowed=None, reach=2):
    """The mesh points seen through sub-pixel image points ``(x, y)``.

    Each ray is tested exactly against the triangles the raster shows within
    ``reach`` pixels of it (restricted to ``allowed`` triangles when given); the
    nearest hit wins.

    Returns
    -------
    points : (p, 3) float, NaN where the ray hits none of its candidates
    tri : (p,) int, -1 where missed
    facing : (p,) float, cosine between the hit triangle's normal and the direction to the viewer
        (negative: the viewer sees the triangle's back, as through inverted normals)
    """
    V, T = np.asarray(V, np.float64), np.asarray(T, np.int64)
    x, y = np.asarray(x, np.float64), np.asarray(y, np.float64)
    n = raster.view.size
    d = np.arange(-reach, reach + 1)
    oy, ox = (g.ravel() for g in np.meshgrid(d, d, indexing="ij"))
    cx = np.clip(np.round(x).astype(np.int64)[:, None] + ox[None], 0, n - 1)
    cy = np.clip(np.round(y).astype(np.int64)[:, None] + oy[None], 0, n - 1)
    cand = raster.tri[cy, cx]
    if allowed is not None:
        cand = np.where(cand >= 0, np.where(allowed[np.maximum(cand, 0)], cand, -1), -1)
    ray, k = np.nonzero(cand >= 0)
    t_ = cand[ray, k]
    o, dirs = raster.view.rays(x, y)
    hit, u, v, t = ray_triangle(o[ray], dirs[ray], V[T[t_, 0]], V[T[t_, 1]], V[T[t_, 2]], eps=1e-7)
    ray, t_, t = ray[hit], t_[hit], t[hit]
    order = np.lexsort((t, ray))
    first = np.ones(len(order), bool)
    first[1:] = ray[order][1:] != ray[order][:-1]
    ray, t_, t = ray[order][first], t_[order][first], t[order][first]
    points = np.full((len(x), 3), np.nan)
    tri = np.full(len(x), -1, np.int64)
    facing = np.zeros(len(x))
    points[ray] = o[ray] + dirs[ray] * t[:, None]
    tri[ray] = t_
    # Rays through sub-pixel slivers (lid margins, lips seen edge-on) may miss every candidate: they take the
    # surface point seen at the nearest pixel centre that shows a candidate.
    miss = np.nonzero(tri < 0)[0]
    if len(miss):
        c = cand[miss]
        dist = np.where(c >= 0, (cx[miss] - x[miss, None]) ** 2 + (cy[miss] - y[miss, None]) ** 2, np.inf)
        k = np.argmin(dist, axis=1)
        seen = np.isfinite(dist[np.arange(len(miss)), k])
        miss, k = miss[seen], k[seen]
        py_, px_ = cy[miss, k], cx[miss, k]
        tri[miss] = raster.tri[py_, px_]
        points[miss] = np.einsum("pk,pkj->pj", raster.bary[py_, px_], V[T[tri[miss]]])
    hit = tri >= 0
    facing[hit] = unit_rows(triangle_cross(V, T[tri[hit]])) @ raster.view.rotation[2]
    return points, tri, facing


def marked(img, pixels, r=2, colour=(230, 30, 30)):
    """An RGB copy of a render (grey or RGB) with square dots of ``colour`` at ``pixels (p, 2)``."""
    img = np.repeat(img[..., None], 3, axis=2) if img.ndim == 2 else img.copy()
    h, w, _ = img.shape
    for x, y in np.round(pixels).astype(int):
        img[max(y - r, 0):min(y + r + 1, h), max(x - r, 0):min(x + r + 1, w)] = colour
    return img
