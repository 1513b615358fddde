"""``pdeface fdt``: fit, average, apply and recognise Facial Deformation Tables."""
from __future__ import annotations

import json
import time

from ..au.modelfile import load_face
from ..errors import PdeFaceError
from ..fdt.deform import NeutralFace, classify, fdt_aus, fdt_curves, fit_fdt
from ..fdt.quadratic import MODELS
from ..fdt.regions import BLEND
from ..fdt.table import generic, load_fdt, load_generic_fdts, read_fdts, write_fdts
from ..head.bind import JAW_AUS, bind_file
from ..io.arguments import file_name, number_in, positive_float, positive_int, unit_float
from ..io.files import check_output
from ..io.meshio import read_mesh, write_mesh, write_posed
from ..presets import BASIC_EXPRESSIONS
from ..surface.fit import face_mesh
from ..surface.frame import landmark_points, read_landmarks
from ..surface.scan import load_scan
from .common import json_option, log, meshing_options, output_option

#: An FDT's blended border width, in pupil half-distances.
blend_width = number_in(0.0, 2.0, what="a width in [0, 2] pupil half-distances")


def _pair(args):
    """Neutral mesh, its landmarks, the posed vertices, and the posed mesh's own landmarks (or None)."""
    neutral, lm = load_scan(args.neutral, args.landmarks)
    if lm is None:
        raise PdeFaceError(f"{args.neutral}: --landmarks is required (JSON with 'indices' or 'points')")
    posed = read_mesh(args.posed)
    posed_lm = None
    if args.posed_landmarks:
        posed_lm = landmark_points(posed.vertices, *read_landmarks(args.posed_landmarks))
    return neutral, lm, posed.vertices, posed_lm


def cmd_fit(args):
    check_output(args.output, args.neutral, args.posed, args.landmarks, args.posed_landmarks)
    neutral, lm, posed, posed_lm = _pair(args)
    model = "2d" if args.two_d else args.model
    name = args.name or args.posed.rsplit("/", 1)[-1].split(".")[0]
    t0 = time.perf_counter()
    fit = fit_fdt(neutral.vertices, posed, neutral.triangles()[0], lm, model, name, posed_lm, source=str(args.posed),
                  blend=args.blend)
    size = write_fdts(args.output, [fit.fdt])
    log(f"FDT {name!r} ({model}) of {args.posed} in {time.perf_counter() - t0:.2f} s: points per region "
        + " ".join(str(len(m)) for m in fit.members.values()))
    print(json.dumps({"output": str(args.output), "name": name, "model": model, "bytes": size}))


def cmd_mean(args):
    check_output(args.output, *args.files)
    tables = [t for f in args.files for t in read_fdts(f)]
    names = {t.name for t in tables}
    if len(names) > 1 and not args.name:
        log(f"averaging FDTs named {', '.join(sorted(names))}: give --name for the result")
    g = generic(tables, args.name or tables[0].name, source=f"mean of {len(tables)} FDTs")
    size = write_fdts(args.output, [g])
    print(json.dumps({"output": str(args.output), "name": g.name, "subjects": g.subjects, "bytes": size}))


def cmd_apply(args):
    check_output(args.output, args.face, args.fdt, args.mesh, args.parts, args.landmarks)
    model = load_face(args.face)
    fdt = load_fdt(args.fdt, args.model)
    weight = args.weight
    dC, dR = fdt_curves(model, fdt, weight, args.blend)
    if args.mesh:
        mesh, binding = bind_file(model, args.mesh, args.landmarks, args.parts)
        V = mesh.vertices + binding.displacement(dC, dR, jaw=bool(set(fdt_aus(fdt.name)) & set(JAW_AUS)))
        write_posed(args.output, args.mesh, mesh, V)
    else:
        write_mesh(args.output, face_mesh(model, args.resolution, coefficients=model.coefficients + dC,
                                          residual=model.residual + dR))
    log(f"wrote {args.output}: FDT {fdt.name!r} ({fdt.model}, {fdt.subjects} subject(s)) at weight {weight:g}")


