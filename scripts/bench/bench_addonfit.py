"""Benchmark what the add-on does around the core as it fits a new head: before vs after (issue #35).

Usage: python -m scripts.bench.bench_addonfit [--repeat N]

Headless with the bpy module and the add-on from this checkout: ICT-FaceKit's head (26,719 vertices, written as
OBJ from the bundled asset) imported, its landmarks found and a PDE face fitted with its 82 keys on it (as in
``bench_newhead``); then, on that head, each piece of the add-on's work that changed, timed the way it was
("before": the model stored with ``model_to_bytes``' file defaults, loop triangles read with their loops, the
binding's triangles from a whole pdeface Mesh with vertices and UVs, every key's displacement multiplied by the
fitted mesh's identity 3×3) and the way it is now, interleaved in one process: the median of ``N`` of each, and
their ratio. Storing and reading back the model both count (a fitted face's keys are made from the model its
.blend keeps). The machine's load average is printed. Needs ``pdeface[blender,landmarks]``.
"""
from __future__ import annotations

import base64
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from scripts.bench.bench_newhead import chain, time_only
from scripts.bench.benchlib import bench_parser, enable_addon, run_bench


def pieces(addon, src, face):
    """``{piece: (before, after)}``: the add-on's changed work on the fitted head ``src`` and its ``face``."""
    from pdeface.au.modelfile import model_from_bytes, model_to_bytes

    br, me = addon.bridge, src.data
    model = br.face_model(face)
    D = np.random.default_rng(0).normal(size=(82, len(me.vertices), 3))
    rest, identity = br.vertices(me), np.eye(3)

    def stored(fast):
        return lambda: model_from_bytes(base64.b64decode(base64.b64encode(model_to_bytes(model, fast=fast))))

    return {
        "store the model, read it back": (stored(False), stored(True)),
        "fit's loop triangles": (lambda: br.triangles(me), lambda: br.triangles(me, loops=False)),
        "the binding's fan triangles (a whole Mesh first, or the polygons alone)": (
            lambda: br.as_pdeface_mesh(me).triangles()[0], lambda: br.polygon_triangles(me, rest)),
        "82 keys into the mesh's space": (lambda: [rest + d @ identity.T for d in D],
                                          lambda: [rest + addon.head._in_object_space(d, identity) for d in D]),
    }


def main(argv=None):
    ap = bench_parser(__doc__)
    ap.add_argument("--repeat", type=int, default=15, help="timings of each piece, before and after")
    args = ap.parse_args(argv)
    addon = enable_addon()
    import bpy
    from pdeface.assets import load_head
    from pdeface.io.meshio import write_obj

    head, _ = load_head()
    path = Path(tempfile.mkdtemp()) / "ict.obj"
    write_obj(path, head)
    chain(bpy, path, time_only)
    src = bpy.context.active_object
    print(f"{os.cpu_count()} cores; load average at the start: {os.getloadavg()[0]:.2f}")
    print(f"ICT head: {len(src.data.vertices)} vertices, {len(src.data.shape_keys.key_blocks) - 1} keys on it")
    total = np.zeros(2)
    for name, fns in pieces(addon, src, addon.face.active_face(bpy.context)).items():
        times = ([], [])
        for _ in range(args.repeat):
            for fn, out in zip(fns, times):
                t = time.perf_counter()
                fn()
                out.append(time.perf_counter() - t)
        before, after = (1000 * np.median(t) for t in times)
        total += before, after
        print(f"  {name:32s} before {before:6.1f} ms  after {after:6.1f} ms  ratio {after / before:.2f}")
    print(f"  {'all':32s} before {total[0]:6.1f} ms  after {total[1]:6.1f} ms  ratio {total[1] / total[0]:.2f}; "
          f"load average at the end: {os.getloadavg()[0]:.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(run_bench(main, "addonfit"))
