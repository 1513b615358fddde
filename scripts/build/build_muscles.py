"""Calibrate the muscles against ICT-FaceKit and write the muscle AU table; add the muscle-only AUs to the default face.

Usage: python -m scripts.build.build_muscles [--evaluations 0] [--start GEOMETRY.json | --from-defaults]
                                      [--rounds 60] [--table core/pdeface/data/muscle_aus.json]

1. Geometry: the muscles' shapes (:data:`pdeface.muscles.placement.DEFAULT_GEOMETRY`: heads, zones,
   fall-offs, bulges, the sphincters' and sheets' sizes), shared by every AU, fitted by nonlinear
   least squares so that each bundled AU (both sides) is best matched by some activations of them
   on the default face's curve points (each AU's error relative to its own motion). It starts from
   the current table's geometry, ``--start`` a geometry JSON, or ``--from-defaults``;
   ``--evaluations 0`` (the default) keeps the start as it is, ``--evaluations 80`` refits it
   (about 8 minutes; the shipped geometry is ``--from-defaults --evaluations 80``).
2. Learned fields (:mod:`pdeface.muscles.fields`): each muscle's correction within its reach and
   every AU's activations, learned together by alternating least squares (``--rounds``, about
   1.5 minutes for 60). The muscles only the authored AUs use keep Waters' fields alone.
3. Activations: for every AU key of the default face, the 24 activations (within their bounds) that
   best match its descriptor's curve motion with the learned fields; the AUs ICT has no shape for
   are authored (:data:`pdeface.muscles.aus.AUTHORED`: named muscles, or calibrated AUs combined).
4. The table (geometry + activations) goes to ``core/pdeface/data/muscle_aus.json`` and the fields
   beside it (``muscle_fields.npz``); the authored AUs become descriptors (source ``muscle``) of
   ``assets/default_face.npz``.
Needs only the assets (no ../shared).
"""
from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np
from pdeface.assets import ICT_NOTICE, asset_path
from pdeface.au.ict import NOTICE_SHORT
from pdeface.au.modelfile import load_face
from pdeface.au.retarget import face_size
from pdeface.landmark_scheme import eye_distance
from pdeface.muscles.aus import AUTHORED, TABLE, VERSION, MuscleBasis, MuscleTable, authored_activations, load_table
from pdeface.muscles.aus import FORMAT as TABLE_FORMAT
from pdeface.muscles.fields import FORMAT as FIELDS_FORMAT
from pdeface.muscles.fields import REACH, LearnedFields, learn_corrections, load_fields, reach_mask
from pdeface.muscles.placement import BOUNDS, DEFAULT_GEOMETRY, MUSCLE_NAMES, place_muscles
from pdeface.surface.model import model_landmarks

ROOT = Path(__file__).resolve().parents[2]
#: Bounds of each geometry value: head moves (eye distances), zone (degrees), fall-offs and sizes
#: (fractions), bulge and push (mm). Anatomical, on purpose: with looser ones (heads moved half an
#: eye distance, sizes tripled) the fit made the muscles generic bumps far from their anatomy
#: (a nasalis from the nose to the chin) for 0.42 captured instead of 0.3x.
LIMITS = {"lateral": (-0.15, 0.15), "up": (-0.15, 0.15), "back": (-0.05, 0.15), "zone": (10.0, 60.0),
          "rs": (0.5, 1.3), "rf": (1.05, 2.2), "bulge": (-3.0, 3.0), "push": (-3.0, 3.0), "scale_x": (0.6, 1.6),
          "scale_y": (0.6, 1.6), "length": (0.6, 1.6), "width": (0.6, 1.6)}


#: Muscles only the authored AUs rely on (13: levator anguli oris; 38, 39: nasalis) keep their anatomical
#: shape and get no learned correction: fitted to the other AUs they became broad bumps (AU13 lifted the
#: lower lip 7 mm more than the corners).
AUTHORED_ONLY = ("levator_anguli_oris", "nasalis")


def recipe_text(recipe: dict) -> str:
    """``{"AU45R": 1.0, "AU7R": 0.33}`` → ``"AU45R 1.0, AU7R 0.33"`` (tables, reports)."""
    return ", ".join(f"{n} {v:g}" for n, v in recipe.items())


def table_to_json(table: dict, hows: dict, notice="", geometry=None, fields=None) -> dict:
    """A muscle table file's content (:mod:`pdeface.muscles.aus`'s format); ``fields``: the learned fields'
    file name (beside the table), if any."""
    out = {"format": TABLE_FORMAT, "version": VERSION, "muscles": list(MUSCLE_NAMES),
           "geometry": {n: {k: round(float(v), 4) for k, v in g.items()} for n, g in (geometry or {}).items()}}
    if fields:
        out["fields"] = str(fields)
    out.update({"aus": {k: {"activations": [round(float(v), 4) for v in a], "how": hows[k]}
                        for k, a in table.items()}, "notice": notice})
    return out


def save_fields(path, learned: LearnedFields):
    """Write :class:`~pdeface.muscles.fields.LearnedFields` in :mod:`pdeface.muscles.fields`'s format (float16:
    0.01 mm at the corrections' size)."""
    np.savez_compressed(path, format=np.array(FIELDS_FORMAT), muscles=np.array(MUSCLE_NAMES),
                        corrections=learned.corrections.astype(np.float16),
                        face_size=np.asarray(learned.face_size, np.float64), notice=np.array(learned.notice))


def curve_motion(face, d):
    C, R = d.dense()
    return face.curve_points(face.coefficients + C, face.residual + R) - face.curve_points()


