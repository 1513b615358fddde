import json

import numpy as np
import pytest
from pdeface.au.expressions import ShapeBasis, mix
from pdeface.errors import ModelFormatError, PdeFaceError
from pdeface.facs import (
    action_unit,
    catalogue,
    letter_to_weight,
    normalise_weights,
    parse_au_key,
    parse_au_weights,
    weight_to_letter,
)
from pdeface.posing import pose_curves
from pdeface.presets import (
    BASIC_EXPRESSIONS,
    PRESETS,
    SUPPLEMENTARY_WEIGHT,
    Preset,
    load_presets,
    merged_presets,
    resolve_preset,
    save_presets,
)
from pdeface.surface.fit import face_mesh


@pytest.fixture(scope="module")
def face(default_face):
    return default_face


def test_catalogue():
    cat = catalogue()
    assert {1, 2, 4, 12, 25, 26, 27, 45, 61, 64} <= set(cat)
    assert action_unit(12).label == "AU12 Lip Corner Puller"
    assert cat[1].region == "upper" and cat[12].region == "lower" and cat[61].region == "eyes_head"
    assert "zygomaticus major" in cat[12].muscles
    with pytest.raises(PdeFaceError, match="not a FACS"):
        action_unit(3)


def test_intensity_letters():
    assert [letter_to_weight(c) for c in "ABCDE"] == [0.2, 0.4, 0.6, 0.8, 1.0]
    assert [weight_to_letter(w) for w in (0, 0.1, 0.2, 0.21, 0.6, 0.99, 1.0, 3.0)] == ["", "A", "A", "B", "C", "E", "E", "E"]
    for c in "ABCDE":
        assert weight_to_letter(letter_to_weight(c)) == c
    with pytest.raises(PdeFaceError, match="A-E"):
        letter_to_weight("F")
    assert normalise_weights({"AU12": 2.0, 6: "c", "4L": -1}) == {"12": 1.0, "6": 0.6, "4L": 0.0}
    assert parse_au_key("au30r") == "30R"


def test_presets_follow_the_method():
    assert set(BASIC_EXPRESSIONS) == {"happy", "sad", "disgust", "surprise", "anger", "fear"}
    assert PRESETS["happy"].weights["12"] == 1.0 and PRESETS["happy"].weights["6"] == SUPPLEMENTARY_WEIGHT
    assert PRESETS["fear"].weights == {"5": 0.3, "7": 0.3, "20": 0.3, "25": 0.3, "26": 0.3, "1": 1.0, "2": 1.0, "4": 1.0}
    assert PRESETS["happy_6_12"].weights == {"6": 1.0, "12": 1.0}
    assert PRESETS["sad_1_4_15"].weights == {"1": 1.0, "4": 1.0, "15": 1.0}


def test_mixers(face):
    ds = {d.key: d for d in face.descriptors}
    w = {"12": 1.0, "6": 1.0}
    s_C, s_R = mix(ds, w, "sum")
    a_C, a_R = mix(ds, w, "average")
    m_C, m_R = mix(ds, w, "max")
    C12, C6 = ds["12"].dense()[0], ds["6"].dense()[0]
    np.testing.assert_allclose(s_C, C12 + C6)
    both = np.intersect1d(ds["12"].curves, ds["6"].curves)
    only = np.setdiff1d(ds["12"].curves, ds["6"].curves)
    np.testing.assert_allclose(a_C[both], (C12 + C6)[both] / 2)
    np.testing.assert_allclose(a_C[only], C12[only])
    pick = np.where(np.abs(C12) >= np.abs(C6), C12, C6)
    np.testing.assert_allclose(m_C, pick)
    # weights are clamped
    np.testing.assert_allclose(mix(ds, {"12": 3.0}, "sum")[0], C12)
    with pytest.raises(PdeFaceError, match="no descriptor"):
        mix(ds, {"8": 1.0})  # no scan and no muscle AU8 on the bundled face
    with pytest.raises(PdeFaceError, match="unknown mixer"):
        mix(ds, w, "median")


