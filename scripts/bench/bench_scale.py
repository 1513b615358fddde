"""Fit and resolution-choice time across mesh sizes, and peak memory (issue #35 targets).

Usage: python -m scripts.bench.bench_scale [--repeat 3] [--no-rig] [--demo-render]
       python -m scripts.bench.bench_scale --steps STEPS.json --no-page [--baseline REF]

``--steps``: only the resolution choice's steps on 11 faces (the bundled face, faces fitted on ICT's generic head
and identities 000, 007 and 013, and on six MakeHuman characters), with its CPU seconds: written to the file, or,
where it exists, compared with it (run it on main first: a faster choice must choose the same steps). With
``--baseline REF`` (a git revision), each face's choice is also made by REF's ``sampling`` module (the rest of
the core this checkout's), the two in turn ``--repeat`` times: CPU medians side by side, and each one's vertices.

Prints, measured in this run (CPU seconds of this process, the figure a busy machine does not
distort, and wall seconds beside them):
- the fit (``fit_face``) of ICT-FaceKit's whole head remeshed to about 2k, 5k, 27k (as bundled),
  100k and 200k vertices (clustered on a grid, or butterfly-subdivided then clustered), each
  against the same fit with the candidate search issue #35 replaced (kept here as the baseline:
  a grid sized from every triangle, each rim column cast on its own), and against the 27k fit
  (coarse meshes must not be slower than fine). Targets: ≤ 1 s at 5k, 27k and 100k.
- choosing the mesh resolution (``adaptive_resolution``, operator caches cleared) of the face fitted
  on the 27k head with the bundled descriptors retargeted, against its fit and against solving its keys once
  on the mesh it chose (the floor of any check of that mesh); of the faces fitted on two MakeHuman
  characters (:data:`CHARACTERS`); and of the 27k head's face with one descriptor's residual blown up (a
  hostile file), capped and uncapped. Target ≤ 0.2 s on any face.
- peak resident memory (of the whole process tree) of ``pdeface demo --no-render`` (``--demo-render``:
  with the render) against a bare ``import numpy, scipy, pdeface`` (with ``--demo-render``, also the
  demo's contact sheet alone, rendered in bands as the demo does against the whole sheet in one render,
  as before), and of *Add ICT Head (rigged)* in bpy against bpy with the add-on enabled. Targets: demo ≤ 1.5 GB,
  the rig ≤ 500 MB.
"""
from __future__ import annotations

import argparse
import copy
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from scripts.bench.bench_head import per_part_clustered
from scripts.bench.benchlib import bench_parser, enable_addon, run_bench

ROOT = Path(__file__).resolve().parents[2]


def old_cylinder_ray_candidates(V, T, axis_z, theta, height):
    """The candidate search before issue #35 (the baseline): a grid over every triangle's box."""
    from pdeface.geometry import cylinder_coords

    th, y, r = cylinder_coords(V, axis_z)
    tth, ty = th[T], y[T]
    ok = (np.ptp(tth, axis=1) < np.pi / 2) & (r[T].min(axis=1) > 1e-9)
    cand = np.nonzero(ok)[0]
    lo = np.stack([tth[cand].min(1), ty[cand].min(1)], 1)
    hi = np.stack([tth[cand].max(1), ty[cand].max(1)], 1)
    size = np.maximum(np.median(hi - lo, axis=0) * 2.0, 1e-9)
    origin = lo.min(0)
    c0 = np.floor((lo - origin) / size).astype(np.int64)
    c1 = np.floor((hi - origin) / size).astype(np.int64)
    ncell = c1.max(0) + 1
    span = c1 - c0 + 1
    reps = span[:, 0] * span[:, 1]
    tid = np.repeat(np.arange(len(cand)), reps)
    k = np.arange(len(tid)) - np.repeat(np.cumsum(reps) - reps, reps)
    cell = (c0[tid, 0] + k % span[tid, 0]) * ncell[1] + c0[tid, 1] + k // span[tid, 0]
    order = np.argsort(cell, kind="stable")
    cell, tid = cell[order], cand[tid[order]]
    qc = np.floor((np.stack([theta, height], 1) - origin) / size).astype(np.int64)
    inside = (qc >= 0).all(1) & (qc < ncell).all(1)
    qcell = np.where(inside, qc[:, 0] * ncell[1] + qc[:, 1], -1)
    start = np.searchsorted(cell, qcell, "left")
    stop = np.where(inside, np.searchsorted(cell, qcell, "right"), start)
    counts = stop - start
    rays = np.repeat(np.arange(len(theta)), counts)
    pos = np.arange(len(rays)) - np.repeat(np.cumsum(counts) - counts, counts) + np.repeat(start, counts)
    return rays, tid[pos]


