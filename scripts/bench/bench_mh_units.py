"""Our AU keys against MakeHuman's own expression units on the development set (issue #40 target).

Usage: python -m scripts.bench.bench_mh_units [--only NAME,...] [--json OUT]

MakeHuman's expression units (``targets/expression/units/<race>/``) were made by its artists on the same
mesh as every development character: an independent reference for what a movement looks like on this
topology (not FACS-coded, not scans). For each character of ``scripts.devset.characters.SPECS`` that keeps
the base's topology (not remeshed), the character is rigged as ``bench_keys_devset`` does (true landmarks,
``fit_face``, the bundled descriptors retargeted, the model read back from its file's bytes,
:class:`pdeface.head.bind.HeadBinding`), and each pair
below is compared over **every vertex of the character** (face, head and, on bodies, the body):

=================  ==================================================
our pose           MakeHuman's units (both sides, weight 1)
=================  ==================================================
AU45               eye-left-closure + eye-right-closure
AU27, AU26         mouth-open
AU12               mouth-corner-puller
AU1+AU2            eyebrows-left-up + eyebrows-right-up
AU1                eyebrows-left-inner-up + eyebrows-right-inner-up
AU4                eyebrows-left-down + eyebrows-right-down
=================  ==================================================

Printed per pair: **field cosine** (the two displacement fields as vectors: 1 = same direction
everywhere, whatever the magnitude), **captured** ``1 − RMS(ours − theirs) / RMS(theirs)`` (aureport's),
**gain** (the weight of their unit that best matches ours: ``<ours, theirs> / |theirs|²``), and for the eye
closure the **lid travel**: our upper-lid middles' motion over theirs, and (target ≥ 0.80) over the travel
that closes the eye: theirs, but no more than the rest gap between the upper and lower lid middles
(MakeHuman's unit is one fixed 8.9 mm motion made for the base's 7.9 mm gap: on narrower eyes it takes the
upper lid 3 mm through the lower one). The units are MakeHuman's race-specific ones (the character's first
identity's race; caucasian for the base).
"""
from __future__ import annotations

import json

import numpy as np
from pdeface.au.aureport import captured
from pdeface.au.modelfile import load_face
from pdeface.errors import PdeFaceError
from pdeface.landmark_scheme import LOWER_LIDS, UPPER_LIDS

from scripts.bench.bench_keys_devset import bound
from scripts.bench.benchlib import bench_parser, run_bench
from scripts.devset.characters import SPECS, build, race_of

#: Our pose (AU weights) → MakeHuman's units (file stems under expression/units/<race>/).
PAIRS = {
    "AU45": ({"45": 1.0}, ("eye-left-closure", "eye-right-closure")),
    "AU27": ({"27": 1.0}, ("mouth-open",)),
    "AU26": ({"26": 1.0}, ("mouth-open",)),
    "AU12": ({"12": 1.0}, ("mouth-corner-puller",)),
    "AU1+2": ({"1": 1.0, "2": 1.0}, ("eyebrows-left-up", "eyebrows-right-up")),
    "AU1": ({"1": 1.0}, ("eyebrows-left-inner-up", "eyebrows-right-inner-up")),
    "AU4": ({"4": 1.0}, ("eyebrows-left-down", "eyebrows-right-down")),
}
LID_TRAVEL_TARGET = 0.80


def unit_field(spec, units, neutral):
    """MakeHuman's units on ``spec``'s character: its displacement (character unit and axes), or None where
    the units change which vertices the character keeps."""
    from dataclasses import replace

    race = race_of(spec)
    # A character with parted lips is already mouth-open at its spec's weight: the unit adds 1 to it.
    opened = spec.mouth_open + ("mouth-open" in units)
    style = dict(spec.style) | {f"expression/units/{race}/{u}": 1.0 for u in units if u != "mouth-open"}
    moved = build(replace(spec, style=style, mouth_open=opened))
    if moved.vertices.shape != neutral.vertices.shape or not np.array_equal(moved.triangles, neutral.triangles):
        return None
    return moved.vertices - neutral.vertices


