"""``pdeface landmarks``: find the 68 landmarks of a head mesh, no clicks."""
from __future__ import annotations

import json

from ..io.files import atomic_open, check_output
from ..io.png import write_png
from ..landmarks.checked import find_checked
from ..landmarks.gate import LandmarkGateError
from ..surface.scan import load_scan
from ..units import UNIT_FORMS
from .common import log, output_option, unit_option, verbose_option


def find_landmarks(mesh, unit=None, keep_images=False, verbose=False, accept=False):
    """:func:`~pdeface.landmarks.checked.find_checked` saying what it found on stderr (also for ``pdeface fit``)."""
    return find_checked(mesh, unit, keep_images=keep_images, verbose=verbose, accept=accept, log=log)


def cmd_landmarks(args):
    check_output(args.output, args.mesh)
    if args.image:
        check_output(args.image, args.mesh)
    mesh, _ = load_scan(args.mesh)
    try:
        found, verdict = find_landmarks(mesh, args.unit, keep_images=bool(args.image), verbose=args.verbose,
                                        accept=args.accept)
    except LandmarkGateError as exc:
        if args.image:  # the picture of what failed, the landmarks themselves not written
            write_png(args.image, exc.found.marked_image())
            exc.args = (f"{exc.args[0]} (picture: {args.image})",)
        raise
    data = {**found.to_json(), "gate": verdict.to_json()}
    with atomic_open(args.output) as f:
        json.dump(data, f, allow_nan=False)  # strictly valid JSON: no bare NaN
    if args.image:
        write_png(args.image, found.marked_image())
    print(json.dumps({"output": str(args.output), "view": found.view, "detector_score": round(found.score, 3),
                      "confidence": {k: round(v, 3) for k, v in found.confidence.items()},
                      "mm_per_unit": round(found.mm_per_unit, 6), "gate": verdict.passed}))


def accept_option(p, given=True):
    """``--accept``: go on with found landmarks that fail the gate and, where the command takes ``--landmarks``
    (``given``), with given ones on a mesh the gate's look at it refuses (its eyes closed)."""
    found = ("go on with found landmarks that fail the landmark gate (a group off the surface, not mirrored, out of "
             "order or out of proportion, or the eyes closed)")
    p.add_argument("--accept", action="store_true",
                   help=found + (", or with given ones (--landmarks) on a mesh whose eyes are closed" if given else ""))


def register(sub):
    """The ``landmarks`` command."""
    p = sub.add_parser("landmarks", help="find the 68 Multi-PIE landmarks on a head or body mesh "
                                         "(needs pdeface[landmarks])")
    p.add_argument("mesh", help="head or body mesh (.obj/.ply/.glb/.gltf), any orientation and unit, or 'head'")
    unit_option(p, f"mesh unit, for the mm figures: {UNIT_FORMS} (default: from the face)")
    p.add_argument("--image", help="also write the frontal render with the landmarks marked (.png); written also "
                                   "when the gate stops")
    accept_option(p, given=False)
    output_option(p, help="landmarks JSON to write ('indices' and 'points', with confidence per group)")
    verbose_option(p)
    p.set_defaults(func=cmd_landmarks)
