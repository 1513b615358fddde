"""Draw the 24 muscles over the default face, and the muscle-only AUs it carries (README pictures).

Usage: python -m scripts.figures.render_muscles [-o docs/images/muscles.png] [--aus docs/images/muscle_aus.png] [--size 640]

Muscles: a front view of the default PDE face (grey), each linear muscle as a line from its
bony head (dot) to its insertion, the sphincters as their ellipses, the sheets as their
rectangles, the jaw's hinge as a cross. AUs: the face neutral and posed by its muscle AUs
13, 23, 38, 39 and 46 (the AUs no ICT shape covers), at weight 1.
"""
from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
from pdeface.au.modelfile import load_face
from pdeface.io.png import draw_text, write_png
from pdeface.muscles.aus import load_table
from pdeface.muscles.placement import place_muscles
from pdeface.surface.fit import face_mesh
from pdeface.surface.model import model_landmarks

from scripts.figures.drawlib import dot, line, rasterise, shade, to_pixel

BOX = ((-85.0, 85.0), (-105.0, 115.0))
COLOURS = {"linear": (200, 40, 40), "sphincter": (40, 90, 200), "sheet": (30, 150, 60), "jaw": (120, 60, 160)}
MUSCLE_AUS = ("13", "23", "38", "39", "46")


def face_tile(face, size, C=None, R=None):
    mesh = face_mesh(face, "fine", coefficients=C, residual=R)
    T, _ = mesh.triangles()
    P = face.frame.to_face(mesh.vertices)
    grey = 40 + 200 * shade(P, T)
    return rasterise(P, T, np.repeat(grey[:, None], 3, axis=1), size, BOX)


def muscles_picture(face, size):
    img = face_tile(face, size)
    for m in place_muscles(model_landmarks(face), load_table().geometry):
        c = COLOURS[m.kind]
        if m.kind == "linear":
            (hx, hy), (ix, iy) = (to_pixel(p[None, :2], size, BOX) for p in (m.head, m.insertion))
            line(img, hx[0], hy[0], ix[0], iy[0], c, 3)
            dot(img, hx[0], hy[0], 5, c)
        elif m.kind == "sphincter":
            t = np.linspace(0, 2 * np.pi, 200)
            ring = m.centre[:2] + np.stack([m.semi_axes[0] * np.cos(t), m.semi_axes[1] * np.sin(t)], 1)
            xs, ys = to_pixel(ring, size, BOX)
            for k in range(len(t) - 1):
                line(img, xs[k], ys[k], xs[k + 1], ys[k + 1], c, 3)
        elif m.kind == "sheet":
            d = m.direction[:2]
            e = np.array([-d[1], d[0]])
            sides = [1, -1] if m.mirrored else [1]
            for sgn in sides:
                dd = d * [sgn, 1]
                o = m.origin[:2]
                corners = [o + e * m.half_width, o + e * m.half_width + dd * m.length,
                           o - e * m.half_width + dd * m.length, o - e * m.half_width, o + e * m.half_width]
                xs, ys = to_pixel(np.array(corners), size, BOX)
                for k in range(4):
                    line(img, xs[k], ys[k], xs[k + 1], ys[k + 1], c, 3)
        else:
            x, y = to_pixel(m.hinge[None, :2], size, BOX)
            line(img, x[0] - 8, y[0], x[0] + 8, y[0], c, 3)
            line(img, x[0], y[0] - 8, x[0], y[0] + 8, c, 3)
    draw_text(img, 10, 10, "MUSCLES: LINEAR (HEAD DOT), SPHINCTER, SHEET, JAW HINGE", (0, 0, 0), scale=2)
    return img


def aus_row(face, size):
    tiles = [face_tile(face, size)]
    draw_text(tiles[0], size // 2, 8, "NEUTRAL", (0, 0, 0), scale=2, anchor="center")
    for key in MUSCLE_AUS:
        d = next(d for d in face.descriptors if d.key == key)
        C, R = d.dense()
        tile = face_tile(face, size, face.coefficients + C, face.residual + R)
        draw_text(tile, size // 2, 8, f"AU{key}", (0, 0, 0), scale=2, anchor="center")
        tiles.append(tile)
    return np.concatenate(tiles, axis=1)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    root = Path(__file__).resolve().parents[2]
    ap.add_argument("-o", "--output", default=str(root / "docs" / "images" / "muscles.png"))
    ap.add_argument("--aus", default=str(root / "docs" / "images" / "muscle_aus.png"))
    ap.add_argument("--size", type=int, default=640)
    args = ap.parse_args(argv)
    face = load_face("default")
    write_png(args.output, np.clip(muscles_picture(face, args.size), 0, 255).astype(np.uint8))
    write_png(args.aus, np.clip(aus_row(face, args.size // 2), 0, 255).astype(np.uint8))
    print(f"wrote {args.output}, {args.aus}")


if __name__ == "__main__":
    main()
