"""The PDE surface evaluated on the output grid: the breaks' confinement, the grid and its quads."""
from __future__ import annotations

import numpy as np

from ..geometry import smoothstep
from ..landmark_scheme import (
    EYE_INNER_LEFT,
    EYE_INNER_RIGHT,
    EYE_OUTER_LEFT,
    EYE_OUTER_RIGHT,
    MOUTH_CORNER_LEFT,
    MOUTH_CORNER_RIGHT,
)
from .model import FaceModel, model_landmarks
from .pde import BREAK_SLOPE, sample_v, solve_surface

#: A break applies between its opening's corners, fading in over this many mm (along x) inside them; beyond
#: them the rims are one line (:func:`break_weights`).
CONFINE_RAMP_MM = 3.0
#: The corner landmarks of the openings a break can span: the eyes' (one break for both eyes), the mouth's.
OPENING_CORNERS = (((EYE_OUTER_RIGHT, EYE_INNER_RIGHT), (EYE_INNER_LEFT, EYE_OUTER_LEFT)),
                   ((MOUTH_CORNER_RIGHT, MOUTH_CORNER_LEFT),))


def break_weights(model: FaceModel, sub_v) -> tuple:
    """``(break, weight, d weight/dv)`` per break on the output columns: 1 between its opening's corner
    landmarks (the eyes' or the mouth's, whichever lies at its rims' height), fading to 0 at the corners over
    :data:`CONFINE_RAMP_MM`, 0 beyond, where the rims are one line
    (:func:`pdeface.surface.pde.solve_surface`). From the neutral face, so the same for every pose: keys stay
    linear. Empty (breaks across the whole width) without the corners' landmarks."""
    L = model_landmarks(model)
    X = model.curve_points()
    J = X.shape[1]
    vs = model.layout.sample_params()
    v = sample_v(J, sub_v)
    out = []
    for b in model.layout.breaks():
        rim = 0.5 * (X[b] + X[b + 1])
        x = np.interp(v, vs, rim[:, 0])  # across the face along the rims
        spans = min(OPENING_CORNERS, key=lambda o: abs(L[np.ravel(o), 1].mean() - rim[J // 2, 1]))
        weight = np.zeros(len(v))
        for a, c in spans:
            if not np.isfinite(L[[a, c]]).all():
                return ()
            lo, hi = sorted((L[a, 0], L[c, 0]))
            weight = np.maximum(weight, smoothstep(np.minimum(x - lo, hi - x) / CONFINE_RAMP_MM))
        out.append((b, weight, np.gradient(weight, v)))
    return tuple(out)


def surface_grid(model: FaceModel, sub_u=4, sub_v=4, assembly=None, coefficients=None, residual=None, deriv=(0, 0),
                 break_slope=BREAK_SLOPE, confine=True, planes=False, nodes=None, weights=None, reuse=None,
                 dtype=np.float64):
    """PDE surface (or a derivative) on the output grid, in the face frame (mm).

    ``confine``: each break only within its opening's span (:func:`break_weights`); the head binding
    reads the breaks across the whole width instead, so skin hidden behind a lip follows its rim.
    ``planes``: as (3, n_u, n_v) coordinate planes (:meth:`pdeface.surface.pde.SurfaceOperator.planes`).
    ``nodes``: at those grid nodes alone (flat indices, increasing), (p, 3)
    (:meth:`pdeface.surface.pde.SurfaceOperator.at_nodes`). ``weights``: :func:`break_weights` of ``sub_v``, when
    known (many solves on one grid). ``reuse``: with ``planes``, buffers kept between solves on one grid
    (:meth:`pdeface.surface.pde.SurfaceOperator.planes`). ``dtype``: with ``planes``, ``np.float32`` solves in
    float32 (the resolution choice's screen).
    """
    return solve_surface(model.coefficients if coefficients is None else coefficients,
                         model.residual if residual is None else residual,
                         model.knots, model.a, model.remainder_w, sub_u, sub_v,
                         assembly or model.assembly, deriv, model.layout.breaks(), break_slope,
                         (break_weights(model, sub_v) if weights is None else weights) if confine else (), planes,
                         nodes, reuse, dtype)


#: Descriptors solved together by :func:`key_grids`: all of a face's 72 at once held ~5 copies of their
#: float64 grids (issue #35: 150 MB on a 27k head's face); a batch this size keeps the solve as fast.
KEY_BATCH = 16


def key_stacks(model: FaceModel, batch=KEY_BATCH, dtype=np.float64) -> list:
    """The descriptors a few at a time, as :func:`key_grids` solves them: ``(first, C, R)``, their dense coefficient
    (K, N+1, 3m) and residual (K, J, 3m) changes side by side (the solve is linear), descriptor ``first + i`` in
    columns ``3i .. 3i + 2`` (:meth:`pdeface.au.descriptor.Descriptor.dense`'s values). The same for every grid: a
    caller solving on several makes them once. ``dtype``: of the stacks (float32 for :func:`key_grids`' own)."""
    stacks = []
    for first in range(0, len(model.descriptors), batch):
        part = model.descriptors[first:first + batch]
        K, J, N = part[0].layout
        C, R = np.zeros((K, N + 1, 3 * len(part)), dtype), np.zeros((K, J, 3 * len(part)), dtype)
        for i, d in enumerate(part):
            C[d.curves, :, 3 * i:3 * i + 3] = d.coefficients
            if d.residual is not None:
                R[d.curves, :, 3 * i:3 * i + 3] = d.residual
        stacks.append((first, C, R))
    return stacks


def key_grids(model: FaceModel, sub_u, sub_v, assembly=None, batch=KEY_BATCH, planes=False, reuse=False, stacks=None,
              dtype=np.float64, weights=None):
    """Each descriptor's change of the surface (face frame, mm) on the output grid, a few solves at a time:
    yields ``(first, grids)``, ``grids`` (n_u, n_v, m, 3) for descriptors ``first .. first + m - 1``
    (``planes``: (m, 3, n_u, n_v)). ``reuse`` (with ``planes``): each batch's grids are written over the last
    one's, for a caller done with a batch before it asks for the next (the same numbers, no fresh pages); a list:
    :meth:`pdeface.surface.pde.SurfaceOperator.planes`' buffers, kept by the caller across grids.
    ``stacks``: :func:`key_stacks` of ``batch``, when made already (made again where not of the solve's dtype: a
    float32 stack would round a float64 solve's keys). ``dtype``: with
    ``planes``, ``np.float32`` solves in float32 (half the bytes, about half the CPU; values to float32's rounding
    of its products), for the resolution choice's screen alone: keys and bindings stay float64. ``weights``:
    :func:`break_weights` of ``sub_v``, when known (the caller's rest grid on the same columns)."""
    weights = break_weights(model, sub_v) if weights is None else weights
    buffers = (reuse if isinstance(reuse, list) else [] if reuse else None) if planes else None
    dtype = dtype if planes else np.float64
    if stacks is not None and stacks and stacks[0][1].dtype != np.dtype(dtype):
        stacks = None
    for first, C, R in key_stacks(model, batch, dtype) if stacks is None else stacks:
        m = C.shape[2] // 3
        X = surface_grid(model, sub_u, sub_v, assembly, coefficients=C, residual=R, planes=planes, weights=weights,
                         reuse=buffers, dtype=dtype)
        yield first, (X.reshape((m, 3) + X.shape[1:]) if planes else X.reshape(X.shape[:2] + (m, 3)))


def grid_faces(n_u: int, n_v: int) -> np.ndarray:
    """Quads ``(m, 4)`` of an n_u × n_v vertex grid (row-major), facing outwards."""
    r, c = np.meshgrid(np.arange(n_u - 1), np.arange(n_v - 1), indexing="ij")
    i = (r * n_v + c).ravel()
    return np.stack([i, i + n_v, i + n_v + 1, i + 1], axis=1)
