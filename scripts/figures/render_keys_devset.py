"""Close-ups of the development set's hardest heads in neutral, AU12, AU27, AU45 and happy (issue #40).

Usage: python -m scripts.figures.render_keys_devset [-o docs/images/keys_devset.png] [--size 260]
       [--only NAME,...] [--as-bound]

Each row a character of ``scripts.devset.characters`` rigged as ``bench_keys_devset`` rigs it (true
landmarks, the add-on's joined objects, :class:`pdeface.head.bind.HeadBinding`); each panel a front view
in the face frame, grey-shaded, every new fold (an edge under 20° at rest and over 40° in the key) a red dot
and its count in the title. ``--as-bound``: the keys without the fold relaxation and the lids' closing
(:mod:`pdeface.head.folds`, :mod:`pdeface.head.lids`), as they were before them.
"""
from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
from pdeface.au.modelfile import load_face
from pdeface.au.retarget import retarget
from pdeface.head import folds
from pdeface.head.bind import HeadBinding, descriptor_motion_args
from pdeface.io.png import draw_text, write_png
from pdeface.landmarks.render import marked
from pdeface.mesh import edge_face_pairs, turn_degrees
from pdeface.presets import every_pose
from pdeface.surface.fit import fit_face

from scripts.devset.characters import SPECS, build
from scripts.figures.drawlib import rasterise, shade, to_pixel

#: The hardest heads of the development set before issue #40's fixes: lids closing 0.32-0.65, 25-110 folds.
HARDEST = ("stylised-chin-cheek-in", "voxel-m", "stylised-parted-decimated-dm", "decimated-cm",
           "eyes-teeth-separate-in")
KEYS = ("neutral", "AU12", "AU27", "AU45", "happy")


def rigged(name, as_bound=False):
    """(face-frame vertices, triangles, face-frame landmarks, {key: face-frame displacements}, eye distance)."""
    ch = build(SPECS[name])
    V, T, L = ch.vertices, ch.triangles, ch.landmarks
    for Vp, Tp in ch.parts.values():  # the add-on joins a head's objects
        T = np.concatenate([T, Tp + len(V)])
        V = np.concatenate([V, Vp])
    model, _ = fit_face(V, T, L)
    model = retarget(load_face("default"), model)
    b = HeadBinding(model, V, T, landmarks=L)
    descr = {f"AU{d.key}": d for d in model.descriptors}
    poses = every_pose(model)
    names = KEYS[1:]
    motions = [descriptor_motion_args(descr[n]) if n in descr else b.pose_motion_args(poses[n], "sum") for n in names]
    if as_bound:  # no lids' closing; the relaxation is off (main)
        motions = [m[:4] for m in motions]
    f = model.frame
    D = {n: f.to_face(V + d) - f.to_face(V) for n, d in zip(names, b.displacements(motions))}
    return f.to_face(V), T, f.to_face(L), D, b.eye_distance


def row(name, size, as_bound):
    Vf, T, Lf, D, ed = rigged(name, as_bound)
    centre = Lf[17:68].mean(0)
    half = 1.05 * ed
    box = ((centre[0] - half, centre[0] + half), (centre[1] - 1.25 * half, centre[1] + 0.75 * half))
    (x0, x1), (y0, y1) = box
    seen = ((Vf[T, 0] > x0) & (Vf[T, 0] < x1) & (Vf[T, 1] > y0) & (Vf[T, 1] < y1)).any(axis=1)
    pairs = edge_face_pairs(T)
    flat = turn_degrees(Vf, T, pairs) < 20
    panels = []
    for key in KEYS:
        P = Vf + D.get(key, 0.0)
        grey = 40 + 200 * shade(P, T)
        img = rasterise(P, T[seen], np.repeat(grey[:, None], 3, axis=1), size, box)
        new = flat & (turn_degrees(P, T, pairs) > 40)
        where = P[T[pairs[new]]].mean(axis=(1, 2))
        if len(where):
            img = marked(img, np.stack(to_pixel(where[:, :2], size, box), 1), 1)
        draw_text(img, 4, 4, f"{name[:24]}" if key == "neutral" else f"{key}: {int(new.sum())} folds", (0, 0, 0), 1)
        panels.append(img)
    return np.concatenate(panels, axis=1)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("-o", "--out", default=str(Path(__file__).resolve().parents[2] / "docs" / "images" / "keys_devset.png"))
    ap.add_argument("--size", type=int, default=260)
    ap.add_argument("--only", help="comma-separated character names (default: the five hardest)")
    ap.add_argument("--as-bound", action="store_true", help="without the fold relaxation and the lids' closing")
    args = ap.parse_args(argv)
    if args.as_bound:
        folds.RELAX_STEPS = 0
    names = args.only.split(",") if args.only else HARDEST
    rows = [row(n, args.size, args.as_bound) for n in names]
    write_png(args.out, np.concatenate(rows, axis=0).astype(np.uint8))
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
