"""Facial Deformation Tables: values, the generic (mean ± σ) table, and their files.

An FDT holds, for each of the 16 regions, the parameters of its quadratic
transform (:mod:`pdeface.fdt.quadratic`). A generic FDT is the mean over
subjects, with the standard deviation σ per parameter (the paper's acceptable
range is mean ± σ).

File (JSON, ``.fdt.json``)::

    {"format": "pdeface.fdt", "version": 1, "name": "happy", "model": "3d",
     "parameters": ["a1", ..., "c10"], "mean": [[30 numbers] × 16],
     "sigma": [[...] × 16] or null, "subjects": 20, "source": "...", "notice": "...", "blend": 0.2}

``blend`` (optional) is the width of the region borders the table was fitted with; it is applied
with the same (absent: pdeface's default; 0: independent regions, as the paper).

A bundle of several: ``{"format": "pdeface.fdts", "version": 1, "fdts": [objects as above]}``.
CSV export: one row per region and one column per parameter, as the paper's Table I.
"""
from __future__ import annotations

import json
import math
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..assets import GENERIC_FDTS, asset_path
from ..errors import ModelFormatError, PdeFaceError
from ..io.files import MAX_BYTES, inflate, parse_json, read_bytes, write_bytes
from .quadratic import MODELS, PARAMETERS
from .regions import N_REGIONS

FORMAT, BUNDLE_FORMAT, VERSION = "pdeface.fdt", "pdeface.fdts", 1
#: Decimals kept in files (parameters act on coordinates of about ±3).
DECIMALS = 4


@dataclass
class FDT:
    """One expression's Facial Deformation Table.

    Attributes
    ----------
    name : str
        The expression or AU key (``"happy"``, ``"12L"``).
    model : {'2d', '3d', '3d-surface'}
    mean : (16, P) array
        Per region, the transform's parameters (:data:`~pdeface.fdt.quadratic.PARAMETERS`).
    sigma : (16, P) array or None
        Their standard deviation over the subjects of a generic FDT.
    subjects : int
        How many faces the mean is over (1: one face's own table).
    source, notice : str
        Where it came from; the licence notice of its data.
    blend : float or None
        Blend width of the region borders it was fitted with, and is applied with
        (:data:`pdeface.fdt.regions.BLEND` when None; 0: independent regions, as the paper).
    """

    name: str
    model: str
    mean: np.ndarray
    sigma: np.ndarray | None = None
    subjects: int = 1
    source: str = ""
    notice: str = ""
    blend: float | None = None

    def __post_init__(self):
        if self.model not in MODELS:
            raise PdeFaceError(f"unknown FDT model {self.model!r}; use one of {', '.join(MODELS)}")
        shape = (N_REGIONS, len(PARAMETERS[self.model]))
        self.mean = np.asarray(self.mean, np.float64)
        if self.mean.shape != shape:
            raise PdeFaceError(f"FDT {self.name!r}: a {self.model} table is {shape[0]} regions × {shape[1]} "
                               f"parameters, got {self.mean.shape}")
        if self.sigma is not None:
            self.sigma = np.asarray(self.sigma, np.float64)
            if self.sigma.shape != shape:
                raise PdeFaceError(f"FDT {self.name!r}: sigma has shape {self.sigma.shape}, the mean {shape}")

    def as_2d(self) -> "FDT":
        """The paper's 2-D table: the x', y' parameters of a ``2d`` or ``3d-surface`` table."""
        if self.model == "3d":
            raise PdeFaceError("a 3d table's x', y' depend on z: it has no 2-D part; fit a 2d one")
        return FDT(self.name, "2d", self.mean[:, :12], None if self.sigma is None else self.sigma[:, :12],
                   self.subjects, self.source, self.notice, self.blend)

    def to_json(self) -> dict:
        def rows(a):
            return [[round(float(v), DECIMALS) for v in r] for r in a]
        return {"format": FORMAT, "version": VERSION, "name": self.name, "model": self.model,
                "parameters": list(PARAMETERS[self.model]), "mean": rows(self.mean),
                "sigma": None if self.sigma is None else rows(self.sigma), "subjects": self.subjects,
                "source": self.source, "notice": self.notice, "blend": self.blend}

    def to_csv(self) -> str:
        """The mean as the paper's Table I (region rows, parameter columns); σ below it when present."""
        names = PARAMETERS[self.model]
        lines = ["region," + ",".join(names)]
        lines += [f"{k + 1}," + ",".join(f"{v:.3f}" for v in row) for k, row in enumerate(self.mean)]
        if self.sigma is not None:
            lines += ["", "sigma region," + ",".join(names)]
            lines += [f"{k + 1}," + ",".join(f"{v:.3f}" for v in row) for k, row in enumerate(self.sigma)]
        return "\n".join(lines) + "\n"


