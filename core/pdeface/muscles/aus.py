"""AUs from muscles: activations → curve changes (a PDE descriptor), the FAS table and its mixers.

An AU is 24 activation values (:data:`~pdeface.muscles.placement.MUSCLE_NAMES`),
as the FAS records it. On a face model, the muscles (placed from its landmarks)
move its curve points; the change of their Fourier fit is the AU's descriptor
(source ``muscle``). The bundled table (``data/muscle_aus.json``, built by
``scripts/build/build_muscles.py``) holds the muscles' shapes fitted to ICT-FaceKit and, per AU,
activations calibrated against it (:meth:`MuscleBasis.calibrate`), or, for the AUs it has no shape
for, authored from FACS's muscles or from calibrated AUs (:data:`AUTHORED`).

Table file::

    {"format": "pdeface.muscle-aus", "version": 2, "muscles": [24 names],
     "geometry": {"zygomatic_major": {"zone": 20, ...}, ...},
     "fields": "muscle_fields.npz",
     "aus": {"12": {"activations": [24 numbers], "how": "calibrated"}, ...}, "notice": "..."}

``fields`` (optional; a file beside the table) names the muscles' corrections learned from scans
(:mod:`pdeface.muscles.fields`); without it the muscles are Waters' alone. Version 1 files (no
``fields``) are read too.

Mixers (the FAS's, on activations): ``muscle-average`` — per muscle, the sum of the
weighted activations over the AUs that activate it, divided by how many do;
``muscle-max`` — per muscle, the largest weighted activation (the one of largest
magnitude, for the muscles that also relax).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..au.descriptor import MUSCLE_SOURCE, descriptor_from_points
from ..errors import ModelFormatError, PdeFaceError
from ..facs import key_side, parse_au_key
from ..io.files import load_json
from ..surface.fourier import fit_fourier
from ..surface.model import model_landmarks
from .fields import LearnedFields, load_fields
from .placement import BOUNDS, DEFAULT_GEOMETRY, MUSCLE_NAMES, place_muscles

FORMAT, VERSION = "pdeface.muscle-aus", 2
#: Versions read: 1 had no learned fields.
READS = (1, 2)
TABLE = Path(__file__).resolve().parent.parent / "data" / "muscle_aus.json"
MUSCLE_MIXERS = ("muscle-average", "muscle-max")
#: How a set of AUs' activations combine: summed (linear, as the descriptors' keys), or the FAS's mixers.
ACTIVATION_MIXERS = ("sum",) + MUSCLE_MIXERS
#: AUs no ICT shape covers, authored from the muscles FACS names for them (activation vectors
#: given by muscle name, or ``"AU<key>"`` for a calibrated AU's activations; the rest 0). Their
#: strengths are set on the learned fields: AU23 presses the lips about as far as the scans' AU24
#: does. A wink is one eye's calibrated blink with its lids tightened (AU7 at a third: the
#: orbicularis oculi at its bound, 2.0). Authored as that muscle alone at 1.6 with the zygomatic at
#: 0.3, the orbicularis' learned correction (learned on blinks, which leave the lower lid) pulled
#: the lower lid 1.5 mm down, where a wink squeezes it up.
AUTHORED = {
    "13": {"levator_anguli_oris_R": 1.0, "levator_anguli_oris_L": 1.0},
    "13R": {"levator_anguli_oris_R": 1.0},
    "13L": {"levator_anguli_oris_L": 1.0},
    "23": {"orbicularis_oris": 0.5},
    "38": {"nasalis": -1.0, "levator_labii_alaeque_R": 0.2, "levator_labii_alaeque_L": 0.2},
    "39": {"nasalis": 1.0},
    "46R": {"AU45R": 1.0, "AU7R": 0.33},
    "46L": {"AU45L": 1.0, "AU7L": 0.33},
}
AUTHORED["46"] = AUTHORED["46R"]  # a wink is one eye's: the subject's right unless 46L is asked for


def activation_vector(named: dict) -> np.ndarray:
    """``{"zygomatic_major_L": 0.6}`` → a (24,) activation vector; unknown names are an error."""
    a = np.zeros(len(MUSCLE_NAMES))
    for name, value in named.items():
        if name not in MUSCLE_NAMES:
            raise PdeFaceError(f"no muscle {name!r}; the muscles are {', '.join(MUSCLE_NAMES)}")
        v = float(value)
        lo, hi = BOUNDS[name]
        if not (math.isfinite(v) and lo <= v <= hi):
            raise PdeFaceError(f"muscle {name}: activation {value!r} outside [{lo:g}, {hi:g}]")
        a[MUSCLE_NAMES.index(name)] = v
    return a


def parse_activations(items) -> dict:
    """Muscle activations written ``MUSCLE=VALUE``, as the command line's ``--activation`` takes them.

    Parameters
    ----------
    items : iterable of str
        ``["zygomatic_major_L=0.6", ...]``.

    Returns
    -------
    dict
        Muscle name → activation (checked by :func:`activation_vector`, not here).

    Raises
    ------
    PdeFaceError
        An item without ``=`` or whose value is not a number.
    """
    named = {}
    for item in items:
        name, sep, value = item.partition("=")
        if not sep:
            raise PdeFaceError(f"--activation {item!r}: use MUSCLE=VALUE, e.g. zygomatic_major_L=0.6")
        try:
            named[name] = float(value)
        except ValueError:
            raise PdeFaceError(f"--activation {item!r}: {value!r} is not a number") from None
    return named


def authored_activations(recipe: dict, calibrated: dict) -> np.ndarray:
    """An :data:`AUTHORED` recipe's (24,) activations: named muscles, plus ``"AU<key>"`` entries, each
    that calibrated AU's activations (``calibrated[key]``) times its weight; the sum must keep within
    :data:`BOUNDS`."""
    a = activation_vector({n: v for n, v in recipe.items() if not n.startswith("AU")})
    for name, weight in recipe.items():
        if name.startswith("AU"):
            if name[2:] not in calibrated:
                raise PdeFaceError(f"authored from {name}, which has no calibrated activations")
            a = a + float(weight) * np.asarray(calibrated[name[2:]], np.float64)
    lo, hi = np.array([BOUNDS[n] for n in MUSCLE_NAMES]).T
    out = [n for n, v, l, h in zip(MUSCLE_NAMES, a, lo, hi) if not l <= v <= h]
    if out:
        raise PdeFaceError(f"{recipe}: {', '.join(out)} outside their bounds")
    return a


@dataclass
class MuscleTable:
    """AU key → (24,) activations, how each was made, and the muscles they go with: their shapes
    (``geometry``) and corrections learned from scans (``fields``, a
    :class:`~pdeface.muscles.fields.LearnedFields`, or None for Waters' fields alone)."""

    activations: dict
    hows: dict = field(default_factory=dict)
    geometry: dict = field(default_factory=dict)
    notice: str = ""
    fields: LearnedFields | None = None


def turns_jaw(activations) -> bool:
    """Whether activations open the jaw (a head binding then turns the lower teeth and tongue)."""
    return float(np.asarray(activations)[MUSCLE_NAMES.index("jaw")]) > 0


class MuscleBasis:
    """A face model's muscles and the curve-point displacement of each at activation 1.

    ``table``: a :class:`MuscleTable` whose muscle shapes (``geometry``) and learned corrections
    (``fields``) to use; the bundled table's when None. ``waters`` holds the Waters fields alone,
    ``fields`` with the corrections; ``learned`` says whether they were applied (not where the
    face's curve layout is not the one they were learned on).
    """

    def __init__(self, face, table: MuscleTable | None = None):

        table = load_table() if table is None else table
        self.face = face
        self.geometry = table.geometry
        self.muscles = place_muscles(model_landmarks(face), self.geometry)
        X = face.curve_points()
        self.shape = X.shape
        self.waters = np.stack([m.displacement(X.reshape(-1, 3)).reshape(X.shape) for m in self.muscles])
        corrections = None if table.fields is None else table.fields.on(face)
        self.learned = corrections is not None
        self.fields = self.waters + corrections if self.learned else self.waters

    def displacement(self, activations) -> np.ndarray:
        """Curve-point displacement (K, J, 3) of an activation vector (linear)."""
        return np.tensordot(np.asarray(activations, np.float64), self.fields, axes=1)

    def curves(self, activations) -> tuple[np.ndarray, np.ndarray]:
        """Change of the curves' coefficients and residual for an activation vector."""

        return fit_fourier(self.displacement(activations), self.face.n_modes)

    def descriptor(self, key: str, activations, notice=""):
        """The AU ``key``'s descriptor (source ``muscle``) from its activations."""

        au, side = key_side(key)
        X = self.face.curve_points()
        return descriptor_from_points(X, X + self.displacement(activations), au, side, self.face.n_modes,
                                      source=MUSCLE_SOURCE, notice=notice)

    def calibrate(self, target_points) -> np.ndarray:
        """Activations (within :data:`BOUNDS`) whose displacement best matches ``target_points`` (K, J, 3)."""
        from scipy.optimize import lsq_linear

        A = self.fields.reshape(len(self.fields), -1).T
        lo, hi = np.array([BOUNDS[n] for n in MUSCLE_NAMES]).T
        return lsq_linear(A, np.asarray(target_points, np.float64).ravel(), bounds=(lo, hi)).x


def parse_table(data, where="muscle table", folder=None) -> MuscleTable:
    """A :class:`MuscleTable` from a parsed file (every field checked); ``folder``: where a
    ``fields`` file it names lies (the table's own folder)."""

    if not isinstance(data, dict) or data.get("format") != FORMAT:
        raise ModelFormatError(f"{where}: not a pdeface muscle table (format {FORMAT!r})")
    if data.get("version") not in READS:
        raise ModelFormatError(f"{where}: version {data.get('version')!r} is not supported "
                               f"(reads {', '.join(map(str, READS))})")
    if data.get("muscles") != list(MUSCLE_NAMES):
        raise ModelFormatError(f"{where}: 'muscles' must list the 24 muscles in order: {', '.join(MUSCLE_NAMES)}")
    aus = data.get("aus")
    if not isinstance(aus, dict) or not aus:
        raise ModelFormatError(f"{where}: 'aus' must be a non-empty object of AU key → activations")
    table, hows = {}, {}
    for key, entry in aus.items():
        try:
            k = parse_au_key(key)
        except PdeFaceError as exc:
            raise ModelFormatError(f"{where}: {exc}") from None
        values = entry.get("activations") if isinstance(entry, dict) else None
        if (not isinstance(values, list) or len(values) != len(MUSCLE_NAMES)
                or not all(isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)
                           for v in values)):
            raise ModelFormatError(f"{where}: AU{key}: 'activations' must be 24 finite numbers")
        for name, v in zip(MUSCLE_NAMES, values):
            lo, hi = BOUNDS[name]
            if not lo <= v <= hi:
                raise ModelFormatError(f"{where}: AU{key}: {name} = {v} outside [{lo:g}, {hi:g}]")
        table[k] = np.array(values, np.float64)
        hows[k] = str(entry.get("how", ""))
    geometry = data.get("geometry", {})
    if not isinstance(geometry, dict):
        raise ModelFormatError(f"{where}: 'geometry' must be an object")
    for name, g in geometry.items():
        known = DEFAULT_GEOMETRY.get(name)
        if known is None or not isinstance(g, dict) or not set(g) <= set(known) or not all(
                isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) for v in g.values()):
            raise ModelFormatError(f"{where}: geometry of {name!r} must hold numbers for {', '.join(known or [])}")
    fields = data.get("fields")
    if fields is not None:
        if not isinstance(fields, str) or not fields or Path(fields).name != fields:
            raise ModelFormatError(f"{where}: 'fields' must name a file beside the table")
        fields = load_fields(Path(folder or ".") / fields)
    return MuscleTable(table, hows, geometry, str(data.get("notice", "")), fields)


