"""Benchmark ``pdeface rig MESH -o OUT`` end to end (issue #35: a new head rigged in ≤ 3 s on the command line).

Usage: python -m scripts.bench.bench_rig [--runs 3] [--import-runs 7]

ICT-FaceKit's whole head (26,719 vertices, written as OBJ from the bundled asset) and the same head
clustered on a grid to about 8k vertices (another topology), each rigged by ``pdeface rig`` in a fresh
process (its imports included, landmarks found with MediaPipe): the process's wall and CPU seconds, each step's
wall and CPU seconds from its report (read; load: the libraries and the head prior that the first step needing
them paid before, ``pdeface.rig.warm_up``; landmarks, fit, retarget, bind, keys; median of the runs) and the
ratio to the 3 s target. Then the command line's own imports before a command runs, median of fresh processes
(``python -X importtime``): ``pdeface rig`` importing its own group only, against every group imported
(as before issue #35), in the same run, and its own group compiled from source in each process, as on a machine
where ``PYTHONDONTWRITEBYTECODE`` is set (this one's): pip compiles an installed pdeface's bytecode and a checkout
writes it on its first run, so the rigs are timed with it (``benchlib.installed_env``). The machine's load average is
printed: other work beside it slows every figure. Needs ``pdeface[landmarks]``.
"""
from __future__ import annotations

import json
import os
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import pdeface
from pdeface.assets import load_head
from pdeface.io.meshio import write_obj
from pdeface.mesh import Mesh

from scripts.bench.benchlib import bench_parser, clustered, installed_env, run_bench

TARGET_S = 3.0
STEPS = ("read", "load", "landmarks", "fit", "retarget", "bind", "keys")


def load_text():
    return ", ".join(f"{x:.2f}" for x in os.getloadavg())


def child_cpu():
    use = resource.getrusage(resource.RUSAGE_CHILDREN)
    return use.ru_utime + use.ru_stime


def child_env(source_only=None):
    """The environment of a child: reading pdeface's bytecode (:func:`~scripts.bench.benchlib.installed_env`), or
    with ``source_only`` (a folder holding a copy of the package without its bytecode, first on the path)
    compiling pdeface's modules from source, none written (numpy's and the rest's bytecode read as ever)."""
    env = installed_env()
    if source_only:
        path = os.pathsep.join(p for p in (str(source_only), env.get("PYTHONPATH")) if p)
        env |= {"PYTHONDONTWRITEBYTECODE": "1", "PYTHONPATH": path}
    return env


def rig_once(path, out):
    """(process wall seconds, its CPU seconds, each step's (wall, CPU) seconds from the report) of ``pdeface rig
    path -o out`` in a fresh process."""
    env = child_env()  # compiles the bytecode first: not the rig's time
    t, c = time.perf_counter(), child_cpu()
    done = subprocess.run([sys.executable, "-m", "pdeface.cli", "rig", str(path), "-o", str(out)],
                          capture_output=True, text=True, check=False, env=env)
    wall, cpu = time.perf_counter() - t, child_cpu() - c
    if done.returncode:
        raise SystemExit(f"pdeface rig {path} failed: {done.stderr.strip()[-600:]}")
    printed = json.loads(done.stdout.strip().splitlines()[-1])
    return wall, cpu, {k: (printed["timings"][k], printed["cpu_timings"][k]) for k in STEPS}


def import_seconds(command, source_only=None):
    """Seconds of the imports a fresh process makes to build the parser for ``command`` (None: every group),
    reading pdeface's bytecode or compiling it (:func:`child_env`)."""
    code = f"from pdeface.cli import build_parser; build_parser({command!r})"
    err = subprocess.run([sys.executable, "-X", "importtime", "-c", code], capture_output=True, text=True,
                         check=True, env=child_env(source_only)).stderr
    top = [line.split("|") for line in err.splitlines() if line.startswith("import time:")]
    # the outermost imports' cumulative times (a nested one's name is indented further)
    return sum(int(f[1]) for f in top if f[1].strip().isdigit() and not f[2].startswith("  ")) / 1e6


def main(argv=None):
    ap = bench_parser(__doc__)
    ap.add_argument("--runs", type=int, default=3, help="rigs per head (0: the imports alone)")
    ap.add_argument("--import-runs", type=int, default=7)
    args = ap.parse_args(argv)
    head, _ = load_head()
    V, T = head.vertices, head.triangles()[0]
    Vc, Tc = clustered(V, T, 0.42)  # cm: about 8k vertices
    print(f"{os.cpu_count()} cores; load average at the start: {load_text()}")
    with tempfile.TemporaryDirectory() as tmp:
        for name, mesh in (("ICT head", head), ("clustered head", Mesh.from_faces(Vc, Tc))) if args.runs else ():
            path = Path(tmp) / f"{len(mesh.vertices)}.obj"
            write_obj(path, mesh)
            runs = [rig_once(path, Path(tmp) / "out") for _ in range(args.runs)]
            wall = statistics.median(w for w, _, _ in runs)
            cpu = statistics.median(c for _, c, _ in runs)
            steps = {k: statistics.median(t[k][0] for _, _, t in runs) for k in STEPS}
            steps_cpu = {k: statistics.median(t[k][1] for _, _, t in runs) for k in STEPS}
            print(f"\n== {name} ({len(mesh.vertices)} vertices): pdeface rig {wall:.2f} s per process ({cpu:.2f} s of "
                  f"CPU: less sensitive to other work), median of {args.runs} (runs "
                  f"{', '.join(f'{w:.2f}' for w, _, _ in runs)}); target ≤ {TARGET_S:.0f} s: ratio "
                  f"{wall / TARGET_S:.2f}, {'met' if wall <= TARGET_S else 'NOT met'}; load after: {load_text()}")
            print(f"  {'step':10s} {'wall s':>6s} {'share':>5s}  {'CPU s':>6s} {'share':>5s}")
            for k, s in steps.items():
                print(f"  {k:10s} {s:6.2f} {100 * s / wall:4.0f}%  "
                      f"{steps_cpu[k]:6.2f} {100 * steps_cpu[k] / cpu:4.0f}%")
            rest, rest_cpu = wall - sum(steps.values()), cpu - sum(steps_cpu.values())
            print(f"  {'the rest':10s} {rest:6.2f} {100 * rest / wall:4.0f}%  "
                  f"{rest_cpu:6.2f} {100 * rest_cpu / cpu:4.0f}%  (Python's start, imports, writing)")
    own, every, compiled = [], [], []
    with tempfile.TemporaryDirectory() as source_only:
        shutil.copytree(Path(pdeface.__file__).parent, Path(source_only) / "pdeface",
                        ignore=shutil.ignore_patterns("__pycache__"))
        for _ in range(args.import_runs):  # interleaved: the machine's load falls on all alike
            own.append(import_seconds("rig"))
            every.append(import_seconds(None))
            compiled.append(import_seconds("rig", source_only))
    if args.import_runs:
        a, b, c = statistics.median(own), statistics.median(every), statistics.median(compiled)
        print(f"\nthe command line's imports before pdeface rig runs: {a:.3f} s (its own group) against {b:.3f} s "
              f"(every group, as before): {b / a:.1f}× less; its own group compiled from source in each process "
              f"(PYTHONDONTWRITEBYTECODE set, no bytecode written before): {c:.3f} s, {c / a:.1f}× the time; median "
              f"of {args.import_runs} fresh processes each")
    print(f"load average at the end: {load_text()}")
    return 0


if __name__ == "__main__":
    raise SystemExit(run_bench(main, "rig"))
