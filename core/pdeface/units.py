"""Mesh units: millimetres per unit, by name or by number, and the one rule that reads them.

A unit is a name (:data:`UNITS_MM`) or any number of millimetres per unit (``0.01``, ``0.01mm``: a head modelled
at 100 times its size); :func:`parse_unit` reads either, wherever a unit is given (the commands' ``--unit``, a
batch job, the add-on, a model file's ``unit``).
"""
from __future__ import annotations

import math
import numbers

from .errors import LandmarkError

#: Millimetres per mesh unit (decimetres: MakeHuman's base mesh).
UNITS_MM = {"mm": 1.0, "cm": 10.0, "dm": 100.0, "m": 1000.0, "in": 25.4}
#: The unit of a mesh whose scale is none of :data:`UNITS_MM`: its millimetres per unit are the face's own estimate.
ESTIMATED = "estimated"
#: The longest unit text read (a number's digits and "mm"): a model file's field is no place for more.
MAX_TEXT = 40
#: How a unit is given, for messages.
UNIT_FORMS = f"{', '.join(UNITS_MM)} or millimetres per unit (e.g. 0.01 or 0.01mm)"


def parse_unit(unit) -> tuple[str, float]:
    """The unit's name and millimetres per unit.

    Parameters
    ----------
    unit : str or float
        A name of :data:`UNITS_MM`, or a positive number of millimetres per unit, as a number or as text with or
        without ``mm`` after it (``"0.01"``, ``"0.01mm"``, ``"0.01 mm"``).

    Returns
    -------
    name : str
        The unit's name; for a number, the name of the unit it equals, else the number as text (``"0.01mm"``,
        which this reads back).
    mm_per_unit : float

    Raises
    ------
    LandmarkError
        Anything else, the value named.
    """
    if isinstance(unit, str):
        text = unit.strip().lower()
        if text in UNITS_MM:
            return text, UNITS_MM[text]
        number = text.removesuffix("mm").strip()
        try:
            mm = float(number) if len(text) <= MAX_TEXT else None
        except ValueError:
            mm = None
        if mm is None:
            raise LandmarkError(f"unknown unit {unit[:MAX_TEXT]!r}: use {UNIT_FORMS}")
    elif isinstance(unit, numbers.Real) and not isinstance(unit, bool):
        mm = float(unit)
    else:
        raise LandmarkError(f"unknown unit {str(unit)[:MAX_TEXT]!r}: use {UNIT_FORMS}")
    if not (math.isfinite(mm) and mm > 0):
        raise LandmarkError(f"unit {str(unit)[:MAX_TEXT]!r}: millimetres per unit must be a positive number")
    named = [name for name, value in UNITS_MM.items() if value == mm]
    if named:
        return named[0], mm
    return (f"{mm:g}" if float(f"{mm:g}") == mm else repr(mm)) + "mm", mm
