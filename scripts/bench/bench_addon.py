"""Benchmark the Blender add-on (issue #4 targets), headless with the bpy module.

Usage: python -m scripts.bench.bench_addon [--updates 200]

Prints, measured in this run:
- building the full rig (neutral PDE face + every bundled AU key + every preset key) after
  ``import bpy``, first time (pdeface imports included) and rebuilt, against a baseline: bare
  Blender making the same mesh and the same number of shape keys from ready arrays;
- milliseconds per slider update (set an AU key value, re-evaluate the mesh), against the same
  re-evaluation with nothing changed;
- the user's own head (ICT-FaceKit's whole head, 26,719 vertices, issue #14): Fit PDE Face to
  Selected (fit, bind, every key on the head), a first Build Shape Keys (binding included) and a
  rebuild, against bare Blender writing as many keys on that mesh; and a slider update on the head.
"""
from __future__ import annotations

import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from scripts.bench.benchlib import bench_parser, median_time, run_bench

ROOT = Path(__file__).resolve().parents[2]


def main(argv=None):
    ap = bench_parser(__doc__)
    ap.add_argument("--updates", type=int, default=200)
    args = ap.parse_args(argv)
    os.environ["BLENDER_USER_RESOURCES"] = tempfile.mkdtemp()
    t = time.perf_counter()
    import bpy  # noqa: I001 - first: addon_utils exists only once bpy is imported
    import addon_utils
    t_import = time.perf_counter() - t
    repo = Path(tempfile.mkdtemp())
    os.symlink(ROOT / "blender_addon", repo / "pdeface")
    bpy.context.preferences.extensions.repos.new(name="bench", module="bench", custom_directory=str(repo), source="USER")
    t = time.perf_counter()
    addon_utils.enable("bl_ext.bench.pdeface", default_set=True)
    t_enable = time.perf_counter() - t
    bpy.ops.wm.read_homefile(use_empty=True)
    try:
        t = time.perf_counter()
        bpy.ops.pdeface.add_default_face()
        t_first = time.perf_counter() - t
        obj = bpy.context.active_object
        n_keys = len(obj.data.shape_keys.key_blocks)
        t_again = median_time(bpy.ops.pdeface.add_default_face)
        t_rebuild = median_time(bpy.ops.pdeface.build_shape_keys)
        # Baseline: bare Blender doing the same writes from arrays already computed.
        V = np.array([v.co[:] for v in obj.data.vertices], np.float32)
        polys = [list(p.vertices) for p in obj.data.polygons]
        def bare_blender():
            me = bpy.data.meshes.new("baseline")
            me.from_pydata(V.tolist(), [], polys)
            o = bpy.data.objects.new("baseline", me)
            bpy.context.collection.objects.link(o)
            o.shape_key_add(name="Basis", from_mix=False)
            for k in range(n_keys - 1):
                o.shape_key_add(name=f"k{k}", from_mix=False).points.foreach_set("co", V.ravel())
        t_base = median_time(bare_blender)
        print(f"import bpy {t_import:.2f} s; enable add-on {t_enable * 1e3:.0f} ms")
        print(f"full rig ({len(obj.data.vertices)} vertices, {n_keys - 1} shape keys): first {t_first:.3f} s "
              f"(target <= 0.5 s, ratio {t_first / 0.5:.2f}); again {t_again:.3f} s; rebuild in place {t_rebuild:.3f} s")
        print(f"  baseline, bare Blender writing the same mesh and keys: {t_base:.3f} s "
              f"(rig / baseline {t_again / t_base:.2f})")
        # Slider updates.
        bpy.context.view_layer.objects.active = obj
        kb = obj.data.shape_keys.key_blocks["AU12 Lip Corner Puller"]
        dg = bpy.context.evaluated_depsgraph_get()

        def evaluate():
            dg.update()
            ev = obj.evaluated_get(dg)
            ev.data.vertices[0].co  # noqa: B018 - touch the evaluated mesh

        times = []
        for i in range(args.updates):
            t = time.perf_counter()
            kb.value = (i % 10) / 10
            evaluate()
            times.append(time.perf_counter() - t)
        idle = []
        for _ in range(args.updates):
            t = time.perf_counter()
            evaluate()
            idle.append(time.perf_counter() - t)
        med, p95 = np.median(times) * 1e3, np.percentile(times, 95) * 1e3
        print(f"slider update (AU key value + mesh re-evaluation): median {med:.2f} ms, p95 {p95:.2f} ms "
              f"(one redraw at 60 Hz = 16.7 ms, ratio {p95 / 16.7:.2f}); unchanged re-evaluation "
              f"{np.median(idle) * 1e3:.3f} ms")
        bench_head(bpy, args.updates)
    finally:
        addon_utils.disable("bl_ext.bench.pdeface", default_set=True)


