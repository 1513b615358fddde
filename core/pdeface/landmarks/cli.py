"""``pdeface landmarks``: find the 68 landmarks of a head mesh, no clicks."""
from __future__ import annotations

import json
import sys
import time

import numpy as np

from ..io.files import check_output


def _log(msg):
    print(msg, file=sys.stderr, flush=True)


def find_on_mesh(mesh, unit=None, keep_images=False):
    """:func:`~pdeface.landmarks.detect` on a :class:`~pdeface.mesh.Mesh`, logging what it found."""
    from .pipeline import detect

    t = time.perf_counter()
    found = detect(mesh.vertices, mesh.triangles()[0], unit, keep_images=keep_images)
    low = min(found.confidence, key=found.confidence.get)
    _log(f"found the 68 landmarks in {time.perf_counter() - t:.1f} s (view {found.view}, detector score "
         f"{found.score:.2f}, {found.residual_mm:.1f} mm from the template; least sure: {low} "
         f"{found.confidence[low]:.2f})")
    return found


def cmd_landmarks(args):
    from ..assets import load_scan
    from ..io.files import atomic_open

    check_output(args.output, args.mesh)
    if args.image:
        check_output(args.image, args.mesh)
    mesh, _ = load_scan(args.mesh)
    found = find_on_mesh(mesh, args.unit, keep_images=bool(args.image))
    with atomic_open(args.output) as f:
        json.dump(found.to_json(), f)
    if args.image:
        from ..io.png import write_png
        from .render import marked

        x, y, _ = found.images["view"].project(found.points)
        write_png(args.image, marked(found.images["frontal"], np.stack([x, y], 1)))
    print(json.dumps({"output": str(args.output), "view": found.view, "detector_score": round(found.score, 3),
                      "confidence": {k: round(v, 3) for k, v in found.confidence.items()}}))


def add_parser(sub, output_option):
    """The ``landmarks`` command."""
    from ..surface.frame import UNITS_MM

    p = sub.add_parser("landmarks", help="find the 68 Multi-PIE landmarks on a head or body mesh "
                                         "(needs pdeface[landmarks])")
    p.add_argument("mesh", help="head or body mesh (.obj/.ply), any orientation and unit, or 'head'")
    p.add_argument("--unit", choices=list(UNITS_MM), help="mesh unit, for the mm figures (default: from the face)")
    p.add_argument("--image", help="also write the frontal render with the landmarks marked (.png)")
    output_option(p, help="landmarks JSON to write ('indices' and 'points', with confidence per group)")
    p.set_defaults(func=cmd_landmarks)
    return p
