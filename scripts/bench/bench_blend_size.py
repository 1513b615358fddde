"""Benchmark the saved size of a rigged head's .blend (issue #40: a rigged 8 k-vertex head <= 40 MB).

Usage: python -m scripts.bench.bench_blend_size [--heads 2700,8000,26719] [--makehuman PATH]

ICT-FaceKit's whole head in four objects (skin, gums, teeth, eyes, split by its part ranges),
decimated to about each vertex count, and MakeHuman's base mesh (``--makehuman``, its body with the
eyes, teeth and tongue as objects, in cm, landmarks found automatically; skipped without MediaPipe
or the file), each fitted and rigged (every AU and expression key on its objects, the PDE face hidden
as their reference) and saved uncompressed. For each head it prints the saved size with the hidden
face meshed at its own adaptive resolution, as before issue #40 (baseline, measured in this run),
and as now (``face.REFERENCE_RESOLUTION``), their ratio, what the head's own keys need (keys x
vertices x 12 bytes; the rest is the constant), and how far the skin and the teeth move with the
skin's AU27 key (the one control) at 1.
"""
from __future__ import annotations

import contextlib
import io
import sys
import tempfile
from pathlib import Path

import numpy as np

from scripts.bench.benchlib import disable_addon, enable_addon, bench_parser, run_bench
from scripts.devset import makehuman

ROOT = Path(__file__).resolve().parents[2]
#: MakeHuman's base mesh where the development set finds it (give ``--makehuman`` from elsewhere).
MAKEHUMAN = makehuman.DATA / "base.obj"
#: ICT's head split as heads are usually exported (HEAD_PARTS prefixes per object).
ICT_OBJECTS = {"Skin": ("face", "head_and_neck", "mouth_socket", "eye_socket", "eyelashes"), "Gums": ("gums",),
               "Teeth": ("teeth",), "Eyes": ("eyeball", "lacrimal", "eye_blend", "eye_occlusion")}
#: MakeHuman's base mesh as a user has it: the body, and its eye, teeth and tongue helpers as objects.
MAKEHUMAN_OBJECTS = {"Skin": ("body",), "Eyes": ("helper-l-eye", "helper-r-eye"),
                     "Teeth": ("helper-upper-teeth", "helper-lower-teeth"), "Tongue": ("helper-tongue",)}
AU27 = "AU27 Mouth Stretch"


def ict_head():
    """ICT's head as ``{object: Mesh}`` (cm), and its landmark points."""
    from pdeface.assets import load_head, split_head

    mesh, lm = load_head()
    return {name: m for name, (m, _) in split_head(mesh, ICT_OBJECTS).items()}, mesh.vertices[lm]


def makehuman_head(path):
    """MakeHuman's base mesh (decimetres) as ``{object: Mesh}`` in cm, and landmarks found on its body."""
    from pdeface.landmarks.pipeline import find_on_mesh
    from pdeface.mesh import Mesh

    V, group, faces = [], None, {}
    for line in Path(path).read_text().splitlines():
        if line.startswith("v "):
            V.append([float(x) for x in line.split()[1:4]])
        elif line.startswith("g "):
            group = line.split()[1]
        elif line.startswith("f "):
            faces.setdefault(group, []).append([int(t.split("/")[0]) - 1 for t in line.split()[1:]])
    V = np.array(V) * 10.0
    objs = {}
    for name, groups in MAKEHUMAN_OBJECTS.items():
        polys = [p for g in groups for p in faces[g]]
        used = np.unique(np.concatenate(polys))
        remap = np.full(len(V), -1)
        remap[used] = np.arange(len(used))
        objs[name] = Mesh(V[used], np.array([len(p) for p in polys]), remap[np.concatenate(polys)])
    return objs, find_on_mesh(objs["Skin"], unit="cm").points


def add_objects(bpy, bridge, meshes, vertices=None):
    """The meshes as objects, decimated to about ``vertices`` in all; returns them, the skin first."""
    ratio = 1.0 if vertices is None else min(1.0, vertices / sum(len(m.vertices) for m in meshes.values()))
    objs = []
    for name, m in meshes.items():
        obj = bpy.data.objects.new(name, bridge.new_mesh(name, m))
        bpy.context.collection.objects.link(obj)
        if ratio < 1.0:
            obj.modifiers.new("Decimate", "DECIMATE").ratio = ratio
            dg = bpy.context.evaluated_depsgraph_get()
            decimated = bpy.data.meshes.new_from_object(obj.evaluated_get(dg))
            obj.modifiers.clear()
            obj.data = decimated
        objs.append(obj)
    bpy.context.view_layer.update()
    return objs


