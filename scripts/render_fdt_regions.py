"""Draw the 16 FDT regions on the bundled neutral face, and FDTs posing the default face (README pictures).

Usage: python scripts/render_fdt_regions.py [-o docs/fdt_regions.png] [--faces docs/fdt_faces.png] [--size 640]

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
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "core"))

from pdeface.assets import load_neutral_scan  # noqa: E402
from pdeface.fdt.regions import OPENINGS, REGIONS, PupilFrame, region_seeds, region_weights  # noqa: E402
from pdeface.io.png import draw_text, write_png  # noqa: E402
from pdeface.mesh import vertex_normals  # noqa: E402

#: One colour per region (pairs share a hue family, left a shade lighter).
PALETTE = np.array([
    (110, 150, 220), (150, 185, 240), (240, 200, 90), (120, 190, 120), (160, 220, 160), (200, 120, 200),
    (230, 165, 230), (240, 150, 80), (250, 110, 110), (90, 180, 190), (140, 215, 220), (220, 90, 140),
    (180, 60, 110), (150, 120, 80), (200, 170, 120), (130, 130, 200)], np.float64)


def rasterise(P, T, colors, size, box):
    """Flat-coloured triangles (vertex colours interpolated), nearest first: an (h, w, 3) image."""
    h = w = size
    (x0, x1), (y0, y1) = box
    px = (P[:, 0] - x0) / (x1 - x0) * (w - 1)
    py = (y1 - P[:, 1]) / (y1 - y0) * (h - 1)
    img = np.full((h, w, 3), 255.0)
    depth = np.full((h, w), -np.inf)
    for a, b, c in T:
        xs, ys = px[[a, b, c]], py[[a, b, c]]
        lo_x, hi_x = int(max(np.floor(xs.min()), 0)), int(min(np.ceil(xs.max()), w - 1))
        lo_y, hi_y = int(max(np.floor(ys.min()), 0)), int(min(np.ceil(ys.max()), h - 1))
        if lo_x > hi_x or lo_y > hi_y:
            continue
        gx, gy = np.meshgrid(np.arange(lo_x, hi_x + 1), np.arange(lo_y, hi_y + 1))
        d = (ys[1] - ys[2]) * (xs[0] - xs[2]) + (xs[2] - xs[1]) * (ys[0] - ys[2])
        if abs(d) < 1e-12:
            continue
        l0 = ((ys[1] - ys[2]) * (gx - xs[2]) + (xs[2] - xs[1]) * (gy - ys[2])) / d
        l1 = ((ys[2] - ys[0]) * (gx - xs[2]) + (xs[0] - xs[2]) * (gy - ys[2])) / d
        l2 = 1 - l0 - l1
        inside = (l0 >= -1e-9) & (l1 >= -1e-9) & (l2 >= -1e-9)
        z = l0 * P[a, 2] + l1 * P[b, 2] + l2 * P[c, 2]
        yy, xx = gy[inside], gx[inside]
        front = z[inside] > depth[yy, xx]
        yy, xx = yy[front], xx[front]
        depth[yy, xx] = z[inside][front]
        img[yy, xx] = (l0[inside][front, None] * colors[a] + l1[inside][front, None] * colors[b]
                       + l2[inside][front, None] * colors[c])
    return img


def to_pixel(xy, size, box):
    (x0, x1), (y0, y1) = box
    return (xy[..., 0] - x0) / (x1 - x0) * (size - 1), (y1 - xy[..., 1]) / (y1 - y0) * (size - 1)


def dot(img, x, y, r, color):
    h, w, _ = img.shape
    gy, gx = np.ogrid[:h, :w]
    img[(gx - x) ** 2 + (gy - y) ** 2 <= r * r] = color


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("-o", "--output", default=str(Path(__file__).resolve().parent.parent / "docs" / "fdt_regions.png"))
    ap.add_argument("--faces", help="also write the row of posed faces here (e.g. docs/fdt_faces.png)")
    ap.add_argument("--size", type=int, default=640)
    args = ap.parse_args(argv)
    mesh, idx = load_neutral_scan()
    T, _ = mesh.triangles()
    V = mesh.vertices
    frame = PupilFrame.from_landmarks(V[idx])
    P, L = frame.normalise(V), frame.normalise(V[idx])
    W = region_weights(P, L, blend=0)  # the partition itself; the motion blends across its borders
    shade = 0.35 + 0.65 * np.clip(vertex_normals(P, T) @ np.array([0.3, 0.4, 0.87]), 0, 1)
    colors = (W @ PALETTE + (1 - W.sum(1, keepdims=True)) * 235.0) * shade[:, None]
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
    from pdeface.assets import load_face, load_fdt
    from pdeface.au.expressions import PRESETS, pose_curves, resolve_preset
    from pdeface.fdt.deform import fdt_curves
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
        shade = 40 + 200 * np.clip(vertex_normals(P, T) @ np.array([0.35, 0.45, 0.82]), 0, 1)
        tile = rasterise(P, T, np.repeat(shade[:, None], 3, axis=1), size, box)
        draw_text(tile, size // 2, 8, label, (0, 0, 0), scale=2, anchor="center")
        tiles.append(tile)
    return np.clip(np.concatenate(tiles, axis=1), 0, 255).astype(np.uint8)


if __name__ == "__main__":
    main()
