"""A small z-buffer rasteriser for the README's pictures (no plotting library): front views of meshes."""
import numpy as np
from pdeface.mesh import vertex_normals

#: The light the pictures are shaded with (a little from the upper right, towards the face).
LIGHT = np.array([0.35, 0.45, 0.82]) / np.linalg.norm([0.35, 0.45, 0.82])


def shade(P, T, gamma=1.0):
    """Per-vertex lightness in [0, 1] of a front view (normals against :data:`LIGHT`)."""
    return np.clip(vertex_normals(P, T) @ LIGHT, 0, 1) ** gamma


def rasterise(P, T, colors, size, box):
    """Flat-coloured triangles (vertex colours interpolated), nearest first: an (h, w, 3) image."""
    h = w = size
    (x0, x1), (y0, y1) = box
    px = (P[:, 0] - x0) / (x1 - x0) * (w - 1)
    py = (y1 - P[:, 1]) / (y1 - y0) * (h - 1)
    img = np.full((h, w, 3), 255.0)
    depth = np.full((h, w), -np.inf)
    for a, b, c in T:
        xs, ys = px[[a, b, c]], py[[a, b, c]]
        lo_x, hi_x = int(max(np.floor(xs.min()), 0)), int(min(np.ceil(xs.max()), w - 1))
        lo_y, hi_y = int(max(np.floor(ys.min()), 0)), int(min(np.ceil(ys.max()), h - 1))
        if lo_x > hi_x or lo_y > hi_y:
            continue
        gx, gy = np.meshgrid(np.arange(lo_x, hi_x + 1), np.arange(lo_y, hi_y + 1))
        d = (ys[1] - ys[2]) * (xs[0] - xs[2]) + (xs[2] - xs[1]) * (ys[0] - ys[2])
        if abs(d) < 1e-12:
            continue
        l0 = ((ys[1] - ys[2]) * (gx - xs[2]) + (xs[2] - xs[1]) * (gy - ys[2])) / d
        l1 = ((ys[2] - ys[0]) * (gx - xs[2]) + (xs[0] - xs[2]) * (gy - ys[2])) / d
        l2 = 1 - l0 - l1
        inside = (l0 >= -1e-9) & (l1 >= -1e-9) & (l2 >= -1e-9)
        z = l0 * P[a, 2] + l1 * P[b, 2] + l2 * P[c, 2]
        yy, xx = gy[inside], gx[inside]
        front = z[inside] > depth[yy, xx]
        yy, xx = yy[front], xx[front]
        depth[yy, xx] = z[inside][front]
        img[yy, xx] = (l0[inside][front, None] * colors[a] + l1[inside][front, None] * colors[b]
                       + l2[inside][front, None] * colors[c])
    return img


def to_pixel(xy, size, box):
    """Pixel (x, y) of points in a square image of ``size`` showing ``box`` ((x0, x1), (y0, y1))."""
    (x0, x1), (y0, y1) = box
    return (xy[..., 0] - x0) / (x1 - x0) * (size - 1), (y1 - xy[..., 1]) / (y1 - y0) * (size - 1)


def dot(img, x, y, r, color):
    """A filled disc of radius ``r`` pixels."""
    h, w, _ = img.shape
    gy, gx = np.ogrid[:h, :w]
    img[(gx - x) ** 2 + (gy - y) ** 2 <= r * r] = color


def line(img, x0, y0, x1, y1, color, width=1):
    """A straight line of discs ``width`` pixels across."""
    n = int(max(abs(x1 - x0), abs(y1 - y0))) + 1
    h, w, _ = img.shape
    for t in np.linspace(0, 1, n):
        x, y = int(round(x0 + t * (x1 - x0))), int(round(y0 + t * (y1 - y0)))
        img[max(y - width // 2, 0):min(y + width // 2 + 1, h), max(x - width // 2, 0):min(x + width // 2 + 1, w)] = color


