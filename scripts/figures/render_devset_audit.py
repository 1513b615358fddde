"""The development set's annotation audited against ICT-FaceKit's convention, by eye.

Usage: python -m scripts.figures.render_devset_audit [-o docs/images/devset_audit.png] [--size 360]
       [--characters base-dm,...] [--found] [--compare OLD.json]

One row per head, three panels each (front, three-quarter from the subject's right, right profile), rendered
with the project's own renderer and framed on the head's own landmarks (so rows compare): first ICT's generic
head with its 68 landmark vertices (the convention the detector's map follows), then each named development-set
character with its annotated landmarks (red; with ``--compare``, an annotation's base vertices carried through
the character's targets in blue beneath: what the truth was before each character was annotated on its own; with
``--found``, the points the detector finds as small green dots on top). Needs ``../shared/data/makehuman`` (and, for
``--found``, ``pdeface[landmarks]``).
"""
from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np
from pdeface.assets import load_head
from pdeface.io.png import write_png
from pdeface.landmark_scheme import eye_distance
from pdeface.landmarks.render import View, marked, rasterise, shade
from pdeface.surface.frame import face_frame

from scripts.devset.characters import SPECS, UNIT_MM, build
from scripts.devset.makehuman import BASE_MM

#: Panels: the direction the viewer looks from, in the face frame (+x the subject's left, +z forward).
PANELS = {"front": (0.0, 0.0, 1.0), "three-quarter": (-0.7, 0.0, 0.7), "profile": (-1.0, 0.0, 0.0)}
RED, BLUE, GREEN = (230, 30, 30), (40, 90, 240), (30, 190, 60)
DRAWN = [BLUE, RED, GREEN]


def panels(V, T, point_sets, size):
    """The three panels of one head: ``point_sets`` a list of ``((68, 3) points, colour)``, the first the
    landmarks that frame it."""
    L = point_sets[0][0]
    f = face_frame(L)
    eyes = eye_distance(L)
    centre = L[17:].mean(0) * 0.5 + L[:17].mean(0) * 0.5
    out = []
    for name, d in PANELS.items():
        forward = np.array(d) @ f.rotation  # face-frame direction → mesh space
        view = View.looking(forward, f.rotation[1], centre, 1.6 * eyes, size)
        img = shade(V, T, rasterise(V, T, view))
        for P, colour in sorted(point_sets, key=lambda s: DRAWN.index(s[1])):  # carried, truth, found on top
            x, y, _ = view.project(P)
            near = np.ones(len(P), bool) if name == "front" else (f.to_face(P)[:, 0] - f.to_face(L)[:, 0].mean()
                                                                   <= 1e-6 * f.scale)
            img = marked(img, np.stack([x, y], 1)[near], r=1 if colour == GREEN else 2, colour=colour)
        out.append(img)
    return np.concatenate(out, axis=1)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("-o", "--output", default="docs/images/devset_audit.png")
    ap.add_argument("--size", type=int, default=360)
    ap.add_argument("--characters", default="base-dm,caucasian-female-young-cm,stylised-chin-cheek-in")
    ap.add_argument("--found", action="store_true", help="also the detector's points (green)")
    ap.add_argument("--compare", help="an annotation json whose base-mesh vertex 'indices' are drawn in blue, carried "
                    "through each character's targets (heads in ICT's axes only)")
    ap.add_argument("--no-ict", action="store_true", help="leave out ICT's row")
    args = ap.parse_args(argv)
    rows = []
    det = None
    if args.found:
        from pdeface.landmarks.detector import Detector
        from pdeface.landmarks.headfind import detect_anywhere
        det = Detector()
    if not args.no_ict:
        head, idx = load_head()
        V, T = head.vertices, head.triangles()[0]
        sets = [(V[idx], RED)]
        if det:
            sets.append((detect_anywhere(V, T, detector=det).points, GREEN))
        rows.append(panels(V, T, sets, args.size))
    for name in args.characters.split(","):
        ch = build(SPECS[name])
        V, T = ch.joined()
        sets = [(ch.landmarks, RED)]
        if args.compare and not (ch.spec.remesh != "none" or ch.spec.body or ch.spec.head_turn
                                 or ch.spec.axes != "ict"):
            old = np.array(json.loads(Path(args.compare).read_text())["indices"])
            sets.append((_carried(ch, old), BLUE))
        if det:
            sets.append((detect_anywhere(ch.vertices, ch.triangles, detector=det).points, GREEN))
        rows.append(panels(V, T, sets, args.size))
    if det:
        det.close()
    write_png(args.output, np.concatenate(rows, axis=0))
    print(f"wrote {args.output}")


def _carried(ch, indices):
    """Base-mesh vertex ``indices`` on character ``ch`` (a head in ICT's axes, not remeshed, posed or turned)."""
    from scripts.devset.characters import _identity

    return _identity(ch.spec)[indices] * BASE_MM / UNIT_MM[ch.spec.unit]


if __name__ == "__main__":
    main()
