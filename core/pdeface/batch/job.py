"""A batch job file (TOML) and the tasks it makes, each keyed by the hash of its inputs and options.

The contract (issue #37): ``kind`` (``rig`` | ``stimuli`` | ``render``) and ``out`` (a folder); ``rig``: ``meshes``
(paths or globs); ``stimuli``: ``faces``, ``aus`` and/or ``presets``, ``intensities`` (FACS letters A-E, or weights),
``size``, ``samples`` (and ``views``, ``lights``); ``render``: ``timeline``, ``face``/``head``/``blend``, ``chunk``. The
other keys are listed in ``docs/user/batch.md``. Paths are relative to the job file's folder.
"""
from __future__ import annotations

import glob
import hashlib
import json
import os
import re
from dataclasses import dataclass, field
from itertools import product
from pathlib import Path

from ..assets import DEFAULT, HEAD
from ..errors import PdeFaceError
from ..facs import au_number, letter_to_weight, parse_au_key, weight_to_letter
from ..presets import merged_presets, normalise_weights
from ..units import parse_unit
from .stimuli import light_spec, view_yaw

KINDS = ("rig", "stimuli", "render")
#: Bumped when a task's outputs change for the same inputs (old outputs are then made again on --resume).
TASK_VERSION = 1
COMMON = {"kind", "out", "retries"}
KEYS = {
    "rig": COMMON | {"meshes", "landmarks", "unit", "descriptors", "presets", "blend", "accept"},
    "stimuli": COMMON | {"faces", "aus", "presets", "intensities", "views", "lights", "size", "samples",
                         "background", "sampler"},
    "render": COMMON | {"timeline", "face", "head", "blend", "chunk", "engine", "size", "samples", "seed"},
}


class JobError(PdeFaceError):
    """A job file that cannot be run as written."""


@dataclass
class Task:
    """One unit of work: ``run`` names the worker function, ``outputs`` the files it makes (relative to the
    job's ``out``); ``key`` is the hash of everything that decides them."""

    kind: str
    name: str
    params: dict
    outputs: list
    key: str = ""
    label: dict = field(default_factory=dict)


@dataclass
class Job:
    kind: str
    out: Path
    tasks: list
    retries: int = 2
    path: str = ""
    aus: list = field(default_factory=list)  # stimuli: every AU number in the job (the label columns)


#: Content hashes of the input files read so far, by (path, size, modification time).
_HASHES = {}


def _hash_file(path) -> str:
    path = os.path.abspath(path)
    st = os.stat(path)
    sig = (path, st.st_size, st.st_mtime_ns)
    if sig not in _HASHES:
        h = hashlib.sha256()
        with open(path, "rb") as fh:
            for block in iter(lambda: fh.read(1 << 20), b""):
                h.update(block)
        _HASHES[sig] = h.hexdigest()
    return _HASHES[sig]


def _input_hash(spec) -> str:
    """The content hash of an input (a file, every file of a folder, or a bundled name as itself)."""
    if spec in (None, DEFAULT, HEAD) or isinstance(spec, bool):
        return str(spec)
    p = Path(spec)
    if p.is_dir():
        return hashlib.sha256("".join(f"{f.name}:{_hash_file(f)}" for f in sorted(p.iterdir())
                                      if f.is_file() and not f.name.startswith(".")).encode()).hexdigest()
    if not p.exists():
        raise JobError(f"{spec}: no such file")
    return _hash_file(p)


def task_key(kind, params, inputs) -> str:
    """The hash of a task's kind, options and inputs' contents: the same key, the same outputs."""
    body = {"kind": kind, "version": TASK_VERSION, "params": params,
            "inputs": {k: _input_hash(v) for k, v in inputs.items()}}
    return hashlib.sha256(json.dumps(body, sort_keys=True, default=str).encode()).hexdigest()[:24]


def identity_key(face, keys) -> str:
    """The hash of an identity posed by AU ``keys`` (see :func:`pdeface.batch.work.prepare_identity`)."""
    return task_key("identity", {"keys": sorted(keys)}, {"face": face})


