"""Find the head of a whole character first, then its landmarks on the head alone.

On a body the face is a small part of each search render, and the face detector may see none. The head is
an extremity: along one of the mesh's principal axes (any up axis), the top of the body, on its midline
(a hand is out to one side), wider than the neck below it and narrower than the shoulders, and about as
deep as it is wide (a hand is flat). Each candidate end is
cut out (the part above the neck, with a margin) and searched on its own, where the face fills the render.
"""
from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np

from ..errors import LandmarkError
from ..mesh import require_usable_triangles, seam_welds, triangle_arrays
from ..rigid import rotation_vector_matrix
from .pipeline import FoundLandmarks, detect
from .render import View

#: A mesh this much longer than it is wide along its principal axes is a body (a head is about 1.3).
BODY_ASPECT = 1.8
#: Candidate ends tried, best first.
MAX_CANDIDATES = 3


@dataclass
class HeadCandidate:
    """One end of a body that may be its head: the vertices kept, the up direction, and how head-like."""

    vertices: np.ndarray  # (k,) indices into the mesh's vertices
    up: np.ndarray
    score: float


def _widths(P, up, bins):
    """The widest extent across ``up`` of the points in each slice along it (slices from the top)."""
    h = P @ up
    top, low = h.max(), h.min()
    edges = np.linspace(top, low, bins + 1)
    out = []
    for a, b in itertools.pairwise(edges):
        m = (h <= a) & (h >= b)
        Q = P[m] - np.outer(P[m] @ up, up)
        out.append(float(np.ptp(Q, axis=0).max()) if m.sum() > 3 else 0.0)
    return np.array(out)


def head_candidates(V, T=None) -> list[HeadCandidate]:
    """The ends of a body that may be its head, best first; an empty list for a mesh that is no body (a head,
    a bust: searched as it is).

    Parameters
    ----------
    V : (n, 3) array
        The character's vertices, any unit, orientation and pose.
    T : (m, 3) int array, optional
        Its triangles (only the vertices they use count).
    """
    V = np.asarray(V, np.float64)
    used = np.unique(T) if T is not None else np.arange(len(V))
    P = V[used]
    centre = P.mean(0)
    _, _, axes = np.linalg.svd(P - centre, full_matrices=False)
    ext = np.ptp((P - centre) @ axes.T, axis=0)
    if ext[0] < BODY_ASPECT * ext[2] and ext[0] < BODY_ASPECT * ext[1]:
        return []
    out = []
    for k in range(3):
        if ext[k] < 0.5 * ext[0]:
            continue
        for sign in (1.0, -1.0):
            up = sign * axes[k]
            h = (P - centre) @ up
            top = h.max()
            # Slices 1 % of the length deep down to 25 %: the neck is the narrowest between 6 and 20 %, the
            # head what lies above it (a margin below: the jaw's underside), the shoulders what follows.
            w = _widths(P[h >= top - 0.25 * ext[k]], up, 25)
            neck_bin = 6 + int(np.argmin(w[6:20]))
            keep = h >= top - (neck_bin + 2) / 100 * ext[k]
            Q = P[keep]
            if len(Q) < 50:
                continue
            head, neck, shoulders = w[:neck_bin].max(), max(w[neck_bin], 1e-12), w[neck_bin:].max()
            sub = Q - np.outer(Q @ up, up)
            sv = np.linalg.svd(sub - sub.mean(0), compute_uv=False)
            # Deep as it is wide (a hand is flat), wider than the neck, the shoulders wider still.
            roundness = float(sv[1] / sv[0]) if sv[0] > 0 else 0.0
            narrowing = float(head / neck)
            shoulders = float(shoulders / head) if head > 0 else 1.0
            # On the body's midline (its symmetry plane and its axis): a hand is out to one side.
            off = Q.mean(0) - centre
            central = 1.0 / (1.0 + (np.linalg.norm(off - (off @ up) * up) / (0.1 * ext[0])) ** 2)
            score = roundness * min(narrowing, 2.0) * min(shoulders, 3.0) * central * (head < 0.45 * ext[0])
            out.append(HeadCandidate(used[keep], up, score))
    out.sort(key=lambda c: -c.score)
    return [c for c in out if c.score > 0][:MAX_CANDIDATES]


