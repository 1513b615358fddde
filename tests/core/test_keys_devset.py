"""AU keys on development characters other artists' heads stand for (issue #40)."""
import numpy as np
import pytest
from pdeface.au.modelfile import load_face
from pdeface.au.retarget import curve_map, retarget
from pdeface.head.bind import HeadBinding, descriptor_motion_args
from pdeface.surface.fit import fit_face

from scripts.bench.bench_keys_devset import LIDS, eyes_of
from scripts.devset import makehuman
from scripts.devset.characters import SPECS, build

needs_makehuman = pytest.mark.skipif(not makehuman.available(), reason="needs ../shared/data/makehuman")


def rig(name):
    """(character's joined V, T, L, retargeted model, binding), as bench_keys_devset rigs it."""
    ch = build(SPECS[name])
    V, T, L = ch.vertices, ch.triangles, ch.landmarks
    for Vp, Tp in ch.parts.values():
        T = np.concatenate([T, Tp + len(V)])
        V = np.concatenate([V, Vp])
    model, _ = fit_face(V, T, L)
    model = retarget(load_face("default"), model)
    return V, T, L, model, HeadBinding(model, V, T, landmarks=L)


def lid_closure(V, L, model, binding, key="45"):
    d = {x.key: x for x in model.descriptors}[key]
    f = model.frame
    Vf, Lf = f.to_face(V), f.to_face(L)
    posed = f.to_face(V + binding.displacement(*descriptor_motion_args(d)))
    near = np.array([np.argmin(np.linalg.norm(Vf - p, axis=1)) for p in Lf])
    rest, _ = eyes_of(Lf)
    moved, _ = eyes_of(posed[near])
    return {s: 1 - np.linalg.norm(moved[s][0] - moved[s][1]) / np.linalg.norm(rest[s][0] - rest[s][1]) for s in LIDS}


@needs_makehuman
def test_descriptors_reach_the_lids_on_a_face_whose_curves_are_spread_otherwise():
    # MakeHuman's base has its upper lid's rim on another curve than ICT's: the blink must still close the
    # lids (it opened them, -0.15, when curve i was carried onto curve i).
    V, _, L, model, b = rig("base-dm")
    source = load_face("default")
    where = curve_map(source.layout, model.layout)
    assert where is not None
    for (a, k), (a_s, k_s) in zip(model.layout.opening_curves(), source.layout.opening_curves()):
        assert a == a_s and where[k] == k_s and where[k + 1] == k_s + 1  # rims onto rims
    closure = lid_closure(V, L, model, b)
    assert min(closure.values()) > 0.7, closure
    assert abs(closure["L"] - closure["R"]) < 0.1 * max(closure.values())


def test_faces_with_the_same_curves_keep_their_descriptors():
    source = load_face("default")
    assert curve_map(source.layout, source.layout) is None
    moved = retarget(source, source)
    for a, b in zip(source.descriptors, moved.descriptors):
        assert np.allclose(a.points(), b.points())
