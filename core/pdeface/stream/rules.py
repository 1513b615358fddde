"""The AU blender: co-occurrence and dominance rules applied to incoming AU sets.

Rules come from a data file (default ``data/au_rules.json``)::

    {"format": "pdeface.au_rules", "version": 1,
     "exclusive": [[5, 43], ...],          # never together: the stronger stays
     "supersedes": {"27": [26, 25], ...}}  # present, it removes these

Rules name AU numbers and apply to both sides (``12``, ``12L``, ``12R``). Off
unless chosen, as in the FAS player.
"""
from __future__ import annotations

from pathlib import Path

from ..errors import ModelFormatError
from ..facs import au_number
from ..io.files import load_json

DEFAULT_RULES = Path(__file__).resolve().parent.parent / "data" / "au_rules.json"


class AUBlender:
    def __init__(self, exclusive=(), supersedes=None):
        self.exclusive = [tuple(int(a) for a in pair) for pair in exclusive]
        self.supersedes = {int(k): [int(a) for a in v] for k, v in (supersedes or {}).items()}

    @classmethod
    def load(cls, path=DEFAULT_RULES) -> "AUBlender":
        obj = load_json(path)
        if not isinstance(obj, dict) or obj.get("format") != "pdeface.au_rules":
            raise ModelFormatError(f"{path}: field 'format' must be 'pdeface.au_rules'")
        ex = obj.get("exclusive", [])
        if not isinstance(ex, list) or not all(isinstance(p, list) and len(p) == 2 and all(isinstance(a, int) for a in p)
                                               for p in ex):
            raise ModelFormatError(f"{path}: field 'exclusive' must be a list of [AU, AU] pairs")
        sup = obj.get("supersedes", {})
        if not isinstance(sup, dict) or not all(isinstance(v, list) and all(isinstance(a, int) for a in v)
                                                for v in sup.values()):
            raise ModelFormatError(f"{path}: field 'supersedes' must map an AU to a list of AUs")
        try:
            return cls(ex, {int(k): v for k, v in sup.items()})
        except ValueError:
            raise ModelFormatError(f"{path}: field 'supersedes' keys must be AU numbers") from None

    def apply(self, weights: dict) -> dict:
        """The AU set with the rules applied (a new dict, order kept)."""
        out = {k: w for k, w in weights.items() if w > 0}
        present = {au_number(k) for k in out}
        for au, removed in self.supersedes.items():
            if au in present:
                out = {k: w for k, w in out.items() if au_number(k) not in removed}
                present = {au_number(k) for k in out}
        for a, b in self.exclusive:
            if a in present and b in present:
                wa = max(w for k, w in out.items() if au_number(k) == a)
                wb = max(w for k, w in out.items() if au_number(k) == b)
                loser = b if wa >= wb else a
                out = {k: w for k, w in out.items() if au_number(k) != loser}
                present.discard(loser)
        return out
