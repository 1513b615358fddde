"""The face model file format (:class:`pdeface.surface.model.FaceModel` on disk).

File format (``.npz``, version 3): a NumPy ``savez_compressed`` archive read
with ``allow_pickle=False``. Members:

``meta`` (uint8)
    UTF-8 JSON: ``format`` = ``"pdeface.face"``, ``version`` = 3, ``unit``,
    ``n_modes``, ``a``, ``w``, ``assembly``, ``residual_step``,
    ``coefficient_step``, ``feature_names``, ``source``, ``notice``; since
    pdeface 0.2, optionally ``landmarks``: ``{"indices": [...], "step_mm":
    s, "codes": [[x, y, z], ...]}``, the landmarks it was fitted with, face
    frame, ``codes × s`` mm: all 68, ``s`` = 1 and the codes the millimetres
    themselves (JSON's shortest float text reads back to the bit), so a head
    binds with what it was fitted with; files written before kept only
    :data:`pdeface.surface.model.KEPT_LANDMARKS`, in integer steps of 0.1 mm
    (both read alike); optionally ``mesh_steps``: ``[[rows per curve
    interval...], [columns per point interval...]]``, the default resolution
    chosen for this model and its descriptors
    (:func:`pdeface.surface.sampling.adaptive_resolution`), so it is not chosen
    again when read back.
``layout`` (float32)
    :meth:`pdeface.surface.layout.CurveLayout.as_array`: axis z, points per curve,
    centre density, the K curve heights and the K half angles (face frame);
    from version 2, then the anchors and feature lines the curves bend
    along; from version 3, then the openings (the top anchors of the eyes'
    and the mouth's pairs of rim curves, whose intervals the smooth assembly
    solves apart). Version 1 (straight curves) and version 2 files (one
    sheet across the openings) still load and solve as they were saved.
``knots`` (float32, K)
    Curve parameters ``u_i`` in [0, 1].
``coefficients`` (uint8, 4 × (N+1) × 3 × K)
    Cosine Fourier coefficients of each curve, face frame, in steps of
    ``coefficient_step`` mm (meta; 0.001), differenced once from curve to
    curve, as the int32 codes' four byte planes
    (:func:`pdeface.io.codec.encode_coefficients`): 40 % of the float32 size
    deflated. Versions 1 and 2 hold float32 (K × (N+1) × 3).
``residual`` (uint8, 2 × 3 × J × K)
    Curve points minus their series in steps of ``residual_step`` mm (meta;
    0.01 unless a residual exceeds 80 mm), delta-coded twice along each curve
    (:func:`pdeface.io.codec.encode_residual`, order 2), stored point-major
    (coordinate, point, curve) as the codes' high and low byte planes
    (:func:`pdeface.io.codec.to_byte_planes`), so the smooth residual deflates
    well. Decoding is exact integer sums; rounding ≤ step / 2. Version 1
    files hold int16 codes (3 × K × J) delta-coded once.
``frame`` (float64, 4 × 4)
    User space → face frame (rotation and scale to mm, nose tip at origin).
``features`` (float32, 19 × 3)
    The method's feature points in the face frame.
``descriptors`` (uint8) and ``descriptor_offsets`` (int64), optional
    AU descriptors carried with the face: binary descriptors (see
    :mod:`pdeface.au.descriptor`) back to back, descriptor i in bytes
    ``offsets[i]:offsets[i+1]``.
``status`` (uint8, K × J)
    How each curve point was found: 0 ray hit, 1 miss, 2 back-facing,
    3 cavity, 4 grazing (1-4 were filled from their neighbours).

Readers refuse other formats and newer versions with a clear error.
"""
from __future__ import annotations

import io
import json
import os

import numpy as np

