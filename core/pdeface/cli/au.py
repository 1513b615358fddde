"""``pdeface descriptor``, ``pose``, ``retarget``, ``au-report`` and ``import-au``: Action Units on a face."""
from __future__ import annotations

import json
import re
import time
from pathlib import Path

from ..animation.timeline import save_timeline
from ..animation.trackers import FORMATS, import_au
from ..assets import DEFAULT, load_ict_shapes
from ..au.aureport import au_report
from ..au.capture import fit_descriptor
from ..au.descriptor import no_descriptors, replace_descriptors
from ..au.descriptorfile import load_descriptor, save_descriptor
from ..au.ict import IctFolder
from ..au.modelfile import load_face, save_model
from ..au.retarget import SCALINGS, retarget
from ..errors import FileError, PdeFaceError
from ..facs import SIDES, parse_au_weights
from ..head.bind import bind_file
from ..io.arguments import file_name, non_negative_float, positive_float, positive_int, unit_float
from ..io.files import check_output
from ..io.meshio import WRITE_FORMATS, read_mesh, write_mesh, write_posed, write_posed_many
from ..posing import MUSCLE_MIXERS, pose_curves
from ..presets import MIXERS, choose_mixer, key_poses, merged_presets, resolve_preset
from ..surface.fit import face_mesh, fit_face
from ..surface.frame import landmark_points, read_landmarks
from ..surface.scan import load_scan
from .common import (
    au_number,
    au_weight,
    json_option,
    log,
    meshing_options,
    output_option,
    turns,
    unit_option,
    weights_text,
)


def cmd_descriptor(args):
    check_output(args.output, args.neutral, args.au_mesh, args.landmarks, args.au_landmarks)

    neutral, lm = load_scan(args.neutral, args.landmarks)
    if lm is None:
        raise PdeFaceError(f"{args.neutral}: --landmarks is required")
    au_mesh = read_mesh(args.au_mesh)
    model, sampler = fit_face(neutral.vertices, neutral.triangles()[0], lm, unit=args.unit)
    if neutral.same_topology(au_mesh):
        d = fit_descriptor(model, sampler, neutral.vertices, au_mesh.vertices, args.au, args.side, source=str(args.au_mesh))
        how = "same topology: curve points read exactly"
    else:
        if not args.au_landmarks:
            raise PdeFaceError(f"{args.au_mesh}: its topology differs from the neutral's; give --au-landmarks to align it")
        au_lm = landmark_points(au_mesh.vertices, *read_landmarks(args.au_landmarks))
        d = fit_descriptor(model, sampler, neutral.vertices, au_mesh.vertices, args.au, args.side,
                           au_triangles=au_mesh.triangles()[0], au_landmarks=au_lm, source=str(args.au_mesh))
        how = "other topology: aligned on unmoved feature points, curve points projected"
    size = save_descriptor(args.output, d)
    log(f"{d.label}: {len(d.curves)} curves affected ({how})")
    print(json.dumps({"output": str(args.output), "au": d.key, "curves": d.curves.tolist(), "bytes": size}))


def _pose_weights(args, model):
    """The AU weights and the preset (or None) ``pdeface pose`` poses ``model`` with: --au over --preset."""
    weights, preset = parse_au_weights(args.au), None
    if args.preset:
        presets = merged_presets(args.presets or [])
        if args.preset not in presets:
            raise PdeFaceError(f"unknown preset {args.preset!r}; have {', '.join(sorted(presets))}")
        preset = presets[args.preset]
        pw, missing = resolve_preset(preset, {d.key for d in model.descriptors})
        if missing:
            log(f"preset {args.preset}: this face has no descriptor for AU {', '.join(missing)} (skipped)")
        weights = {**pw, **weights}
    if not weights:
        raise PdeFaceError("give AU weights (--au 12=1) or a --preset")
    return weights, preset


