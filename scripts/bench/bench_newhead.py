"""Benchmark a new head in Blender: import → Find Landmarks → Fit to Selected (issue #35: ≤ 3 s each head).

Usage: python -m scripts.bench.bench_newhead [--profile N]

Headless with the bpy module and the add-on from this checkout: ICT-FaceKit's whole head (26,719
vertices, written as OBJ from the bundled asset) and the same head clustered on a grid to about 8k
vertices (another topology, as a sculpted head has), each imported with Blender's OBJ importer,
then Find Landmarks and Fit PDE Face to Selected (fit, bind, every key on the mesh). Prints each
step's wall and CPU seconds (this process's, all its threads: on a busy machine wall exceeds CPU)
and share of the chain; then, from a second run of the chain under cProfile (which slows
Python-heavy steps), where each step's time goes: how much of it pdeface's core takes (its
functions the add-on calls) and the add-on with Blender the rest, and the ``N`` functions of the
most time of their own, pdeface's and the libraries'. The second run binds the head again (the
add-on's binding cache is emptied first), as a new head would be. The ICT head runs first in the
process: its first Find Landmarks pays scipy's and MediaPipe's imports and the first Fit the head prior's read.
Then the ICT head's chain in a fresh process after the add-on's warm-up (``blender_addon/warm.py``, which
Blender runs on a thread a few seconds after its start: here started and waited for before the import, as
when the artist opens a mesh a few seconds after Blender starts): its wall and CPU seconds beside the cold
chain's of this run, and the warm-up's own; ``--heap-runs N`` such fresh processes each with the C heap kept
(:func:`pdeface.heap.keep_heap` with 32 MiB kept free, called first) and at glibc's default (as the add-on runs), in
turn: each step's median wall and CPU seconds and page faults both ways, and the processes' peak memory. pdeface's
bytecode is compiled first and read by both (``benchlib.installed_env``). The machine's load average is printed.
Needs ``pdeface[blender,landmarks]``.
"""
from __future__ import annotations

import cProfile
import importlib
import json
import os
import pstats
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from scripts.bench.benchlib import bench_parser, clustered, enable_addon, installed_env, run_bench

ROOT = Path(__file__).resolve().parents[2]
TARGET_S = 3.0
#: Free memory the heap comparison's kept heap holds (in Blender, which lives on: Add ICT Head (rigged) peaked at
#: 461 MB with 32 MiB, 486 MB with 64, 457 MB at glibc's default).
KEPT_FREE = 32 << 20


def load_text():
    return ", ".join(f"{x:.2f}" for x in os.getloadavg())


def time_only(fn):
    """``fn()``'s (wall, CPU) seconds."""
    t, c = time.perf_counter(), time.process_time()
    fn()
    return time.perf_counter() - t, time.process_time() - c


def profiled(fn):
    """``fn()``'s profile."""
    prof = cProfile.Profile()
    prof.enable()
    fn()
    prof.disable()
    return prof


def chain(bpy, path, measure, accept=False):
    """Import the OBJ ``path`` into an empty scene, Find Landmarks on it, Fit to Selected: ``{step: measure(step)}``.
    ``accept``: Fit goes on past the landmark gate (the clustered head: its cells fuse its lids with its eyeballs,
    which the gate on found landmarks cannot tell from closed eyes and refuses naming that case); the time is the
    same work."""
    bpy.ops.wm.read_homefile(use_empty=True)
    bpy.context.scene.pdeface.unit = "AUTO"
    out = {"import (Blender's OBJ importer)": measure(lambda: bpy.ops.wm.obj_import(filepath=str(path)))}
    obj = bpy.context.selected_objects[0]
    bpy.context.view_layer.objects.active = obj
    out["Find Landmarks"] = measure(bpy.ops.pdeface.find_landmarks)
    bpy.context.view_layer.objects.active = obj
    obj.select_set(True)
    out["Fit PDE Face to Selected (fit, bind, keys)"] = measure(lambda: bpy.ops.pdeface.fit_to_selected(accept=accept))
    return out


def top(prof, n):
    """The ``n`` functions of most time of their own, then the ``n`` of pdeface's (core and add-on) of most
    time in all they call: (own seconds, cumulative seconds, calls, name) each."""
    rows = []
    for (file, line, name), (_, calls, own, cum, _) in pstats.Stats(prof).stats.items():
        where = file.split("site-packages/")[-1].split("/core/")[-1].split("/blender_addon/")[-1]
        ours = "/core/pdeface/" in file or "/pdeface/" in file and "site-packages" not in file
        rows.append((own, cum, calls, f"{where}:{line}({name})" if line else name, ours))
    own = sorted(rows, key=lambda r: -r[0])[:n]
    cum = sorted([r for r in rows if r[4] and "bench_newhead" not in r[3]], key=lambda r: -r[1])[:n]
    return own, cum