from ..assets import DEFAULT, DEFAULT_FACE, asset_path
from ..errors import LayoutError, ModelFormatError, PdeFaceError
from ..io.codec import (
    decode_coefficients,
    decode_residual,
    encode_coefficients,
    encode_residual,
    from_byte_planes,
    to_byte_planes,
)
from ..io.files import check_archive, npz_bytes, parse_json, read_bytes, write_bytes
from ..landmark_scheme import FEATURE_NAMES
from ..surface.frame import FaceFrame
from ..surface.layout import CurveLayout, check_sizes
from ..surface.model import FaceModel
from ..surface.sampling import known_resolution, remember_resolution
from ..units import ESTIMATED, UNIT_FORMS, parse_unit
from .descriptorfile import check_reach, pack_descriptors, unpack_descriptors

FORMAT = "pdeface.face"
VERSION = 3


def _member(z, name, path):
    if name not in z.files:
        raise ModelFormatError(f"{path}: missing field {name!r}")
    try:
        return z[name]
    except ValueError as exc:
        raise ModelFormatError(f"{path}: field {name!r} is not a plain array ({exc})") from None


def model_to_bytes(model: FaceModel, descriptors: bool = True, fast: bool = False) -> bytes:
    """The model file's bytes (with or without the descriptors it carries).

    ``fast``: written in a third of the time, about 10 % larger (the descriptors deflated at zlib's level 1, the
    archive stored): the same file format, read back to the same model; for a copy kept in memory or a .blend.
    """
    q, step = encode_residual(model.residual, order=2)
    cq, cstep = encode_coefficients(model.coefficients)
    meta = {"format": FORMAT, "version": VERSION, "unit": model.frame.unit, "n_modes": model.n_modes,
            "residual_step": step, "coefficient_step": cstep,
            "a": model.a, "w": model.w, "assembly": model.assembly, "feature_names": FEATURE_NAMES,
            "source": model.source, "notice": model.notice}
    if descriptors:
        steps = known_resolution(model)
        if steps is not None:
            meta["mesh_steps"] = [list(steps[0]), list(steps[1])]
    if model.landmarks is not None:
        # Every landmark, unrounded: kept to 0.1 mm and 24 of them, a rig's binding lost the inner lips' sides and
        # let a decimated head's upper lip sink with the jaw in AU27 (decimated-cm -0.25 eye distances; all 68 -0.03).
        L = np.asarray(model.landmarks, np.float64)
        kept = np.nonzero(np.isfinite(L).all(axis=1))[0]
        if len(kept):  # none kept: no entry (the reader refuses an empty one), read back as no landmarks
            meta["landmarks"] = {"indices": kept.tolist(), "step_mm": 1.0, "codes": L[kept].tolist()}
    arrays = {
        "meta": np.frombuffer(json.dumps(meta, separators=(",", ":")).encode(), dtype=np.uint8),
        "layout": model.layout.as_array().astype(np.float32),
        "knots": np.asarray(model.knots, np.float32),
        "coefficients": cq,
        "residual": to_byte_planes(q.transpose(0, 2, 1)),
        "frame": model.frame.matrix(),
        "features": np.asarray(model.features, np.float32),
    }
    if model.status is not None:
        arrays["status"] = np.asarray(model.status, np.uint8)
    if descriptors and model.descriptors:
        arrays.update(pack_descriptors(model.descriptors, level=1 if fast else 9))
    return npz_bytes(arrays, compress=not fast)


def model_nbytes(model: FaceModel) -> int:
    """Size of the face model itself (curves, layout, frame), without descriptors."""
    return len(model_to_bytes(model, descriptors=False))


def save_model(path, model: FaceModel) -> int:
    """Write a face model (with its descriptors); returns the file size in bytes."""
    return write_bytes(path, model_to_bytes(model))


#: The closest two curves' parameters (in [0, 1]) may lie: closer, the surface's equations are singular.
MIN_KNOT_GAP = 1e-6


def model_from_bytes(data: bytes, where: str = "model") -> FaceModel:
    """Read a face model from the bytes of a model file."""
    return load_model(io.BytesIO(data), where)


