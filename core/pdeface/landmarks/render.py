"""A light orthographic z-buffer renderer in numpy, for finding faces in meshes.

:class:`View` is an orthographic camera; :func:`rasterise` gives, per pixel,
the nearest triangle and the barycentric weights of the point seen there;
:func:`shade` turns that into a grey image a face detector reads; and
:func:`back_project` casts exact rays through sub-pixel image points back onto
the mesh, taking its candidate triangles from the rasterised neighbourhood
(candidate search apart from the hit test, as in :mod:`pdeface.geometry`).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..geometry import ray_triangle, triangle_cross, unit_rows
from ..mesh import vertex_normals

#: Candidate (pixel, triangle) pairs evaluated at once while rasterising: a chunk's arrays (1 MiB each) stay in the
#: cache (ICT's head's renders: 0.7x the CPU of chunks of 2M, the same fragments in the same order).
_CHUNK = 131_072


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

    @property
    def pixel(self) -> float:
        """Mesh units per pixel."""
        return 2 * self.half / self.size

    def nearest_pixel(self, c) -> int:
        """The pixel row or column nearest the pixel coordinate ``c`` (a :meth:`project` x or y), kept in the image."""
        return int(np.clip(np.round(c), 0, self.size - 1))

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
    """What each pixel sees: triangle (-1 for background) and barycentric weights, row 0 at the top.

    ``fragments`` (kept on request by :func:`rasterise`) are every triangle's covered pixel centres, so that
    :meth:`showing` can draw a subset of the triangles without rendering again.
    """

    view: View
    tri: np.ndarray
    bary: np.ndarray
    fragments: _Fragments | None = field(default=None, repr=False)

    def rolled(self, k: int) -> "Raster":
        """This raster seen in :meth:`View.rolled` ``(k)``, without rendering again."""
        return Raster(self.view.rolled(k), np.rot90(self.tri, k), np.rot90(self.bary, k, axes=(0, 1)))

    def flipped(self) -> "Raster":
        """This raster seen in :meth:`View.flipped`, without rendering again."""
        return Raster(self.view.flipped(), self.tri[:, ::-1], self.bary[:, ::-1])

    def showing(self, only) -> Raster:
        """The raster of the triangles ``T[only]`` alone (numbered as in ``T[only]``), from the kept fragments.

        Equal to ``rasterise(V, T[only], view)``: the nearest of those triangles wins each pixel. A pixel one of
        them won here keeps its fragment (the nearest of all, the first on a tie, is the nearest and first of any
        subset holding it); only the pixels the others won are resolved again, from these triangles' fragments
        there: a few thousand of a frontal render's 250k for the skin (a third of the time of resolving them all).
        """
        if self.fragments is None:
            raise ValueError("Raster.showing needs the fragments: rasterise(..., keep_fragments=True)")
        only = np.asarray(only, bool)
        f = self.fragments
        number = np.cumsum(only) - 1
        won = self.tri.reshape(-1)
        kept = only.take(won) & (won >= 0)
        # indices and take: the same values as masks, sooner
        redo = np.flatnonzero(only.take(f.tri) & ~kept.take(f.pix))
        rest = _resolved(self.view, f.pix.take(redo), f.z.take(redo), number.take(f.tri.take(redo)),
                         f.l0.take(redo), f.l1.take(redo))
        np.copyto(rest.tri.reshape(-1), number.take(won), where=kept)
        bary = self.bary.copy()  # whole: most pixels keep theirs (a masked copy of rows is several times slower)
        others = np.flatnonzero(~kept & (won >= 0))
        bary.reshape(-1, 3)[others] = rest.bary.reshape(-1, 3)[others]
        return Raster(self.view, rest.tri, bary)


@dataclass
class _Fragments:
    """Pixel centres inside triangles: flat pixel index, depth, triangle and the first two barycentric weights."""

    pix: np.ndarray
    z: np.ndarray
    tri: np.ndarray
    l0: np.ndarray
    l1: np.ndarray


def rasterise(V, T, view: View, keep_fragments=False, near=None) -> Raster:
    """The nearest triangle and barycentric weights at every pixel centre.

    Every triangle's pixel box is enumerated exactly (in chunks of :data:`_CHUNK` candidates), the centres
    inside it are its fragments, and the nearest fragment wins each pixel (the first triangle on a tie).
    ``keep_fragments`` keeps them on the raster for :meth:`Raster.showing`. ``near`` (a bool image): only the
    triangles whose box meets one of its pixels are drawn, so those pixels are as in the whole render (the
    others may lack triangles), for a look at a few points; the triangles about its bounding box
    (:func:`_straddling`) are the only ones whose boxes are worked out.
    """
    V, T = np.asarray(V, np.float64), np.asarray(T, np.int64)
    n = view.size
    px, py, pz = view.project(V)
    if near is not None:  # the triangles whose corners straddle near's bounding box, numbered in order
        near = np.asarray(near, bool)
        among = _straddling(px, py, T, near)
        T = T.take(among, 0)
    # Corners a, b, c of each triangle; np.minimum of columns, as .min(1) over three is several times slower.
    corner = np.ascontiguousarray(T.T)  # each corner's column contiguous: takes along it run sooner
    (ax, bx, cx), (ay, by, cy), (za, zb, zc) = ([p.take(k) for k in corner] for p in (px, py, pz))
    x0 = np.maximum(np.ceil(np.minimum(np.minimum(ax, bx), cx)), 0).astype(np.int32)
    y0 = np.maximum(np.ceil(np.minimum(np.minimum(ay, by), cy)), 0).astype(np.int32)
    x1 = np.minimum(np.floor(np.maximum(np.maximum(ax, bx), cx)), n - 1).astype(np.int32)
    y1 = np.minimum(np.floor(np.maximum(np.maximum(ay, by), cy)), n - 1).astype(np.int32)
    # The barycentric weights of (x, y): l0 = (e0x (x - cx) + e0y (y - cy)) / d, l1 likewise, l2 = 1 - l0 - l1.
    d = (by - cy) * (ax - cx) + (cx - bx) * (ay - cy)
    width, height = x1 - x0 + 1, y1 - y0 + 1
    drawn = (width > 0) & (height > 0) & (np.abs(d) > 1e-12)
    if near is not None:  # the pixels of near in each box, by the image's summed-area table
        area = np.zeros((n + 1, n + 1), np.int32)
        area[1:, 1:] = np.asarray(near, bool).cumsum(0, dtype=np.int32).cumsum(1, dtype=np.int32)
        xa, xb, ya, yb = (np.clip(e, 0, n) for e in (x0, x1 + 1, y0, y1 + 1))
        ya, yb, flat = ya * (n + 1), yb * (n + 1), area.reshape(-1)  # flat indices: area[y, x] sooner
        drawn &= flat.take(yb + xb) - flat.take(ya + xb) - flat.take(yb + xa) + flat.take(ya + xa) > 0
    e0x, e0y, e1x, e1y = by - cy, cx - bx, cy - ay, ax - cx  # the edges, for the weights above
    ids = np.nonzero(drawn)[0]
    count = width[ids] * height[ids]
    ends = np.cumsum(count, dtype=np.int64)
    pieces = []
    lo = 0
    while lo < len(ids):
        # The triangles whose candidates fit in one chunk (at least one triangle: a box is at most the image).
        hi = max(int(np.searchsorted(ends, (ends[lo - 1] if lo else 0) + _CHUNK, side="right")), lo + 1)
        t = ids[lo:hi]
        c = count[lo:hi]
        # Each box row by row: a row's pixels are its first column onwards (no division to find them).
        h, w = height[t], width[t]
        row_w = np.repeat(w, h)
        row_y = np.arange(len(row_w), dtype=np.int32) - np.repeat(np.cumsum(h, dtype=np.int32) - h - y0[t], h)
        row_start = np.cumsum(row_w, dtype=np.int32) - row_w - np.repeat(x0[t], h)
        gx = np.arange(int(c.sum()), dtype=np.int32) - np.repeat(row_start, row_w)
        gy = np.repeat(row_y, row_w)
        # l0 = (e0x dx + e0y dy) / d as written in full, in place: the same values, fewer passes over memory.
        dx, dy, dt = np.repeat(cx[t], c), np.repeat(cy[t], c), np.repeat(d[t], c)
        np.subtract(gx, dx, out=dx)
        np.subtract(gy, dy, out=dy)
        l0, l1, term = np.repeat(e0x[t], c), np.repeat(e1x[t], c), np.repeat(e0y[t], c)
        l0 *= dx
        term *= dy
        l0 += term
        l0 /= dt
        l1 *= dx
        np.multiply(np.repeat(e1y[t], c), dy, out=term)
        l1 += term
        l1 /= dt
        keep = l0 >= 0
        keep &= l1 >= 0
        np.subtract(1, l0, out=term)
        term -= l1
        keep &= term >= 0
        inside = np.nonzero(keep)[0]
        tt = np.repeat(t, c)[inside]
        l0, l1 = l0[inside], l1[inside]
        z = l0 * za[tt] + l1 * zb[tt] + (1 - l0 - l1) * zc[tt]
        pieces.append((gy[inside] * n + gx[inside], z, tt, l0, l1))
        lo = hi
    if pieces:
        fragments = _Fragments(*(np.concatenate(p) for p in zip(*pieces)))
    else:
        fragments = _Fragments(np.zeros(0, np.int32), np.zeros(0), np.zeros(0, np.int64), np.zeros(0), np.zeros(0))
    if near is not None:
        fragments.tri = among.take(fragments.tri)  # numbered as in the whole T
    f = fragments
    raster = _resolved(view, f.pix, f.z, f.tri, f.l0, f.l1)
    if keep_fragments:
        raster.fragments = fragments
    return raster


def _straddling(px, py, T, near) -> np.ndarray:
    """The triangles (ascending indices) with a corner past each side of the bounding box of ``near``'s pixels,
    widened by a pixel: among them every triangle whose pixel box meets one of those pixels (its box's last
    column, the floor of its corners' largest x, is at least the box's first column c only if a corner's x is),
    and a few more, which :func:`rasterise`'s own test then leaves out as before. Four flags a vertex, one per
    side, or-ed over each triangle's corners: a fraction of the cost of every triangle's box, for a few spots."""
    rows, cols = np.flatnonzero(near.any(1)), np.flatnonzero(near.any(0))
    if not len(rows):
        return np.zeros(0, np.int64)
    flags = ((px > cols[0] - 1).view(np.uint8) | (px < cols[-1] + 1).view(np.uint8) << 1
             | (py > rows[0] - 1).view(np.uint8) << 2 | (py < rows[-1] + 1).view(np.uint8) << 3)
    corner = np.ascontiguousarray(T.T)
    return np.flatnonzero((flags.take(corner[0]) | flags.take(corner[1]) | flags.take(corner[2])) == 15)


def _resolved(view: View, pix, z, tri, l0, l1) -> Raster:
    """The raster where the nearest fragment wins each pixel (the first one on a tie)."""
    n = view.size
    nearest = np.full(n * n, -np.inf)
    np.maximum.at(nearest, pix, z)
    win = np.nonzero(z == nearest[pix])[0]
    # Ties: the first winning fragment of each pixel.
    first = np.full(n * n, len(z))
    np.minimum.at(first, pix[win], win)
    seen = np.nonzero(first < len(z))[0]
    w = first[seen]
    out_tri = np.full(n * n, -1, np.int64)
    bary = np.zeros((n * n, 3))
    out_tri[seen] = tri[w]
    a, b, flat = l0[w], l1[w], bary.reshape(-1)  # flat indices: several times faster than bary[seen, k]
    flat[3 * seen], flat[3 * seen + 1], flat[3 * seen + 2] = a, b, 1 - a - b
    return Raster(view, out_tri.reshape(n, n), bary.reshape(n, n, 3))


def shade(V, T, raster: Raster, background=0.0, lights=None, normals=None) -> np.ndarray:
    """An 8-bit grey image (h, w) of the raster: smooth normals lit from the viewer's side, a little from above.

    Back faces are shaded as front ones (a mesh's normals may point either way). ``lights``, a list of
    ``(direction towards the light in mesh coordinates, strength)``, lights the surface facing the viewer with
    those directional lights instead (Lambert's cosine, plus the same ambient). ``normals``: the mesh's
    :func:`~pdeface.mesh.vertex_normals`, when several renders of one mesh share them.
    """
    N = vertex_normals(np.asarray(V, np.float64), np.asarray(T, np.int64)) if normals is None else normals
    seen = np.flatnonzero(raster.tri >= 0)  # flat indices and take, as depth_map's: the same values sooner
    corners = N.take(np.asarray(T).take(raster.tri.take(seen), 0), 0)
    n = unit_rows(np.einsum("pk,pkj->pj", raster.bary.reshape(-1, 3).take(seen, 0), corners))
    R = raster.view.rotation
    if lights is None:
        # Left-right symmetric light: a sideways light would shift what the face mesh sees as the midline.
        light = unit_rows((R[2] + 0.35 * R[1])[None])[0]
        lit = np.abs(n @ light)
    else:
        n *= np.where(n @ R[2] < 0, -1.0, 1.0)[:, None]  # the side the viewer sees
        lit = np.zeros(len(n))
        for direction, strength in lights:
            lit += float(strength) * np.maximum(n @ unit_rows(np.asarray(direction, np.float64)[None])[0], 0.0)
    img = np.full(raster.tri.shape, float(background))
    img.reshape(-1)[seen] = 0.12 + 0.88 * lit
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
    # A triangle covers several of a ray's pixels: each (ray, triangle) is tested once, the first kept in place
    # (the same hits, in the same order: about half the tests on the ICT head's renders).
    _, once = np.unique(ray * len(T) + t_, return_index=True)
    once.sort()
    ray, t_ = ray[once], t_[once]
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


def pixel_boxes(size, boxes) -> np.ndarray:
    """A bool image ``(size, size)`` true in each box ``(x0, x1, y0, y1)`` (inclusive pixel bounds, each clipped into
    the image as :func:`back_project` clips its candidates): :func:`rasterise`'s ``near`` for a look at a few spots."""
    near = np.zeros((size, size), bool)
    for x0, x1, y0, y1 in boxes:
        (x0, x1), (y0, y1) = np.clip((x0, x1), 0, size - 1), np.clip((y0, y1), 0, size - 1)
        near[y0:y1 + 1, x0:x1 + 1] = True
    return near


def column_depths(V, T, view: View, columns, rows=None) -> tuple[Raster, np.ndarray]:
    """``(raster, depth)`` of ``view`` drawn only over the pixel ``columns`` (the rest shows nothing): for steps that
    read the skin's profile down a few columns of a straight-on view. ``rows``: ``(first, last)``, the rows read
    (all when None); the columns' pixels there, and those beside them (:func:`back_project`'s candidates), are as
    drawn over the whole columns (a triangle over a pixel there and over a column is over that column's pixel in
    the same row), in a fraction of the time."""
    near = np.zeros((view.size, view.size), bool)
    lo, hi = (0, view.size - 1) if rows is None else np.clip(rows, 0, view.size - 1)
    near[lo:hi + 1, sorted(set(np.atleast_1d(columns).tolist()))] = True
    raster = rasterise(V, T, view, near=near)
    return raster, depth_map(V, T, raster)


def depth_map(V, T, raster: Raster) -> np.ndarray:
    """Each pixel's depth towards the viewer (mesh units), -inf where the raster shows nothing."""
    depth = np.full(raster.tri.shape, -np.inf)
    seen = np.flatnonzero(raster.tri >= 0)  # flat indices and take: half the time of boolean masks, same values
    corners = np.asarray(V, np.float64).take(np.asarray(T).take(raster.tri.take(seen), 0), 0)
    Q = np.einsum("pk,pkj->pj", raster.bary.reshape(-1, 3).take(seen, 0), corners)
    depth.reshape(-1)[seen] = (Q - raster.view.centre) @ raster.view.rotation[2]
    return depth


def disc_closing(img, r):
    """``scipy.ndimage.grey_closing(img, footprint=disc)`` for the disc of radius ``r`` pixels, equal to it
    value for value (borders reflected alike), several times faster at r = 13.

    The disc is a stack of centred rows, one per row offset dy, ``2 w(dy) + 1`` pixels wide: its max (min)
    filter is the max (min), over the offsets, of a 1-D filter along the rows shifted by dy; the 2-D footprint
    filter costs O(pixels · r²). The row filters of widths 3, 5, 7, ... are each the max (min) of the one before
    shifted a pixel either way (a third of the time of scipy's 1-D filters; max and min are exact, in any order).
    """
    half = [int(np.sqrt(r * r - dy * dy)) for dy in range(-r, r + 1)]  # exact for integers: w² <= r² - dy²
    n, m = img.shape

    def filtered(a, pick):
        padded = np.pad(a, r, mode="symmetric")  # scipy's default border, "reflect"
        rows, level = {}, padded  # level w: column i is the filter of width 2 w + 1 about padded's column i + w
        for w in range(max(half) + 1):
            if w == 1:
                level = pick(pick(level[:, :-2], level[:, 1:-1]), level[:, 2:])
            elif w:  # two of width 2 w - 1 two apart overlap: together they are 2 w + 1 wide
                level = pick(level[:, :-2], level[:, 2:])
            if w in half:
                rows[w] = level[:, r - w:r - w + m]
        out = rows[half[0]][:n].copy()
        for k, w in enumerate(half[1:], 1):
            pick(out, rows[w][k:k + n], out=out)
        return out

    return filtered(filtered(img, np.maximum), np.minimum)


def closed_depth(depth, r):
    """A depth map (NaN where nothing was seen) closed by a disc of radius ``r`` pixels (:func:`disc_closing`), the
    unseen background held far behind the face (the closing must not spill it onto the face): where the surface
    seen lies well behind it, an opening (an empty socket, a slit between the lips) shows. None where nothing was
    seen."""
    seen = np.isfinite(depth)
    if not seen.any():
        return None
    return disc_closing(np.where(seen, depth, depth[seen].min() - 1.0), r)
