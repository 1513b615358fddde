"""Close-ups of the development set's hardest heads in neutral, AU12, AU27, AU45 and happy (issue #40).

Usage: python -m scripts.figures.render_keys_devset [-o docs/images] [--size 512] [--only NAME,...]
       (with the bpy module; Blender's Workbench engine renders headless)

Each character of ``scripts.devset.characters`` is rigged as ``bench_keys_devset`` rigs it (true landmarks,
the add-on's joined objects, :class:`pdeface.head.bind.HeadBinding`) and rendered with Blender's Workbench
(studio light, smooth shading) in a front and a three-quarter view, one ``keys_devset_<name>.png`` per character:
a row per view, a column per key. Vertices of a new fold (an edge under 20° at rest and over 40° in the key) are
red, and each panel's title counts those edges. The mouth's lining (skin behind the inner lips) is dark and the
teeth ivory and the tongue red, as a texture would have them; a head with no mouth inside gets the mouth bag the
add-on adds (:mod:`pdeface.head.mouth`), dark too (``--no-mouth-bag``: not), as ``no-mouth-inside-cm``
(``scripts.devset.characters.NO_MOUTH_INSIDE``) and ``voxel-m-cut-lips`` (voxel-m's fused lips cut open, fitted
again) show.
"""
from __future__ import annotations

import argparse
import math
import tempfile
from pathlib import Path

import numpy as np
from pdeface.au.modelfile import load_face
from pdeface.au.retarget import retarget
from pdeface.head.bind import HeadBinding
from pdeface.head.mouth import cut_lips, mouth_bag
from pdeface.head.parts import mouth_line
from pdeface.io.png import draw_text, write_png
from pdeface.landmark_scheme import INNER_LIPS, MOUTH_CORNERS
from pdeface.mesh import connected_components, edge_face_pairs, turn_degrees
from pdeface.surface.fit import fit_face

from scripts.devset.characters import NO_MOUTH_INSIDE, SPECS, build