def load_model(path, where=None) -> FaceModel:
    """Read a face model written by :func:`save_model` (a path or a binary file object).

    Raises
    ------
    ModelFormatError
        For a missing file, a non-model file, a newer version or a bad field.
    """
    path_arg, path = path, (where or path)
    data = read_bytes(path_arg) if isinstance(path_arg, (str, os.PathLike)) else path_arg.read()
    try:
        check_archive(data, path, "pdeface model")  # the bundled face with 63 descriptors inflates to under 1 MiB
        return _read_model(io.BytesIO(data), path)
    except PdeFaceError:
        raise
    except Exception as exc:  # noqa: BLE001 - a damaged archive or array header raises many kinds; all mean one thing
        raise ModelFormatError(f"{path}: not a valid pdeface model file ({type(exc).__name__}: "
                               f"{str(exc)[:80]})") from None


def _landmarks(entry, path) -> np.ndarray:
    """The landmarks a model file keeps, as (68, 3) with NaN rows for the others."""
    try:
        idx = np.array(entry["indices"], dtype=np.int64)
        step = float(entry["step_mm"])
        codes = np.array(entry["codes"], dtype=np.float64)
    except (TypeError, KeyError, ValueError, OverflowError):
        raise ModelFormatError(f"{path}: meta 'landmarks' must hold 'indices', 'step_mm' and 'codes'") from None
    if (idx.ndim != 1 or codes.shape != (len(idx), 3) or not len(idx) or idx.min() < 0 or idx.max() > 67
            or not step > 0 or not np.isfinite(codes).all()):
        raise ModelFormatError(f"{path}: meta 'landmarks' is malformed (indices 0-67, one finite point each)")
    check_reach(codes * step, path, "landmarks")
    out = np.full((68, 3), np.nan)
    out[idx] = codes * step
    return out