def generic(tables, name=None, source="", notice="") -> FDT:
    """The generic FDT: mean and σ (population) over several faces' tables of one expression."""
    tables = list(tables)
    if not tables:
        raise PdeFaceError("no FDTs to average")
    models = {t.model for t in tables}
    if len(models) > 1:
        raise PdeFaceError(f"cannot average FDTs of models {', '.join(sorted(models))}")
    blends = {t.blend for t in tables}
    if len(blends) > 1:
        raise PdeFaceError(f"cannot average FDTs fitted with region blends {', '.join(map(str, blends))}")
    A = np.stack([t.mean for t in tables])
    n = sum(t.subjects for t in tables)
    w = np.array([t.subjects for t in tables], np.float64)[:, None, None]
    mean = (A * w).sum(0) / w.sum()
    sigma = np.sqrt(((A - mean) ** 2 * w).sum(0) / w.sum())
    return FDT(name or tables[0].name, tables[0].model, mean, sigma, n, source, notice or tables[0].notice,
               tables[0].blend)


def _number_rows(value, where):
    if not isinstance(value, list) or not all(isinstance(r, list) for r in value):
        raise ModelFormatError(f"{where}: must be a list of rows of numbers")
    for r in value:
        for v in r:
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
                raise ModelFormatError(f"{where}: {str(v)[:20]!r} is not a finite number")
    if len({len(r) for r in value}) > 1:
        raise ModelFormatError(f"{where}: rows of different lengths")
    return np.array(value, np.float64)


def fdt_from_json(obj, where="FDT") -> FDT:
    """Validate one FDT object (see the module docstring)."""
    if not isinstance(obj, dict):
        raise ModelFormatError(f"{where}: expected a JSON object")
    if obj.get("format") != FORMAT:
        raise ModelFormatError(f"{where}: not a pdeface FDT (format {obj.get('format')!r}, expected {FORMAT!r})")
    if obj.get("version") != VERSION:
        raise ModelFormatError(f"{where}: FDT version {obj.get('version')!r} is not supported (this pdeface "
                               f"reads version {VERSION})")
    model = obj.get("model")
    if model not in MODELS:
        raise ModelFormatError(f"{where}: model {model!r} unknown; expected one of {', '.join(MODELS)}")
    name = obj.get("name")
    if not isinstance(name, str) or not name:
        raise ModelFormatError(f"{where}: 'name' must be a non-empty string")
    if "parameters" in obj and obj["parameters"] != list(PARAMETERS[model]):
        raise ModelFormatError(f"{where}: parameters {obj['parameters']} are not the {model} model's "
                               f"{list(PARAMETERS[model])}")
    mean = _number_rows(obj.get("mean"), f"{where}: 'mean'")
    sigma = obj.get("sigma")
    sigma = None if sigma is None else _number_rows(sigma, f"{where}: 'sigma'")
    if sigma is not None and (sigma < 0).any():
        raise ModelFormatError(f"{where}: 'sigma' has negative entries")
    subjects = obj.get("subjects", 1)
    if isinstance(subjects, bool) or not isinstance(subjects, int) or subjects < 1:
        raise ModelFormatError(f"{where}: 'subjects' must be a positive integer")
    texts = {k: obj.get(k, "") for k in ("source", "notice")}
    if not all(isinstance(v, str) for v in texts.values()):
        raise ModelFormatError(f"{where}: 'source' and 'notice' must be strings")
    blend = obj.get("blend")
    if blend is not None and (isinstance(blend, bool) or not isinstance(blend, (int, float)) or not 0 <= blend <= 2):
        raise ModelFormatError(f"{where}: 'blend' must be a number in [0, 2] or null")
    try:
        return FDT(name, model, mean, sigma, subjects, **texts, blend=None if blend is None else float(blend))
    except PdeFaceError as exc:
        raise ModelFormatError(f"{where}: {exc}") from None


