"""Minimal PNG writing, text and annotated line plots, so reports need no plotting library."""
from __future__ import annotations

import math
import struct
import zlib

import numpy as np

from .files import write_bytes

# A 5 × 7 bitmap font (the HD44780 character ROM's shapes): each glyph is seven rows of five pixels.
# Lower case is drawn as upper case; "*" is a multiplication sign.
_GLYPHS = {
    "0": "01110 10001 10011 10101 11001 10001 01110", "1": "00100 01100 00100 00100 00100 00100 01110",
    "2": "01110 10001 00001 00010 00100 01000 11111", "3": "11111 00010 00100 00010 00001 10001 01110",
    "4": "00010 00110 01010 10010 11111 00010 00010", "5": "11111 10000 11110 00001 00001 10001 01110",
    "6": "00110 01000 10000 11110 10001 10001 01110", "7": "11111 00001 00010 00100 01000 01000 01000",
    "8": "01110 10001 10001 01110 10001 10001 01110", "9": "01110 10001 10001 01111 00001 00010 01100",
    "A": "01110 10001 10001 10001 11111 10001 10001", "B": "11110 10001 10001 11110 10001 10001 11110",
    "C": "01110 10001 10000 10000 10000 10001 01110", "D": "11100 10010 10001 10001 10001 10010 11100",
    "E": "11111 10000 10000 11110 10000 10000 11111", "F": "11111 10000 10000 11110 10000 10000 10000",
    "G": "01110 10001 10000 10111 10001 10001 01111", "H": "10001 10001 10001 11111 10001 10001 10001",
    "I": "01110 00100 00100 00100 00100 00100 01110", "J": "00111 00010 00010 00010 00010 10010 01100",
    "K": "10001 10010 10100 11000 10100 10010 10001", "L": "10000 10000 10000 10000 10000 10000 11111",
    "M": "10001 11011 10101 10101 10001 10001 10001", "N": "10001 10001 11001 10101 10011 10001 10001",
    "O": "01110 10001 10001 10001 10001 10001 01110", "P": "11110 10001 10001 11110 10000 10000 10000",
    "Q": "01110 10001 10001 10001 10101 10010 01101", "R": "11110 10001 10001 11110 10100 10010 10001",
    "S": "01111 10000 10000 01110 00001 00001 11110", "T": "11111 00100 00100 00100 00100 00100 00100",
    "U": "10001 10001 10001 10001 10001 10001 01110", "V": "10001 10001 10001 10001 10001 01010 00100",
    "W": "10001 10001 10001 10101 10101 10101 01010", "X": "10001 10001 01010 00100 01010 10001 10001",
    "Y": "10001 10001 10001 01010 00100 00100 00100", "Z": "11111 00001 00010 00100 01000 10000 11111",
    " ": "00000 00000 00000 00000 00000 00000 00000", ".": "00000 00000 00000 00000 00000 01100 01100",
    ",": "00000 00000 00000 00000 01100 00100 01000", ":": "00000 01100 01100 00000 01100 01100 00000",
    "-": "00000 00000 00000 11111 00000 00000 00000", "+": "00000 00100 00100 11111 00100 00100 00000",
    "=": "00000 00000 11111 00000 11111 00000 00000", "/": "00000 00001 00010 00100 01000 10000 00000",
    "(": "00010 00100 01000 01000 01000 00100 00010", ")": "01000 00100 00010 00010 00010 00100 01000",
    "*": "00000 10001 01010 00100 01010 10001 00000", "%": "11000 11001 00010 00100 01000 10011 00011",
    "'": "01100 00100 01000 00000 00000 00000 00000", "?": "01110 10001 00001 00010 00100 00000 00100",
}
FONT = {c: np.array([[b == "1" for b in row] for row in g.split()]) for c, g in _GLYPHS.items()}
GLYPH_W, GLYPH_H = 6, 7  # advance (5 pixels and a gap) and height, at scale 1


def write_png(path, rgb: np.ndarray) -> None:
    """Write an (h, w, 3) uint8 image as PNG."""
    rgb = np.ascontiguousarray(rgb, dtype=np.uint8)
    h, w, _ = rgb.shape
    raw = b"".join(b"\x00" + rgb[y].tobytes() for y in range(h))

    def chunk(tag, data):
        return struct.pack(">I", len(data)) + tag + data + struct.pack(">I", zlib.crc32(tag + data) & 0xFFFFFFFF)

    write_bytes(path, b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 8, 2, 0, 0, 0))
                + chunk(b"IDAT", zlib.compress(raw, 9)) + chunk(b"IEND", b""))


def text_width(text: str, scale: int = 1) -> int:
    return len(text) * GLYPH_W * scale - scale


def draw_text(img, x, y, text, color=(0, 0, 0), scale=1, anchor="left"):
    """Write ``text`` with its top-left corner at pixel (x, y) (``anchor`` centre/right: x is that point)."""
    x = int(x - (text_width(text, scale) / 2 if anchor == "centre" else text_width(text, scale) if anchor == "right"
                 else 0))
    for i, ch in enumerate(text.upper()):
        glyph = np.kron(FONT.get(ch, FONT["?"]), np.ones((scale, scale), bool))
        ys, xs = np.nonzero(glyph)
        ys, xs = ys + int(y), xs + x + i * GLYPH_W * scale
        ok = (xs >= 0) & (xs < img.shape[1]) & (ys >= 0) & (ys < img.shape[0])
        img[ys[ok], xs[ok]] = color