class OldSearch:
    """The pre-#35 candidate search, and the rim walk casting each column on its own, in place for a ``with``
    block."""

    def __enter__(self):
        from pdeface import geometry
        from pdeface.surface import rims
        self.saved = geometry.cylinder_ray_candidates, rims._rims
        walk = rims._rims

        def one_column_at_a_time(V, T, axis_z, th, *heights_and_gap):
            cols = [walk(V, T, axis_z, th[c:c + 1], *(h[c:c + 1] for h in heights_and_gap[:4]), heights_and_gap[4])
                    for c in range(len(th))]
            return tuple(np.concatenate(parts) if parts else np.zeros(0) for parts in zip(*cols)) or (th, th)

        geometry.cylinder_ray_candidates, rims._rims = old_cylinder_ray_candidates, one_column_at_a_time

    def __exit__(self, *exc):
        from pdeface import geometry
        from pdeface.surface import rims
        geometry.cylinder_ray_candidates, rims._rims = self.saved


def clustered(V, T, cell):
    """``V, T`` remeshed by clustering each connected piece on a grid of ``cell`` (cm): bench_head's remesher."""
    return per_part_clustered(V, T, cell)[:2]


def test_heads():
    """{label: (V, T)} ICT's head at five sizes, and its 68 landmark positions (cm)."""
    from pdeface.assets import load_head
    from pdeface.mesh import butterfly_step

    head, idx = load_head()
    V, (T, _) = head.vertices, head.triangles()
    S, T1 = butterfly_step(len(V), T)
    V1 = S @ V
    S2, T2 = butterfly_step(len(V1), T1)
    heads = {"2k": clustered(V, T, 1.35), "5k": clustered(V, T, 0.75), "27k": (V, T), "100k": (V1, T1),
             "200k": clustered(S2 @ V1, T2, 0.1)}
    return heads, V[idx]


def timed(fn, repeat):
    """Best CPU and wall seconds of ``repeat`` calls, and the last result."""
    cpu, wall = [], []
    for _ in range(repeat):
        c, w = time.process_time(), time.perf_counter()
        out = fn()
        cpu.append(time.process_time() - c)
        wall.append(time.perf_counter() - w)
    return min(cpu), min(wall), out


def fit_times(repeat):
    from pdeface.surface.fit import fit_face

    heads, L = test_heads()
    fit_face(*heads["27k"], L, unit="cm")  # imports and first-use caches out of the figures
    rows = {}
    for label, (V, T) in heads.items():
        def fit(V=V, T=T):
            return fit_face(V, T, L, unit="cm")

        cpu, wall, (_, sampler) = timed(fit, repeat)
        with OldSearch():
            old_cpu, old_wall, (_, old_sampler) = timed(fit, 1)
        same = np.array_equal(sampler.matrix.toarray(), old_sampler.matrix.toarray())
        rows[label] = (len(V), cpu, wall, old_cpu, old_wall, same)
    base = rows["27k"][1]
    print("fit_face of ICT's head remeshed (CPU s, wall s in brackets; baseline: the pre-#35 candidate search, "
          "one run):")
    for label, (n, cpu, wall, old_cpu, old_wall, same) in rows.items():
        print(f"  {label:>4} ({n:6d} vertices): {cpu:.2f} s ({wall:.2f}) against {old_cpu:.2f} s ({old_wall:.2f}) "
              f"before: {old_cpu / cpu:.1f}x faster; {cpu / base:.2f}x the 27k fit; curve points "
              f"{'the same' if same else 'DIFFERENT'}; target <= 1 s: {'met' if cpu <= 1 else 'NOT met'}")
    return heads, L, base


