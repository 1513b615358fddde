"""Draw the 68 landmark vertices annotated on MakeHuman's base mesh (the development set's truth).

Usage: python -m scripts.figures.render_devset_landmarks [-o docs/images/makehuman_landmarks.png] [--size 480]
       [--compare OLD.json]

Panels: the whole face, the right eye and the mouth, rendered straight on with the project's own renderer,
each annotated point a red dot (with ``--compare``, an older annotation's vertices as blue dots beneath; a
profile panel is added). Needs ``../shared/data/makehuman``.
"""
from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np
from pdeface.io.png import write_png
from pdeface.landmarks.render import View, marked, rasterise, shade

from scripts.devset.characters import annotated_points
from scripts.devset.makehuman import read_base, triangles

#: Panels: centre (base-mesh decimetres) and half-width of each close-up.
PANELS = [((0, 7.0, 1.1), 0.9), ((-0.31, 7.28, 1.1), 0.28), ((0, 6.62, 1.3), 0.3)]


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("-o", "--output", default="docs/images/makehuman_landmarks.png")
    ap.add_argument("--size", type=int, default=480)
    ap.add_argument("--compare", help="an older annotation (json with vertex 'indices'), drawn in blue")
    args = ap.parse_args(argv)
    base = read_base()
    V, T = base.vertices, triangles(base.group_quads("body"))
    points = [(annotated_points(V), (230, 30, 30))]
    views = [(np.array([0, 0, 1.0]), centre, half) for centre, half in PANELS]
    if args.compare:
        old = V[np.array(json.loads(Path(args.compare).read_text())["indices"])]
        points.insert(0, (old, (40, 90, 240)))
        views.append((np.array([-1.0, 0, 0]), PANELS[0][0], PANELS[0][1]))  # the subject's right profile
    panels = []
    for forward, centre, half in views:
        view = View.looking(forward, np.array([0, 1.0, 0]), np.array(centre), half, args.size)
        img = shade(V, T, rasterise(V, T, view))
        for P, colour in points:
            x, y, _ = view.project(P)
            inside = (x > 3) & (x < args.size - 4) & (y > 3) & (y < args.size - 4)
            if forward[0] < 0:  # the profile: the near side only
                inside &= P[:, 0] <= 1e-6
            img = marked(img, np.stack([x, y], 1)[inside], r=3, colour=colour)
        panels.append(img)
    write_png(args.output, np.concatenate(panels, axis=1))
    print(f"wrote {args.output}")


if __name__ == "__main__":
    main()
