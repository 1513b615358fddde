"""Presets: named AU weight sets, the mixers' names, and preset files.

Presets (:data:`PRESETS`): the method's six basic expressions (its Table 5-3: main
AUs at weight 1, supplementary AUs at :data:`SUPPLEMENTARY_WEIGHT`) and the four it
demonstrated (all AUs at 1). Mixers (:data:`MIXERS`) name how AUs acting on the same
curves combine; :mod:`pdeface.posing` applies them.

Preset files (JSON)::

    {"format": "pdeface.preset", "version": 1, "name": "smirk",
     "weights": {"12L": 0.8, "6": "B"}, "mixer": "sum", "description": "..."}

or ``{"format": "pdeface.presets", "version": 1, "presets": [ ...objects as above... ]}``.

This is FACS vocabulary, below the surface: it knows AU keys and weights, not descriptors.
"""
from __future__ import annotations

import json
from dataclasses import dataclass, field

from .errors import ModelFormatError, PdeFaceError
from .facs import normalise_weights, split_au_key
from .io.files import atomic_open, load_json

#: How AUs that move the same curves combine (the FAS's mixers); only ``sum`` is linear, i.e. plain shape keys.
MIXERS = {"sum": "Linear: the AUs' changes add up (shape keys)",
          "average": "Each coefficient averaged over the AUs acting on its curve",
          "max": "Each coefficient from the AU moving it most",
          "muscle-average": "The FAS's: each muscle's activation averaged over the AUs using it (muscle table)",
          "muscle-max": "The FAS's: each muscle's largest activation over the AUs (muscle table)"}
SUPPLEMENTARY_WEIGHT = 0.3

#: The method's Table 5-3: (main AUs, supplementary AUs).
BASIC_EXPRESSIONS = {
    "happy": ([12], [6, 16, 25, 26]),
    "sad": ([1, 15], [4, 17, 7, 25, 26]),
    "disgust": ([9], [10, 17, 25, 26]),
    "surprise": ([1, 2], [5, 26, 27]),
    "anger": ([23, 24], [2, 4, 9, 16, 17, 25, 26]),
    "fear": ([1, 2, 4], [5, 7, 20, 25, 26]),
}
#: The combinations the method demonstrated.
DEMONSTRATED = {"happy_6_12": [6, 12], "sad_1_4_15": [1, 4, 15], "fear_1_2_4": [1, 2, 4], "disgust_9_17": [9, 17]}


@dataclass
class Preset:
    """A named AU weight set."""

    name: str
    weights: dict
    mixer: str = "sum"
    description: str = ""
    builtin: bool = field(default=False, compare=False)

    @property
    def recipe(self) -> str:
        """``12 + 6 (0.3) + 16 (0.3)``: its AU keys, strongest first, each with its weight unless 1."""
        weights = normalise_weights(self.weights)
        keys = sorted(weights, key=lambda k: (-weights[k], split_au_key(k)))
        return " + ".join(k if weights[k] == 1 else f"{k} ({weights[k]:g})" for k in keys)


def _builtin_presets() -> dict:
    out = {}
    for name, (main, supp) in BASIC_EXPRESSIONS.items():
        w = {str(a): SUPPLEMENTARY_WEIGHT for a in supp}
        w.update({str(a): 1.0 for a in main})
        out[name] = Preset(name, w, "sum", f"{name}: main AUs {'+'.join(map(str, main))}, "
                           f"supplementary {', '.join(map(str, supp))} (method Table 5-3)", True)
    for name, aus in DEMONSTRATED.items():
        out[name] = Preset(name, {str(a): 1.0 for a in aus}, "sum",
                           f"AU {'+'.join(map(str, aus))} as demonstrated in the method", True)
    return out


PRESETS = _builtin_presets()


def resolve_preset(preset: Preset, available) -> tuple[dict, list]:
    """Weights of a preset restricted to the available AU keys, and the missing keys."""
    weights, missing = {}, []
    for k, w in normalise_weights(preset.weights).items():
        (weights.__setitem__(k, w) if k in available else missing.append(k))
    return weights, missing


def merged_presets(files=()) -> dict:
    """The built-in presets and those of preset files, by name.

    Parameters
    ----------
    files : iterable of path-like
        Preset files (see :func:`load_presets`), read in turn: a preset replaces an earlier one
        (built-in or from an earlier file) of the same name.

    Returns
    -------
    dict
        Preset name → :class:`Preset`: :data:`PRESETS` first, then each file's new names.

    Raises
    ------
    ModelFormatError
        A file that cannot be read or holds no valid preset.
    """
    presets = dict(PRESETS)
    for path in files:
        presets.update({p.name: p for p in load_presets(path)})
    return presets


