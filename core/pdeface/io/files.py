"""Opening a user's files with errors that name the file (the one way pdeface does it)."""
from __future__ import annotations

import json

from ..errors import ModelFormatError


def open_file(path, mode="r", error=ModelFormatError, **kwargs):
    """``open(path, mode, **kwargs)``; a failure raises ``error`` (a PdeFaceError subclass) naming the file."""
    try:
        return open(path, mode, **kwargs)
    except OSError as exc:
        raise error(f"{path}: cannot open ({exc.strerror})") from None


def read_bytes(path, error=ModelFormatError) -> bytes:
    """A whole file's bytes (see :func:`open_file`)."""
    with open_file(path, "rb", error) as fh:
        return fh.read()


def read_lines(path, error=ModelFormatError) -> list:
    """A UTF-8 text file's lines (undecodable bytes replaced; see :func:`open_file`)."""
    with open_file(path, "r", error, encoding="utf-8", errors="replace") as fh:
        return fh.read().splitlines()


def load_json(path, error=ModelFormatError):
    """Parse a JSON file; ``error`` names the file and line of a problem."""
    try:
        with open_file(path, "r", error, encoding="utf-8") as fh:
            return json.load(fh)
    except json.JSONDecodeError as exc:
        raise error(f"{path}: not valid JSON ({exc.msg}, line {exc.lineno})") from None
    except UnicodeDecodeError:
        raise error(f"{path}: not UTF-8 text") from None
