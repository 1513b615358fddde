"""The PDE face model: a neutral face as boundary curves in its face frame.

The value that fitting makes and everything downstream reads; its file format
lives in :mod:`pdeface.au.modelfile`.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..landmark_scheme import FEATURE_NAMES, FEATURE_POINTS
from .fourier import evaluate_fourier
from .frame import FaceFrame
from .layout import CurveLayout

#: The landmarks binding a whole head needs at least (:mod:`pdeface.head`): jawline 0, 5, 8, 11, 16, nose bottom
#: 33, the eyes 36-47 and the lips 48, 51, 54, 57, 62, 66; older model files kept these alone, to
#: 0.1 mm (a model file now keeps all 68 it was fitted with, unrounded: :mod:`pdeface.au.modelfile`).
KEPT_LANDMARKS = (0, 5, 8, 11, 16, 33, *range(36, 48), 48, 51, 54, 57, 62, 66)


@dataclass
class FaceModel:
    """A neutral face as PDE boundary curves.

    All geometry is in the face frame (mm); :attr:`frame` maps back to the
    source mesh's space and unit.

    Attributes
    ----------
    layout : CurveLayout
    knots : (K,) array
        Curve parameters ``u_i``.
    coefficients : (K, N+1, 3) array
    residual : (K, J, 3) array
    frame : FaceFrame
    features : (19, 3) array
    a : float
        PDE smoothing parameter.
    w : float
        Remainder wavenumber.
    assembly : str
        Default assembly for meshing.
    source : str
        Where the model came from (free text).
    notice : str
        Licence notice of the data it derives from, if any.
    status : (K, J) int array or None
        Curve point status (see :mod:`pdeface.surface.curves`).
    descriptors : list
        AU descriptors carried with the model (see :mod:`pdeface.au.descriptor`).
    landmarks : (68, 3) array or None
        The 68 landmarks it was fitted with, face frame (binding a whole head needs
        them). A model read from an older file has only the
        :data:`KEPT_LANDMARKS` (to 0.1 mm) and NaN rows for the others.
    """

    layout: CurveLayout
    knots: np.ndarray
    coefficients: np.ndarray
    residual: np.ndarray
    frame: FaceFrame
    features: np.ndarray
    a: float = 1.0
    w: float | None = None
    assembly: str = "smooth"
    source: str = ""
    notice: str = ""
    status: np.ndarray | None = None
    descriptors: list = field(default_factory=list)
    landmarks: np.ndarray | None = None

    @property
    def n_modes(self) -> int:
        return self.coefficients.shape[1] - 1

    @property
    def remainder_w(self) -> float:
        return self.a * (self.n_modes + 1) if self.w is None else self.w

    def curve_points(self, coefficients=None, residual=None) -> np.ndarray:
        """Curve points (K, J, 3) in the face frame (from the series and residual)."""

        c = self.coefficients if coefficients is None else coefficients
        r = self.residual if residual is None else residual
        return evaluate_fourier(c, self.layout.sample_params()) + r


def model_landmarks(model) -> np.ndarray:
    """A face model's 68 landmarks (face frame): the kept ones, and the feature points' where missing
    (the brows' ends, the nose bridge, wings and tip are feature points of one landmark each)."""

    L = np.full((68, 3), np.nan) if model.landmarks is None else np.array(model.landmarks, np.float64)
    for name, F in zip(FEATURE_NAMES, model.features):
        ids = FEATURE_POINTS[name]
        if len(ids) == 1 and not np.isfinite(L[ids[0]]).all():
            L[ids[0]] = F
    return L
