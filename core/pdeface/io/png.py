"""Minimal PNG writing and line plots, so reports need no plotting library."""
from __future__ import annotations

import struct
import zlib

import numpy as np


def write_png(path, rgb: np.ndarray) -> None:
    """Write an (h, w, 3) uint8 image as PNG."""
    rgb = np.ascontiguousarray(rgb, dtype=np.uint8)
    h, w, _ = rgb.shape
    raw = b"".join(b"\x00" + rgb[y].tobytes() for y in range(h))

    def chunk(tag, data):
        return struct.pack(">I", len(data)) + tag + data + struct.pack(">I", zlib.crc32(tag + data) & 0xFFFFFFFF)

    with open(path, "wb") as fh:
        fh.write(b"\x89PNG\r\n\x1a\n")
        fh.write(chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 8, 2, 0, 0, 0)))
        fh.write(chunk(b"IDAT", zlib.compress(raw, 9)))
        fh.write(chunk(b"IEND", b""))


def draw_polyline(img, xs, ys, color, box):
    """Draw a polyline in data coordinates into ``img`` inside ``box``.

    ``box`` is (x0, y0, x1, y1, data_xmin, data_xmax, data_ymin, data_ymax);
    NaN points break the line.
    """
    x0, y0, x1, y1, dx0, dx1, dy0, dy1 = box
    px = x0 + (np.asarray(xs) - dx0) / max(dx1 - dx0, 1e-12) * (x1 - x0)
    py = y1 - (np.asarray(ys) - dy0) / max(dy1 - dy0, 1e-12) * (y1 - y0)
    for a in range(len(px) - 1):
        if not np.isfinite([px[a], py[a], px[a + 1], py[a + 1]]).all():
            continue
        n = int(max(abs(px[a + 1] - px[a]), abs(py[a + 1] - py[a]), 1)) * 2
        t = np.linspace(0, 1, n + 1)
        cx = np.round(px[a] + (px[a + 1] - px[a]) * t).astype(int)
        cy = np.round(py[a] + (py[a + 1] - py[a]) * t).astype(int)
        ok = (cx >= 0) & (cx < img.shape[1]) & (cy >= 0) & (cy < img.shape[0])
        img[cy[ok], cx[ok]] = color


def plot_panels(path, panels, size=(360, 260)):
    """Side-by-side line-plot panels, saved as PNG.

    ``panels`` is a list of lists of ``(x, y, (r, g, b))`` series; each panel
    gets its own axes box scaled to its data, with equal aspect.
    """
    w, h = size
    img = np.full((h, w * len(panels), 3), 255, np.uint8)
    for p, series in enumerate(panels):
        xs = np.concatenate([s[0] for s in series])
        ys = np.concatenate([s[1] for s in series])
        ok = np.isfinite(xs) & np.isfinite(ys)
        if not ok.any():
            continue
        xmin, xmax, ymin, ymax = xs[ok].min(), xs[ok].max(), ys[ok].min(), ys[ok].max()
        span = max(xmax - xmin, ymax - ymin, 1e-9) * 1.08
        cx, cy = (xmin + xmax) / 2, (ymin + ymax) / 2
        box = (p * w + 12, 12, p * w + w - 12, h - 12, cx - span / 2 * (w / h), cx + span / 2 * (w / h),
               cy - span / 2, cy + span / 2)
        img[12:h - 12, [p * w + 12, p * w + w - 12]] = 180
        img[[12, h - 12], p * w + 12:p * w + w - 12] = 180
        for x, y, color in series:
            draw_polyline(img, x, y, color, box)
    write_png(path, img)