def draw_polyline(img, xs, ys, color, box, width=1):
    """Draw a polyline in data coordinates into ``img`` inside ``box``, ``width`` pixels wide.

    ``box`` is (x0, y0, x1, y1, data_xmin, data_xmax, data_ymin, data_ymax);
    NaN points break the line.
    """
    x0, y0, x1, y1, dx0, dx1, dy0, dy1 = box
    px = x0 + (np.asarray(xs) - dx0) / max(dx1 - dx0, 1e-12) * (x1 - x0)
    py = y1 - (np.asarray(ys) - dy0) / max(dy1 - dy0, 1e-12) * (y1 - y0)
    offsets = range(-(width // 2), width - width // 2)
    for a in range(len(px) - 1):
        if not np.isfinite([px[a], py[a], px[a + 1], py[a + 1]]).all():
            continue
        n = int(max(abs(px[a + 1] - px[a]), abs(py[a + 1] - py[a]), 1)) * 2
        t = np.linspace(0, 1, n + 1)
        for ox in offsets:
            for oy in offsets:
                cx = np.round(px[a] + (px[a + 1] - px[a]) * t).astype(int) + ox
                cy = np.round(py[a] + (py[a + 1] - py[a]) * t).astype(int) + oy
                ok = (cx >= x0) & (cx <= x1) & (cy >= y0) & (cy <= y1)
                img[cy[ok], cx[ok]] = color


def nice_ticks(lo: float, hi: float, target: int = 5) -> np.ndarray:
    """Round tick values (1, 2 or 5 × 10^k apart) inside [lo, hi]."""
    raw = max(hi - lo, 1e-12) / target
    mag = 10 ** math.floor(math.log10(raw))
    step = next(m * mag for m in (1, 2, 5, 10) if m * mag >= raw)
    return np.arange(math.ceil(lo / step) * step, hi + step * 1e-9, step)


def _tick_label(v: float) -> str:
    return f"{v:.0f}" if abs(v - round(v)) < 1e-9 else f"{v:g}"


def plot_panels(path, panels, size=(420, 320), titles=(), xlabel="", ylabel="", legend=()):
    """Side-by-side line-plot panels with titles, ticks, axis labels and a legend, saved as PNG.

    ``panels`` is a list of lists of series ``(x, y, (r, g, b))`` or
    ``(x, y, (r, g, b), width)``; each panel gets its own axes scaled to its
    data, with equal aspect. ``legend`` is a list of ``((r, g, b), label)``
    drawn under the panels.
    """
    w, h = size
    left, right, top, bottom = 46, 10, 22, 34
    legend_h = 14 * len(legend) + (8 if legend else 0)
    img = np.full((h + legend_h, w * len(panels), 3), 255, np.uint8)
    axis = (120, 120, 120)
    for p, series in enumerate(panels):
        x0, y0, x1, y1 = p * w + left, top, p * w + w - right, h - bottom
        if p < len(titles):
            draw_text(img, (x0 + x1) / 2, 6, titles[p], scale=1, anchor="centre")
        xs = np.concatenate([s[0] for s in series])
        ys = np.concatenate([s[1] for s in series])
        ok = np.isfinite(xs) & np.isfinite(ys)
        img[y0:y1 + 1, [x0, x1]] = axis
        img[[y0, y1], x0:x1 + 1] = axis
        if not ok.any():
            continue
        xmin, xmax, ymin, ymax = xs[ok].min(), xs[ok].max(), ys[ok].min(), ys[ok].max()
        aspect = (x1 - x0) / (y1 - y0)
        span = max((xmax - xmin) / aspect, ymax - ymin, 1e-9) * 1.08
        cx, cy = (xmin + xmax) / 2, (ymin + ymax) / 2
        box = (x0, y0, x1, y1, cx - span / 2 * aspect, cx + span / 2 * aspect, cy - span / 2, cy + span / 2)
        for v in nice_ticks(box[4], box[5]):
            px = int(round(x0 + (v - box[4]) / (box[5] - box[4]) * (x1 - x0)))
            img[y1:y1 + 4, px] = axis
            draw_text(img, px, y1 + 6, _tick_label(v), axis, anchor="centre")
        for v in nice_ticks(box[6], box[7]):
            py = int(round(y1 - (v - box[6]) / (box[7] - box[6]) * (y1 - y0)))
            img[py, x0 - 4:x0] = axis
            draw_text(img, x0 - 6, py - 3, _tick_label(v), axis, anchor="right")
        if xlabel:
            draw_text(img, (x0 + x1) / 2, y1 + 18, xlabel, axis, anchor="centre")
        if ylabel and p == 0:
            draw_text(img, p * w + 2, y0 - 14, ylabel, axis)
        for s in series:
            draw_polyline(img, s[0], s[1], s[2], box, s[3] if len(s) > 3 else 1)
    for i, (color, label) in enumerate(legend):
        y = h + 4 + 14 * i
        img[y + 2:y + 5, left:left + 18] = color
        draw_text(img, left + 24, y, label)
    write_png(path, img)
