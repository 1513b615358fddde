"""Benchmark the whole-head binding on ICT-FaceKit's heads (issue #14 targets).

Usage: python scripts/bench_head.py [--identities N] [--json OUT]

For the generic head and identities 000-(N-1) (bundled, full heads, 26,719
vertices): fit the PDE face on the head, retarget the bundled descriptors,
bind the head, and compare every AU key with the truth, identity + (ICT
expression − ICT neutral), over every vertex:

- captured over **all** face-region vertices (0-9408) moving > 0.5 mm, hidden or not;
- captured over the whole head (teeth, eyeballs, lashes, mouth and eye sockets);
- beside them, captured over the skin the PDE face covers (the subset the method is strong on);
- spill: the 99th percentile of the motion of vertices whose true motion is < 0.1 mm;
- time to bind and build all keys, as a ratio to the fit of the same head (measured in this run).

Targets: face region median over AUs >= 0.92 and every AU >= 0.80; whole head median
>= 0.85; spill p99 < 0.3 mm.
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "core"))

from pdeface.assets import load_face, load_head, load_head_shapes  # noqa: E402
from pdeface.au.ict import AU_SHAPES, FACE_VERTICES, au_offsets  # noqa: E402
from pdeface.au.retarget import retarget  # noqa: E402
from pdeface.head.bind import HeadBinding  # noqa: E402
from pdeface.head.report import head_report  # noqa: E402
from pdeface.surface.fit import fit_face  # noqa: E402

REGIONS = ("face", "head", "covered")


def measure(V, T, lm, shapes, source):
    t = time.perf_counter()
    model, _ = fit_face(V, T, V[lm], unit="cm")
    t_fit = time.perf_counter() - t
    model = retarget(source, model)
    t = time.perf_counter()
    b = HeadBinding(model, V, T)
    keys = [b.descriptor_displacement(d) for d in model.descriptors]
    t_bind = time.perf_counter() - t
    face = np.zeros(len(V), bool)
    face[:FACE_VERTICES] = True
    covered = np.zeros(len(V), bool)
    covered[b.skin[b.covered]] = True
    truth = {k: au_offsets(k, shapes) for k in AU_SHAPES}
    rep = head_report(b, truth, {"face": face, "head": np.ones(len(V), bool), "covered": covered & face})
    return rep, t_fit, t_bind, len(keys), b


def summary(rep):
    s = {}
    for r in REGIONS:
        vals = {k: v[r] for k, v in rep.items() if v[r] is not None}
        worst = min(vals, key=vals.get)
        s[r] = {"median": float(np.median(list(vals.values()))), "min": vals[worst], "worst": worst}
    spills = [v["spill_p99_mm"] for v in rep.values()]
    s["spill"] = {"median": float(np.median(spills)), "max": float(max(spills))}
    return s


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--identities", type=int, default=20)
    ap.add_argument("--json")
    args = ap.parse_args(argv)
    source = load_face("default")
    head, lm = load_head()
    T, _ = head.triangles()
    shapes = load_head_shapes()
    out = {}
    print("== generic head: every AU key against ICT-FaceKit (captured; spill = p99 mm of still vertices)")
    rep, t_fit, t_bind, n_keys, b = measure(head.vertices, T, lm, shapes, source)
    print("  " + "; ".join(b.notes))
    print(f"  {'AU':5s} {'face':>6s} {'head':>6s} {'covered':>7s} {'spill':>6s}   (face/head: all vertices moving "
          "> 0.5 mm; covered: the PDE face's own skin)")
    fmt = lambda x: "   n/a" if x is None else f"{x:6.3f}"  # noqa: E731
    for k, v in rep.items():
        print(f"  AU{k:4s} {fmt(v['face'])} {fmt(v['head'])}  {fmt(v['covered'])} {v['spill_p99_mm']:6.2f}")
    s = summary(rep)
    for r in REGIONS:
        print(f"  {r:8s} median {s[r]['median']:.3f}, worst AU{s[r]['worst']} {s[r]['min']:.3f}")
    print(f"  spill p99: median {s['spill']['median']:.2f} mm, max {s['spill']['max']:.2f} mm (target < 0.3)")
    print(f"  bind + {n_keys} keys {t_bind:.2f} s for {len(head.vertices)} vertices; "
          f"ratio to fitting the same head ({t_fit:.2f} s): {t_bind / t_fit:.2f}")
    out["generic"] = {"aus": rep, "summary": s, "bind_and_keys_s": t_bind, "fit_s": t_fit}
    if args.identities:
        print(f"== identity000-{args.identities - 1:03d} (fit on each head, bundled descriptors retargeted)")
        rows = []
        for i in range(args.identities):
            Vi = head.vertices + shapes[f"identity{i:03d}"]
            rep_i, _, t_b, _, _ = measure(Vi, T, lm, shapes, source)
            si = summary(rep_i)
            rows.append(si)
            print(f"  identity{i:03d}: face median {si['face']['median']:.3f} (worst AU{si['face']['worst']} "
                  f"{si['face']['min']:.3f}), head median {si['head']['median']:.3f}, covered median "
                  f"{si['covered']['median']:.3f}, spill max {si['spill']['max']:.2f} mm, bind+keys {t_b:.2f} s")
        for r in REGIONS:
            med = [x[r]["median"] for x in rows]
            print(f"  {r:8s} median of medians {np.median(med):.3f}, worst identity {min(med):.3f}; "
                  f"worst AU anywhere {min(x[r]['min'] for x in rows):.3f}")
        out["identities"] = rows
    if args.json:
        Path(args.json).write_text(json.dumps(out, indent=2))


if __name__ == "__main__":
    main()
