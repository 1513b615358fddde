"""Running a job's tasks on Dask distributed: a local cluster of worker processes, or an existing one.

Workers have one thread each (one Blender, one numerical solve per process); the BLAS pools inside them are
held to one thread by Dask's nanny (its ``pre-spawn-environ``). Tasks already done are skipped with
``resume``; a failed task is recorded and the job goes on; a task whose worker died is run again elsewhere by
the scheduler (at most ``distributed.scheduler.allowed-failures`` times); a task raising something unexpected
is retried ``job.retries`` times. At the end: ``manifest.json`` (every task, its status and one-line error)
and, for a stimulus set, ``labels.csv``.
"""
from __future__ import annotations

import csv
import io
import json
import logging
import os
import sys
import time
from dataclasses import dataclass, field

from ..errors import PdeFaceError
from ..io.files import write_bytes
from .job import identity_key
from .stimuli import bound_once
from .work import RECORDS, dask_setup, is_done, one_line, prepare_identity, run_task

#: Dask's settings for a local cluster. Its workers are forked from a fork server that imported Dask once, where
#: the platform has one (POSIX), instead of spawned, each a fresh interpreter importing it again: that took about
#: 1 s of CPU per worker to start and as long to close, a fixed cost the job's second worker could not share.
#: The processes' monitors sample every 2 s (not 0.5 s; a worker's memory every 1 s, not 0.1 s) and their event
#: loops' watchdog ticks every 0.5 s (not 20 ms): the client's process, which holds the scheduler and the
#: nannies, spent 5% of a core on them, taken from the workers.
LOCAL_DASK = {"distributed.admin.system-monitor.interval": "2s", "distributed.worker.memory.monitor-interval": "1s",
              "distributed.admin.tick.interval": "500ms"}
NO_DASK = "pdeface batch needs Dask distributed: python -m pip install 'pdeface[cluster]'"
MANIFEST = "manifest.json"
LABELS = "labels.csv"


@dataclass
class Summary:
    done: int = 0
    skipped: int = 0
    failed: dict = field(default_factory=dict)  # task name → its one-line error
    seconds: float = 0.0
    manifest: str = ""
    dashboard: str | None = None
    workers: int = 0

    def as_dict(self) -> dict:
        rate = self.done / self.seconds if self.seconds else 0.0
        return {"done": self.done, "skipped": self.skipped, "failed": len(self.failed), "errors": self.failed,
                "seconds": round(self.seconds, 2), "per_second": round(rate, 3), "workers": self.workers,
                "manifest": self.manifest}


class Progress:
    """The progress line on stderr: done, failed, rate and time left (redrawn in place on a terminal, a line
    every few seconds elsewhere)."""

    def __init__(self, total, stream=None, every=5.0):
        self.total, self.stream, self.every = total, stream or sys.stderr, every
        self.tty = getattr(self.stream, "isatty", lambda: False)()
        self.t0 = self.shown = time.perf_counter()
        self.done = self.failed = 0

    def line(self) -> str:
        took = time.perf_counter() - self.t0
        finished = self.done + self.failed
        rate = finished / took if took > 0 else 0.0
        eta = f"~{(self.total - finished) / rate:.0f} s left" if rate > 0 else "time left: -"
        return (f"batch: {finished}/{self.total} ({self.done} done, {self.failed} failed), "
                f"{rate:.2f} tasks/s, {eta}")

    def update(self, status):
        self.done += status == "done"
        self.failed += status == "failed"
        now = time.perf_counter()
        last = self.done + self.failed == self.total
        if self.tty:
            self.stream.write("\r" + self.line() + ("\n" if last else ""))
        elif last or now - self.shown >= self.every:
            self.stream.write(self.line() + "\n")
            self.shown = now
        self.stream.flush()


def _dask():
    try:
        import distributed
    except ImportError:
        raise PdeFaceError(NO_DASK) from None
    return distributed