def load_job(path) -> Job:
    """Read and plan the job file ``path``; a :class:`JobError` names what is wrong."""
    try:
        import tomllib
    except ImportError:  # Python 3.10: its backport
        try:
            import tomli as tomllib
        except ImportError:
            raise JobError("reading a job file on Python 3.10 needs tomli: python -m pip install tomli") from None
    path = Path(path)
    try:
        data = tomllib.loads(path.read_text())
    except OSError as exc:
        raise JobError(f"{path}: cannot read the job file ({exc.strerror})") from None
    except tomllib.TOMLDecodeError as exc:
        raise JobError(f"{path}: not TOML ({exc})") from None
    return plan_job(data, path.parent, str(path))


def plan_job(data: dict, base=".", where="job") -> Job:
    """The tasks of a job given as a dict (a parsed job file); paths are relative to ``base``."""
    kind = data.get("kind")
    if kind not in KINDS:
        raise JobError(f"{where}: 'kind' must be one of {', '.join(KINDS)} (got {kind!r})")
    unknown = sorted(set(data) - KEYS[kind])
    if unknown:
        raise JobError(f"{where}: unknown key {unknown[0]!r} for a {kind} job (known: {', '.join(sorted(KEYS[kind]))})")
    if not isinstance(data.get("out"), str):
        raise JobError(f"{where}: 'out' (the output folder) is required")
    base = Path(base)
    out = base / data["out"]
    retries = data.get("retries", 2)
    if not isinstance(retries, int) or not 0 <= retries <= 10:
        raise JobError(f"{where}: 'retries' must be an integer 0-10")
    planner = {"rig": _plan_rig, "stimuli": _plan_stimuli, "render": _plan_render}[kind]
    tasks, aus = planner(data, base, where)
    if not tasks:
        raise JobError(f"{where}: the job makes nothing (no {'meshes' if kind == 'rig' else 'items'})")
    return Job(kind, out, tasks, retries, where, aus)


def _path(base, spec):
    return spec if spec in (DEFAULT, HEAD) else str(base / spec)


def _unique_names(stems):
    seen, names = {}, []
    for s in stems:
        seen[s] = seen.get(s, 0) + 1
        names.append(s if seen[s] == 1 else f"{s}_{seen[s]}")
    return names


def _listed(data, key, what, where) -> list:
    """The job's ``key``: one string or a non-empty list (``what`` names what it must list)."""
    value = data.get(key)
    value = [value] if isinstance(value, str) else value
    if not isinstance(value, list) or not value:
        raise JobError(f"{where}: '{key}' must list {what}")
    return value


def _check_unit(unit, where):
    """A unit ``parse_unit`` reads (or None), else a :class:`JobError` naming ``where``."""
    if unit is not None:
        try:
            parse_unit(unit)
        except PdeFaceError as exc:
            raise JobError(f"{where}: {exc}") from None


def _plan_rig(data, base, where):
    meshes = _listed(data, "meshes", "head meshes (paths or globs)", where)
    entries = []
    for m in meshes:
        entry = dict(m) if isinstance(m, dict) else {"mesh": m}
        spec = entry.get("mesh")
        if not isinstance(spec, str):
            raise JobError(f"{where}: each of 'meshes' is a path, a glob or a table with 'mesh'")
        if spec in (DEFAULT, HEAD):
            entries.append(entry)
            continue
        found = sorted(glob.glob(str(base / spec))) if glob.has_magic(spec) else [str(base / spec)]
        if not found:
            raise JobError(f"{where}: {spec!r} matches no file")
        entries += [{**entry, "mesh": f} for f in found]
    _check_unit(data.get("unit"), f"{where}: unit")  # the job's own, checked whether or not an entry sets its own
    options = {"unit": data.get("unit"), "descriptors": _path(base, data.get("descriptors", DEFAULT)),
               "presets": bool(data.get("presets", True)), "blend": bool(data.get("blend", False)),
               "accept": bool(data.get("accept", False))}  # landmarks or a mesh that fail the gate: go on anyway
    tasks = []
    names = _unique_names(Path(e["mesh"]).stem for e in entries)
    for entry, name in zip(entries, names):
        lm = entry.get("landmarks", data.get("landmarks"))
        if lm and "{stem}" in lm:  # the mesh's file name without its extension; no such file: found on the mesh
            lm = str(Path(entry["mesh"]).parent / lm.format(stem=Path(entry["mesh"]).stem))
            lm = lm if os.path.exists(lm) else None
        elif lm:
            lm = str(base / lm)
        unit = entry.get("unit", options["unit"])
        _check_unit(unit, f"{where}: {entry['mesh']}")
        params = {**options, "mesh": entry["mesh"], "landmarks": lm, "unit": unit,
                  "parts": str(base / entry["parts"]) if entry.get("parts") else None, "folder": name}
        outputs = [f"{name}/{f}" for f in ("landmarks.json", "face.npz", "rigged.npz", "keys.npz", "report.json")]
        outputs += [f"{name}/head.blend"] if options["blend"] else []
        key = task_key("rig", {k: v for k, v in params.items() if k not in ("mesh", "landmarks", "parts",
                                                                             "descriptors")},
                       {"mesh": entry["mesh"], "landmarks": lm, "parts": params["parts"],
                        "descriptors": options["descriptors"]})
        tasks.append(Task("rig", name, params, outputs, key))
    return tasks, []


