"""Benchmark batch jobs on Dask (issue #37 targets): 2 worker processes against 1 on the same jobs.

Usage: python -m scripts.bench.bench_batch [--heads 12] [--makehuman 4] [--images 120] [--big] [--workers 2]

Prints, measured in this run (each job's wall time includes starting its local cluster):
- a ``rig`` job of ``--heads`` ICT-FaceKit identities (the bundled face region with each identity's offsets, its
  landmarks given) and ``--makehuman`` MakeHuman characters of the development set (``scripts/devset``: heads in
  their own units, their true landmarks given; left out, and said so, where ``../shared/data/makehuman`` is
  missing): 1 worker, then 2; throughput ratio (target ≥ 1.7× on 2 cores);
- a ``stimuli`` job of ``--images`` 256-px images (the bundled face and head × AU sets × 5 intensities): the same;
- with ``--big``, the 1,000-image set: 4 identities (the bundled face, the bundled head, two heads the rig job
  made) × 50 AU combinations × the 5 intensities A-E at 256 px on 2 workers: wall time, images/s and each
  worker's peak memory (resident set, sampled every 0.2 s).
The machine's load is printed before each job: the ratios only mean something when the cores are free.
"""
from __future__ import annotations

import json
import os
import tempfile
import threading
import time
from pathlib import Path

import numpy as np
import psutil

from scripts.bench.benchlib import bench_parser, run_bench


