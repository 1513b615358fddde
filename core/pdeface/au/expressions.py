"""Expressions: AU weight sets, mixers, posing a face, and the linear shape basis.

Mixers combine the descriptors of several AUs per coefficient (the FAS
system's idea): ``sum`` (default, linear: Σ wᵢ Dᵢ), ``average`` (each
coefficient's sum divided by how many weighted AUs act on that curve) and
``max`` (each coefficient from the weighted AU with the largest magnitude).
Weights are clamped to [0, 1]; FACS letters A-E are accepted (see
:mod:`pdeface.au.facs`).

Presets (``PRESETS``): the method's six basic expressions (its Table 5-3: main
AUs at weight 1, supplementary AUs at ``SUPPLEMENTARY_WEIGHT``) and the four it
demonstrated (all AUs at 1).

Preset files (JSON)::

    {"format": "pdeface.preset", "version": 1, "name": "smirk",
     "weights": {"12L": 0.8, "6": "B"}, "mixer": "sum", "description": "..."}

or ``{"format": "pdeface.presets", "version": 1, "presets": [ ...objects as above... ]}``.
"""
from __future__ import annotations

import json
import math
from dataclasses import dataclass, field

import numpy as np

from ..errors import ModelFormatError, PdeFaceError
from .facs import clamp_weight, clamp_weights, letter_to_weight, parse_au_key, split_au_key

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


def parse_weight(value, where="weight") -> float:
    """A weight: number (clamped to [0, 1]) or FACS letter A-E."""
    if isinstance(value, str):
        return letter_to_weight(value)
    try:
        number = float(value) if isinstance(value, (int, float, np.integer, np.floating)) else math.nan
    except OverflowError:  # an integer of hundreds of digits
        number = math.nan
    if isinstance(value, (bool, np.bool_)) or not math.isfinite(number):
        raise PdeFaceError(f"{where}: {str(value)[:20]!r} is not a weight (a number in [0, 1] or a letter A-E)")
    return clamp_weight(number)


def normalise_weights(weights: dict) -> dict:
    """``{"AU12": 0.8, 6: "C"}`` → ``{"12": 0.8, "6": 0.6}``."""
    return {parse_au_key(k): parse_weight(v, f"AU{k}") for k, v in weights.items()}


def mix(descriptors: dict, weights: dict, mixer: str = "sum") -> tuple[np.ndarray, np.ndarray]:
    """Combine weighted descriptors into one change of coefficients and residual.

    Parameters
    ----------
    descriptors : dict
        AU key → :class:`~pdeface.au.descriptor.Descriptor` (one layout).
    weights : dict
        AU key → weight; keys must be in ``descriptors``.
    mixer : {'sum', 'average', 'max'}

    Returns
    -------
    dC : (K, N+1, 3) array
    dR : (K, J, 3) array
    """
    if mixer not in MIXERS:
        raise PdeFaceError(f"unknown mixer {mixer!r}; use one of {', '.join(MIXERS)}")
    if mixer.startswith("muscle-"):
        raise PdeFaceError(f"the {mixer} mixer mixes muscle activations: pose the face with pose_curves")
    if not descriptors:
        raise PdeFaceError("this face carries no AU descriptors")
    layout = next(iter(descriptors.values())).layout
    K, J, N = layout
    dC, dR = np.zeros((K, N + 1, 3)), np.zeros((K, J, 3))
    count = np.zeros(K)
    for key, w in weights.items():
        w = parse_weight(w, f"AU{key}")
        if key not in descriptors:
            raise PdeFaceError(f"AU{key} has no descriptor in this face (has: {', '.join(sorted(descriptors, key=split_au_key))})")
        d = descriptors[key]
        if d.layout != layout:
            raise PdeFaceError(f"AU{key}: descriptor layout {d.layout} differs from {layout}")
        if w == 0:
            continue
        C, R = d.dense()
        C, R = w * C, w * R
        if mixer == "max":
            np.copyto(dC, C, where=np.abs(C) > np.abs(dC))
            np.copyto(dR, R, where=np.abs(R) > np.abs(dR))
        else:
            dC += C
            dR += R
        count[d.curves] += 1
    if mixer == "average":
        div = np.maximum(count, 1)[:, None, None]
        dC, dR = dC / div, dR / div
    return dC, dR


def resolve_preset(preset: Preset, available) -> tuple[dict, list]:
    """Weights of a preset restricted to the available AU keys, and the missing keys."""
    weights, missing = {}, []
    for k, w in normalise_weights(preset.weights).items():
        (weights.__setitem__(k, w) if k in available else missing.append(k))
    return weights, missing


def choose_mixer(requested=None, preset: Preset | None = None) -> str:
    """The mixer to pose with: the one asked for, else the preset's own, else ``sum``."""
    mixer = requested or (preset.mixer if preset is not None else "sum")
    if mixer not in MIXERS:
        raise PdeFaceError(f"unknown mixer {mixer!r}; use one of {', '.join(MIXERS)}")
    return mixer


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