OUT = Path(__file__).resolve().parents[2] / "docs" / "images"
#: The hardest heads of the development set after issue #40's first fixes: fused lips (voxel-m), the mouth curves
#: once on the chin (body-A-cm), the most keys folding (eyes-teeth-separate-in), the least closed lids and smallest
#: smile (stylised-parted-decimated-dm, stylised-chin-cheek-in).
HARDEST = ("voxel-m", "body-A-cm", "eyes-teeth-separate-in", "stylised-parted-decimated-dm", "stylised-chin-cheek-in")
#: A character's name with this after it: its fused lips cut open (:func:`pdeface.head.mouth.cut_lips`), fitted again.
CUT = "-cut-lips"
#: Rendered beside them by default: the head with no mouth inside, and voxel-m with its lips cut, with mouth bags.
MOUTH_BAG = (NO_MOUTH_INSIDE.name, "voxel-m" + CUT)
#: Rendered beside them by default: lips a decimation merged at the middle (AU27 opened them as a beak before the
#: jaw keys' relaxation kept the lower lip, branch keys-joined-lips).
MERGED_LIPS = ("decimated-cm",)
#: Every character rendered by default, in the page's order.
RENDERED = HARDEST + MOUTH_BAG + MERGED_LIPS
#: What the renders show, looked at (2026-11-26, branch keys-au45; the bench's page lists them). Rendered
#: again after a change to the binding, these are to be looked at and written again.
SEEN = {
    "voxel-m": "fused lips (one surface, no opening): AU27 drops the chin and lower lip and stretches the skin joining "
               "the lips into a sheet with a crease down its middle (8 new folds): no opening without cutting the "
               "mesh, so the binding warns (lips joined: cut the mouth open); AU12 a fold on one cheek (1); AU45 "
               "closes the jagged voxel lids part way, a fold on the right upper lid (3, as before the lower lids "
               "were held); happy a fold at one corner (1)",
    "body-A-cm": "AU27 opens a round mouth over the dark lining, folds at both lip corners (16); happy parts the lips "
                 "over the lining (11); AU45 closes the lids to a thin line, the lower lids at their rest height, "
                 "folds at an outer lid corner (14); AU12 folds at the corners (4); no beak",
    "eyes-teeth-separate-in": "AU27: the tongue (red) and lower teeth (ivory) turn down whole with the jaw, no spikes "
                              "or stretched teeth; the folds left are skin at the lip corners (8); happy shows tongue "
                              "and lower teeth (4); AU45 closes the lids to a thin line (7); AU12 no folds",
    "stylised-parted-decimated-dm": "the dark holes round the nose and lips are the decimation's, there at rest; the "
                                    "parted lips show the dark lining; AU27 opens wide (2 folds); AU45 closes the lids "
                                    "with folds at a corner of each eye (4); AU12 and happy no folds",
    "stylised-chin-cheek-in": "AU27 opens the mouth over the dark lining (2); AU45 closes the lids to a thin line (4); "
                              "AU12 and happy read as smiles, a fold at the upper lip's middle (4, 4); the dark "
                              "shading on the cheeks is the style's cheek bones, at rest too",
    NO_MOUTH_INSIDE.name: "lips that open onto the inside of the head, with the add-on's mouth bag: AU27 and happy "
                          "show the dark bag between the lips, no hole; folds at the lip corners (5 in AU27, 2 in "
                          "happy); AU12 (4) and AU45 (3, the lids closed to a thin line) as on the others",
    "voxel-m" + CUT: "voxel-m's fused lips cut open along the line between them (cut_lips), fitted again, with a mouth "
                     "bag: AU27 opens the mouth over the dark bag, no sheet (6 new folds, on the neck under the jaw); "
                     "happy parts the lips over it; the cut follows the voxel grid's edges, so the lip line is jagged "
                     "(a saw-tooth slit at rest); AU45 as on voxel-m (3); AU12 and happy no folds",
    "decimated-cm": "decimated to ~3k vertices, the lips' rims merged at the middle (the short dark slits at rest are "
                    "the decimation's): AU27 opens a rounded mouth, the lower lip down along its width (a pointed V, "
                    "a beak, with 5 folds before branch keys-joined-lips), with grey slivers of the skin joining the "
                    "lips inside the opening and 1 fold at a merged rim (Cut Lips Open removes both); AU45 closes "
                    "the lids, 1 fold at an inner corner; AU12 and happy no folds",
}
KEYS = ("neutral", "AU12", "AU27", "AU45", "happy")
#: The views: the camera turned this many degrees about the face's vertical axis (towards the subject's left).
VIEWS = {"front": 0.0, "3/4": 40.0}
SKIN = (0.80, 0.74, 0.68, 1.0)
FOLD = (0.9, 0.05, 0.05, 1.0)
MOUTH = (0.14, 0.09, 0.09, 1.0)
TEETH = (0.95, 0.93, 0.84, 1.0)
TONGUE = (0.70, 0.33, 0.33, 1.0)
#: The PNGs' colour levels are this many apart (smooth shading's gradients compress three times smaller).
LEVEL_STEP = 8


