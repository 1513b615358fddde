import resource
import subprocess
import sys
from pathlib import Path

import pytest
from pdeface import heap

#: The system's page (4 KiB on x86-64, 16 or 64 KiB on some ARM kernels): each first write to one is a page fault.
PAGE = resource.getpagesize()
#: Where the kernel gives every anonymous mapping huge pages (RHEL's default), a heap's faults are not counted in
#: pages of PAGE bytes: 2 MiB pages fault hundreds of times less, kept heap or not.
THP = Path("/sys/kernel/mm/transparent_hugepage/enabled")
HUGE_PAGES_ALWAYS = THP.is_file() and "[always]" in THP.read_text()
SKIP_HUGE = "transparent huge pages 'always': the heap's faults are not counted in the system's pages"

GROWING_ARRAYS = """
import resource, sys
import numpy as np
from pdeface.heap import keep_heap

glibc = keep_heap() if sys.argv[1] == "kept" else None
start = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
for kb in range(1024, 4096, 128):  # each array larger than the last, under 4 MiB (numpy asks for huge pages there)
    a = np.ones(kb << 7)  # kb KiB, every page written
    del a
print(resource.getrusage(resource.RUSAGE_SELF).ru_minflt - start, glibc)
"""


def test_keep_heap_reuses_freed_arrays_pages():
    """After keep_heap, arrays made and dropped one after another reuse the heap's pages: a fraction of the page
    faults of glibc's default, where each new larger array is fresh memory (a fresh process each)."""
    runs = {}
    for mode in ("default", "kept"):
        out = subprocess.run([sys.executable, "-c", GROWING_ARRAYS, mode], check=True, capture_output=True,
                             text=True).stdout.split()
        runs[mode], glibc = int(out[0]), out[1]
    pages = (sum(range(1024, 4096, 128)) << 10) // PAGE  # the pages of all the arrays
    if glibc == "True":
        if HUGE_PAGES_ALWAYS:
            pytest.skip(SKIP_HUGE)
        assert runs["default"] > 0.8 * pages
        assert runs["kept"] < 0.25 * pages, runs
    else:  # another C library: nothing changed
        assert glibc == "False" and abs(runs["kept"] - runs["default"]) < 0.25 * pages, runs


HELD_ARRAYS = """
import resource, sys
import numpy as np
from pdeface.heap import grow_heap, keep_heap

kept = keep_heap()
thread = grow_heap(80 << 20) if sys.argv[1] == "grown" else None
if thread is not None:
    thread.join()
start = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
# 64 MiB at once, every page written: the heap must grow by that much (each array under 4 MiB, where numpy asks for
# huge pages)
held = [np.ones(1 << 18) for _ in range(32)]
print(resource.getrusage(resource.RUSAGE_SELF).ru_minflt - start, kept, thread is not None)
"""


def test_grow_heap_gives_the_pages_before_the_arrays_ask():
    """Arrays held together (the heap grows) fault a fraction of their pages after grow_heap wrote as many bytes on
    its thread; without keep_heap (another C library) it does nothing (a fresh process each)."""
    runs = {}
    for mode in ("kept", "grown"):
        out = subprocess.run([sys.executable, "-c", HELD_ARRAYS, mode], check=True, capture_output=True,
                             text=True).stdout.split()
        runs[mode], kept, grown = int(out[0]), out[1], out[2]
    pages = (64 << 20) // PAGE  # the pages of the arrays
    if kept == "True":
        if HUGE_PAGES_ALWAYS:
            pytest.skip(SKIP_HUGE)
        assert grown == "True" and runs["kept"] > 0.8 * pages and runs["grown"] < 0.1 * pages, runs
    else:
        assert grown == "False", runs


def test_grow_heap_does_nothing_unless_the_heap_is_kept(monkeypatch):
    """Only a process that keeps its heap (keep_heap, glibc) grows it: elsewhere freed blocks would go back to the
    system at once; and less than a block is not worth a thread."""
    for kept in ([], [False]):
        monkeypatch.setattr(heap, "_kept", kept)
        assert heap.grow_heap(4 * heap.GROW_BLOCK) is None
    monkeypatch.setattr(heap, "_kept", [True])
    assert heap.grow_heap(heap.GROW_BLOCK - 1) is None


def test_grow_heap_grows_the_heap_once_per_process():
    """A second call does nothing (each call keeps a block for good): a script calling it per head holds no more."""
    code = ("from pdeface.heap import grow_heap, keep_heap\n"
            "kept = keep_heap()\n"
            "first = grow_heap(2 << 24)\n"
            "first is None or first.join()\n"
            "print(kept, first is not None, grow_heap(2 << 24) is None)\n")
    kept, grew, second_none = subprocess.run([sys.executable, "-c", code], check=True, capture_output=True,
                                             text=True).stdout.split()
    assert second_none == "True" and grew == kept  # grown where the heap is kept (glibc), never twice


class _FakeLibc:
    def __init__(self):
        self.calls = []

    def mallopt(self, option, value):
        self.calls.append((option, value))
        return 1


def test_keep_heap_sets_the_thresholds_once(monkeypatch):
    fake = _FakeLibc()
    monkeypatch.setattr(heap, "_kept", [])
    monkeypatch.setattr(heap, "_glibc", lambda: fake)
    assert heap.keep_heap(trim_threshold=5 << 20) and heap.keep_heap()  # the first call's settings hold
    assert fake.calls == [(-3, heap.MMAP_THRESHOLDS[0]), (-1, 5 << 20)]  # M_MMAP_THRESHOLD, M_TRIM_THRESHOLD


def test_keep_heap_changes_nothing_without_glibc(monkeypatch):
    monkeypatch.setattr(heap, "_kept", [])
    monkeypatch.setattr(heap, "_glibc", lambda: None)
    assert heap.keep_heap() is False and heap._kept == [False]


def test_keep_heap_falls_back_to_the_threshold_older_glibc_takes(monkeypatch):
    """An older glibc refuses an mmap threshold over 32 MiB (mallopt returns 0): the smaller is set, then the trim
    threshold."""
    fake = _FakeLibc()
    fake.mallopt = lambda option, value: fake.calls.append((option, value)) or int(value <= 32 << 20)
    monkeypatch.setattr(heap, "_kept", [])
    monkeypatch.setattr(heap, "_glibc", lambda: fake)
    assert heap.keep_heap() is True
    assert fake.calls == [(-3, 64 << 20), (-3, 32 << 20), (-1, heap.TRIM_THRESHOLD)]


def test_keep_heap_sets_nothing_more_where_glibc_refuses_every_threshold(monkeypatch):
    """Every mmap threshold refused: the trim threshold is left too (alone it would freeze glibc's moving threshold
    at 128 KiB) and the heap is reported as not kept."""
    fake = _FakeLibc()
    fake.mallopt = lambda option, value: fake.calls.append((option, value)) or 0
    monkeypatch.setattr(heap, "_kept", [])
    monkeypatch.setattr(heap, "_glibc", lambda: fake)
    assert heap.keep_heap() is False
    assert fake.calls == [(-3, size) for size in heap.MMAP_THRESHOLDS]
