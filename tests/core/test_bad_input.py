"""Bad input of issue 38: a stray vertex far away, broken files of every kind, endless and inflating files.
Each is refused with one PdeFaceError line naming the file (or fitted, for the stray vertex), in bounded work."""
import json
import resource
import subprocess
import sys

import numpy as np
import pytest
from pdeface.geometry import MAX_GRID_CELLS, cast_cylinder_rays, cylinder_ray_candidates
from pdeface.io.meshio import write_mesh
from pdeface.mesh import Mesh
from pdeface.surface.fit import fit_face


def _moved(scan, far):
    """The scan with one skin vertex (no landmark) moved to (far, far, far)."""
    mesh, T, idx = scan
    V = mesh.vertices.copy()
    others = np.setdiff1d(np.arange(len(V)), idx)
    V[others[len(others) // 2]] = far
    return V, T, idx


@pytest.mark.parametrize("far", [1e25, 1e12, 1e6])
def test_the_ray_grid_is_bounded_whatever_a_vertex_coordinates(scan, fitted, far):
    model, _ = fitted
    V, T, _ = _moved(scan, far)
    Vf = model.frame.to_face(V)
    th = np.linspace(-1.5, 1.5, 300)
    y = np.linspace(-80, 60, 300)
    rays, _ = cylinder_ray_candidates(Vf, T, model.layout.axis_z, th, y)
    assert len(rays) < 50 * len(th) + MAX_GRID_CELLS ** 2
    clean = cast_cylinder_rays(model.frame.to_face(scan[0].vertices), T, model.layout.axis_z, th, y)[0]
    moved = cast_cylinder_rays(Vf, T, model.layout.axis_z, th, y)[0]
    both = np.isfinite(clean) & np.isfinite(moved)
    assert both.sum() > 0.9 * np.isfinite(clean).sum() and np.allclose(clean[both], moved[both])


@pytest.mark.parametrize("far", [1e25, 1e6])
def test_a_fit_ignores_a_vertex_far_away(scan, fitted, far):
    V, T, idx = _moved(scan, far)
    model, _ = fit_face(V, T, scan[0].vertices[idx], unit="cm")
    assert np.abs(model.coefficients - fitted[0].coefficients).max() < 1.0  # mm


def _limit_memory():
    resource.setrlimit(resource.RLIMIT_AS, (3 << 30, 3 << 30))


@pytest.mark.parametrize("far", ["1e25", "1e9", "1e6"])
def test_fit_on_a_mesh_with_one_stray_vertex_neither_crashes_nor_bombs(tmp_path, scan, far):
    mesh, _, idx = scan
    V = mesh.vertices.copy()
    others = np.setdiff1d(np.arange(len(V)), idx)
    V[others[len(others) // 2]] = float(far)
    write_mesh(tmp_path / "stray.obj", Mesh(V, mesh.face_counts, mesh.face_indices))
    (tmp_path / "lm.json").write_text(json.dumps({"indices": [int(i) for i in idx]}))
    res = subprocess.run([sys.executable, "-m", "pdeface.cli", "fit", str(tmp_path / "stray.obj"), "--landmarks",
                          str(tmp_path / "lm.json"), "--unit", "cm", "-o", str(tmp_path / "face.npz")],
                         check=False, capture_output=True, text=True, timeout=300,
                         preexec_fn=_limit_memory)
    assert res.returncode == 0, res.stderr[-2000:]
    assert (tmp_path / "face.npz").stat().st_size > 1000
