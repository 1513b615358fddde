"""What each vertex of a user's head is: skin, an eyeball, the jaw, the skull, or attached.

A head mesh has several connected parts. The skin is the part (or parts) the
68 landmarks lie on. The others are told apart by where they sit in the face
frame, measured in eye distances (IOD) so any unit and any face size works:

========  ==============================================================
kind      rule (first that matches)
========  ==============================================================
skin      holds the vertex nearest a landmark (ties go to the largest part;
          copies split along seams join their part)
eye_L/R   the eyeball: the outermost round part of the right size behind
          each eye's landmarks (a sphere is fitted to it)
jaw       inside the mouth (behind the lips, between nose and chin, no
          wider than the jaw at landmarks 5-11, as a beard round it is), the
          middle of its height below the mouth line, in front of the jaw
          hinge: lower teeth, lower gums, tongue; turned whole. A part
          spanning the mouth's width and reaching the upper and lower gums'
          height (ICT's gums and tongue are one) is split per vertex.
skull     inside the mouth, above the line or behind the hinge: upper teeth
          and gums; they do not move
eye_L/R   lies within an eyeball's sphere: iris, cornea
follow    touches the skin (within ``TOUCH_IOD``): lashes, lacrimal and
          occlusion meshes, brows and beards glued to the skin
follow    within ``NEAR_IOD`` of the skin: hair cards, brows
rest      anything else (a body's other parts, props): never moves
mouth     never found: a mouth bag named so (:mod:`pdeface.head.mouth`)
          hangs from the lips, turning with the jaw below the mouth line
========  ==============================================================

Users override any of it by naming vertices per kind (a JSON file on the
command line, vertex groups ``pdeface_<kind>`` in Blender).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..errors import MeshError
from ..geometry import row_norms
from ..io.files import load_json
from ..landmark_scheme import (
    CHIN,
    JAW_LEFT_ANGLE,
    JAW_RIGHT_ANGLE,
    LIP_LOWER_INNER,
    LIP_MIDDLES,
    LIP_UPPER_INNER,
    MOUTH_CORNER_LEFT,
    MOUTH_CORNER_RIGHT,
    MOUTH_CORNERS,
    NOSE_BOTTOM,
    eye_distance,
)
from ..mesh import connected_components
from ..rigid import jaw_hinge
from ..surface.fit import skin_vertices
from ..surface.frame import face_frame

#: Part kinds, in the order of their integer codes (a new kind goes last: files and vertex groups keep theirs).
KINDS = ("skin", "follow", "eye_L", "eye_R", "jaw", "skull", "rest", "mouth")
CODE = {k: i for i, k in enumerate(KINDS)}

#: A part within this many eye distances of the skin is glued to it (lashes, lacrimal meshes).
TOUCH_IOD = 0.008
#: A part within this many eye distances of the skin follows it (brows, hair cards).
NEAR_IOD = 0.15
#: Eyeball diameter range, in eye distances (adults ~24 mm for ~63 mm IOD: 0.38; MakeHuman's adults 0.50-0.54, its
#: baby 0.64, a cartoon's larger; two eyeballs wider than the eye distance would overlap).
EYEBALL_IOD = (0.2, 0.9)
#: An attached part lying within this many radii of an eyeball's centre, every vertex of it, is a film on the eye
#: (ICT's occlusion and tear-line meshes: 0.96-1.16; its lashes reach 1.4-1.7).
FILM_RADII = 1.2


@dataclass
class Parts:
    """Per-vertex part kinds of a head mesh, and the eyeballs found.

    Attributes
    ----------
    kind : (n,) int8 array
        Code of :data:`KINDS` per vertex.
    eyes : dict
        ``"eye_L"``/``"eye_R"`` → (centre (3,), radius) in the face frame (mm), for eyes found.
    notes : list of str
        What was decided, for the user (how many vertices of each kind, overrides applied).
    pieces : (n,) int array or None
        The connected piece of every vertex (:func:`pdeface.mesh.connected_components` of the triangles classified).
    """

    kind: np.ndarray
    eyes: dict = field(default_factory=dict)
    notes: list = field(default_factory=list)
    pieces: np.ndarray | None = None

    def mask(self, *kinds) -> np.ndarray:
        return np.isin(self.kind, [CODE[k] for k in kinds])

    def counts(self) -> dict:
        return {k: int((self.kind == CODE[k]).sum()) for k in KINDS}


def mouth_line(Lf) -> float:
    """Height (face frame) of the line between the lips: mouth corners and inner lip centres."""
    return float(Lf[[*MOUTH_CORNERS, LIP_UPPER_INNER, LIP_LOWER_INNER], 1].mean())


def fit_sphere(P):
    """Least-squares sphere through points: (centre, radius)."""
    A = np.c_[2 * P, np.ones(len(P))]
    b = (P ** 2).sum(1)
    sol, *_ = np.linalg.lstsq(A, b, rcond=None)
    c = sol[:3]
    return c, float(np.sqrt(max(sol[3] + c @ c, 0.0)))


def classify_parts(Vf, T, Lf, hinge, overrides=None, welded=False, pieces=None) -> Parts:
    """Part kind of every vertex of a head mesh.

    Parameters
    ----------
    Vf : (n, 3) array
        Vertices in the face frame (mm).
    T : (t, 3) int array
        Triangles.
    Lf : (68, 3) array
        Landmarks in the face frame.
    hinge : (3,) array
        The jaw hinge (see :func:`pdeface.rigid.jaw_hinge`).
    overrides : dict, optional
        Kind → vertex indices, applied last (see :func:`apply_overrides`).
    welded : bool
        ``T``'s seam copies already joined (:func:`pdeface.mesh.seam_welds`, as the binding does): none welded again.
    pieces : (n,) int array, optional
        ``connected_components(len(Vf), T)`` where found already (the binding's, when it joined no seams).
    """
    from scipy.spatial import cKDTree


    n = len(Vf)
    lab = connected_components(n, T) if pieces is None else pieces
    s = eye_distance(Lf)
    kind = np.full(n, CODE["rest"], np.int8)

    # under the landmarks it has (a model file keeps some)
    skin = skin_vertices(Vf, T, Lf[np.isfinite(Lf).all(axis=1)], pieces=lab if welded else None)
    kind[skin] = CODE["skin"]

    # Each other part's vertices (ascending): one sort for them all.
    rest = np.nonzero(~skin)[0]
    rest = rest[np.argsort(lab[rest], kind="stable")]
    others, starts = np.unique(lab[rest], return_index=True)
    members = dict(zip(others.tolist(), np.split(rest, starts[1:])))
    # Each part's centre and box, once: the loops below read them (mean's own sums: reduceat's differ in rounding).
    centre, box_lo, box_hi = {c: Vf[m].mean(0) for c, m in members.items()}, {}, {}
    if len(rest):
        Vr = Vf[rest]
        box_lo = dict(zip(others.tolist(), np.minimum.reduceat(Vr, starts, axis=0)))
        box_hi = dict(zip(others.tolist(), np.maximum.reduceat(Vr, starts, axis=0)))

    # Eyeballs: the roundest part of the right size behind each eye, and what lies inside its sphere.
    eyes = {}
    for name, sl in (("eye_R", slice(36, 42)), ("eye_L", slice(42, 48))):
        E = Lf[sl].mean(0)
        best = None
        for c, m in members.items():
            ctr, ext = centre[c], box_hi[c] - box_lo[c]
            if np.hypot(*(ctr[:2] - E[:2])) > 0.3 * s or not (E[2] - 0.5 * s < ctr[2] < E[2] + 0.1 * s):
                continue
            if not (EYEBALL_IOD[0] * s < ext.max() < EYEBALL_IOD[1] * s) or ext.min() < 0.5 * ext.max():
                continue
            P = Vf[m]
            c0, r = fit_sphere(P)
            err = np.abs(row_norms(P - c0) - r).mean() / r
            if err < 0.1 and (best is None or r > best[0]):  # the outermost sphere: sclera, not iris
                best = (r, c0, r, c)
        if best is not None:
            eyes[name] = (best[1], best[2])
            kind[members[best[3]]] = CODE[name]
    balls = {best_c for best_c in (int(lab[np.nonzero(kind == CODE[e])[0][0]]) for e in eyes)}

    ymouth = mouth_line(Lf)
    lips_z = Lf[LIP_MIDDLES, 2].max()
    half_width = 0.75 * s
    zcut = hinge[2] + JAW_CUT_IOD * s
    # What is inside the mouth lies within the face's outline: a part wider than the jaw at the lower lip's height
    # lies over it (a beard shell round the mouth, 1.58 of that width; teeth, gums and tongues 0.81-0.88).
    # (The jaw's angles, 5 and 11; where they are NaN, no width is asked.)
    jaw_width = np.nan_to_num(abs(Lf[JAW_RIGHT_ANGLE, 0] - Lf[JAW_LEFT_ANGLE, 0]), nan=np.inf)
    attached = []
    for c, m in members.items():
        if c in balls:
            continue
        ctr = centre[c]
        in_mouth = (abs(ctr[0] - Lf[MOUTH_CORNERS, 0].mean()) < half_width and Lf[CHIN, 1] < ctr[1] < Lf[NOSE_BOTTOM, 1]
                    and lips_z - 2 * s < ctr[2] < lips_z and box_hi[c][0] - box_lo[c][0] < jaw_width)
        if in_mouth:
            P = Vf[m]
            reach = SPLIT_REACH_IOD * s
            spans = P[:, 1].min() < ymouth - reach and P[:, 1].max() > ymouth + reach
            if spans and np.ptp(P[:, 0]) > 0.5 * abs(Lf[MOUTH_CORNER_LEFT, 0] - Lf[MOUTH_CORNER_RIGHT, 0]):
                lower = (P[:, 1] < ymouth) & (P[:, 2] > zcut)  # both jaws' gums and the tongue: per vertex
            else:  # one rigid piece (a tooth, a row of teeth, a tongue): the middle of its height says which jaw
                lower = np.full(len(m), (P[:, 1].min() + P[:, 1].max()) / 2 < ymouth and ctr[2] > zcut)
            kind[m] = np.where(lower, CODE["jaw"], CODE["skull"])
            continue
        # (a part whose centre is outside the sphere reaches outside it: its points need no look)
        eye = next((e for e, (c0, r) in eyes.items() if np.linalg.norm(ctr - c0) < (r + 0.03 * s) * (1 + 1e-9)
                    and row_norms(Vf[m] - c0).max() < r + 0.03 * s), None)
        if eye:  # iris, cornea: inside the eyeball's sphere
            kind[m] = CODE[eye]
            continue
        attached.append(c)
    # The parts left follow the skin where they touch it (lashes, lacrimal meshes) or lie near it (brows, hair
    # cards): their gaps to the skin in one query, as far as NEAR_IOD (inf beyond: the bound prunes the search of the
    # far parts; the eyeballs and the mouth's parts, ICT's 10k vertices, need none).
    if attached:
        skin_tree = cKDTree(Vf[skin], balanced_tree=False, compact_nodes=False)  # built 2x faster, the same distances
        near = np.concatenate([members[c] for c in attached])
        firsts = np.cumsum([0] + [len(members[c]) for c in attached[:-1]])
        gaps = np.minimum.reduceat(skin_tree.query(Vf[near], distance_upper_bound=NEAR_IOD * s)[0], firsts)
        for c, gap in zip(attached, gaps):
            if gap < NEAR_IOD * s:  # touching (within TOUCH_IOD) or near: both follow
                kind[members[c]] = CODE["follow"]
    parts = Parts(kind, eyes, pieces=lab)
    if overrides:
        apply_overrides(parts, overrides)
    counts = parts.counts()
    parts.notes.append("parts: " + ", ".join(f"{k} {v}" for k, v in counts.items() if v))
    missing = [e for e in ("eye_L", "eye_R") if e not in eyes]
    if missing:
        parts.notes.append(f"no eyeball found for {', '.join(missing)}"
                           + (": no gaze keys (AU61-64) for this head" if len(missing) == 2 else
                              " (gaze AUs turn the other eyeball)"))
    return parts


#: How far in front of the jaw hinge (eye distances) the jaw's inner parts start moving with it
#: (ICT-FaceKit's jawOpen: gums and tongue further back stay put).
JAW_CUT_IOD = 0.15
#: A piece inside the mouth is split per vertex between the jaw and the skull only where it reaches this far (eye
#: distances) both above and below the mouth line: both jaws' gums in one piece (ICT's reach 0.33 below, 0.38 above,
#: as far as its teeth's roots). A tongue alone stays between the teeth (MakeHuman's reaches 0.07-0.16 above): split,
#: its back stayed with the skull while its tip turned with the jaw, stretched into spikes and folded 14-40 edges in
#: AU27 (issue #40); whole, it turns with the jaw and keeps its shape.
SPLIT_REACH_IOD = 0.25


def eye_films(parts: Parts, Vf) -> np.ndarray:
    """The attached parts that lie on an eyeball: films over the eye under the lids (ICT's occlusion and
    tear-line meshes), left out of the folds' relaxation and count.

    Parameters
    ----------
    parts : Parts
        The head's parts (its eyeballs' centres and radii, its attached pieces).
    Vf : (n, 3) array
        The vertices in the face frame.

    Returns
    -------
    (n,) bool array
        The vertices of attached pieces whose every vertex lies within :data:`FILM_RADII` eyeball radii of an
        eye's centre (ICT's films 0.96-1.16; its lashes reach 1.4-1.7).
    """
    films = np.zeros(len(Vf), bool)
    attached = np.nonzero(parts.mask("follow"))[0]
    if not parts.eyes or not len(attached) or parts.pieces is None:
        return films
    order = np.argsort(parts.pieces[attached], kind="stable")
    attached = attached[order]
    pieces, starts = np.unique(parts.pieces[attached], return_index=True)
    for centre, radius in parts.eyes.values():
        reach = np.maximum.reduceat(row_norms(Vf[attached] - centre), starts)
        films |= np.isin(parts.pieces, pieces[reach < FILM_RADII * radius])
    return films & parts.mask("follow")


def override_indices(kind, indices, n_vertices) -> np.ndarray:
    """An override's vertex indices as an array, each checked to be a vertex of a mesh of ``n_vertices``."""
    idx = np.asarray(indices, dtype=np.int64).ravel()
    if len(idx) and (idx.min() < 0 or idx.max() >= n_vertices):
        raise MeshError(f"part override {kind!r}: vertex index out of range 0..{n_vertices - 1}")
    return idx


