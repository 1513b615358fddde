"""A user's head rigged in one go: landmarks → face model → retargeted model → every key on the user's mesh.

The chain ``pdeface landmarks``, ``fit``, ``retarget`` and ``pose --mesh --all-keys`` run one by one (and the
add-on's Fit to Selected), in one process that reads the mesh once: :func:`rig_head`, behind ``pdeface rig`` and
the batch ``rig`` job. It writes into one folder:

- ``landmarks.json`` (as ``pdeface landmarks`` writes), ``face.npz`` (the fitted face model), ``rigged.npz``
  (the same carrying the retargeted AU descriptors);
- ``keys.npz``: the keys for other tools (:func:`save_keys`, :func:`load_keys`): the mesh at rest, its
  triangles and landmarks, and each key's vertex deltas (every AU, then the presets the face has AUs for);
- ``report.json``: what each step found (the landmark gate, the fit's points, the binding's notes) and took;
- with ``blend``, ``head.blend``: the add-on's rigged head, made by its headless renderer (needs the bpy module).

Every file but the report's ``timings`` and ``cpu_timings`` is the same, byte for byte, for the same inputs.
"""
from __future__ import annotations

import importlib
import json
import os
import time
from pathlib import Path

import numpy as np

from .assets import DEFAULT, HEAD, ICT_NOTICE
from .au.modelfile import load_face, model_from_bytes, model_to_bytes
from .au.retarget import retarget
from .errors import FileError, ModelFormatError, PdeFaceError
from .head.bind import HeadBinding
from .head.parts import read_overrides, skin_mask
from .head.prior import load_head_prior
from .headless import run_headless
from .io.files import MAX_BYTES, load_npz, parse_json, stored_npz_bytes, write_bytes, write_npz
from .landmarks.checked import check_given, find_checked
from .landmarks.detector import available
from .presets import key_poses, merged_presets
from .surface.fit import fit_face
from .surface.scan import load_scan
from .units import parse_unit

KEYS_FORMAT = "pdeface.keys"
KEYS_VERSION = 1
#: The files :func:`rig_head` writes into its folder (``head.blend`` only when asked).
OUTPUTS = ("landmarks.json", "face.npz", "rigged.npz", "keys.npz", "report.json")
#: The libraries the chain imports inside its functions (landmarks, fit, binding): 0.4 s of CPU on a first call,
#: most of it scipy's own set-up (its docstrings parsed at import).
CHAIN_MODULES = ("scipy.sparse", "scipy.sparse.csgraph", "scipy.sparse.linalg", "scipy.linalg", "scipy.spatial",
                 "scipy.ndimage")


def warm_up(landmarks=True):
    """Load what the chain's first call would: :data:`CHAIN_MODULES`, MediaPipe's two models (with ``landmarks``;
    skipped where it is not installed) and the bundled head prior the binding reads, with its kernel-ridge solver
    (the same for every head: 8-10 ms of the first binding's CPU).

    Nothing of a head is computed: a later chain runs as it would after a first one (about 0.7 s of CPU less on the
    first head). The add-on calls it on a thread of its own after it is enabled; :func:`rig_head` calls it first, so
    that its steps' timings are each step's own work.
    """
    for name in CHAIN_MODULES:
        importlib.import_module(name)
    try:
        load_head_prior().solver()
    except PdeFaceError:
        pass  # an install without it: the binding says so when it runs
    if landmarks:  # last: an optional extra that fails to load leaves the rest loaded
        available()


def save_keys(path, vertices, triangles, landmarks, names, deltas, unit, source="") -> int:
    """Write the keys file: the rest mesh ``vertices (n, 3)``, ``triangles (t, 3)``, ``landmarks (68, 3)`` and
    each key's ``deltas (k, n, 3)`` (float32, the mesh's unit) named ``names``; returns its size in bytes.

    Raises :class:`FileError`, writing nothing, where the file would be over ``MAX_BYTES["keys"]`` (which
    :func:`load_keys` refuses)."""
    arrays = _keys_arrays(vertices, triangles, landmarks, names, deltas, unit, source)
    check_keys_size(path, arrays)
    # stored, not deflated: the deltas (float32, 26 MB for the 27k head's 82 keys) deflate only to 55 % and took
    # 0.5-1 s of the rig's 3 s (issue #35); numpy.load reads either
    return write_npz(path, arrays, compress=False)


