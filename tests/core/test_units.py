"""Mesh units by name or by number (issue #39): one parsing rule, read by the commands, jobs, files and the fit."""
import argparse
import json

import numpy as np
import pytest
from pdeface.au.modelfile import load_model, save_model
from pdeface.cli import main
from pdeface.errors import LandmarkError
from pdeface.io.arguments import mesh_unit
from pdeface.io.meshio import write_obj
from pdeface.mesh import Mesh
from pdeface.surface.fit import fit_face
from pdeface.surface.frame import face_frame
from pdeface.units import UNITS_MM, parse_unit


@pytest.mark.parametrize("given, name, mm", [
    ("cm", "cm", 10.0), (" IN ", "in", 25.4), ("0.01", "0.01mm", 0.01), ("0.01mm", "0.01mm", 0.01),
    ("0.01 mm", "0.01mm", 0.01), (0.01, "0.01mm", 0.01), ("168", "168mm", 168.0), (10, "cm", 10.0),
    ("1000", "m", 1000.0), (1 / 3, f"{1 / 3!r}mm", 1 / 3),
])
def test_a_unit_is_a_name_or_millimetres_per_unit(given, name, mm):
    assert parse_unit(given) == (name, mm)
    assert parse_unit(name) == (name, mm)  # the name reads back as the same unit


@pytest.mark.parametrize("bad", ["furlong", "", "mmm", "0", "-1", "nan", "inf", "1e999", "9" * 60, None, True, [1]])
def test_anything_else_is_refused_naming_it(bad):
    with pytest.raises(LandmarkError, match="unit") as e:
        parse_unit(bad)
    assert str(bad)[:20] in str(e.value)
    with pytest.raises(argparse.ArgumentTypeError, match="unit"):
        mesh_unit(bad)


def test_the_frame_takes_a_number_as_the_unit(scan):
    mesh, _, idx = scan
    L_cm = mesh.vertices[idx]
    L = L_cm * 100  # a head modelled at 100 times its size: 0.1 mm per unit
    f = face_frame(L, "0.1mm")
    assert (f.unit, f.scale) == ("0.1mm", 0.1)
    np.testing.assert_allclose(f.to_face(L), face_frame(L_cm, "cm").to_face(L_cm), atol=1e-6)
    assert face_frame(L_cm, 10).unit == "cm"
    with pytest.raises(LandmarkError, match="eyes are .* mm apart in unit '0.01mm'"):
        face_frame(L, 0.01)  # the eyes 6 mm apart: a face ten times too small


def test_fit_takes_millimetres_per_unit_and_saves_them(tmp_path, capsys, scan):
    mesh, _, idx = scan
    scaled = Mesh(mesh.vertices * 100, mesh.face_counts, mesh.face_indices)
    write_obj(tmp_path / "big.obj", scaled)
    (tmp_path / "lm.json").write_text(json.dumps({"indices": idx.tolist()}))
    code = main(["fit", str(tmp_path / "big.obj"), "--landmarks", str(tmp_path / "lm.json"), "--unit", "0.1mm",
                 "--curves", "12", "--points", "17", "-o", str(tmp_path / "f.npz")])
    assert code == 0 and json.loads(capsys.readouterr().out)["unit"] == "0.1mm"
    model = load_model(tmp_path / "f.npz")
    assert model.frame.unit == "0.1mm" and model.frame.scale == pytest.approx(0.1)
    with pytest.raises(SystemExit) as e:
        main(["fit", str(tmp_path / "big.obj"), "--unit", "0.0x", "-o", str(tmp_path / "g.npz")])
    assert e.value.code == 2 and "argument --unit: unknown unit '0.0x'" in capsys.readouterr().err


def test_pdeface_rig_names_a_head_at_no_named_scale_by_its_millimetres_per_unit(tmp_path, capsys, scan):
    """The command's rig on the neutral scan scaled by 0.0137 (no unit named, none fits: about 730 mm per unit,
    estimated): keys.npz names the unit as the fit's millimetres per unit, which reads back as that number, and the
    stimuli read the head in the fit's millimetres (its frame, a smile's motion)."""
    from pdeface.batch.stimuli import load_identity
    from pdeface.rig import load_keys

    mesh, _, idx = scan
    write_obj(tmp_path / "small.obj", Mesh(mesh.vertices * 0.0137, mesh.face_counts, mesh.face_indices))
    (tmp_path / "lm.json").write_text(json.dumps({"indices": idx.tolist()}))
    assert main(["rig", str(tmp_path / "small.obj"), "--landmarks", str(tmp_path / "lm.json"), "--no-presets",
                 "-o", str(tmp_path / "rig")]) == 0
    capsys.readouterr()
    assert json.loads((tmp_path / "rig" / "report.json").read_text())["fit"]["unit"] == "estimated"
    scale = load_model(tmp_path / "rig" / "face.npz").frame.scale
    keys = load_keys(tmp_path / "rig" / "keys.npz")
    name, mm = parse_unit(keys["unit"])
    assert name == keys["unit"] and name.endswith("mm") and name not in UNITS_MM
    assert mm == scale and mm == pytest.approx(10 / 0.0137, rel=0.15)  # the estimate, near the truth
    identity = load_identity(str(tmp_path / "rig"), ("12",))
    frame = face_frame(keys["landmarks"], mm)
    np.testing.assert_allclose(identity.landmarks, frame.to_face(keys["landmarks"]), atol=1e-9)
    smile = keys["deltas"][keys["names"].index("AU12")]
    assert np.linalg.norm(identity.keys["12"], axis=1).max() == pytest.approx(
        np.linalg.norm(smile, axis=1).max() * mm, rel=1e-3)
    assert 3.0 < np.linalg.norm(identity.keys["12"], axis=1).max() < 30.0  # millimetres: a smile's corners


def test_a_model_file_with_a_unit_that_is_none_is_refused(tmp_path, scan):
    from pdeface.errors import ModelFormatError

    mesh, T, idx = scan
    model, _ = fit_face(mesh.vertices, T, mesh.vertices[idx], unit=UNITS_MM["cm"], n_curves=12, n_points=17)
    model.frame.unit = "furlong"
    save_model(tmp_path / "bad.npz", model)
    with pytest.raises(ModelFormatError, match="field 'unit'"):
        load_model(tmp_path / "bad.npz")


def test_a_batch_job_names_a_bad_unit(tmp_path):
    from pdeface.batch.job import JobError, plan_job

    (tmp_path / "a.obj").write_text("")
    job = {"kind": "rig", "out": "out", "meshes": ["a.obj"]}
    with pytest.raises(JobError, match="unknown unit 'furlong'"):
        plan_job({**job, "unit": "furlong"}, tmp_path)
    with pytest.raises(JobError, match="unit '0'"):
        plan_job({**job, "meshes": [{"mesh": "a.obj", "unit": 0}]}, tmp_path)
    with pytest.raises(JobError, match="unit: unknown unit 'furlong'"):  # the job's own, though each mesh sets one
        plan_job({**job, "unit": "furlong", "meshes": [{"mesh": "a.obj", "unit": "cm"}]}, tmp_path)
    assert plan_job({**job, "unit": 0.01}, tmp_path).tasks[0].params["unit"] == 0.01
