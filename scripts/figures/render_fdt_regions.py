"""Draw the 16 FDT regions on the bundled neutral face, and FDTs posing the default face (README pictures).

Usage: python -m scripts.figures.render_fdt_regions [-o docs/images/fdt_regions.png] [--faces docs/images/fdt_faces.png] [--size 640]

Regions: a front view of the ICT-FaceKit neutral face region (orthographic, in
the pupil-normalised frame), each skin vertex coloured by its region, shaded by
its normal, with the regions' seeds as dots, their numbers, and the openings'
lines. Faces: the default PDE face (fine mesh) neutral, happy from the PDE
descriptors, from the generic 3-D and 2-D FDTs, the paper's Table I smile, and
AU27 from its 3-D FDT, grey-shaded so that a crack or fold at a region's border
would show. No plotting library: a small z-buffer rasteriser and :mod:`pdeface.io.png`.
"""
from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
from pdeface.assets import load_neutral_scan
from pdeface.fdt.regions import OPENINGS, REGIONS, PupilFrame, region_seeds, region_weights
from pdeface.io.png import draw_text, write_png

from scripts.figures.drawlib import dot, rasterise, shade, to_pixel

#: One colour per region (pairs share a hue family, left a shade lighter).
PALETTE = np.array([
    (110, 150, 220), (150, 185, 240), (240, 200, 90), (120, 190, 120), (160, 220, 160), (200, 120, 200),
    (230, 165, 230), (240, 150, 80), (250, 110, 110), (90, 180, 190), (140, 215, 220), (220, 90, 140),
    (180, 60, 110), (150, 120, 80), (200, 170, 120), (130, 130, 200)], np.float64)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("-o", "--output", default=str(Path(__file__).resolve().parents[2] / "docs" / "images" / "fdt_regions.png"))
    ap.add_argument("--faces", help="also write the row of posed faces here (e.g. docs/images/fdt_faces.png)")
    ap.add_argument("--size", type=int, default=640)
    args = ap.parse_args(argv)
    mesh, idx = load_neutral_scan()
    T, _ = mesh.triangles()
    V = mesh.vertices
    frame = PupilFrame.from_landmarks(V[idx])
    P, L = frame.normalise(V), frame.normalise(V[idx])
    W = region_weights(P, L, blend=0)  # the partition itself; the motion blends across its borders
    colors = (W @ PALETTE + (1 - W.sum(1, keepdims=True)) * 235.0) * (0.35 + 0.65 * shade(P, T, 1.0))[:, None]
    box = ((-2.7, 2.7), (-3.6, 2.3))
    img = rasterise(P, T, colors, args.size, box)
    for spans, _, _ in OPENINGS.values():
        for groups in spans:
            knots = np.array([L[list(g), :2].mean(0) for g in groups])
            xs = np.linspace(knots[0, 0], knots[-1, 0], 200)
            px, py = to_pixel(np.column_stack([xs, np.interp(xs, knots[:, 0], knots[:, 1])]), args.size, box)
            img[np.clip(py.round().astype(int), 0, args.size - 1), np.clip(px.round().astype(int), 0, args.size - 1)] = 0
    seeds, owner = region_seeds(L)
    sx, sy = to_pixel(seeds, args.size, box)
    for x, y in zip(sx, sy):
        dot(img, x, y, 3, (30, 30, 30))
    for k, r in enumerate(REGIONS):
        x, y = sx[owner == k].mean(), sy[owner == k].mean()
        draw_text(img, int(x), int(y) - 16, str(r.number), (0, 0, 0), scale=2, anchor="center")
    draw_text(img, 10, 10, "FDT REGIONS (SEEDS: DOTS, OPENINGS: LINES)", (0, 0, 0), scale=2)
    Path(args.output).parent.mkdir(parents=True, exist_ok=True)
    write_png(args.output, np.clip(img, 0, 255).astype(np.uint8))
    print(f"wrote {args.output}")
    if args.faces:
        write_png(args.faces, faces_row(args.size // 2))
        print(f"wrote {args.faces}")


def faces_row(size):
    """Neutral, happy (PDE descriptors, 3-D FDT, 2-D FDT), the paper's smile and AU27 (3-D FDT), side by side."""
    from pdeface.au.modelfile import load_face
    from pdeface.fdt.deform import fdt_curves
    from pdeface.fdt.table import load_fdt
    from pdeface.posing import pose_curves
    from pdeface.presets import PRESETS, resolve_preset
    from pdeface.surface.fit import face_mesh
    from pdeface.surface.model import model_landmarks

    face = load_face("default")
    happy, _ = resolve_preset(PRESETS["happy"], {d.key for d in face.descriptors})
    poses = [("NEUTRAL", (face.coefficients, face.residual)), ("HAPPY PDE", pose_curves(face, happy))]
    for label, name, model in (("HAPPY FDT 3D", "happy", "3d"), ("HAPPY FDT 2D", "happy", "2d"),
                               ("PAPER SMILE", "paper-smile", "2d"), ("AU27 FDT 3D", "27", "3d")):
        dC, dR = fdt_curves(face, load_fdt(name, model))
        poses.append((label, (face.coefficients + dC, face.residual + dR)))
    frame = PupilFrame.from_landmarks(model_landmarks(face))
    box = ((-2.3, 2.3), (-3.9, 1.6))
    tiles = []
    for label, (C, R) in poses:
        mesh = face_mesh(face, "fine", coefficients=C, residual=R)
        T, _ = mesh.triangles()
        P = frame.normalise(face.frame.to_face(mesh.vertices))
        tile = rasterise(P, T, np.repeat((40 + 200 * shade(P, T))[:, None], 3, axis=1), size, box)
        draw_text(tile, size // 2, 8, label, (0, 0, 0), scale=2, anchor="center")
        tiles.append(tile)
    return np.clip(np.concatenate(tiles, axis=1), 0, 255).astype(np.uint8)


if __name__ == "__main__":
    main()