#: MakeHuman development-set characters whose faces' resolution choice is timed too: the costliest of 11 faces
#: measured (its first choice fails the check twice, a 46k-vertex mesh) and a plain one.
CHARACTERS = ("african-male-old-m", "base-dm")


def chosen_afresh(m, sampling=None):
    """The resolution choice of face model ``m`` made again: its cache and the operators' cleared. ``sampling``:
    the module choosing (this checkout's, or :func:`baseline_sampling`'s)."""
    from pdeface.surface import pde

    if sampling is None:
        from pdeface.surface import sampling
    sampling._CHOSEN.clear()
    for cache in (pde.surface_operator, pde.confined_operator, pde.merged_operator, pde.mode_operator,
                  pde.mode_operators, pde._smooth_coefficients, pde._smooth_coefficient_stack):
        cache.cache_clear()
    return sampling.adaptive_resolution(m)


def resolution_times(heads, L, fit_cpu, repeat):
    from pdeface.au.modelfile import load_face
    from pdeface.au.retarget import retarget
    from pdeface.surface import grid, sampling
    from pdeface.surface.fit import fit_face

    from scripts.devset.characters import SPECS, build

    model = retarget(load_face("default"), fit_face(*heads["27k"], L, unit="cm")[0])

    choose = chosen_afresh

    def choose_counting(m):
        """``choose(m)``, and how many meshes it measured (the probe, then each check)."""
        measured, counting = [], sampling.interval_turns

        def counted(*args, **kw):
            measured.append(1)
            return counting(*args, **kw)
        sampling.interval_turns = counted
        try:
            return choose(m), len(measured)
        finally:
            sampling.interval_turns = counting

    cpu, wall, steps = timed(lambda: choose(model), repeat)
    n = (sum(steps[0]) + 1) * (sum(steps[1]) + 1)
    solve_cpu, _, _ = timed(lambda: list(grid.key_grids(model, *steps, planes=True)), repeat)  # operator cached
    print(f"resolution choice of the face fitted on the 27k head ({len(model.descriptors)} descriptors, "
          f"{n} vertices chosen): {cpu:.2f} s CPU ({wall:.2f} wall), {cpu / fit_cpu:.1f}x its fit, "
          f"{cpu / solve_cpu:.1f}x "
          f"solving its keys once on the chosen mesh ({solve_cpu:.3f} s: what any check of that mesh costs); target "
          f"<= 0.2 s: {'met' if cpu <= 0.2 else 'NOT met'}")
    for name in CHARACTERS:
        ch = build(SPECS[name])
        (V, T), L_ch = ch.joined(), ch.landmarks
        face = retarget(load_face("default"), fit_face(V, T, L_ch)[0])
        cpu_c, wall_c, (steps, meshes) = timed(lambda f=face: choose_counting(f), repeat)
        n = (sum(steps[0]) + 1) * (sum(steps[1]) + 1)
        print(f"  the face fitted on MakeHuman's {name} ({n} vertices chosen, {meshes} meshes measured): "
              f"{cpu_c:.2f} s CPU ({wall_c:.2f} wall), {cpu_c / cpu:.1f}x the 27k head's; target <= 0.2 s: "
              f"{'met' if cpu_c <= 0.2 else 'NOT met'}")
    hostile = copy.deepcopy(model)
    d = hostile.descriptors[0]
    d.residual = d.residual * 1e4 + 50 * np.random.default_rng(0).normal(size=d.residual.shape)
    cpu_h, wall_h, steps = timed(lambda: choose(hostile), 1)
    n_h = (sum(steps[0]) + 1) * (sum(steps[1]) + 1)
    cap, sampling.MAX_VERTICES = sampling.MAX_VERTICES, 10 ** 9
    try:
        cpu_u, wall_u, steps = timed(lambda: choose(hostile), 1)
    finally:
        sampling.MAX_VERTICES = cap
    n_u = (sum(steps[0]) + 1) * (sum(steps[1]) + 1)
    print(f"  one descriptor's residual blown up (x1e4 + noise): capped at {cap} vertices {cpu_h:.2f} s CPU "
          f"({wall_h:.2f} wall, {n_h} vertices); uncapped {cpu_u:.2f} s ({wall_u:.2f} wall, {n_u} vertices): "
          f"{cpu_u / cpu_h:.1f}x")