def _evaluated(bpy, bridge, obj):
    return bridge.vertices(obj.evaluated_get(bpy.context.evaluated_depsgraph_get()).data)


def rigged(bpy, addon, meshes, landmarks, reference, path, vertices=None):
    """The head rigged with the hidden face at ``reference`` resolution and saved at ``path``:
    (bytes, vertices, keys, {object: cm it moves with the skin's AU27 key at 1})."""
    bpy.ops.wm.read_homefile(use_empty=True)
    objs = add_objects(bpy, addon.bridge, meshes, vertices)
    skin = objs[0]
    addon.face.REFERENCE_RESOLUTION = reference
    with contextlib.redirect_stdout(io.StringIO()):  # the binding's notes, Blender's "Saved as": not figures
        addon.rigging.fit_and_rig(bpy.context, skin, landmarks, unit="cm", parts=objs[1:])
        rest = [_evaluated(bpy, addon.bridge, o) for o in objs]
        skin.data.shape_keys.key_blocks[AU27].value = 1.0
        bpy.context.view_layer.update()
        moved = {o.name: float(np.linalg.norm(_evaluated(bpy, addon.bridge, o) - r, axis=1).max())
                 for o, r in zip(objs, rest)}
        skin.data.shape_keys.key_blocks[AU27].value = 0.0
        bpy.ops.wm.save_as_mainfile(filepath=str(path), compress=False)
    n = sum(len(o.data.vertices) for o in objs)
    return path.stat().st_size, n, len(skin.data.shape_keys.key_blocks), moved


def main(argv=None):
    ap = bench_parser(__doc__)
    ap.add_argument("--heads", default="2700,8000,26719", help="about how many vertices each ICT head has")
    ap.add_argument("--makehuman", default=str(MAKEHUMAN), help="MakeHuman's base.obj ('' to skip)")
    args = ap.parse_args(argv)
    addon = enable_addon()
    import bpy
    from pdeface.landmarks.detector import available
    now = addon.face.REFERENCE_RESOLUTION
    ict, ict_landmarks = ict_head()
    heads = [("ICT" if v >= 26719 else "ICT decimated", ict, ict_landmarks, v) for v in map(int, args.heads.split(","))]
    if args.makehuman and Path(args.makehuman).exists() and available():
        heads.append(("MakeHuman body + eyes, teeth, tongue", *makehuman_head(args.makehuman), None))
    else:
        print("MakeHuman skipped: no base.obj or no MediaPipe for its landmarks")
    folder = Path(tempfile.mkdtemp())
    print("| head | objects | vertices | keys | before: hidden face adaptive | now | now / before | "
          "head's own keys | now - own keys | AU27 control at 1: skin / teeth move |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    rows = []
    try:
        for name, meshes, landmarks, vertices in heads:
            before, *_ = rigged(bpy, addon, meshes, landmarks, "default", folder / "before.blend", vertices)
            after, n, k, moved = rigged(bpy, addon, meshes, landmarks, now, folder / "now.blend", vertices)
            own = n * k * 12
            rows.append((n, after))
            print(f"| {name} | {len(meshes)} | {n} | {k} | {before / 1e6:.1f} MB | {after / 1e6:.1f} MB | "
                  f"{after / before:.2f} | {own / 1e6:.1f} MB | {(after - own) / 1e6:.1f} MB | "
                  f"{moved['Skin']:.2f} / {moved['Teeth']:.2f} cm |")
    finally:
        addon.face.REFERENCE_RESOLUTION = now
        disable_addon()
    n, after = min(rows, key=lambda r: abs(r[0] - 8000))
    print(f"\ntarget: a rigged 8 k-vertex head <= 40 MB; the {n}-vertex head: {after / 1e6:.1f} MB "
          f"(ratio to the target {after / 40e6:.2f})")


if __name__ == "__main__":
    sys.exit(run_bench(main, "blend_size"))
