"""``pdeface fit``, ``mesh``, ``report`` and ``parts``: a face model from a scan, its surface, its
accuracy, and what each vertex of a head is."""
from __future__ import annotations

import json
import time

from ..assets import DEFAULT, HEAD, ICT_NOTICE
from ..au.modelfile import load_face, model_nbytes, save_model
from ..errors import PdeFaceError
from ..head.parts import classify_mesh, overrides_of, read_overrides, skin_mask
from ..io.arguments import number_in, positive_float
from ..io.files import check_output, write_bytes
from ..io.meshio import write_mesh
from ..landmarks.checked import check_given
from ..surface.fit import face_mesh, fit_face
from ..surface.layout import DEFAULT_CURVES, MAX_CURVES, MAX_MODES, MAX_POINTS
from ..surface.pde import ASSEMBLIES
from ..surface.report import accuracy_report
from ..surface.scan import load_scan
from .common import (
    assembly_option,
    json_option,
    log,
    meshing_options,
    output_option,
    turns,
    unit_option,
    verbose_option,
)
from .landmarks import accept_option, find_landmarks


def cmd_fit(args):
    check_output(args.output, args.mesh, args.landmarks, args.parts)

    mesh, lm = load_scan(args.mesh, args.landmarks)
    if lm is None:
        log(f"{args.mesh}: no --landmarks given: finding them (pdeface landmarks)")
        lm = find_landmarks(mesh, args.unit, verbose=args.verbose, accept=args.accept)[0].points
    elif args.landmarks:  # the user's points; the mesh may still be no rest (its eyes closed)
        check_given(mesh, lm, args.unit, accept=args.accept, log=log)
    T, _ = mesh.triangles()
    skin = skin_mask(read_overrides(args.parts), len(mesh.vertices)) if args.parts else None
    t0 = time.perf_counter()
    model, sampler = fit_face(mesh.vertices, T, lm, unit=args.unit, n_curves=args.curves, n_points=args.points,
                              n_modes=args.modes, a=args.a, assembly=args.assembly, source=str(args.mesh),
                              follow_lips=not args.straight, skin=skin)
    if args.mesh in (DEFAULT, HEAD):
        model.notice = ICT_NOTICE
    size = save_model(args.output, model)
    points = sampler.summary()
    log(f"fitted {model.layout.n_curves} curves x {model.layout.n_points} points in "
        f"{time.perf_counter() - t0:.2f} s (unit {model.frame.unit}); points: {points}")
    beyond = points["beyond the edge"]
    if beyond:
        curves = sampler.beyond_curves()
        log(f"note: {beyond} curve points lie beyond the mesh's edge and were extrapolated from the rest"
            + (f" (mostly on curves {', '.join(map(str, curves))}; 0 is the forehead's top)" if len(curves) else "")
            + ": the mesh does not reach the face's band there")
    print(json.dumps({"output": str(args.output), "model_bytes": size, "unit": model.frame.unit, "points": points}))


def cmd_mesh(args):
    check_output(args.output, args.face)

    model = load_face(args.face)
    mesh = face_mesh(model, args.resolution, args.assembly)
    write_mesh(args.output, mesh)
    log(f"wrote {args.output}: {len(mesh.vertices)} vertices, {len(mesh.face_counts)} quads; {turns(model, mesh)}")


def cmd_report(args):
    for out in (args.profiles_png, args.profiles_csv):
        if out:
            check_output(out, args.face, args.mesh)

    model = load_face(args.face)
    mesh, _ = load_scan(args.mesh)
    result = accuracy_report(model, mesh.vertices, mesh.triangles()[0], args.assembly, args.profiles_png,
                             args.profiles_csv)
    result["model_bytes"] = model_nbytes(model)
    if args.json:
        print(json.dumps(result))
    else:
        for k, v in result.items():
            print(f"{k:18s} {v:.4f}" if isinstance(v, float) else f"{k:18s} {v}")


