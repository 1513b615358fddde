"""AU descriptor files: JSON for people, ``.pdd`` binary for shipping.

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
:mod:`pdeface.io.codec`; the same point of neighbouring curves moves alike, so
this order deflates best).
Coefficients and residual are a linear function of the points (the Fourier
fit), so they are rebuilt exactly from them on reading; the points are the
smallest exact form. Rounding: ≤ point_step / 2 = 0.025 mm per point.
"""
from __future__ import annotations

import json
import math
import struct
import zlib

import numpy as np

from ..errors import ModelFormatError, PdeFaceError
from ..facs import SIDES, action_unit
from ..io.codec import decode_residual, encode_residual
from ..io.files import inflate, parse_json, read_bytes, write_bytes
from ..surface.fourier import fit_fourier
from ..surface.frame import FACE_REACH_MM
from ..surface.layout import check_sizes
from .descriptor import Descriptor

FORMAT = "pdeface.descriptor"
VERSION = 1
MAGIC = b"PDEDESC\0"
#: Rounding step of point changes in binary descriptors (mm).
POINT_STEP_MM = 0.05
#: The most a binary descriptor's body may inflate to (a full face's points at 1 µm would be far less).
MAX_INFLATED = 16 * 2**20


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
    except (KeyError, TypeError, ValueError, OverflowError):
        raise ModelFormatError(f"{where}: field 'layout' needs integer curves, points, modes") from None
    check_sizes(*layout, f"{where}: field 'layout'", ModelFormatError)
    extra = {k: v for k, v in obj.items() if k in ("approximation",)}
    acts = obj.get("activations")  # a muscle AU's 24 activations (pdeface.muscles), kept to edit it again
    if acts is not None:
        if not (isinstance(acts, list) and len(acts) == 24 and all(
                isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) for v in acts)):
            raise ModelFormatError(f"{where}: field 'activations' must be 24 finite numbers")
        extra["activations"] = acts
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
    check_reach(a, where, name)
    return a


def check_reach(values, where, name):
    """Refuse point changes (mm) larger than a face (:data:`pdeface.surface.frame.FACE_REACH_MM`)."""
    top = float(np.abs(values).max(initial=0))
    if top > FACE_REACH_MM:
        raise ModelFormatError(f"{where}: field {name!r} holds {top:.3g} mm; no face moves more than "
                               f"{FACE_REACH_MM:g} mm")


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


def descriptor_to_bytes(d: Descriptor, level: int = 9) -> bytes:
    """The compact binary form (see the module docs), deflated at zlib ``level`` (any level reads the same)."""
    meta = _meta(d)
    codes, step = encode_residual(d.points(), POINT_STEP_MM, order=2)
    meta["point_step"] = step
    head = json.dumps(meta, separators=(",", ":")).encode()
    body = d.curves.astype(np.uint8).tobytes() + np.ascontiguousarray(codes.transpose(0, 2, 1)).astype("<i2").tobytes()
    return MAGIC + zlib.compress(struct.pack("<I", len(head)) + head + body, level)


def descriptor_from_bytes(data: bytes, where="descriptor") -> Descriptor:
    """Read the compact binary form; errors name the problem."""
    if data[:8] != MAGIC:
        raise ModelFormatError(f"{where}: not a pdeface binary descriptor (bad magic)")
    raw = inflate(data[8:], f"{where}: body", limit=MAX_INFLATED)
    if len(raw) < 4:
        raise ModelFormatError(f"{where}: truncated")
    (n,) = struct.unpack("<I", raw[:4])
    meta = parse_json(raw[4:4 + n], f"{where}: header")
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
    check_reach(points, where, "point_step")
    C, R = fit_fourier(points, N) if m else (np.zeros((0, N + 1, 3)), np.zeros((0, J, 3)))
    return Descriptor(au, side, curves, C, R, (K, J, N), name=str(meta.get("name", "")),
                      source=str(meta.get("source", "")), notice=str(meta.get("notice", "")), extra=extra)


def save_descriptor(path, d: Descriptor) -> int:
    """Write ``.json`` (people) or anything else as binary; returns bytes written."""
    if str(path).lower().endswith(".json"):
        data = json.dumps(descriptor_to_json(d), indent=1).encode()
    else:
        data = descriptor_to_bytes(d)
    return write_bytes(path, data)


def load_descriptor(path) -> Descriptor:
    """Read a descriptor file (JSON or binary, by content)."""
    data = read_bytes(path)
    if data[:8] == MAGIC:
        return descriptor_from_bytes(data, str(path))
    return descriptor_from_json(parse_json(data, f"{path} (neither a binary descriptor nor JSON)"), str(path))


def pack_descriptors(descriptors, level: int = 9) -> dict:
    """npz members carrying descriptors inside a face model file (each deflated at zlib ``level``)."""
    blobs = [descriptor_to_bytes(d, level) for d in descriptors]
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
