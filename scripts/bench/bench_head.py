"""Benchmark the whole-head binding on ICT-FaceKit's heads (issue #14 targets).

Usage: python -m scripts.bench.bench_head [--identities N] [--json OUT]

For the generic head and identities 000-(N-1) (bundled, full heads, 26,719
vertices): fit the PDE face on the head, retarget the bundled descriptors,
bind the head, and compare every AU key with the truth, identity + (ICT
expression − ICT neutral), over every vertex:

- captured over **all** face-region vertices (0-9408) moving > 0.5 mm, hidden or not;
- captured over the whole head (teeth, eyeballs, lashes, mouth and eye sockets);
- beside them, captured over the skin the PDE face covers (the subset the method is strong on);
- spill: the 99th percentile of the motion of vertices whose true motion is < 0.1 mm;
- time to bind and build all keys, as a ratio to the fit of the same head (measured in this run).

Each figure three ways: with the bundled head prior (:mod:`pdeface.head.prior`, learned on the
generic head from the same AUs: what a user of the bundled keys gets); **held out**: each AU with
its own samples (both sides) left out of the prior, as an AU the prior never saw (a muscle AU,
the user's own scan) fares; and without the prior (the PDE face and its harmonic extension).
Then the same on another topology: the generic head remeshed by clustering each of its pieces on
a ``--cell`` mm grid (truth: the mean of each cluster's vertices).

Targets: face region median over AUs >= 0.92 and every AU >= 0.80; whole head median
>= 0.85; spill p99 < 0.3 mm.
"""
from __future__ import annotations

import json
import time
from pathlib import Path

import numpy as np
from pdeface.assets import load_head, load_head_shapes
from pdeface.au.ict import AU_SHAPES, FACE_VERTICES, au_offsets
from pdeface.au.modelfile import load_face
from pdeface.au.retarget import retarget
from pdeface.facs import au_number
from pdeface.head.bind import HeadBinding
from pdeface.head.prior import load_head_prior
from pdeface.head.report import head_report
from pdeface.surface.fit import fit_face

from scripts.bench.benchlib import bench_parser, run_bench

REGIONS = ("face", "head", "covered")
WAYS = ("prior", "held out", "no prior")


def measure(V, T, lm, truth, face, source):
    """Per-AU reports of one head, the three ways; fit and bind+keys times; the binding."""
    t = time.perf_counter()
    model, _ = fit_face(V, T, V[lm], unit="cm")
    t_fit = time.perf_counter() - t
    model = retarget(source, model)
    t = time.perf_counter()
    b = HeadBinding(model, V, T)
    keys = b.descriptor_displacements(model.descriptors)
    t_bind = time.perf_counter() - t
    covered = np.zeros(len(V), bool)
    covered[b.skin[b.covered]] = True
    regions = {"face": face, "head": np.ones(len(V), bool), "covered": covered & face}
    reps = {"prior": head_report(b, truth, regions)}
    on_head, prior = b.prior, load_head_prior()
    held = {}
    for group in sorted({au_number(k) for k in prior.keys}):
        left_out = [k for k in prior.keys if au_number(k) == group]
        b.prior = on_head.leaving_out(prior, left_out)
        held.update(head_report(b, {k: truth[k] for k in left_out if k in truth}, regions))
    reps["held out"] = held
    b.prior = None
    reps["no prior"] = head_report(b, truth, regions)
    b.prior = on_head
    return reps, t_fit, t_bind, len(keys), b


def per_part_clustered(V, T, cell):
    """``V, T`` remeshed by clustering each connected piece on a grid of ``cell``: (vertices, triangles,
    the cluster of each original vertex)."""
    from pdeface.mesh import connected_components

    key = np.c_[np.floor(V / cell).astype(np.int64), connected_components(len(V), T)]
    _, inv, counts = np.unique(key, axis=0, return_inverse=True, return_counts=True)
    inv = inv.ravel()
    Vc = np.zeros((len(counts), 3))
    np.add.at(Vc, inv, V)
    Tc = inv[T]
    Tc = np.unique(Tc[(Tc[:, 0] != Tc[:, 1]) & (Tc[:, 1] != Tc[:, 2]) & (Tc[:, 0] != Tc[:, 2])], axis=0)
    return Vc / counts[:, None], Tc, inv


def summary(rep):
    s = {}
    for r in REGIONS:
        vals = {k: v[r] for k, v in rep.items() if v[r] is not None}
        worst = min(vals, key=vals.get)
        s[r] = {"median": float(np.median(list(vals.values()))), "min": vals[worst], "worst": worst}
    spills = [v["spill_p99_mm"] for v in rep.values()]
    s["spill"] = {"median": float(np.median(spills)), "max": float(max(spills))}
    return s


def print_summaries(reps, indent="  "):
    for way, rep in reps.items():
        s = summary(rep)
        print(f"{indent}{way:9s} face median {s['face']['median']:.3f} (worst AU{s['face']['worst']} "
              f"{s['face']['min']:.3f}), head median {s['head']['median']:.3f}, covered median "
              f"{s['covered']['median']:.3f}, spill p99 median {s['spill']['median']:.2f} mm (max "
              f"{s['spill']['max']:.2f})")


