"""Argument types: each checks one command-line option's value at parse time.

A bad value is then argparse's usage error (exit 2, one line naming the option:
``argument --modes: '-1' is not in [0, 64]``) before any file is read. Shared by
``pdeface`` (whose AU and meshing types are in :mod:`pdeface.cli.common`) and the
add-on's headless renderer (``pdeface render``), which may not import the CLI.
"""
from __future__ import annotations

import argparse
import math

from ..errors import PdeFaceError
from ..units import parse_unit
from .files import MAX_DIGITS, whole_digits


def _number(text, kind):
    text = str(text).strip()
    digits = len(text) > MAX_DIGITS and whole_digits(text)
    if digits > MAX_DIGITS:  # as in every file pdeface reads: no count, rate or weight needs more
        raise argparse.ArgumentTypeError(f"{text[:12]}... has {digits} digits (at most {MAX_DIGITS})")
    try:
        value = kind(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text[:40]!r} is not {'an integer' if kind is int else 'a number'}") \
            from None
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"{text[:40]!r} is not a finite number")
    return value


def number_in(low=None, high=None, kind=float, low_open=False, what="", zero=False):
    """An argparse type: a finite ``kind`` (float or int) in [low, high] (``low_open``: low excluded; ``zero``:
    0 too, an "off" or "no limit" outside the range).

    ``what`` names the range in the message (default: the bounds).
    """
    def parse(text):
        value = _number(text, kind)
        if zero and value == 0:
            return value
        if (low is not None and (value < low or (low_open and value == low))) or (high is not None and value > high):
            lo, hi = ("-inf" if low is None else f"{low:g}"), ("inf" if high is None else f"{high:g}")
            bounds = ("(" if low_open else "[") + f"{lo}, {hi}]"
            raise argparse.ArgumentTypeError(f"{text.strip()[:40]!r} is not {what or 'in ' + bounds}")
        return value

    parse.__name__ = kind.__name__  # argparse names the type in some messages
    return parse


#: > 0 and finite: rates, durations, sizes.
positive_float = number_in(0.0, low_open=True, what="a positive number")
#: >= 0 and finite: tolerances.
non_negative_float = number_in(0.0, what="a number >= 0")
#: >= 1: counts.
positive_int = number_in(1, kind=int, what="a whole number >= 1")
#: >= 0: indices, seeds.
non_negative_int = number_in(0, kind=int, what="a whole number >= 0")
#: [0, 1]: weights, confidences.
unit_float = number_in(0.0, 1.0)


def mesh_unit(text):
    """An argparse type: a mesh unit (:func:`pdeface.units.parse_unit`: a name, or millimetres per unit such as
    ``0.01`` or ``0.01mm``); returns the text as given, stripped, for the commands to pass on."""
    try:
        parse_unit(text)
    except PdeFaceError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None
    return str(text).strip()


#: A TCP port.
port = number_in(1, 65535, int, what="a port number (1-65535)")


def address(text, default_host="127.0.0.1") -> tuple:
    """An argparse type: ``HOST:PORT`` or ``PORT`` → (host, port); ``:PORT`` is on ``default_host``."""
    host, sep, number = str(text).rpartition(":")
    if sep and not host.strip("[]"):
        host = default_host
    try:
        return (host.strip("[]") if sep else default_host), port(number if sep else text)
    except argparse.ArgumentTypeError:
        raise argparse.ArgumentTypeError(f"{text[:60]!r}: use HOST:PORT or PORT, the port 1-65535") from None


def file_name(text):
    """An argparse type: a file's name that is not blank (an option given ``""`` is refused, not taken as absent)."""
    if not str(text).strip():
        raise argparse.ArgumentTypeError("an empty file name (leave the option out instead)")
    return text


def existing_file(suffixes=(), magic=()):
    """An argparse type: a file that exists and is a file, named with one of ``suffixes`` and starting with one
    of the byte strings ``magic`` (where given)."""
    def parse(text):
        from pathlib import Path

        path = Path(text)
        if not path.is_file():
            raise argparse.ArgumentTypeError(f"{text}: no such file")
        if suffixes and path.suffix.lower() not in suffixes:
            raise argparse.ArgumentTypeError(f"{text}: not a {' or '.join(suffixes)} file")
        if magic:
            try:
                with open(path, "rb") as f:
                    head = f.read(max(len(m) for m in magic))
            except OSError as exc:
                raise argparse.ArgumentTypeError(f"{text}: {exc.strerror}") from None
            if not any(head.startswith(m) for m in magic):
                raise argparse.ArgumentTypeError(f"{text}: not a {' or '.join(suffixes) or 'valid'} file "
                                                 "(its first bytes say otherwise)")
        return text

    return parse


#: The largest frame a renderer is asked for, per side.
MAX_FRAME_SIDE = 16384


def size(text):
    """An argparse type: a frame size ``WIDTHxHEIGHT``, each 1 to :data:`MAX_FRAME_SIDE` pixels; returns the text."""
    parts = str(text).lower().split("x")
    side = number_in(1, MAX_FRAME_SIDE, int)
    try:
        if len(parts) != 2:
            raise argparse.ArgumentTypeError("")
        for p in parts:
            side(p)
    except argparse.ArgumentTypeError:
        raise argparse.ArgumentTypeError(f"{text[:40]!r}: use WIDTHxHEIGHT, each 1 to {MAX_FRAME_SIDE} pixels") \
            from None
    return text
