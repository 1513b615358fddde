"""The C heap kept between a numerical run's steps: numpy's big arrays reuse freed memory, not fresh pages.

glibc's ``malloc`` takes each block over its threshold (128 KiB at first, rising to the largest freed since)
straight from the system (``mmap``) and gives it back when freed: the next array of that size is fresh memory,
every 4 KiB page of it a fault the kernel fills with zeros. The landmarks' renders, the fit and the head
binding make and drop thousands of arrays of 0.1-50 MB: a 27k-vertex head's ``pdeface rig`` took 139k page
faults, and half the renders' time went to them on a virtual machine (issue #35). Inside :func:`kept_heap`,
blocks under :data:`MMAP_THRESHOLD` come from the heap and up to :data:`TRIM_THRESHOLD` of free memory stays at
its top, so a freed array's pages serve the next one; leaving the outermost block gives the free memory back to
the system (``malloc_trim``) unless told not to. The two thresholds stay set after it (once set, glibc's
threshold no longer rises; its first 128 KiB would fault more than its moving one did). Elsewhere than glibc
(macOS, Windows, musl) it changes nothing.
"""
from __future__ import annotations

import ctypes
import threading
from contextlib import contextmanager

#: Blocks under this many bytes come from the heap inside :func:`kept_heap` (a 27k head's largest arrays are ~30 MB).
MMAP_THRESHOLD = 64 << 20
#: Free bytes kept at the heap's top inside :func:`kept_heap` before any is given back.
TRIM_THRESHOLD = 128 << 20
_M_TRIM_THRESHOLD, _M_MMAP_THRESHOLD = -1, -3  # glibc's malloc.h

_lock = threading.Lock()
_depth = 0
_libc = []  # [glibc, or None where the C library is another], found once


def _glibc():
    if not _libc:
        try:
            libc = ctypes.CDLL(None)
            if not hasattr(libc, "gnu_get_libc_version"):  # glibc's own: musl's mallopt does nothing
                raise AttributeError("not glibc")
            libc.mallopt.argtypes = [ctypes.c_int, ctypes.c_int]
            libc.malloc_trim.argtypes = [ctypes.c_size_t]
        except (OSError, TypeError, AttributeError):  # Windows (CDLL(None)), macOS, musl
            libc = None
        _libc.append(libc)
    return _libc[0]


@contextmanager
def kept_heap(give_back: bool = True):
    """Run the block with numpy's big arrays kept in the C heap between uses (see the module's notes).

    Parameters
    ----------
    give_back : bool
        On leaving the outermost block, give the heap's free memory back to the system (an application that
        lives on: the add-on). A process about to end (the command line) leaves it to the exit.
    """
    global _depth
    libc = _glibc()
    if libc is None:
        yield
        return
    with _lock:
        if _depth == 0:
            libc.mallopt(_M_MMAP_THRESHOLD, MMAP_THRESHOLD)
            libc.mallopt(_M_TRIM_THRESHOLD, TRIM_THRESHOLD)
        _depth += 1
    try:
        yield
    finally:
        with _lock:
            _depth -= 1
            if _depth == 0 and give_back:
                libc.malloc_trim(0)