_bundled = {}


def load_table(path=None) -> MuscleTable:
    """An activation table file (see the module docstring); the bundled one by default."""

    path = TABLE if path is None else Path(path)
    if path == TABLE and "table" in _bundled:
        return _bundled["table"]
    table = parse_table(load_json(path, ModelFormatError), str(path), path.parent)
    if path == TABLE:
        _bundled["table"] = table
    return table


def mix_activations(table: dict, weights: dict, mixer: str) -> np.ndarray:
    """The activations of weighted AUs combined by ``mixer`` (:data:`ACTIVATION_MIXERS`): ``sum``, or the
    FAS's ``muscle-average`` / ``muscle-max``. ``table``: AU key → (24,) activations."""
    if mixer not in ACTIVATION_MIXERS:
        raise PdeFaceError(f"unknown muscle mixer {mixer!r}; use one of {', '.join(ACTIVATION_MIXERS)}")
    missing = [k for k in weights if k not in table]
    if missing:
        raise PdeFaceError(f"the muscle table has no AU {', '.join(missing)} (has: {', '.join(sorted(table))})")
    rows = np.array([w * table[k] for k, w in weights.items() if w]) if weights else np.zeros((0, len(MUSCLE_NAMES)))
    if not len(rows):
        return np.zeros(len(MUSCLE_NAMES))
    if mixer == "sum":
        return rows.sum(axis=0)
    if mixer == "muscle-max":
        return rows[np.abs(rows).argmax(axis=0), np.arange(rows.shape[1])]
    used = (rows != 0).sum(axis=0)
    return rows.sum(axis=0) / np.maximum(used, 1)


def muscle_pose(face, weights: dict, mixer: str, table: MuscleTable | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Change of ``face``'s curves for AU ``weights`` mixed on muscle activations (the bundled table's
    by default)."""
    table = load_table() if table is None else table
    return MuscleBasis(face, table).curves(mix_activations(table.activations, weights, mixer))