def cmd_classify(args):
    neutral, lm, posed, posed_lm = _pair(args)
    if args.against:
        generics = [t for f in args.against for t in read_fdts(f)] if args.against != ["bundled-aus"] else \
            list(load_generic_fdts(args.model).values())
    else:
        generics = [load_fdt(name, args.model) for name in BASIC_EXPRESSIONS]
    models = {g.model for g in generics}
    if len(models) != 1:
        raise PdeFaceError(f"compare against FDTs of one model, got {', '.join(sorted(models))}")
    face = NeutralFace(neutral.vertices, neutral.triangles()[0], lm)
    ranking = classify(face.fit(posed, models.pop(), "observed", posed_lm), generics, args.sigmas)
    if args.json:
        print(json.dumps({"best": ranking[0]["name"], "ranking": ranking}))
        return
    for c in ranking[:args.top]:
        inside = "-" if c["inside"] is None else f"{c['inside']:.0%}"
        print(f"{c['name']:12s} distance {c['distance']:.3f}  intensity {c['intensity']:.2f}  inside ±{args.sigmas:g}σ "
              f"{inside}")


def register(sub):
    """The ``fdt`` command and its subcommands."""
    p = sub.add_parser("fdt", help="Facial Deformation Tables: fit, mean, apply, classify")
    fsub = p.add_subparsers(dest="fdt_command", required=True)
    model_help = "quadratic model: 3d (x', y', z' quadratic in x, y, z; default), 3d-surface, or the paper's 2d"

    def pair(q):
        q.add_argument("neutral", help="neutral mesh (.obj/.ply/.glb/.gltf) or 'default' (the bundled ICT neutral "
                                       "face)")
        q.add_argument("posed", help="the same mesh (same vertices) showing the expression")
        q.add_argument("--landmarks", help="the neutral's 68 landmarks (JSON; required unless NEUTRAL is 'default')")
        q.add_argument("--posed-landmarks", help="the posed mesh's own landmarks: normalise it by its own pupils "
                                                 "(as the paper does for two photographs)")

    q = fsub.add_parser("fit", help="one face's FDT from a neutral and a posed mesh")
    pair(q)
    q.add_argument("--model", choices=MODELS, default="3d", help=model_help)
    q.add_argument("--2d", dest="two_d", action="store_true", help="the paper's 2-D model (same as --model 2d)")
    q.add_argument("--name", help="the expression's name or AU key (default: the posed file's name)")
    q.add_argument("--blend", type=blend_width, help="width of the regions' blended borders, in pupil half-distances "
                                               f"(default {BLEND}); 0 fits each region alone, as the paper")
    output_option(q, ".fdt.json, or .csv (the paper's Table I layout)")
    q.set_defaults(func=cmd_fit)

    q = fsub.add_parser("mean", help="the generic FDT (mean ± σ) of several faces' FDTs of one expression")
    q.add_argument("files", nargs="+", help="FDT files (.fdt.json)")
    q.add_argument("--name", help="name of the result (default: the first table's)")
    output_option(q, ".fdt.json or .csv")
    q.set_defaults(func=cmd_mean)

    q = fsub.add_parser("apply", help="deform a face model with an FDT and mesh it (or the head it was fitted on)")
    q.add_argument("face", help="face model (.npz) or 'default'")
    q.add_argument("fdt", help="FDT file, or a bundled generic FDT: an AU key (12, 12L), a basic expression "
                               "(happy, sad, ...) or paper-smile")
    q.add_argument("--model", choices=MODELS, default="3d", help="model of a bundled FDT")
    q.add_argument("--weight", type=unit_float, default=1.0, help="how much of the expression, in [0, 1]")
    q.add_argument("--blend", type=blend_width, help="apply with this border width instead of the table's own")
    g = q.add_argument_group("the whole head (the mesh FACE was fitted on)")
    g.add_argument("--mesh", type=file_name,
                   help="pose this head mesh (.obj/.ply/.glb/.gltf or 'head') instead of the PDE face")
    g.add_argument("--parts", type=file_name, help="JSON of part kind → vertex indices (see 'pdeface parts')")
    g.add_argument("--landmarks", type=file_name,
                   help="the mesh's 68 landmarks (JSON), for a face model made by pdeface 0.1")
    meshing_options(q)
    output_option(q)
    q.set_defaults(func=cmd_apply)

    q = fsub.add_parser("classify", help="name a face's expression: the nearest generic FDT")
    pair(q)
    q.add_argument("--against", nargs="+", help="FDT files to compare with (default: the bundled six basic "
                                                "expressions; 'bundled-aus': every bundled FDT)")
    q.add_argument("--model", choices=MODELS, default="3d", help="model of the bundled FDTs")
    q.add_argument("--sigmas", type=positive_float, default=1.0, help="k of the mean ± kσ range")
    q.add_argument("--top", type=positive_int, default=3, help="candidates to print")
    json_option(q)
    q.set_defaults(func=cmd_classify)