def rigged(name, keys=KEYS, bag=True):
    """(face-frame vertices / eye distance, triangles, face-frame landmarks / eye distance, {key: moved vertices},
    dark vertices: the mouth's lining and bag, the teeth and tongue, the tongue). ``bag``: a head with no mouth inside
    gets the add-on's mouth bag."""
    ch = build(SPECS.get(name.removesuffix(CUT), NO_MOUTH_INSIDE))
    (V, T), L = ch.joined(), ch.landmarks
    model = retarget(load_face("default"), fit_face(V, T, L)[0])
    if name.endswith(CUT):
        V, T, L = cut_lips(V, T, L, model.frame)
        model = retarget(load_face("default"), fit_face(V, T, L)[0])
    b = HeadBinding(model, V, T, landmarks=L)
    f = model.frame
    # The lining: skin the PDE face does not cover behind the inner lips (their depth across the mouth), within the
    # mouth's width and near its line.
    dark = np.zeros(len(V), bool)
    Pf, Lf, ed = f.to_face(V[b.skin]), f.to_face(L), b.eye_distance
    corners, lips = Lf[MOUTH_CORNERS, 0], Lf[INNER_LIPS][np.argsort(Lf[INNER_LIPS, 0])]
    behind = Pf[:, 2] < np.interp(Pf[:, 0], lips[:, 0], lips[:, 2]) - 0.01 * ed
    dark[b.skin] = (~b.covered & behind & (np.abs(Pf[:, 1] - mouth_line(Lf)) < 0.35 * ed)
                    & (np.abs(Pf[:, 0] - corners.mean()) < np.ptp(corners) / 2 + 0.2 * ed))
    if bag and any(w.startswith("no mouth inside") for w in b.warnings):
        Vb, Tb = mouth_bag(f.to_face(V), T, b.parts.mask("skin"), f.to_face(L), b.eye_distance)
        bag_idx = np.arange(len(V), len(V) + len(Vb))
        V, T = np.r_[V, f.to_user(Vb)], np.r_[T, Tb + len(V)]
        b = HeadBinding(model, V, T, landmarks=L, overrides={"mouth": bag_idx.tolist()})
        dark = np.r_[dark, np.ones(len(Vb), bool)]
    names = [k for k in keys if k != "neutral"]
    ed = b.eye_distance
    posed = {n: f.to_face(V + d) / ed for n, d in zip(names, b.displacements(b.every_pose_motion_args(names)))}
    # The teeth and tongue: the jaw's and skull's pieces, the largest of three or more the tongue (MakeHuman's).
    inner = np.where(b.parts.mask("jaw", "skull"), connected_components(len(V), T), -1)
    pieces, sizes = np.unique(inner[inner >= 0], return_counts=True)
    tongue = inner == (pieces[np.argmax(sizes)] if len(pieces) >= 3 else -2)
    return (f.to_face(V) / ed, T, f.to_face(L) / ed, {"neutral": f.to_face(V) / ed, **posed}, dark, inner >= 0,
            tongue)


def new_fold_vertices(V0, P, T, pairs):
    """(vertices of edges that newly fold in ``P``, how many edges)."""
    new = (turn_degrees(V0, T, pairs) < 20) & (turn_degrees(P, T, pairs) > 40)
    return np.unique(T[pairs[new]]), int(new.sum())


def _scene(size):
    import bpy

    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.render.engine = "BLENDER_WORKBENCH"
    scene.render.resolution_x = scene.render.resolution_y = size
    scene.render.film_transparent = False
    shading = scene.display.shading
    shading.light, shading.color_type = "STUDIO", "VERTEX"
    shading.show_cavity = False  # its ridges drew a voxel remesh's steps as dark diamonds
    shading.show_specular_highlight = False
    scene.world = bpy.data.worlds.new("pdeface renders")
    scene.world.color = (1.0, 1.0, 1.0)
    scene.view_settings.view_transform = "Standard"
    cam = bpy.data.objects.new("camera", bpy.data.cameras.new("camera"))
    cam.data.type, cam.data.ortho_scale = "ORTHO", 2.6  # eye distances across
    scene.collection.objects.link(cam)
    scene.camera = cam
    return scene, cam


def _panel(scene, cam, centre, degrees, path):
    """Render the scene from ``degrees`` about the face's vertical axis through ``centre``: (size, size, 3) uint8."""
    import bpy
    from mathutils import Euler, Vector

    a = math.radians(degrees)
    cam.location = Vector(centre) + 10.0 * Vector((math.sin(a), 0.0, math.cos(a)))
    cam.rotation_euler = Euler((0.0, a, 0.0), "XYZ")  # the camera looks down its -z
    cam.data.clip_start, cam.data.clip_end = 0.1, 30.0
    scene.render.filepath = str(path)
    bpy.ops.render.render(write_still=True)
    img = bpy.data.images.load(str(path))
    w, h = img.size
    px = np.empty(w * h * 4, np.float32)
    img.pixels.foreach_get(px)
    bpy.data.images.remove(img)
    rgb = px.reshape(h, w, 4)[::-1, :, :3]
    return (np.clip(rgb, 0, 1) * 255).astype(np.uint8)


