"""``pdeface render``: the add-on's headless renderer, run in a child Python with the bpy module."""
from __future__ import annotations

from ..headless import run_headless


def cmd_render(args):
    code, _ = run_headless(args.extra)
    if code:
        raise SystemExit(code)


def register(sub):
    """The ``render`` command: its arguments pass on to the renderer, which describes them."""
    p = sub.add_parser("render", add_help=False, help="render a timeline, presets or AU data headless "
                                                      "(pdeface render --help lists its options)")
    p.set_defaults(func=cmd_render, passes_arguments_on=True)