def make_heads(folder: Path, n: int) -> list:
    """``n`` ICT identities' face regions as OBJ files with their landmarks beside them (``{stem}.json``)."""
    from pdeface.assets import load_ict_shapes, load_neutral_scan
    from pdeface.io.meshio import write_mesh

    mesh, idx = load_neutral_scan()
    shapes = load_ict_shapes()
    rest = mesh.vertices.copy()
    paths = []
    for i in range(n):
        mesh.vertices = rest + shapes[f"identity{i % 20:03d}"] * (1.0 + 0.1 * (i // 20))
        path = folder / f"ict{i:03d}.obj"
        write_mesh(path, mesh)
        (folder / f"ict{i:03d}.json").write_text(json.dumps({"indices": idx.tolist()}))
        paths.append(path)
    return paths


#: Development-set characters for the rig job: heads (not whole bodies) of several ethnicities, ages and units.
CHARACTERS = ["caucasian-female-young-cm", "african-male-old-m", "asian-female-old-in", "african-asian-female-young-mm",
              "caucasian-male-old-dm-eyes", "base-dm"]


def make_characters(folder: Path, n: int) -> list:
    """``n`` MakeHuman characters as OBJ files with their landmarks beside them (``{stem}.json``), as the rig job's
    entries (each with its unit); [] where the MakeHuman data is missing."""
    from pdeface.io.meshio import write_mesh
    from pdeface.mesh import Mesh

    from scripts.devset import makehuman
    from scripts.devset.characters import SPECS, build

    if n and not makehuman.available():
        print(f"no MakeHuman data at {makehuman.DATA}: the rig job has the ICT heads only\n")
        return []
    entries = []
    for name in CHARACTERS[:n]:
        ch = build(SPECS[name])
        T = np.asarray(ch.triangles)
        write_mesh(folder / f"mh_{name}.obj", Mesh(ch.vertices, np.full(len(T), 3), T.ravel()))
        (folder / f"mh_{name}.json").write_text(json.dumps({"points": np.asarray(ch.landmarks).tolist()}))
        entries.append({"mesh": f"mh_{name}.obj", "unit": SPECS[name].unit})
    return entries


class PeakMemory:
    """The peak resident memory and the CPU time of each child process of this one (the local cluster's
    workers). The workers are looked for every 2 s, their memory read every 0.2 s: looking through every process
    of the machine each time took this process (which also holds the scheduler) 5% of a core."""

    def __init__(self, every=0.2, look_every=2.0):
        self.every, self.look_every, self.peak, self.cpu = every, look_every, {}, {}
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._watch, daemon=True)

    def _watch(self):
        from pdeface.batch.run import local_workers

        workers, looked = [], -self.look_every
        while not self._stop.is_set():
            if time.perf_counter() - looked >= self.look_every:
                workers, looked = local_workers(), time.perf_counter()
            for p in workers:
                try:
                    self.peak[p.pid] = max(self.peak.get(p.pid, 0), p.memory_info().rss)
                    t = p.cpu_times()
                    self.cpu[p.pid] = t.user + t.system
                except psutil.Error:
                    pass
            self._stop.wait(self.every)

    def __enter__(self):
        self._thread.start()
        return self

    def __exit__(self, *exc):
        self._stop.set()
        self._thread.join()


def load_text():
    return "load average " + ", ".join(f"{x:.2f}" for x in os.getloadavg())


def run(data, folder, workers, label):
    from pdeface.batch.job import plan_job
    from pdeface.batch.run import run_job

    job = plan_job(data, folder, label)
    print(f"  {label}, {workers} worker(s), {len(job.tasks)} tasks ({load_text()})", flush=True)
    with open(os.devnull, "w") as quiet, PeakMemory() as mem:
        summary = run_job(job, workers=workers, stream=quiet)
    if summary.failed:
        raise SystemExit(f"{label}: {len(summary.failed)} tasks failed: {next(iter(summary.failed.values()))}")
    rate = summary.done / summary.seconds
    peaks = sorted(mem.peak.values(), reverse=True)[:workers]
    cpu = sum(mem.cpu.values())
    print(f"    {summary.seconds:.1f} s, {rate:.3f} tasks/s; peak RSS per worker "
          + ", ".join(f"{p / 2**20:.0f} MB" for p in peaks)
          + f"; workers' CPU {cpu / max(summary.done, 1):.2f} s per task, {cpu / summary.seconds:.2f} cores busy "
          "on average (of the workers': the rest went to other processes)", flush=True)
    return summary, rate, peaks


def compare(data, folder, workers, label):
    _, one, _ = run({**data, "out": "one"}, folder, 1, label)
    _, many, _ = run({**data, "out": f"x{workers}"}, folder, workers, label)
    print(f"  {label}: {workers} workers / 1 worker throughput: {many / one:.2f}x (target >= 1.7x)\n", flush=True)


def main(argv=None):
    ap = bench_parser(__doc__)
    ap.add_argument("--heads", type=int, default=12, help="ICT heads in the rig job")
    ap.add_argument("--makehuman", type=int, default=4, choices=range(len(CHARACTERS) + 1),
                    help="MakeHuman characters added to the rig job")
    ap.add_argument("--images", type=int, default=120, help="images in the 1-vs-2 stimuli job (a multiple of 10)")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--big", action="store_true", help="also the 1,000-image set")
    args = ap.parse_args(argv)
    print(f"{os.cpu_count()} cores; {load_text()} at the start\n")
    with tempfile.TemporaryDirectory(prefix="bench_batch_") as tmp:
        tmp = Path(tmp)
        make_heads(tmp, args.heads)
        characters = make_characters(tmp, args.makehuman)
        compare({"kind": "rig", "meshes": ["ict*.obj", *characters], "landmarks": "{stem}.json"}, tmp, args.workers,
                f"rig job of {args.heads} ICT heads and {len(characters)} MakeHuman characters")
        sets = [[12], [1, 2], [4], [6, 12], [15, 17], [26], [9], [20], [5, 7], [1, 4, 15], [10], [14]]
        n_sets = max(1, args.images // 10)
        compare({"kind": "stimuli", "faces": ["default", "head"], "aus": sets[:n_sets],
                 "intensities": list("ABCDE"), "size": 256}, tmp, args.workers,
                f"stimuli job of {2 * n_sets * 5} images")
        if args.big:
            from pdeface.au.modelfile import load_face

            from pdeface.head.bind import GAZE_AUS

            # Every identity has these keys: the heads the rig job made have no eyeballs, so no gaze keys.
            keys = sorted({d.key for d in load_face("default").descriptors
                           if d.key.isdigit() and int(d.key) not in GAZE_AUS}, key=int)
            singles = [[int(k)] for k in keys]
            pairs = [[int(a), int(b)] for a, b in zip(keys, keys[3:])]
            combos = (singles + pairs)[:50]
            data = {"kind": "stimuli", "faces": ["default", "head", "x2/ict000", "x2/ict001"], "aus": combos,
                    "intensities": list("ABCDE"), "size": 256, "out": "big"}
            summary, rate, peaks = run(data, tmp, args.workers, "the 1,000-image set")
            print(f"  the {summary.done}-image set: {summary.seconds:.0f} s on {args.workers} workers, "
                  f"{rate:.2f} images/s, peak memory per worker "
                  + ", ".join(f"{p / 2**20:.0f} MB" for p in peaks))
    print(f"\n{load_text()} at the end")


if __name__ == "__main__":
    run_bench(main, "batch")
