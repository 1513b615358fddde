"""The landmark gate refuses what is wrong, not what is a little off (issue #39: its false refusals)."""
import numpy as np
import pytest
from pdeface.assets import load_head
from pdeface.landmark_scheme import LOWER_LIDS, eye_distance
from pdeface.landmarks import available as mediapipe_available
from pdeface.landmarks.facemap import GROUPS
from pdeface.landmarks.gate import FACE_LENGTHS, JAW_ANGLES_BACK, check, face_size
from pdeface.surface.frame import face_frame

from scripts.devset import makehuman
from scripts.devset.characters import SPECS, build

needs_makehuman = pytest.mark.skipif(not makehuman.available(), reason="needs ../shared/data/makehuman")
needs_mediapipe = pytest.mark.skipif(not mediapipe_available(), reason='needs pip install "pdeface[landmarks]"')


@pytest.fixture(scope="module")
def ict():
    mesh, lm = load_head()
    V = mesh.vertices
    return V, mesh.triangles()[0], V[lm]


def moved(L, rows, d_eyes, unit="cm"):
    """``L`` with the landmarks ``rows`` moved by ``d_eyes`` (eye distances, in the face frame: x, y up, z forward)."""
    f = face_frame(L, unit)
    out = L.copy()
    out[rows] = f.to_user(f.to_face(L[rows]) + np.asarray(d_eyes) * eye_distance(L) * f.scale)
    return out


def checks(verdict, group):
    return [c for c, _ in verdict.failures.get(group, [])]


@pytest.mark.parametrize("row", [48, 54, 42, 45, 31, 35])
def test_a_corner_in_its_crease_may_lie_under_the_fold_a_lip_or_lid_may_not(ict, row):
    V, T, L = ict
    group = next(g for g, rows in GROUPS.items() if row in rows)
    # 0.08 eye distances back: where found corners lie under the lids' or lips' fold (african-male-old's 42: 0.06)
    assert "surface" not in checks(check(moved(L, [row], [0, 0, -0.08]), V, T, "cm"), group)
    # fallen into the socket or the mouth: refused
    deep = check(moved(L, [row], [0, 0, -0.2]), V, T, "cm")
    assert "surface" in checks(deep, group), deep.message()


@pytest.mark.parametrize("row", [57, 40, 33])
def test_the_middle_of_a_lip_a_lid_or_the_nose_bottom_under_the_surface_is_refused(ict, row):
    V, T, L = ict
    group = next(g for g, rows in GROUPS.items() if row in rows)
    v = check(moved(L, [row], [0, 0, -0.08]), V, T, "cm")  # the depth a corner may lie in its crease
    assert "surface" in checks(v, group), v.message()


@needs_makehuman
def test_lids_fallen_into_an_empty_socket_are_refused_by_their_depth():
    ch = build(SPECS["base-dm"])  # no eyeballs: the socket is seen through the eye's opening
    P = moved(ch.landmarks, LOWER_LIDS, [0, 0, -0.2], None)
    v = check(P, ch.vertices, ch.triangles)
    assert "surface" not in checks(v, "eyes")  # nothing of the mesh in front of them
    assert "depth" in checks(v, "eyes") and "eyes: depth (landmark" in v.message(), v.message()
    assert check(ch.landmarks, ch.vertices, ch.triangles).passed


@needs_makehuman
@pytest.mark.parametrize("name", ["eyes-teeth-merged-cm", "caucasian-female-young-cm"])
def test_a_shallow_true_jaw_under_a_pitched_frame_keeps_its_depth(name):
    # Shallow jaws (angles 0.14-0.16 behind the eyes); the chin found 0.1 back pitches the frame, which took the
    # angles to 0.05-0.07 behind the eyes; behind the mouth corners, at their height, they stay > 0.3.
    ch = build(SPECS[name])
    P = moved(ch.landmarks, [8], [0, 0, -0.1], None)
    F = face_frame(P).to_face(P) / (eye_distance(P) * face_frame(P).scale)
    assert F[36:48, 2].mean() - F[[5, 11], 2].mean() < 0.11  # the old measure would refuse it
    assert "depth" not in checks(check(P), "jaw")
    # the angles slid forward along the contour, level with the mouth: refused
    slid = moved(ch.landmarks, [5, 11], [0, 0, 0.25], None)
    v = check(slid)
    assert "depth" in checks(v, "jaw") and f"at least {JAW_ANGLES_BACK}" in v.message(), v.message()


