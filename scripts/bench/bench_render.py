"""Benchmark headless animation and AU import (issue #5 targets).

Usage: python -m scripts.bench.bench_render [--frames 24]

Prints, measured in this run:
- our overhead per frame (timeline keyframing amortised + the frame change that evaluates
  the shape keys) against Cycles' render time per frame at the demo settings (192x192, 16 samples);
- importing a 10,000-row OpenFace CSV, against reading the same file with the csv module alone.
"""
from __future__ import annotations

import csv
import importlib.util
import os
import tempfile
import time
from pathlib import Path

import numpy as np

from scripts.bench.benchlib import bench_parser, run_bench

ROOT = Path(__file__).resolve().parents[2]


def write_openface(path, rows=10000, seed=0):
    rng = np.random.default_rng(seed)
    aus = [1, 2, 4, 5, 6, 7, 9, 10, 12, 14, 15, 17, 20, 23, 25, 26, 45]
    head = ["frame", " face_id", " timestamp", " confidence", " success"] + [f" AU{a:02d}_r" for a in aus] \
        + [f" AU{a:02d}_c" for a in aus + [28]]
    with open(path, "w") as fh:
        fh.write(",".join(head) + "\n")
        for i in range(rows):
            r = [str(i + 1), "0", f"{i / 30:.3f}", "0.98", "1"] + [f"{v:.2f}" for v in rng.random(len(aus)) * 5] \
                + [str(int(v)) for v in rng.random(len(aus) + 1) > 0.3]
            fh.write(", ".join(r) + "\n")


def main(argv=None):
    ap = bench_parser(__doc__)
    ap.add_argument("--frames", type=int, default=24)
    args = ap.parse_args(argv)
    from pdeface.animation.trackers import import_au

    tmp = Path(tempfile.mkdtemp())
    write_openface(tmp / "of.csv")
    t = time.perf_counter()
    with open(tmp / "of.csv", newline="") as fh:
        n = sum(1 for _ in csv.reader(fh))
    t_csv = time.perf_counter() - t
    t = time.perf_counter()
    r = import_au(tmp / "of.csv", fps=30)
    t_import = time.perf_counter() - t
    print(f"OpenFace import: {n - 1} rows in {t_import:.3f} s (target <= 1 s, ratio {t_import:.2f}); "
          f"csv module alone {t_csv:.3f} s; {len(r.timeline.keys)} keys")

    os.environ.setdefault("BLENDER_USER_RESOURCES", tempfile.mkdtemp())
    spec = importlib.util.spec_from_file_location("pdeface_headless", ROOT / "blender_addon" / "headless.py")
    rs = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(rs)
    import bpy

    module = rs.enable_addon(bpy)
    render = __import__(module + ".render", fromlist=["render"])
    animation = __import__(module + ".animation", fromlist=["animation"])
    try:
        bpy.ops.wm.read_homefile(use_empty=True)
        bpy.ops.pdeface.add_default_face()
        face = bpy.context.active_object
        scene = bpy.context.scene
        from pdeface.animation.sequence import METHOD_SEQUENCE
        from pdeface.animation.timeline import sequence_timeline
        timeline = sequence_timeline(METHOD_SEQUENCE, 12, 0.33, 0.33)
        t = time.perf_counter()
        first, last, _ = animation.apply_timeline(face, timeline)
        t_keys = time.perf_counter() - t
        render.setup_render(scene, face, "CYCLES", (192, 192), 16, 0, 12)
        frames = list(range(first, min(last, first + args.frames - 1) + 1))
        t = time.perf_counter()
        for f in frames:
            scene.frame_set(f)
        t_update = (time.perf_counter() - t) / len(frames)
        out = tmp / "frames"
        t = time.perf_counter()
        render.render_frames(scene, out, frames[0], frames[-1])
        t_render = (time.perf_counter() - t) / len(frames)
        overhead = t_keys / (last - first + 1) + t_update
        print(f"per frame: our overhead {overhead * 1e3:.2f} ms (keyframing {t_keys * 1e3:.1f} ms for "
              f"{last - first + 1} frames, frame change {t_update * 1e3:.2f} ms); Cycles render {t_render * 1e3:.0f} ms "
              f"(192x192, 16 samples) -> overhead {100 * overhead / t_render:.2f}% of render (target <= 1%)")
    finally:
        import addon_utils
        addon_utils.disable(module, default_set=True)


if __name__ == "__main__":
    run_bench(main, "render")
