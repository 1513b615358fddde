"""pdeface.threads: the BLAS pools are bounded inside bounded_threads and restored after it."""
import sys

import numpy as np
import pytest
from pdeface.threads import THREADS, bounded, bounded_threads

threadpoolctl = pytest.importorskip("threadpoolctl")


def blas_threads():
    """The thread count of every BLAS pool loaded (numpy's and scipy's OpenBLAS at least)."""
    import scipy.linalg  # noqa: F401 - loads scipy's own BLAS too

    return [p["num_threads"] for p in threadpoolctl.threadpool_info() if p["user_api"] == "blas"]


def test_bounded_threads_limits_every_blas_pool_and_restores_it():
    np.linalg.solve(np.eye(3), np.ones(3))  # numpy's BLAS loaded
    with threadpoolctl.threadpool_limits(limits=2, user_api="blas"):  # a known start, even on one core
        before = blas_threads()
        assert len(before) >= 1 and set(before) == {2}
        with bounded_threads():
            assert set(blas_threads()) == {THREADS}
            with bounded_threads(2):  # nested: the outermost limit stands
                assert set(blas_threads()) == {THREADS}
            assert set(blas_threads()) == {THREADS}
        assert blas_threads() == before
        with pytest.raises(ValueError), bounded_threads():
            raise ValueError("a failing solve")
        assert blas_threads() == before  # restored after an error too


def test_bounded_decorates_a_function_and_keeps_its_result():
    @bounded
    def inside(x):
        """doc"""
        return x, blas_threads()

    with threadpoolctl.threadpool_limits(limits=2, user_api="blas"):
        value, threads = inside(3)
        assert value == 3 and set(threads) == {THREADS} and inside.__doc__ == "doc"
        assert set(blas_threads()) == {2}


def test_without_threadpoolctl_the_block_runs_unbounded(monkeypatch):
    with threadpoolctl.threadpool_limits(limits=2, user_api="blas"):
        monkeypatch.setitem(sys.modules, "threadpoolctl", None)  # as if not installed
        with bounded_threads():
            inside = blas_threads()
        monkeypatch.undo()
        assert set(inside) == {2} and set(blas_threads()) == {2}
        with bounded_threads():  # and once installed again, bounded again
            assert set(blas_threads()) == {THREADS}


def test_a_blas_loaded_inside_a_bound_is_bounded_by_the_next_nested_one():
    """A command is bounded before scipy (and its own BLAS) loads; the fit's or binding's bound inside it
    catches that library, at the command's limit."""
    import subprocess

    probe = ("import numpy; from threadpoolctl import threadpool_info, threadpool_limits\n"
             "from pdeface.threads import bounded_threads\n"
             "with threadpool_limits(limits=2, user_api='blas'), bounded_threads(1):\n"
             "    import scipy.linalg\n"
             "    with bounded_threads(2):\n"
             "        print(sorted({p['num_threads'] for p in threadpool_info() if p['user_api'] == 'blas'}),"
             " len([p for p in threadpool_info() if p['user_api'] == 'blas']))\n")
    out = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, check=True).stdout.split()
    assert out[0] == "[1]" and int(out[1]) >= 2  # numpy's and scipy's pools, both at the outer limit


def test_the_resolution_choice_runs_bounded(monkeypatch, default_face):
    """Choosing a face's mesh resolution (small solves: more threads only spin) runs inside the bound, called
    from anywhere (the add-on, the API), not only from a command."""
    import copy

    from pdeface.surface import sampling

    seen, measure = [], sampling.interval_turns

    def spy(*args, **kwargs):
        seen.append(blas_threads())
        return measure(*args, **kwargs)

    monkeypatch.setattr(sampling, "interval_turns", spy)
    model = copy.deepcopy(default_face)
    model.descriptors = model.descriptors[:3]  # another model: chosen afresh
    with threadpoolctl.threadpool_limits(limits=2, user_api="blas"):
        sampling.adaptive_resolution(model)
        assert set(blas_threads()) == {2}
    assert seen and all(set(s) == {THREADS} for s in seen)


def test_the_landmark_search_runs_bounded(monkeypatch):
    """Finding landmarks (numpy's products on the renders: an OpenBLAS thread beside them only spins on a busy
    machine) runs inside the bound, called from the API as the benchmarks call it, not only from a command."""
    from pdeface.errors import LandmarkError
    from pdeface.landmarks import pipeline
    from pdeface.mesh import Mesh

    seen = []

    def search(*args, **kwargs):  # the first step after the normals: stop there, no MediaPipe needed
        seen.append(blas_threads())
        raise LandmarkError("stopped")

    class Unused:
        def close(self):
            raise AssertionError("a detector given is the caller's to close")

    monkeypatch.setattr(pipeline, "search", search)
    box = Mesh.from_faces(np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1.0]]),
                          np.array([[0, 1, 2], [0, 1, 3], [0, 2, 3], [1, 2, 3]]))
    with threadpoolctl.threadpool_limits(limits=2, user_api="blas"):
        with pytest.raises(LandmarkError, match="stopped"):
            pipeline.detect(box.vertices, box.triangles()[0], detector=Unused())
        assert set(blas_threads()) == {2}
    assert seen and all(set(s) == {THREADS} for s in seen)
