"""AU descriptors: the change of curve coefficients an Action Unit causes.

A :class:`Descriptor` holds, for the curves an AU moves only, the change of
each curve's Fourier coefficients and of its remainder residual (face frame,
mm). Curves it does not move hold nothing. The face with AUs is
``solve(neutral + Σ wᵢ Dᵢ)``; the solve is linear, so a descriptor is exactly a
linear shape key.

File formats: :mod:`pdeface.au.descriptorfile`; descriptors from scans:
:mod:`pdeface.au.capture`.
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from ..errors import PdeFaceError
from ..facs import SIDES, action_unit
from ..surface.fourier import evaluate_fourier, fit_fourier

#: A curve is affected when one of its points moves more than this (mm); the
#: same 0.5 mm below which the AU report does not count a vertex as moving.
AFFECTED_MM = 0.5

#: A descriptor's ``source`` when the muscles made it (:mod:`pdeface.muscles.aus`), and the word that
#: begins it when an FDT did (``fdt 3d (TABLE)``, :mod:`pdeface.fdt.deform`); any other source names the
#: scan it was captured from (an AU mesh, ICT-FaceKit's shapes).
MUSCLE_SOURCE = "muscle"
FDT_SOURCE = "fdt"
#: Where descriptors come from, as :func:`source_kind` names it (``other``: no source recorded).
SOURCE_KINDS = ("scan", "muscle", "fdt", "other")


def source_kind(source: str) -> str:
    """Where a descriptor with this ``source`` came from: one of :data:`SOURCE_KINDS`."""
    if not source:
        return "other"
    if source == MUSCLE_SOURCE:
        return "muscle"
    if source.split(" ", 1)[0] == FDT_SOURCE:
        return "fdt"
    return "scan"


def no_descriptors(face=None) -> str:
    """The one-line message for a face model without descriptors, naming the command that gives it some."""
    where = f"{face}: this face" if face else "this face"
    return f"{where} carries no AU descriptors: run `pdeface retarget {face or 'FACE'} -o RIG.npz` first"


@dataclass
class Descriptor:
    """One Action Unit as a sparse change of the curves (face frame, mm).

    Attributes
    ----------
    au : int
        FACS AU number.
    side : {'both', 'left', 'right'}
        The subject's side it acts on.
    curves : (m,) int array
        Indices of the affected curves.
    coefficients : (m, N+1, 3) array
        Change of the cosine coefficients of those curves.
    residual : (m, J, 3) array or None
        Change of their remainder residual.
    layout : (int, int, int)
        (curves, points per curve, modes) of the face layout it belongs to.
    name, source, notice : str
        FACS name, where it came from, licence notice of its data.
    """

    au: int
    side: str
    curves: np.ndarray
    coefficients: np.ndarray
    residual: np.ndarray | None
    layout: tuple
    name: str = ""
    source: str = ""
    notice: str = ""
    extra: dict = field(default_factory=dict)

    def __post_init__(self):
        self.curves = np.asarray(self.curves, dtype=np.int64)
        self.coefficients = np.asarray(self.coefficients, dtype=np.float64)
        if self.residual is not None:
            self.residual = np.asarray(self.residual, dtype=np.float64)
        self.layout = tuple(int(x) for x in self.layout)
        if not self.name:
            self.name = action_unit(self.au).name

    @property
    def key(self) -> str:
        """``"12"``, ``"12L"`` or ``"12R"``."""
        return str(self.au) + {"both": "", "left": "L", "right": "R"}[self.side]

    @property
    def kind(self) -> str:
        """Where it came from: ``scan``, ``muscle``, ``fdt`` or ``other`` (:func:`source_kind`)."""
        return source_kind(self.source)

    @property
    def label(self) -> str:
        """``"AU12 Lip Corner Puller"`` (with ``(left)``/``(right)``)."""
        side = "" if self.side == "both" else f" ({self.side})"
        return f"AU{self.au} {self.name}{side}"

    def points(self) -> np.ndarray:
        """Change of the affected curves' points (m, J, 3): series plus residual."""

        pts = evaluate_fourier(self.coefficients, np.linspace(0, np.pi, self.layout[1]))
        return pts if self.residual is None else pts + self.residual

    def dense(self) -> tuple[np.ndarray, np.ndarray]:
        """Full (K, N+1, 3) coefficient and (K, J, 3) residual changes."""
        K, J, N = self.layout
        C = np.zeros((K, N + 1, 3))
        R = np.zeros((K, J, 3))
        C[self.curves] = self.coefficients
        if self.residual is not None:
            R[self.curves] = self.residual
        return C, R

    def scaled(self, factor) -> "Descriptor":
        """The descriptor times a scalar or a per-axis (3,) factor."""
        f = np.asarray(factor, dtype=np.float64)
        return replace(self, coefficients=self.coefficients * f,
                       residual=None if self.residual is None else self.residual * f)

    def __mul__(self, factor):
        return self.scaled(factor)

    __rmul__ = __mul__

    def __neg__(self):
        return self.scaled(-1.0)

    def __add__(self, other: "Descriptor") -> "Descriptor":
        if self.layout != other.layout:
            raise PdeFaceError(f"cannot add descriptors of layouts {self.layout} and {other.layout}")
        C = self.dense()[0] + other.dense()[0]
        R = self.dense()[1] + other.dense()[1]
        curves = np.union1d(self.curves, other.curves)
        return replace(self, curves=curves, coefficients=C[curves], residual=R[curves],
                       name=f"{self.name} + {other.name}" if other.key != self.key else self.name)

    def __sub__(self, other):
        return self + (-other)