def main(argv=None):
    ap = bench_parser(__doc__)
    ap.add_argument("--identities", type=int, default=20)
    ap.add_argument("--cell", type=float, default=3.0, help="grid of the remeshed head (mm); 0: skip it")
    ap.add_argument("--json")
    args = ap.parse_args(argv)
    source = load_face("default")
    head, lm = load_head()
    T, _ = head.triangles()
    shapes = load_head_shapes()
    truth = {k: au_offsets(k, shapes) for k in AU_SHAPES}
    face = np.zeros(len(head.vertices), bool)
    face[:FACE_VERTICES] = True
    out = {}
    print("== generic head: every AU key against ICT-FaceKit (captured; spill = p99 mm of still vertices)")
    reps, t_fit, t_bind, n_keys, b = measure(head.vertices, T, lm, truth, face, source)
    print("  " + "; ".join(b.notes))
    print(f"  {'AU':5s} {'face':>6s} {'head':>6s} {'covered':>7s} {'spill':>6s} | held out: {'face':>6s} {'head':>6s} "
          f"{'spill':>6s} | no prior: {'face':>6s} {'head':>6s}")
    fmt = lambda x: "   n/a" if x is None else f"{x:6.3f}"  # noqa: E731
    for k, v in reps["prior"].items():
        h, n = reps["held out"][k], reps["no prior"][k]
        print(f"  AU{k:4s} {fmt(v['face'])} {fmt(v['head'])}  {fmt(v['covered'])} {v['spill_p99_mm']:6.2f} |"
              f"           {fmt(h['face'])} {fmt(h['head'])} {h['spill_p99_mm']:6.2f} |           "
              f"{fmt(n['face'])} {fmt(n['head'])}")
    print_summaries(reps)
    print(f"  bind + {n_keys} keys {t_bind:.2f} s for {len(head.vertices)} vertices; "
          f"ratio to fitting the same head ({t_fit:.2f} s): {t_bind / t_fit:.2f}")
    out["generic"] = {"aus": reps, "summary": {w: summary(r) for w, r in reps.items()}, "bind_and_keys_s": t_bind,
                      "fit_s": t_fit}
    if args.identities:
        print(f"== identity000-{args.identities - 1:03d} (fit on each head, bundled descriptors retargeted)")
        rows = []
        for i in range(args.identities):
            Vi = head.vertices + shapes[f"identity{i:03d}"]
            reps_i, _, t_b, _, _ = measure(Vi, T, lm, truth, face, source)
            rows.append({w: summary(r) for w, r in reps_i.items()})
            print(f"  identity{i:03d} (bind + keys {t_b:.2f} s)")
            print_summaries(reps_i, "    ")
        learned = set(load_head_prior().identities)
        groups = {"all": list(range(len(rows))), "unseen": [i for i in range(len(rows)) if i not in learned],
                  "learned": [i for i in range(len(rows)) if i in learned]}
        print(f"  (the prior learned from the generic head and identities {sorted(learned)}: 'unseen' are the others)")
        for label, members in groups.items():
            if not members:
                continue
            print(f"  -- {label} identities ({len(members)})")
            for way in WAYS:
                for r in REGIONS:
                    med = [rows[i][way][r]["median"] for i in members]
                    print(f"  {way:9s} {r:8s} median of medians {np.median(med):.3f} (min-max {min(med):.3f}-"
                          f"{max(med):.3f}); worst AU anywhere {min(rows[i][way][r]['min'] for i in members):.3f}")
                sp = [rows[i][way]["spill"]["median"] for i in members]
                print(f"  {way:9s} spill    median of medians {np.median(sp):.2f} mm, largest anywhere "
                      f"{max(rows[i][way]['spill']['max'] for i in members):.2f} mm")
        out["identities"] = rows
    if args.cell:
        Vc, Tc, cluster = per_part_clustered(head.vertices, T, args.cell / 10.0)
        counts = np.bincount(cluster)

        def mean_over_clusters(a):
            m = np.zeros((len(counts), a.shape[1]))
            np.add.at(m, cluster, a)
            return m / counts[:, None]

        face_c = mean_over_clusters(face[:, None].astype(float))[:, 0] > 0.5
        print(f"== another topology: the generic head's pieces clustered on a {args.cell:g} mm grid ({len(Vc)} "
              f"vertices, {len(Tc)} triangles)")
        reps_c, _, t_b, _, _ = measure(Vc, Tc, cluster[lm], {k: mean_over_clusters(v) for k, v in truth.items()},
                                       face_c, source)
        print_summaries(reps_c)
        out["remeshed"] = {w: summary(r) for w, r in reps_c.items()}
    if args.json:
        Path(args.json).write_text(json.dumps(out, indent=2))


if __name__ == "__main__":
    run_bench(main, "head")