def parse_fdts(data, where="FDT file") -> list:
    """FDTs from a parsed file: one table or a bundle."""
    if isinstance(data, dict) and data.get("format") == BUNDLE_FORMAT:
        if data.get("version") != VERSION:
            raise ModelFormatError(f"{where}: FDT bundle version {data.get('version')!r} is not supported")
        items = data.get("fdts")
        if not isinstance(items, list) or not items:
            raise ModelFormatError(f"{where}: 'fdts' must be a non-empty list")
        return [fdt_from_json(o, f"{where}: fdts[{i}]") for i, o in enumerate(items)]
    return [fdt_from_json(data, where)]


def read_fdts(path) -> list:
    """Every FDT in a ``.fdt.json`` file or bundle (``.gz``: gzip-compressed)."""
    data = read_bytes(path)
    if str(path).endswith(".gz"):
        if data[:2] != b"\x1f\x8b":
            raise ModelFormatError(f"{path}: not a gzip file")
        data = inflate(data, path, wbits=31, limit=MAX_BYTES["json"])  # capped, as the JSON file itself is
    return parse_fdts(parse_json(data, str(path)), str(path))


def read_fdt(path) -> FDT:
    """The one FDT of a file (a bundle must hold exactly one)."""
    tables = read_fdts(path)
    if len(tables) != 1:
        raise ModelFormatError(f"{path}: holds {len(tables)} FDTs ({', '.join(t.name for t in tables[:6])}...); "
                               "name the one you want")
    return tables[0]


def write_fdts(path, tables) -> int:
    """Write one FDT or a bundle (atomically); returns the bytes written. ``.csv`` writes Table I,
    ``.gz`` compresses."""

    tables = list(tables)
    if str(path).lower().endswith(".csv"):
        if len(tables) != 1:
            raise PdeFaceError("a CSV holds one FDT")
        return write_bytes(path, tables[0].to_csv().encode())
    obj = tables[0].to_json() if len(tables) == 1 else {
        "format": BUNDLE_FORMAT, "version": VERSION, "fdts": [t.to_json() for t in tables]}
    data = (json.dumps(obj, separators=(",", ":")) + "\n").encode()
    if str(path).endswith(".gz"):
        import gzip
        data = gzip.compress(data, mtime=0)
    return write_bytes(path, data)


#: The paper's Table I (its generic smile FDT, 2-D), shipped with the package's data.
PAPER_SMILE = "paper-smile"


def load_generic_fdts(model: str = "3d") -> dict:
    """The bundled generic FDTs of one model: name (AU key or basic expression) → FDT, and the paper's smile."""
    out = {t.name: t for t in read_fdts(asset_path(GENERIC_FDTS)) if t.model == model}
    if model == "2d":
        out[PAPER_SMILE] = read_fdt(Path(__file__).resolve().parent.parent / "data" / "paper_smile.fdt.json")
    return out


def load_fdt(arg, model: str = "3d"):
    """An FDT from a file, or a bundled one by name (``happy``, ``12L``, ``paper-smile``)."""
    if Path(str(arg)).suffix in (".json", ".gz") or os.sep in str(arg):
        return read_fdt(arg)
    tables = load_generic_fdts("2d" if arg == PAPER_SMILE else model)
    if arg not in tables:
        raise PdeFaceError(f"{arg!r} is neither an FDT file nor a bundled FDT ({model}: {', '.join(sorted(tables))})")
    return tables[arg]
