"""FDTs from faces, FDTs onto faces, and naming an expression by its FDT.

- :func:`fit_fdt`: one face's table from a neutral and a posed mesh (same
  vertices; the regions are placed from the neutral's 68 landmarks, so any
  topology will do), or :func:`fit_fdt_model` from a face model posed with AU weights.
- :func:`fdt_curves`: a table applied to a face model's curve points is a change
  of its curves' coefficients: a PDE descriptor, so one more linear shape key.
- :func:`classify`: the generic FDT nearest a face's own (the paper's recognition idea).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..au.descriptor import FDT_SOURCE, descriptor_from_points
from ..errors import MeshError, PdeFaceError
from ..facs import au_number, key_side, normalise_weights, parse_au_key
from ..mesh import vertex_normals
from ..posing import pose_curves
from ..presets import PRESETS
from ..surface.fit import skin_vertices
from ..surface.fourier import fit_fourier
from ..surface.grid import surface_grid
from ..surface.layout import ANCHOR_NAMES
from ..surface.model import model_landmarks
from ..surface.report import REPORT_RESOLUTION
from . import quadratic, regions
from .regions import N_REGIONS, REGIONS, PupilFrame, assign_regions, opening_sides, region_weights
from .table import FDT

#: Skin facing away from the front by more than this (normal's forward component below it) is left
#: out of a fit: inner lips, the mouth lining and lid margins, which a frontal view (the paper's
#: photographs) does not see and which fold over the skin in front of them in x, y.
FACING_MIN = 0.2
#: At most this many points per region go into a classification (every region weighs the same).
CLASSIFY_POINTS = 300
#: A parameter is inside a generic FDT's range when within this many σ of its mean (the paper: 1).
RANGE_SIGMAS = 1.0


def _facing(V, T, frame: PupilFrame) -> np.ndarray:

    return (vertex_normals(V, T) @ frame.rotation[2]) >= FACING_MIN


@dataclass
class FaceFit:
    """A face's own FDT and the points it was fitted on (normalised frame), for classification."""

    fdt: FDT
    neutral: np.ndarray
    posed: np.ndarray
    members: dict


class NeutralFace:
    """A neutral face ready to fit many expressions' FDTs: its pupil frame, points and regions.

    Parameters
    ----------
    vertices : (n, 3) array
        The neutral mesh (any unit and pose).
    triangles : (t, 3) int array
    landmarks : (68, 3) array
        Its landmarks (positions): they place the pupils and the regions.
    skin : (n,) bool array, optional
        The skin; default: the pieces under the landmarks. Skin not facing the front
        (:data:`FACING_MIN`) is left out either way, and so is skin beyond the regions'
        reach (:data:`~pdeface.fdt.regions.REACH`: ears, neck).
    blend : float, optional
        Blend width of the regions' borders (:data:`~pdeface.fdt.regions.BLEND`); 0 fits each
        region on its own points alone: the paper's 16 independent normal equations.
    """

    def __init__(self, vertices, triangles=None, landmarks=None, skin=None, keep=None, blend=None):

        V = np.asarray(vertices, np.float64)
        if V.ndim != 2 or V.shape[1] != 3 or not np.isfinite(V).all():
            raise MeshError("the neutral's vertices must be a finite (n, 3) array")
        self.frame = PupilFrame.from_landmarks(landmarks)
        if keep is None:
            T = np.asarray(triangles, np.int64)
            keep = skin_vertices(V, T, np.asarray(landmarks, np.float64)) if skin is None else np.asarray(skin, bool)
            keep = keep & _facing(V, T, self.frame)
        self.n_vertices = len(V)
        self.landmarks = self.frame.normalise(landmarks)
        region = np.full(len(V), -1)
        region[keep] = assign_regions(self.frame.normalise(V[keep]), self.landmarks)
        self.keep = np.nonzero(region >= 0)[0]
        self.neutral = self.frame.normalise(V[self.keep])
        region = region[self.keep]
        self.members = {r: np.nonzero(region == r)[0] for r in range(N_REGIONS)}
        # The regions are fitted together as they are applied: blended at their borders.
        self.blend = regions.BLEND if blend is None else float(blend)
        self.weights = region_weights(self.neutral, self.landmarks, self.blend)
        for r, idx in self.members.items():
            if len(idx) < 10:  # a full quadratic in x, y, z has 10 terms a coordinate
                raise PdeFaceError(f"region {REGIONS[r].number} ({REGIONS[r].name}) holds {len(idx)} of the face's "
                                   "points: too few to fit (is the face there, and the landmarks on it?)")
        self._equations = {}

    @classmethod
    def of_model(cls, face) -> "NeutralFace":
        """The neutral PDE surface of a face model (face frame, mm)."""
        X = _grid(face)
        return cls(X, landmarks=model_landmarks(face), keep=np.ones(len(X), bool))

    def fit(self, posed_vertices, model="3d", name="", posed_landmarks=None, source="", notice="") -> FaceFit:
        """The FDT taking this neutral to ``posed_vertices`` (the same vertices, showing an expression).

        ``posed_landmarks``: the posed mesh's own landmarks; it is then normalised by its own
        pupils, as the paper does for two photographs. Without them the posed mesh is taken in
        the neutral's pose (shape offsets, a rig's expressions).
        """
        Q = np.asarray(posed_vertices, np.float64)
        if Q.shape != (self.n_vertices, 3):
            raise MeshError(f"the posed mesh has {len(Q)} vertices, the neutral {self.n_vertices}: an FDT "
                            "needs the same vertices in both")
        if not np.isfinite(Q[self.keep]).all():
            raise MeshError("the posed mesh has NaN or inf vertices")
        frame = self.frame if posed_landmarks is None else PupilFrame.from_landmarks(posed_landmarks)
        P = frame.normalise(Q[self.keep])
        if model not in self._equations:  # the normal matrix depends on the neutral only
            self._equations[model] = quadratic.BlendedEquations(
                model, self.neutral, self.weights, [f"region {r.number} ({r.name})" for r in REGIONS])
        fdt = FDT(name, model, self._equations[model].solve(P), source=source, notice=notice, blend=self.blend)
        return FaceFit(fdt, self.neutral, P, self.members)