def apply_overrides(parts: Parts, overrides: dict) -> None:
    """Set the kind of named vertices: ``{"skin": [...], "jaw": [...], ...}`` (indices, 0-based)."""
    n = len(parts.kind)
    for k, idx in overrides.items():
        if k not in CODE:
            raise MeshError(f"part override: unknown kind {k!r}; use {', '.join(KINDS)}")
        parts.kind[override_indices(k, idx, n)] = CODE[k]
        parts.notes.append(f"{len(idx)} vertices set to {k} by the user")


def classify_mesh(vertices, triangles, landmarks, unit=None, overrides=None) -> Parts:
    """:func:`classify_parts` of a mesh in the user's space, from its 68 landmarks (no fitted face needed)."""

    frame = face_frame(landmarks, unit)
    Lf = frame.to_face(landmarks)
    return classify_parts(frame.to_face(vertices), triangles, Lf, jaw_hinge(Lf, eye_distance(Lf)), overrides)


def overrides_of(parts: Parts) -> dict:
    """The parts as the override format: kind → vertex indices (kinds with none left out)."""
    return {k: idx.tolist() for i, k in enumerate(KINDS) if len(idx := np.nonzero(parts.kind == i)[0])}


def read_overrides(path) -> dict:
    """Part overrides from a JSON file (see :func:`parse_overrides`)."""

    return parse_overrides(load_json(path, MeshError), str(path))


def skin_mask(overrides: dict, n_vertices: int) -> np.ndarray | None:
    """The vertices the overrides' ``skin`` list names, as an (n_vertices,) mask; None where it names none."""
    listed = overrides.get("skin")
    if not listed:
        return None
    skin = np.zeros(n_vertices, bool)
    skin[override_indices("skin", listed, n_vertices)] = True
    return skin


def parse_overrides(data, name="parts") -> dict:
    """Validate part overrides read from JSON: an object of kind → list of vertex indices."""
    if not isinstance(data, dict):
        raise MeshError(f"{name}: expected an object of part kind → vertex indices")
    out = {}
    for k, v in data.items():
        if k not in CODE:
            raise MeshError(f"{name}: unknown part kind {k!r}; use {', '.join(KINDS)}")
        if not isinstance(v, list) or not all(isinstance(i, int) and not isinstance(i, bool) for i in v):
            raise MeshError(f"{name}: {k!r} must be a list of vertex indices")
        out[k] = v
    return out
