import json

import numpy as np
import pytest
from pdeface.errors import LandmarkError
from pdeface.landmark_scheme import FEATURE_NAMES
from pdeface.surface.frame import estimate_unit, face_frame, feature_points, landmark_points, read_landmarks
from pdeface.units import UNITS_MM


def test_frame_puts_nose_at_origin_eyes_on_x_face_forward(scan):
    mesh, _, idx = scan
    L = mesh.vertices[idx]
    f = face_frame(L, "cm")
    Lf = f.to_face(L)
    np.testing.assert_allclose(Lf[30], 0, atol=1e-9)
    eyes = Lf[42:48].mean(0) - Lf[36:42].mean(0)
    assert eyes[0] > 55 and abs(eyes[1]) < 1e-9 and abs(eyes[2]) < 1e-9  # mm, along +x
    assert Lf[27, 1] > 0 > Lf[8, 1]  # nose bridge up, chin down
    assert (Lf[36:48, 2] < 0).all()  # eyes behind the nose tip: the face looks +z


@pytest.mark.parametrize("unit", ["mm", "cm", "m", "in"])
def test_unit_guess_and_invariance_to_pose_and_scale(scan, rng, rotation, unit):
    mesh, _, idx = scan
    L_cm = mesh.vertices[idx]
    R, t = rotation, rng.normal(size=3) * 5
    L_user = (L_cm * 10 / UNITS_MM[unit]) @ R.T + t
    assert estimate_unit(L_user)[0] == unit
    f = face_frame(L_user)
    assert f.unit == unit
    # the face frame does not depend on how the user posed or scaled the head
    np.testing.assert_allclose(f.to_face(L_user), face_frame(L_cm, "cm").to_face(L_cm), atol=1e-6)
    np.testing.assert_allclose(f.to_user(f.to_face(L_user)), L_user, atol=1e-9)


def test_feature_points(scan):
    mesh, _, idx = scan
    F = feature_points(mesh.vertices[idx])
    assert F.shape == (19, 3) and len(FEATURE_NAMES) == 19
    np.testing.assert_allclose(F[FEATURE_NAMES.index("nose_tip")], mesh.vertices[idx[30]])


def test_read_landmarks_indices_and_points(tmp_path, scan):
    mesh, _, idx = scan
    p = tmp_path / "l.json"
    p.write_text(json.dumps({"indices": idx.tolist()}))
    i, pts = read_landmarks(p)
    assert pts is None and i.tolist() == idx.tolist()
    p.write_text(json.dumps({"points": mesh.vertices[idx].tolist()}))
    i, pts = read_landmarks(p)
    np.testing.assert_allclose(landmark_points(mesh.vertices, i, pts), mesh.vertices[idx])


@pytest.mark.parametrize("content, message", [
    ("{", "not valid JSON"),
    ("[1, 2]", "expected an object"),
    ('{"indices": [1, 2, 3]}', "needs 68"),
    ('{"indices": ["a"]}', "list of integers"),
    ('{"points": [[0, 0]]}', "68"),
    ('{"points": ' + json.dumps([[0, 0, 0]] * 67 + [[0, "nan", 0]]) + "}", "must be a list|NaN"),
])
def test_bad_landmark_files(tmp_path, content, message):
    p = tmp_path / "l.json"
    p.write_text(content)
    with pytest.raises(LandmarkError, match=message):
        read_landmarks(p)


def test_bad_landmark_geometry(scan):
    mesh, _, idx = scan
    L = mesh.vertices[idx]
    with pytest.raises(LandmarkError, match="out of range"):
        landmark_points(mesh.vertices, np.full(68, len(mesh.vertices)))
    with pytest.raises(LandmarkError, match="eyes are 0 mm apart"):
        face_frame(np.zeros((68, 3)), "cm")
    flat = L.copy()
    flat[27] = flat[8]  # the nose bridge on the chin
    with pytest.raises(LandmarkError, match="degenerate"):
        face_frame(flat, "cm")
    with pytest.raises(LandmarkError, match=r"eyes are 6\.\d+e\+03 mm apart in unit 'm'"):
        face_frame(L, "m")  # a scan in cm said to be in metres: a face over a metre wide
    with pytest.raises(LandmarkError, match="unknown unit"):
        face_frame(L, "furlong")
    mirrored = L * np.array([1, 1, -1])  # the face now looks -z, but the order says +z
    with pytest.raises(LandmarkError, match="mirrored"):
        face_frame(mirrored, "cm")
