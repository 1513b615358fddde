"""One command reads its mesh file once (issue #35): the landmarks `pdeface fit` finds are found on the
mesh it read, and the fit runs on that same mesh."""
import json
from types import SimpleNamespace

import numpy as np
from pdeface.cli import main
from pdeface.io import meshio
from pdeface.io.meshio import write_obj


def test_fit_without_landmarks_finds_them_on_the_mesh_it_read(tmp_path, capsys, monkeypatch, scan):
    mesh, _, idx = scan
    write_obj(tmp_path / "neutral.obj", mesh)
    reads, searched = [], []
    real_read = meshio.read_bytes
    monkeypatch.setattr(meshio, "read_bytes", lambda path, *a: reads.append(str(path)) or real_read(path, *a))

    def found(m, unit, verbose=False, **options):  # the finder and its gate stood in for: the scan's own landmarks
        searched.append(m)
        return SimpleNamespace(points=m.vertices[idx]), None

    monkeypatch.setattr("pdeface.cli.face.find_landmarks", found)
    code = main(["fit", str(tmp_path / "neutral.obj"), "--unit", "cm", "-o", str(tmp_path / "face.npz")])
    assert code == 0 and json.loads(capsys.readouterr().out)["output"] == str(tmp_path / "face.npz")
    assert reads == [str(tmp_path / "neutral.obj")]  # read once, by the fit's own load
    assert len(searched) == 1 and np.allclose(searched[0].vertices, mesh.vertices, atol=1e-5)
