"""``pdeface demo``: the main job on the bundled face: fit, mesh, report, and (with bpy) rig and render."""
from __future__ import annotations

import json
from pathlib import Path

from ..animation.sequence import METHOD_SEQUENCE
from ..assets import DEFAULT, ICT_NOTICE
from ..au.modelfile import save_model
from ..errors import PdeFaceError
from ..headless import run_headless
from ..io.arguments import positive_float, positive_int, size
from ..io.files import write_bytes
from ..io.meshio import write_mesh
from ..surface.fit import face_mesh, fit_face
from ..surface.report import accuracy_report
from ..surface.scan import load_scan
from .common import log


def cmd_demo(args):
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    total = 3 if args.no_render else 4
    mesh, lm = load_scan(DEFAULT)
    T, _ = mesh.triangles()
    log(f"[1/{total}] fit")
    model, _ = fit_face(mesh.vertices, T, lm, unit="cm", source="ICT-FaceKit generic neutral (face region)")
    model.notice = ICT_NOTICE
    size = save_model(out / "face.npz", model)
    log(f"[2/{total}] mesh")
    write_mesh(out / "face.obj", face_mesh(model))
    log(f"[3/{total}] report")
    result = accuracy_report(model, mesh.vertices, T, profiles_png=out / "profiles.png",
                             profiles_csv=out / "profiles.csv")
    result["model_bytes"] = size
    write_bytes(out / "report.json", json.dumps(result, indent=2).encode())
    log(f"wrote {out}/face.npz, face.obj, report.json, profiles.png, profiles.csv")
    if not args.no_render:
        log(f"[4/{total}] rig, animation, render (Blender, headless)")
        result["render"] = render_demo(out, args)
    print(json.dumps(result))


def render_demo(out, args):
    """The rig on ICT-FaceKit's whole head, the method's sequence, frames, contact sheet and .blend (bpy).

    Runs in a child process (:func:`~pdeface.headless.run_headless`), so this package never imports bpy itself.
    """
    argv = ["--head", "--sequence", ",".join(METHOD_SEQUENCE), "--out", str(out), "--fps", str(args.fps), "--hold", "0.33",
            "--blend-time", "0.33", "--size", args.size, "--samples", str(args.samples), "--contact-sheet",
            "--save-blend", str(out / "demo.blend")] + (["--video"] if args.video else [])
    code, stdout = run_headless(argv, capture=True)
    if code != 0:
        raise PdeFaceError(f"rendering failed (exit {code}); see the messages above")
    try:
        summary = json.loads(stdout)  # the renderer's stdout is its JSON summary alone
    except json.JSONDecodeError:
        raise PdeFaceError(f"the renderer printed no JSON summary (got {stdout[:80]!r})") from None
    log(f"wrote {summary.get('frames', 0)} frames in {out}/frames, {out}/contact_sheet.png, {out}/demo.blend")
    return {k: summary[k] for k in ("frame_start", "frame_end", "contact_sheet", "blend", "render_s") if k in summary}


def register(sub):
    """The ``demo`` command."""
    p = sub.add_parser("demo", help="the main job on the bundled face")
    p.add_argument("--out", default="out", help="output folder")
    p.add_argument("--no-render", action="store_true", help="fit, mesh and report only (no bpy needed)")
    p.add_argument("--size", default="192x192", type=size, help="frame size, WIDTHxHEIGHT")
    p.add_argument("--samples", type=positive_int, default=16, help="Cycles samples per pixel")
    p.add_argument("--fps", type=positive_float, default=12, help="frames per second of the animation")
    p.add_argument("--video", action="store_true", help="also write frames.mp4")
    p.set_defaults(func=cmd_demo)