def test_preset_resolution_reports_missing(face):
    weights, missing = resolve_preset(PRESETS["anger"], {d.key for d in face.descriptors})
    assert not missing and weights["23"] == 1.0 and weights["24"] == 1.0  # AU23 from the muscles
    weights, missing = resolve_preset(PRESETS["anger"], {d.key for d in face.descriptors if d.source != "muscle"})
    assert "23" in missing and "24" in weights


def test_shape_basis_matches_pose(face):
    basis = ShapeBasis(face, "2,2")
    w = {"12": 0.8, "6": 0.5, "30L": 0.3}
    C, R = pose_curves(face, w)
    expect = face_mesh(face, "2,2", coefficients=C, residual=R).vertices
    got = basis.vertices(basis.weights_matrix(w))[0]
    np.testing.assert_allclose(got, expect, atol=1e-5)
    np.testing.assert_allclose(basis.vertices(np.zeros(len(basis.keys)))[0], face_mesh(face, "2,2").vertices, atol=1e-5)


def test_preset_files(tmp_path):
    p = Preset("smirk", {"12L": 0.8, "6": "B"}, "max", "one-sided")
    save_presets(tmp_path / "one.json", [p])
    back = load_presets(tmp_path / "one.json")[0]
    assert back.name == "smirk" and back.weights == {"12L": 0.8, "6": 0.4} and back.mixer == "max"
    save_presets(tmp_path / "two.json", [p, PRESETS["happy"]])
    assert [q.name for q in load_presets(tmp_path / "two.json")] == ["smirk", "happy"]
    bad = [({"format": "pdeface.preset", "version": 1, "weights": {"12": 1}}, "'name'"),
           ({"format": "pdeface.preset", "version": 1, "name": "x", "weights": {"3": 1}}, "'weights'"),
           ({"format": "pdeface.preset", "version": 1, "name": "x", "weights": {"12": "Z"}}, "'weights'"),
           ({"format": "pdeface.preset", "version": 1, "name": "x", "weights": {"12": 1}, "mixer": "min"}, "'mixer'"),
           ({"format": "pdeface.presets", "version": 1, "presets": {}}, "'presets'"),
           ({"format": "other"}, "'format'")]
    for obj, message in bad:
        (tmp_path / "bad.json").write_text(json.dumps(obj))
        with pytest.raises(ModelFormatError, match=message):
            load_presets(tmp_path / "bad.json")
    (tmp_path / "broken.json").write_text("{")
    with pytest.raises(ModelFormatError, match="not valid JSON"):
        load_presets(tmp_path / "broken.json")


def test_au_weights_as_the_command_line_writes_them():
    assert parse_au_weights(["12=1", "6=0.5", "AU4=C", "12l=2"]) == {"12": 1.0, "6": 0.5, "4": 0.6, "12L": 1.0}
    assert parse_au_weights(None) == {} and parse_au_weights([]) == {}
    for items, message in ((["12"], "--au '12': use AU=WEIGHT"), (["3=1"], "not a FACS Action Unit"),
                           (["12=Z"], "not a FACS letter"), (["x=1"], "not an AU key")):
        with pytest.raises(PdeFaceError, match=message) as exc:
            parse_au_weights(items)
        assert "\n" not in str(exc.value)


def test_merged_presets_let_a_later_file_win(tmp_path):
    assert merged_presets() == PRESETS and merged_presets() is not PRESETS
    save_presets(tmp_path / "a.json", [Preset("smirk", {"12L": 0.8}), Preset("happy", {"12": 0.5})])
    save_presets(tmp_path / "b.json", [Preset("smirk", {"12R": 0.8})])
    presets = merged_presets([tmp_path / "a.json", tmp_path / "b.json"])
    assert list(presets)[:len(PRESETS)] == list(PRESETS) and set(presets) == set(PRESETS) | {"smirk"}
    assert presets["smirk"].weights == {"12R": 0.8} and presets["happy"].weights == {"12": 0.5}
    assert PRESETS["happy"].weights["12"] == 1.0  # the built-ins are left alone
    with pytest.raises(ModelFormatError, match="missing.json"):
        merged_presets([tmp_path / "missing.json"])
