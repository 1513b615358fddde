"""The 68-point Multi-PIE landmark scheme: named indices, the method's feature points, eye distance.

Indices are 0-based. "Right" and "left" are the subject's own (the right eye is on the
image's left). Every module names a landmark from here rather than by its number.
"""
from __future__ import annotations

import numpy as np

#: Number of landmarks in the scheme.
COUNT = 68

#: The jaw line, right ear to left ear (0–16), and its named points.
JAW = range(0, 17)
JAW_RIGHT_END = 0
JAW_RIGHT_ANGLE = 5
CHIN = 8
JAW_LEFT_ANGLE = 11
JAW_LEFT_END = 16

#: Brows (outer to inner on each side).
BROW_RIGHT = range(17, 22)
BROW_LEFT = range(22, 27)
BROW_OUTER_RIGHT, BROW_INNER_RIGHT, BROW_INNER_LEFT, BROW_OUTER_LEFT = 17, 21, 22, 26

#: Nose: bridge (27–30, top to tip) and base (31–35, right wing to left wing).
NOSE_BRIDGE = range(27, 31)
NOSE_BRIDGE_TOP = 27
NOSE_TIP = 30
NOSE_WING_RIGHT = 31
NOSE_BOTTOM = 33
NOSE_WING_LEFT = 35

#: Eyes, six points each: outer corner, two upper-lid points, inner corner, two lower-lid points.
EYE_RIGHT = range(36, 42)
EYE_LEFT = range(42, 48)
EYE_OUTER_RIGHT, EYE_INNER_RIGHT, EYE_INNER_LEFT, EYE_OUTER_LEFT = 36, 39, 42, 45
#: Each eye's corners (inner, outer): the right eye's, then the left's.
EYE_CORNERS = ((EYE_INNER_RIGHT, EYE_OUTER_RIGHT), (EYE_INNER_LEFT, EYE_OUTER_LEFT))
#: The right eye's lower-lid points (inner, outer); the left's mirror them (:data:`MIRROR`).
LID_LOWER_INNER_RIGHT, LID_LOWER_OUTER_RIGHT = 40, 41
#: The upper- and lower-lid points of both eyes, the right eye's first; each lower point lies under the upper point at
#: the same place in the list (37 over 41, 38 over 40, 43 over 47, 44 over 46).
UPPER_LIDS = [37, 38, 43, 44]
LOWER_LIDS = [41, 40, 47, 46]

#: Mouth: outer lip line (48–59) and inner lip line (60–67).
OUTER_LIPS = range(48, 60)
INNER_LIPS = range(60, 68)
MOUTH_CORNER_RIGHT = 48
LIP_UPPER_TOP = 51
MOUTH_CORNER_LEFT = 54
LIP_LOWER_BOTTOM = 57
LIP_UPPER_INNER = 62
LIP_LOWER_INNER = 66
MOUTH_CORNERS = [MOUTH_CORNER_RIGHT, MOUTH_CORNER_LEFT]
#: The lips' middle, outer and inner: where an open mouth's gap is measured.
LIP_MIDDLES = [LIP_UPPER_TOP, LIP_LOWER_BOTTOM, LIP_UPPER_INNER, LIP_LOWER_INNER]

#: Each landmark's mirror image across the face's midline (its own index on the midline): jaw, brows,
#: nose base, eyes and lips read right to left in the scheme, so the pairs are fixed by its numbering.
MIRROR = tuple(
    [16 - i for i in JAW] + [43 - i for i in range(17, 27)] + list(NOSE_BRIDGE) + [66 - i for i in range(31, 36)]
    + [81 - i for i in range(36, 40)] + [87 - i for i in range(40, 42)] + [81 - i for i in range(42, 46)]
    + [87 - i for i in range(46, 48)] + [102 - i for i in range(48, 55)] + [114 - i for i in range(55, 60)]
    + [124 - i for i in range(60, 65)] + [132 - i for i in range(65, 68)]
)

#: The 19 feature points of the method, each the mean of the listed landmarks.
FEATURE_POINTS = {
    "brow_outer_right": [BROW_OUTER_RIGHT], "brow_inner_right": [BROW_INNER_RIGHT],
    "brow_inner_left": [BROW_INNER_LEFT], "brow_outer_left": [BROW_OUTER_LEFT],
    "eye_outer_right": [EYE_OUTER_RIGHT], "eye_inner_right": [EYE_INNER_RIGHT],
    "eye_inner_left": [EYE_INNER_LEFT], "eye_outer_left": [EYE_OUTER_LEFT],
    "nose_bridge": [NOSE_BRIDGE_TOP], "nose_wing_right": [NOSE_WING_RIGHT], "nose_tip": [NOSE_TIP],
    "nose_wing_left": [NOSE_WING_LEFT], "nose_bottom": [NOSE_BOTTOM],
    "mouth_corner_right": [MOUTH_CORNER_RIGHT], "lip_upper": [LIP_UPPER_TOP], "mouth_corner_left": [MOUTH_CORNER_LEFT],
    "lip_center": [LIP_UPPER_INNER, LIP_LOWER_INNER], "lip_lower": [LIP_LOWER_BOTTOM], "chin": [CHIN],
}
FEATURE_NAMES = list(FEATURE_POINTS)


def eye_centres(landmarks) -> tuple[np.ndarray, np.ndarray]:
    """The right and left eye centres: the means of each eye's six landmarks."""
    L = np.asarray(landmarks, dtype=np.float64)
    return L[EYE_RIGHT].mean(0), L[EYE_LEFT].mean(0)


def eye_distance(landmarks) -> float:
    """Distance between the eye centres (:func:`eye_centres`), in the landmarks' unit.

    The face's size everywhere in pdeface: muscles' sizes, the head binding's reach and the
    units guess are all measured in it.
    """
    right, left = eye_centres(landmarks)
    return float(np.linalg.norm(left - right))
