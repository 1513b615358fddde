"""The FAS's 24 muscle values placed on any face from its landmarks (face frame, mm).

Eighteen linear muscles in nine pairs, three sphincters, two sheets and the jaw,
as the FAS records an AU (24 activation values). Waters' own nine pairs were
chosen for his face; these nine are the muscles FACS names for the AUs pdeface
animates (Ekman and Friesen's muscle list, thesis tables 2-1..2-3), so that the
AUs no scan covers (13, 23, 38, 39, 46) can be authored from their muscles.
Insertions lie on the skin at landmarks; heads lie on the skull, towards each
muscle's bone and :data:`HEAD_DEPTH` eye distances behind the skin. Sizes are in
eye distances (e = distance between the eye centres), so the set scales with the face.
"""
from __future__ import annotations

import numpy as np

from ..errors import LandmarkError
from ..landmark_scheme import (
    BROW_INNER_RIGHT,
    BROW_OUTER_RIGHT,
    CHIN,
    EYE_INNER_RIGHT,
    EYE_LEFT,
    EYE_OUTER_RIGHT,
    EYE_RIGHT,
    JAW_RIGHT_ANGLE,
    LID_LOWER_INNER_RIGHT,
    LID_LOWER_OUTER_RIGHT,
    LIP_LOWER_BOTTOM,
    LIP_LOWER_INNER,
    LIP_UPPER_INNER,
    LIP_UPPER_TOP,
    MIRROR,
    MOUTH_CORNER_LEFT,
    MOUTH_CORNER_RIGHT,
    NOSE_TIP,
    NOSE_WING_LEFT,
    NOSE_WING_RIGHT,
    eye_distance,
)
from ..rigid import JAW_BONE_GAIN, jaw_hinge
from .model import Jaw, LinearMuscle, Sheet, Sphincter

#: How far behind the skin (eye distances) a linear muscle's bony head lies.
HEAD_DEPTH = 0.12
#: The jawOpen turn of the bone (degrees) measured on ICT (pdeface.rigid), for the skin.
JAW_DEGREES = 25.3

#: (name, FACS muscle, AUs it serves), in the table's order; "_R"/"_L" are the subject's sides.
_PAIRS = (
    ("frontalis_inner", "frontalis, pars medialis", "1"),
    ("frontalis_outer", "frontalis, pars lateralis", "2"),
    ("corrugator", "corrugator supercilii, depressor supercilii", "4"),
    ("levator_labii_alaeque", "levator labii superioris alaeque nasi", "9, 38"),
    ("levator_labii", "levator labii superioris", "10, 11"),
    ("zygomatic_major", "zygomaticus major", "12, 6"),
    ("levator_anguli_oris", "levator anguli oris (caninus)", "13"),
    ("depressor_anguli_oris", "depressor anguli oris (triangularis)", "15, 20"),
    ("depressor_labii", "depressor labii inferioris", "16"),
)
_OTHERS = (
    ("orbicularis_oris", "orbicularis oris (sphincter)", "23, 24, 18, 22, 28"),
    ("orbicularis_oculi_R", "orbicularis oculi (sphincter), subject's right", "6, 7, 45, 46"),
    ("orbicularis_oculi_L", "orbicularis oculi (sphincter), subject's left", "6, 7, 45, 46"),
    ("mentalis", "mentalis (sheet)", "17"),
    ("nasalis", "nasalis (sheet: contracted, pars transversa compresses; relaxed below 0, pars alaris dilates)",
     "39, 38"),
    ("jaw", "masseter, temporalis, pterygoids: the jaw's turn", "26, 27"),
)
MUSCLES = tuple((f"{n}_{s}", m, a) for n, m, a in _PAIRS for s in "RL") + _OTHERS
#: The 24 muscle names, in the order of an activation vector.
MUSCLE_NAMES = tuple(n for n, _, _ in MUSCLES)
#: The nasalis' pull fades over this share of its length beyond the nose wing: AU38 pushes the wing 3 mm
#: outwards, and over the sheets' usual 0.3 (4 mm) that squeezed the cheek beside it into a fold (20 edges
#: over 30° off the scan's creases); over a whole length, none.
NASALIS_FADE = 1.0
#: Activation bounds: muscles pull (≥ 0); sphincters and the nasalis also relax below 0 (the lids
#: open wider, AU5; the nostrils flare, AU38).
BOUNDS = {n: ((-1.0, 2.0) if n.startswith(("orbicularis", "nasalis")) else (0.0, 2.0)) for n in MUSCLE_NAMES}


