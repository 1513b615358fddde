"""The unit estimated from the face's size where it snaps to no named unit (issue #39: within 10 % on every character).

Usage: python -m scripts.bench.bench_units [--found] [--json OUT]

The estimate (:func:`pdeface.surface.frame.estimate_mm_per_unit`) does not depend on the scale: at 0.01 or 100,000 mm
per unit (where none of mm, cm, dm, m, in lies within 30 %, so the estimate is the unit) its error is the
error measured here, ``estimate / true mm per unit - 1``. On ICT-FaceKit's 21 heads (true: 10 mm per unit), the
development set's 24 characters and bench_gate's 8 held out (MakeHuman's, each in its own unit), from their true
landmarks and, with ``--found``, the landmarks the detector finds (as ``bench_devset`` does: slower). Beside it the
estimate before issue #39's change (:data:`BEFORE`: the median over five sizes at ICT's sizes scaled to 63 mm
between the eyes).
"""
from __future__ import annotations

import contextlib
import json

import numpy as np
from pdeface.assets import load_head, load_head_shapes
from pdeface.landmark_scheme import EYE_LEFT, EYE_RIGHT, NOSE_BRIDGE_TOP
from pdeface.surface.frame import estimate_mm_per_unit

from scripts.bench.bench_gate import HELD_OUT
from scripts.bench.benchlib import bench_parser, run_bench
from scripts.devset.annotate import annotate_shape, ict_face, makehuman_head
from scripts.devset.characters import SPECS, build, shape

#: The estimate before: the median over these sizes (landmark groups whose means are measured apart, mm).
BEFORE = [(list(EYE_RIGHT), list(EYE_LEFT), 63.0), ([*EYE_RIGHT, *EYE_LEFT], [48, 51, 54, 57], 68.9),
          ([NOSE_BRIDGE_TOP], [33], 48.4), ([48], [54], 48.9), ([36], [45], 86.3)]


def before_mm_per_unit(L) -> float:
    return float(np.median([mm / np.linalg.norm(L[a].mean(0) - L[b].mean(0)) for a, b, mm in BEFORE]))


def heads():
    """``(family, name, vertices, triangles, true landmarks, true mm per unit)`` of every head measured."""
    mesh, lm = load_head()
    T, shapes = mesh.triangles()[0], load_head_shapes()
    for i in range(-1, 20):
        V = mesh.vertices + (shapes[f"identity{i:03d}"] if i >= 0 else 0)
        yield "ICT", "neutral" if i < 0 else f"identity{i:03d}", V, T, V[lm], 10.0
    for name, spec in SPECS.items():
        ch = build(spec)
        yield "devset", name, ch.vertices, ch.triangles, ch.landmarks, ch.mm_per_unit
    Vs, Ts, Ls, _ = ict_face()
    _, Tt, head = makehuman_head()
    Th = Tt[head[Tt].all(1)]
    for spec in HELD_OUT:
        ch = build(spec, own=annotate_shape(shape(spec), Vs, Ts, Ls, Th))
        yield "held out", spec.name, ch.vertices, ch.triangles, ch.landmarks, ch.mm_per_unit


def main(argv=None):
    ap = bench_parser(__doc__)
    ap.add_argument("--found", action="store_true", help="also from the landmarks the detector finds")
    ap.add_argument("--json")
    args = ap.parse_args(argv)
    if args.found:
        from pdeface.landmarks.detector import Detector
        from pdeface.landmarks.headfind import detect_anywhere
    rows = []
    print("== error of the unit estimated from the face (estimate / true mm per unit - 1, %): before / now, from the "
          "true landmarks" + (" and the found ones" if args.found else ""))
    print(f"  {'family':9s} {'character':40s} {'true':>15s}" + (f" {'found':>15s}" if args.found else ""))
    with Detector() if args.found else contextlib.nullcontext() as detector:
        for family, name, V, T, L, mm in heads():
            r = {"family": family, "name": name, "true": [100 * (f(L) / mm - 1)
                                                          for f in (before_mm_per_unit, estimate_mm_per_unit)]}
            line = f"  {family:9s} {name:40s} {r['true'][0]:+6.1f} / {r['true'][1]:+6.1f}"
            if detector is not None:
                P = detect_anywhere(V, T, detector=detector).points
                r["found"] = [100 * (f(P) / mm - 1) for f in (before_mm_per_unit, estimate_mm_per_unit)]
                line += f" {r['found'][0]:+6.1f} / {r['found'][1]:+6.1f}"
            rows.append(r)
            print(line, flush=True)
    print("== per family: worst |error| and median error (%), before / now")
    for family in dict.fromkeys(r["family"] for r in rows):
        for kind in ("true", "found") if args.found else ("true",):
            E = np.array([r[kind] for r in rows if r["family"] == family])
            print(f"  {family:9s} {kind:5s} landmarks: worst {abs(E[:, 0]).max():4.1f} / {abs(E[:, 1]).max():4.1f}, "
                  f"median {np.median(E[:, 0]):+5.1f} / {np.median(E[:, 1]):+5.1f}; within 10 %: "
                  f"{(abs(E[:, 0]) <= 10).sum()} / {(abs(E[:, 1]) <= 10).sum()} of {len(E)}")
    if args.json:
        with open(args.json, "w") as f:
            json.dump(rows, f, indent=1)


if __name__ == "__main__":
    run_bench(main, "units")
