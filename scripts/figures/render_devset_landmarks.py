"""Draw the 68 landmark vertices annotated on MakeHuman's base mesh (the development set's truth).

Usage: python -m scripts.figures.render_devset_landmarks [-o docs/images/makehuman_landmarks.png] [--size 480]

Panels: the whole face, the right eye and the mouth, rendered straight on with the project's own renderer,
each annotated vertex a red dot. Needs ``../shared/data/makehuman``.
"""
from __future__ import annotations

import argparse

import numpy as np
from pdeface.io.png import write_png
from pdeface.landmarks.render import View, marked, rasterise, shade

from scripts.devset.characters import annotated_indices
from scripts.devset.makehuman import read_base, triangles

#: Panels: centre (base-mesh decimetres) and half-width of each close-up.
PANELS = [((0, 7.0, 1.1), 0.9), ((-0.31, 7.28, 1.1), 0.28), ((0, 6.62, 1.3), 0.3)]


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("-o", "--output", default="docs/images/makehuman_landmarks.png")
    ap.add_argument("--size", type=int, default=480)
    args = ap.parse_args(argv)
    base = read_base()
    V, T = base.vertices, triangles(base.group_quads("body"))
    idx = annotated_indices()
    panels = []
    for centre, half in PANELS:
        view = View.looking(np.array([0, 0, 1.0]), np.array([0, 1.0, 0]), np.array(centre), half, args.size)
        x, y, _ = view.project(V[idx])
        inside = (x > 3) & (x < args.size - 4) & (y > 3) & (y < args.size - 4)
        panels.append(marked(shade(V, T, rasterise(V, T, view)), np.stack([x, y], 1)[inside], r=3))
    write_png(args.output, np.concatenate(panels, axis=1))
    print(f"wrote {args.output}")


if __name__ == "__main__":
    main()
