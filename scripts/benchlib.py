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


def bundled_ict():
    """The bundled face and ICT data every benchmark measures on: (face, V, T, landmark indices, shapes)."""
    from pdeface.assets import load_face, load_ict_shapes, load_neutral_scan

    mesh, idx = load_neutral_scan()
    return load_face("default"), mesh.vertices, mesh.triangles()[0], idx, load_ict_shapes()
