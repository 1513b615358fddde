"""The C heap kept between a numerical run's steps: numpy's big arrays reuse freed memory, not fresh pages.

glibc's ``malloc`` takes each block over its threshold (128 KiB at first, rising to the largest freed since)
straight from the system (``mmap``) and gives it back when freed: the next array of that size is fresh memory,
every 4 KiB page of it a fault the kernel fills with zeros. The landmarks' renders, the fit and the head
binding make and drop thousands of arrays of 0.1-50 MB: a 27k-vertex head's ``pdeface rig`` took 134k page
faults, and half the renders' time went to them on a virtual machine (issue #35). After :func:`keep_heap`,
blocks under :data:`MMAP_THRESHOLDS` come from the heap and up to :data:`TRIM_THRESHOLD` of free memory stays at
its top, so a freed array's pages serve the next one: the rig faults half as often, its CPU time 10 % less.
It is process-wide and stays, so only a process's owner calls it: the ``pdeface`` command (``cli.run``), or your
own script; the library's functions and the add-on do not (in Blender, which lives on, it made no clear difference:
``bench_newhead --heap-runs``). Free memory at the heap's top beyond ``trim_threshold`` goes back to the system; memory
freed below a block still in use stays with the process until it ends (a command's process ends after one run).
:func:`grow_heap` has the pages a command will fault given on a thread beside it (``pdeface rig``: the faults off
its main thread, 0.1-0.2 s of its CPU). Elsewhere than glibc (macOS, Windows, musl) it changes nothing.
"""
from __future__ import annotations

import ctypes
import threading

#: Blocks under this many bytes come from the heap (a 27k head's largest arrays are ~30 MB; at 64 MiB its rig faulted
#: 66-71k times, at 32 MiB 90k); the second where glibc refuses the first (older glibc: at most HEAP_MAX_SIZE / 2,
#: 32 MiB on 64-bit systems, ``mallopt(3)``).
MMAP_THRESHOLDS = (64 << 20, 32 << 20)
#: Free bytes kept at the heap's top before any is given back to the system (at 32 MiB the rig faulted 82k times, at
#: 64 or 128 MiB 64k).
TRIM_THRESHOLD = 64 << 20
#: The blocks :func:`grow_heap` takes: under either mmap threshold (a block of 32 MiB and its header would be mapped
#: apart where the threshold is 32 MiB), so from the heap.
GROW_BLOCK = 16 << 20
_M_TRIM_THRESHOLD, _M_MMAP_THRESHOLD = -1, -3  # glibc's malloc.h

_lock = threading.Lock()
_kept = []  # [whether the thresholds were set], once per process
_grown = []  # [the grow_heap thread]: it grows the heap once per process


def _glibc():
    """The C library when it is glibc, else None."""
    try:
        libc = ctypes.CDLL(None)
        if not hasattr(libc, "gnu_get_libc_version"):  # glibc's own: musl's mallopt does nothing
            return None
        libc.mallopt.argtypes = [ctypes.c_int, ctypes.c_int]
    except (OSError, TypeError, AttributeError):  # Windows (no CDLL(None)), macOS
        return None
    return libc


def grow_heap(nbytes: int):
    """Have the kernel give the kept heap ``nbytes`` of memory now, on a thread of its own, for the arrays to come.

    A command's first arrays are fresh memory, each page a fault (see the module's notes): ICT's head's
    ``pdeface rig`` took ~70k on its main thread (docs/design/rig.md). Here blocks of :data:`GROW_BLOCK` are taken from
    the heap at once in the calling thread (its arena, the one the command's arrays come from) and one more above
    them, left untouched and never freed, so that the others do not end at the heap's top (which gives back all
    but ``TRIM_THRESHOLD`` of what is freed there). A daemon thread then writes each block, faulting its pages with
    the GIL released, and frees it: later arrays reuse those pages. Where a core is free the faults leave the
    command's critical path; where none is they cost what the arrays' own faults would have, as long as ``nbytes``
    is no more than the command would have faulted (more is memory the process holds for nothing).

    Only after :func:`keep_heap` took (a process's owner decides its heap): otherwise nothing is done. Once per
    process (it leaves its block above the others taken for good): a later call does nothing and returns None.

    Returns
    -------
    threading.Thread or None
        The thread writing the blocks (a daemon: a process may end before it has), or None where nothing was done.
    """
    if not (_kept and _kept[0]) or nbytes < GROW_BLOCK:
        return None
    with _lock:
        if _grown:  # once per process: each call keeps a block for good
            return None
        _grown.append(None)
    libc = _glibc()
    libc.malloc.restype, libc.malloc.argtypes = ctypes.c_void_p, [ctypes.c_size_t]
    libc.free.restype, libc.free.argtypes = None, [ctypes.c_void_p]
    libc.memset.restype, libc.memset.argtypes = ctypes.c_void_p, [ctypes.c_void_p, ctypes.c_int, ctypes.c_size_t]
    blocks = [libc.malloc(GROW_BLOCK) for _ in range(nbytes // GROW_BLOCK)]
    libc.malloc(GROW_BLOCK)  # the block above them, kept: freed, they are not the heap's top

    def fault_in():
        for block in blocks:
            if block:  # NULL: none to be had; the arrays will ask the system themselves
                libc.memset(block, 0, GROW_BLOCK)
                libc.free(block)

    thread = threading.Thread(target=fault_in, name="pdeface.heap.grow_heap", daemon=True)
    thread.start()
    _grown[0] = thread
    return thread


def keep_heap(trim_threshold: int = TRIM_THRESHOLD) -> bool:
    """Keep numpy's big arrays in the C heap from now on, in this process (see the module's notes), with up to
    ``trim_threshold`` bytes of free memory kept; the first call's settings hold, a later call does nothing.
    Returns whether the heap is kept (glibc that took the settings; elsewhere nothing is changed)."""
    with _lock:
        if not _kept:
            libc = _glibc()
            # mallopt returns 0 for a value refused: then the trim threshold is left too (setting it alone would
            # freeze glibc's moving mmap threshold at its first 128 KiB: more faults, not fewer)
            kept = libc is not None and any(libc.mallopt(_M_MMAP_THRESHOLD, size) == 1 for size in MMAP_THRESHOLDS)
            if kept:
                libc.mallopt(_M_TRIM_THRESHOLD, int(trim_threshold))
            _kept.append(kept)
    return _kept[0]
