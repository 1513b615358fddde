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
from .io.files import check_output


def _log(msg):
    print(msg, file=sys.stderr, flush=True)


def cmd_fit(args):
    from .assets import DEFAULT, HEAD, ICT_NOTICE, load_scan
    from .io.modelfile import save_model
    from .surface.fit import fit_face

    check_output(args.output, args.mesh, args.landmarks, args.parts)

    mesh, lm = load_scan(args.mesh, args.landmarks)
    if lm is None:
        from .landmarks.cli import find_on_mesh

        _log(f"{args.mesh}: no --landmarks given: finding them (pdeface landmarks)")
        lm = find_on_mesh(mesh, args.unit).points
    T, _ = mesh.triangles()
    skin = None
    if args.parts:
        from .head.parts import read_overrides
        listed = read_overrides(args.parts).get("skin")
        if listed:
            skin = np.zeros(len(mesh.vertices), bool)
            skin[np.asarray(listed, np.int64)] = True
    t0 = time.perf_counter()
    model, sampler = fit_face(mesh.vertices, T, lm, unit=args.unit, n_curves=args.curves, n_points=args.points,
                              n_modes=args.modes, a=args.a, assembly=args.assembly, source=str(args.mesh),
                              follow_lips=not args.straight, skin=skin)
    if args.mesh in (DEFAULT, HEAD):
        model.notice = ICT_NOTICE
    size = save_model(args.output, model)
    _log(f"fitted {model.layout.n_curves} curves x {model.layout.n_points} points in "
         f"{time.perf_counter() - t0:.2f} s (unit {model.frame.unit}); points: {sampler.summary()}")
    beyond = sampler.summary()["beyond the edge"]
    if beyond:
        from .surface.curves import BEYOND
        curves = np.nonzero((sampler.status == BEYOND).mean(axis=1) > 0.5)[0]
        _log(f"note: {beyond} curve points lie beyond the mesh's edge and were extrapolated from the rest"
             + (f" (mostly on curves {', '.join(map(str, curves))}; 0 is the forehead's top)" if len(curves) else "")
             + ": the mesh does not reach the face's band there")
    print(json.dumps({"output": str(args.output), "model_bytes": size, "unit": model.frame.unit,
                      "points": sampler.summary()}))


def _turns(model, mesh, rest=None) -> str:
    """The mesh's largest turn between neighbouring faces outside the openings (issue #16's fold figure)."""
    from .surface.folds import fold_edges
    from .surface.model import model_landmarks

    r = fold_edges(mesh, model.frame, model_landmarks(model), rest=rest)
    return f"largest turn outside the eyes, mouth and nostrils {r['max_deg']:.0f}°, {r['count']} edges over 30°"


def cmd_mesh(args):
    from .assets import load_face
    from .io.meshio import write_mesh
    from .surface.fit import face_mesh

    check_output(args.output, args.face)

    model = load_face(args.face)
    mesh = face_mesh(model, args.resolution, args.assembly)
    write_mesh(args.output, mesh)
    _log(f"wrote {args.output}: {len(mesh.vertices)} vertices, {len(mesh.face_counts)} quads; {_turns(model, mesh)}")


def cmd_report(args):
    from .assets import load_face, load_scan
    from .io.modelfile import model_nbytes
    from .surface.report import accuracy_report

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


def cmd_import_au(args):
    from .io.timeline import save_timeline
    from .io.trackers import import_au

    check_output(args.output, args.file)

    r = import_au(args.file, args.format, args.fps, args.hold, args.smooth, args.reduce, args.min_confidence,
                  capture_fps=args.capture_fps)
    save_timeline(args.output, r.timeline)
    for note in r.notes:
        _log(note)
    if r.unknown:
        _log(f"ignored (not FACS AUs, or not mapped): {', '.join(map(str, r.unknown))}")
    aus, _ = r.timeline.channels()
    print(json.dumps({"output": str(args.output), "format": r.format, "rows": r.rows, "dropped": r.dropped,
                      "keys": len(r.timeline.keys), "frames": [r.timeline.keys[0].frame, r.timeline.frame_end],
                      "aus": aus, "unknown": [str(u) for u in r.unknown], "capture_fps": r.capture_fps}))


