"""Render a PDE face animation headless: ``pdeface render``, ``scripts/figures/render_sequence.py``.

Runs as ``pdeface render ARGS``, ``blender -b -P scripts/figures/render_sequence.py -- ARGS``
and ``python scripts/figures/render_sequence.py ARGS`` (with the bpy module); this
file travels with the add-on (and, installed, as ``pdeface_blender``), so an
installed pdeface renders without a checkout. It imports nothing of Blender's
until it has parsed its arguments, and enables the add-on from its own folder
as an extension. Builds the PDE
face with its shape keys (or loads a .blend), keyframes a timeline (a
pdeface.animation.timeline JSON, a list of presets, or an AU data file), frames the face
with a camera and lights, renders PNG frames (Cycles CPU by default), and
optionally a video, a contact sheet and the .blend.

``--frame-start/--frame-end`` render a chunk: the camera depends only on the
face at rest and the sampling seed is fixed, so chunks from several machines
(e.g. a Flamenco job) join seamlessly. Prints a JSON summary on stdout.
"""
from __future__ import annotations

import argparse
import contextlib
import io
import json
import os
import sys
import tempfile
import time
from pathlib import Path

ADDON_DIR = Path(__file__).resolve().parent
MODULE = "bl_ext.pdeface_render.pdeface"


def script_args(argv):
    """Arguments after ``--`` (Blender's convention), else all of them."""
    return argv[argv.index("--") + 1:] if "--" in argv else argv[1:]


#: What a .blend file starts with: plain, zstd- (Blender 3+) or gzip-compressed (older).
BLEND_MAGIC = (b"BLENDER", b"\x28\xb5\x2f\xfd", b"\x1f\x8b")
#: Blender's last frame.
MAX_FRAME = 1048574


