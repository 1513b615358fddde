"""Benchmark the saved size of a rigged head's .blend (issue #40: a rigged 8 k-vertex head <= 40 MB).

Usage: python -m scripts.bench.bench_blend_size [--heads 2700,8000,26719]

ICT-FaceKit's whole head in four objects (skin, gums, teeth, eyes, split by its part ranges),
decimated to about each vertex count, fitted and rigged (every AU and expression key on the four
objects, the PDE face hidden as their reference) and saved uncompressed. For each head it prints the
saved size with the hidden face meshed at its own adaptive resolution, as before issue #40
(baseline, measured in this run), and as now (``face.REFERENCE_RESOLUTION``), their ratio, and what
the head's own keys need (keys x vertices x 12 bytes): the rest is the constant.
"""
from __future__ import annotations

import contextlib
import io
import os
import sys
import tempfile
from pathlib import Path

from scripts.bench.benchlib import bench_parser, run_bench

ROOT = Path(__file__).resolve().parents[2]
#: ICT's head split as heads are usually exported (HEAD_PARTS prefixes per object).
OBJECTS = {"Skin": ("face", "head_and_neck", "mouth_socket", "eye_socket", "eyelashes"), "Gums": ("gums",),
           "Teeth": ("teeth",), "Eyes": ("eyeball", "lacrimal", "eye_blend", "eye_occlusion")}


def head_objects(bpy, bridge, vertices):
    """ICT's head as four objects, decimated to about ``vertices`` in all; returns (skin, the others)."""
    from pdeface.assets import load_head, split_head

    mesh, _ = load_head()
    ratio = min(1.0, vertices / len(mesh.vertices))
    objs = []
    for name, (m, _) in split_head(mesh, OBJECTS).items():
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
    return objs[0], objs[1:]


def rigged_size(bpy, addon, vertices, reference, folder):
    """(saved bytes, vertices, keys) of the head rigged with the hidden face at ``reference`` resolution."""
    from pdeface.assets import load_head

    bpy.ops.wm.read_homefile(use_empty=True)
    skin, parts = head_objects(bpy, addon.bridge, vertices)
    mesh, lm = load_head()
    addon.face.REFERENCE_RESOLUTION = reference
    addon.rigging.fit_and_rig(bpy.context, skin, mesh.vertices[lm], unit="cm", parts=parts)
    path = folder / f"head_{vertices}_{reference.replace(',', '_')}.blend"
    with contextlib.redirect_stdout(io.StringIO()):  # Blender's "Saved as" report, not a figure
        bpy.ops.wm.save_as_mainfile(filepath=str(path), compress=False)
    n = sum(len(o.data.vertices) for o in [skin, *parts])
    return path.stat().st_size, n, len(skin.data.shape_keys.key_blocks)


def main(argv=None):
    ap = bench_parser(__doc__)
    ap.add_argument("--heads", default="2700,8000,26719", help="about how many vertices each head has")
    args = ap.parse_args(argv)
    os.environ["BLENDER_USER_RESOURCES"] = tempfile.mkdtemp()
    import bpy  # noqa: I001 - first: addon_utils exists only once bpy is imported
    import addon_utils
    repo = Path(tempfile.mkdtemp())
    os.symlink(ROOT / "blender_addon", repo / "pdeface")
    bpy.context.preferences.extensions.repos.new(name="bench", module="bench", custom_directory=str(repo), source="USER")
    addon_utils.enable("bl_ext.bench.pdeface", default_set=True)
    addon = sys.modules["bl_ext.bench.pdeface"]
    now = addon.face.REFERENCE_RESOLUTION
    folder = Path(tempfile.mkdtemp())
    rows = []
    print("| head (4 objects) | keys | before: hidden face adaptive | now | now / before | head's own keys | "
          "now - own keys |")
    print("|---|---|---|---|---|---|---|")
    try:
        for target in (int(v) for v in args.heads.split(",")):
            before, n, k = rigged_size(bpy, addon, target, "default", folder)
            after, n, k = rigged_size(bpy, addon, target, now, folder)
            own = n * k * 12
            rows.append((n, after))
            print(f"| {n} vertices | {k} | {before / 1e6:.1f} MB | {after / 1e6:.1f} MB | {after / before:.2f} | "
                  f"{own / 1e6:.1f} MB | {(after - own) / 1e6:.1f} MB |")
            for p in folder.iterdir():
                p.unlink()
    finally:
        addon.face.REFERENCE_RESOLUTION = now
        addon_utils.disable("bl_ext.bench.pdeface", default_set=True)
    n, after = min(rows, key=lambda r: abs(r[0] - 8000))
    print(f"\ntarget: a rigged 8 k-vertex head <= 40 MB; the {n}-vertex head: {after / 1e6:.1f} MB "
          f"(ratio to the target {after / 40e6:.2f})")


if __name__ == "__main__":
    sys.exit(run_bench(main, "blend_size"))
