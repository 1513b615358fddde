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
process: its first Find Landmarks pays scipy's and MediaPipe's imports. The machine's load average
is printed. Needs ``pdeface[blender,landmarks]``.
"""
from __future__ import annotations

import cProfile
import importlib
import os
import pstats
import sys
import tempfile
import time
from pathlib import Path

from scripts.bench.benchlib import bench_parser, clustered, enable_addon, run_bench

ROOT = Path(__file__).resolve().parents[2]
TARGET_S = 3.0


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


def chain(bpy, path, measure):
    """Import the OBJ ``path`` into an empty scene, Find Landmarks on it, Fit to Selected: ``{step: measure(step)}``."""
    bpy.ops.wm.read_homefile(use_empty=True)
    bpy.context.scene.pdeface.unit = "AUTO"
    out = {"import (Blender's OBJ importer)": measure(lambda: bpy.ops.wm.obj_import(filepath=str(path)))}
    obj = bpy.context.selected_objects[0]
    bpy.context.view_layer.objects.active = obj
    out["Find Landmarks"] = measure(bpy.ops.pdeface.find_landmarks)
    bpy.context.view_layer.objects.active = obj
    obj.select_set(True)
    out["Fit PDE Face to Selected (fit, bind, keys)"] = measure(bpy.ops.pdeface.fit_to_selected)
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


def main(argv=None):
    ap = bench_parser(__doc__)
    ap.add_argument("--profile", type=int, default=8, help="functions listed per step")
    args = ap.parse_args(argv)
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
    for name, mesh in heads.items():
        path = tmp / f"{len(mesh.vertices)}.obj"
        write_obj(path, mesh)
        timed = chain(bpy, path, time_only)
        obj = bpy.context.view_layer.objects.active
        total, total_cpu = (sum(s[i] for s in timed.values()) for i in (0, 1))
        keys = len(obj.data.shape_keys.key_blocks) - 1 if obj.data.shape_keys else 0
        print(f"\n== {name}: {len(mesh.vertices)} vertices, {keys} keys on it; chain {total:.2f} s, "
              f"CPU {total_cpu:.2f} s (target ≤ {TARGET_S:.0f} s, ratio {total / TARGET_S:.2f}); "
              f"load after: {load_text()}")
        bindings.clear()  # profiled as a new head: bound again
        profiles = chain(bpy, path, profiled) if args.profile else {}
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
    return 0


if __name__ == "__main__":
    sys.exit(run_bench(main, "newhead"))