def fit_geometry(face, evaluations, start):
    from scipy.optimize import least_squares

    L = model_landmarks(face)
    X = face.curve_points().reshape(-1, 3)
    targets = [curve_motion(face, d).ravel() for d in face.descriptors if not d.key.endswith(("L", "R"))]
    spec = [(n, k) for n, g in DEFAULT_GEOMETRY.items() for k in g if k != "pull" and n not in AUTHORED_ONLY]
    scale = np.array([30.0 if k == "zone" else 3.0 if k in ("bulge", "push") else 1.0 for _, k in spec])

    def geometry(x):
        g = {n: dict(start[n]) for n in AUTHORED_ONLY if n in start}
        for (n, k), v in zip(spec, x * scale):
            g.setdefault(n, {})[k] = float(v)
        return g

    def residuals(x):
        A = np.stack([m.displacement(X).ravel() for m in place_muscles(L, geometry(x))], axis=1)
        out = []
        for t in targets:  # activations by plain least squares here; the table's are bounded
            a = np.linalg.lstsq(A, t, rcond=None)[0]
            out.append((A @ a - t) / np.sqrt((t ** 2).mean()))
        return np.concatenate(out)

    x0 = np.array([start.get(n, {}).get(k, DEFAULT_GEOMETRY[n][k]) for n, k in spec]) / scale
    lo = np.array([LIMITS[k][0] for _, k in spec]) / scale
    hi = np.array([LIMITS[k][1] for _, k in spec]) / scale
    x0 = np.clip(x0, lo, hi)
    before = np.sqrt((residuals(x0) ** 2).mean())
    if evaluations <= 0:
        print(f"geometry: kept; relative RMS error over {len(targets)} AUs {before:.3f}")
        return geometry(x0)
    res = least_squares(residuals, x0, bounds=(lo, hi), max_nfev=evaluations, diff_step=1e-3)
    after = np.sqrt((res.fun ** 2).mean())
    print(f"geometry: relative RMS error over {len(targets)} AUs {before:.3f} → {after:.3f} ({res.nfev} evaluations)")
    return geometry(res.x)


def learn_fields(face, geometry, targets, rounds):
    """The muscles' corrections (:func:`pdeface.muscles.fields.learn_corrections`) on the default face."""
    waters = MuscleBasis(face, MuscleTable({}, geometry=geometry))
    X = face.curve_points().reshape(-1, 3)
    W = waters.fields.reshape(len(MUSCLE_NAMES), -1, 3)
    mask = reach_mask(X, W, REACH * eye_distance(model_landmarks(face)))
    mask[[i for i, n in enumerate(MUSCLE_NAMES) if n.startswith(AUTHORED_ONLY)]] = False
    T = np.stack([t.ravel() for t in targets])
    A0 = np.stack([waters.calibrate(t) for t in targets])

    def log(r, err):
        if r % 10 == 9 or r == 0:
            print(f"  round {r + 1}: median relative RMS error {err:.3f}", flush=True)

    print(f"fields: {mask.sum(1).mean():.0f} of {len(X)} curve points in a muscle's reach on average; "
          f"Waters alone: median relative RMS error "
          f"{np.median(np.sqrt(((A0 @ W.reshape(24, -1) - T) ** 2).mean(1) / (T ** 2).mean(1))):.3f}")
    C, _ = learn_corrections(W.reshape(len(W), -1), T, A0, np.repeat(mask, 3, axis=1), rounds=rounds, log=log)
    return LearnedFields(C.reshape(waters.fields.shape), face_size(face), ICT_NOTICE)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--evaluations", type=int, default=0, help="geometry fit: most function evaluations (0: keep)")
    ap.add_argument("--rounds", type=int, default=60, help="learned fields: rounds of alternating least squares")
    ap.add_argument("--start", type=Path, help="geometry JSON to start from")
    ap.add_argument("--from-defaults", action="store_true", help="start from the placement's defaults")
    ap.add_argument("--table", type=Path, default=ROOT / "core" / "pdeface" / "data" / "muscle_aus.json")
    args = ap.parse_args(argv)
    face = load_face("default")
    face.descriptors = [d for d in face.descriptors if d.source != "muscle"]  # a rebuild replaces its own
    if args.from_defaults:
        start = {}
    elif args.start:
        start = json.loads(args.start.read_text())
    else:
        start = load_table().geometry if TABLE.exists() else {}
    geometry = fit_geometry(face, args.evaluations, start)
    targets = [curve_motion(face, d) for d in face.descriptors]
    fields_path = args.table.parent / "muscle_fields.npz"
    save_fields(fields_path, learn_fields(face, geometry, targets, args.rounds))
    print(f"{fields_path}: {fields_path.stat().st_size} bytes")
    basis = MuscleBasis(face, MuscleTable({}, geometry=geometry, fields=load_fields(fields_path)))  # as stored
    table, hows = {}, {}
    for d, t in zip(face.descriptors, targets):
        table[d.key] = basis.calibrate(t)
        hows[d.key] = "calibrated on ICT-FaceKit"
    for key, recipe in AUTHORED.items():
        table[key] = authored_activations(recipe, table)
        hows[key] = f"authored: {recipe_text(recipe)}"
    data = table_to_json(table, hows, ICT_NOTICE, geometry, fields_path.name)
    args.table.write_text(json.dumps(data, indent=1) + "\n")
    print(f"{args.table}: {len(table)} AUs x {len(MUSCLE_NAMES)} muscles")
    from pdeface.au.modelfile import save_model

    added = [basis.descriptor(k, table[k], NOTICE_SHORT) for k in AUTHORED]  # shapes fitted to ICT
    face.descriptors += added
    size = save_model(asset_path("default_face.npz"), face)
    print(f"default_face.npz: + AU {', '.join(d.key for d in added)} (source muscle), {size} bytes")
    assert set(BOUNDS) == set(MUSCLE_NAMES)


if __name__ == "__main__":
    main()