def _intensity(value, where):
    """(weight, FACS letter, the file names' tag) of an intensity: a letter or a weight."""
    if isinstance(value, str):
        try:
            return letter_to_weight(value), value.upper(), value.upper()
        except PdeFaceError as exc:
            raise JobError(f"{where}: intensities: {exc}") from None
    if isinstance(value, (int, float)) and 0 < value <= 1:
        return float(value), weight_to_letter(value), f"w{float(value):g}"
    raise JobError(f"{where}: intensity {value!r}: a FACS letter A-E or a weight in (0, 1]")


def _combos(data, where):
    """The AU combinations: (name, {AU key: weight at intensity E})."""
    combos = []
    for s in data.get("aus", []):
        aus = s if isinstance(s, list) else [s]
        try:
            keys = [parse_au_key(a) for a in aus]
        except PdeFaceError as exc:
            raise JobError(f"{where}: aus: {exc}") from None
        if not keys:
            raise JobError(f"{where}: aus: an empty AU set")
        name = "AU" + "+".join(f"{au_number(k):02d}{k.lstrip('0123456789')}" for k in keys)
        combos.append((name, {k: 1.0 for k in keys}))
    presets = data.get("presets", [])
    if presets:
        known = merged_presets([])
        for p in presets:
            if p not in known:
                raise JobError(f"{where}: unknown preset {p!r}; have {', '.join(sorted(known))}")
            combos.append((p, normalise_weights(known[p].weights)))
    if not combos:
        raise JobError(f"{where}: give 'aus' (AU sets, e.g. [[12], [1, 2]]) and/or 'presets'")
    return combos


