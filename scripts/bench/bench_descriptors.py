"""Benchmark AU descriptors on the bundled ICT-FaceKit data (issue #3 targets).

Usage: python -m scripts.bench.bench_descriptors [--identities N] [--json OUT]

Prints, measured in this run:
- per AU of the bundled face: captured, p95 error, binary size, against the targets;
- evaluation speed of faces for arbitrary weights of all AUs at the original resolution
  with the precomputed linear operator, against re-solving the PDE per face (the baseline);
- descriptors retargeted to identity000-019: median captured per identity.
"""
from __future__ import annotations

import json
import time
from pathlib import Path

import numpy as np
from pdeface.au.aureport import au_report
from pdeface.au.expressions import ShapeBasis, mix
from pdeface.au.retarget import retarget
from pdeface.facs import au_number
from pdeface.surface.fit import fit_face
from pdeface.surface.grid import surface_grid

from scripts.bench.benchlib import bench_parser, bundled_ict, run_bench

STRICT = {"1", "2", "4", "12", "15"}  # captured >= 0.95
MOUTH_OPENING = {"25", "26", "27"}  # the method's admitted gap: reported, no target


def target_of(key):
    base = str(au_number(key))
    return None if base in MOUTH_OPENING else (0.95 if base in STRICT else 0.90)


def main(argv=None):
    ap = bench_parser(__doc__)
    ap.add_argument("--identities", type=int, default=20)
    ap.add_argument("--json")
    args = ap.parse_args(argv)
    face, V, T, idx, shapes = bundled_ict()
    report = au_report(face, V, T, shapes)
    out = {"aus": {}}
    print("== bundled descriptors (ICT-FaceKit generic neutral)")
    print(f"  {'AU':5s} {'captured':>8s} {'target':>6s} {'p95 mm':>7s} {'bytes':>6s} (target <= 2560)  curves")
    misses = []
    for d in face.descriptors:
        if d.key not in report:  # made from muscles: no ICT truth to measure against (bench_muscles.py)
            continue
        r = report[d.key]
        size = r.pop("bytes")
        t = target_of(d.key)
        cap = r["captured"]
        flag = "" if t is None or cap is None or cap >= t else "  <-- below target"
        if flag:
            misses.append(d.key)
        cap_s = "n/a" if cap is None else f"{cap:.3f}"
        p95_s = "n/a" if r["p95_err_mm"] is None else f"{r['p95_err_mm']:.2f}"
        print(f"  AU{d.key:4s} {cap_s:>8s} {('-' if t is None else t):>6} {p95_s:>7s} {size:6d}  "
              f"{d.curves.min() + 1 if len(d.curves) else '-'}-{d.curves.max() + 1 if len(d.curves) else '-'}{flag}")
        out["aus"][d.key] = {**r, "bytes": size, "target": t}
    print(f"  below target: {', '.join(misses) or 'none'}; largest descriptor "
          f"{max(v['bytes'] for v in out['aus'].values())} bytes")
    print("== evaluation at the original resolution (10,1), all AUs, sum mixer")
    basis = ShapeBasis(face, "original")
    rng = np.random.default_rng(0)
    W = rng.random((20000, len(basis.keys))).astype(np.float32)
    batch = 250
    buf = np.empty((batch, basis.neutral_flat.size), np.float32)
    basis.vertices(W[:batch], buf)
    t = time.perf_counter()
    for i in range(0, len(W), batch):
        basis.vertices(W[i:i + batch], buf)
    fps = len(W) / (time.perf_counter() - t)
    ds = {d.key: d for d in face.descriptors}
    surface_grid(face, 10, 1)
    t = time.perf_counter()
    for w in W[:50]:
        dC, dR = mix(ds, dict(zip(basis.keys, w)))
        surface_grid(face, 10, 1, coefficients=face.coefficients + dC, residual=face.residual + dR)
    fps_solve = 50 / (time.perf_counter() - t)
    print(f"  linear operator {fps:,.0f} faces/s ({basis.deltas.shape[1] // 3} vertices, {len(basis.keys)} AUs; "
          f"target >= 10,000, ratio {fps / 10000:.2f}); mix + PDE solve per face {fps_solve:,.0f} faces/s "
          f"(operator is {fps / fps_solve:.0f}x faster)")
    out["faces_per_s"], out["faces_per_s_solve"] = fps, fps_solve
    if args.identities:
        print(f"== retargeted to identity000-{args.identities - 1:03d} (scaled by face size; "
              f"beside it without the gap rule, pdeface.au.retarget.narrowed)")
        medians, plain, worst, worst_plain = [], [], [], []
        for i in range(args.identities):
            Vi = V + shapes[f"identity{i:03d}"]
            target, _ = fit_face(Vi, T, Vi[idx], unit="cm")
            for spacing, meds, mins in ((True, medians, worst), (False, plain, worst_plain)):
                caps = [r["captured"] for r in au_report(retarget(face, target, spacing=spacing), Vi, T,
                                                         shapes).values() if r["captured"] is not None]
                meds.append(float(np.median(caps)))
                mins.append(float(min(caps)))
        print(f"  median captured per identity: min {min(medians):.3f}, median {np.median(medians):.3f}, "
              f"max {max(medians):.3f} (target median >= 0.90); without the gap rule "
              f"{min(plain):.3f}, {np.median(plain):.3f}, {max(plain):.3f}")
        print(f"  worst AU per identity: min {min(worst):.3f}, median {np.median(worst):.3f}; "
              f"without the gap rule {min(worst_plain):.3f}, {np.median(worst_plain):.3f}")
        out["retarget_medians"], out["retarget_medians_plain"] = medians, plain
        out["retarget_worst"], out["retarget_worst_plain"] = worst, worst_plain
    if args.json:
        Path(args.json).write_text(json.dumps(out, indent=2))


if __name__ == "__main__":
    run_bench(main, "descriptors")
