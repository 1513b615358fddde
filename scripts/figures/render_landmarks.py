"""Draw automatic landmarks found on three meshes (README picture).

Usage: python -m scripts.figures.render_landmarks [-o docs/images/landmarks.png] [--size 320]

Panels: a held-out ICT head as ICT gives it (cm, +z front); the same head in
Blender's axes, turned 25° and in metres; a whole body in metres of another
topology (its search view, then its face). Each face panel is the frontal
render the landmarks were read from, ICT's own landmarks in green under the
found ones in red. Needs ``pdeface[landmarks]``.
"""
from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
from pdeface.assets import load_head, load_head_shapes
from pdeface.io.png import draw_text, write_png
from pdeface.landmarks import detect
from pdeface.landmarks.detector import Detector
from pdeface.landmarks.pipeline import SEARCH_AXES, _framing
from pdeface.landmarks.render import marked, rasterise, shade
from pdeface.rigid import rotation_vector_matrix
from pdeface.surface.frame import BLENDER_FROM_ICT

from scripts.bench.benchlib import body_character

HEAD = "identity017"  # held out of the shipped map


def resize(img, size):
    """Nearest-neighbour resize of a square image."""
    idx = np.arange(size) * img.shape[0] // size
    return img[idx][:, idx]


def face_panel(V, T, true, det, size, title):
    found = detect(V, T, detector=det, keep_images=True)
    view, img = found.images["view"], found.images["frontal"]
    k = size / img.shape[0]
    tx, ty, _ = view.project(true)
    fx, fy, _ = view.project(found.points)
    rgb = resize(np.repeat(img[..., None], 3, axis=2), size)
    rgb = marked(marked(rgb, np.stack([tx, ty], 1) * k, 2, (40, 200, 60)), np.stack([fx, fy], 1) * k, 1)
    draw_text(rgb, 6, 6, title, (255, 255, 255), 1)
    draw_text(rgb, 6, 18, f"view {found.view}", (200, 200, 200), 1)
    return rgb


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("-o", "--out", default=str(Path(__file__).resolve().parents[2] / "docs" / "images" / "landmarks.png"))
    ap.add_argument("--size", type=int, default=320)
    args = ap.parse_args(argv)
    mesh, lm = load_head()
    T, _ = mesh.triangles()
    V = mesh.vertices + load_head_shapes()[HEAD]
    M = BLENDER_FROM_ICT @ rotation_vector_matrix([0, np.radians(25), 0]) * 0.01
    Vb, Tb, Mb, shift = body_character(V, T)
    with Detector() as det:
        panels = [face_panel(V, T, V[lm], det, args.size, "ICT head, cm"),
                  face_panel(V @ M.T, T, V[lm] @ M.T, det, args.size, "Blender axes, 25 deg, m")]
        forward, up = SEARCH_AXES["-y"]
        body = resize(np.repeat(shade(Vb, Tb, rasterise(Vb, Tb, _framing(Vb, forward, up, 512)))[..., None], 3, 2),
                      args.size)
        draw_text(body, 6, 6, "body, m, other topology", (255, 255, 255), 1)
        panels += [body, face_panel(Vb, Tb, V[lm] @ Mb.T + shift, det, args.size, "its face")]
    write_png(args.out, np.concatenate(panels, axis=1))
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
