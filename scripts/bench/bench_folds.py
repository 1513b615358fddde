"""Count the folds of PDE face meshes (issue #16's figure), at rest and in every AU and preset.

Usage: python -m scripts.bench.bench_folds [--identities N] [--resolution default] [--json OUT]

``--resolution 4,4`` measures the even 4-step mesh the default was before it adapted to each face
(:mod:`pdeface.surface.sampling`).

A fold is a mesh edge of ``pdeface mesh``'s output whose two faces turn by more than 30°
outside the eye, mouth and nostril openings (landmark polygons grown by a third, at rest and where
a pose moves them;
:mod:`pdeface.surface.folds`). Target (issue #16): 0 everywhere. Printed for the face fitted
on the bundled neutral and on identities 000-(N-1), each with the bundled descriptors
(retargeted): the count and the largest turn at rest, and the worst AU or preset. Then the same
for the low-poly face (MediaPipe's 468-point mesh on the ICT neutral, ``assets/low_poly_face.npz``),
with its accuracy against the full-resolution scan beside the low-poly mesh's own (its
tessellation error), over the area the low-poly mesh covers.

Beside each count, the scan's own creases: the same metric on ICT-FaceKit's mesh (the one the
face was fitted to), at rest and posed by ICT's shapes for the same AU or preset, over the PDE
face's area. A PDE fold within ``--crease-mm`` of an edge where the scan itself turns by more
than 30° in that pose, or at rest carried by the pose (each crease point moving as the PDE face's
nearest vertex does; the only creases for poses ICT has no shapes for), lies on a crease the face
truly has (the nose wings' grooves, the lower lids' margins); the others are **off the scan's
creases**: what the PDE surface adds. The low-poly face lies on the ICT neutral: its creases are the full
scan's.
"""
from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import numpy as np
from pdeface.assets import load_ict_shapes, load_low_poly_face, load_neutral_scan
from pdeface.au.ict import AU_SHAPES, weights_offsets
from pdeface.au.modelfile import load_face
from pdeface.au.retarget import retarget
from pdeface.geometry import ClosestPoint
from pdeface.posing import pose_curves
from pdeface.presets import every_pose
from pdeface.surface.fit import face_mesh, fit_face
from pdeface.surface.folds import CREASE_MM, carried, fold_edges, off_creases

from scripts.bench.benchlib import bench_parser, run_bench


def folds_of(model, resolution, scan=None, shapes=None, crease_mm=CREASE_MM):
    """{pose name: (count, max_deg, off the scan's creases or None)} at rest, every AU at 1 and every preset.

    ``scan`` (the fitted mesh, same unit) and ``shapes`` (ICT offsets of its vertices): count the PDE folds
    farther than ``crease_mm`` from the scan's own folds in the same pose and from its folds at rest carried by
    the pose.
    """
    out = {}
    rest = face_mesh(model, resolution)
    scan_rest = fold_edges(scan, model.frame, model.landmarks)["where"] if scan is not None else None
    rest_face = model.frame.to_face(rest.vertices)
    for name, weights in every_pose(model).items():
        C, R = pose_curves(model, weights) if weights else (None, None)
        posed = face_mesh(model, resolution, coefficients=C, residual=R)
        r = fold_edges(posed, model.frame, model.landmarks, rest=rest)
        off = None
        if scan is not None:
            # the scan's creases at rest go where the pose takes their skin (a flared wing carries its groove)
            creases = carried(rest_face, model.frame.to_face(posed.vertices), scan_rest)
            if weights and all(k in AU_SHAPES for k in weights):
                scan_posed = replace(scan, vertices=scan.vertices + weights_offsets(weights, shapes)[0])
                creases = np.r_[creases, fold_edges(scan_posed, model.frame, model.landmarks, rest=scan)["where"]]
            off = int(off_creases(r["where"], creases, crease_mm).sum())
        out[name] = (r["count"], r["max_deg"], off)
    return out


def scan_creases(model, scan, resolution, near_mm=2.0):
    """The scan's own folds at rest (same metric) over the PDE face's area (within ``near_mm`` of it)."""
    pde = face_mesh(model, resolution)
    Tp, _ = pde.triangles()
    where = fold_edges(scan, model.frame, model.landmarks)["where"]
    return int((ClosestPoint(model.frame.to_face(pde.vertices), Tp).query(where)[0] < near_mm).sum())