def crop(V, T, keep_vertices):
    """The triangles whose corners are all kept, on their own vertices: ``(Vc, Tc, vertices, triangles)``,
    the last two the kept vertices' and triangles' indices in the whole mesh."""
    T = np.asarray(T)
    inside = np.zeros(len(V), bool)
    inside[keep_vertices] = True
    tri = np.flatnonzero(inside[T].all(1))
    used = np.unique(T[tri])
    remap = np.full(len(V), -1)
    remap[used] = np.arange(len(used))
    return np.asarray(V)[used], remap[T[tri]], used, tri


def upright(up) -> np.ndarray:
    """The rotation taking ``up`` to +y (about their common perpendicular)."""
    up = np.asarray(up, np.float64) / np.linalg.norm(up)
    axis = np.cross(up, [0.0, 1.0, 0.0])
    s = np.linalg.norm(axis)
    angle = np.arctan2(s, up[1])
    if s < 1e-9:
        return np.eye(3) if up[1] > 0 else rotation_vector_matrix([np.pi, 0.0, 0.0])
    return rotation_vector_matrix(axis / s * angle)


def _turn_back(found: FoundLandmarks, R):
    """Landmarks found on the mesh turned by ``R`` (``V @ R.T``), taken back to the mesh's own space."""
    found.points = found.points @ R
    for name in ("mesh_points", "view_points"):
        if getattr(found, name) is not None:
            setattr(found, name, getattr(found, name) @ R)
    if "view" in found.images:
        v = found.images["view"]
        found.images["view"] = View(v.rotation @ R, v.centre @ R, v.half, v.size)


def detect_anywhere(V, T, unit=None, **kwargs) -> FoundLandmarks:
    """:func:`~pdeface.landmarks.pipeline.detect` on the head first: on a body (:func:`head_candidates`), the
    likeliest head cut out; then the whole mesh; then the other candidate ends. A head or bust is searched
    as it is. The landmarks, indices and skin come back in the whole mesh's terms.

    Raises
    ------
    LandmarkError
        No face anywhere tried (the message says what was tried), or the error of the whole mesh's search
        when it was not "no face found".
    MeshError
        A triangle soup or mixed normals (:func:`~pdeface.mesh.require_usable_triangles`).
    """
    V, T = triangle_arrays(V, T)
    require_usable_triangles(T)
    # Copies an exporter split along UV seams joined (a seam down the face's midline left the midline's points a
    # crack to fall through, and the steps that walk the skin a border there); none on ICT's or MakeHuman's heads.
    T = seam_welds(V, T)[T]
    cands = head_candidates(V, T)
    order = [cands[0], None, *cands[1:]] if cands else [None]
    tried, whole = [], None
    for cand in order:
        if cand is None:
            try:
                return detect(V, T, unit, **kwargs)
            except LandmarkError as exc:
                if "no face found" not in str(exc):
                    raise
                whole = exc
                continue
        Vc, Tc, used, tri = crop(V, T, cand.vertices)
        R = upright(cand.up)
        try:  # the head stood up (its up along +y): the search's first views are then from its sides
            found = detect(Vc @ R.T, Tc, unit, **kwargs)
        except LandmarkError as exc:
            tried.append(str(exc).split(":")[0])
            continue
        _turn_back(found, R)
        found.indices = used[found.indices]
        if found.skin is not None:
            skin = np.zeros(len(T), bool)
            skin[tri[found.skin]] = True
            found.skin = skin
        found.view = f"head cut out, {found.view}"
        return found
    if not cands:
        raise whole
    raise LandmarkError(f"{whole}; and the head searched alone: {len(cands)} end(s) of the body that may be "
                        "the head cut out, no face on any") from None
