"""Close-ups of what ``pdeface rig`` made of a head: its landmarks at rest and the keys AU27, AU45, AU12 on the user's
mesh (the audit of characters nobody tuned on, ``docs/measurements/audit_unseen.md``).

Usage: python -m scripts.figures.render_audit_unseen RIG_FOLDER [RIG_FOLDER ...] [-o OUT.png] [--size 256]
       [--keys AU27,AU45,AU12] [--title TEXT] [--across 3.2]
       python -m scripts.figures.render_audit_unseen --tile PICTURE.png [PICTURE.png ...] -o OUT.png
       (with the bpy module; Blender's Workbench renders headless)

Each folder is one ``pdeface rig -o`` output: its ``keys.npz`` (the rest mesh, its landmarks and every key's deltas,
:func:`pdeface.rig.load_keys`) is rendered as ``render_keys_devset`` renders the development set (Workbench, studio
light, orthographic, framed on the face from its landmarks): a row per folder and view (front, three-quarter), a
column for the rest (landmarks as red spots) and each key (vertices of a new fold red, the title counting the fold
edges). Several folders stack their rows in one picture. With ``--tile``, the arguments are instead pictures
(``pdeface landmarks --image``), tiled four to a row, each titled with its folder's name.
"""
from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

import numpy as np
from pdeface.io.png import draw_text, write_png
from pdeface.landmark_scheme import eye_distance
from pdeface.mesh import edge_face_pairs
from pdeface.rig import load_keys
from pdeface.surface.frame import face_frame

from .render_keys_devset import FOLD, LEVEL_STEP, SKIN, VIEWS, _coloured_mesh, _panel, _scene, new_fold_vertices

KEYS = ("AU27", "AU45", "AU12")
LANDMARK = (0.85, 0.05, 0.05, 1.0)


def face_view(folder):
    """``(rest vertices, triangles, landmarks, {key: moved vertices})`` of a rig folder in the face frame of its
    landmarks, in eye distances (so every head renders at one size)."""
    k = load_keys(Path(folder) / "keys.npz")
    L = k["landmarks"]
    f, ed = face_frame(L), eye_distance(L)
    to = lambda P: f.to_face(P) / (ed * f.scale)  # noqa: E731
    moved = {n: to(k["vertices"] + d) for n, d in zip(k["names"], k["deltas"])}
    return to(k["vertices"]), k["triangles"], to(L), moved


def rows(folder, size, tmp, keys=KEYS, title="", across=3.2):
    """One folder's rows (front, three-quarter) of panels: rest with its landmarks, then each key; ``across``: eye
    distances across a panel."""
    from scipy.spatial import cKDTree

    V0, T, Lf, moved = face_view(folder)
    pairs = edge_face_pairs(T)
    scene, cam = _scene(size)
    cam.data.ortho_scale = across
    me, colours = _coloured_mesh(scene, "head", V0, T, "marks")
    centre = (Lf[17:68, 0].mean(), Lf[17:68, 1].mean() - 0.35, Lf[17:68, 2].mean())
    spots = np.unique(np.concatenate(cKDTree(V0).query_ball_point(Lf, 0.03)).astype(int))
    out = {v: [] for v in VIEWS}
    for key in ("rest", *keys):
        P = V0 if key == "rest" else moved.get(key)
        c = np.tile(SKIN, (len(V0), 1))
        label = key if key == "rest" else f"{key}: no key" if P is None else key
        if P is None:
            P = V0
        elif key == "rest":
            c[spots] = LANDMARK
        else:
            at, n = new_fold_vertices(V0, P, T, pairs)
            c[at] = FOLD
            label += f": {n} new folds"
        me.vertices.foreach_set("co", P.astype(np.float32).ravel())
        colours.data.foreach_set("color", c.astype(np.float32).ravel())
        me.update()
        for view, degrees in VIEWS.items():
            img = _panel(scene, cam, centre, degrees, Path(tmp) / "panel.png")
            text = (title[:28] + ": " if key == "rest" and title else "") + label if view == "front" else view
            draw_text(img, 4, 4, text, (0, 0, 0), 1)
            out[view].append(img)
    return [np.concatenate(r, axis=1) for r in out.values()]


def tiled(paths, size=288, columns=4):
    """The pictures ``paths`` (PNG, square) shrunk to ``size`` pixels and tiled ``columns`` to a row, each titled with
    its folder's name."""
    import bpy

    tiles = []
    for path in paths:
        img = bpy.data.images.load(str(Path(path).resolve()))
        w, h = img.size
        px = np.empty(w * h * 4, np.float32)
        img.pixels.foreach_get(px)
        rgb = (np.clip(px.reshape(h, w, 4)[::-1, :, :3], 0, 1) * 255).astype(np.uint8)
        pick = (np.arange(size) * h / size).astype(int)
        tile = rgb[pick][:, pick].copy()
        draw_text(tile, 4, 4, Path(path).parent.name, (255, 255, 0), 1)
        tiles.append(tile)
    tiles += [np.zeros_like(tiles[0])] * (-len(tiles) % columns)
    return np.concatenate([np.concatenate(tiles[i:i + columns], axis=1) for i in range(0, len(tiles), columns)])


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("folders", nargs="+", help="pdeface rig output folders")
    ap.add_argument("-o", "--out", default="audit.png")
    ap.add_argument("--size", type=int, default=256, help="pixels per panel")
    ap.add_argument("--keys", default=",".join(KEYS))
    ap.add_argument("--across", type=float, default=3.2, help="eye distances across a panel")
    ap.add_argument("--title", help="comma-separated titles, one per folder (default: the folders' names)")
    ap.add_argument("--tile", action="store_true", help="tile the pictures given instead (pdeface landmarks --image)")
    args = ap.parse_args(argv)
    if args.tile:
        write_png(args.out, (tiled(args.folders) // LEVEL_STEP) * LEVEL_STEP + LEVEL_STEP // 2)
        print(f"wrote {args.out} ({Path(args.out).stat().st_size / 1e3:.0f} kB)")
        return
    titles = args.title.split(",") if args.title else [Path(f).parent.name for f in args.folders]
    with tempfile.TemporaryDirectory() as tmp:
        img = np.concatenate([r for f, t in zip(args.folders, titles)
                              for r in rows(f, args.size, tmp, args.keys.split(","), t, args.across)], axis=0)
    write_png(args.out, (img // LEVEL_STEP) * LEVEL_STEP + LEVEL_STEP // 2)
    print(f"wrote {args.out} ({Path(args.out).stat().st_size / 1e3:.0f} kB)")


if __name__ == "__main__":
    main()