def _one_winding(me):
    """Turn ``me``'s triangles one way (the voxel remesh's winding is mixed: its flipped triangles shaded as dark
    diamonds). bmesh comes with bpy, imported first."""
    import bmesh

    bm = bmesh.new()
    bm.from_mesh(me)
    bmesh.ops.recalc_face_normals(bm, faces=bm.faces)
    bm.to_mesh(me)
    bm.free()


def _coloured_mesh(scene, name, V, T, attribute):
    """A smooth-shaded mesh ``name`` of ``(V, T)``, one winding, linked into ``scene``, with a per-vertex colour
    ``attribute`` (the one shown); returns ``(mesh, colours)``."""
    import bpy

    me = bpy.data.meshes.new(name)
    me.from_pydata(V.tolist(), [], T.tolist())
    _one_winding(me)
    me.shade_smooth() if hasattr(me, "shade_smooth") else None
    colours = me.color_attributes.new(attribute, "FLOAT_COLOR", "POINT")
    me.color_attributes.active_color = colours
    me.color_attributes.default_color_name = colours.name
    scene.collection.objects.link(bpy.data.objects.new(name, me))
    return me, colours


def sheet(name, size, tmp, keys=KEYS, bag=True):
    """One character's (views × keys) panels as one image, and its new folds per key."""
    V0, T, Lf, posed, dark, teeth, tongue = rigged(name, keys, bag)
    pairs = edge_face_pairs(T)
    scene, cam = _scene(size)
    me, colours = _coloured_mesh(scene, name, V0, T, "folds")
    centre = (Lf[17:68, 0].mean(), Lf[17:68, 1].mean() - 0.35, Lf[17:68, 2].mean())
    rows, folds = {v: [] for v in VIEWS}, {}
    for key in keys:
        P = posed[key]
        me.vertices.foreach_set("co", P.astype(np.float32).ravel())
        at, folds[key] = new_fold_vertices(V0, P, T, pairs)
        c = np.tile(SKIN, (len(P), 1))
        c[dark] = MOUTH
        c[teeth] = TEETH
        c[tongue] = TONGUE
        c[at] = FOLD
        colours.data.foreach_set("color", c.astype(np.float32).ravel())
        me.update()
        for view, degrees in VIEWS.items():
            img = _panel(scene, cam, centre, degrees, Path(tmp) / "panel.png")
            title = name[:30] if key == "neutral" and view == "front" else key if view == "front" else view
            draw_text(img, 6, 6, title + (f": {folds[key]} new folds" if key != "neutral" and view == "front" else ""),
                      (0, 0, 0), 2 if size >= 400 else 1)
            rows[view].append(img)
    return np.concatenate([np.concatenate(r, axis=1) for r in rows.values()], axis=0), folds


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("-o", "--out", default=str(OUT), help="folder of the keys_devset_<name>.png files")
    ap.add_argument("--size", type=int, default=512, help="pixels per panel")
    ap.add_argument("--only", help=f"comma-separated character names (default: the five hardest and "
                                   f"{', '.join(MOUTH_BAG + MERGED_LIPS)})")
    ap.add_argument("--no-mouth-bag", action="store_true", help="no mouth bag on a head with no mouth inside")
    ap.add_argument("--keys", default=",".join(KEYS), help="comma-separated keys (default: %(default)s)")
    args = ap.parse_args(argv)
    names = args.only.split(",") if args.only else RENDERED
    with tempfile.TemporaryDirectory() as tmp:
        for name in names:
            img, folds = sheet(name, args.size, tmp, args.keys.split(","), not args.no_mouth_bag)
            path = Path(args.out) / f"keys_devset_{name}.png"
            write_png(path, (img // LEVEL_STEP) * LEVEL_STEP + LEVEL_STEP // 2)  # a third of the bytes
            print(f"wrote {path} ({path.stat().st_size / 1e3:.0f} kB); new folds: "
                  + ", ".join(f"{k} {n}" for k, n in folds.items() if k != "neutral"), flush=True)


if __name__ == "__main__":
    main()