def cmd_pose(args):
    check_output(args.output, args.face, *(args.presets or []), *(args.descriptor or []))

    model = load_face(args.face)
    if args.descriptor:
        model.descriptors = replace_descriptors(model.descriptors, [load_descriptor(p) for p in args.descriptor])
    if args.all_keys:
        _pose_all_keys(args, model)
        return
    if args.format:
        raise PdeFaceError("--format is for --all-keys (a single pose is written in -o's format)")
    if not model.descriptors and args.mixer not in MUSCLE_MIXERS:  # before a preset's AUs are skipped one by one
        raise PdeFaceError(no_descriptors(args.face))
    weights, preset = _pose_weights(args, model)
    mixer = choose_mixer(args.mixer, preset)
    if args.mesh:
        _pose_head(args, model, weights, mixer)
        return
    C, R = pose_curves(model, weights, mixer)
    mesh = face_mesh(model, args.resolution, args.assembly, coefficients=C, residual=R)
    write_mesh(args.output, mesh)
    rest = face_mesh(model, args.resolution, args.assembly)
    log(f"wrote {args.output}: {weights_text(weights, mixer)}; " + turns(model, mesh, rest))


def _pose_head(args, model, weights, mixer):
    check_output(args.output, args.mesh, args.parts, args.landmarks)
    t0 = time.perf_counter()
    mesh, binding = bind_file(model, args.mesh, args.landmarks, args.parts)
    V = mesh.vertices + binding.pose_displacement(weights, mixer)
    write_posed(args.output, args.mesh, mesh, V)
    for note in binding.notes:
        log(note)
    took = time.perf_counter() - t0
    # The fold figure is measured where it is defined, on the PDE face (the openings come from its
    # landmarks; the head has ears, eyeballs and teeth): the same figure `pose` without --mesh prints.
    C, R = pose_curves(model, weights, mixer)
    face = face_mesh(model, args.resolution, args.assembly, coefficients=C, residual=R)
    rest = face_mesh(model, args.resolution, args.assembly)
    log(f"wrote {args.output}: {len(V)} vertices of {args.mesh} posed in {took:.2f} s, {weights_text(weights, mixer)}; "
        f"the posed PDE face's {turns(model, face, rest)}")


def _pose_all_keys(args, model):
    """``pose --all-keys``: one mesh per AU and per preset in the folder ``args.output``, for other DCC tools."""
    if args.au or args.preset:
        raise PdeFaceError("--all-keys writes every AU and preset: drop --au and --preset")
    presets = merged_presets(args.presets or [])
    if not model.descriptors:  # before the mesh is bound
        raise PdeFaceError(no_descriptors(args.face))
    taken = {"neutral"} | {f"AU{d.key}" for d in model.descriptors}
    clash = sorted(n for n in presets if n in taken or n.lower() in {t.lower() for t in taken})
    if clash:  # its file would replace the base or an AU's own
        raise PdeFaceError(f"preset {clash[0]!r} has the name of an AU's or the neutral's file: rename it")
    mesh = binding = None
    if args.mesh:  # bound first: a head without eyeballs gets no gaze keys (its notes say so)
        mesh, binding = bind_file(model, args.mesh, args.landmarks, args.parts)
    keyed = model.descriptors if binding is None else binding.bindable(model.descriptors)
    poses = key_poses(model, presets, args.mixer, descriptors=keyed)
    if not poses:
        raise PdeFaceError(no_descriptors(args.face))
    poses = {"neutral": ({}, choose_mixer(args.mixer)), **poses}  # the base the other files are targets of
    ext = "." + (args.format or _input_format(args.mesh))
    out = Path(args.output)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise FileError(f"{out}: cannot make the output folder ({exc.strerror})") from None
    # A preset file's name may hold any character: the file name keeps letters, digits, '-', '_' and '.'.
    files = {name: out / (re.sub(r"[^\w.-]", "_", name) + ext) for name in poses}
    seen = {}
    for name, path in files.items():  # 'a b' and 'a/b' (or 'Happy' and 'happy' on some disks) share a file name
        other = seen.setdefault(path.name.lower(), name)
        if other != name:
            raise PdeFaceError(f"presets {other!r} and {name!r} would both be written to {path.name}: rename one")
    inputs = (args.face, args.mesh, args.parts, args.landmarks, *(args.presets or []), *(args.descriptor or []))
    for path in files.values():
        check_output(path, *inputs)
    t0 = time.perf_counter()
    if binding is not None:
        D = binding.pose_displacements(list(poses.values()))
        write_posed_many(((path, mesh.vertices + d) for path, d in zip(files.values(), D)), args.mesh, mesh)
        for note in binding.notes:
            log(note)
        vertices = len(mesh.vertices)
    else:
        for name, (weights, mixer) in poses.items():
            C, R = pose_curves(model, weights, mixer)
            mesh = face_mesh(model, args.resolution, args.assembly, coefficients=C, residual=R)
            write_mesh(files[name], mesh)
        vertices = len(mesh.vertices)
    aus = [f"AU{d.key}" for d in keyed]
    log(f"wrote {len(files)} meshes of {vertices} vertices in {time.perf_counter() - t0:.1f} s: {len(aus)} AUs, "
        f"{len(files) - len(aus) - 1} presets and the neutral")
    presets = [n for n in poses if n not in aus and n != "neutral"]
    print(json.dumps({"output": str(out), "format": ext[1:], "vertices": vertices, "aus": aus, "presets": presets,
                      "files": {n: str(p) for n, p in files.items()}}))


