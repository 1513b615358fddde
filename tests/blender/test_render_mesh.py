"""``pdeface render --mesh``: a head of the user's own, read from OBJ or glTF, landmarked, fitted, rigged and
rendered in one command."""
import importlib.util
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from pdeface.assets import load_head
from pdeface.io.meshio import write_obj
from test_render import pixels, run_script

TINY = ["--sequence", "happy", "--fps", "4", "--hold", "0.5", "--blend-time", "0.5", "--size", "48x48",
        "--samples", "1", "--frame-start", "1", "--frame-end", "4", "--quiet"]


@pytest.fixture(scope="module")
def head_files(tmp_path_factory):
    """The bundled ICT head as an OBJ (cm) and as a GLB in metres, as glTF has it, with its landmarks."""
    trimesh = pytest.importorskip("trimesh")
    d = tmp_path_factory.mktemp("head")
    mesh, idx = load_head()
    write_obj(d / "head.obj", mesh)
    trimesh.Trimesh(mesh.vertices * 0.01, mesh.triangles()[0], process=False).export(d / "head.glb")
    (d / "landmarks.json").write_text(json.dumps({"indices": idx.tolist()}))
    return d


def render_mesh(tmp_path, *args):
    return run_script(["-m", "pdeface.cli", "render", *map(str, args), *TINY, "--out", str(tmp_path / "out")],
                      tmp_path)


def assert_the_face_moves(bpy, summary):
    frames = sorted(Path(summary["frames_dir"]).iterdir())
    assert summary["frames"] == 4 and len(frames) == 4
    rest, smile = pixels(bpy, frames[0]), pixels(bpy, frames[-1])
    assert rest[16:32, 16:32].mean() > rest[:3, :3].mean() + 0.1  # a head, lighter than the background
    assert np.abs(smile - rest).max() > 0.1  # and it smiles


def test_render_a_glb_head_with_its_landmarks(bpy, head_files, tmp_path):
    summary = render_mesh(tmp_path, "--mesh", head_files / "head.glb", "--landmarks", head_files / "landmarks.json")
    assert_the_face_moves(bpy, summary)


@pytest.mark.skipif(importlib.util.find_spec("mediapipe") is None, reason="finding landmarks needs pdeface[landmarks]")
def test_render_an_obj_head_finding_its_landmarks(bpy, head_files, tmp_path):
    summary = render_mesh(tmp_path, "--mesh", head_files / "head.obj")
    assert_the_face_moves(bpy, summary)


def test_render_mesh_errors(head_files, tmp_path):
    def fails(*args):
        res = subprocess.run([sys.executable, "-m", "pdeface.cli", "render", *map(str, args), *TINY,
                              "--out", str(tmp_path / "out")], capture_output=True, text=True, timeout=600,
                             check=False)
        assert res.returncode == 2, res.stderr[-2000:]
        return res.stderr

    assert "drop --face, --head and --blend" in fails("--mesh", head_files / "head.obj", "--head")
    # a head modelled with its eyes closed, its landmarks given: refused as pdeface rig refuses it, naming the check
    from pdeface.mesh import Mesh

    from scripts.devset.unseen import ict_expression

    V, T, L, _ = ict_expression()
    write_obj(tmp_path / "blink.obj", Mesh.from_faces(V, T))
    (tmp_path / "blink.json").write_text(json.dumps({"points": L.tolist()}))
    err = fails("--mesh", tmp_path / "blink.obj", "--landmarks", tmp_path / "blink.json")
    assert "eyes: closed" in err and "--accept" in err
    err = fails("--mesh", tmp_path / "missing.glb", "--landmarks", head_files / "landmarks.json")
    assert "pdeface render: error:" in err and "missing.glb: cannot open" in err
