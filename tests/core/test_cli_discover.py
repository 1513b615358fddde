"""What a face has and how to pose it: ``pdeface aus``, the no-descriptors hint, ``pose --mesh``'s fold line."""
import json
import re

import pytest
from pdeface.au.descriptor import MUSCLE_SOURCE, SOURCE_KINDS, descriptor_rows, no_descriptors, source_kind
from pdeface.au.modelfile import load_face, save_model
from pdeface.cli import main
from pdeface.presets import PRESETS, Preset, preset_rows, save_presets


def run(capsys, *args):
    code = main([str(a) for a in args])
    out = capsys.readouterr()
    return code, out.out, out.err


@pytest.fixture(scope="module")
def bare(tmp_path_factory):
    """The bundled face without its descriptors: a face fitted but not retargeted."""
    model = load_face("default")
    model.descriptors = []
    path = tmp_path_factory.mktemp("bare") / "bare.npz"
    save_model(path, model)
    return path


def test_source_kinds():
    from pdeface.fdt.deform import fdt_descriptor
    from pdeface.fdt.table import load_fdt

    face = load_face("default")
    assert {d.kind for d in face.descriptors} == {"scan", "muscle"}
    assert fdt_descriptor(face, load_fdt("12L")).kind == "fdt"
    assert [source_kind(s) for s in ("ICT-FaceKit: 1 jawOpen", "smile.obj", MUSCLE_SOURCE, "fdt 2d (file)", "")] \
        == ["scan", "scan", "muscle", "fdt", "other"]
    assert set(SOURCE_KINDS) == {"scan", "muscle", "fdt", "other"}


def test_rows():
    rows = descriptor_rows(load_face("default").descriptors)
    assert [r["key"] for r in rows[:3]] == ["1", "1L", "1R"]  # by AU number, then both, left, right
    r12 = next(r for r in rows if r["key"] == "12L")
    assert r12["name"] == "Lip Corner Puller" and r12["side"] == "left" and r12["kind"] == "scan" and r12["curves"]
    presets = {r["name"]: r for r in preset_rows(PRESETS, {"12", "6"})}
    assert presets["happy"]["recipe"] == "12 + 6 (0.3) + 16 (0.3) + 25 (0.3) + 26 (0.3)"
    assert presets["happy"]["missing"] == ["16", "25", "26"] and presets["happy_6_12"]["missing"] == []


def test_aus_lists_the_face_and_its_presets(tmp_path, capsys):
    save_presets(tmp_path / "mine.json", [Preset("smirk", {"12L": 0.8, "6": "B", "28": 1}, "max")])
    code, out, _ = run(capsys, "aus", "default", "--presets", tmp_path / "mine.json")
    assert code == 0
    assert re.search(r"^12L +12 +Lip Corner Puller +left +scan ", out, re.MULTILINE)
    assert re.search(r"^23 +23 +Lip Tightener +both +muscle ", out, re.MULTILINE)
    happy = re.escape("12 + 6 (0.3) + 16 (0.3) + 25 (0.3) + 26 (0.3)")
    assert re.search(rf"^happy +sum +{happy} +-$", out, re.MULTILINE)  # it lacks none of them
    assert re.search(r"^smirk +max +28 \+ 12L \(0\.8\) \+ 6 \(0\.4\)", out, re.MULTILINE)
    code, out, _ = run(capsys, "aus", "default", "--json")
    inv = json.loads(out)
    assert code == 0 and "hint" not in inv and len(inv["aus"]) == len(load_face("default").descriptors)
    assert {"key": "12", "au": 12, "name": "Lip Corner Puller", "side": "both", "kind": "scan"}.items() \
        <= inv["aus"][[r["key"] for r in inv["aus"]].index("12")].items()
    assert [p["name"] for p in inv["presets"]] == list(PRESETS)


def test_a_face_without_descriptors_says_how_to_get_them(tmp_path, capsys, bare):
    hint = f"run `pdeface retarget {bare} -o RIG.npz` first"
    assert no_descriptors(bare).endswith(hint) and "\n" not in no_descriptors(bare)
    code, out, _ = run(capsys, "aus", bare)
    assert code == 0 and hint in out and re.search(r"^happy .* 6, 12, 16, 25, 26$", out, re.MULTILINE)
    code, out, _ = run(capsys, "aus", bare, "--json")
    inv = json.loads(out)
    assert inv["aus"] == [] and hint in inv["hint"]
    for how in (["--au", "12=1"], ["--preset", "happy"], ["--mesh", "head", "--au", "12=1"]):
        code, _, err = run(capsys, "pose", bare, *how, "-o", tmp_path / "x.obj")
        assert code == 2 and err.strip() == f"pdeface: error: {bare}: this face carries no AU descriptors: {hint}"
    code, _, err = run(capsys, "au-report", bare, "--truth", "default")
    assert code == 2 and hint in err
    assert not (tmp_path / "x.obj").exists()
    # the muscle mixers pose from the muscle table, without descriptors
    code, _, _ = run(capsys, "pose", bare, "--au", "12=1", "--mixer", "muscle-average", "-o", tmp_path / "m.obj")
    assert code == 0


def test_pose_mesh_prints_the_pde_faces_largest_turn(tmp_path, capsys):
    turn = re.compile(r"largest turn outside the eyes, mouth and nostrils \d+°, \d+ edges over 30°")
    code, _, err = run(capsys, "pose", "default", "--au", "27=1", "-o", tmp_path / "face.obj")
    assert code == 0
    on_face = turn.search(err).group()
    code, _, err = run(capsys, "pose", "default", "--mesh", "head", "--au", "27=1", "-o", tmp_path / "head.obj")
    assert code == 0 and f"the posed PDE face's {on_face}" in err  # the same figure, on the same PDE face