def _side(L, side):
    """The landmarks of one side, named by the subject's right: as given, or mirrored for the left."""
    if side == "R":
        return lambda i: L[i]
    return lambda i: L[MIRROR[i]]


#: Shape of each muscle pair beyond what the landmarks give, in eye distances e and degrees; the
#: bundled table's own (``geometry``, fitted to ICT-FaceKit by ``scripts/build/build_muscles.py``)
#: replaces these defaults. Linear: head moved (lateral, up, back), zone, Rs and Rf as fractions
#: of the head-insertion length, bulge (mm). Sphincters: semi-axes' scale, pull, push (mm).
#: Sheets: length and width scale, pull (mm).
DEFAULT_GEOMETRY = {
    **{n: {"lateral": 0.0, "up": 0.0, "back": 0.0, "zone": z, "rs": 0.9, "rf": 1.5, "bulge": 0.0}
       for n, z in (("frontalis_inner", 25), ("frontalis_outer", 25), ("corrugator", 35),
                    ("levator_labii_alaeque", 22), ("levator_labii", 22), ("zygomatic_major", 20),
                    ("levator_anguli_oris", 20), ("depressor_anguli_oris", 25), ("depressor_labii", 25))},
    "orbicularis_oris": {"scale_x": 1.0, "scale_y": 1.0, "pull": 0.35, "push": 0.0},
    "orbicularis_oculi": {"scale_x": 1.0, "scale_y": 1.0, "pull": 0.6, "push": 0.0},
    "mentalis": {"length": 1.0, "width": 1.0, "pull": 5.0},
    "nasalis": {"length": 1.0, "width": 1.0, "pull": 3.0},
}


def _linear(name, side, L, e, g):
    p = _side(L, side)
    out = -1.0 if side == "R" else 1.0  # +x is the subject's left
    up, back = np.array([0, 1.0, 0]), np.array([0, 0, -1.0])
    lateral = np.array([out, 0, 0])
    mid = lambda a, b, t=0.5: p(a) + t * (p(b) - p(a))  # noqa: E731
    if name == "frontalis_inner":
        i, h, pull = p(BROW_INNER_RIGHT) + 0.05 * e * up, p(BROW_INNER_RIGHT) + 0.8 * e * up, 7.0
    elif name == "frontalis_outer":
        i, h, pull = p(BROW_OUTER_RIGHT) + 0.05 * e * up, p(BROW_OUTER_RIGHT) + 0.8 * e * up - 0.1 * e * lateral, 7.0
    elif name == "corrugator":
        i = mid(BROW_INNER_RIGHT, BROW_OUTER_RIGHT, 0.45)
        h, pull = p(BROW_INNER_RIGHT) - 0.1 * e * lateral - 0.08 * e * up, 6.0
    elif name == "levator_labii_alaeque":
        i, h, pull = p(NOSE_WING_RIGHT) - 0.04 * e * up, p(EYE_INNER_RIGHT) - 0.05 * e * lateral - 0.05 * e * up, 6.0
    elif name == "levator_labii":
        i = mid(LIP_UPPER_TOP, MOUTH_CORNER_RIGHT, 0.55) + 0.03 * e * up
        h, pull = mid(LID_LOWER_INNER_RIGHT, LID_LOWER_OUTER_RIGHT) - 0.22 * e * up, 6.0
    elif name == "zygomatic_major":
        i, h, pull = p(MOUTH_CORNER_RIGHT), p(EYE_OUTER_RIGHT) + 0.12 * e * lateral - 0.42 * e * up, 10.0
    elif name == "levator_anguli_oris":
        i = p(MOUTH_CORNER_RIGHT) + 0.04 * e * up
        lower_lid = mid(LID_LOWER_INNER_RIGHT, LID_LOWER_OUTER_RIGHT)
        h = np.array([p(MOUTH_CORNER_RIGHT)[0] - 0.02 * e * out, 0.5 * (p(NOSE_WING_RIGHT)[1] + lower_lid[1]),
                      lower_lid[2]])
        pull = 7.0
    elif name == "depressor_anguli_oris":
        i, h, pull = p(MOUTH_CORNER_RIGHT), mid(MOUTH_CORNER_RIGHT, JAW_RIGHT_ANGLE, 0.6) - 0.1 * e * up, 8.0
    elif name == "depressor_labii":
        i = mid(LIP_LOWER_BOTTOM, MOUTH_CORNER_RIGHT, 0.4)
        h, pull = p(LIP_LOWER_BOTTOM) + 0.7 * (L[CHIN] - p(LIP_LOWER_BOTTOM)) + 0.15 * e * lateral, 7.0
    else:
        raise KeyError(name)
    h = h + e * (g["lateral"] * lateral + g["up"] * up + (HEAD_DEPTH + g["back"]) * back)
    length = np.linalg.norm(i - h)
    return LinearMuscle(f"{name}_{side}", h, i, float(np.clip(g["zone"], 5, 85)), g["rs"] * length,
                        max(g["rf"], g["rs"] + 0.05) * length, pull, g["bulge"])


