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
import atexit
import importlib
import os
import sys
import threading

from .. import __version__
from ..errors import PdeFaceError, one_line
from ..heap import keep_heap
from ..threads import bounded_threads
from .common import HelpFormatter

#: Each command and the module of its group, in the order ``pdeface --help`` lists them. A command imports only
#: its own group (the groups import most of the library: all of them took a third of a second, issue #35);
#: tests/core/test_cli.py checks this table against what the groups register.
COMMANDS = {"fit": "face", "mesh": "face", "report": "face", "parts": "face", "descriptor": "au", "pose": "au",
            "retarget": "au", "au-report": "au", "import-au": "au", "aus": "aus", "fdt": "fdt", "muscles": "muscles",
            "landmarks": "landmarks", "rig": "rig", "stream": "stream", "render": "render", "batch": "batch",
            "demo": "demo"}
#: The command groups' modules, in that order.
GROUPS = tuple(dict.fromkeys(COMMANDS.values()))


def build_parser(command=None):
    """The ``pdeface`` parser: every group's subcommands, each showing its options' defaults; only the group of
    ``command`` (a name of :data:`COMMANDS`) when given."""
    ap = argparse.ArgumentParser(prog="pdeface", description="PDE face models and FACS Action Units.")
    ap.add_argument("--version", action="version", version=f"pdeface {__version__}")
    sub = ap.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for group in (COMMANDS[command],) if command in COMMANDS else GROUPS:
        importlib.import_module(f".{group}", __name__).register(sub)
    for parser in subcommands(ap).values():
        parser.formatter_class = HelpFormatter
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
    argv = sys.argv[1:] if argv is None else list(argv)
    # the command is the first word that is not an option (pdeface's own options take no value)
    ap = build_parser(next((a for a in argv if not a.startswith("-")), None))
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


def run():
    """The ``pdeface`` command (the entry point, ``python -m pdeface.cli``): :func:`main`, then the process ends.

    The interpreter is not torn down: freeing every module, scipy's and MediaPipe's among them, took 0.1-0.3 s
    after a ``pdeface rig`` had written everything (issue #35). What exit would still do is done first: the
    exit handlers registered with :mod:`atexit` (temporary folders, logging, Dask's clients), then stdout and
    stderr flushed. A thread still working (not a daemon) is waited for as ever: the plain exit.

    The command's process keeps numpy's big arrays in the C heap (:func:`pdeface.heap.keep_heap`: half the page
    faults of a 27k head's rig). The library's functions leave the allocator as they find it: a script or Blender
    that imports them decides for its own process.
    """
    keep_heap()
    code = main()
    if any(t.is_alive() and not t.daemon for t in threading.enumerate() if t is not threading.main_thread()):
        sys.exit(code)
    atexit._run_exitfuncs()  # what Python runs first at exit (private but there since 2.x)
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (AttributeError, OSError, ValueError):  # closed, or a pipe whose reader left
            code = code or 1
    os._exit(code)
