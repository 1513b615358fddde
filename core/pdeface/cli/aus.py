"""``pdeface aus``: the AUs a face model carries and the presets it can pose."""
from __future__ import annotations

import json

from ..au.descriptor import descriptor_rows, no_descriptors
from ..au.modelfile import load_face
from ..presets import merged_presets, preset_rows
from .common import json_option


def _inventory(face, preset_files=()) -> dict:
    """``{"face", "aus", "presets"}`` (and ``hint`` for a face without descriptors): what ``pdeface aus`` prints."""
    model = load_face(face)
    aus = descriptor_rows(model.descriptors)
    out = {"face": str(face), "aus": aus,
           "presets": preset_rows(merged_presets(preset_files), {r["key"] for r in aus})}
    if not aus:
        out["hint"] = no_descriptors(face)
    return out


def _table(rows, columns) -> list:
    """Rows of dicts as lines of left-aligned columns (``columns``: heading → row key)."""
    cells = [list(columns)] + [[str(r[k]) for k in columns.values()] for r in rows]
    widths = [max(len(c[i]) for c in cells) for i in range(len(columns) - 1)]
    return ["  ".join([c.ljust(w) for c, w in zip(line, widths)] + [line[-1]]).rstrip() for line in cells]


def cmd_aus(args):
    inv = _inventory(args.face, args.presets or [])
    if args.json:
        print(json.dumps(inv))
        return
    if inv["aus"]:
        print(f"{args.face}: {len(inv['aus'])} AU descriptors (pose FACE --au KEY=WEIGHT)")
        # the source as recorded, where it says more than its kind (a muscle descriptor's says "muscle")
        rows = [{**r, "curves": len(r["curves"]), "source": r["source"] if r["source"] not in ("", r["kind"]) else "-"}
                for r in inv["aus"]]
        print("\n".join(_table(rows, {"key": "key", "AU": "au", "FACS name": "name", "side": "side",
                                      "source": "kind", "curves": "curves", "from": "source"})))
    else:
        print(inv["hint"])
    print("\npresets (pose FACE --preset NAME; --presets FILE adds your own):")
    rows = [{**r, "lacks": ", ".join(r["missing"]) or "-"} for r in inv["presets"]]
    print("\n".join(_table(rows, {"preset": "name", "mixer": "mixer", "recipe (AU key, weight if not 1)": "recipe",
                                  "this face lacks (skipped)": "lacks"})))


def register(sub):
    """The ``aus`` command."""
    p = sub.add_parser("aus", help="list a face's AUs (FACS name, side, source) and the presets with their recipes")
    p.add_argument("face", help="face model (.npz) or 'default'")
    p.add_argument("--presets", action="append", metavar="FILE",
                   help="user preset JSON file to list as well (repeatable)")
    json_option(p)
    p.set_defaults(func=cmd_aus)
