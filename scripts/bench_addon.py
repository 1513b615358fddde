"""Benchmark the Blender add-on (issue #4 targets), headless with the bpy module.

Usage: python scripts/bench_addon.py [--updates 200]

Prints, measured in this run:
- building the full rig (neutral PDE face + every bundled AU key + every preset key) after
  ``import bpy``, first time (pdeface imports included) and rebuilt, against a baseline: bare
  Blender making the same mesh and the same number of shape keys from ready arrays;
- milliseconds per slider update (set an AU key value, re-evaluate the mesh), against the same
  re-evaluation with nothing changed.
"""
from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from benchlib import median_time

ROOT = Path(__file__).resolve().parent.parent


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--updates", type=int, default=200)
    args = ap.parse_args(argv)
    os.environ["BLENDER_USER_RESOURCES"] = tempfile.mkdtemp()
    t = time.perf_counter()
    import addon_utils  # noqa: I001 - available once bpy is imported
    import bpy
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
                o.shape_key_add(name=f"k{k}", from_mix=False).data.foreach_set("co", V.ravel())
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
    finally:
        addon_utils.disable("bl_ext.bench.pdeface", default_set=True)


if __name__ == "__main__":
    sys.exit(main())
