"""Reading JSON files with errors that name the file (the one way pdeface does it)."""
from __future__ import annotations

import json

from ..errors import ModelFormatError


def load_json(path, error=ModelFormatError):
    """Parse a JSON file; ``error`` (a PdeFaceError subclass) names the file and line of a problem."""
    try:
        with open(path, "r", encoding="utf-8") as fh:
            return json.load(fh)
    except OSError as exc:
        raise error(f"{path}: cannot open ({exc.strerror})") from None
    except json.JSONDecodeError as exc:
        raise error(f"{path}: not valid JSON ({exc.msg}, line {exc.lineno})") from None
    except UnicodeDecodeError:
        raise error(f"{path}: not UTF-8 text") from None
