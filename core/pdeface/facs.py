"""The FACS Action Unit catalogue and intensity letters.

The catalogue (``data/facs.json``) lists every AU with its number, name,
region (``upper`` face, ``lower`` face, ``eyes_head``) and muscles.

Intensity letters map to weights at the top of five equal bins:
A (trace) 0.2, B (slight) 0.4, C (marked) 0.6, D (severe) 0.8, E (maximum) 1.0;
a weight maps back to the letter of its bin (0 → no letter).
"""
from __future__ import annotations

import json
import math
import numbers
import re
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

from .errors import PdeFaceError

INTENSITY = {"A": 0.2, "B": 0.4, "C": 0.6, "D": 0.8, "E": 1.0}
REGIONS = {"upper": "Upper face", "lower": "Lower face", "eyes_head": "Eyes & head"}
SIDES = ("both", "left", "right")


@dataclass(frozen=True)
class ActionUnit:
    au: int
    name: str
    region: str
    muscles: tuple

    @property
    def label(self) -> str:
        """``"AU12 Lip Corner Puller"``."""
        return f"AU{self.au} {self.name}"


@lru_cache(maxsize=1)
def catalogue() -> dict:
    """All FACS AUs: ``{number: ActionUnit}``."""
    data = json.loads((Path(__file__).resolve().parent / "data" / "facs.json").read_text())
    return {d["au"]: ActionUnit(d["au"], d["name"], d["region"], tuple(d["muscles"])) for d in data["action_units"]}


def action_unit(au: int) -> ActionUnit:
    """One AU of the catalogue; :class:`PdeFaceError` for an unknown number."""
    try:
        return catalogue()[int(au)]
    except (KeyError, ValueError):
        raise PdeFaceError(f"AU{au} is not a FACS Action Unit") from None


def letter_to_weight(letter: str) -> float:
    """FACS intensity letter A-E → weight."""
    try:
        return INTENSITY[letter.upper()]
    except (KeyError, AttributeError):
        raise PdeFaceError(f"intensity {letter!r} is not a FACS letter A-E") from None


def clamp_weight(weight) -> float:
    """One AU weight clamped to [0, 1] (the one rule every reader applies)."""
    return min(max(float(weight), 0.0), 1.0)


def clamp_weights(weights, out=None):
    """A numpy array of AU weights clamped to [0, 1] (see :func:`clamp_weight`).

    (A method of the array: this module stays free of numpy, which the stream player does not need.)
    """
    return weights.clip(0.0, 1.0, out=out)


def weight_to_letter(weight: float) -> str:
    """Weight in [0, 1] → FACS letter ('' for 0)."""
    w = clamp_weight(weight)
    return "" if w <= 0 else "ABCDE"[min(4, max(0, math.ceil(round(w * 5, 9)) - 1))]


_KEY = re.compile(r"^(?:AU)?(\d{1,4})([LR]?)$", re.IGNORECASE)  # the key grammar (zero-padded to 4 digits at most)


def parse_au_key(key) -> str:
    """Normalise ``12``, ``"AU12"``, ``"au12l"`` → ``"12"``, ``"12L"``; checks the catalogue."""
    m = _KEY.match(str(key).strip())
    if not m:
        raise PdeFaceError(f"{str(key)[:20]!r} is not an AU key (use 12, AU12, 12L or 12R)")
    action_unit(int(m.group(1)))
    return f"{int(m.group(1))}{m.group(2).upper()}"


def split_au_key(key: str) -> tuple[int, str]:
    """A normalised key → (AU number, side letter): ``"12L"`` → (12, "L"), ``"12"`` → (12, "")."""
    side = key[-1] if key[-1] in "LR" else ""
    return int(key[:-1] if side else key), side


def au_number(key: str) -> int:
    """A normalised key's AU number: ``"12L"`` → 12."""
    return split_au_key(key)[0]


def key_side(key: str) -> tuple[int, str]:
    """``"12L"`` → (12, 'left')."""
    au, side = split_au_key(parse_au_key(key))
    return au, {"L": "left", "R": "right"}.get(side, "both")


def parse_weight(value, where="weight") -> float:
    """A weight: number (clamped to [0, 1]) or FACS letter A-E."""
    if isinstance(value, str):
        return letter_to_weight(value)
    try:
        number = float(value) if isinstance(value, numbers.Real) else math.nan  # numpy's numbers too
    except OverflowError:  # an integer of hundreds of digits
        number = math.nan
    if isinstance(value, bool) or not math.isfinite(number):  # numpy's bool_ is no numbers.Real
        raise PdeFaceError(f"{where}: {str(value)[:20]!r} is not a weight (a number in [0, 1] or a letter A-E)")
    return clamp_weight(number)


def normalise_weights(weights: dict) -> dict:
    """``{"AU12": 0.8, 6: "C"}`` → ``{"12": 0.8, "6": 0.6}``."""
    return {parse_au_key(k): parse_weight(v, f"AU{k}") for k, v in weights.items()}


def parse_au_weights(items) -> dict:
    """AU weights written ``AU=WEIGHT``, as the command line's ``--au`` takes them.

    Parameters
    ----------
    items : iterable of str, or None
        ``["12=1", "6=0.5", "AU4=C"]``: an AU key, ``=``, then a number (clamped to [0, 1]) or a
        FACS intensity letter A-E. None or empty gives no weights.

    Returns
    -------
    dict
        Normalised AU key → weight: ``{"12": 1.0, "6": 0.5, "4": 0.6}``.

    Raises
    ------
    PdeFaceError
        An item without ``=``, an AU key that is not a FACS AU, or a weight that is neither a
        number nor a letter A-E (a one-line message naming the item).
    """
    weights = {}
    for item in items or []:
        key, sep, value = item.partition("=")
        if not sep:
            raise PdeFaceError(f"--au {item!r}: use AU=WEIGHT, e.g. 12=0.8 or 12L=C")
        try:
            value = float(value)
        except ValueError:
            pass  # a FACS letter
        weights[key] = value
    return normalise_weights(weights)
