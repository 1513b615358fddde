import json
from dataclasses import replace

import numpy as np
import pytest
from pdeface.assets import load_ict_shapes
from pdeface.au.descriptorfile import load_descriptor
from pdeface.au.ict import au_offsets
from pdeface.au.modelfile import load_face, save_model
from pdeface.cli import main
from pdeface.io.meshio import read_obj, write_obj
from pdeface.mesh import Mesh
from pdeface.presets import Preset, save_presets
from pdeface.surface.fit import face_mesh


def run(capsys, *args):
    code = main([str(a) for a in args])
    out = capsys.readouterr()
    return code, out.out, out.err


@pytest.fixture(scope="module")
def files(tmp_path_factory, scan):
    mesh, _, idx = scan
    d = tmp_path_factory.mktemp("aus")
    shapes = load_ict_shapes()
    write_obj(d / "neutral.obj", mesh)
    write_obj(d / "smile.obj", Mesh.from_faces(mesh.vertices + au_offsets("12", shapes), mesh.face_indices.reshape(-1, 4)))
    (d / "lm.json").write_text(json.dumps({"indices": idx.tolist()}))
    # a mini ICT-FaceKit folder: face region as the "head", a few shapes
    write_obj(d / "generic_neutral_mesh.obj", mesh)
    for name in ("browInnerUp_L", "browInnerUp_R", "mouthSmile_L", "mouthSmile_R"):
        write_obj(d / f"{name}.obj", Mesh.from_faces(mesh.vertices + shapes[name], mesh.face_indices.reshape(-1, 4)))
    (d / "vertex_indices.json").write_text(json.dumps({"idx_to_landmark_verts": idx.tolist()}))
    return d


def test_descriptor_command_same_and_other_topology(tmp_path, capsys, files, scan):
    code, out, err = run(capsys, "descriptor", files / "neutral.obj", files / "smile.obj", "--landmarks",
                         files / "lm.json", "--au", 12, "-o", tmp_path / "AU12.json")
    assert code == 0 and "same topology" in err
    d = load_descriptor(tmp_path / "AU12.json")
    assert d.key == "12" and json.loads(out)["curves"] == d.curves.tolist()
    # the same smile, re-triangulated, as a binary descriptor
    mesh, _, idx = scan
    F = mesh.face_indices.reshape(-1, 4)
    tris = np.concatenate([F[:, [0, 1, 3]], F[:, [1, 2, 3]]])
    smile = read_obj(files / "smile.obj").vertices
    write_obj(tmp_path / "smile_tri.obj", Mesh.from_faces(smile, tris))
    code, out, err = run(capsys, "descriptor", files / "neutral.obj", tmp_path / "smile_tri.obj", "--landmarks",
                         files / "lm.json", "--au-landmarks", files / "lm.json", "--au", 12, "-o", tmp_path / "AU12.pdd")
    assert code == 0 and "projected" in err and json.loads(out)["bytes"] <= 2560
    code, _, err = run(capsys, "descriptor", files / "neutral.obj", tmp_path / "smile_tri.obj", "--landmarks",
                       files / "lm.json", "--au", 12, "-o", tmp_path / "x.json")
    assert code == 2 and "--au-landmarks" in err


def test_pose_command(tmp_path, capsys, files):
    code, _, err = run(capsys, "pose", "default", "--preset", "happy", "-o", tmp_path / "happy.obj")
    assert code == 0 and "AU12=1" in err
    code, _, err = run(capsys, "pose", "default", "--preset", "anger", "-o", tmp_path / "anger.obj")
    assert code == 0 and "AU23=1" in err and "no descriptor" not in err  # AU23 from the muscles now
    no_muscles = load_face("default")
    no_muscles.descriptors = [d for d in no_muscles.descriptors if d.source != "muscle"]
    save_model(tmp_path / "scan_only.npz", no_muscles)
    code, _, err = run(capsys, "pose", tmp_path / "scan_only.npz", "--preset", "anger", "-o", tmp_path / "anger2.obj")
    assert code == 0 and "no descriptor for AU 23" in err
    code, _, _ = run(capsys, "pose", "default", "--au", "12=1", "--au", "6=C", "--mixer", "average",
                     "-o", tmp_path / "p.obj")
    assert code == 0
    posed, neutral = read_obj(tmp_path / "p.obj"), face_mesh(load_face("default"))
    assert posed.vertices.shape == neutral.vertices.shape  # same vertex order as `pdeface mesh`
    assert posed.face_indices.tolist() == neutral.face_indices.tolist()
    assert 0.3 < np.abs(posed.vertices - neutral.vertices).max() < 3.0  # cm: the lip corners moved
    save_presets(tmp_path / "mine.json", [Preset("wink", {"45L": 1.0})])
    code, _, err = run(capsys, "pose", "default", "--preset", "wink", "--presets", tmp_path / "mine.json",
                       "-o", tmp_path / "w.obj")
    assert code == 0 and "AU45L=1" in err
    code, _, _ = run(capsys, "pose", "default", "--au", "12=1", "--descriptor", "nope.json", "-o", tmp_path / "x.obj")
    assert code == 2
    for bad in (["--au", "12"], ["--au", "3=1"]):  # refused at parse time: argparse's usage error
        with pytest.raises(SystemExit) as exc:
            run(capsys, "pose", "default", *bad, "-o", tmp_path / "x.obj")
        assert exc.value.code == 2 and "pdeface pose: error: argument --au" in capsys.readouterr().err
    for bad in (["--au", "8=1"], ["--preset", "grumpy"], []):  # a FACS AU this face lacks, no such preset
        code, _, err = run(capsys, "pose", "default", *bad, "-o", tmp_path / "x.obj")
        assert code == 2 and "pdeface: error:" in err


def test_retarget_and_au_report(tmp_path, capsys, files, scan):
    mesh, T, idx = scan
    code, _, _ = run(capsys, "fit", files / "neutral.obj", "--landmarks", files / "lm.json", "-o", tmp_path / "f.npz")
    assert code == 0
    code, out, _ = run(capsys, "retarget", tmp_path / "f.npz", "-o", tmp_path / "rt.npz")
    assert code == 0 and json.loads(out)["descriptors"] == len(load_face("default").descriptors)
    code, _, _ = run(capsys, "pose", tmp_path / "rt.npz", "--preset", "sad", "-o", tmp_path / "sad.obj")
    assert code == 0
    # au-report against a real ICT-FaceKit folder (a small one) and the bundled shapes
    small = load_face("default")
    small = replace(small, descriptors=[d for d in small.descriptors if d.key in ("1", "12")])
    save_model(tmp_path / "small.npz", small)
    code, out, _ = run(capsys, "au-report", tmp_path / "small.npz", "--truth", files, "--json")
    r = json.loads(out)
    assert code == 0 and set(r) == {"1", "12"}
    assert r["12"]["captured"] >= 0.95 and r["1"]["captured"] >= 0.95 and r["12"]["bytes"] <= 2560
    code, out, _ = run(capsys, "au-report", tmp_path / "small.npz", "--truth", "default", "--json")
    assert json.loads(out)["12"]["captured"] == pytest.approx(r["12"]["captured"], abs=1e-3)
    code, _, err = run(capsys, "au-report", tmp_path / "small.npz", "--truth", tmp_path, "--json")
    assert code == 2 and "not an ICT-FaceKit folder" in err
