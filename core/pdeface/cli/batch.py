"""``pdeface batch``: a job of many heads, images or frames on a Dask cluster (local processes or remote)."""
from __future__ import annotations

import contextlib
import json
import signal
import threading

from ..batch.job import load_job
from ..batch.run import run_job
from .common import log


def cmd_batch(args):
    if args.workers is not None and args.workers < 1:
        raise SystemExit("pdeface batch: error: --workers must be at least 1")
    job = load_job(args.job)
    came = []  # the signal that stopped it
    try:
        with _stopped_by_sigterm(came):
            summary = run_job(job, workers=args.workers, scheduler=args.scheduler, resume=args.resume)
    except KeyboardInterrupt:
        log(f"\nbatch: interrupted; what was done is kept (see {job.out / 'manifest.json'}): run it again with "
            "--resume to make only what is missing")
        raise SystemExit(128 + (came[0] if came else signal.SIGINT)) from None
    result = summary.as_dict()
    rate = f", {result['per_second']:.2f} {'images' if job.kind == 'stimuli' else 'tasks'}/s" if summary.done else ""
    log(f"batch: {summary.done} done, {summary.skipped} skipped, {len(summary.failed)} failed in "
        f"{summary.seconds:.1f} s{rate}")
    for name, error in summary.failed.items():
        log(f"  failed: {name}: {error}")
    print(json.dumps(result))
    if summary.failed:
        log(f"batch: see {summary.manifest}")
        raise SystemExit(2)


@contextlib.contextmanager
def _stopped_by_sigterm(came):
    """SIGTERM (``kill``, a cluster's time limit) stops the job as Ctrl-C does: the cluster is closed (no task
    starts after it but those already handed to a worker), the manifest is written.
    A job started in the background by a shell ignores Ctrl-C's SIGINT; this is how it stops.
    The signal's number goes into the list ``came``."""

    def stop(signum, frame):
        came.append(signum)
        raise KeyboardInterrupt

    here = threading.current_thread() is threading.main_thread()  # where Python lets a handler be set
    before = signal.signal(signal.SIGTERM, stop) if here else None
    try:
        yield
    finally:
        if here:
            signal.signal(signal.SIGTERM, before)


def register(sub):
    """The ``batch`` command."""
    p = sub.add_parser("batch", help="run a job (TOML: rig many heads, a stimulus set, a render in frame chunks) "
                                     "on a Dask cluster (needs pdeface[cluster])")
    p.add_argument("job", help="the job file (TOML with 'kind' = rig | stimuli | render and 'out'; "
                               "see docs/user/batch.md)")
    g = p.add_mutually_exclusive_group()
    g.add_argument("--workers", type=int, help="worker processes of a local cluster (default: the cores)")
    g.add_argument("--scheduler", metavar="ADDRESS", help="an existing Dask cluster's scheduler, tcp://HOST:8786")
    p.add_argument("--resume", action="store_true", help="skip the tasks whose outputs are already there "
                                                         "(made with the same inputs and options)")
    p.set_defaults(func=cmd_batch)