def _input_format(mesh_arg):
    """The format ``pose --all-keys`` writes by default: the input mesh's if writable, else OBJ."""
    ext = Path(str(mesh_arg)).suffix.lower() if mesh_arg else ""
    return ext[1:] if ext in WRITE_FORMATS else "obj"


def cmd_retarget(args):
    check_output(args.output, args.target, args.descriptors)

    target = load_face(args.target)
    source = load_face(args.descriptors)
    out = retarget(source, target, scaling=args.scaling, spacing=args.spacing)
    size = save_model(args.output, out)
    print(json.dumps({"output": str(args.output), "descriptors": len(out.descriptors), "bytes": size}))


def cmd_au_report(args):
    model = load_face(args.face)
    if not model.descriptors:
        raise PdeFaceError(no_descriptors(args.face))
    if args.truth == DEFAULT:
        mesh, _ = load_scan(DEFAULT)
        V, T, shapes = mesh.vertices, mesh.triangles()[0], load_ict_shapes()
    else:
        shapes = IctFolder(args.truth)
        V, T = shapes.vertices, shapes.triangles()
    if args.neutral:
        V = read_mesh(args.neutral).vertices[:len(V)]
    result = au_report(model, V, T, shapes)
    if args.json:
        print(json.dumps(result))
    else:
        for k, r in result.items():
            cap = "  n/a " if r["captured"] is None else f"{r['captured']:.3f}"
            p95 = "  n/a " if r["p95_err_mm"] is None else f"{r['p95_err_mm']:.2f}"
            print(f"AU{k:4s} captured {cap}  p95 {p95} mm  {r['bytes']} bytes")


def cmd_import_au(args):
    check_output(args.output, args.file)

    r = import_au(args.file, args.format, args.fps, args.hold, args.smooth, args.reduce, args.min_confidence,
                  capture_fps=args.capture_fps)
    save_timeline(args.output, r.timeline)
    for note in r.notes:
        log(note)
    if r.unknown:
        log(f"ignored (not FACS AUs, or not mapped): {', '.join(map(str, r.unknown))}")
    aus, _ = r.timeline.channels()
    print(json.dumps({"output": str(args.output), "format": r.format, "rows": r.rows, "dropped": r.dropped,
                      "keys": len(r.timeline.keys), "frames": [r.timeline.keys[0].frame, r.timeline.frame_end],
                      "aus": aus, "unknown": [str(u) for u in r.unknown], "capture_fps": r.capture_fps}))


