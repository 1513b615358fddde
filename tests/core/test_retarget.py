import numpy as np
import pytest
from pdeface.assets import load_ict_shapes
from pdeface.au.aureport import MotionProbe
from pdeface.au.ict import au_offsets
from pdeface.au.modelfile import load_face
from pdeface.au.retarget import LID_GAP_RATIO, face_size, gap_factors, narrowed, retarget
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
    d0, d1 = source.descriptors[0], retarget(source, target, spacing=False).descriptors[0]
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
    with pytest.raises(PdeFaceError, match="source face's layout"):  # the gap rule compares both faces' curves
        retarget(small, source, descriptors=source.descriptors)
    assert len(retarget(small, source, descriptors=source.descriptors, spacing=False).descriptors) > 0


def test_a_face_retargeted_to_itself_is_unchanged():
    face = load_face("default")
    assert np.all(gap_factors(face, face) == 1.0)
    out = retarget(face, face)
    for a, b in zip(face.descriptors, out.descriptors):
        np.testing.assert_array_equal(a.curves, b.curves)
        np.testing.assert_array_equal(a.coefficients, b.coefficients)


def test_a_narrow_gap_shrinks_the_relative_motion_across_it():
    """Curves 0-4 moving 1 mm forward and 5-9 3 mm: with the gap 4-5 at factor 0.25 the 2 mm jump across it
    becomes about a quarter, in every column; the curves on either side meet halfway, the mean motion kept."""
    from pdeface.au.descriptor import Descriptor

    K, J, N = 10, 9, 3
    C = np.zeros((K, N + 1, 3))
    C[:5, 0, 2], C[5:, 0, 2] = 1.0, 3.0
    d = Descriptor(12, "both", np.arange(K), C, np.zeros((K, J, 3)), (K, J, N))
    f = np.ones((K - 1, J))
    f[4] = 0.25
    (out,) = narrowed([d], f)
    P = np.zeros((K, J, 3))
    P[out.curves] = out.points()
    jump = P[5, :, 2] - P[4, :, 2]
    np.testing.assert_allclose(jump, jump[0])
    assert 0.5 < jump[0] < 0.8  # the source weight keeps a little more than a quarter
    np.testing.assert_allclose(P[..., 2].mean(axis=0), 2.0)
    np.testing.assert_allclose(P[..., :2], 0.0, atol=1e-12)
    assert P[0, 0, 2] > 1.0 and P[9, 0, 2] < 3.0
    assert narrowed([d], np.ones((K - 1, J)))[0] is d


def test_retargeting_keeps_curves_apart_where_the_target_converges(scan, tmp_path):
    """Identity012's curves above the upper lip converge to half the default face's spacing: AU28 retargeted by
    curve index moved them past each other (26 folds), the gap rule leaves none and captures as much."""
    from pdeface.posing import pose_curves
    from pdeface.surface.fit import face_mesh
    from pdeface.surface.folds import fold_edges

    mesh, T, idx = scan
    shapes = load_ict_shapes()
    V = mesh.vertices + shapes["identity012"]
    target, _ = fit_face(V, T, V[idx], unit="cm")
    source = load_face("default")
    f = gap_factors(source, target, face_size(target) / face_size(source))
    assert f.min() < 0.6
    (_, eyes), (_, mouth) = target.layout.opening_curves()
    assert np.all(f[mouth] == 1.0)  # the lips still part
    assert np.all((f[eyes] >= LID_GAP_RATIO[0]) & (f[eyes] <= LID_GAP_RATIO[1]))  # the lids close their own opening
    folds, captured = [], []
    for spacing in (False, True):
        rig = retarget(source, target, spacing=spacing)
        C, R = pose_curves(rig, {"28": 1.0})
        # on an even mesh: the default's steps follow a crease (a sharp one included), so they would hide it
        folds.append(fold_edges(face_mesh(rig, "4,4", coefficients=C, residual=R), rig.frame, rig.landmarks,
                                rest=face_mesh(rig, "4,4"))["count"])
        d = next(x for x in rig.descriptors if x.key == "28")
        captured.append(MotionProbe(rig, V, T).measure(*d.dense(), au_offsets("28", shapes))["captured"])
    assert folds[0] > 15 and folds[1] == 0  # measured 26 -> 0
    assert captured[1] >= captured[0] - 0.005
    # the command line does the same, and --no-spacing the plain retarget
    from pdeface.au.modelfile import save_model
    from pdeface.cli import main

    save_model(tmp_path / "t.npz", target)
    def motion(model):  # AU28's curve point motion (K, J, 3)
        d = next(x for x in model.descriptors if x.key == "28")
        P = np.zeros((d.layout[0], d.layout[1], 3))
        P[d.curves] = d.points()
        return P

    got = []
    for flags, spacing in (([], True), (["--no-spacing"], False)):
        assert main(["retarget", str(tmp_path / "t.npz"), *flags, "-o", str(tmp_path / "rt.npz")]) == 0
        got.append(motion(load_face(tmp_path / "rt.npz")))
        np.testing.assert_allclose(got[-1], motion(retarget(source, target, spacing=spacing)), atol=0.05)
    assert np.abs(got[0] - got[1]).max() > 0.2
