"""Apply AU descriptors made on one face to another.

Both faces are fitted with the same layout (curve count, points, modes); the
layout is placed from each face's own landmarks, so curve i lies on the same
anatomy on both. A descriptor is a change in the face frame (mm), so it keeps
its direction there; it is scaled per axis by the ratio of face sizes.

Curve i of one face is curve i of the other, but the gaps between neighbouring
curves differ: above the upper lip's rim some faces' curves converge to half
the default face's spacing. Moving them by the source's motion there squeezes
a curve past its neighbour and folds the surface (``pdeface.surface.folds``).
So where the target's gap is much narrower than the source's, the two curves'
motion relative to each other is shrunk in proportion to the gap, and the
motion is recovered from those differences by least squares, staying close to
the scaled source motion (:func:`narrowed`). Gaps across an opening keep their
motion: the lips and lids still part.

Curve i is not always the same anatomy, though: the curves are spread by density between the landmarks, so
a face with a longer brow-to-eye distance has one curve more above the lids (MakeHuman's base: the upper
lid's rim is curve 8, ICT-FaceKit's 9). The source's motion is first carried to the target's curves by
anatomy (:func:`realigned`: the openings' rims onto the rims, linear in between), else the upper lid's
closing lands on the lower lid.
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from ..errors import PdeFaceError
from ..geometry import smoothstep
from ..landmark_scheme import FEATURE_NAMES
from ..surface.fourier import fit_fourier
from ..surface.layout import ANCHOR_NAMES

SCALINGS = ("face", "none")

#: Gap ratio (target / scaled source) at and below which neighbouring curves'
#: relative motion is scaled by the ratio itself ...
NARROW_FULL = 0.6
#: ... and at and above which it is left as it is; smooth in between. Shrinking
#: every gap (no threshold) also shrinks the lids' closing where their curves
#: converge at the eye corners (AU45 capture 0.905 -> 0.892 on identity007).
NARROW_NONE = 0.9
#: The lids' relative motion across the eye opening scales with the target's opening against the source's
#: (a blink closes a wider eye as far), within these bounds (above 1.5 the low-poly face's AU45 folds its lid).
LID_GAP_RATIO = (0.5, 1.5)
#: Weight of staying at the scaled source motion against matching the shrunk
#: differences: small, so a shrunk gap's motion is taken up by the curves beside it.
SOURCE_WEIGHT = 0.05
#: Corrections below this (mm) leave a curve out of a descriptor's affected set.
NEGLIGIBLE_MM = 1e-3


def face_size(model) -> np.ndarray:
    """(width, height, depth) of a face in mm from its feature points.

    Width: eye outer corners; height: brows to chin; depth: their mean.
    """
    F = dict(zip(FEATURE_NAMES, model.features))
    width = np.linalg.norm(F["eye_outer_left"] - F["eye_outer_right"])
    brows = np.mean([F[n][1] for n in FEATURE_NAMES if n.startswith("brow")])
    height = brows - F["chin"][1]
    return np.array([width, height, 0.5 * (width + height)])


def gap_factors(source, target, scale=1.0) -> np.ndarray:
    """(K-1, J) factors on neighbouring curves' relative motion, in (0, 1] (the eyes' opening up to 2).

    The ratio ρ of the target's gap between curves k and k+1 at point j to the
    source's (its points scaled by ``scale``, a scalar or per axis), passed through a smooth step:
    ρ itself at and below :data:`NARROW_FULL`, 1 at and above
    :data:`NARROW_NONE`. Gaps across an opening (``layout.breaks()``) get 1, but the eyes': the ratio
    itself within :data:`LID_GAP_RATIO` (may exceed 1).
    """
    P = source.curve_points() * scale
    where = curve_map(source.layout, target.layout)
    if where is not None:  # the source's curves where the target's lie (see realigned)
        lo = np.minimum(np.floor(where).astype(int), len(P) - 2)
        w = (where - lo)[:, None, None]
        P = (1 - w) * P[lo] + w * P[lo + 1]
    gap_s = np.linalg.norm(np.diff(P, axis=0), axis=-1)
    gap_t = np.linalg.norm(np.diff(target.curve_points(), axis=0), axis=-1)
    rho = np.clip(gap_t / np.maximum(gap_s, 1e-9), 0.0, 1.0)
    factor = 1.0 - (1.0 - rho) * smoothstep((NARROW_NONE - rho) / (NARROW_NONE - NARROW_FULL))
    factor[list(target.layout.breaks())] = 1.0
    lids = ANCHOR_NAMES.index("lid_top")
    for a, k in target.layout.opening_curves():
        if a == lids:  # a blink closes the target's own opening: scaled by its height against the source's
            factor[k] = np.clip(gap_t[k] / np.maximum(gap_s[k], 1e-9), *LID_GAP_RATIO)
    return factor


def narrowed(descriptors, factors) -> list:
    """Descriptors whose neighbouring curves' relative motion is scaled by ``factors``.

    Per point column, the new motion ``D`` minimises
    ``SOURCE_WEIGHT·|D - D₀|² + |diff(D) - f·diff(D₀)|²`` over the curves, ``D₀``
    the descriptor's motion and ``f`` the (K-1, J) ``factors``. Where every
    factor is 1 a descriptor is returned unchanged.
    """
    descriptors = list(descriptors)
    if not descriptors or np.all(factors == 1.0):
        return descriptors
    K, J, N = descriptors[0].layout
    D0 = np.zeros((K, len(descriptors), J, 3))
    for i, d in enumerate(descriptors):
        D0[d.curves, i] = d.points()
    excess = np.diff(D0, axis=0) * (factors - 1.0)[:, None, :, None]
    # normal equations of the correction E = D - D0: (w I + ∇ᵀ∇) E = ∇ᵀ excess; K×K, solved densely
    # (a few dozen curves; numpy's solver spares the add-on importing scipy.linalg)
    rhs = np.zeros_like(D0)
    rhs[:-1] -= excess
    rhs[1:] += excess
    grad = np.diff(np.eye(K), axis=0)
    E = np.linalg.solve(SOURCE_WEIGHT * np.eye(K) + grad.T @ grad, rhs.reshape(K, -1)).reshape(D0.shape)
    moved = np.abs(E).max(axis=(2, 3)) > NEGLIGIBLE_MM  # (K, n)
    C, R = fit_fourier((D0 + E).reshape(K * len(descriptors), J, 3), N)  # one product for all
    C, R = C.reshape(K, len(descriptors), N + 1, 3), R.reshape(K, len(descriptors), J, 3)
    out = []
    for i, d in enumerate(descriptors):
        if not moved[:, i].any():
            out.append(d)
            continue
        curves = np.union1d(d.curves, np.nonzero(moved[:, i])[0])
        out.append(replace(d, curves=curves, coefficients=C[curves, i], residual=R[curves, i]))
    return out


def curve_map(source_layout, target_layout) -> np.ndarray | None:
    """Each target curve's (fractional) source curve: the first and last curves and the rims of the openings
    both layouts carry (:meth:`~pdeface.surface.layout.CurveLayout.opening_curves`) onto each other, linear
    in between; None where every curve is already its own."""
    K = target_layout.n_curves
    src, tgt = dict(source_layout.opening_curves()), dict(target_layout.opening_curves())
    ks, kt = [0.0], [0.0]
    for a in sorted(set(src) & set(tgt), key=tgt.get):
        ks += [src[a], src[a] + 1]
        kt += [tgt[a], tgt[a] + 1]
    ks.append(K - 1.0)
    kt.append(K - 1.0)
    if ks == kt or np.any(np.diff(ks) <= 0) or np.any(np.diff(kt) <= 0):
        return None
    return np.interp(np.arange(K), kt, ks)


def realigned(descriptors, source_layout, target_layout) -> list:
    """Descriptors carried from the source's curves to the target's by anatomy (:func:`curve_map`): each target
    curve takes the motion of its source position, linear between the two source curves around it."""
    descriptors = list(descriptors)
    where = curve_map(source_layout, target_layout)
    if where is None or not descriptors:
        return descriptors
    K, J, N = descriptors[0].layout
    D0 = np.zeros((K, len(descriptors), J, 3))
    for i, d in enumerate(descriptors):
        D0[d.curves, i] = d.points()
    lo = np.minimum(np.floor(where).astype(int), K - 2)
    w = (where - lo)[:, None, None, None]
    D = (1 - w) * D0[lo] + w * D0[lo + 1]
    moved = np.abs(D).max(axis=(2, 3)) > NEGLIGIBLE_MM  # (K, n)
    C, R = fit_fourier(D.reshape(K * len(descriptors), J, 3), N)
    C, R = C.reshape(K, len(descriptors), N + 1, 3), R.reshape(K, len(descriptors), J, 3)
    out = []
    for i, d in enumerate(descriptors):
        curves = np.nonzero(moved[:, i])[0]
        if not len(curves):
            curves = np.array([int(np.argmax(np.abs(D[:, i]).max(axis=(1, 2))))])
        out.append(replace(d, curves=curves, coefficients=C[curves, i], residual=R[curves, i]))
    return out


def retarget(source, target, descriptors=None, scaling="face", spacing=True):
    """A copy of ``target`` carrying ``source``'s descriptors, scaled to it.

    Parameters
    ----------
    source, target : FaceModel
    descriptors : list, optional
        Defaults to ``source.descriptors``.
    scaling : {'face', 'none'}
        ``face`` scales each axis by the ratio of :func:`face_size`.
    spacing : bool
        Shrink neighbouring curves' relative motion where the target's curves
        lie much closer together than the source's (:func:`gap_factors`,
        :func:`narrowed`), so no curve is moved past its neighbour.
    """
    if scaling not in SCALINGS:
        raise PdeFaceError(f"unknown scaling {scaling!r}; use one of {', '.join(SCALINGS)}")
    descriptors = source.descriptors if descriptors is None else descriptors
    if not descriptors:
        raise PdeFaceError("no descriptors to retarget")
    lay = (target.layout.n_curves, target.layout.n_points, target.n_modes)
    bad = [d.key for d in descriptors if d.layout != lay]
    if bad:
        raise PdeFaceError(f"descriptors {', '.join(bad[:5])} were made for layout {descriptors[0].layout}, "
                           f"the target face has {lay}: refit the target with that layout")
    s = face_size(target) / face_size(source) if scaling == "face" else np.ones(3)
    scaled = [d.scaled(s) for d in descriptors]
    if source.layout.n_curves == lay[0]:
        scaled = realigned(scaled, source.layout, target.layout)
    if spacing:
        if (source.layout.n_curves, source.layout.n_points) != lay[:2]:
            raise PdeFaceError(f"the source face's layout ({source.layout.n_curves} curves, "
                               f"{source.layout.n_points} points) differs from the target's {lay[:2]}")
        scaled = narrowed(scaled, gap_factors(source, target, s))
    return replace(target, descriptors=scaled)