#: MakeHuman development-set characters whose faces' steps ``--steps`` compares (the two timed, and four more).
STEPS_CHARACTERS = CHARACTERS + ("caucasian-female-young-cm", "asian-male-young-blender-m", "stylised-nose-mouth-cm",
                                 "decimated-cm")


def baseline_sampling(ref):
    """Git revision ``ref``'s ``pdeface.surface.sampling``, loaded beside this checkout's (its relative imports this
    checkout's modules)."""
    import importlib.util

    source = subprocess.run(["git", "show", f"{ref}:core/pdeface/surface/sampling.py"], capture_output=True,
                            text=True, check=True, cwd=ROOT).stdout
    spec = importlib.util.spec_from_loader("pdeface.surface._baseline_sampling", loader=None)
    module = importlib.util.module_from_spec(spec)
    module.__package__ = "pdeface.surface"
    exec(compile(source, f"{ref}:sampling.py", "exec"), module.__dict__)
    return module


def steps_check(path, repeat, baseline=None):
    """The resolution choice's steps on 11 faces, and its CPU seconds on each: written to ``path``, or compared
    with the steps there; with ``baseline`` (a git revision), against its choice too, timed in turn."""
    from pdeface.assets import load_head, load_head_shapes
    from pdeface.au.modelfile import load_face
    from pdeface.au.retarget import retarget
    from pdeface.surface.fit import fit_face

    from scripts.devset.characters import SPECS, build

    source = load_face("default")
    head, idx = load_head()
    T, _ = head.triangles()
    shapes = load_head_shapes()
    faces = {"bundled": source}
    identities = ((f"ICT identity{i:03d}", head.vertices + shapes[f"identity{i:03d}"]) for i in (0, 7, 13))
    for name, V in (("ICT generic", head.vertices), *identities):
        faces[name] = retarget(source, fit_face(V, T, V[idx])[0])
    for name in STEPS_CHARACTERS:
        ch = build(SPECS[name])
        faces[name] = retarget(source, fit_face(*ch.joined(), ch.landmarks)[0])

    before = json.loads(Path(path).read_text()) if Path(path).exists() else None
    old = baseline_sampling(baseline) if baseline else None
    chosen, total, changed, rows = {}, 0.0, [], []
    for name, m in faces.items():
        if old is None:
            cpu, wall, chosen[name] = timed(lambda m=m: [list(s) for s in chosen_afresh(m)], repeat)
        else:
            now, then = [], []
            for _ in range(repeat):  # in turn, so that a change of load weighs on both
                now.append(timed(lambda m=m: [list(s) for s in chosen_afresh(m)], 1))
                then.append(timed(lambda m=m: [list(s) for s in chosen_afresh(m, old)], 1))
            cpu, wall = (float(np.median([r[i] for r in now])) for i in (0, 1))
            chosen[name], old_steps = now[-1][2], then[-1][2]
            old_cpu = float(np.median([r[0] for r in then]))
            rows.append((cpu, old_cpu))
        total += cpu
        n = (sum(chosen[name][0]) + 1) * (sum(chosen[name][1]) + 1)
        same = "" if before is None else ("the same steps" if before.get(name) == chosen[name] else "OTHER STEPS")
        changed += [name] if same == "OTHER STEPS" else []
        versus = "" if old is None else (f" against {old_cpu:.2f} s ({baseline}'s rule, "
                                         f"{(sum(old_steps[0]) + 1) * (sum(old_steps[1]) + 1)} vertices)")
        print(f"  {name:28s} {n:6d} vertices chosen: {cpu:.2f} s CPU ({wall:.2f} wall){versus} {same}")
    if rows:
        print(f"  medians of {repeat} each, in turn: {sum(r[0] for r in rows):.2f} s CPU for the {len(rows)} faces "
              f"against {sum(r[1] for r in rows):.2f} s; at most {max(r[0] for r in rows):.2f} s against "
              f"{max(r[1] for r in rows):.2f} s; faces at or under 0.2 s: {sum(r[0] <= 0.2 for r in rows)} against "
              f"{sum(r[1] <= 0.2 for r in rows)}")
    if before is None:
        Path(path).write_text(json.dumps(chosen))
        print(f"resolution choice on {len(faces)} faces: {total:.2f} s CPU; steps written to {path}")
    else:
        print(f"resolution choice on {len(faces)} faces: {total:.2f} s CPU; steps against {path}: "
              f"{'all the same' if not changed else 'OTHER on ' + ', '.join(changed)}")


