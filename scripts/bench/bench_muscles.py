"""Benchmark the muscle AUs (issue #19 targets).

Usage: python -m scripts.bench.bench_muscles [--identities 20] [--json OUT]

Prints, measured in this run:
- per AU key ICT covers: captured (as in au-report) of the muscle table's AU on the bundled face,
  beside the scan descriptor's; the median against the target 0.75; and, for comparison, Waters'
  fields alone (no learned corrections), each AU's activations calibrated on them in this run;
- the same table on identity000-019 (each fitted, its muscles placed from its own landmarks, no
  recalibration): median captured per identity, against the target 0.70;
- what the muscle-only AUs (13, 23, 38, 39, 46) move on the default face;
- time of one AU → descriptor (the face's muscles placed once), against the target 5 ms.
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
from pdeface.au.aureport import MotionProbe
from pdeface.au.ict import AU_SHAPES, au_offsets
from pdeface.muscles.aus import AUTHORED, MuscleBasis, MuscleTable, load_table
from pdeface.surface.fit import fit_face
from pdeface.surface.grid import surface_grid
from pdeface.surface.model import model_landmarks

from scripts.bench.benchlib import bench_parser, bundled_ict, median_time, run_bench
from scripts.build.build_muscles import curve_motion, recipe_text


def captured(face, V, T, shapes, table, keys):
    basis = MuscleBasis(face, table)
    assert basis.learned == (table.fields is not None)
    probe = MotionProbe(face, V, T)
    return {k: probe.measure(*basis.descriptor(k, table.activations[k]).dense(), au_offsets(k, shapes))["captured"]
            for k in keys}


def waters_alone(face, table):
    """The table's muscle shapes without learned fields, each AU calibrated on them (as before #19's fields)."""
    basis = MuscleBasis(face, MuscleTable({}, geometry=table.geometry))
    acts = {d.key: basis.calibrate(curve_motion(face, d)) for d in face.descriptors if d.source != "muscle"}
    return MuscleTable(acts, geometry=table.geometry)


def main(argv=None):
    ap = bench_parser(__doc__)
    ap.add_argument("--identities", type=int, default=20)
    ap.add_argument("--json")
    args = ap.parse_args(argv)
    face, V, T, idx, shapes = bundled_ict()
    table = load_table()
    keys = [k for k in table.activations if k in AU_SHAPES]
    mine = captured(face, V, T, shapes, table, keys)
    probe = MotionProbe(face, V, T)
    scan = {d.key: probe.measure(*d.dense(), au_offsets(d.key, shapes))["captured"] for d in face.descriptors
            if d.key in AU_SHAPES}
    plain = captured(face, V, T, shapes, waters_alone(face, table), keys)
    print("== muscle AUs (the table, learned fields) on the bundled face, against ICT truth; Waters' fields "
          "alone and the scan descriptor beside")
    both = [k for k in keys if not k.endswith(("L", "R"))]
    print("  " + "  ".join(f"AU{k} {mine[k]:.2f} ({plain[k]:.2f}, {scan[k]:.2f})" for k in both))
    med = float(np.median([v for v in mine.values() if v is not None]))
    print(f"  median over {len(keys)} AU keys: {med:.3f} (target >= 0.75); Waters' fields alone "
          f"{np.median(list(plain.values())):.3f}; scan descriptors {np.median([scan[k] for k in keys]):.3f}")
    worst = sorted(keys, key=mine.get)[:8]
    print("  worst: " + ", ".join(f"AU{k} {mine[k]:.2f}" for k in worst))
    out = {"bundled": mine, "median": med, "waters_alone": plain}
    if args.identities:
        medians = []
        for i in range(args.identities):
            Vi = V + shapes[f"identity{i:03d}"]
            fi, _ = fit_face(Vi, T, Vi[idx], unit="cm")
            caps = captured(fi, Vi, T, shapes, table, keys)
            medians.append(float(np.median([v for v in caps.values() if v is not None])))
        print(f"== the same table on identity000-{args.identities - 1:03d} (no recalibration): median captured per "
              f"identity min {min(medians):.3f}, median {np.median(medians):.3f}, max {max(medians):.3f} "
              f"(target median >= 0.70)")
        out["identities"] = medians
    print("== the muscle-only AUs on the default face (largest motion of the PDE surface, and where)")
    L = model_landmarks(face)
    X0 = surface_grid(face, 4, 4).reshape(-1, 3)
    named = {48: "right mouth corner", 54: "left mouth corner", 51: "upper lip", 57: "lower lip", 31: "right nose wing",
             35: "left nose wing", 37: "right upper lid", 44: "left upper lid", 41: "right lower lid", 8: "chin"}
    motion = {}
    for k in ("13", "23", "38", "39", "46"):
        d = next(d for d in face.descriptors if d.key == k)
        C, R = d.dense()
        D = surface_grid(face, 4, 4, coefficients=face.coefficients + C, residual=face.residual + R).reshape(-1, 3) - X0
        at = {name: D[np.argmin(np.linalg.norm(X0 - L[i], axis=1))] for i, name in named.items()}
        top = sorted(at.items(), key=lambda kv: -np.linalg.norm(kv[1]))[:3]
        motion[k] = {n: [round(float(x), 2) for x in v] for n, v in top}
        print(f"  AU{k} ({recipe_text(AUTHORED[k])}): max "
              f"{np.linalg.norm(D, axis=1).max():.1f} mm; " + "; ".join(
                  f"{n} ({v[0]:+.1f}, {v[1]:+.1f}, {v[2]:+.1f}) mm" for n, v in top))
    out["motion"] = motion
    basis = MuscleBasis(face, table)
    t_desc = median_time(lambda: basis.descriptor("12", table.activations["12"]), 21)
    t_place = median_time(lambda: MuscleBasis(face, table), 5)
    print(f"== one muscle AU → descriptor {t_desc * 1e3:.2f} ms (target <= 5 ms, ratio {t_desc / 5e-3:.2f}); "
          f"placing the face's 24 muscles once {t_place * 1e3:.1f} ms")
    out["descriptor_ms"], out["place_ms"] = t_desc * 1e3, t_place * 1e3
    if args.json:
        Path(args.json).write_text(json.dumps(out, indent=1))


if __name__ == "__main__":
    run_bench(main, "muscles")
