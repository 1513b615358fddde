"""Bounded thread pools for the numerical work: BLAS threads that do not spin on a busy machine.

OpenBLAS's worker threads busy-wait for work. When another process holds a core (Blender's own
UI, a browser, a render, a batch worker beside this one) they wait for a core instead, and the
27k-vertex head's binding took 5-7 s instead of 0.8 s (issue #35). The solves the core runs are
small or sparse (SuperLU, a few hundred small dense solves), so one thread loses little even on
an idle machine: ``scripts/bench/bench_load.py`` measures 1 thread, the libraries' default and
this module's choice, quiet and beside a busy process.

:func:`bounded_threads` caps the BLAS and OpenMP pools with ``threadpoolctl`` (an optional
dependency: the ``blender`` and ``test`` extras, and a wheel in the Blender extension) and puts
them back afterwards; without it, it changes nothing. Only BLAS pools are bounded: OpenMP's belong
to whatever else runs in the process (Blender's renderer). The command line, the add-on's operators,
the landmarks' search, the fit and the head binding run inside it.
"""
from __future__ import annotations

import functools
import sys
import threading
from contextlib import contextmanager

#: Threads the BLAS libraries (numpy's and scipy's OpenBLAS, MKL ...) may use inside :func:`bounded_threads`.
THREADS = 1

_inside = threading.local()


@contextmanager
def bounded_threads(limit: int = THREADS):
    """Run the block with at most ``limit`` BLAS threads, then restore the pools as they were.

    Nested uses keep the outermost limit, and bound again only when modules were imported since
    (scipy loads its own BLAS when first used, inside a command already bounded). Without
    ``threadpoolctl`` installed the block runs unbounded, as before.
    """
    outer = getattr(_inside, "limit", None)
    if outer is not None and _inside.modules == len(sys.modules):
        yield  # nothing new loaded: the outer bound holds
        return
    limiter = _limiter(limit if outer is None else outer)
    saved = outer, getattr(_inside, "modules", None)
    _inside.limit, _inside.modules = (limit if outer is None else outer), len(sys.modules)
    try:
        if limiter is None:
            yield
        else:
            with limiter:
                yield
    finally:
        _inside.limit, _inside.modules = saved


def bounded(fn):
    """Decorate ``fn`` to run inside :func:`bounded_threads`."""
    @functools.wraps(fn)
    def run(*args, **kwargs):
        with bounded_threads():
            return fn(*args, **kwargs)
    return run


def _limiter(limit: int):
    """threadpoolctl's limiter of every loaded BLAS pool to ``limit`` threads, or None without threadpoolctl."""
    try:
        from threadpoolctl import threadpool_limits
    except ImportError:
        return None
    return threadpool_limits(limits=limit, user_api="blas")  # OpenMP is left to its users (a renderer)