def replace_descriptors(descriptors, extra) -> list:
    """``descriptors`` with ``extra`` added, each replacing the one of its AU key (``"12"``, ``"12L"``) if any.

    Parameters
    ----------
    descriptors : list of Descriptor
        A face model's own descriptors.
    extra : list of Descriptor
        Descriptors to add, for instance read from files.

    Returns
    -------
    list of Descriptor
        The kept descriptors in their order, then ``extra``.
    """
    keys = {d.key for d in extra}
    return [d for d in descriptors if d.key not in keys] + list(extra)


def affected_curves(delta_points: np.ndarray, threshold_mm: float = AFFECTED_MM) -> np.ndarray:
    """Curves with a point moving more than ``threshold_mm``."""
    return np.nonzero(np.linalg.norm(delta_points, axis=2).max(axis=1) > threshold_mm)[0]


def descriptor_from_points(neutral_points, au_points, au, side="both", n_modes=5, source="", notice="",
                           threshold_mm=AFFECTED_MM) -> Descriptor:
    """Descriptor from neutral and AU curve points (K, J, 3), face frame mm."""
    if side not in SIDES:
        raise PdeFaceError(f"side must be one of {', '.join(SIDES)}, got {side!r}")
    d = np.asarray(au_points, np.float64) - np.asarray(neutral_points, np.float64)
    if not np.isfinite(d).all():
        raise PdeFaceError("AU curve points contain NaN or inf")
    C, R = fit_fourier(d, n_modes)  # the fit is linear: fit(AU) - fit(neutral) = fit(AU - neutral)
    curves = affected_curves(d, threshold_mm)
    K, J, _ = d.shape
    return Descriptor(int(au), side, curves, C[curves], R[curves], (K, J, n_modes), source=source, notice=notice)


def descriptor_rows(descriptors) -> list:
    """What a face's descriptors are, one row per AU key, by AU number then side.

    Parameters
    ----------
    descriptors : iterable of Descriptor

    Returns
    -------
    list of dict
        ``key`` (``"12L"``), ``au`` (12), ``name`` (the FACS catalogue's), ``side`` (``both``, ``left``,
        ``right``), ``kind`` (:func:`source_kind`), ``source`` (as recorded) and ``curves`` (the
        indices of the curves it moves).
    """
    rows = [{"key": d.key, "au": d.au, "name": action_unit(d.au).name, "side": d.side, "kind": d.kind,
             "source": d.source, "curves": d.curves.tolist()} for d in descriptors]
    return sorted(rows, key=lambda r: (r["au"], SIDES.index(r["side"])))