def cmd_parts(args):
    check_output(args.output, args.mesh, args.landmarks, args.parts)
    mesh, lm = load_scan(args.mesh, args.landmarks)
    if lm is None:
        raise PdeFaceError(f"{args.mesh}: --landmarks is required (JSON with 'indices' or 'points')")
    parts = classify_mesh(mesh.vertices, mesh.triangles()[0], lm, args.unit,
                          read_overrides(args.parts) if args.parts else None)
    write_bytes(args.output, json.dumps(overrides_of(parts)).encode())
    for note in parts.notes:
        log(note)
    print(json.dumps({"output": str(args.output), **parts.counts()}))


def register(sub):
    """The ``fit``, ``mesh``, ``report`` and ``parts`` commands."""
    p = sub.add_parser("fit", help="fit a PDE face model to a neutral mesh")
    p.add_argument("mesh", help="neutral face, head or body mesh (.obj/.ply/.glb/.gltf), 'default' (the bundled "
                                "ICT neutral face) or 'head' (the bundled ICT whole head)")
    p.add_argument("--landmarks", help="JSON with the 68 Multi-PIE landmarks as 'indices' or 'points' (default: the "
                                       "bundled meshes' own; for a file, found automatically with pdeface[landmarks])")
    p.add_argument("--parts", help="JSON of part kind → vertex indices; its 'skin' list is the skin to fit "
                                   "(default: the parts under the landmarks; see 'pdeface parts')")
    unit_option(p)
    accept_option(p)
    p.add_argument("--curves", type=number_in(4, MAX_CURVES, int), default=DEFAULT_CURVES,
                   help=f"boundary curves (default {DEFAULT_CURVES}; 31 is the method's 10 patches of 4)")
    p.add_argument("--points", type=number_in(7, MAX_POINTS, int), default=37, help="points per curve (rays from the axis behind the face)")
    p.add_argument("--modes", type=number_in(0, MAX_MODES, int), default=5, help="Fourier modes per curve (the rest goes to the remainder)")
    p.add_argument("--a", type=positive_float, default=1.0, help="PDE smoothing parameter")
    p.add_argument("--assembly", choices=ASSEMBLIES, default="smooth",
                   help="smooth: one C1 surface through all curves; patches: the method's patches of 4")
    p.add_argument("--straight", action="store_true",
                   help="horizontal curves throughout, as the original method (default: bend along the lips "
                        "and nostrils, with a curve on each rim of the eyes and mouth)")
    output_option(p)
    verbose_option(p)
    p.set_defaults(func=cmd_fit)

    p = sub.add_parser("mesh", help="mesh the PDE surface of a face model")
    p.add_argument("face", help="face model (.npz) or 'default'")
    meshing_options(p)
    output_option(p)
    p.set_defaults(func=cmd_mesh)

    p = sub.add_parser("report", help="accuracy of a face model against its scan")
    p.add_argument("face", help="face model (.npz) or 'default'")
    p.add_argument("mesh", help="the scan (.obj/.ply/.glb/.gltf) or 'default'")
    assembly_option(p)
    json_option(p)
    p.add_argument("--profiles-png", help="write the three cut profiles (scan, PDE, difference x10) as a PNG")
    p.add_argument("--profiles-csv", help="write the three cut profiles as CSV")
    p.set_defaults(func=cmd_report)

    p = sub.add_parser("parts", help="what each vertex of a head is: skin, eyeball, jaw, skull, attached, rest")
    p.add_argument("mesh", help="head mesh (.obj/.ply/.glb/.gltf) or 'head' (the bundled ICT head)")
    p.add_argument("--landmarks", help="JSON with the 68 landmarks (required for a mesh file)")
    unit_option(p)
    p.add_argument("--parts", help="overrides to apply (JSON, as written by this command)")
    output_option(p, ".json: part kind → vertex indices, editable and given back with --parts")
    p.set_defaults(func=cmd_parts)
