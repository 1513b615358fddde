"""The ``pdeface`` command line.

Wherever a command takes a face model, ``default`` means the bundled one;
wherever it takes a scan mesh, ``default`` means the bundled ICT-FaceKit
neutral face.

One module per command group, each registering its own subcommands
(``register(sub)``): :mod:`.face` (fit, mesh, report, parts), :mod:`.au`
(descriptor, pose, retarget, au-report, import-au), :mod:`.aus` (the AUs and
presets a face has), :mod:`.fdt`,
:mod:`.muscles`, :mod:`.landmarks`, :mod:`.rig`, :mod:`.stream`, :mod:`.render`,
:mod:`.batch` and :mod:`.demo`; what they share is in :mod:`.common`. The library functions
they call live in their concerns' modules and return results: the commands
parse, call and print.
"""
from __future__ import annotations

import argparse
import sys

from .. import __version__
from ..errors import PdeFaceError, one_line
from ..threads import bounded_threads
from . import au, aus, batch, demo, face, fdt, landmarks, muscles, render, rig, stream
from .common import HelpFormatter

#: The command groups, in the order ``pdeface --help`` lists their commands.
GROUPS = (face, au, aus, fdt, muscles, landmarks, rig, stream, render, batch, demo)


def build_parser():
    """The ``pdeface`` parser: every group's subcommands, each showing its options' defaults."""
    ap = argparse.ArgumentParser(prog="pdeface", description="PDE face models and FACS Action Units.")
    ap.add_argument("--version", action="version", version=f"pdeface {__version__}")
    sub = ap.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for group in GROUPS:
        group.register(sub)
    for command in subcommands(ap).values():
        command.formatter_class = HelpFormatter
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
    """Run one ``pdeface`` command; returns its exit status (2 for a :class:`PdeFaceError` or a file error).

    A bad argument is argparse's usage error (``SystemExit(2)``); any other exception is a bug and shows
    its traceback.
    """
    ap = build_parser()
    args, extra = ap.parse_known_args(argv)
    if extra and not getattr(args, "passes_arguments_on", False):
        ap.error(f"unrecognized arguments: {' '.join(extra)}")
    args.extra = extra  # pdeface render passes its arguments on to the renderer
    try:
        with bounded_threads():  # BLAS threads that do not spin beside other work (pdeface.threads)
            args.func(args)
    except PdeFaceError as exc:
        print(f"pdeface: error: {one_line(exc)}", file=sys.stderr)
        return 2
    except BrokenPipeError:  # output piped into head & co.
        return 1
    except OSError as exc:
        print(f"pdeface: error: {one_line(str(exc.filename or '') + ': ' + str(exc.strerror or exc))}", file=sys.stderr)
        return 2
    return 0
