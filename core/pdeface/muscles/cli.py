"""``pdeface muscles``: a face posed by muscle activations or by AUs made of them."""
from __future__ import annotations

import sys

from ..errors import PdeFaceError
from ..io.files import check_output


def cmd_muscles(args):
    from ..assets import load_face
    from ..io.meshio import write_mesh
    from ..surface.fit import face_mesh
    from .aus import MuscleBasis, activation_vector, load_table, mix_activations

    check_output(args.output, args.face, args.table)
    if bool(args.au) == bool(args.activation):
        raise PdeFaceError("give AU weights (--au 23=1) or muscle activations (--activation zygomatic_major_L=0.6)")
    face = load_face(args.face)
    table = load_table(args.table)
    if args.au:
        from ..cli import parse_au_weights

        weights = parse_au_weights(args.au)
        a = mix_activations(table.activations, weights, args.mixer)
        what = ", ".join(f"AU{k}={w:g}" for k, w in weights.items()) + f" ({args.mixer})"
    else:
        named = {}
        for item in args.activation:
            name, sep, value = item.partition("=")
            if not sep:
                raise PdeFaceError(f"--activation {item!r}: use MUSCLE=VALUE, e.g. zygomatic_major_L=0.6")
            try:
                named[name] = float(value)
            except ValueError:
                raise PdeFaceError(f"--activation {item!r}: {value!r} is not a number") from None
        a = activation_vector(named)
        what = ", ".join(args.activation)
    basis = MuscleBasis(face, table)
    if table.fields is not None and not basis.learned:
        print("note: the table's learned muscle fields were made for another curve layout; "
              "this face uses Waters' fields alone", file=sys.stderr)
    C, R = basis.curves(a)
    write_mesh(args.output, face_mesh(face, args.resolution, coefficients=face.coefficients + C,
                                      residual=face.residual + R))
    print(f"wrote {args.output}: {what}", file=sys.stderr)


def add_parser(sub, output_option, meshing_options):
    """The ``muscles`` command."""
    from .aus import ACTIVATION_MIXERS
    from .placement import MUSCLE_NAMES

    p = sub.add_parser("muscles", help="pose a face with Waters muscles: AUs from the muscle table, or activations")
    p.add_argument("face", help="face model (.npz) or 'default'")
    p.add_argument("--au", action="append", metavar="AU=W", help="AU weight from the muscle table (repeatable)")
    p.add_argument("--activation", action="append", metavar="MUSCLE=A",
                   help=f"a muscle's activation (repeatable); muscles: {', '.join(MUSCLE_NAMES)}")
    p.add_argument("--mixer", choices=ACTIVATION_MIXERS, default="sum",
                   help="how AUs' activations combine: sum, or the FAS's average / maximum per muscle")
    p.add_argument("--table", help="a muscle table file (default: the bundled one)")
    meshing_options(p)
    output_option(p)
    p.set_defaults(func=cmd_muscles)
    return p