def register(sub):
    """The ``descriptor``, ``pose``, ``retarget``, ``au-report`` and ``import-au`` commands."""
    p = sub.add_parser("descriptor", help="AU descriptor from a neutral mesh and an AU mesh")
    p.add_argument("neutral", help="neutral mesh (.obj/.ply/.glb/.gltf) or 'default'")
    p.add_argument("au_mesh", help="the same face showing the AU")
    p.add_argument("--landmarks", help="68 landmarks of the neutral (JSON; required unless NEUTRAL is 'default')")
    p.add_argument("--au-landmarks", help="68 landmarks of the AU mesh, when its topology differs")
    p.add_argument("--au", type=au_number, required=True, help="the FACS AU number the AU mesh shows")
    p.add_argument("--side", choices=SIDES, default="both", help="the subject's side(s) the AU acts on")
    unit_option(p)
    output_option(p, ".json (readable) or .pdd (compact binary)")
    p.set_defaults(func=cmd_descriptor)

    p = sub.add_parser("pose", help="mesh a face with AU weights or an expression preset")
    p.add_argument("face", help="face model with descriptors (.npz) or 'default'")
    p.add_argument("--au", action="append", metavar="AU=W", type=au_weight, help="AU weight, e.g. 12=1, 12L=0.5, 4=C (repeatable)")
    p.add_argument("--preset", help="expression preset (happy, sad, ... or one from --presets; "
                                    "'pdeface aus FACE' lists them)")
    p.add_argument("--presets", action="append", help="user preset JSON file(s)")
    p.add_argument("--descriptor", action="append", help="extra descriptor file(s) (.json/.pdd)")
    p.add_argument("--mixer", choices=MIXERS, help="how AUs on the same curves combine (default: the preset's "
                                                   "own, else sum)")
    g = p.add_argument_group("the whole head (the mesh FACE was fitted on)")
    g.add_argument("--mesh", type=file_name,
                   help="pose this head or body mesh (.obj/.ply/.glb/.gltf, or 'head': the bundled ICT "
                        "head) instead of the PDE face: same vertices, order, faces, UVs, groups and "
                        "materials")
    g.add_argument("--parts", type=file_name,
                   help="JSON of part kind → vertex indices overriding the automatic parts "
                        "(see 'pdeface parts')")
    g.add_argument("--landmarks", type=file_name,
                   help="the mesh's 68 landmarks (JSON), for a face model made by pdeface 0.1")
    g = p.add_argument_group("every key as a mesh file (for other DCC tools)")
    g.add_argument("--all-keys", action="store_true",
                   help="write the neutral (neutral.obj), one mesh per AU (AU12.obj ...) and one per preset "
                        "(happy.obj ...) into the folder -o, all in the input's vertex order; prints a JSON summary")
    g.add_argument("--format", choices=[e[1:] for e in WRITE_FORMATS],
                   help="file format of --all-keys' meshes (default: the --mesh file's when writable, else obj)")
    meshing_options(p)
    output_option(p, "file to write (with --all-keys: the folder)")
    p.set_defaults(func=cmd_pose)

    p = sub.add_parser("retarget", help="carry AU descriptors over to another face model")
    p.add_argument("target", help="the target face model (.npz)")
    p.add_argument("--descriptors", default="default", help="face model whose descriptors to use (default: bundled)")
    p.add_argument("--scaling", choices=SCALINGS, default="face", help="scale the descriptors by the faces' sizes")
    p.add_argument("--no-spacing", dest="spacing", action="store_false",
                   help="move every curve as the source's curve of the same index moved, even where the target's "
                        "curves lie much closer together (by default their relative motion is shrunk there)")
    output_option(p)
    p.set_defaults(func=cmd_retarget)

    p = sub.add_parser("au-report", help="how much of each AU's true motion the descriptors capture")
    p.add_argument("face", help="face model with descriptors (.npz) or 'default'")
    p.add_argument("--truth", required=True, help="ICT-FaceKit folder, or 'default' for the bundled ICT shapes")
    p.add_argument("--neutral", help="the neutral scan the face was fitted to (default: ICT's generic neutral)")
    json_option(p)
    p.set_defaults(func=cmd_au_report)

    p = sub.add_parser("import-au", help="AU data from a tracker (OpenFace, Py-Feat, Live Link Face, FAS) → timeline")
    p.add_argument("file", help="the tracker's CSV or FAS text file")
    p.add_argument("--format", default="auto", choices=("auto",) + FORMATS, help="file format (auto: from its header)")
    p.add_argument("--fps", type=positive_float, default=30.0, help="frame rate of the timeline written")
    p.add_argument("--hold", type=positive_float, default=0.5, help="seconds per FAS AU set")
    p.add_argument("--smooth", type=positive_int, default=1, help="moving-average window (samples)")
    p.add_argument("--reduce", type=non_negative_float, default=0.0, help="keyframe reduction tolerance (weight)")
    p.add_argument("--capture-fps", type=positive_float,
                   help="rate of a Live Link Face timecode's frames (default: read off the file)")
    p.add_argument("--min-confidence", type=unit_float, default=0.75,
                   help="drop OpenFace rows below this confidence (Py-Feat: FaceScore)")
    output_option(p)
    p.set_defaults(func=cmd_import_au)
