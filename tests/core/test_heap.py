import subprocess
import sys

import pytest
from pdeface import heap

GROWING_ARRAYS = """
import resource, sys
import numpy as np
from pdeface.heap import kept_heap, _glibc

def faults():  # each array a little larger than the last: glibc's moving threshold sends each to mmap
    start = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
    for kb in range(1024, 4096, 128):  # under 4 MiB: numpy asks for huge pages from there (fewer faults)
        a = np.ones(kb << 7)  # kb KiB, every page written
        del a
    return resource.getrusage(resource.RUSAGE_SELF).ru_minflt - start

if sys.argv[1] == "kept":
    with kept_heap():
        print(faults())
else:
    print(faults())
print(_glibc() is not None)
"""


def test_kept_heap_reuses_freed_arrays_pages():
    """Inside kept_heap, arrays made and dropped one after another reuse the heap's pages: a fraction of the
    page faults of glibc's default, where each new larger array is fresh memory (a fresh process each)."""
    runs = {}
    for mode in ("default", "kept"):
        out = subprocess.run([sys.executable, "-c", GROWING_ARRAYS, mode], check=True, capture_output=True,
                             text=True).stdout.split()
        runs[mode], glibc = int(out[0]), out[1] == "True"
    if not glibc:
        pytest.skip("not glibc: kept_heap changes nothing here")
    pages = sum(range(1024, 4096, 128)) >> 2  # 4 KiB pages of all the arrays
    assert runs["default"] > 0.8 * pages
    assert runs["kept"] < 0.25 * pages, runs


class _FakeLibc:
    def __init__(self):
        self.calls = []

    def mallopt(self, option, value):
        self.calls.append(("mallopt", option, value))
        return 1

    def malloc_trim(self, pad):
        self.calls.append(("trim", pad))
        return 1


def test_kept_heap_sets_once_and_gives_back_on_leaving_the_outermost(monkeypatch):
    fake = _FakeLibc()
    monkeypatch.setattr(heap, "_libc", [fake])
    with heap.kept_heap():
        with heap.kept_heap(give_back=False):
            pass
        assert fake.calls == [("mallopt", -3, heap.MMAP_THRESHOLD), ("mallopt", -1, heap.TRIM_THRESHOLD)]
    assert fake.calls[-1] == ("trim", 0) and len(fake.calls) == 3
    with pytest.raises(KeyError), heap.kept_heap(give_back=False):  # an error leaves it as a return does
        raise KeyError("x")
    assert heap._depth == 0 and len(fake.calls) == 5  # set again, not given back


def test_kept_heap_changes_nothing_without_glibc(monkeypatch):
    monkeypatch.setattr(heap, "_libc", [None])

    @heap.kept_heap()
    def work(x):
        return x + 1

    assert work(1) == 2 and heap._depth == 0
