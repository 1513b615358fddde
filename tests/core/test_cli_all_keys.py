"""``pdeface pose --all-keys``: every key as a mesh file, on the PDE face and on a head read from glTF."""
import json

import numpy as np
import pytest
from pdeface.assets import load_head
from pdeface.au.modelfile import save_model
from pdeface.cli import main
from pdeface.io.meshio import read_mesh


def run(capsys, *args):
    code = main([str(a) for a in args])
    out = capsys.readouterr()
    return code, out.out, out.err


def write_glb(path, mesh, scale=1.0):
    """A mesh as a one-node GLB (trimesh keeps its vertex order with process=False)."""
    trimesh = pytest.importorskip("trimesh")
    trimesh.Trimesh(mesh.vertices * scale, mesh.triangles()[0], process=False).export(path)
    return path


@pytest.fixture(scope="module")
def small_face(tmp_path_factory, default_face):
    """The bundled face with three of its descriptors (a file for the CLI; fewer keys to write)."""
    default_face.descriptors = [d for d in default_face.descriptors if d.key in ("12", "26", "1L")]
    path = tmp_path_factory.mktemp("face") / "face.npz"
    save_model(path, default_face)
    return path


def test_all_keys_on_the_pde_face(tmp_path, capsys, small_face):
    code, out, err = run(capsys, "pose", small_face, "--all-keys", "--resolution", "2,2",
                         "-o", tmp_path / "keys")
    assert code == 0, err
    r = json.loads(out)
    assert r["aus"] == ["AU1L", "AU12", "AU26"] and r["format"] == "obj"
    assert "happy" in r["presets"] and "neutral" not in r["presets"]  # happy is AUs 6 and 12: 12 is here
    assert sorted(p.name for p in (tmp_path / "keys").iterdir()) == sorted(f"{n}.obj" for n in r["files"])
    neutral, smile = read_mesh(tmp_path / "keys/neutral.obj"), read_mesh(tmp_path / "keys/AU12.obj")
    assert smile.same_topology(neutral) and len(neutral.vertices) == r["vertices"]
    assert np.abs(smile.vertices - neutral.vertices).max() > 0.1  # cm: the lip corners moved
    code, _, err = run(capsys, "pose", small_face, "--all-keys", "--au", "12=1", "-o", tmp_path / "k2")
    assert code == 2 and "drop --au and --preset" in err
    code, _, err = run(capsys, "pose", small_face, "--au", "12=1", "--format", "ply", "-o", tmp_path / "x.ply")
    assert code == 2 and "--format is for --all-keys" in err


def test_all_keys_on_a_glb_head_in_its_vertex_order(tmp_path, capsys, small_face):
    head, _ = load_head()
    write_glb(tmp_path / "head.glb", head)
    code, out, err = run(capsys, "pose", small_face, "--all-keys", "--mesh", tmp_path / "head.glb",
                         "-o", tmp_path / "keys")
    assert code == 0, err
    r = json.loads(out)
    assert r["format"] == "obj"  # glTF is read, not written: OBJ by default
    assert r["aus"] == ["AU1L", "AU12", "AU26"] and "happy" in r["presets"]
    neutral = read_mesh(tmp_path / "keys/neutral.obj")
    np.testing.assert_allclose(neutral.vertices, head.vertices, atol=1e-5)  # as read, in the file's order
    jaw = read_mesh(tmp_path / "keys/AU26.obj").vertices - head.vertices
    assert np.linalg.norm(jaw, axis=1).max() > 0.5  # cm: the jaw dropped
    # The same keys as on the bundled head itself (same vertices, same order), here as PLY.
    code, out, err = run(capsys, "pose", small_face, "--all-keys", "--mesh", "head", "--format", "ply",
                         "-o", tmp_path / "ply")
    assert code == 0, err
    np.testing.assert_allclose(read_mesh(tmp_path / "ply/AU26.ply").vertices - head.vertices, jaw, atol=1e-4)


def test_all_keys_refuses_presets_whose_files_would_clash(tmp_path, capsys, small_face):
    """A preset named like an AU's or the neutral's file, or two whose file names meet, would overwrite a
    file the user asked for: refused, nothing written."""
    for names in (["AU12"], ["neutral"], ["a b", "a/b"]):
        presets = tmp_path / "p.json"
        presets.write_text(json.dumps({"format": "pdeface.presets", "version": 1, "presets": [
            {"format": "pdeface.preset", "version": 1, "name": n, "weights": {"12": 0.5}} for n in names]}))
        out = tmp_path / "keys"
        code, _, err = run(capsys, "pose", small_face, "--all-keys", "--presets", presets, "--resolution", "2,2",
                           "-o", out)
        assert code == 2 and "rename" in err, (names, err)
        assert not out.exists() or not any(out.iterdir())
