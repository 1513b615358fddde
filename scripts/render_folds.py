"""Close-ups of the PDE face's eyes, nose and mouth with its folds marked (README picture, issue #16).

Usage: python scripts/render_folds.py [-o docs/folds_closeup.png] [--size 420]

Panels: the bundled ICT neutral scan; the PDE face fitted to it at rest; the same with the bundled
descriptors retargeted, in AU27 and in happy. Front views in the face frame, grey-shaded; every fold
(:func:`pdeface.surface.folds.fold_edges`: an edge over 30° outside the openings) is a red dot.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "core"))

from drawlib import rasterise, shade, to_pixel  # noqa: E402
from pdeface.assets import load_face, load_neutral_scan  # noqa: E402
from pdeface.au.expressions import PRESETS, pose_curves, resolve_preset  # noqa: E402
from pdeface.au.retarget import retarget  # noqa: E402
from pdeface.io.png import draw_text, write_png  # noqa: E402
from pdeface.landmarks.render import marked  # noqa: E402
from pdeface.surface.fit import face_mesh, fit_face  # noqa: E402
from pdeface.surface.folds import fold_edges  # noqa: E402

BOX = ((-75.0, 75.0), (-65.0, 45.0))


def panel(P, T, size, title, folds=None):
    grey = 40 + 200 * shade(P, T)
    img = rasterise(P, T, np.repeat(grey[:, None], 3, axis=1), size, BOX)
    if folds is not None and len(folds):
        img = marked(img, np.stack(to_pixel(folds[:, :2], size, BOX), 1), 1)
    draw_text(img, 6, 6, title, (0, 0, 0), 1)
    return img


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("-o", "--out", default=str(Path(__file__).resolve().parent.parent / "docs" / "folds_closeup.png"))
    ap.add_argument("--size", type=int, default=420)
    args = ap.parse_args(argv)
    scan, idx = load_neutral_scan()
    T, _ = scan.triangles()
    model, _ = fit_face(scan.vertices, T, scan.vertices[idx], unit="cm")
    rig = retarget(load_face("default"), model)
    panels = [panel(model.frame.to_face(scan.vertices), T, args.size, "ICT scan")]
    poses = {"rest": {}, "AU27": {"27": 1.0},
             "happy": resolve_preset(PRESETS["happy"], {d.key for d in rig.descriptors})[0]}
    for name, weights in poses.items():
        C, R = pose_curves(rig, weights) if weights else (None, None)
        mesh = face_mesh(rig, coefficients=C, residual=R)
        r = fold_edges(mesh, rig.frame, rig.landmarks, rest=face_mesh(rig))
        panels.append(panel(rig.frame.to_face(mesh.vertices), mesh.triangles()[0], args.size,
                            f"PDE {name}: {r['count']} folds", r["where"]))
    write_png(args.out, np.concatenate(panels, axis=1).astype(np.uint8))
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