def open_client(workers=None, scheduler=None):
    """A Dask client: of the cluster at ``scheduler`` (``tcp://HOST:8786``), else of a new local cluster of
    ``workers`` processes (default: the cores) with one thread each. Returns ``(client, cluster or None,
    the dashboard's address or None)``."""
    distributed = _dask()
    if scheduler:
        try:
            client = distributed.Client(scheduler, timeout="20s")
            return client, None, client.dashboard_link
        except OSError as exc:
            raise PdeFaceError(f"--scheduler {scheduler}: cannot reach the Dask scheduler ({exc})") from None
    n = workers or os.cpu_count() or 1
    try:
        import bokeh  # noqa: F401 - the dashboard needs it
        dashboard = True
    except ImportError:
        dashboard = False
    # a free port for the scheduler's web server (another job's cluster may hold the usual 8787); each worker runs
    # dask_setup as it starts (its stdout to stderr, Ctrl-C for this process alone)
    cluster = distributed.LocalCluster(n_workers=n, threads_per_worker=1, processes=True, dashboard_address=":0",
                                       silence_logs=logging.CRITICAL, preload=[dask_setup.__module__])
    client = distributed.Client(cluster)
    return client, cluster, client.dashboard_link if dashboard else None


def run_job(job, workers=None, scheduler=None, resume=False, stream=None) -> Summary:
    """Run ``job`` (:class:`~pdeface.batch.job.Job`); returns its :class:`Summary` (the manifest is written
    whatever happens, also when interrupted)."""
    stream = stream or sys.stderr
    out = job.out
    try:
        (out / RECORDS).mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise PdeFaceError(f"{out}: cannot make the output folder ({exc.strerror})") from None
    summary = Summary(manifest=str(out / MANIFEST))
    status = {}
    todo = []
    for t in job.tasks:
        if resume and is_done(out, t):
            status[t.key] = {"status": "skipped", "error": None}
        else:
            todo.append(t)
    summary.skipped = len(job.tasks) - len(todo)
    t0 = time.perf_counter()
    try:
        if todo:
            _run(job, todo, status, summary, workers, scheduler, stream)
    finally:
        summary.seconds = time.perf_counter() - t0
        for t in job.tasks:
            status.setdefault(t.key, {"status": "not run", "error": None})
        summary.done = sum(s["status"] == "done" for s in status.values())
        summary.failed = {t.name: status[t.key]["error"] for t in job.tasks if status[t.key]["status"] == "failed"}
        _write_results(job, status, summary)
    return summary


def _local_dask(scheduler):
    """The Dask settings this job's cluster runs with (:data:`LOCAL_DASK`; none for a cluster of its own)."""
    import multiprocessing

    import dask

    _dask()  # Dask's own defaults first: leaving the block puts back what was there before it
    if scheduler:
        return dask.config.set({})
    fork = {"distributed.worker.multiprocessing-method": "forkserver"} \
        if "forkserver" in multiprocessing.get_all_start_methods() else {}
    return dask.config.set({**LOCAL_DASK, **fork})


def local_workers(pid=None) -> list:
    """The worker processes (psutil) of the local clusters that process ``pid`` (default: this one) started: spawned
    ones, and those the fork server forked (see :data:`LOCAL_DASK`)."""
    import psutil

    found = []
    for p in psutil.Process(pid).children(recursive=True):
        try:
            if any("spawn_main" in part for part in p.cmdline()) or \
                    any("multiprocessing.forkserver" in part for part in psutil.Process(p.ppid()).cmdline()):
                found.append(p)
        except psutil.Error:  # gone meanwhile
            pass
    return found


def _run(job, todo, status, summary, workers, scheduler, stream):
    distributed = _dask()
    with _local_dask(scheduler):  # for the cluster's lifetime: a nanny restarting a lost worker reads it again
        _run_on(distributed, job, todo, status, summary, workers, scheduler, stream)