def _keys_arrays(vertices, triangles, landmarks, names, deltas, unit, source=""):
    meta = {"version": KEYS_VERSION, "unit": unit, "names": list(names), "source": source}
    meta_bytes = json.dumps(meta, separators=(",", ":")).encode()
    return {"format": np.array(KEYS_FORMAT), "meta": np.frombuffer(meta_bytes, np.uint8),
            "vertices": np.asarray(vertices, np.float64), "triangles": np.asarray(triangles, np.int32),
            "landmarks": np.asarray(landmarks, np.float64), "deltas": np.asarray(deltas, np.float32)}


def check_keys_size(path, arrays=None, vertices=None, triangles=None, names=()):
    """Raise :class:`FileError` where the keys file of ``arrays`` (:func:`save_keys`'), or of keys ``names`` on
    ``vertices`` and ``triangles`` (before their deltas are made: a rig refused before it binds), would be over
    ``MAX_BYTES["keys"]``."""
    if arrays is None:  # the deltas' size alone (a view of one number: nothing allocated)
        deltas = np.broadcast_to(np.float32(0), (len(names), len(vertices), 3))
        arrays = _keys_arrays(vertices, triangles, np.zeros((68, 3)), names, deltas, "mm")
    size, limit = stored_npz_bytes(arrays), MAX_BYTES["keys"]
    if size > limit:
        raise FileError(f"{path}: {len(arrays['deltas'])} keys of {len(arrays['vertices'])} vertices would be a "
                        f"{size / 2**20:.0f} MiB keys file, over the {limit >> 20} MiB a keys file may be; "
                        "rig fewer keys (--no-presets) or a lighter mesh")


def load_keys(path) -> dict:
    """A keys file as ``{"vertices", "triangles", "landmarks", "deltas", "names", "unit", "source"}``."""
    data = load_npz(path, KEYS_FORMAT, "keys", kind="keys")
    meta = parse_json(data["meta"].tobytes().decode(), f"{path}: meta")
    if meta.get("version", 0) > KEYS_VERSION:
        raise ModelFormatError(f"{path}: keys file version {meta['version']} is newer than this pdeface reads")
    out = {k: data[k] for k in ("vertices", "triangles", "landmarks", "deltas")}
    if out["deltas"].shape != (len(meta["names"]), *out["vertices"].shape):
        raise ModelFormatError(f"{path}: its deltas do not match its vertices and names")
    return out | {"names": list(meta["names"]), "unit": meta["unit"], "source": meta.get("source", "")}