def pose_curves(model, weights: dict, mixer: str = "sum"):
    """Coefficients and residual of ``model`` posed with AU ``weights``.

    The ``muscle-*`` mixers combine the AUs' muscle activations (the bundled muscle table's,
    :mod:`pdeface.muscles.aus`) instead of their descriptors.
    """
    if mixer in ("muscle-average", "muscle-max"):
        from ..muscles.aus import muscle_pose
        dC, dR = muscle_pose(model, normalise_weights(weights), mixer)
        return model.coefficients + dC, model.residual + dR
    descriptors = {d.key: d for d in model.descriptors}
    dC, dR = mix(descriptors, normalise_weights(weights), mixer)
    return model.coefficients + dC, model.residual + dR


class ShapeBasis:
    """The posed face as a linear function of AU weights (``sum`` mixer).

    ``vertices(W) = neutral + W @ deltas``: one matrix product per batch of
    faces, in the source mesh's space, same vertex order as
    :func:`pdeface.surface.fit.face_mesh`. This is what Blender shape keys are.
    """

    def __init__(self, model, resolution="default", assembly=None, dtype=np.float32):
        from ..surface.fit import face_mesh, surface_grid
        from ..surface.sampling import mesh_resolution

        su, sv = mesh_resolution(model, resolution)
        self.keys = [d.key for d in model.descriptors]
        self.neutral = face_mesh(model, (su, sv), assembly).vertices
        n = len(model.descriptors)
        dense = [d.dense() for d in model.descriptors]
        # All AUs in one solve: stacked along the last axis (the solve is linear).
        C = np.concatenate([c for c, _ in dense], axis=2) if n else np.zeros(model.coefficients.shape[:2] + (0,))
        R = np.concatenate([r for _, r in dense], axis=2) if n else np.zeros(model.residual.shape[:2] + (0,))
        D = surface_grid(model, su, sv, assembly, coefficients=C, residual=R).reshape(-1, n, 3)
        D = model.frame.to_user_vectors(D)  # (vertices, n, 3)
        # Stored vertex-major (column-major deltas): sgemm with the short AU axis innermost is fastest.
        self._deltas_t = np.ascontiguousarray(D.transpose(0, 2, 1).reshape(-1, n).astype(dtype))
        self.neutral_flat = self.neutral.ravel().astype(dtype)

    @property
    def deltas(self) -> np.ndarray:
        """(n_keys, n_vertices * 3) vertex offsets of each AU at weight 1."""
        return self._deltas_t.T

    def weights_matrix(self, weights: dict) -> np.ndarray:
        """One row of weights in :attr:`keys` order."""
        w = np.zeros(len(self.keys), dtype=self.deltas.dtype)
        for k, v in normalise_weights(weights).items():
            if k not in self.keys:
                raise PdeFaceError(f"AU{k} has no descriptor in this face")
            w[self.keys.index(k)] = v
        return w

    def vertices(self, W: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
        """Faces for weight rows ``W (B, n_keys)`` → (B, n_vertices, 3).

        ``out`` (B, n_vertices * 3), when given, is filled and reused, which
        keeps batch evaluation allocation-free.
        """
        W = clamp_weights(np.atleast_2d(np.asarray(W, dtype=self._deltas_t.dtype)))
        if out is None:
            out = np.empty((len(W), self._deltas_t.shape[0]), dtype=self._deltas_t.dtype)
        np.matmul(W, self.deltas, out=out)
        out += self.neutral_flat
        return out.reshape(len(W), -1, 3)


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
    if mixer not in MIXERS:
        raise ModelFormatError(f"{where}: field 'mixer' must be one of {', '.join(MIXERS)}")
    return Preset(name, weights, mixer, str(obj.get("description", "")))


def save_presets(path, presets) -> None:
    """Write one preset, or several in a ``pdeface.presets`` file."""
    presets = list(presets)
    obj = preset_to_json(presets[0]) if len(presets) == 1 else \
        {"format": "pdeface.presets", "version": 1, "presets": [preset_to_json(p) for p in presets]}
    from ..io.files import atomic_open

    with atomic_open(path, "w", encoding="utf-8") as fh:
        json.dump(obj, fh, indent=1)


def load_presets(path) -> list:
    """Read a preset file (one preset or a ``pdeface.presets`` list)."""
    from ..io.files import load_json

    obj = load_json(path)
    if isinstance(obj, dict) and obj.get("format") == "pdeface.presets":
        items = obj.get("presets")
        if not isinstance(items, list):
            raise ModelFormatError(f"{path}: field 'presets' must be a list")
        return [preset_from_json(p, f"{path}: presets[{i}]") for i, p in enumerate(items)]
    return [preset_from_json(obj, str(path))]


def merged_presets(paths=()) -> dict:
    """The built-in presets with those of preset files laid over them.

    Parameters
    ----------
    paths : iterable of str or os.PathLike
        Preset files (one preset or a ``pdeface.presets`` list each), read in
        turn; a preset replaces any earlier one of the same name, built-in or
        from an earlier file.

    Returns
    -------
    dict
        ``{name: Preset}``: the built-in presets (:data:`PRESETS`) first, in
        their order, then the files' new names in the order read.

    Raises
    ------
    PdeFaceError
        A file that cannot be read or is not a preset file (as
        :func:`load_presets`).
    """
    presets = dict(PRESETS)
    for path in paths:
        presets.update({p.name: p for p in load_presets(path)})
    return presets
