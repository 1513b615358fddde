import numpy as np
import pytest
from pdeface.assets import load_neutral_scan
from pdeface.au.modelfile import load_face
from pdeface.surface.fit import fit_face


@pytest.fixture(scope="session")
def scan():
    """The bundled ICT-FaceKit neutral face region: (mesh, triangles, 68 landmark indices)."""
    mesh, idx = load_neutral_scan()
    T, _ = mesh.triangles()
    return mesh, T, idx


@pytest.fixture(scope="session")
def fitted(scan):
    """(model, sampler) fitted to the bundled scan with the default layout."""
    mesh, T, idx = scan
    return fit_face(mesh.vertices, T, mesh.vertices[idx], unit="cm")


@pytest.fixture(scope="module")
def default_face():
    """The bundled default face model (read once per test module: a test may change its descriptors)."""
    return load_face("default")


@pytest.fixture
def rng():
    return np.random.default_rng(1234)


@pytest.fixture
def rotation(rng):
    """A random proper rotation (3, 3)."""
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    return q * np.sign(np.linalg.det(q))