def _address(text, default_host="127.0.0.1"):
    host, sep, port = text.rpartition(":")
    try:
        return (host or default_host) if sep else default_host, int(port if sep else text)
    except ValueError:
        raise PdeFaceError(f"{text!r}: use HOST:PORT or PORT") from None


def cmd_stream_send(args):
    from .stream.sender import read_packets, send

    packets, bad = read_packets(args.file)
    for line in bad:
        _log(f"skipped {line}")
    try:
        result = send(packets, args.host, args.port, args.rate, args.listen)
    except OSError as exc:
        raise PdeFaceError(f"{args.host}:{args.port}: {exc.strerror or exc}") from None
    print(json.dumps({**result, "skipped": len(bad)}))


def cmd_stream_play(args):
    from .stream.player import Player
    from .stream.rules import DEFAULT_RULES, AUBlender

    blender = AUBlender.load(args.rules or DEFAULT_RULES) if args.rules is not None else None
    player = Player(transition=args.transition, mode=args.mode, blender=blender)
    try:
        if args.connect:
            player.connect(*_address(args.connect))
            _log(f"connecting to {args.connect}")
        else:
            host, port = player.listen(*_address(args.listen))
            _log(f"listening on {host}:{port}")
    except OSError as exc:
        raise PdeFaceError(f"cannot listen/connect: {exc.strerror or exc}") from None
    def print_pose(t, pose):
        print(json.dumps({"t": round(t, 4), "au": {k: round(w, 4) for k, w in pose.items()}}), flush=True)

    try:
        player.run(args.hz, args.duration, args.keep_running, print_pose if args.print else None)
    except KeyboardInterrupt:
        pass
    finally:
        player.close()
    _log(json.dumps(player.stats.as_dict()))


def run_headless(argv, capture=False):
    """Run the add-on's headless renderer (``headless.py``) in a child Python with the bpy module.

    The add-on travels with the package (``pdeface_blender``, or ``blender_addon/``
    in a checkout), so this works from an install; this package never imports
    bpy itself. Returns the child's exit status and, with ``capture``, its stdout.
    """
    import importlib.util
    import subprocess

    addon = importlib.util.find_spec("pdeface_blender")
    if importlib.util.find_spec("bpy") is None or addon is None:
        raise PdeFaceError("rendering needs Blender's bpy module and the add-on: "
                           "python -m pip install 'pdeface[blender]' (or -e '.[blender]' in a checkout)")
    script = Path(list(addon.submodule_search_locations)[0]) / "headless.py"
    code = ("import runpy, sys; sys.exit(runpy.run_path(sys.argv.pop(1))['main'](prog='pdeface render'))")
    res = subprocess.run([sys.executable, "-c", code, str(script), *argv],
                         stdout=subprocess.PIPE if capture else None, text=True)
    return res.returncode, res.stdout


def cmd_render(args):
    code, _ = run_headless(args.extra)
    if code:
        raise SystemExit(code)


def cmd_demo(args):
    from .assets import DEFAULT, ICT_NOTICE, load_scan
    from .io.files import write_bytes
    from .io.meshio import write_mesh
    from .io.modelfile import save_model
    from .surface.fit import face_mesh, fit_face
    from .surface.report import accuracy_report

    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    total = 3 if args.no_render else 4
    mesh, lm = load_scan(DEFAULT)
    T, _ = mesh.triangles()
    _log(f"[1/{total}] fit")
    model, _ = fit_face(mesh.vertices, T, lm, unit="cm", source="ICT-FaceKit generic neutral (face region)")
    model.notice = ICT_NOTICE
    size = save_model(out / "face.npz", model)
    _log(f"[2/{total}] mesh")
    write_mesh(out / "face.obj", face_mesh(model))
    _log(f"[3/{total}] report")
    result = accuracy_report(model, mesh.vertices, T, profiles_png=out / "profiles.png",
                             profiles_csv=out / "profiles.csv")
    result["model_bytes"] = size
    write_bytes(out / "report.json", json.dumps(result, indent=2).encode())
    _log(f"wrote {out}/face.npz, face.obj, report.json, profiles.png, profiles.csv")
    if not args.no_render:
        _log(f"[4/{total}] rig, animation, render (Blender, headless)")
        result["render"] = render_demo(out, args)
    print(json.dumps(result))