def fit_fdt(neutral_vertices, posed_vertices, triangles, landmarks, model="3d", name="", posed_landmarks=None,
            skin=None, source="", notice="", blend=None) -> FaceFit:
    """The FDT of one face's expression from its neutral and posed meshes (see :class:`NeutralFace`)."""
    return NeutralFace(neutral_vertices, triangles, landmarks, skin, blend=blend).fit(
        posed_vertices, model, name, posed_landmarks, source, notice)


def _grid(model, coefficients=None, residual=None):

    return surface_grid(model, *REPORT_RESOLUTION, coefficients=coefficients, residual=residual).reshape(-1, 3)


def fit_fdt_model(face, weights, model="3d", mixer="sum", name="", neutral=None) -> FaceFit:
    """The FDT of a face model posed with AU ``weights``: its PDE surface, neutral against posed."""

    neutral = NeutralFace.of_model(face) if neutral is None else neutral
    C, R = pose_curves(face, weights, mixer)
    return neutral.fit(_grid(face, C, R), model, name, source=f"{face.source} posed", notice=face.notice)


def fdt_displacement(fdt: FDT, points, landmarks, blend=None, sides=None) -> np.ndarray:
    """Displacement (n, 3) an FDT gives normalised ``points``, regions blended (:func:`region_weights`)
    as the table was fitted (its ``blend``) unless ``blend`` says otherwise."""
    P = np.asarray(points, np.float64)
    W = region_weights(P[:, :2], landmarks, fdt.blend if blend is None else blend, sides)
    D = np.zeros_like(P)
    for r in np.nonzero(W.max(axis=0) > 0)[0]:
        on = W[:, r] > 0
        D[on] += W[on, r, None] * (quadratic.transform(fdt.model, fdt.mean[r], P[on]) - P[on])
    return D


def curve_sides(layout, sides) -> np.ndarray:
    """Opening sides (n, 2) of a layout's curve points, read off the curves: the rim curves of a
    closed eye or mouth lie 0.1 mm apart, too close to tell by height. ``sides`` (from
    :func:`~pdeface.fdt.regions.opening_sides`) says which points lie within an opening's span."""

    K, J = layout.n_curves, layout.n_points
    out = np.asarray(sides).reshape(K, J, -1).copy()
    column = {ANCHOR_NAMES.index("lid_top"): 0, ANCHOR_NAMES.index("mouth_top"): 1}  # regions.OPENINGS' order
    for a, k in layout.opening_curves():
        c = column.get(a)
        if c is not None:
            side = np.where(np.arange(K) <= k, 1, -1)[:, None]
            out[:, :, c] = np.where(out[:, :, c] != 0, side, 0)
    return out.reshape(K * J, -1)


def fdt_curve_displacement(face, fdt: FDT, weight=1.0, blend=None) -> np.ndarray:
    """Displacement (K, J, 3) of ``face``'s curve points (face frame, mm) that an FDT causes.

    The curve points are pupil-normalised by the face's own landmarks, moved by
    the table (the rim curves' sides read off the layout), and brought back.
    Linear in ``weight``.
    """
    L = model_landmarks(face)
    frame = PupilFrame.from_landmarks(L)
    X = face.curve_points()
    N, Ln = frame.normalise(X.reshape(-1, 3)), frame.normalise(L)
    D = fdt_displacement(fdt, N, Ln, blend, curve_sides(face.layout, opening_sides(N, Ln)))
    return frame.vectors_to_source(D).reshape(X.shape) * float(weight)