def _run_on(distributed, job, todo, status, summary, workers, scheduler, stream):
    client, cluster, summary.dashboard = open_client(workers, scheduler)
    try:
        summary.workers = len(client.scheduler_info()["workers"])
        where = scheduler or f"a local cluster of {summary.workers} worker processes"
        stream.write(f"batch: {len(todo)} {job.kind} tasks on {where}; dashboard: "
                     f"{summary.dashboard or 'none (pip install bokeh for it)'}\n")
        progress = Progress(len(todo), stream)
        by_key = {t.key: t for t in todo}
        # Identities made once for the job, submitted first so that Dask starts them first: one worker binds the
        # head while the other renders the other faces, rather than every worker binding it again.
        prepared = {}
        for t in todo:
            if t.kind == "stimuli" and bound_once(t.params["face"]):
                k = identity_key(t.params["face"], t.params["keys"])
                if k not in prepared:
                    prepared[k] = client.submit(prepare_identity, t.params["face"], t.params["keys"], str(job.out), k,
                                                key=f"pdeface-identity-{k}", pure=False, retries=job.retries)

        def after(t):
            """What ``t`` waits for: its identity made once, if it is one of those."""
            if t.kind != "stimuli" or not bound_once(t.params["face"]):
                return ()
            return (prepared[identity_key(t.params["face"], t.params["keys"])],)

        futures = [client.submit(run_task, t, str(job.out), *after(t), key=f"pdeface-{job.kind}-{t.key}", pure=False,
                                 retries=job.retries) for t in todo]
        for fut in distributed.as_completed(futures):
            key = fut.key.rsplit("-", 1)[1]
            try:
                res = fut.result()
            except Exception as exc:  # noqa: BLE001 - retries spent or the worker died too often: record it
                res = {"status": "failed", "error": one_line(exc)}
            status[key] = {"status": res["status"], "error": res.get("error"),
                           "seconds": round(res.get("seconds", 0.0), 3), "worker": res.get("pid")}
            if res["status"] == "failed":
                stream.write(f"\nbatch: {by_key[key].name}: {res['error']}\n" if progress.tty else
                             f"batch: {by_key[key].name}: {res['error']}\n")
            progress.update(res["status"])
    finally:
        client.close()
        if cluster is not None:
            cluster.close()


def _write_results(job, status, summary):
    """``manifest.json`` (and a stimulus set's ``labels.csv``), each written atomically."""
    shown = ("identity", "view", "light", "intensity")  # a stimulus's label, as in labels.csv
    tasks = [{"key": t.key, "name": t.name, "outputs": t.outputs, **{k: t.label[k] for k in shown if k in t.label},
              **status[t.key]} for t in job.tasks]
    manifest = {"job": job.path, "kind": job.kind, "summary": summary.as_dict(), "tasks": tasks}
    write_bytes(job.out / MANIFEST, json.dumps(manifest, indent=1).encode())
    if job.kind == "stimuli":
        write_bytes(job.out / LABELS, labels_csv(job, status).encode())
    for stale in job.out.rglob(".*.part"):  # a worker killed mid-write leaves its temporary file
        stale.unlink(missing_ok=True)


def labels_csv(job, status) -> str:
    """One row per image made: ``file``, ``face``, ``identity``, ``view``, ``light``, ``intensity`` (FACS letter), then
    ``AUxx_r`` (0-5) and ``AUxx_c`` (0/1) for every AU in the job, as OpenFace writes them."""
    from .stimuli import label_row

    cols = ["file", "face", "identity", "view", "light", "intensity"]
    cols += [f"AU{n:02d}_r" for n in job.aus] + [f"AU{n:02d}_c" for n in job.aus]
    buf = io.StringIO()
    w = csv.DictWriter(buf, cols, lineterminator="\n")
    w.writeheader()
    for t in job.tasks:
        if status[t.key]["status"] in ("done", "skipped"):
            lab = t.label
            w.writerow({k: lab[k] for k in cols[:6]} | label_row(lab["weights"], job.aus))
    return buf.getvalue()