def place_muscles(landmarks_face, geometry=None) -> list:
    """The 24 muscles (:data:`MUSCLE_NAMES` order) of a face from its landmarks in the face frame (mm).

    Reads landmarks 0/5/8/11/16, 17/21/22/26, 27/30/31/35, 36-47, 48/51/54/57/62/66: those
    a saved face model keeps (:func:`pdeface.surface.model.model_landmarks`). ``geometry``
    overrides :data:`DEFAULT_GEOMETRY` (per pair or muscle, the keys given).
    """
    g = {k: dict(v) for k, v in DEFAULT_GEOMETRY.items()}
    for k, v in (geometry or {}).items():
        g[k].update(v)
    L = np.asarray(landmarks_face, np.float64)
    need = [0, 5, 8, 11, 16, 17, 21, 22, 26, 27, 30, 31, 35, *range(36, 48), 48, 51, 54, 57, 62, 66]
    if L.shape != (68, 3) or not np.isfinite(L[need]).all():
        raise LandmarkError(f"placing the muscles needs landmarks {', '.join(map(str, need))}")
    e = eye_distance(L)
    out = [_linear(n, s, L, e, g[n]) for n, _, _ in _PAIRS for s in "RL"]
    mouth = 0.5 * (L[LIP_UPPER_INNER] + L[LIP_LOWER_INNER])
    m = g["orbicularis_oris"]
    mouth_width = L[MOUTH_CORNER_LEFT, 0] - L[MOUTH_CORNER_RIGHT, 0]
    lips_height = L[LIP_UPPER_TOP, 1] - L[LIP_LOWER_BOTTOM, 1]
    out.append(Sphincter("orbicularis_oris", mouth, (0.75 * m["scale_x"] * mouth_width, 1.2 * m["scale_y"] * lips_height),
                         m["pull"], push_mm=m["push"]))
    o = g["orbicularis_oculi"]
    for side, eye in (("R", EYE_RIGHT), ("L", EYE_LEFT)):
        c = L[list(eye)].mean(0)
        half = 0.5 * abs(L[eye[3], 0] - L[eye[0], 0])
        out.append(Sphincter(f"orbicularis_oculi_{side}", c, (1.5 * o["scale_x"] * half, 0.9 * o["scale_y"] * half),
                             o["pull"], to_axis=True, push_mm=o["push"]))
    below_lip = L[LIP_LOWER_BOTTOM] + 0.25 * (L[CHIN] - L[LIP_LOWER_BOTTOM])
    s = g["mentalis"]
    out.append(Sheet("mentalis", below_lip, np.array([0, -1.0, 0]), 0.8 * s["length"] * np.linalg.norm(L[CHIN] - L[LIP_LOWER_BOTTOM]),
                     0.3 * s["width"] * e, s["pull"]))
    s = g["nasalis"]
    nose = np.array([0.0, L[NOSE_WING_RIGHT, 1] + 0.05 * e, L[NOSE_TIP, 2]])
    out.append(Sheet("nasalis", nose, np.array([1.0, 0, 0]), 1.1 * s["length"] * 0.5 * (L[NOSE_WING_LEFT, 0] - L[NOSE_WING_RIGHT, 0]),
                     0.2 * s["width"] * e, s["pull"], mirrored=True, fade=NASALIS_FADE))
    out.append(Jaw("jaw", jaw_hinge(L, e), JAW_DEGREES / JAW_BONE_GAIN, L[LIP_LOWER_BOTTOM, 1], mouth[1]))
    return out