def core_calls(prof):
    """``{core function: cumulative seconds}`` of pdeface's core functions called from the add-on (the core's
    share of a step is their sum; the add-on's own code and Blender take the rest)."""
    def in_core(file):
        return "/core/pdeface/" in file

    def in_addon(file):
        return "/pdeface/" in file and not in_core(file) and "site-packages" not in file

    out = {}
    for (file, line, name), (*_, callers) in pstats.Stats(prof).stats.items():
        if in_core(file):
            for (caller, _, caller_name), called in callers.items():
                if in_addon(caller):  # a bounded function (threads.run) named by the add-on's function calling it
                    where = f"{file.split('/core/')[-1]}:{line}({name}) from the add-on's {caller_name}"
                    out[where] = out.get(where, 0.0) + called[3]
    return out


def with_faults(fn):
    """``fn()``'s (wall, CPU) seconds and the page faults it took (minor: memory the kernel gave the process)."""
    before = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
    wall, cpu = time_only(fn)
    return wall, cpu, resource.getrusage(resource.RUSAGE_SELF).ru_minflt - before


def warmed_chain(path, kept_heap=False):
    """In this (fresh) process: the add-on's warm-up started and waited for, then the chain on ``path``; prints
    ``{"warm-up": (wall, CPU, faults), step: (wall, CPU, faults), ..., "peak MB": ...}`` as JSON (CPU: the
    process's, the warm-up's thread's too). ``kept_heap``: :func:`pdeface.heap.keep_heap` called first."""
    if kept_heap:
        from pdeface.heap import keep_heap

        keep_heap(trim_threshold=KEPT_FREE)
    addon = enable_addon()
    import bpy

    warm = importlib.import_module(f"{addon.__name__}.warm")
    steps = {"warm-up": with_faults(lambda: (warm.start(), warm.wait()))}
    steps |= chain(bpy, path, with_faults)
    print(json.dumps(steps | {"peak MB": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024}))


def warmed_in_a_fresh_process(path, env, kept_heap=False):
    """:func:`warmed_chain` of ``path`` in a fresh process: its ``{step: (wall, CPU, faults)}`` and peak MB."""
    argv = ["--warmed", str(path), "--no-page"] + (["--kept-heap"] if kept_heap else [])
    done = subprocess.run([sys.executable, "-m", "scripts.bench.bench_newhead", *argv],
                          env=env, capture_output=True, text=True, check=False, cwd=ROOT)
    if done.returncode:
        raise SystemExit(f"the warmed chain failed: {done.stderr.strip()[-600:]}")
    return json.loads(done.stdout.strip().splitlines()[-1])


def heap_both_ways(path, env, runs):
    """The warmed chain on ``path`` in fresh processes with the C heap kept and at glibc's default, in turn (the
    machine's load falls on both alike): each step's medians both ways."""
    ways = {"kept": [], "default": []}
    for _ in range(runs):
        for way, rows in ways.items():
            rows.append(warmed_in_a_fresh_process(path, env, kept_heap=way == "kept"))
    print(f"\n== ICT head after the warm-up, {runs} fresh processes each way in turn: the C heap kept "
          f"(pdeface.heap.keep_heap) and at glibc's default (as the add-on runs); medians; load after: {load_text()}")
    print(f"  {'step':45s} {'wall kept':>9s} {'default':>8s} {'ratio':>6s}  {'CPU kept':>8s} {'default':>8s} "
          f"{'ratio':>6s}  {'faults kept':>11s} {'default':>8s}")
    steps = [k for k in ways["kept"][0] if k not in ("warm-up", "peak MB")]
    for step in [*steps, "chain"]:
        med = {way: [statistics.median(sum(r[s][i] for s in (steps if step == "chain" else [step])) for r in rows)
                     for i in range(3)] for way, rows in ways.items()}
        (kw, kc, kf), (dw, dc, df) = med["kept"], med["default"]
        print(f"  {step:45s} {kw:8.2f}s {dw:7.2f}s {kw / dw:6.2f}  {kc:7.2f}s {dc:7.2f}s {kc / dc:6.2f}  "
              f"{kf:11.0f} {df:8.0f}")
    peaks = {way: statistics.median(r["peak MB"] for r in rows) for way, rows in ways.items()}
    print(f"  peak memory of the process: {peaks['kept']:.0f} MB kept, {peaks['default']:.0f} MB at the default")


