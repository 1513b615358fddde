"""Draw the 68-point landmark scheme for the add-on's guided landmark editor (shipped as a small PNG).

Usage: python -m scripts.figures.render_landmark_scheme [-o blender_addon/images/landmark_scheme.png] [--size 640]

ICT-FaceKit's generic head seen straight on, its 68 landmarks (:mod:`pdeface.landmark_scheme`) as dots coloured
by group (the colours of :data:`GROUP_COLOURS`, which the add-on names in its panel), each with its number, and
a legend of the groups. Drawn once; the add-on only shows the picture.
"""
from __future__ import annotations

import argparse

import numpy as np
from pdeface.assets import load_head
from pdeface.io.png import draw_text, text_width, write_png
from pdeface.landmark_scheme import COUNT, MIRROR
from pdeface.landmarks.facemap import GROUPS
from pdeface.landmarks.render import View, rasterise, shade

#: Each group's colour in the picture (RGB), in the order the add-on's panel lists them.
GROUP_COLOURS = {"jaw": (40, 110, 230), "brows": (150, 70, 200), "nose": (20, 160, 60), "eyes": (230, 140, 0),
                 "mouth": (220, 30, 40)}


#: Landmarks labelled above their dot (brows, upper lids, upper lips), the rest below.
ABOVE = {*range(17, 27), 37, 38, 43, 44, *range(49, 54), *range(60, 65)}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("-o", "--output", default="blender_addon/images/landmark_scheme.png")
    ap.add_argument("--size", type=int, default=640)
    args = ap.parse_args(argv)
    mesh, lm = load_head()
    V, T = mesh.vertices, mesh.triangles()[0]
    P = V[lm]
    centre = (P.min(0) + P.max(0)) / 2
    half = 0.62 * float((P.max(0) - P.min(0))[:2].max())
    view = View.looking(np.array([0, 0, 1.0]), np.array([0, 1.0, 0]), centre, half, args.size)
    img = np.repeat((shade(V, T, rasterise(V, T, view), background=255) * 0.35 + 165)[..., None], 3, axis=2)
    img = img.astype(np.uint8)
    x, y, _ = view.project(P)
    colour = {i: GROUP_COLOURS[g] for g, rows in GROUPS.items() for i in rows}
    for i in range(COUNT):
        xi, yi = round(float(x[i])), round(float(y[i]))
        img[max(yi - 3, 0):yi + 4, max(xi - 3, 0):xi + 4] = colour[i]
        # Numbers outward from the face's middle, so neighbours' labels do not overlap the dots.
        side = -1 if x[i] < x[MIRROR[i]] - 1 else 1 if x[i] > x[MIRROR[i]] + 1 else 0
        label = str(i)
        lx = xi + 6 if side >= 0 else xi - 6 - text_width(label)
        draw_text(img, lx, yi - 9 if i in ABOVE else yi + 2,
                  label, colour[i])
    for k, (g, rows) in enumerate(GROUPS.items()):
        draw_text(img, 10, 10 + 18 * k, f"{g} {rows.start}-{rows.stop - 1}", GROUP_COLOURS[g], scale=2)
    write_png(args.output, img)
    print(f"wrote {args.output}")


if __name__ == "__main__":
    main()