def rig_head(mesh_arg, out, landmarks=None, unit=None, parts=None, descriptors=DEFAULT, presets=True,
             blend=False, accept=False, log=None) -> dict:
    """Rig the head ``mesh_arg`` (a file, ``head`` or ``default``) into the folder ``out``; returns the report.

    Parameters
    ----------
    mesh_arg : str or path
    out : str or path
        The folder to write (made if missing; the files of :data:`OUTPUTS` in it are replaced).
    landmarks : str, optional
        The mesh's landmarks JSON; found on the mesh (MediaPipe) when None and the mesh is a file.
    unit : str or float, optional
        The mesh's unit, a name or millimetres per unit (:func:`~pdeface.units.parse_unit`; estimated from the
        face's size when None: any scale).
    parts : str, optional
        JSON of part overrides (as ``pdeface parts`` writes): its skin is fitted, its parts bound.
    descriptors : str
        The face model whose AU descriptors are retargeted (``default``: the bundled ones).
    presets : bool
        Also a key per preset the face has AUs for (as the add-on's Fit makes).
    blend : bool
        Also ``head.blend``, rigged by the add-on (needs Blender's bpy module).
    accept : bool
        Go on with found landmarks that fail the landmark gate, or with given ones on a mesh whose eyes are closed
        (the report records the verdict).
    log : callable, optional
        Called with each progress line.

    Raises
    ------
    PdeFaceError
        A broken mesh, landmarks refused by the gate, a fit or binding that cannot be made.
    """
    say = log or (lambda msg: None)
    out = Path(out)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise FileError(f"{out}: cannot make the output folder ({exc.strerror})") from None
    timings, cpu, report = {}, {}, {"mesh": str(mesh_arg)}
    clock = [time.perf_counter(), time.process_time()]

    def lap(name):  # wall seconds, and CPU seconds (all threads: less sensitive to other work on the machine)
        now = time.perf_counter(), time.process_time()
        timings[name], cpu[name] = (round(b - a, 3) for a, b in zip(clock, now))
        clock[:] = now

    mesh, lm = load_scan(mesh_arg, landmarks)
    V, T = mesh.vertices, mesh.triangles()[0]
    report["vertices"], report["triangles"] = len(V), len(T)
    lap("read")
    warm_up(landmarks=lm is None)
    lap("load")  # libraries and the bundled prior, paid by whichever step came first
    if lm is None:
        found, verdict = find_checked(mesh, unit, accept=accept, log=say)  # the head first; then the gate
        lm = found.points
        lm_json = {**found.to_json(), "gate": verdict.to_json()}  # as pdeface landmarks writes it
        report["landmarks"] = {"source": "found", "detector_score": round(found.score, 3), "view": found.view,
                               "residual_mm": round(found.residual_mm, 2), "gate": verdict.to_json(),
                               "confidence": {k: round(v, 3) for k, v in found.confidence.items()}}
    else:
        lm_json = {"points": np.round(lm, 6).tolist()}
        report["landmarks"] = {"source": "given" if landmarks else "bundled"}
        if landmarks:  # the user's points, but the mesh may still be no rest: its eyes closed
            report["landmarks"]["gate"] = check_given(mesh, lm, unit, accept=accept, log=say).to_json()
    write_bytes(out / "landmarks.json", json.dumps(lm_json, allow_nan=False).encode())
    lap("landmarks")

    overrides = read_overrides(parts) if parts else None
    skin = skin_mask(overrides, len(V)) if overrides else None
    model, sampler = fit_face(V, T, lm, unit=unit, source=str(mesh_arg), skin=skin)
    if mesh_arg in (DEFAULT, HEAD):
        model.notice = ICT_NOTICE
    model = _saved(out / "face.npz", model)
    report["fit"] = {"unit": model.frame.unit, "curves": model.layout.n_curves, "points": sampler.summary()}
    lap("fit")

    rigged = _saved(out / "rigged.npz", retarget(load_face(descriptors), model))
    lap("retarget")

    binding = HeadBinding(rigged, V, T, overrides=overrides)
    keyed = binding.bindable(rigged.descriptors)  # no gaze keys on a head without eyeballs (its notes say so)
    poses = key_poses(rigged, merged_presets([]) if presets else {}, descriptors=keyed)
    check_keys_size(out / "keys.npz", vertices=V, triangles=T, names=list(poses))  # before the keys are made
    deltas = binding.pose_displacements(list(poses.values()))
    lap("bind")
    # the unit as its millimetres where the fit estimated it: a keys file names a unit its readers' frame takes
    save_keys(out / "keys.npz", V, T, lm, list(poses), deltas, parse_unit(model.frame.scale)[0], str(mesh_arg))
    report["keys"] = {"count": len(poses), "aus": sum(n.startswith("AU") for n in poses),
                      "left_out": sorted({f"AU{d.key}" for d in rigged.descriptors} - set(poses)),
                      "largest_mm": round(_largest_move(deltas) * model.frame.scale, 2)}
    report["binding_notes"] = list(binding.notes)
    lap("keys")

    outputs = list(OUTPUTS)
    if blend:
        rig_blend(mesh_arg, out / "landmarks.json", out / "head.blend", unit, accept)
        outputs.append("head.blend")
        lap("blend")
    report["outputs"] = outputs
    report["timings"] = {**timings, "total": round(sum(timings.values()), 3)}
    report["cpu_timings"] = {**cpu, "total": round(sum(cpu.values()), 3)}
    write_bytes(out / "report.json", json.dumps(report, indent=1).encode())
    say(f"{mesh_arg}: rigged {len(poses)} keys on {len(V)} vertices in {report['timings']['total']:.1f} s")
    return report


def _largest_move(deltas) -> float:
    """The longest of the vertex moves ``deltas (k, n, 3)`` (0 for none), without an array of their lengths."""
    if deltas.size == 0:
        return 0.0
    return float(np.sqrt(np.einsum("knj,knj->kn", deltas, deltas).max()))


def _saved(path, model):
    """Write ``model`` to ``path`` and return it as read back (its file's precision): the next step works on
    what the file holds, as ``pdeface retarget`` and ``pose --mesh`` do after ``pdeface fit``."""
    data = model_to_bytes(model)
    write_bytes(path, data)
    return model_from_bytes(data, str(path))


def rig_blend(mesh_arg, landmarks, path, unit=None, accept=False):
    """``path``: the head rigged by the add-on (its Fit), saved as a ``.blend`` by the headless renderer; ``accept``:
    past the look at the mesh's eyes, as the rig went on."""
    argv = ["--mesh", mesh_arg, "--landmarks", landmarks, "--no-frames", "--quiet", "--save-blend",
            os.fspath(Path(path).resolve())] + (["--accept"] if accept else [])
    code, _ = run_headless(argv + (["--unit", str(unit)] if unit is not None else []), capture=True, prog="pdeface rig")
    if code:
        raise PdeFaceError(f"{path}: Blender could not rig the head (the headless renderer exited with {code})")