def render_demo(out, args):
    """The rig on ICT-FaceKit's whole head, the method's sequence, frames, contact sheet and .blend (bpy).

    Runs in a child process (:func:`run_headless`), so this package never imports bpy itself.
    """
    from .au.sequence import METHOD_SEQUENCE
    argv = ["--head", "--sequence", ",".join(METHOD_SEQUENCE), "--out", str(out), "--fps", str(args.fps), "--hold", "0.33",
            "--blend-time", "0.33", "--size", args.size, "--samples", str(args.samples), "--contact-sheet",
            "--save-blend", str(out / "demo.blend")] + (["--video"] if args.video else [])
    code, stdout = run_headless(argv, capture=True)
    if code != 0:
        raise PdeFaceError(f"rendering failed (exit {code}); see the messages above")
    summary = json.loads(stdout.strip().splitlines()[-1])
    _log(f"wrote {summary.get('frames', 0)} frames in {out}/frames, {out}/contact_sheet.png, {out}/demo.blend")
    return {k: summary[k] for k in ("frame_start", "frame_end", "contact_sheet", "blend", "render_s") if k in summary}


def parse_au_weights(items):
    """``["12=1", "6=0.5", "AU4=C"]`` → {"12": 1.0, "6": 0.5, "4": 0.6}."""
    from .au.expressions import normalise_weights

    weights = {}
    for item in items or []:
        key, sep, value = item.partition("=")
        if not sep:
            raise PdeFaceError(f"--au {item!r}: use AU=WEIGHT, e.g. 12=0.8 or 12L=C")
        try:
            value = float(value)
        except ValueError:
            pass  # a FACS letter
        weights[key] = value
    return normalise_weights(weights)


def cmd_descriptor(args):
    from .assets import load_scan
    from .au.capture import fit_descriptor
    from .io.descriptorfile import save_descriptor
    from .io.meshio import read_mesh
    from .surface.fit import fit_face
    from .surface.frame import landmark_points, read_landmarks

    check_output(args.output, args.neutral, args.au_mesh, args.landmarks, args.au_landmarks)

    neutral, lm = load_scan(args.neutral, args.landmarks)
    if lm is None:
        raise PdeFaceError(f"{args.neutral}: --landmarks is required")
    au_mesh = read_mesh(args.au_mesh)
    T, _ = neutral.triangles()
    model, sampler = fit_face(neutral.vertices, T, lm, unit=args.unit)
    same = len(au_mesh.vertices) == len(neutral.vertices) and np.array_equal(au_mesh.face_indices, neutral.face_indices)
    if same:
        d = fit_descriptor(model, sampler, neutral.vertices, au_mesh.vertices, args.au, args.side, source=str(args.au_mesh))
        how = "same topology: curve points read exactly"
    else:
        if not args.au_landmarks:
            raise PdeFaceError(f"{args.au_mesh}: its topology differs from the neutral's; give --au-landmarks to align it")
        idx, pts = read_landmarks(args.au_landmarks)
        Ta, _ = au_mesh.triangles()
        d = fit_descriptor(model, sampler, neutral.vertices, au_mesh.vertices, args.au, args.side, au_triangles=Ta,
                           au_landmarks=landmark_points(au_mesh.vertices, idx, pts), source=str(args.au_mesh))
        how = "other topology: aligned on unmoved feature points, curve points projected"
    size = save_descriptor(args.output, d)
    _log(f"{d.label}: {len(d.curves)} curves affected ({how})")
    print(json.dumps({"output": str(args.output), "au": d.key, "curves": d.curves.tolist(), "bytes": size}))