def print_folds(label, folds, extra=""):
    rest, worst = folds["neutral"], max(folds, key=lambda k: folds[k][0])
    steepest = max(folds, key=lambda k: folds[k][1])
    print(f"{label}{extra}: {rest[0]} folds at rest (largest turn {rest[1]:.0f}°); worst pose {worst} "
          f"{folds[worst][0]} folds; median over {len(folds)} poses {np.median([v[0] for v in folds.values()]):.0f} "
          f"(target 0); largest turn in any pose {folds[steepest][1]:.1f}° ({steepest})")
    if rest[2] is not None:
        off = {k: v[2] for k, v in folds.items()}
        worst_off = max(off, key=off.get)
        print(f"  off the scan's own creases: {off['neutral']} at rest; worst pose {worst_off} {off[worst_off]}; "
              f"median {np.median(list(off.values())):.0f}; poses with any {sum(v > 0 for v in off.values())} of "
              f"{len(off)}")


def main(argv=None):
    ap = bench_parser(__doc__)
    ap.add_argument("--identities", type=int, default=3)
    ap.add_argument("--resolution", default="default")
    ap.add_argument("--crease-mm", type=float, default=CREASE_MM,
                    help="a PDE fold this near a fold of the scan itself (same pose) lies on the scan's crease")
    ap.add_argument("--json")
    args = ap.parse_args(argv)
    mesh, idx = load_neutral_scan()
    T, _ = mesh.triangles()
    shapes = load_ict_shapes()
    source = load_face("default")
    faces = [("generic neutral", mesh.vertices)]
    faces += [(f"identity{i:03d}", mesh.vertices + shapes[f"identity{i:03d}"]) for i in range(args.identities)]
    report = {}
    for label, V in faces:
        model, _ = fit_face(V, T, V[idx], unit="cm")  # in memory: all 68 landmarks
        scan = replace(mesh, vertices=V)
        model = retarget(source, model)
        folds = folds_of(model, args.resolution, scan, shapes, args.crease_mm)
        print_folds(label, folds, f" ({len(face_mesh(model, args.resolution).vertices)} vertices; the scan itself: "
                                  f"{scan_creases(model, scan, args.resolution)} over the same area at rest)")
        report[label] = folds
    low, L = load_low_poly_face()
    Tl, _ = low.triangles()
    model, sampler = fit_face(low.vertices, Tl, L, unit="cm")
    # The low-poly mesh lies on the ICT neutral: its creases are the full-resolution scan's.
    rig = retarget(source, model)
    folds = folds_of(rig, args.resolution, mesh, shapes, args.crease_mm)
    print_folds(f"low-poly face ({len(low.vertices)} vertices, {len(Tl)} triangles; points {sampler.summary()}; "
                f"PDE mesh {len(face_mesh(rig, args.resolution).vertices)} vertices)", folds)
    report["low-poly"] = folds
    truth = ClosestPoint(mesh.vertices, T)
    b = np.stack(np.meshgrid(np.linspace(0, 1, 7), np.linspace(0, 1, 7)), -1).reshape(-1, 2)
    b = b[b.sum(1) <= 1]
    on_low = np.einsum("pk,tkc->tpc", np.c_[1 - b.sum(1), b], low.vertices[Tl]).reshape(-1, 3)
    own = truth.query(on_low)[0] * 10  # cm → mm
    pde = face_mesh(model, args.resolution).vertices
    over = ClosestPoint(low.vertices, Tl).query(pde)[0] * 10 < 1.0  # the PDE face where the low-poly mesh is
    err = truth.query(pde[over])[0] * 10
    print(f"  against the full-resolution scan, over the low-poly mesh's area: the PDE face median "
          f"{np.median(err):.2f} mm, p95 {np.percentile(err, 95):.2f}, max {err.max():.2f}; the low-poly mesh "
          f"itself (its tessellation error) median {np.median(own):.2f}, p95 {np.percentile(own, 95):.2f}, "
          f"max {own.max():.2f}")
    report["low-poly accuracy mm"] = {"pde": [float(np.median(err)), float(np.percentile(err, 95)), float(err.max())],
                                      "tessellation": [float(np.median(own)), float(np.percentile(own, 95)),
                                                       float(own.max())]}
    if args.json:
        Path(args.json).write_text(json.dumps(report, indent=1))


if __name__ == "__main__":
    run_bench(main, "folds")
