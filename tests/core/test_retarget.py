import numpy as np
import pytest
from pdeface.assets import load_face, load_ict_shapes
from pdeface.au.aureport import MotionProbe
from pdeface.au.ict import au_offsets
from pdeface.au.retarget import face_size, retarget
from pdeface.errors import PdeFaceError
from pdeface.surface.fit import fit_face


def test_retarget_to_an_ict_identity(scan):
    mesh, T, idx = scan
    source = load_face("default")
    Vi = mesh.vertices + load_ict_shapes()["identity003"]
    target, _ = fit_face(Vi, T, Vi[idx], unit="cm")
    out = retarget(source, target)
    assert len(out.descriptors) == len(source.descriptors)
    s = face_size(target) / face_size(source)
    d0, d1 = source.descriptors[0], out.descriptors[0]
    np.testing.assert_allclose(d1.coefficients, d0.coefficients * s)
    # ground truth: identity neutral + (ICT expression − ICT neutral)
    probe = MotionProbe(out, Vi, T)
    shapes = load_ict_shapes()
    caps = []
    for key in ("1", "2", "4", "12", "15", "20"):
        d = next(x for x in out.descriptors if x.key == key)
        caps.append(probe.measure(*d.dense(), au_offsets(key, shapes))["captured"])
    assert np.median(caps) >= 0.90


def test_retarget_checks_layouts(scan):
    mesh, T, idx = scan
    source = load_face("default")
    small, _ = fit_face(mesh.vertices, T, mesh.vertices[idx], unit="cm", n_curves=19, n_points=21)
    with pytest.raises(PdeFaceError, match="layout"):
        retarget(source, small)
    with pytest.raises(PdeFaceError, match="scaling"):
        retarget(source, source, scaling="huge")
