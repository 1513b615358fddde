"""What the commands share: messages, the options several take, the help format, and output.

A command prints its result on stdout (one JSON object or lines) and its
progress and notes on stderr (:func:`log`); errors are handled once, in
:func:`pdeface.cli.main`.
"""
from __future__ import annotations

import argparse
import sys

from ..io.arguments import mesh_unit, number_in, unit_float
from ..surface.folds import fold_edges
from ..surface.model import model_landmarks
from ..surface.pde import ASSEMBLIES
from ..units import UNIT_FORMS

UNIT_HELP = f"mesh unit: {UNIT_FORMS} (default: estimated from the face's size, any scale)"



def log(msg):
    """A progress line or note on stderr (stdout carries the command's result)."""
    print(msg, file=sys.stderr, flush=True)


def plain_scipy_docs():
    """Have scipy keep its functions' docstrings as written in this process, not rewrite them when imported.

    scipy ≥ 1.15 parses and rewrites some 300 docstrings as its modules load (a note on the Array API backends
    each, through ``scipy._lib._docscrape.FunctionDoc``): 0.15 s of CPU of ``pdeface rig``'s 3 s (issue #35),
    for docstrings a command never shows. Before scipy's subpackages load, the decorators doing it are handed
    :class:`_DocAsWritten`; a scipy whose internals differ, or where they no longer take it, is left alone.
    Only the commands call it: a script or Blender importing pdeface keeps scipy's docstrings.
    """
    try:
        from scipy._lib import _array_api, _util
    except ImportError:  # no scipy, or another layout: nothing to do
        return
    users = [m for m in (_array_api, _util) if isinstance(getattr(m, "FunctionDoc", None), type)]
    saved = {m: m.FunctionDoc for m in users}
    for m in users:
        m.FunctionDoc = _DocAsWritten
    try:  # the decorator as scipy's modules apply it, on a function of ours
        _array_api.xp_capabilities(capabilities_table={})(plain_scipy_docs)
    except Exception:  # noqa: BLE001 - whatever broke: scipy's own docstring rewriting as before
        for m, cls in saved.items():
            m.FunctionDoc = cls


class _DocAsWritten(dict):
    """What scipy's docstring decorators use of a ``FunctionDoc``: sections to add to (empty) and the text,
    which is the docstring as written (after a signature line, which they cut)."""

    def __init__(self, func, *args, **kwargs):
        super().__init__()
        self.text = getattr(func, "__doc__", None) or ""

    def __missing__(self, section):
        return self.setdefault(section, [])

    def __str__(self):
        return "\n" + self.text


class HelpFormatter(argparse.ArgumentDefaultsHelpFormatter):
    """Shows each option's default, where it has one worth showing."""

    def _get_help_string(self, action):
        if action.default is None or action.default is False or "default" in (action.help or ""):
            return action.help
        return super()._get_help_string(action)


def output_option(p, help="file to write"):
    p.add_argument("-o", "--output", required=True, help=help)


def assembly_option(p):
    p.add_argument("--assembly", choices=ASSEMBLIES, help="assembly to mesh with (default: the model's own)")


def meshing_options(p):
    p.add_argument("--resolution", default="default", type=resolution,
                   help="default (steps per interval chosen for the face: more where it creases), original, "
                        "fine, or ROWS,COLS subdivisions")
    assembly_option(p)


def unit_option(p, help=UNIT_HELP):
    p.add_argument("--unit", type=mesh_unit, metavar="UNIT", help=help)


def verbose_option(p):
    """``--verbose`` for the commands that run the landmark detector."""
    p.add_argument("--verbose", action="store_true",
                   help="also show MediaPipe's own log lines (TensorFlow Lite, absl), silenced by default")


def json_option(p):
    p.add_argument("--json", action="store_true", help="print one JSON object")


def weights_text(weights: dict, mixer: str) -> str:
    """``AU12=1, AU6=0.5 (sum)``: the weights a face was posed with."""
    return ", ".join(f"AU{k}={w:g}" for k, w in weights.items()) + f" ({mixer})"


def turns(model, mesh, rest=None) -> str:
    """The mesh's largest turn between neighbouring faces outside the openings (issue #16's fold figure)."""
    r = fold_edges(mesh, model.frame, model_landmarks(model), rest=rest)
    return f"largest turn outside the eyes, mouth and nostrils {r['max_deg']:.0f}°, {r['count']} edges over 30°"



# The argument types of AUs and meshing (the others, which the renderer shares, are pdeface.io.arguments'):
# each checks one option's value at parse time, so a bad value is argparse's usage error (exit 2, one line
# naming the option: "argument --au: ...") before any file is read.

def au_number(text):
    """An argparse type: the number of an AU in the FACS catalogue (``12`` or ``AU12``)."""
    from ..errors import PdeFaceError
    from ..facs import action_unit

    digits = str(text).strip().upper().removeprefix("AU")
    try:
        return action_unit(number_in(kind=int)(digits)).au
    except PdeFaceError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def au_weight(text):
    """An argparse type: ``AU=WEIGHT`` with an AU key the catalogue has and a weight in [0, 1] or a letter A-E.

    Returns the text as given (:func:`pdeface.facs.parse_au_weights` reads it).
    """
    from ..errors import PdeFaceError
    from ..facs import INTENSITY, parse_au_key

    key, sep, value = str(text).partition("=")
    if not sep:
        raise argparse.ArgumentTypeError(f"{text[:40]!r}: use AU=WEIGHT, e.g. 12=0.8 or 12L=C")
    try:
        parse_au_key(key)
    except PdeFaceError:
        raise argparse.ArgumentTypeError(f"{key[:20]!r} is not a FACS AU key (use 12, AU12, 12L or 12R)") from None
    if value.strip().upper() not in INTENSITY:
        try:
            unit_float(value)
        except argparse.ArgumentTypeError:
            raise argparse.ArgumentTypeError(f"{text[:40]!r}: the weight is a number in [0, 1] or a letter A-E") \
                from None
    return text


def resolution(text):
    """An argparse type: a meshing resolution :func:`pdeface.surface.sampling.parse_resolution` takes."""
    from ..errors import PdeFaceError
    from ..surface.sampling import parse_resolution

    try:
        parse_resolution(text)
    except PdeFaceError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None
    return text