def main(argv=None):
    ap = bench_parser(__doc__)
    ap.add_argument("--profile", type=int, default=8, help="functions listed per step")
    ap.add_argument("--warmed", metavar="OBJ", help="(its own child) the chain on OBJ after the add-on's warm-up")
    ap.add_argument("--kept-heap", action="store_true", help="(with --warmed) pdeface.heap.keep_heap called first")
    ap.add_argument("--heap-runs", type=int, default=0, help="fresh processes each way, heap kept and default")
    args = ap.parse_args(argv)
    if args.warmed:
        warmed_chain(args.warmed, args.kept_heap)
        return 0
    env = installed_env()  # pdeface's bytecode compiled now and read, here and in the warmed child alike
    addon = enable_addon()
    import bpy
    from pdeface.assets import load_head
    from pdeface.io.meshio import write_obj
    from pdeface.mesh import Mesh
    bindings = importlib.import_module(f"{addon.__name__}.head")._bindings  # the add-on's cache of head bindings
    head, _ = load_head()
    tmp = Path(tempfile.mkdtemp())
    V, T = head.vertices, head.triangles()[0]
    Vc, Tc = clustered(V, T, 0.42)  # cm: about 8k vertices
    heads = {"ICT head": head, f"clustered head ({len(Vc) / 1000:.0f}k)": Mesh.from_faces(Vc, Tc)}
    print(f"{os.cpu_count()} cores; load average at the start: {load_text()}")
    cold = {}
    for name, mesh in heads.items():
        path = tmp / f"{len(mesh.vertices)}.obj"
        write_obj(path, mesh)
        accept = name.startswith("clustered")
        timed = chain(bpy, path, time_only, accept)
        cold.setdefault("ICT head", (path, timed))
        obj = bpy.context.view_layer.objects.active
        total, total_cpu = (sum(s[i] for s in timed.values()) for i in (0, 1))
        keys = len(obj.data.shape_keys.key_blocks) - 1 if obj.data.shape_keys else 0
        print(f"\n== {name}: {len(mesh.vertices)} vertices, {keys} keys on it; chain {total:.2f} s, "
              f"CPU {total_cpu:.2f} s (target ≤ {TARGET_S:.0f} s, ratio {total / TARGET_S:.2f}); "
              f"load after: {load_text()}")
        bindings.clear()  # profiled as a new head: bound again
        profiles = chain(bpy, path, profiled, accept) if args.profile else {}
        for step, (s, cpu) in timed.items():
            print(f"  {step:45s} {s:6.2f} s  CPU {cpu:6.2f} s  {100 * s / total:4.0f}%")
            if step in profiles:
                spent = pstats.Stats(profiles[step]).total_tt
                calls = core_calls(profiles[step])
                core = sum(calls.values())
                print(f"    profiled: {spent:.2f} s, of which pdeface's core {core:.2f} s, the add-on and Blender "
                      f"{spent - core:.2f} s")
                print("    pdeface's core as the add-on calls it:" if calls else "", end="\n" if calls else "")
                for fn, c in sorted(calls.items(), key=lambda kv: -kv[1])[:args.profile]:
                    print(f"      {c:6.2f} s  {fn[:130]}")
                own, cum = top(profiles[step], args.profile)
                for title, listed in (("most time of their own", own), ("pdeface's, most time in all they call", cum)):
                    print(f"    {title}:" if listed else "", end="\n" if listed else "")
                    for o, c, calls, fn, _ in listed:
                        print(f"      {o:6.2f} s own {c:6.2f} s cum {calls:7d}×  {fn[:110]}")
    path, timed = cold["ICT head"]
    warmed = warmed_in_a_fresh_process(path, env)
    warmed.pop("peak MB")
    warm_s, warm_cpu, _ = warmed.pop("warm-up")
    print(f"\n== ICT head after the add-on's warm-up, in a fresh process (the warm-up itself {warm_s:.2f} s, CPU "
          f"{warm_cpu:.2f} s, on its thread before the import); cold: this run's first chain above; load after: "
          f"{load_text()}")
    print(f"  {'step':45s} {'warmed':>8s} {'cold':>8s} {'ratio':>6s}   {'CPU warmed':>10s} {'cold':>6s} {'ratio':>6s}")
    for step, (s, cpu) in timed.items():
        ws, wc, _ = warmed[step]
        print(f"  {step:45s} {ws:7.2f}s {s:7.2f}s {ws / s:6.2f}   {wc:9.2f}s {cpu:5.2f}s {wc / cpu:6.2f}")
    total = [sum(v[i] for v in d.values()) for d in (warmed, timed) for i in (0, 1)]
    print(f"  {'chain':45s} {total[0]:7.2f}s {total[2]:7.2f}s {total[0] / total[2]:6.2f}   {total[1]:9.2f}s "
          f"{total[3]:5.2f}s {total[1] / total[3]:6.2f}   (target ≤ {TARGET_S:.0f} s: "
          f"{'met' if total[0] <= TARGET_S else 'NOT met'} warmed)")
    if args.heap_runs:
        heap_both_ways(path, env, args.heap_runs)
    return 0


if __name__ == "__main__":
    sys.exit(run_bench(main, "newhead"))