def cmd_pose(args):
    from .assets import load_face
    from .au.expressions import PRESETS, choose_mixer, load_presets, pose_curves, resolve_preset
    from .io.meshio import write_mesh
    from .surface.fit import face_mesh

    check_output(args.output, args.face, *(args.presets or []), *(args.descriptor or []))

    model = load_face(args.face)
    if args.descriptor:
        from .io.descriptorfile import load_descriptor
        extra = [load_descriptor(p) for p in args.descriptor]
        keys = {d.key for d in extra}
        model.descriptors = [d for d in model.descriptors if d.key not in keys] + extra
    weights, preset = parse_au_weights(args.au), None
    if args.preset:
        presets = dict(PRESETS)
        for f in args.presets or []:
            presets.update({p.name: p for p in load_presets(f)})
        if args.preset not in presets:
            raise PdeFaceError(f"unknown preset {args.preset!r}; have {', '.join(sorted(presets))}")
        pw, missing = resolve_preset(presets[args.preset], {d.key for d in model.descriptors})
        if missing:
            _log(f"preset {args.preset}: this face has no descriptor for AU {', '.join(missing)} (skipped)")
        weights = {**pw, **weights}
        preset = presets[args.preset]
    if not weights:
        raise PdeFaceError("give AU weights (--au 12=1) or a --preset")
    mixer = choose_mixer(args.mixer, preset)
    if args.mesh:
        _pose_head(args, model, weights, mixer)
        return
    C, R = pose_curves(model, weights, mixer)
    mesh = face_mesh(model, args.resolution, args.assembly, coefficients=C, residual=R)
    write_mesh(args.output, mesh)
    rest = face_mesh(model, args.resolution, args.assembly)
    _log(f"wrote {args.output}: " + ", ".join(f"AU{k}={w:g}" for k, w in weights.items()) + f" ({mixer}); "
         + _turns(model, mesh, rest))


def _pose_head(args, model, weights, mixer):
    from dataclasses import replace

    from .assets import DEFAULT, HEAD
    from .head.bind import bind_file
    from .io.meshio import write_mesh, write_posed

    check_output(args.output, args.mesh, args.parts, args.landmarks)
    t0 = time.perf_counter()
    mesh, binding = bind_file(model, args.mesh, args.landmarks, args.parts)
    V = mesh.vertices + binding.pose_displacement(weights, mixer)
    if args.mesh in (DEFAULT, HEAD):
        write_mesh(args.output, replace(mesh, vertices=V))
    else:
        write_posed(args.output, args.mesh, mesh, V)
    for note in binding.notes:
        _log(note)
    _log(f"wrote {args.output}: {len(V)} vertices of {args.mesh} posed in {time.perf_counter() - t0:.2f} s, "
         + ", ".join(f"AU{k}={w:g}" for k, w in weights.items()) + f" ({mixer})")


def cmd_parts(args):
    from .assets import load_scan
    from .head.parts import classify_mesh, overrides_of, read_overrides
    from .io.files import write_bytes

    check_output(args.output, args.mesh, args.landmarks, args.parts)
    mesh, lm = load_scan(args.mesh, args.landmarks)
    if lm is None:
        raise PdeFaceError(f"{args.mesh}: --landmarks is required (JSON with 'indices' or 'points')")
    parts = classify_mesh(mesh.vertices, mesh.triangles()[0], lm, args.unit,
                          read_overrides(args.parts) if args.parts else None)
    write_bytes(args.output, json.dumps(overrides_of(parts)).encode())
    for note in parts.notes:
        _log(note)
    print(json.dumps({"output": str(args.output), **parts.counts()}))


def cmd_retarget(args):
    from .assets import load_face
    from .au.retarget import retarget
    from .io.modelfile import save_model

    check_output(args.output, args.target, args.descriptors)

    target = load_face(args.target)
    source = load_face(args.descriptors)
    out = retarget(source, target, scaling=args.scaling, spacing=args.spacing)
    size = save_model(args.output, out)
    print(json.dumps({"output": str(args.output), "descriptors": len(out.descriptors), "bytes": size}))


