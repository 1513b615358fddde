"""Close-ups of the PDE face's eyes, nose and mouth with its folds marked (README pictures, issue #16).

Usage: python -m scripts.figures.render_folds [-o docs/images/folds_closeup.png] [--size 420]
       python -m scripts.figures.render_folds --identity 7 --au 28 --resolution 4,4 -o docs/images/folds_retarget.png
       python -m scripts.figures.render_folds --identity 0 --au 18 --compare-steps -o docs/images/folds_steps.png

Panels: the bundled ICT neutral scan; the PDE face fitted to it at rest; the same with the bundled
descriptors retargeted, in AU27 and in happy. With ``--identity``: that ICT identity posed by ICT's
own shape for ``--au`` (the truth), then the PDE face fitted to it with the bundled descriptors
retargeted by curve index alone and with the gap rule (:mod:`pdeface.au.retarget`), in that AU; with
``--compare-steps``, the retargeted face on an even 4-step mesh and at the default resolution's steps
(:mod:`pdeface.surface.sampling`).
Front views in the face frame, grey-shaded; every fold (:func:`pdeface.surface.folds.fold_edges`: an
edge over 30° outside the openings) is a red dot.
"""
from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
from pdeface.assets import load_ict_shapes, load_neutral_scan
from pdeface.au.ict import au_offsets
from pdeface.au.modelfile import load_face
from pdeface.au.retarget import retarget
from pdeface.io.png import draw_text, write_png
from pdeface.landmarks.render import marked
from pdeface.posing import pose_curves
from pdeface.presets import PRESETS, resolve_preset
from pdeface.surface.fit import face_mesh, fit_face
from pdeface.surface.folds import fold_edges

from scripts.figures.drawlib import rasterise, shade, to_pixel

BOX = ((-75.0, 75.0), (-65.0, 45.0))
MOUTH_BOX = ((-45.0, 45.0), (-75.0, 15.0))  # --identity: the mouth and the cheeks beside its corners


def panel(P, T, size, title, folds=None, box=BOX):
    grey = 40 + 200 * shade(P, T)
    img = rasterise(P, T, np.repeat(grey[:, None], 3, axis=1), size, box)
    if folds is not None and len(folds):
        img = marked(img, np.stack(to_pixel(folds[:, :2], size, box), 1), 1)
    draw_text(img, 6, 6, title, (0, 0, 0), 1)
    return img


def posed_panel(rig, weights, size, title, box=BOX, resolution="default"):
    """``rig`` posed by ``weights``, its folds (outside the openings at rest and posed) marked."""
    C, R = pose_curves(rig, weights) if weights else (None, None)
    mesh = face_mesh(rig, resolution, coefficients=C, residual=R)
    r = fold_edges(mesh, rig.frame, rig.landmarks, rest=face_mesh(rig, resolution))
    return panel(rig.frame.to_face(mesh.vertices), mesh.triangles()[0], size, f"{title}: {r['count']} folds",
                 r["where"], box)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("-o", "--out", default=str(Path(__file__).resolve().parents[2] / "docs" / "images" / "folds_closeup.png"))
    ap.add_argument("--size", type=int, default=420)
    ap.add_argument("--identity", type=int, help="an ICT identity (0-19): compare retargeting with and without "
                                                 "the gap rule on it")
    ap.add_argument("--au", default="28", help="with --identity: the AU key to pose")
    ap.add_argument("--resolution", default="default", help="the PDE face's mesh resolution (pdeface mesh's)")
    ap.add_argument("--compare-steps", action="store_true",
                    help="with --identity: the retargeted face on an even 4-step mesh and at the default's steps")
    args = ap.parse_args(argv)
    scan, idx = load_neutral_scan()
    T, _ = scan.triangles()
    if args.identity is None:
        model, _ = fit_face(scan.vertices, T, scan.vertices[idx], unit="cm")
        rig = retarget(load_face("default"), model)
        panels = [panel(model.frame.to_face(scan.vertices), T, args.size, "ICT scan")]
        poses = {"rest": {}, "AU27": {"27": 1.0},
                 "happy": resolve_preset(PRESETS["happy"], {d.key for d in rig.descriptors})[0]}
        panels += [posed_panel(rig, weights, args.size, f"PDE {name}", resolution=args.resolution)
                   for name, weights in poses.items()]
    else:
        shapes = load_ict_shapes()
        V = scan.vertices + shapes[f"identity{args.identity:03d}"]
        model, _ = fit_face(V, T, V[idx], unit="cm")
        truth = model.frame.to_face(V + au_offsets(args.au, shapes))
        panels = [panel(truth, T, args.size, f"ICT identity{args.identity:03d} AU{args.au}", box=MOUTH_BOX)]
        if args.compare_steps:
            rig = retarget(load_face("default"), model)
            for resolution, name in (("4,4", "even 4 steps"), ("default", "default steps")):
                panels.append(posed_panel(rig, {args.au: 1.0}, args.size, f"PDE AU{args.au}, {name}", MOUTH_BOX,
                                          resolution))
        else:
            for spacing, name in ((False, "by curve index"), (True, "gap rule")):
                rig = retarget(load_face("default"), model, spacing=spacing)
                panels.append(posed_panel(rig, {args.au: 1.0}, args.size, f"PDE AU{args.au}, {name}", MOUTH_BOX,
                                          args.resolution))
    write_png(args.out, np.concatenate(panels, axis=1).astype(np.uint8))
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
