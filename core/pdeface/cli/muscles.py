"""``pdeface muscles``: a face posed by muscle activations or by AUs made of them."""
from __future__ import annotations

from ..au.modelfile import load_face
from ..errors import PdeFaceError
from ..facs import parse_au_weights
from ..io.files import check_output
from ..io.meshio import write_mesh
from ..muscles.aus import (
    ACTIVATION_MIXERS,
    MuscleBasis,
    activation_vector,
    load_table,
    mix_activations,
    parse_activations,
)
from ..muscles.placement import MUSCLE_NAMES
from ..surface.fit import face_mesh
from .common import au_weight, log, meshing_options, output_option, weights_text


def cmd_muscles(args):
    check_output(args.output, args.face, args.table)
    if bool(args.au) == bool(args.activation):
        raise PdeFaceError("give AU weights (--au 23=1) or muscle activations (--activation zygomatic_major_L=0.6)")
    face = load_face(args.face)
    table = load_table(args.table)
    if args.au:
        weights = parse_au_weights(args.au)
        a = mix_activations(table.activations, weights, args.mixer)
        what = weights_text(weights, args.mixer)
    else:
        a = activation_vector(parse_activations(args.activation))
        what = ", ".join(args.activation)
    basis = MuscleBasis(face, table)
    if table.fields is not None and not basis.learned:
        log("note: the table's learned muscle fields were made for another curve layout; "
            "this face uses Waters' fields alone")
    C, R = basis.curves(a)
    write_mesh(args.output, face_mesh(face, args.resolution, coefficients=face.coefficients + C,
                                      residual=face.residual + R))
    log(f"wrote {args.output}: {what}")


def register(sub):
    """The ``muscles`` command."""
    p = sub.add_parser("muscles", help="pose a face with Waters muscles: AUs from the muscle table, or activations")
    p.add_argument("face", help="face model (.npz) or 'default'")
    p.add_argument("--au", action="append", metavar="AU=W", type=au_weight, help="AU weight from the muscle table (repeatable)")
    p.add_argument("--activation", action="append", metavar="MUSCLE=A",
                   help=f"a muscle's activation (repeatable); muscles: {', '.join(MUSCLE_NAMES)}")
    p.add_argument("--mixer", choices=ACTIVATION_MIXERS, default="sum",
                   help="how AUs' activations combine: sum, or the FAS's average / maximum per muscle")
    p.add_argument("--table", help="a muscle table file (default: the bundled one)")
    meshing_options(p)
    output_option(p)
    p.set_defaults(func=cmd_muscles)