def preset_rows(presets, available) -> list:
    """What presets are and which of their AUs a face lacks, one row per preset, in ``presets``' order.

    Parameters
    ----------
    presets : dict
        Name → :class:`Preset` (e.g. :func:`merged_presets`).
    available : collection of str
        The AU keys the face has descriptors for.

    Returns
    -------
    list of dict
        ``name``, ``recipe`` (:attr:`Preset.recipe`), ``weights`` (normalised), ``mixer``,
        ``builtin``, ``description`` and ``missing`` (its AU keys the face lacks, which
        :func:`resolve_preset` skips).
    """
    return [{"name": name, "recipe": p.recipe, "weights": normalise_weights(p.weights), "mixer": p.mixer,
             "builtin": p.builtin, "description": p.description,
             "missing": sorted(resolve_preset(p, available)[1], key=split_au_key)}
            for name, p in presets.items()]


def choose_mixer(requested=None, preset: Preset | None = None) -> str:
    """The mixer to pose with: the one asked for, else the preset's own, else ``sum``."""
    mixer = requested or (preset.mixer if preset is not None else "sum")
    if mixer not in MIXERS:
        raise PdeFaceError(f"unknown mixer {mixer!r}; use one of {', '.join(MIXERS)}")
    return mixer


def key_poses(model, presets, mixer=None, descriptors=None) -> dict:
    """``{name: (AU weights, mixer)}`` of every key a face gets: each descriptor at weight 1 (``AU<key>``),
    then each of ``presets`` (name → :class:`Preset`) this face has AUs for.

    ``mixer`` overrides the presets' own (see :func:`choose_mixer`); the AUs' is ``mixer`` or ``sum``.
    ``descriptors`` (default: the model's) are the ones keyed, e.g. a head's
    :meth:`~pdeface.head.bind.HeadBinding.bindable` (no gaze keys without eyeballs).
    """
    descriptors = model.descriptors if descriptors is None else descriptors
    keys = {d.key for d in descriptors}
    poses = {f"AU{d.key}": ({d.key: 1.0}, choose_mixer(mixer)) for d in descriptors}
    for name, preset in presets.items():
        weights = resolve_preset(preset, keys)[0]
        if weights:
            poses[name] = (weights, choose_mixer(mixer, preset))
    return poses


def every_pose(model) -> dict:
    """``{name: AU weights}``: rest (``neutral``), each descriptor at weight 1 (``AU<key>``) and each built-in
    preset this face has AUs for, as a sum: the poses a face's folds are measured in (issue #16)."""
    keys = {d.key for d in model.descriptors}
    poses = {"neutral": {}} | {f"AU{d.key}": {d.key: 1.0} for d in model.descriptors}
    for name, preset in PRESETS.items():
        weights = resolve_preset(preset, keys)[0]
        if weights:
            poses[name] = weights
    return poses


# ---------------------------------------------------------------- preset files

def preset_to_json(p: Preset) -> dict:
    return {"format": "pdeface.preset", "version": 1, "name": p.name, "weights": p.weights,
            "mixer": p.mixer, "description": p.description}


def preset_from_json(obj, where="preset") -> Preset:
    """Validate one preset object; errors name the field."""
    if not isinstance(obj, dict) or obj.get("format") != "pdeface.preset":
        raise ModelFormatError(f"{where}: field 'format' must be 'pdeface.preset'")
    if not isinstance(obj.get("version"), int) or obj["version"] > 1:
        raise ModelFormatError(f"{where}: field 'version' must be 1")
    name = obj.get("name")
    if not isinstance(name, str) or not name.strip():
        raise ModelFormatError(f"{where}: field 'name' must be a non-empty string")
    weights = obj.get("weights")
    if not isinstance(weights, dict) or not weights:
        raise ModelFormatError(f"{where}: field 'weights' must be an object of AU → weight")
    try:
        weights = normalise_weights(weights)
    except PdeFaceError as exc:
        raise ModelFormatError(f"{where}: field 'weights': {exc}") from None
    mixer = obj.get("mixer", "sum")
    if not isinstance(mixer, str) or mixer not in MIXERS:
        raise ModelFormatError(f"{where}: field 'mixer' must be one of {', '.join(MIXERS)}")
    return Preset(name, weights, mixer, str(obj.get("description", "")))


def save_presets(path, presets) -> None:
    """Write one preset, or several in a ``pdeface.presets`` file."""
    presets = list(presets)
    obj = preset_to_json(presets[0]) if len(presets) == 1 else \
        {"format": "pdeface.presets", "version": 1, "presets": [preset_to_json(p) for p in presets]}
    with atomic_open(path, "w", encoding="utf-8") as fh:
        json.dump(obj, fh, indent=1)


def load_presets(path) -> list:
    """Read a preset file (one preset or a ``pdeface.presets`` list)."""
    obj = load_json(path)
    if isinstance(obj, dict) and obj.get("format") == "pdeface.presets":
        items = obj.get("presets")
        if not isinstance(items, list):
            raise ModelFormatError(f"{path}: field 'presets' must be a list")
        return [preset_from_json(p, f"{path}: presets[{i}]") for i, p in enumerate(items)]
    return [preset_from_json(obj, str(path))]
