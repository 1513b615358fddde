"""AU descriptors: the change of curve coefficients an Action Unit causes.

A :class:`Descriptor` holds, for the curves an AU moves only, the change of
each curve's Fourier coefficients and of its remainder residual (face frame,
mm). Curves it does not move hold nothing. The face with AUs is
``solve(neutral + Σ wᵢ Dᵢ)``; the solve is linear, so a descriptor is exactly a
linear shape key.

Files
-----
JSON (``.json``, for people)::

    {"format": "pdeface.descriptor", "version": 1, "au": 12, "side": "both",
     "name": "Lip Corner Puller", "source": "...", "notice": "...",
     "unit": "mm", "frame": "face",
     "layout": {"curves": 34, "points": 37, "modes": 5},
     "curves": [14, 15, ...],                       # affected curve indices (0 = top)
     "coefficients": [[[dx, dy, dz] × (modes+1)] × len(curves)],
     "residual": [[[dx, dy, dz] × points] × len(curves)] or null}

Binary (``.pdd``, for shipping): the magic ``b"PDEDESC\\0"``, then one zlib
stream of: a little-endian uint32 length and that many bytes of the same JSON
without the arrays plus ``"point_step"`` (mm); the curves (uint8); the change of
the curve points themselves (int16, stored 3 × points × curves, in
``point_step`` units, differenced twice along each curve, see
:mod:`pdeface.codec`; the same point of neighbouring curves moves alike, so
this order deflates best).
Coefficients and residual are a linear function of the points (the Fourier
fit), so they are rebuilt exactly from them on reading; the points are the
smallest exact form. Rounding: ≤ point_step / 2 = 0.025 mm per point.
"""
from __future__ import annotations

import json
import struct
import zlib
from dataclasses import dataclass, field, replace

import numpy as np

from .codec import decode_residual, encode_residual
from .errors import LandmarkError, ModelFormatError, PdeFaceError
from .facs import SIDES, action_unit
from .fourier import fit_fourier

FORMAT = "pdeface.descriptor"
VERSION = 1
MAGIC = b"PDEDESC\0"
#: A curve is affected when one of its points moves more than this (mm); the
#: same 0.5 mm below which the AU report does not count a vertex as moving.
AFFECTED_MM = 0.5
#: Rounding step of point changes in binary descriptors (mm).
POINT_STEP_MM = 0.05


@dataclass
class Descriptor:
    """One Action Unit as a sparse change of the curves (face frame, mm).

    Attributes
    ----------
    au : int
        FACS AU number.
    side : {'both', 'left', 'right'}
        The subject's side it acts on.
    curves : (m,) int array
        Indices of the affected curves.
    coefficients : (m, N+1, 3) array
        Change of the cosine coefficients of those curves.
    residual : (m, J, 3) array or None
        Change of their remainder residual.
    layout : (int, int, int)
        (curves, points per curve, modes) of the face layout it belongs to.
    name, source, notice : str
        FACS name, where it came from, licence notice of its data.
    """

    au: int
    side: str
    curves: np.ndarray
    coefficients: np.ndarray
    residual: np.ndarray | None
    layout: tuple
    name: str = ""
    source: str = ""
    notice: str = ""
    extra: dict = field(default_factory=dict)

    def __post_init__(self):
        self.curves = np.asarray(self.curves, dtype=np.int64)
        self.coefficients = np.asarray(self.coefficients, dtype=np.float64)
        if self.residual is not None:
            self.residual = np.asarray(self.residual, dtype=np.float64)
        self.layout = tuple(int(x) for x in self.layout)
        if not self.name:
            self.name = action_unit(self.au).name

    @property
    def key(self) -> str:
        """``"12"``, ``"12L"`` or ``"12R"``."""
        return str(self.au) + {"both": "", "left": "L", "right": "R"}[self.side]

    @property
    def label(self) -> str:
        """``"AU12 Lip Corner Puller"`` (with ``(left)``/``(right)``)."""
        side = "" if self.side == "both" else f" ({self.side})"
        return f"AU{self.au} {self.name}{side}"

    def points(self) -> np.ndarray:
        """Change of the affected curves' points (m, J, 3): series plus residual."""
        from .fourier import evaluate_fourier

        pts = evaluate_fourier(self.coefficients, np.linspace(0, np.pi, self.layout[1]))
        return pts if self.residual is None else pts + self.residual

    def dense(self) -> tuple[np.ndarray, np.ndarray]:
        """Full (K, N+1, 3) coefficient and (K, J, 3) residual changes."""
        K, J, N = self.layout
        C = np.zeros((K, N + 1, 3))
        R = np.zeros((K, J, 3))
        C[self.curves] = self.coefficients
        if self.residual is not None:
            R[self.curves] = self.residual
        return C, R

    def scaled(self, factor) -> "Descriptor":
        """The descriptor times a scalar or a per-axis (3,) factor."""
        f = np.asarray(factor, dtype=np.float64)
        return replace(self, coefficients=self.coefficients * f,
                       residual=None if self.residual is None else self.residual * f)

    def __mul__(self, factor):
        return self.scaled(factor)

    __rmul__ = __mul__

    def __neg__(self):
        return self.scaled(-1.0)

    def __add__(self, other: "Descriptor") -> "Descriptor":
        if self.layout != other.layout:
            raise PdeFaceError(f"cannot add descriptors of layouts {self.layout} and {other.layout}")
        C = self.dense()[0] + other.dense()[0]
        R = self.dense()[1] + other.dense()[1]
        curves = np.union1d(self.curves, other.curves)
        return replace(self, curves=curves, coefficients=C[curves], residual=R[curves],
                       name=f"{self.name} + {other.name}" if other.key != self.key else self.name)

    def __sub__(self, other):
        return self + (-other)