def bench_head(bpy, updates):
    """The whole-head rig on the user's own mesh (ICT-FaceKit's head)."""
    from pdeface.assets import load_head

    bridge = sys.modules["bl_ext.bench.pdeface.bridge"]
    bpy.ops.wm.read_homefile(use_empty=True)
    mesh, lm = load_head()
    obj = bpy.data.objects.new("Head", bridge.new_mesh("Head", mesh))
    bpy.context.collection.objects.link(obj)
    bpy.context.view_layer.update()
    obj.select_set(True)
    bpy.context.view_layer.objects.active = obj
    group = obj.vertex_groups.new(name="landmarks")
    for i, v in enumerate(lm):
        group.add([int(v)], (i + 1) / 68, "REPLACE")
    face_module = sys.modules["bl_ext.bench.pdeface.face"]
    keys_module = sys.modules["bl_ext.bench.pdeface.keys"]
    t = time.perf_counter()
    bpy.ops.pdeface.fit_to_selected()
    t_fit = time.perf_counter() - t
    n_keys = len(obj.data.shape_keys.key_blocks) - 1
    # The same again on a fresh copy, timing the binding and keys alone (the fit apart).
    fresh = bpy.data.objects.new("Head 2", bridge.new_mesh("Head 2", mesh))
    bpy.context.collection.objects.link(fresh)
    bpy.context.view_layer.update()
    pde, _, _ = face_module.fit_face_object(bpy.context, fresh, mesh.vertices[lm], unit="cm", keys_on_mesh=True)
    presets = keys_module.all_presets(bpy.context.scene)
    t = time.perf_counter()
    keys_module.build_keys(pde, presets)
    t_first = time.perf_counter() - t
    face_module.show_user_objects(bpy.context, pde)
    bpy.context.view_layer.objects.active = obj
    t_rebuild = median_time(bpy.ops.pdeface.build_shape_keys, repeat=3)
    V = mesh.vertices.astype(np.float32)

    def bare_blender():
        me = bpy.data.meshes.new("baseline")
        me.vertices.add(len(V))
        me.vertices.foreach_set("co", V.ravel())
        o = bpy.data.objects.new("baseline", me)
        bpy.context.collection.objects.link(o)
        o.shape_key_add(name="Basis", from_mix=False)
        for k in range(2 * n_keys):  # the head's keys and the hidden PDE face's
            o.shape_key_add(name=f"k{k}", from_mix=False).points.foreach_set("co", V.ravel())
    t_base = median_time(bare_blender, repeat=3)
    print(f"whole head ({len(V)} vertices, {n_keys} keys on the user's mesh): fit to selected with keys "
          f"{t_fit:.2f} s; binding and all keys (head and hidden face) {t_first:.2f} s (target <= 1 s, ratio "
          f"{t_first:.2f}); rebuild {t_rebuild:.2f} s")
    print(f"  baseline, bare Blender writing {2 * n_keys} keys on that mesh: {t_base:.2f} s "
          f"(rebuild / baseline {t_rebuild / t_base:.2f})")
    kb = obj.data.shape_keys.key_blocks["AU12 Lip Corner Puller"]
    dg = bpy.context.evaluated_depsgraph_get()
    times = []
    for i in range(updates):
        t = time.perf_counter()
        kb.value = (i % 10) / 10
        dg.update()
        obj.evaluated_get(dg).data.vertices[0].co  # noqa: B018 - touch the evaluated mesh
        times.append(time.perf_counter() - t)
    p95 = np.percentile(times, 95) * 1e3
    print(f"  slider update on the head: median {np.median(times) * 1e3:.2f} ms, p95 {p95:.2f} ms "
          f"(ratio to 16.7 ms {p95 / 16.7:.2f})")


if __name__ == "__main__":
    sys.exit(run_bench(main, "addon"))