def child_peak_mb(argv, env=None):
    """Peak RSS (MB) of the whole process tree a child running ``argv`` starts, its processes' RSS summed (polled
    every 20 ms: a fork inherits its parent's ``ru_maxrss``, so the children's own figure would be this
    benchmark's), its wall seconds and its stdout. The exit code must be 0."""
    import psutil

    t = time.perf_counter()
    with tempfile.TemporaryFile("w+") as out, tempfile.TemporaryFile("w+") as err:  # files: a full pipe would block
        proc = subprocess.Popen(argv, cwd=ROOT, env=env, stdout=out, stderr=err, text=True)
        top, peak = psutil.Process(proc.pid), 0
        while proc.poll() is None:
            try:
                peak = max(peak, sum(p.memory_info().rss for p in [top, *top.children(recursive=True)]))
            except psutil.Error:
                pass  # a process ended between the listing and the reading
            time.sleep(0.02)
        out.seek(0), err.seek(0)
        if proc.returncode:
            raise SystemExit(f"{' '.join(argv)} failed: {err.read()[-800:]}")
        return peak / 2 ** 20, time.perf_counter() - t, out.read()


def high_water_mb():
    """This process's own peak RSS (MB) since it started its program (``VmHWM``; ``ru_maxrss`` counts the
    parent's memory before the exec too)."""
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith("VmHWM:"):
            return int(line.split()[1]) / 1024
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def memory(args):
    env = dict(os.environ)
    base, _, _ = child_peak_mb([sys.executable, "-c", "import numpy, scipy.sparse, scipy.spatial, pdeface"], env)
    with tempfile.TemporaryDirectory() as out:
        demo = [sys.executable, "-m", "pdeface.cli", "demo", "--out", out] + ([] if args.demo_render else
                                                                              ["--no-render"])
        peak, wall, _ = child_peak_mb(demo, env)
    what = "pdeface demo" + ("" if args.demo_render else " --no-render")
    print(f"peak RSS: {what} {peak:.0f} MB ({wall:.0f} s) against a bare import of numpy, scipy and pdeface "
          f"{base:.0f} MB: {peak / base:.1f}x; target <= 1536 MB: {'met' if peak <= 1536 else 'NOT met'}")
    if args.demo_render:
        sheet_memory(env)
    if args.no_rig:
        return
    done = subprocess.run([sys.executable, "-m", "scripts.bench.bench_scale", "--rig-child"], check=False, cwd=ROOT,
                          env=env,
                          capture_output=True, text=True)
    if done.returncode:
        raise SystemExit(f"the rig in bpy failed: {done.stderr[-800:]}")
    r = json.loads(done.stdout.strip().splitlines()[-1])
    print(f"peak RSS: Add ICT Head (rigged) in bpy, {r['keys']} keys on {r['vertices']} vertices, {r['peak']:.0f} MB "
          f"({r['seconds']:.0f} s) against bpy with the add-on enabled {r['base']:.0f} MB: "
          f"+{r['peak'] - r['base']:.0f} "
          f"MB, {r['peak'] / r['base']:.1f}x; target <= 500 MB: {'met' if r['peak'] <= 500 else 'NOT met'}")


