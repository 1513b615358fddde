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


def clustered(V, T, cell):
    """The mesh remeshed by vertex clustering on a grid of ``cell``: another topology of the same shape."""
    key = np.floor(V / cell).astype(np.int64)
    _, inv, counts = np.unique(key, axis=0, return_inverse=True, return_counts=True)
    inv = inv.ravel()
    Vc = np.zeros((len(counts), 3))
    np.add.at(Vc, inv, V)
    Tc = inv[T]
    Tc = Tc[(Tc[:, 0] != Tc[:, 1]) & (Tc[:, 1] != Tc[:, 2]) & (Tc[:, 0] != Tc[:, 2])]
    return Vc / counts[:, None], np.unique(Tc, axis=0)


def body_character(V, T):
    """A whole-body character in metres, Blender's axes (-y front, +z up), of another topology than ``V, T``
    (an ICT head in cm, ICT axes): the head clustered on a 3 mm grid on a box torso, arms and legs.
    Returns vertices, triangles and the matrix taking ICT cm to the body's space (``V @ M.T``)."""
    from pdeface.surface.frame import BLENDER_FROM_ICT

    M = BLENDER_FROM_ICT * 0.01
    Vh, Th = clustered(V @ M.T + [0, 0, 1.55], T, 0.003)
    parts = [(Vh, Th)]
    quads = np.array([[0, 1, 3, 2], [4, 6, 7, 5], [0, 4, 5, 1], [2, 3, 7, 6], [0, 2, 6, 4], [1, 5, 7, 3]])
    box_t = np.concatenate([quads[:, [0, 1, 2]], quads[:, [0, 2, 3]]])
    # torso, arms (slightly spread), legs: (centre, half sizes) in metres
    for c, h in [((0, 0, 1.15), (0.18, 0.11, 0.3)), ((-0.3, 0, 1.05), (0.05, 0.05, 0.35)),
                 ((0.3, 0, 1.05), (0.05, 0.05, 0.35)), ((-0.1, 0, 0.42), (0.07, 0.07, 0.42)),
                 ((0.1, 0, 0.42), (0.07, 0.07, 0.42))]:
        box = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)]) * h + c
        parts.append((box, box_t))
    Vs, Ts, n = [], [], 0
    for Vp, Tp in parts:
        Vs.append(Vp)
        Ts.append(Tp + n)
        n += len(Vp)
    return np.concatenate(Vs), np.concatenate(Ts), M, np.array([0, 0, 1.55])
