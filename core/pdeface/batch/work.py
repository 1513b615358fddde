"""What a batch worker runs: one task, its outputs written atomically, then its record.

A task is idempotent: run twice (a worker lost mid-task, its task run again elsewhere) it writes the same bytes
to the same files, each through a temporary file renamed over it, so no output is ever half written. The record
(``.pdeface-batch/KEY.json`` in the job's folder) is written last: a task with its record and every output
present is done, and ``--resume`` skips it.
"""
from __future__ import annotations

import json
import os
import shutil
import signal
import threading
import time
from pathlib import Path

from ..errors import PdeFaceError
from ..headless import blender_here
from ..io.files import write_bytes
from ..io.png import write_png
from ..rig import rig_head
from ..threads import bounded_threads
from .stimuli import load_identity, load_saved, render_identity, save_identity

RECORDS = ".pdeface-batch"


def record_path(out, key) -> Path:
    return Path(out) / RECORDS / f"{key}.json"


def is_done(out, task) -> bool:
    """Whether ``task``'s record (with its key) and every output it lists are in ``out``."""
    try:
        rec = json.loads(record_path(out, task.key).read_text())
    except (OSError, ValueError):
        return False
    return rec.get("key") == task.key and all((Path(out) / f).is_file() for f in task.outputs)


def one_line(exc) -> str:
    """An error as one line: a pdeface error's own message, else its type and first line."""
    text = (str(exc).strip().splitlines() or [""])[0]
    return text if isinstance(exc, PdeFaceError) else f"{type(exc).__name__}: {text}".rstrip(": ")


def identity_path(out, key) -> Path:
    """Where a job's identity prepared once (:func:`prepare_identity`) is kept."""
    return Path(out) / RECORDS / "faces" / f"{key}.npz"


def prepare_identity(face, keys, out, key):
    """The identity ``face`` posed by its AU ``keys``, made once for the whole job and saved under the job's records
    (:func:`identity_path`); its stimulus tasks (which Dask runs after this) load it rather than each worker making
    it again. Returns the file's path, or None where it cannot be made (then each task fails with the reason)."""
    path = identity_path(out, key)
    if path.is_file():  # an earlier run's, same key: the same identity
        return str(path)
    try:
        with bounded_threads():
            identity = load_identity(face, tuple(keys))
        path.parent.mkdir(parents=True, exist_ok=True)
        save_identity(identity, path)
    except (PdeFaceError, OSError):
        return None
    return str(path)


def dask_setup(worker):
    """Run by each worker process of a local cluster as it starts (Dask's preload, see
    :func:`pdeface.batch.run.open_client`).

    Its standard output goes to the job's standard error: the workers share the job's stdout, which carries
    ``pdeface batch``'s JSON summary alone, and what a worker's Blender prints there (its extension cache's
    ``reading cache failed`` line, when another Blender was writing that cache) would spoil it. It ignores SIGINT:
    Ctrl-C in a terminal reaches the job's whole process group, and the job's own process answers it, closing the
    cluster so that no task starts after it but those already handed to a worker, where a worker stopped by it
    would print its traceback and be started again by its nanny.
    """
    os.dup2(2, 1)  # what sys.stdout holds is written there too
    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGINT, signal.SIG_IGN)


def run_task(task, out, *after) -> dict:
    """Run ``task`` into the folder ``out``; returns ``{"key", "status": "done" | "failed", "error", "seconds"}``.

    A :class:`PdeFaceError` or a file error (a broken mesh, the landmark gate refusing) is the task's result,
    ``failed`` with its one-line message: run again, it would fail again. Anything else propagates, and the
    scheduler retries the task (a bounded number of times). ``after``: the results of the tasks it waited for
    (a stimulus: its identity's file made by :func:`prepare_identity`, or None).
    """
    t0 = time.perf_counter()
    out = Path(out)
    try:
        with bounded_threads():  # workers share the machine's cores: BLAS threads that do not spin
            RUNNERS[task.kind](task.params, out, task.key, *after)
    except (PdeFaceError, OSError) as exc:
        return {"key": task.key, "status": "failed", "error": one_line(exc), "seconds": time.perf_counter() - t0}
    seconds = time.perf_counter() - t0
    (out / RECORDS).mkdir(parents=True, exist_ok=True)
    write_bytes(record_path(out, task.key), json.dumps({"key": task.key, "name": task.name,
                                                         "outputs": task.outputs}).encode())
    return {"key": task.key, "status": "done", "error": None, "seconds": seconds, "pid": os.getpid()}


def _rig(p, out, key, *after):
    rig_head(p["mesh"], out / p["folder"], landmarks=p["landmarks"], unit=p["unit"], parts=p["parts"],
             descriptors=p["descriptors"], presets=p["presets"], blend=p["blend"],
             accept=p.get("accept", False))


def _stimulus(p, out, key, prepared=None):
    identity = load_saved(prepared) if prepared else load_identity(p["face"], tuple(p["keys"]))
    img = render_identity(identity, p["weights"], p["view"], p["size"], p["samples"], p["background"],
                          p.get("lights"))
    out.mkdir(parents=True, exist_ok=True)
    write_png(out / p["file"], img)


def _render_chunk(p, out, key, *after):
    """Frames ``frame_start``-``frame_end`` by the add-on's headless renderer, run in this worker's own Blender
    (imported by its first chunk, kept for the next: each render resets the scene), rendered aside and moved into
    ``out/frames`` one by one (a rename: atomic)."""
    aside = out / RECORDS / "chunks" / key
    shutil.rmtree(aside, ignore_errors=True)
    argv = ["--timeline", p["timeline"], "--out", aside, "--frame-start", p["frame_start"],
            "--frame-end", p["frame_end"], "--engine", p["engine"], "--size", p["size"],
            "--samples", p["samples"], "--seed", p["seed"], "--quiet"]
    if p["blend"]:
        argv += ["--blend", p["blend"]]
    elif p["head"]:
        argv += ["--head"]
    else:
        argv += ["--face", p["face"]]
    status, stderr = blender_here().render_here(argv, prog="pdeface batch")
    if status:
        lines = [ln for ln in stderr.splitlines() if ln.strip()]
        raise PdeFaceError(f"frames {p['frame_start']}-{p['frame_end']}: "
                           f"{lines[-1] if lines else f'the renderer exited with {status}'}")
    frames = out / "frames"
    frames.mkdir(parents=True, exist_ok=True)
    for f in range(p["frame_start"], p["frame_end"] + 1):
        name = f"frame_{f:04d}.png"
        os.replace(aside / "frames" / name, frames / name)
    shutil.rmtree(aside, ignore_errors=True)


RUNNERS = {"rig": _rig, "stimuli": _stimulus, "render": _render_chunk}
