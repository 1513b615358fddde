"""Helpers shared by the benchmark scripts."""
import time

import numpy as np


def median_time(fn, repeat=5):
    """Median wall time of ``fn()`` over ``repeat`` calls (seconds)."""
    times = []
    for _ in range(repeat):
        t = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t)
    return float(np.median(times))