def cmd_au_report(args):
    from .assets import DEFAULT, load_face, load_ict_shapes, load_scan
    from .au.aureport import au_report
    from .au.ict import IctFolder

    model = load_face(args.face)
    if not model.descriptors:
        raise PdeFaceError(f"{args.face}: carries no AU descriptors")
    if args.truth == DEFAULT:
        mesh, _ = load_scan(DEFAULT)
        V, T, shapes = mesh.vertices, mesh.triangles()[0], load_ict_shapes()
    else:
        shapes = IctFolder(args.truth)
        V, T = shapes.vertices, shapes.triangles()
    if args.neutral:
        from .io.meshio import read_mesh
        V = read_mesh(args.neutral).vertices[:len(V)]
    result = au_report(model, V, T, shapes)
    if args.json:
        print(json.dumps(result))
    else:
        for k, r in result.items():
            cap = "  n/a " if r["captured"] is None else f"{r['captured']:.3f}"
            p95 = "  n/a " if r["p95_err_mm"] is None else f"{r['p95_err_mm']:.2f}"
            print(f"AU{k:4s} captured {cap}  p95 {p95} mm  {r['bytes']} bytes")


class _HelpFormatter(argparse.ArgumentDefaultsHelpFormatter):
    """Shows each option's default, where it has one worth showing."""

    def _get_help_string(self, action):
        if action.default is None or action.default is False or "default" in (action.help or ""):
            return action.help
        return super()._get_help_string(action)