def _plan_stimuli(data, base, where):
    faces = [_path(base, f) for f in _listed(data, "faces", "face models, rigged heads, 'default' or 'head'", where)]
    names = _unique_names(Path(f).stem if Path(f).name != "keys.npz" else Path(f).parent.name for f in faces)
    combos = _combos(data, where)
    intensities = [_intensity(v, where) for v in data.get("intensities", ["C"])]
    views = data.get("views", ["front"])
    for v in views:
        try:
            view_yaw(v)
        except PdeFaceError as exc:
            raise JobError(f"{where}: views: {exc}") from None
    lights = _lights(data, where)
    size, samples = data.get("size", 256), data.get("samples", 1)
    if not isinstance(size, int) or not 16 <= size <= 4096:
        raise JobError(f"{where}: 'size' must be an integer number of pixels, 16-4096")
    if not isinstance(samples, int) or samples < 1 or round(samples ** 0.5) ** 2 != samples:
        raise JobError(f"{where}: 'samples' (per pixel) must be a square: 1, 4, 9, 16 ...")
    background = float(data.get("background", 0.0))
    every_key = sorted({k for _, w in combos for k in w})
    items = list(product(range(len(faces)), range(len(combos)), range(len(intensities)), views, lights or [None]))
    sampler = data.get("sampler")
    if sampler is not None:
        import numpy as np

        count, seed = sampler.get("count"), sampler.get("seed", 0)
        if not isinstance(count, int) or count < 1:
            raise JobError(f"{where}: sampler: 'count' (the number of images) must be a positive integer")
        rng = np.random.default_rng(seed)
        items = [(int(rng.integers(len(faces))), int(rng.integers(len(combos))), int(rng.integers(len(intensities))),
                  views[int(rng.integers(len(views)))], lights[int(rng.integers(len(lights)))] if lights else None)
                 for _ in range(count)]  # a job without lights draws as it did before they were added
    tasks = []
    for i, (f, c, n, view, light) in enumerate(items):
        combo, weights = combos[c]
        w, letter, tag = intensities[n]
        posed = {k: round(v * w, 6) for k, v in weights.items()}
        safe = re.sub(r"[^\w.+-]", "_", combo)
        stem = f"{names[f]}_{safe}_{tag}_{view}" + (f"_{light[0]}" if light else "")
        file = (f"{i:05d}_{stem}" if sampler is not None else stem) + ".png"
        params = {"face": faces[f], "keys": every_key, "weights": posed, "view": view, "size": size,
                  "samples": samples, "background": background, "file": file}
        if light:  # a job without lights keeps the keys (and file names) it had before they were added
            params |= {"light": light[0], "lights": light[1]}
        key = task_key("stimuli", {k: v for k, v in params.items() if k != "face"}, {"face": faces[f]})
        label = {"file": file, "face": faces[f], "identity": names[f], "view": view,
                 "light": light[0] if light else "front", "intensity": letter, "weights": posed}
        tasks.append(Task("stimuli", file, params, [file], key, label))
    aus = sorted({au_number(k) for k in every_key})
    return tasks, aus


def _lights(data, where) -> list:
    """The job's lights as ``(unique name, what shade takes)``; [] when it names none (the default lighting)."""
    if "lights" not in data:
        return []
    given = data["lights"]
    given = [given] if isinstance(given, (str, dict)) else given
    if not isinstance(given, list) or not given:
        raise JobError(f"{where}: 'lights' must list lights (names or {{direction, strength}} tables)")
    try:
        specs = [light_spec(x) for x in given]
    except PdeFaceError as exc:
        raise JobError(f"{where}: {exc}") from None
    return list(zip(_unique_names(n for n, _ in specs), (s for _, s in specs)))


def _plan_render(data, base, where):
    from ..animation.timeline import load_timeline

    if not isinstance(data.get("timeline"), str):
        raise JobError(f"{where}: 'timeline' (a timeline JSON) is required")
    timeline = str(base / data["timeline"])
    tl = load_timeline(timeline)
    first, last = tl.keys[0].frame, tl.frame_end
    sources = [k for k in ("face", "head", "blend") if data.get(k)]
    if len(sources) > 1:
        raise JobError(f"{where}: give one of 'face', 'head' and 'blend'")
    chunk = data.get("chunk", 10)
    if not isinstance(chunk, int) or chunk < 1:
        raise JobError(f"{where}: 'chunk' (frames per task) must be a positive integer")
    source = {"face": _path(base, data["face"]) if data.get("face") else DEFAULT, "head": bool(data.get("head")),
              "blend": str(base / data["blend"]) if data.get("blend") else None}
    options = {"engine": data.get("engine", "WORKBENCH"), "size": data.get("size", "256x256"),
               "samples": data.get("samples", 16), "seed": data.get("seed", 0)}
    tasks = []
    for start in range(first, last + 1, chunk):
        end = min(start + chunk - 1, last)
        params = {**options, **source, "timeline": timeline, "frame_start": start, "frame_end": end}
        outputs = [f"frames/frame_{f:04d}.png" for f in range(start, end + 1)]
        key = task_key("render", {**options, "head": source["head"], "frame_start": start, "frame_end": end},
                       {"timeline": timeline, "face": source["face"], "blend": source["blend"]})
        tasks.append(Task("render", f"frames {start}-{end}", params, outputs, key))
    return tasks, []