def test_one_jaw_point_off_on_one_side_is_refused_a_frame_turned_by_an_eye_point_is_not(ict):
    L = ict[2]
    v = check(moved(L, [4], [0.15, 0, 0]), None, None, "cm")  # one point slid 0.15 inward: the median hides it
    assert "mirror" in checks(v, "jaw") and "landmarks 4 and 12" in v.message(), v.message()
    # an eye corner 0.06 back (under its fold) turns the frame: the wide jaw pairs move, the fitted midline takes it
    assert "mirror" not in checks(check(moved(L, [36], [0, 0, -0.06]), None, None, "cm"), "jaw")


@needs_makehuman
@needs_mediapipe
@pytest.mark.parametrize("name", ["african-male-old-m", "head-turn40-m", "parted-lips-teeth-separate-m",
                                  "eyes-teeth-merged-cm", "stylised-nose-mouth-cm", "asian-female-old-in",
                                  "asian-male-young-blender-m", "body-A-turn40-m", "stylised-chin-cheek-in"])
def test_found_landmarks_are_refused_when_a_group_is_off_and_pass_when_none_is(name):
    """The gate's contract on the development set: every group within 10 % of the eye distance passes (these were
    refused: a corner under its fold, a shallow jaw, narrow eyes' corners found under the epicanthic fold and the brows'
    span read against the eyes found too far apart), a group more than 10 % off is refused (stylised-chin-cheek's
    eyes)."""
    from pdeface.landmarks.headfind import detect_anywhere

    ch = build(SPECS[name])
    found = detect_anywhere(ch.vertices, ch.triangles)
    e = np.linalg.norm(found.points - ch.landmarks, axis=1) / ch.eye_distance
    worst = max(np.median(e[list(rows)]) for rows in GROUPS.values())
    v = check(found.points, ch.vertices, ch.triangles[found.skin])
    assert v.passed == (worst <= 0.10), (worst, v.message())


def test_one_eyes_lids_turned_over_are_refused_by_their_order(ict):
    # Each lower lid point is compared with the upper one over it in the same eye: compared across the eyes (as the
    # gate once did), one eye's lids swapped lie level with the other eye's and passed.
    V, T, L = ict
    assert "order" not in checks(check(L), "eyes")
    swapped = L.copy()
    swapped[[37, 38, 41, 40]] = L[[41, 40, 37, 38]]
    assert "order" in checks(check(swapped), "eyes"), check(swapped).message()


def test_the_face_size_is_one_on_icts_generic_head(ict):
    """:data:`FACE_LENGTHS` hold ICT's generic head's lengths: the spacing's limits are eye distances on its
    proportions."""
    L = ict[2]
    F = face_frame(L, "cm").to_face(L) / (eye_distance(L) * face_frame(L, "cm").scale)
    assert face_size(F) == pytest.approx(1.0, abs=1e-3)
    for a, b, length in FACE_LENGTHS.values():
        assert np.linalg.norm(F[list(a)].mean(0) - F[list(b)].mean(0)) == pytest.approx(length, abs=1e-3)


@pytest.mark.parametrize("apart", [1.0, 1.07])
def test_the_brows_span_passes_with_the_eyes_found_apart_and_squeezed_brows_are_refused(ict, apart):
    """Narrow eyes' corners found under the epicanthic fold put the eyes up to 7 % too far apart (asian-male-young,
    its turned body): the brows' span, over the eye distance alone, read 1.65 where true brows span 1.70 and more, and
    good brows were refused. Over the face's size (the eye distance, the eyes to the mouth and the nose's length) they
    pass; brows squeezed in from their ends by a fifth (their median point 12 % of the eye distance off) are refused
    whether the eyes are found apart or not."""
    V, T, L = ict
    f = face_frame(L, "cm")
    F = f.to_face(L)
    for eye in (range(36, 42), range(42, 48)):  # each eye slid outward, the eye distance 7 % larger
        F[list(eye), 0] += (apart - 1) * (F[list(eye), 0].mean() - F[27, 0])
    P = f.to_user(F)
    assert eye_distance(P) / eye_distance(L) == pytest.approx(apart, rel=1e-3)
    assert check(P, V, T, "cm").passed, check(P, V, T, "cm").message()
    squeezed = f.to_user(np.where(np.isin(np.arange(68), range(17, 27))[:, None],
                                  F * [0.8, 1, 1] + [0.2 * F[27, 0], 0, 0], F))
    assert np.median(np.linalg.norm(squeezed - P, axis=1)[17:27]) > 0.10 * eye_distance(L)
    v = check(squeezed, V, T, "cm")
    assert "spacing" in checks(v, "brows") and "17-26" in v.message(), v.message()
