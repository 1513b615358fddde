"""The ``pdeface`` command line.

Wherever a command takes a face model, ``default`` means the bundled one;
wherever it takes a scan mesh, ``default`` means the bundled ICT-FaceKit
neutral face.
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

from .errors import PdeFaceError


def _log(msg):
    print(msg, file=sys.stderr, flush=True)


def load_face(arg):
    """A face model from a path, or the bundled one for ``default``."""
    from .assets import DEFAULT, DEFAULT_FACE, asset_path
    from .model import load_model

    return load_model(asset_path(DEFAULT_FACE) if arg == DEFAULT else arg)


def load_scan(arg, landmarks_arg=None):
    """(mesh, 68 landmarks xyz or None) from a path or ``default``."""
    from .assets import DEFAULT, load_neutral_scan
    from .frame import landmark_points, read_landmarks
    from .meshio import read_mesh

    if arg == DEFAULT:
        mesh, idx = load_neutral_scan()
        lm = mesh.vertices[idx]
    else:
        mesh, lm = read_mesh(arg), None
    mesh.validate(str(arg))
    if landmarks_arg:
        idx, pts = read_landmarks(landmarks_arg)
        lm = landmark_points(mesh.vertices, idx, pts)
    return mesh, lm


def skin_of(mesh, model):
    """Skin triangles of a scan: the pieces nearest the model's feature points."""
    from scipy.spatial import cKDTree

    from .fit import skin_triangles

    T, _ = mesh.triangles()
    near = cKDTree(mesh.vertices).query(model.frame.to_user(model.features))[1]
    return skin_triangles(T, len(mesh.vertices), near)


def cmd_fit(args):
    from .fit import fit_face
    from .model import save_model

    mesh, lm = load_scan(args.mesh, args.landmarks)
    if lm is None:
        raise PdeFaceError(f"{args.mesh}: --landmarks is required (JSON with 'indices' or 'points')")
    T, _ = mesh.triangles()
    t0 = time.perf_counter()
    model, sampler = fit_face(mesh.vertices, T, lm, unit=args.unit, n_curves=args.curves, n_points=args.points,
                              n_modes=args.modes, a=args.a, assembly=args.assembly, source=str(args.mesh))
    if args.mesh == "default":
        from .model import ICT_NOTICE
        model.notice = ICT_NOTICE
    size = save_model(args.output, model)
    _log(f"fitted {model.layout.n_curves} curves x {model.layout.n_points} points in "
         f"{time.perf_counter() - t0:.2f} s (unit {model.frame.unit}); points: {sampler.summary()}")
    print(json.dumps({"output": str(args.output), "model_bytes": size, "unit": model.frame.unit,
                      "points": sampler.summary()}))


def cmd_mesh(args):
    from .fit import face_mesh
    from .meshio import write_mesh

    model = load_face(args.face)
    mesh = face_mesh(model, args.resolution, args.assembly)
    write_mesh(args.output, mesh)
    _log(f"wrote {args.output}: {len(mesh.vertices)} vertices, {len(mesh.face_counts)} quads")


def cmd_report(args):
    from .report import accuracy_report

    model = load_face(args.face)
    mesh, _ = load_scan(args.mesh)
    result = accuracy_report(model, mesh.vertices, skin_of(mesh, model), args.assembly,
                             args.profiles_png, args.profiles_csv)
    result["model_bytes"] = Path(args.face if args.face != "default" else _default_path()).stat().st_size
    if args.json:
        print(json.dumps(result))
    else:
        for k, v in result.items():
            print(f"{k:18s} {v:.4f}" if isinstance(v, float) else f"{k:18s} {v}")


def _default_path():
    from .assets import DEFAULT_FACE, asset_path
    return asset_path(DEFAULT_FACE)


def cmd_demo(args):
    from .fit import face_mesh
    from .meshio import write_mesh
    from .model import save_model
    from .report import accuracy_report

    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    steps = ["fit", "mesh", "report"]
    mesh, lm = load_scan("default")
    T, _ = mesh.triangles()
    from .fit import fit_face
    from .model import ICT_NOTICE
    for i, step in enumerate(steps, 1):
        _log(f"[{i}/{len(steps)}] {step}")
        if step == "fit":
            model, _ = fit_face(mesh.vertices, T, lm, unit="cm", source="ICT-FaceKit generic neutral (face region)")
            model.notice = ICT_NOTICE
            size = save_model(out / "face.npz", model)
        elif step == "mesh":
            write_mesh(out / "face.obj", face_mesh(model))
        else:
            result = accuracy_report(model, mesh.vertices, T, profiles_png=out / "profiles.png",
                                     profiles_csv=out / "profiles.csv")
            result["model_bytes"] = size
            (out / "report.json").write_text(json.dumps(result, indent=2))
    print(json.dumps(result))
    _log(f"wrote {out}/face.npz, face.obj, report.json, profiles.png, profiles.csv")


def build_parser():
    ap = argparse.ArgumentParser(prog="pdeface", description="PDE face models and FACS Action Units.")
    sub = ap.add_subparsers(dest="command", required=True)

    p = sub.add_parser("fit", help="fit a PDE face model to a neutral mesh")
    p.add_argument("mesh", help="neutral face mesh (.obj/.ply) or 'default'")
    p.add_argument("--landmarks", help="JSON with 68 'indices' or 'points' (Multi-PIE order)")
    p.add_argument("--unit", choices=["mm", "cm", "m", "in"], help="mesh unit (default: guessed from the eyes)")
    p.add_argument("--curves", type=int, default=31)
    p.add_argument("--points", type=int, default=37)
    p.add_argument("--modes", type=int, default=5)
    p.add_argument("--a", type=float, default=1.0, help="PDE smoothing parameter")
    p.add_argument("--assembly", choices=["smooth", "patches"], default="smooth")
    p.add_argument("-o", "--output", required=True)
    p.set_defaults(func=cmd_fit)

    p = sub.add_parser("mesh", help="mesh the PDE surface of a face model")
    p.add_argument("face", help="face model (.npz) or 'default'")
    p.add_argument("--resolution", default="default", help="default, original, fine, or ROWS,COLS subdivisions")
    p.add_argument("--assembly", choices=["smooth", "patches"])
    p.add_argument("-o", "--output", required=True)
    p.set_defaults(func=cmd_mesh)

    p = sub.add_parser("report", help="accuracy of a face model against its scan")
    p.add_argument("face", help="face model (.npz) or 'default'")
    p.add_argument("mesh", help="the scan (.obj/.ply) or 'default'")
    p.add_argument("--assembly", choices=["smooth", "patches"])
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.add_argument("--profiles-png")
    p.add_argument("--profiles-csv")
    p.set_defaults(func=cmd_report)

    p = sub.add_parser("demo", help="the main job on the bundled face")
    p.add_argument("--out", default="out")
    p.set_defaults(func=cmd_demo)
    return ap


def main(argv=None):
    args = build_parser().parse_args(argv)
    try:
        args.func(args)
    except PdeFaceError as exc:
        print(f"pdeface: error: {exc}", file=sys.stderr)
        return 2
    except OSError as exc:
        print(f"pdeface: error: {exc.filename or ''}: {exc.strerror}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
