"""Benchmark reading a mesh file (issue #35: an OBJ of the 27k-vertex head in ≤ 0.03 s, ≥ 10× the old reader).

Usage: python -m scripts.bench.bench_io [--repeat N] [--baseline REF]

The bundled ICT-FaceKit whole head (26,719 vertices, UVs, quads) is written as OBJ, in the
``v/vt`` form ICT ships, and again with normals and relative (negative) indices; each is read by
``read_obj`` (numpy, a block of like lines at a time) and by the line-by-line reader it falls back
to for irregular files, which is the reader before issue #35 unchanged: median seconds of each,
interleaved, and their ratio, measured in the same run; the same in CPU seconds of this process
(less sensitive to a busy machine's waits). Both must give the same mesh. The process keeps the C heap as the
``pdeface`` command's does (:func:`pdeface.heap.keep_heap`: without it each read of the head paid ~6.6k page faults,
~40 ms instead of ~25 ms on this machine). With ``--baseline REF`` (a git revision, e.g. ``main``), each file
is also read by REF's ``read_obj`` (its ``meshio`` module, ``git show``), its reads interleaved with this checkout's
so that the machine's load falls on both alike: median and fastest CPU seconds both ways, their ratio, and whether
both read the same mesh.
"""
from __future__ import annotations

import importlib.util
import os
import subprocess
import tempfile
import time
from pathlib import Path

import numpy as np
from pdeface.assets import load_head
from pdeface.heap import keep_heap
from pdeface.io import meshio

from scripts.bench.benchlib import bench_parser, run_bench

TARGETS = {"seconds": 0.03, "ratio": 10.0}
ROOT = Path(__file__).resolve().parents[2]
MESH_FIELDS = ("vertices", "face_counts", "face_indices", "uvs", "face_uv_indices", "normals", "face_normal_indices")