def build_parser():
    from . import __version__
    from .au.expressions import MIXERS
    from .au.facs import SIDES
    from .au.retarget import SCALINGS
    from .io.trackers import FORMATS
    from .stream.player import MODES
    from .surface.frame import UNITS_MM
    from .surface.layout import DEFAULT_CURVES
    from .surface.pde import ASSEMBLIES

    ASSEMBLY_HELP = "assembly to mesh with (default: the model's own)"

    def meshing_options(p):
        p.add_argument("--resolution", default="default",
                       help="default (steps per interval chosen for the face: more where it creases), original, "
                            "fine, or ROWS,COLS subdivisions")
        p.add_argument("--assembly", choices=ASSEMBLIES, help=ASSEMBLY_HELP)

    def output_option(p, help="file to write"):
        p.add_argument("-o", "--output", required=True, help=help)

    ap = argparse.ArgumentParser(prog="pdeface", description="PDE face models and FACS Action Units.")
    ap.add_argument("--version", action="version", version=f"pdeface {__version__}")
    sub = ap.add_subparsers(dest="command", required=True, metavar="COMMAND")

    p = sub.add_parser("fit", help="fit a PDE face model to a neutral mesh")
    p.add_argument("mesh", help="neutral face, head or body mesh (.obj/.ply), 'default' (the bundled ICT neutral "
                                "face) or 'head' (the bundled ICT whole head)")
    p.add_argument("--landmarks", help="JSON with the 68 Multi-PIE landmarks as 'indices' or 'points' (default: the "
                                       "bundled meshes' own; for a file, found automatically with pdeface[landmarks])")
    p.add_argument("--parts", help="JSON of part kind → vertex indices; its 'skin' list is the skin to fit "
                                   "(default: the parts under the landmarks; see 'pdeface parts')")
    p.add_argument("--unit", choices=list(UNITS_MM), help="mesh unit (default: guessed from the eyes)")
    p.add_argument("--curves", type=int, default=DEFAULT_CURVES,
                   help=f"boundary curves (default {DEFAULT_CURVES}; 31 is the method's 10 patches of 4)")
    p.add_argument("--points", type=int, default=37, help="points per curve (rays from the axis behind the face)")
    p.add_argument("--modes", type=int, default=5, help="Fourier modes per curve (the rest goes to the remainder)")
    p.add_argument("--a", type=float, default=1.0, help="PDE smoothing parameter")
    p.add_argument("--assembly", choices=ASSEMBLIES, default="smooth",
                   help="smooth: one C1 surface through all curves; patches: the method's patches of 4")
    p.add_argument("--straight", action="store_true",
                   help="horizontal curves throughout, as the original method (default: bend along the lips "
                        "and nostrils, with a curve on each rim of the eyes and mouth)")
    output_option(p)
    p.set_defaults(func=cmd_fit)

    p = sub.add_parser("mesh", help="mesh the PDE surface of a face model")
    p.add_argument("face", help="face model (.npz) or 'default'")
    meshing_options(p)
    output_option(p)
    p.set_defaults(func=cmd_mesh)

    p = sub.add_parser("report", help="accuracy of a face model against its scan")
    p.add_argument("face", help="face model (.npz) or 'default'")
    p.add_argument("mesh", help="the scan (.obj/.ply) or 'default'")
    p.add_argument("--assembly", choices=ASSEMBLIES, help=ASSEMBLY_HELP)
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.add_argument("--profiles-png", help="write the three cut profiles (scan, PDE, difference x10) as a PNG")
    p.add_argument("--profiles-csv", help="write the three cut profiles as CSV")
    p.set_defaults(func=cmd_report)

    p = sub.add_parser("descriptor", help="AU descriptor from a neutral mesh and an AU mesh")
    p.add_argument("neutral", help="neutral mesh (.obj/.ply) or 'default'")
    p.add_argument("au_mesh", help="the same face showing the AU")
    p.add_argument("--landmarks", help="68 landmarks of the neutral (JSON; required unless NEUTRAL is 'default')")
    p.add_argument("--au-landmarks", help="68 landmarks of the AU mesh, when its topology differs")
    p.add_argument("--au", type=int, required=True, help="the FACS AU number the AU mesh shows")
    p.add_argument("--side", choices=SIDES, default="both", help="the subject's side(s) the AU acts on")
    p.add_argument("--unit", choices=list(UNITS_MM), help="mesh unit (default: guessed from the eyes)")
    output_option(p, ".json (readable) or .pdd (compact binary)")
    p.set_defaults(func=cmd_descriptor)

    p = sub.add_parser("pose", help="mesh a face with AU weights or an expression preset")
    p.add_argument("face", help="face model with descriptors (.npz) or 'default'")
    p.add_argument("--au", action="append", metavar="AU=W", help="AU weight, e.g. 12=1, 12L=0.5, 4=C (repeatable)")
    p.add_argument("--preset", help="expression preset (happy, sad, ... or one from --presets)")
    p.add_argument("--presets", action="append", help="user preset JSON file(s)")
    p.add_argument("--descriptor", action="append", help="extra descriptor file(s) (.json/.pdd)")
    p.add_argument("--mixer", choices=MIXERS, help="how AUs on the same curves combine (default: the preset's "
                                                   "own, else sum)")
    g = p.add_argument_group("the whole head (the mesh FACE was fitted on)")
    g.add_argument("--mesh", help="pose this head or body mesh (.obj/.ply, or 'head': the bundled ICT head) instead "
                                  "of the PDE face: same vertices, order, faces, UVs, groups and materials")
    g.add_argument("--parts", help="JSON of part kind → vertex indices overriding the automatic parts "
                                   "(see 'pdeface parts')")
    g.add_argument("--landmarks", help="the mesh's 68 landmarks (JSON), for a face model made by pdeface 0.1")
    meshing_options(p)
    output_option(p)
    p.set_defaults(func=cmd_pose)

    p = sub.add_parser("parts", help="what each vertex of a head is: skin, eyeball, jaw, skull, attached, rest")
    p.add_argument("mesh", help="head mesh (.obj/.ply) or 'head' (the bundled ICT head)")
    p.add_argument("--landmarks", help="JSON with the 68 landmarks (required for a mesh file)")
    p.add_argument("--unit", choices=list(UNITS_MM), help="mesh unit (default: guessed from the eyes)")
    p.add_argument("--parts", help="overrides to apply (JSON, as written by this command)")
    output_option(p, ".json: part kind → vertex indices, editable and given back with --parts")
    p.set_defaults(func=cmd_parts)

    from .fdt.cli import add_parser as add_fdt_parser
    from .landmarks.cli import add_parser as add_landmarks_parser
    from .muscles.cli import add_parser as add_muscles_parser
    add_fdt_parser(sub, output_option, meshing_options)
    add_muscles_parser(sub, output_option, meshing_options)
    add_landmarks_parser(sub, output_option)

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
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.set_defaults(func=cmd_au_report)

    p = sub.add_parser("import-au", help="AU data from a tracker (OpenFace, Py-Feat, Live Link Face, FAS) → timeline")
    p.add_argument("file", help="the tracker's CSV or FAS text file")
    p.add_argument("--format", default="auto", choices=("auto",) + FORMATS, help="file format (auto: from its header)")
    p.add_argument("--fps", type=float, default=30.0, help="frame rate of the timeline written")
    p.add_argument("--hold", type=float, default=0.5, help="seconds per FAS AU set")
    p.add_argument("--smooth", type=int, default=1, help="moving-average window (samples)")
    p.add_argument("--reduce", type=float, default=0.0, help="keyframe reduction tolerance (weight)")
    p.add_argument("--capture-fps", type=float,
                   help="rate of a Live Link Face timecode's frames (default: read off the file)")
    p.add_argument("--min-confidence", type=float, default=0.75,
                   help="drop OpenFace rows below this confidence (Py-Feat: FaceScore)")
    output_option(p)
    p.set_defaults(func=cmd_import_au)

    p = sub.add_parser("stream", help="live AU stream: the remote player and a sender")
    ssub = p.add_subparsers(dest="stream_command", required=True)
    q = ssub.add_parser("send", help="replay a file of AU packets to a player")
    q.add_argument("file", help="one {1,2,5} / {12:0.8} / {12E} packet or JSON line per line")
    q.add_argument("--host", default="127.0.0.1", help="the player's address")
    q.add_argument("--port", type=int, default=5000, help="the player's port")
    q.add_argument("--rate", type=float, default=4.0, help="packets per second (0: as fast as allowed)")
    q.add_argument("--listen", action="store_true", help="wait for a player to connect instead")
    q.set_defaults(func=cmd_stream_send)
    q = ssub.add_parser("play", help="run the player headless")
    g = q.add_mutually_exclusive_group()
    g.add_argument("--listen", default="127.0.0.1:5000", help="HOST:PORT to listen on (default 127.0.0.1:5000)")
    g.add_argument("--connect", help="HOST:PORT of a sender that listens")
    q.add_argument("--print", action="store_true", help="print each pose as a JSON line")
    q.add_argument("--mode", choices=MODES, default="queue",
                   help="queue: play every packet in turn (the FAS player); live: head for the newest")
    q.add_argument("--transition", type=float, default=0.25, help="seconds from one pose to the next")
    q.add_argument("--rules", nargs="?", const="", default=None,
                   help="apply the AU blender's co-occurrence rules (a rules JSON, or the bundled ones)")
    q.add_argument("--hz", type=float, default=60.0, help="poses per second")
    q.add_argument("--duration", type=float, default=0.0, help="stop after this many seconds (0: never)")
    q.add_argument("--keep-running", action="store_true", help="do not exit when the sender ends")
    q.set_defaults(func=cmd_stream_play)

    p = sub.add_parser("render", add_help=False, help="render a timeline, presets or AU data headless "
                                                      "(pdeface render --help lists its options)")
    p.set_defaults(func=cmd_render)

    p = sub.add_parser("demo", help="the main job on the bundled face")
    p.add_argument("--out", default="out", help="output folder")
    p.add_argument("--no-render", action="store_true", help="fit, mesh and report only (no bpy needed)")
    p.add_argument("--size", default="192x192", help="frame size, WIDTHxHEIGHT")
    p.add_argument("--samples", type=int, default=16, help="Cycles samples per pixel")
    p.add_argument("--fps", type=float, default=12, help="frames per second of the animation")
    p.add_argument("--video", action="store_true", help="also write frames.mp4")
    p.set_defaults(func=cmd_demo)
    for command in subcommands(ap).values():
        command.formatter_class = _HelpFormatter
    return ap


def subcommands(parser, prefix="") -> dict:
    """Every (nested) subcommand parser: ``{"fit": ..., "stream send": ...}``."""
    out = {}
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, sub in action.choices.items():
                out[prefix + name] = sub
                out.update(subcommands(sub, prefix + name + " "))
    return out


def main(argv=None):
    ap = build_parser()
    args, extra = ap.parse_known_args(argv)
    if extra and args.command != "render":
        ap.error(f"unrecognized arguments: {' '.join(extra)}")
    args.extra = extra  # pdeface render passes its arguments on to the renderer
    try:
        args.func(args)
    except PdeFaceError as exc:
        print(f"pdeface: error: {exc}", file=sys.stderr)
        return 2
    except BrokenPipeError:  # output piped into head & co.
        return 1
    except OSError as exc:
        print(f"pdeface: error: {exc.filename or ''}: {exc.strerror}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