def compare(ours, theirs, mm_per_unit, lid_vertices=None) -> dict:
    """The figures of one pair (every vertex)."""
    o, t = ours.ravel(), theirs.ravel()
    cos = float(o @ t / (np.linalg.norm(o) * np.linalg.norm(t) + 1e-30))
    out = {"cosine": cos, "captured": captured(ours, theirs), "gain": float(o @ t / (t @ t + 1e-30)),
           "ours_max_mm": float(np.linalg.norm(ours, axis=1).max() * mm_per_unit),
           "theirs_max_mm": float(np.linalg.norm(theirs, axis=1).max() * mm_per_unit)}
    if lid_vertices is not None:
        upper, gap = lid_vertices
        travel = lambda D: np.linalg.norm(D[upper], axis=1).mean()
        out["lid_travel"] = float(travel(ours) / travel(theirs))
        out["closing_travel"] = float(travel(ours) / min(travel(theirs), gap))
    return out


def measure(spec, source) -> dict:
    ch = build(spec)
    V, T, L = ch.vertices, ch.triangles, ch.landmarks
    model, b = bound(V, T, L, source)
    keys = {d.key for d in model.descriptors}
    names = [n for n, (w, _) in PAIRS.items() if set(w) <= keys]
    D = b.pose_displacements([(PAIRS[n][0], "sum") for n in names])
    nearest = lambda idx: np.array([np.argmin(np.linalg.norm(V - L[i], axis=1)) for i in idx])
    upper = nearest(UPPER_LIDS)
    lids = upper, float(np.linalg.norm(V[upper] - V[nearest(LOWER_LIDS)], axis=1).mean())
    out = {}
    for n, ours in zip(names, D):
        theirs = unit_field(spec, PAIRS[n][1], ch)
        if theirs is None:
            out[n] = {"skipped": "the unit changes the character's vertices"}
            continue
        out[n] = compare(ours, theirs, ch.mm_per_unit, lids if n == "AU45" else None)
    return out


def main(argv=None):
    ap = bench_parser(__doc__)
    ap.add_argument("--only", help="comma-separated character names")
    ap.add_argument("--json")
    args = ap.parse_args(argv)
    names = args.only.split(",") if args.only else [n for n, s in SPECS.items() if s.remesh == "none"]
    source = load_face("default")
    print(f"== {len(names)} characters (not remeshed), true landmarks; every vertex of each; "
          "cos: field cosine, cap: captured, gain: their unit's best-matching weight")
    print(f"  {'character':30s} " + " ".join(f"{n:>17s}" for n in PAIRS) + "  AU45 lid travel, to closing")
    rows = {}
    for name in names:
        try:
            r = measure(SPECS[name], source)
        except PdeFaceError as exc:
            rows[name] = {"error": str(exc)}
            print(f"  {name:30s} REFUSED: {exc}", flush=True)
            continue
        rows[name] = r
        cells = [f"{r[n]['cosine']:5.2f} {r[n]['captured']:5.2f} {r[n]['gain']:5.2f}" if "cosine" in r.get(n, {})
                 else f"{'-':>17s}" for n in PAIRS]
        lid, closing = (r.get("AU45", {}).get(k) for k in ("lid_travel", "closing_travel"))
        print(f"  {name:30s} " + " ".join(cells) + (f"  {lid:5.2f} {closing:5.2f}" if lid is not None else "  -"),
              flush=True)
    done = [r for r in rows.values() if "error" not in r]
    print("== summary (median over characters; cos / captured / gain)")
    for n in PAIRS:
        vals = [r[n] for r in done if "cosine" in r.get(n, {})]
        if vals:
            med = lambda k, vals=vals: float(np.median([v[k] for v in vals]))
            print(f"  {n:6s} vs {' + '.join(PAIRS[n][1]):50s} cos {med('cosine'):5.2f}  captured "
                  f"{med('captured'):5.2f}  gain {med('gain'):5.2f}  max motion ours {med('ours_max_mm'):5.1f} mm, "
                  f"theirs {med('theirs_max_mm'):5.1f} mm ({len(vals)} characters)")
    lids = [r["AU45"]["lid_travel"] for r in done if "lid_travel" in r.get("AU45", {})]
    closing = [r["AU45"]["closing_travel"] for r in done if "closing_travel" in r.get("AU45", {})]
    if lids:
        ok = sum(x >= LID_TRAVEL_TARGET for x in closing)
        print(f"  AU45 lid travel against the eye closure: median {np.median(lids):.2f}, worst {min(lids):.2f}; "
              f"against its travel up to the rest gap: median {np.median(closing):.2f}, worst {min(closing):.2f}, "
              f">= {LID_TRAVEL_TARGET:.2f} on {ok}/{len(closing)} (target: every character)")
    if args.json:
        with open(args.json, "w") as fh:
            json.dump(rows, fh, indent=1)
    return rows


if __name__ == "__main__":
    run_bench(main, "mh_units")
