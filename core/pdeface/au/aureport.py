"""How much of an AU's true motion a PDE descriptor captures.

For each scan vertex that is visible in the curve band and truly moves more
than 0.5 mm, the PDE displacement is read at the vertex's place on the neutral
PDE surface (closest point, then the same (u, v) on the posed surface):

``captured = 1 − RMS(d_pde − d_true) / RMS(d_true)``, and ``p95_err_mm`` is the
95th percentile of ``|d_pde − d_true|``.
"""
from __future__ import annotations

import numpy as np

from ..geometry import ClosestPoint
from ..surface.grid import grid_faces, surface_grid
from ..surface.report import REPORT_RESOLUTION, band_vertices
from .descriptorfile import descriptor_to_bytes
from .ict import AU_SHAPES, au_offsets

#: Only vertices moving more than this (mm) are measured.
MOTION_MM = 0.5


def captured(predicted, true) -> float:
    """``1 − RMS(predicted − true) / RMS(true)`` over rows of displacements (the same vertices)."""
    err = np.linalg.norm(predicted - true, axis=1)
    return float(1 - np.sqrt((err ** 2).mean()) / np.sqrt((np.linalg.norm(true, axis=1) ** 2).mean()))


class MotionProbe:
    """Neutral PDE surface and scan correspondence, shared by many AUs."""

    def __init__(self, model, scan_vertices, scan_triangles, resolution=REPORT_RESOLUTION):
        self.model = model
        self.resolution = resolution
        self.V = np.asarray(scan_vertices, np.float64)
        self.Vf = model.frame.to_face(self.V)
        self.visible = band_vertices(model, self.Vf, np.asarray(scan_triangles))["visible"]
        X0 = surface_grid(model, *resolution)
        self.X0 = X0.reshape(-1, 3)
        nu, nv, _ = X0.shape
        Q = grid_faces(nu, nv)
        self.Tp = np.concatenate([Q[:, [0, 1, 2]], Q[:, [0, 2, 3]]])
        idx = np.nonzero(self.visible)[0]
        _, tri, bary, _ = ClosestPoint(self.X0, self.Tp).query(self.Vf[idx])
        self.idx, self.tri, self.bary = idx, tri, bary

    def pde_displacement(self, delta_coefficients, delta_residual):
        """PDE displacement (face frame, mm) at the measured vertices."""
        m = self.model
        D = surface_grid(m, *self.resolution, coefficients=delta_coefficients, residual=delta_residual)
        D = D.reshape(-1, 3)  # the solve is linear: solve(Δ) is the displacement
        return np.einsum("pk,pkc->pc", self.bary, D[self.Tp[self.tri]])

    def measure(self, delta_coefficients, delta_residual, true_offsets) -> dict:
        """``captured``, ``p95_err_mm``, ``n_vertices`` for one AU.

        ``true_offsets`` are the scan's per-vertex offsets in the scan's space.
        """
        d_true_all = self.model.frame.to_face(self.V + true_offsets) - self.Vf
        d_true = d_true_all[self.idx]
        moving = np.linalg.norm(d_true, axis=1) > MOTION_MM
        if not moving.any():
            return {"captured": None, "p95_err_mm": None, "n_vertices": 0}
        d_pde = self.pde_displacement(delta_coefficients, delta_residual)[moving]
        err = np.linalg.norm(d_pde - d_true[moving], axis=1)
        return {"captured": captured(d_pde, d_true[moving]),
                "p95_err_mm": float(np.percentile(err, 95)), "n_vertices": int(moving.sum())}


def au_report(model, scan_vertices, scan_triangles, shapes) -> dict:
    """How much of each AU's true motion the model's descriptors capture.

    Parameters
    ----------
    model : FaceModel
        A face with descriptors, fitted to ``scan_vertices``.
    scan_vertices, scan_triangles : arrays
        The neutral scan (ICT-FaceKit's face region topology).
    shapes : mapping
        ICT shape name → (n, 3) offsets: the bundled shapes
        (:func:`pdeface.assets.load_ict_shapes`) or an :class:`pdeface.au.ict.IctFolder`.

    Returns
    -------
    dict
        AU key → ``captured``, ``p95_err_mm``, ``n_vertices`` (see
        :meth:`MotionProbe.measure`) and ``bytes`` (binary descriptor size), for
        every descriptor whose AU ICT-FaceKit has shapes for.
    """

    probe = MotionProbe(model, scan_vertices, scan_triangles)
    result = {}
    for d in model.descriptors:
        if d.key in AU_SHAPES:
            r = probe.measure(*d.dense(), au_offsets(d.key, shapes))
            result[d.key] = {**r, "bytes": len(descriptor_to_bytes(d))}
    return result