def _read_model(fileobj, path) -> FaceModel:
    z = np.load(fileobj, allow_pickle=False)
    with z:
        meta = parse_json(bytes(_member(z, "meta", path)), f"{path}: field 'meta'")
        if not isinstance(meta, dict) or meta.get("format") != FORMAT:
            raise ModelFormatError(f"{path}: not a pdeface face model (format {meta.get('format') if isinstance(meta, dict) else None!r})")
        if not isinstance(meta.get("version"), int) or meta["version"] > VERSION:
            raise ModelFormatError(f"{path}: model version {meta.get('version')!r} is newer than this pdeface reads ({VERSION})")
        if meta.get("unit") != ESTIMATED:
            try:
                parse_unit(meta.get("unit") if isinstance(meta.get("unit"), str) else None)
            except PdeFaceError:
                raise ModelFormatError(f"{path}: field 'unit' must be {UNIT_FORMS}, or {ESTIMATED}") from None
        layout_arr = _member(z, "layout", path).astype(np.float64)
        knots = _member(z, "knots", path).astype(np.float64)
        coef = _member(z, "coefficients", path)
        if coef.dtype == np.uint8:  # version 3: byte planes of µm codes
            cstep = meta.get("coefficient_step")
            if not isinstance(cstep, (int, float)) or not cstep > 0:
                raise ModelFormatError(f"{path}: meta 'coefficient_step' must be a positive number")
            if coef.ndim != 4 or coef.shape[0] != 4 or coef.shape[2] != 3:
                raise ModelFormatError(f"{path}: field 'coefficients' must be uint8 (4, N+1, 3, K) byte planes")
            coef = decode_coefficients(coef, cstep)
        else:
            coef = coef.astype(np.float64)
        res = _member(z, "residual", path)
        step = meta.get("residual_step")
        if not isinstance(step, (int, float)) or not step > 0:
            raise ModelFormatError(f"{path}: meta 'residual_step' must be a positive number")
        if meta["version"] == 1:
            if res.dtype != np.int16 or res.ndim != 3:
                raise ModelFormatError(f"{path}: field 'residual' must be int16 (3, K, J) in a version 1 model")
            res = decode_residual(res, step)
        else:
            if res.dtype != np.uint8 or res.ndim != 4 or res.shape[:2] != (2, 3):
                raise ModelFormatError(f"{path}: field 'residual' must be uint8 (2, 3, J, K) byte planes")
            res = decode_residual(from_byte_planes(res).transpose(0, 2, 1), step, order=2)
        M = _member(z, "frame", path).astype(np.float64)
        feats = _member(z, "features", path).astype(np.float64)
        K = len(knots)
        if meta["version"] == 1 and len(layout_arr) != 3 + 2 * K:
            raise ModelFormatError(f"{path}: field 'layout' has {len(layout_arr)} values, expected {3 + 2 * K}")
        try:
            layout = CurveLayout.from_array(layout_arr, K)
        except LayoutError as exc:
            raise ModelFormatError(f"{path}: field 'layout': {exc}") from None
        J = layout.n_points
        check_sizes(K, J, coef.shape[1] - 1 if coef.ndim == 3 else 0, f"{path}: field 'layout'", ModelFormatError)
        if coef.ndim != 3 or coef.shape[0] != K or coef.shape[2] != 3:
            raise ModelFormatError(f"{path}: field 'coefficients' has shape {coef.shape}, expected ({K}, N+1, 3)")
        if res.shape != (K, J, 3):
            raise ModelFormatError(f"{path}: field 'residual' has shape {res.shape[:2]} (curves, points), expected ({K}, {J})")
        if M.shape != (4, 4) or feats.shape != (len(FEATURE_NAMES), 3):
            raise ModelFormatError(f"{path}: field 'frame' or 'features' has the wrong shape")
        for name, arr in (("knots", knots), ("coefficients", coef), ("residual", res), ("frame", M), ("layout", layout_arr)):
            if not np.isfinite(arr).all():
                raise ModelFormatError(f"{path}: field {name!r} contains NaN or inf")
        for name, arr in (("coefficients", coef), ("residual", res), ("features", feats)):
            check_reach(arr, path, name)
        for name in ("a", "w"):  # the PDE's smoothing and its weight: positive numbers (w: None, derived from a)
            v = meta.get(name, 1.0)
            if not (v is None and name == "w") and (isinstance(v, bool) or not isinstance(v, (int, float))
                                                    or not 0 < v < 1e6):
                raise ModelFormatError(f"{path}: meta {name!r} must be a positive number, got {str(v)[:20]!r}")
        if (knots.ndim != 1 or len(knots) < 2 or abs(knots[0]) > 1e-6 or abs(knots[-1] - 1) > 1e-6
                or not np.diff(knots).min() >= MIN_KNOT_GAP):
            raise ModelFormatError(f"{path}: field 'knots' must rise from 0 to 1, at least {MIN_KNOT_GAP:g} apart")
        with np.errstate(all="ignore"):  # a frame scaled by 1e300 overflows here: refused below
            scale = float(np.cbrt(np.linalg.det(M[:3, :3])))
            R = M[:3, :3] / scale
        if not (np.isfinite(scale) and scale > 0) or not np.allclose(R @ R.T, np.eye(3), atol=1e-4):
            raise ModelFormatError(f"{path}: field 'frame' is not a proper rotation and scale")
        origin = -np.linalg.solve(M[:3, :3], M[:3, 3])
        frame = FaceFrame(R, origin, scale, meta["unit"])
        model = FaceModel(layout, knots, coef, res, frame, feats,
                          a=float(meta.get("a", 1.0)), w=meta.get("w"), assembly=meta.get("assembly", "smooth"),
                          source=str(meta.get("source", "")), notice=str(meta.get("notice", "")))
        if "status" in z.files:
            st = _member(z, "status", path)
            if st.shape != (K, J):
                raise ModelFormatError(f"{path}: field 'status' has shape {st.shape}, expected ({K}, {J})")
            model.status = st.astype(np.int64)
        if "landmarks" in meta:
            model.landmarks = _landmarks(meta["landmarks"], path)
        if "descriptors" in z.files:
            model.descriptors = unpack_descriptors(z, path)
        if "mesh_steps" in meta:
            try:
                remember_resolution(model, *meta["mesh_steps"])
            except (TypeError, ValueError, PdeFaceError) as exc:
                raise ModelFormatError(f"{path}: meta 'mesh_steps': {exc}") from None
    return model


def load_face(arg):
    """A face model from a path, or the bundled one for ``"default"``."""
    return load_model(asset_path(DEFAULT_FACE) if arg == DEFAULT else arg)