def fdt_curves(face, fdt: FDT, weight=1.0, blend=None) -> tuple[np.ndarray, np.ndarray]:
    """Change of ``face``'s curve coefficients and residual (K, N+1, 3), (K, J, 3) an FDT causes:
    the Fourier fit of :func:`fdt_curve_displacement` (linear, so a shape key)."""

    return fit_fourier(fdt_curve_displacement(face, fdt, weight, blend), face.n_modes)


def fdt_descriptor(face, fdt: FDT):
    """An AU's FDT (named by its AU key, ``"12"``, ``"12L"``) on ``face`` as a descriptor (source ``fdt``)."""

    try:
        au, side = key_side(fdt.name)
    except PdeFaceError:
        raise PdeFaceError(f"FDT {fdt.name!r} is not named by an AU (12, 12L...): use it as an expression") from None
    X = face.curve_points()
    return descriptor_from_points(X, X + fdt_curve_displacement(face, fdt), au, side, face.n_modes,
                                  source=f"{FDT_SOURCE} {fdt.model} ({fdt.source or 'file'})", notice=fdt.notice)


def fdt_aus(name) -> list:
    """AU numbers an FDT's name stands for: its AU key's, or a basic expression's AUs."""

    if name in PRESETS:
        return [au_number(k) for k in normalise_weights(PRESETS[name].weights)]
    try:
        return [au_number(parse_au_key(name))]
    except PdeFaceError:
        return []


def _region_sample(members, r, rng):
    idx = members[r]
    return idx if len(idx) <= CLASSIFY_POINTS else rng.choice(idx, CLASSIFY_POINTS, replace=False)


def _spread(fdt, r, P):
    """σ of the displacement at points ``P`` (n, 3) implied by the parameters' σ (taken independent)."""
    Phi = quadratic.design(fdt.model, P)
    S = fdt.sigma[r].reshape(-1, Phi.shape[1])
    return np.sqrt((Phi ** 2) @ (S ** 2).T)[:, :P.shape[1]]


def classify(face_fit: FaceFit, generics, range_sigmas=RANGE_SIGMAS) -> list:
    """Rank generic FDTs by how well they explain a face's own expression.

    Each generic table's motion, scaled by the intensity s ∈ [0, 1.25] that fits
    best, is compared with the face's observed motion on the face's own points
    (up to :data:`CLASSIFY_POINTS` a region): ``distance`` is the RMS misfit
    over the RMS observed motion (0: identical), ``inside`` the share of points
    and coordinates whose misfit lies within ``range_sigmas`` σ of the generic
    table (the paper's mean ± σ range; needs generic tables with σ).

    Returns
    -------
    list of dict
        ``{"name", "distance", "intensity", "inside", "regions"}`` best first; ``regions`` is the
        per-region distance.
    """
    rng = np.random.default_rng(0)
    samples = {r: _region_sample(face_fit.members, r, rng) for r in range(N_REGIONS)}
    idx = np.concatenate(list(samples.values()))
    P = face_fit.neutral[idx]
    observed = face_fit.posed[idx] - P
    norm = np.sqrt((observed ** 2).sum(1).mean())
    if not norm > 0:
        raise PdeFaceError("the posed face does not move: nothing to classify")
    region_of = np.concatenate([np.full(len(s), r) for r, s in samples.items()])
    out = []
    for g in generics:
        pred = np.zeros_like(P)
        for r in range(N_REGIONS):
            on = region_of == r
            pred[on] = quadratic.transform(g.model, g.mean[r], P[on]) - P[on]
        dims = 2 if g.model == "2d" else 3
        o, p = observed[:, :dims], pred[:, :dims]
        s = float(np.clip((o * p).sum() / max((p * p).sum(), 1e-12), 0.0, 1.25))
        miss = o - s * p
        inside = None
        if g.sigma is not None:
            spread = np.zeros_like(p)
            for r in range(N_REGIONS):
                on = region_of == r
                spread[on] = _spread(g, r, P[on])[:, :dims]
            inside = float((np.abs(miss) <= range_sigmas * s * spread + 1e-9).mean())
        per_region = [float(np.sqrt((miss[region_of == r] ** 2).sum(1).mean()) / norm) if (region_of == r).any()
                      else None for r in range(N_REGIONS)]
        out.append({"name": g.name, "distance": float(np.sqrt((miss ** 2).sum(1).mean()) / norm),
                    "intensity": s, "inside": inside, "regions": per_region})
    return sorted(out, key=lambda c: c["distance"])