def affected_curves(delta_points: np.ndarray, threshold_mm: float = AFFECTED_MM) -> np.ndarray:
    """Curves with a point moving more than ``threshold_mm``."""
    return np.nonzero(np.linalg.norm(delta_points, axis=2).max(axis=1) > threshold_mm)[0]


def descriptor_from_points(neutral_points, au_points, au, side="both", n_modes=5, source="", notice="",
                           threshold_mm=AFFECTED_MM) -> Descriptor:
    """Descriptor from neutral and AU curve points (K, J, 3), face frame mm."""
    if side not in SIDES:
        raise PdeFaceError(f"side must be one of {', '.join(SIDES)}, got {side!r}")
    d = np.asarray(au_points, np.float64) - np.asarray(neutral_points, np.float64)
    if not np.isfinite(d).all():
        raise PdeFaceError("AU curve points contain NaN or inf")
    C, R = fit_fourier(d, n_modes)  # the fit is linear: fit(AU) - fit(neutral) = fit(AU - neutral)
    curves = affected_curves(d, threshold_mm)
    K, J, _ = d.shape
    return Descriptor(int(au), side, curves, C[curves], R[curves], (K, J, n_modes), source=source, notice=notice)


#: Feature points each AU group moves (the method's Table 5-6 idea); the others anchor the alignment.
_BROWS = ["brow_outer_right", "brow_inner_right", "brow_inner_left", "brow_outer_left"]
_EYES = ["eye_outer_right", "eye_inner_right", "eye_inner_left", "eye_outer_left"]
_NOSE = ["nose_wing_right", "nose_wing_left", "nose_bottom"]
_MOUTH = ["mouth_corner_right", "lip_upper", "mouth_corner_left", "lip_center", "lip_lower", "chin"]
MOVED_FEATURES = {1: _BROWS, 2: _BROWS, 4: _BROWS, 5: _BROWS + _EYES, 6: _EYES + _NOSE, 7: _EYES,
                  9: _BROWS[1:3] + _NOSE + _MOUTH, 10: _NOSE + _MOUTH, 11: _NOSE + _MOUTH}
for _au in (41, 42, 43, 44, 45, 46, 61, 62, 63, 64):
    MOVED_FEATURES[_au] = _BROWS + _EYES


def moved_features(au: int) -> list:
    """Names of the feature points AU ``au`` moves (mouth and nose for lower-face AUs)."""
    return MOVED_FEATURES.get(int(au), _NOSE + _MOUTH)