def sheet_memory(env):
    """Peak RSS of the demo's contact sheet alone (the rigged ICT head, 83 poses and their motion rows, the demo's
    size) rendered in bands, as the demo does, against the whole sheet in one render (the baseline, as before
    issue #35), and whether the two images match."""
    try:
        from PIL import Image  # not a dependency of ours: mediapipe's matplotlib brings it
    except ImportError:
        Image = None
    figures = {}
    with tempfile.TemporaryDirectory() as out:
        for name, bands in (("one render", "0"), ("bands", None)):
            argv = [sys.executable, "-m", "pdeface.cli", "render", "--head", "--no-frames", "--contact-sheet",
                    "--quiet", "--out", f"{out}/{name}"] + ([] if bands is None else ["--sheet-band-vertices", bands])
            peak, wall, _ = child_peak_mb(argv, env)
            image = Image and np.asarray(Image.open(f"{out}/{name}/contact_sheet.png").convert("RGB"))
            figures[name] = peak, wall, image
    (p1, w1, a), (pb, wb, b) = figures["one render"], figures["bands"]
    if Image is None:
        compared = "not compared (no Pillow)"
    elif a.shape != b.shape:
        compared = f"of different sizes ({b.shape} against {a.shape})"
    else:
        diff = np.abs(a.astype(float) - b)
        compared = (f"{a.shape[1]}x{a.shape[0]} px both, mean difference {diff.mean():.2f}/255, "
                    f"{100 * (diff.max(axis=2) > 8).mean():.2f}% of pixels off by more than 8/255")
    print(f"peak RSS: the demo's contact sheet alone, in bands {pb:.0f} MB ({wb:.0f} s) against one render "
          f"{p1:.0f} MB ({w1:.0f} s): {p1 / pb:.1f}x less; images {compared}")


def rig_child():
    """In a child: bpy, the add-on, then Add ICT Head (rigged); prints its peak RSS as JSON."""
    enable_addon()
    import bpy
    bpy.ops.wm.read_homefile(use_empty=True)
    base = high_water_mb()
    t = time.perf_counter()
    bpy.ops.pdeface.add_ict_head()
    obj = bpy.context.active_object
    print(json.dumps({"base": base, "peak": high_water_mb(),
                      "seconds": time.perf_counter() - t, "vertices": len(obj.data.vertices),
                      "keys": len(obj.data.shape_keys.key_blocks) - 1}))


def main(argv=None):
    ap = bench_parser(__doc__)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--no-rig", action="store_true", help="leave out the bpy rig's memory")
    ap.add_argument("--no-memory", action="store_true", help="leave out the peak-memory figures")
    ap.add_argument("--demo-render", action="store_true", help="measure the whole demo, render included (minutes)")
    ap.add_argument("--steps", metavar="JSON", help="only the resolution choice's steps on 11 faces: written to "
                    "JSON, or compared with it where it exists")
    ap.add_argument("--baseline", metavar="REF", help="with --steps: REF's resolution choice too, timed in turn")
    ap.add_argument("--rig-child", action="store_true", help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.rig_child:
        return rig_child()
    print(f"threads: OPENBLAS_NUM_THREADS={os.environ.get('OPENBLAS_NUM_THREADS', 'unset')}; "
          f"load average at the start {os.getloadavg()[0]:.2f}")
    if args.steps:
        steps_check(args.steps, args.repeat, args.baseline)
        print(f"load average at the end {os.getloadavg()[0]:.2f}")
        return
    heads, L, fit_cpu = fit_times(args.repeat)
    resolution_times(heads, L, fit_cpu, args.repeat)
    if not args.no_memory:
        memory(args)
    print(f"load average at the end {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    if "--rig-child" in sys.argv:
        main(sys.argv[1:])
    else:
        run_bench(main, "scale")