def baseline_meshio(ref, folder):
    """git revision ``ref``'s ``pdeface.io.meshio``, loaded from ``folder`` beside this checkout's (its relative
    imports: this checkout's ``pdeface.errors``, ``mesh`` and ``io.files``)."""
    text = subprocess.run(["git", "show", f"{ref}:core/pdeface/io/meshio.py"], capture_output=True, check=True,
                          cwd=ROOT).stdout
    path = Path(folder) / "baseline_meshio.py"
    path.write_bytes(text)
    spec = importlib.util.spec_from_file_location("pdeface.io._baseline_meshio", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def same_mesh(a, b) -> bool:
    return all(np.array_equal(getattr(a, f), getattr(b, f)) for f in MESH_FIELDS)


def relative_obj(mesh, path):
    """The head as ``v/vt/vn`` with every index relative (negative), each face after its own vertices'."""
    V, uv = mesh.vertices, mesh.uvs
    normals = np.tile([0.0, 0.0, 1.0], (len(V), 1))
    lines = [f"v {x:.6f} {y:.6f} {z:.6f}" for x, y, z in V]
    lines += [f"vt {u:.6f} {v:.6f}" for u, v in uv] + [f"vn {a:.6f} {b:.6f} {c:.6f}" for a, b, c in normals]
    nv, nt = len(V), len(uv)
    for s, c in zip(mesh.face_starts, mesh.face_counts):
        fv, ft = mesh.face_indices[s:s + c], mesh.face_uv_indices[s:s + c]
        lines.append("f " + " ".join(f"{v - nv}/{t - nt}/{v - nv}" for v, t in zip(fv, ft)))
    Path(path).write_text("\n".join(lines) + "\n")


def line_by_line(path):
    """The reader before issue #35: every line split and parsed in Python (now the fallback)."""
    return meshio._obj_lines(path, Path(path).read_bytes().decode("utf-8", "replace").split("\n"))


def timed(read, path):
    """(wall seconds, CPU seconds of this process, the mesh) of ``read(path)``."""
    t, c = time.perf_counter(), time.process_time()
    mesh = read(path)
    return time.perf_counter() - t, time.process_time() - c, mesh


def main(argv=None):
    ap = bench_parser(__doc__)
    ap.add_argument("--repeat", type=int, default=7)
    ap.add_argument("--baseline", metavar="REF", help="also read each file with git revision REF's read_obj, "
                                                      "interleaved")
    ap.add_argument("--baseline-repeat", type=int, default=41, help="reads each way against the baseline")
    args = ap.parse_args(argv)
    keep_heap()  # as the command's process (cli.run) reads its meshes
    head, _ = load_head()
    print(f"load average at the start: {', '.join(f'{x:.2f}' for x in os.getloadavg())} ({os.cpu_count()} cores)")
    ok = True
    with tempfile.TemporaryDirectory() as tmp:
        files = {"ICT head, v/vt (as ICT ships it)": Path(tmp) / "head.obj",
                 "ICT head, v/vt/vn, relative indices": Path(tmp) / "relative.obj"}
        meshio.write_obj(files["ICT head, v/vt (as ICT ships it)"], head)
        relative_obj(head, files["ICT head, v/vt/vn, relative indices"])
        print(f"{'file':40s} {'MB':>5s} {'read_obj s':>11s} {'line by line s':>15s} {'ratio':>6s} "
              f"{'CPU s':>7s} {'CPU s':>7s} {'ratio':>6s}  same mesh")
        for name, path in files.items():
            data = path.read_bytes()
            new_s, old_s, new_c, old_c = [], [], [], []
            for _ in range(args.repeat):  # interleaved: the machine's load falls on both alike
                s, c, fast = timed(meshio.read_obj, path)
                new_s.append(s)
                new_c.append(c)
                s, c, slow = timed(line_by_line, path)
                old_s.append(s)
                old_c.append(c)
            same = same_mesh(fast, slow)
            in_blocks = meshio._obj_blocks(data) is not None
            new, old = float(np.median(new_s)), float(np.median(old_s))
            cpu_new, cpu_old = float(np.median(new_c)), float(np.median(old_c))
            print(f"{name:40s} {len(data) / 1e6:5.2f} {new:11.4f} {old:15.4f} {old / new:5.1f}× "
                  f"{cpu_new:7.4f} {cpu_old:7.4f} {cpu_old / cpu_new:5.1f}×  "
                  f"{'yes' if same else 'NO'}{'' if in_blocks else ' (read line by line)'}")
            ok &= same and in_blocks and old / new >= TARGETS["ratio"]
            if name.endswith("(as ICT ships it)"):  # the file: its time is the target
                ok &= new <= TARGETS["seconds"]
        if args.baseline:
            against_baseline(baseline_meshio(args.baseline, tmp), files, args.baseline_repeat, args.baseline)
    print(f"load average at the end: {', '.join(f'{x:.2f}' for x in os.getloadavg())}")
    print(f"targets: ≤ {TARGETS['seconds']} s on a quiet machine, ≥ {TARGETS['ratio']:.0f}× the line-by-line "
          f"reader in the same run: {'met' if ok else 'NOT met'}")
    return 0


def against_baseline(before, files, repeat, ref):
    """Read each file with ``before``'s read_obj and this checkout's in turn; print their CPU seconds."""
    print(f"\nagainst {ref}'s read_obj, CPU seconds of {repeat} reads each, interleaved "
          f"(load: {', '.join(f'{x:.2f}' for x in os.getloadavg())}):")
    print(f"{'file':40s} {'now med':>8s} {'before':>8s} {'ratio':>6s} "
          f"{'now min':>8s} {'before':>8s} {'ratio':>6s}  same")
    for name, path in files.items():
        now, old = [], []
        for _ in range(repeat):
            for read, out in ((meshio.read_obj, now), (before.read_obj, old)):
                c = time.process_time()
                mesh = read(path)
                out.append(time.process_time() - c)
        same = same_mesh(meshio.read_obj(path), mesh)
        a, b = float(np.median(now)), float(np.median(old))
        print(f"{name:40s} {a:8.4f} {b:8.4f} {a / b:6.2f} {min(now):8.4f} {min(old):8.4f} {min(now) / min(old):6.2f}  "
              f"{'yes' if same else 'NO'}")


if __name__ == "__main__":
    raise SystemExit(run_bench(main, "io"))