def rigid_align(src: np.ndarray, dst: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """Rotation R and translation t minimising |R src + t - dst|; and the RMS residual."""
    cs, cd = src.mean(0), dst.mean(0)
    U, _, Vt = np.linalg.svd((src - cs).T @ (dst - cd))
    D = np.diag([1, 1, np.sign(np.linalg.det(Vt.T @ U.T))])
    R = Vt.T @ D @ U.T
    t = cd - R @ cs
    rms = float(np.sqrt(((src @ R.T + t - dst) ** 2).sum(1).mean()))
    return R, t, rms


def align_to_neutral(model, au_vertices, au_landmarks, au: int, max_rms_mm: float = 4.0) -> np.ndarray:
    """Bring a scan of the same person (other topology) into the neutral's face frame.

    The AU scan's feature points that the AU does not move are aligned
    rigidly to the neutral's. Returns the AU vertices in the face frame (mm).

    Raises
    ------
    LandmarkError
        When the alignment residual exceeds ``max_rms_mm``: not the same
        person, or landmarks in another order.
    """
    from .frame import FEATURE_NAMES, feature_points

    F_au = model.frame.to_face(feature_points(au_landmarks))
    moved = set(moved_features(au))
    anchor = np.array([n not in moved for n in FEATURE_NAMES])
    R, t, rms = rigid_align(F_au[anchor], model.features[anchor])
    if rms > max_rms_mm:
        raise LandmarkError(
            f"the AU mesh does not align with the neutral face (residual {rms:.1f} mm over "
            f"{anchor.sum()} unmoved feature points, limit {max_rms_mm} mm): is it the same person, "
            "with landmarks in the same order?")
    return model.frame.to_face(au_vertices) @ R.T + t


def fit_descriptor(model, sampler, neutral_vertices, au_vertices, au, side="both", au_triangles=None,
                   au_landmarks=None, source="", notice="") -> Descriptor:
    """Descriptor of an AU mesh against the neutral mesh the model was fitted to.

    With the neutral's topology (same vertex count, no ``au_triangles``) the
    curve material points are read off the AU mesh exactly. Otherwise the AU
    mesh is aligned on the feature points the AU does not move (needs
    ``au_landmarks``) and the neutral's curve points are projected onto it.
    """
    neutral_points = sampler.sample(model.frame.to_face(neutral_vertices))
    au_vertices = np.asarray(au_vertices, np.float64)
    if not np.isfinite(au_vertices).all():
        raise PdeFaceError("AU mesh has NaN or inf vertices")
    if au_triangles is None:
        if len(au_vertices) != len(neutral_vertices):
            raise PdeFaceError(f"AU mesh has {len(au_vertices)} vertices, the neutral {len(neutral_vertices)}: "
                               "give its triangles and landmarks to project instead")
        au_points = sampler.sample(model.frame.to_face(au_vertices))
    else:
        if au_landmarks is None:
            raise LandmarkError("an AU mesh of another topology needs its own 68 landmarks for the alignment")
        from .curves import project_samples

        Vf = align_to_neutral(model, au_vertices, au_landmarks, au)
        au_points = project_samples(neutral_points, Vf, np.asarray(au_triangles), sampler.status).sample(Vf)
    return descriptor_from_points(neutral_points, au_points, au, side, model.n_modes, source, notice)


# ---------------------------------------------------------------- files

def _meta(d: Descriptor) -> dict:
    K, J, N = d.layout
    return {"format": FORMAT, "version": VERSION, "au": d.au, "side": d.side, "name": d.name,
            "source": d.source, "notice": d.notice, "unit": "mm", "frame": "face",
            "layout": {"curves": K, "points": J, "modes": N}, **d.extra}


def descriptor_to_json(d: Descriptor) -> dict:
    """The JSON object of a descriptor (see the module docs)."""
    out = _meta(d)
    out["curves"] = d.curves.tolist()
    out["coefficients"] = np.round(d.coefficients, 6).tolist()
    out["residual"] = None if d.residual is None else np.round(d.residual, 5).tolist()
    return out


def _field(obj, name, where, kind=None):
    if name not in obj:
        raise ModelFormatError(f"{where}: missing field {name!r}")
    v = obj[name]
    if kind is not None and not isinstance(v, kind):
        raise ModelFormatError(f"{where}: field {name!r} has the wrong type")
    return v


def _check_meta(obj, where):
    if not isinstance(obj, dict):
        raise ModelFormatError(f"{where}: a descriptor must be a JSON object")
    if obj.get("format") != FORMAT:
        raise ModelFormatError(f"{where}: field 'format' must be {FORMAT!r}")
    version = _field(obj, "version", where, int)
    if version > VERSION:
        raise ModelFormatError(f"{where}: descriptor version {version} is newer than this pdeface reads ({VERSION})")
    au = _field(obj, "au", where, int)
    try:
        action_unit(au)
    except PdeFaceError:
        raise ModelFormatError(f"{where}: field 'au' is not a FACS AU number: {au}") from None
    side = _field(obj, "side", where, str)
    if side not in SIDES:
        raise ModelFormatError(f"{where}: field 'side' must be one of {', '.join(SIDES)}")
    if obj.get("unit", "mm") != "mm":
        raise ModelFormatError(f"{where}: field 'unit' must be 'mm' (face frame)")
    lay = _field(obj, "layout", where, dict)
    try:
        layout = (int(lay["curves"]), int(lay["points"]), int(lay["modes"]))
    except (KeyError, TypeError, ValueError):
        raise ModelFormatError(f"{where}: field 'layout' needs integer curves, points, modes") from None
    if min(layout) < 0 or layout[0] < 1 or layout[1] < 1:
        raise ModelFormatError(f"{where}: field 'layout' has impossible sizes {layout}")
    extra = {k: v for k, v in obj.items() if k in ("approximation",)}
    return au, side, layout, extra


def _array(value, shape, where, name):
    try:
        a = np.array(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise ModelFormatError(f"{where}: field {name!r} must be nested lists of numbers") from None
    if a.shape != shape:
        raise ModelFormatError(f"{where}: field {name!r} has shape {a.shape}, expected {shape}")
    if not np.isfinite(a).all():
        raise ModelFormatError(f"{where}: field {name!r} contains NaN or inf")
    return a


def _curves(value, K, where):
    if not isinstance(value, list) or not all(isinstance(i, int) and not isinstance(i, bool) for i in value):
        raise ModelFormatError(f"{where}: field 'curves' must be a list of curve indices")
    c = np.array(value, dtype=np.int64)
    if len(c) and (c.min() < 0 or c.max() >= K or len(np.unique(c)) != len(c)):
        raise ModelFormatError(f"{where}: field 'curves' has indices outside 0..{K - 1} or repeats")
    return c


def descriptor_from_json(obj, where="descriptor") -> Descriptor:
    """Validate a descriptor JSON object; errors name the field."""
    au, side, (K, J, N), extra = _check_meta(obj, where)
    curves = _curves(_field(obj, "curves", where), K, where)
    C = _array(_field(obj, "coefficients", where), (len(curves), N + 1, 3), where, "coefficients")
    res = _field(obj, "residual", where)
    R = None if res is None else _array(res, (len(curves), J, 3), where, "residual")
    return Descriptor(au, side, curves, C, R, (K, J, N), name=str(obj.get("name", "")),
                      source=str(obj.get("source", "")), notice=str(obj.get("notice", "")), extra=extra)


def descriptor_to_bytes(d: Descriptor) -> bytes:
    """The compact binary form (see the module docs)."""
    meta = _meta(d)
    codes, step = encode_residual(d.points(), POINT_STEP_MM, order=2)
    meta["point_step"] = step
    head = json.dumps(meta, separators=(",", ":")).encode()
    body = d.curves.astype(np.uint8).tobytes() + np.ascontiguousarray(codes.transpose(0, 2, 1)).astype("<i2").tobytes()
    return MAGIC + zlib.compress(struct.pack("<I", len(head)) + head + body, 9)


def descriptor_from_bytes(data: bytes, where="descriptor") -> Descriptor:
    """Read the compact binary form; errors name the problem."""
    if data[:8] != MAGIC:
        raise ModelFormatError(f"{where}: not a pdeface binary descriptor (bad magic)")
    try:
        raw = zlib.decompress(data[8:])
    except zlib.error:
        raise ModelFormatError(f"{where}: body is corrupt (zlib)") from None
    if len(raw) < 4:
        raise ModelFormatError(f"{where}: truncated")
    (n,) = struct.unpack("<I", raw[:4])
    try:
        meta = json.loads(raw[4:4 + n].decode())
    except (UnicodeDecodeError, json.JSONDecodeError):
        raise ModelFormatError(f"{where}: header is not JSON") from None
    au, side, (K, J, N), extra = _check_meta(meta, where)
    body = raw[4 + n:]
    step = meta.get("point_step")
    if not isinstance(step, (int, float)) or isinstance(step, bool) or not step > 0:
        raise ModelFormatError(f"{where}: field 'point_step' must be a positive number")
    if len(body) % (1 + J * 3 * 2):
        raise ModelFormatError(f"{where}: body size {len(body)} does not match layout {K}x{J}x{N}")
    m = len(body) // (1 + J * 3 * 2)
    curves = np.frombuffer(body, np.uint8, m, 0).astype(np.int64)
    if len(curves) and (curves.max() >= K or len(np.unique(curves)) != m):
        raise ModelFormatError(f"{where}: field 'curves' has indices outside 0..{K - 1} or repeats")
    codes = np.frombuffer(body, "<i2", 3 * m * J, m).reshape(3, J, m).transpose(0, 2, 1)
    points = decode_residual(codes, step, order=2)
    C, R = fit_fourier(points, N) if m else (np.zeros((0, N + 1, 3)), np.zeros((0, J, 3)))
    return Descriptor(au, side, curves, C, R, (K, J, N), name=str(meta.get("name", "")),
                      source=str(meta.get("source", "")), notice=str(meta.get("notice", "")), extra=extra)


def save_descriptor(path, d: Descriptor) -> int:
    """Write ``.json`` (people) or anything else as binary; returns bytes written."""
    if str(path).lower().endswith(".json"):
        data = json.dumps(descriptor_to_json(d), indent=1).encode()
    else:
        data = descriptor_to_bytes(d)
    with open(path, "wb") as fh:
        fh.write(data)
    return len(data)


def load_descriptor(path) -> Descriptor:
    """Read a descriptor file (JSON or binary, by content)."""
    try:
        data = open(path, "rb").read()
    except OSError as exc:
        raise ModelFormatError(f"{path}: cannot open ({exc.strerror})") from None
    if data[:8] == MAGIC:
        return descriptor_from_bytes(data, str(path))
    try:
        obj = json.loads(data.decode("utf-8"))
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise ModelFormatError(f"{path}: neither a binary descriptor nor JSON ({exc})") from None
    return descriptor_from_json(obj, str(path))


def pack_descriptors(descriptors) -> dict:
    """npz members carrying descriptors inside a face model file."""
    blobs = [descriptor_to_bytes(d) for d in descriptors]
    offsets = np.cumsum([0] + [len(b) for b in blobs]).astype(np.int64)
    return {"descriptors": np.frombuffer(b"".join(blobs), np.uint8), "descriptor_offsets": offsets}


def unpack_descriptors(z, where) -> list:
    """Descriptors from the npz members written by :func:`pack_descriptors`."""
    if "descriptor_offsets" not in z.files:
        raise ModelFormatError(f"{where}: missing field 'descriptor_offsets'")
    data = bytes(z["descriptors"])
    off = z["descriptor_offsets"]
    if off.ndim != 1 or len(off) < 1 or off[0] != 0 or off[-1] != len(data) or np.any(np.diff(off) <= 0):
        raise ModelFormatError(f"{where}: field 'descriptor_offsets' does not match 'descriptors'")
    return [descriptor_from_bytes(data[a:b], f"{where}: descriptor {i}") for i, (a, b) in enumerate(zip(off[:-1], off[1:]))]