def build_parser(prog="render_sequence.py"):
    from pdeface.io.arguments import (
        existing_file,
        non_negative_float,
        non_negative_int,
        number_in,
        positive_float,
        positive_int,
        size,
    )

    frame = number_in(0, MAX_FRAME, int)
    ap = argparse.ArgumentParser(prog=prog, description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    src = ap.add_mutually_exclusive_group()
    src.add_argument("--timeline", help="pdeface.timeline JSON")
    src.add_argument("--sequence", help="comma-separated presets (default: the method's sequence)")
    src.add_argument("--au-data", help="an OpenFace / Py-Feat / Live Link Face CSV or FAS text file")
    ap.add_argument("--face", default="default", help="face model (.npz) or 'default'")
    ap.add_argument("--head", action="store_true", help="render ICT-FaceKit's whole head (eyes, teeth, lashes) "
                                                        "with every key on it, instead of the PDE face")
    ap.add_argument("--blend", type=existing_file((".blend",), BLEND_MAGIC), help="load this .blend (its PDE face) instead of building one")
    ap.add_argument("--out", default="render", help="output folder")
    ap.add_argument("--frame-start", type=frame, help="first frame to render (default: the timeline's first); "
                                                    "with --frame-end, a chunk")
    ap.add_argument("--frame-end", type=frame, help="last frame to render (default: the timeline's last)")
    ap.add_argument("--engine", default="CYCLES", choices=["CYCLES", "EEVEE", "WORKBENCH"],
                    help="Blender render engine (Cycles renders on the CPU)")
    ap.add_argument("--size", default="256x256", type=size, help="WIDTHxHEIGHT")
    ap.add_argument("--samples", type=positive_int, default=16,
                    help="Cycles samples per pixel (denoised where Blender has OpenImageDenoise)")
    ap.add_argument("--seed", type=non_negative_int, default=0, help="Cycles sampling seed (fixed, so chunks join seamlessly)")
    ap.add_argument("--fps", type=positive_float, default=24, help="frame rate of a --sequence or --au-data timeline "
                                                          "(a --timeline keeps its own)")
    ap.add_argument("--hold", type=positive_float, default=0.5, help="seconds each preset is held (--sequence)")
    ap.add_argument("--blend-time", type=non_negative_float, default=0.5, help="seconds between poses (--sequence)")
    ap.add_argument("--video", action="store_true", help="also write frames.mp4 (Blender's FFmpeg)")
    ap.add_argument("--contact-sheet", action="store_true", help="also write contact_sheet.png")
    ap.add_argument("--sheet-cell", type=number_in(1, 4096, int), default=256, help="contact sheet cell width in pixels")
    ap.add_argument("--sheet-samples", type=positive_int, default=4, help="contact sheet samples (denoised)")
    ap.add_argument("--sheet-band-vertices", type=number_in(0, 10**9, int), default=None,
                    help="contact sheet rendered in bands of whole rows of at most about this many vertices of "
                         "posed meshes (default: 250000; 0: the whole sheet in one render, as memory allows)")
    ap.add_argument("--plain-sheet", action="store_true", help="a contact sheet without its rows coloured by "
                                                               "how far each vertex moved (mm)")
    ap.add_argument("--no-frames", action="store_true", help="render no animation frames")
    ap.add_argument("--save-blend", help="save the scene to this .blend")
    ap.add_argument("--quiet", action="store_true", help="no progress bars")
    add_mesh_options(ap)
    ap.add_argument("--json", action="store_true", help="stdout: the JSON summary only (always so: "
                                                       "Blender's own messages go to stderr)")
    return ap


def add_mesh_options(ap):
    """``--mesh``: a head of the user's own, found, fitted and rigged here, and what that takes."""
    from pdeface.io.arguments import mesh_unit
    from pdeface.units import UNIT_FORMS

    g = ap.add_argument_group("a head of your own (instead of --face, --head or --blend)")
    g.add_argument("--mesh", help="head mesh (.obj, .ply, .glb or .gltf): its landmarks found (or --landmarks), "
                                  "a PDE face fitted, the bundled AU descriptors retargeted and every key put on "
                                  "the whole mesh, then rendered")
    g.add_argument("--landmarks", help="the mesh's 68 landmarks (JSON with 'indices' or 'points', as "
                                       "'pdeface landmarks' writes); default: found (needs pdeface[landmarks])")
    g.add_argument("--unit", type=mesh_unit, metavar="UNIT",
                   help=f"the mesh's unit: {UNIT_FORMS} (default: estimated from the face's size)")
    g.add_argument("--accept", action="store_true",
                   help="go on where the landmark gate refuses: found landmarks that fail it, or a mesh whose eyes "
                        "are closed (as pdeface rig --accept)")


def rig_mesh_file(context, addon, path, landmarks=None, unit=None, accept=False):
    """The user's head file as a Blender object with every AU and expression key (``--mesh``); returns it.

    Read, landmarked, gated and fitted as ``pdeface rig`` does (the landmark gate on found landmarks, the look at
    the mesh's eyes with given ones; ``accept`` goes on past them), rigged as the add-on's Fit does
    (:func:`rigging.add_head_mesh`).
    """
    from pdeface.landmarks.checked import check_given, find_checked
    from pdeface.surface.scan import load_scan

    def say(line):
        sys.stderr.write(f"{path}: {line}\n")

    mesh, lm = load_scan(path, landmarks)
    if lm is None:
        found, _ = find_checked(mesh, unit, accept=accept, log=say)
        say(f"found the 68 landmarks (detector score {found.score:.2f}, {found.residual_mm:.1f} mm from the template)")
        lm = found.points
    else:
        check_given(mesh, lm, unit, accept=accept, log=say)
    # Blender's importers turn OBJ's and glTF's +Y up to +Z; a PLY keeps its axes.
    y_up = Path(path).suffix.lower() != ".ply"
    return addon.rigging.add_head_mesh(context, Path(path).stem, mesh, lm, unit=unit, y_up=y_up)


def enable_addon(bpy, repo_name="pdeface_render"):
    """Enable the add-on from this checkout as an extension (if it is not installed already).

    This folder (the add-on) is linked into a new local extension
    repository ``repo_name``; returns the add-on's module name.
    """
    import addon_utils

    for name in list(addon_utils.addons_fake_modules) + [m.module for m in bpy.context.preferences.addons]:
        if name.endswith(".pdeface") and name.startswith("bl_ext.") and name in bpy.context.preferences.addons:
            return name
    repo = Path(tempfile.mkdtemp(prefix=f"{repo_name}_repo_"))
    try:
        os.symlink(ADDON_DIR, repo / "pdeface")
    except OSError:
        import shutil
        shutil.copytree(ADDON_DIR, repo / "pdeface")
    bpy.context.preferences.extensions.repos.new(name=repo_name, module=repo_name, custom_directory=str(repo),
                                                 source="USER")
    module = f"bl_ext.{repo_name}.pdeface"
    if addon_utils.enable(module, default_set=True) is None:
        raise SystemExit("could not enable the PDE Face add-on")
    return module


#: Keep Blender and the add-on as they are after a render (:func:`render_here`: the next call reuses them).
_KEEP = False


def render_here(argv, prog="pdeface batch"):
    """Run :func:`main` with ``argv`` in this process, keeping Blender (the bpy module, imported once) and the
    add-on enabled for the next call: a batch worker's one Blender, each render starting from a scene reset by
    ``read_homefile`` or ``open_mainfile``. Returns (exit status, the lines it wrote to ``sys.stderr``)."""
    global _KEEP
    _KEEP = True
    err = io.StringIO()
    try:
        with contextlib.redirect_stderr(err):
            status = main(["--", *map(str, argv)], prog=prog, summary=io.StringIO())
    except SystemExit as exc:  # argparse's error, or a check of main's
        status = exc.code if isinstance(exc.code, int) else 2
        if not isinstance(exc.code, int) and exc.code:
            err.write(f"{exc.code}\n")
    return status, err.getvalue()


def blend_identity(path):
    """The user's head in an add-on's ``.blend`` (``pdeface rig --blend``, the add-on's Fit): its first PDE face
    and the mesh it drives (else the face itself), opened in this process's Blender (kept, as
    :func:`render_here`). Returns a dict of numpy arrays in the face model's frame (mm, +z front, +y up):
    ``vertices`` (the mesh's basis), ``triangles``, ``landmarks`` (the model's 68), ``names`` and ``deltas`` of
    its shape keys (each key minus the basis); and ``object``, the mesh's name."""
    global _KEEP
    _KEEP = True
    if "bpy" not in sys.modules:
        os.environ.setdefault("BLENDER_USER_RESOURCES", tempfile.mkdtemp(prefix="pdeface_blender_"))
    import bpy
    import numpy as np
    from pdeface.errors import PdeFaceError
    from pdeface.surface.model import model_landmarks

    module = enable_addon(bpy)
    addon = __import__(module, fromlist=["bridge", "face"])
    try:
        with blender_output_aside(shown=False):
            bpy.ops.wm.open_mainfile(filepath=str(Path(path).resolve()), load_ui=False)
    except RuntimeError as exc:
        raise PdeFaceError(f"{path}: cannot open ({str(exc).strip().splitlines()[-1]})") from None
    faces = [o for o in bpy.data.objects if o.type == "MESH" and o.pdeface.is_face]
    if not faces:
        raise PdeFaceError(f"{path}: no PDE face in it (make one with the add-on's Fit or pdeface rig --blend)")
    face = faces[0]
    shown = next(iter(addon.face.user_objects(face)), face)
    frame = addon.bridge.face_model(face).frame  # the model was fitted to this mesh's object space
    keys = shown.data.shape_keys
    blocks = list(keys.key_blocks) if keys is not None else []
    basis = (addon.bridge.key_coords(blocks[0]) if blocks else addon.bridge.vertices(shown.data)).astype(np.float64)
    rest = frame.to_face(basis)
    names = [b.name for b in blocks[1:]]
    deltas = [frame.to_face(addon.bridge.key_coords(b).astype(np.float64)) - rest for b in blocks[1:]]
    return {"vertices": rest, "triangles": addon.bridge.triangles(shown.data)[0],
            "landmarks": model_landmarks(addon.bridge.face_model(face)), "names": names,
            "deltas": np.array(deltas).reshape(len(names), *rest.shape), "object": shown.name}


#: Stages whose start line went out and whose end line has not (stderr not a terminal).
_STAGES_BEGUN = set()


def progress_bar(done, total, label, quiet):
    """A bar redrawn in place on a terminal; elsewhere (a log file, a pipe) a line when a stage starts and one
    when it ends, not a line per step."""
    if quiet:
        return
    if getattr(sys.stderr, "isatty", lambda: False)():
        width = 30
        n = int(width * done / max(total, 1))
        sys.stderr.write(f"\r{label} [{'#' * n}{'.' * (width - n)}] {done}/{total}")
        if done >= total:
            sys.stderr.write("\n")
    elif done >= total:
        _STAGES_BEGUN.discard(label)
        sys.stderr.write(f"{label}: done ({done}/{total})\n")
    elif label not in _STAGES_BEGUN:
        _STAGES_BEGUN.add(label)
        sys.stderr.write(f"{label}: started ({done}/{total})\n")
    sys.stderr.flush()


def _flush_c_stdout():
    """Flush the C library's stdout buffer (Blender's printf), so it lands where fd 1 points now."""
    import ctypes
    try:
        libc = ctypes.CDLL(None) if os.name == "posix" else ctypes.CDLL("ucrtbase")  # Blender's C runtime
        libc.fflush(None)
    except (OSError, AttributeError):  # no C library to reach: Python's own flush is all there is
        pass


@contextlib.contextmanager
def blender_output_aside(shown=True):
    """File descriptor 1 points at stderr inside (``shown``) or at the null device: Blender's ``Saved: …``
    lines, one per frame, cannot mix with the JSON summary, nor fill a log file.

    Yields a text stream on the real stdout; fd 1 is restored however the block ends.
    """
    sys.stdout.flush()
    _flush_c_stdout()
    saved = os.dup(1)
    aside = os.open(os.devnull, os.O_WRONLY) if not shown else None
    try:
        os.dup2(2 if shown else aside, 1)
        with os.fdopen(os.dup(saved), "w") as real:
            yield real
            sys.stdout.flush()
            _flush_c_stdout()
    finally:
        os.dup2(saved, 1)
        os.close(saved)
        if aside is not None:
            os.close(aside)


def main(argv=None, prog="render_sequence.py", summary=None):
    """Render as the arguments say; the JSON summary goes to the real stdout, or to the text stream ``summary``."""
    ap = build_parser(prog)
    args = ap.parse_args(script_args(sys.argv if argv is None else argv))
    if args.mesh and (args.blend or args.head or args.face != "default"):
        ap.error("--mesh renders your head: drop --face, --head and --blend")
    if not args.mesh and (args.landmarks or args.unit):
        ap.error("--landmarks and --unit are for --mesh")
    if (args.sheet_band_vertices or 0) < 0:
        ap.error(f"--sheet-band-vertices {args.sheet_band_vertices}: use 0 (one render) or a positive count")
    # Blender's own lines (a Saved line per frame, its warnings) to stderr; none with --quiet.
    with blender_output_aside(shown=not args.quiet) as stdout:
        return render_job(args, prog, summary or stdout)


def render_job(args, prog, stdout):
    """Render what ``args`` ask; the JSON summary goes to ``stdout``. Returns the exit status."""
    if "bpy" not in sys.modules:  # plain python: keep Blender's user config out of the user's home
        os.environ.setdefault("BLENDER_USER_RESOURCES", tempfile.mkdtemp(prefix="pdeface_blender_"))
    progress_bar(0, 1, "Blender start-up", args.quiet)
    import bpy

    module = enable_addon(bpy)
    progress_bar(1, 1, "Blender start-up", args.quiet)
    addon = __import__(module, fromlist=["animation", "face", "keys", "render", "rigging"])
    render = addon.render
    from pdeface.errors import PdeFaceError, one_line
    try:
        width, height = (int(v) for v in args.size.lower().split("x"))
    except ValueError:
        raise SystemExit(f"--size {args.size!r}: use WIDTHxHEIGHT") from None
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    summary = {}
    try:
        progress_bar(0, 1, "rig", args.quiet)
        if args.blend:
            try:
                bpy.ops.wm.open_mainfile(filepath=str(args.blend))
            except RuntimeError as exc:  # a damaged .blend: Blender's own one line
                raise PdeFaceError(f"{args.blend}: cannot open ({str(exc).strip().splitlines()[-1]})") from None
            faces = [o for o in bpy.context.scene.objects if o.type == "MESH" and o.pdeface.is_face]
            if not faces:
                raise SystemExit(f"{args.blend}: no PDE face in the scene")
            face = faces[0]
            bpy.context.view_layer.objects.active = face
            shown = next(iter(addon.face.user_objects(face)), face)
        elif args.mesh:
            bpy.ops.wm.read_homefile(use_empty=True)
            shown = rig_mesh_file(bpy.context, addon, args.mesh, args.landmarks, args.unit, args.accept)
            face = shown.pdeface.rig_face
        elif args.head:
            bpy.ops.wm.read_homefile(use_empty=True)
            shown = addon.rigging.add_ict_head(bpy.context)
            face = shown.pdeface.rig_face
        else:
            bpy.ops.wm.read_homefile(use_empty=True)
            face = addon.face.add_face(bpy.context, "" if args.face == "default" else str(Path(args.face).resolve()))
            addon.keys.build_keys(face, addon.keys.all_presets(bpy.context.scene))
            shown = face
        progress_bar(1, 1, "rig", args.quiet)
        scene = bpy.context.scene
        t0 = time.perf_counter()
        timeline = None
        if args.timeline:
            from pdeface.animation.timeline import load_timeline
            timeline = load_timeline(args.timeline)
        elif args.au_data:
            from pdeface.animation.trackers import import_au
            result = import_au(args.au_data, fps=args.fps)
            timeline = result.timeline
            summary["au_data"] = {"format": result.format, "rows": result.rows, "dropped": result.dropped,
                                  "unknown": result.unknown}
        elif not args.blend or args.sequence:
            from pdeface.animation.sequence import METHOD_SEQUENCE
            from pdeface.animation.timeline import sequence_timeline
            names = [n.strip() for n in (args.sequence or ",".join(METHOD_SEQUENCE)).split(",") if n.strip()]
            timeline = sequence_timeline(names, args.fps, args.hold, args.blend_time)
        if timeline is not None:
            first, last, missing = addon.animation.apply_timeline(face, timeline)
            scene.frame_start, scene.frame_end = first, last
            if missing:
                sys.stderr.write(f"this face has no shape key for: {', '.join(missing)} (skipped)\n")
            summary["timeline"] = {"frame_start": first, "frame_end": last, "fps": timeline.fps}
            fps = timeline.fps
        else:
            fps = scene.render.fps
        render.setup_render(scene, shown, args.engine, (width, height), args.samples, args.seed, fps)
        summary["setup_s"] = time.perf_counter() - t0
        start = scene.frame_start if args.frame_start is None else args.frame_start
        end = scene.frame_end if args.frame_end is None else args.frame_end
        if not args.no_frames:
            t = time.perf_counter()
            frames = render.render_frames(scene, out / "frames", start, end,
                                          lambda d, n: progress_bar(d, n, "frames", args.quiet))
            summary["frames"] = len(frames)  # frames/frame_####.png, frame_start to frame_end
            summary["frames_dir"] = str(out / "frames")
            summary["render_s"] = time.perf_counter() - t
            if args.video:
                summary["video"] = str(render.make_video(frames, fps, out / "frames.mp4"))
        if args.contact_sheet:
            progress_bar(0, 1, "contact sheet", args.quiet)
            path, cells = render.contact_sheet(shown, out / "contact_sheet.png", cell=args.sheet_cell,
                                               samples=args.sheet_samples, motion=not args.plain_sheet,
                                               band_vertices=render.SHEET_BAND_VERTICES if args.sheet_band_vertices
                                               is None else args.sheet_band_vertices or None)
            progress_bar(1, 1, "contact sheet", args.quiet)
            summary["contact_sheet"], summary["contact_sheet_cells"] = str(path), cells
        if args.save_blend:
            bpy.ops.wm.save_as_mainfile(filepath=str(Path(args.save_blend).resolve()), copy=True)
            summary["blend"] = str(args.save_blend)
    except PdeFaceError as exc:
        sys.stderr.write(f"{prog}: error: {one_line(exc)}\n")
        return 2
    finally:
        import addon_utils
        if module == MODULE and not _KEEP:
            addon_utils.disable(module, default_set=True)
    summary.update({"frame_start": start, "frame_end": end, "engine": args.engine})
    print(json.dumps(summary), file=stdout)
    return 0


if __name__ == "__main__":
    sys.exit(main())  # inside blender -b -P too: Blender exits with this status
