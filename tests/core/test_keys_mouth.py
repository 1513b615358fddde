"""Teeth and tongue turn whole with the jaw or stay with the skull; heads without a mouth inside (issue #40)."""
from functools import lru_cache

import numpy as np
import pytest
from pdeface.au.modelfile import load_face
from pdeface.au.retarget import retarget
from pdeface.head.bind import JAW_AUS, HeadBinding
from pdeface.head.parts import CODE
from pdeface.mesh import connected_components, edge_face_pairs, turn_degrees
from pdeface.surface.fit import fit_face

from scripts.devset import makehuman
from scripts.devset.characters import SPECS, build

needs_makehuman = pytest.mark.skipif(not makehuman.available(), reason="needs ../shared/data/makehuman")


@lru_cache(maxsize=2)
def rig(name):
    """(joined V, T, L, retargeted model, binding) of a development character, as bench_keys_devset rigs it."""
    ch = build(SPECS[name])
    (V, T), L = ch.joined(), ch.landmarks
    model = retarget(load_face("default"), fit_face(V, T, L)[0])
    return V, T, L, model, HeadBinding(model, V, T, landmarks=L)


def edges(T):
    E = np.sort(np.concatenate([T[:, [0, 1]], T[:, [1, 2]], T[:, [2, 0]]]), axis=1)
    return np.unique(E, axis=0)


@needs_makehuman
@pytest.mark.parametrize("name", ["eyes-teeth-separate-in", "eyes-teeth-merged-cm", "parted-lips-teeth-separate-m"])
def test_teeth_and_tongue_turn_whole_with_the_jaw_or_stay_with_the_skull(name):
    """MakeHuman's upper teeth, lower teeth and tongue (separate objects or pieces of the one mesh): each piece is
    one kind; the jaw keys turn the lower teeth and the tongue without stretching them (the tongue was split between
    jaw and skull: its back stayed, its tip turned, 14-40 folded edges in AU27) and leave the upper teeth."""
    V, T, _, model, b = rig(name)
    lab = connected_components(len(V), T)
    inner = np.unique(lab[b.parts.mask("jaw", "skull")]).tolist()
    assert len(inner) == 3  # upper teeth, lower teeth, tongue
    kinds = {c: set(b.parts.kind[lab == c].tolist()) for c in inner}
    assert all(len(k) == 1 for k in kinds.values()), kinds
    jaw = [c for c in inner if kinds[c] == {CODE["jaw"]}]
    assert len(jaw) == 2  # lower teeth and tongue; the upper teeth with the skull
    f, ed = model.frame, b.eye_distance
    Vf = f.to_face(V)
    E = edges(T)
    length = np.linalg.norm(Vf[E[:, 0]] - Vf[E[:, 1]], axis=1)
    pairs = edge_face_pairs(T)
    flat = turn_degrees(Vf, T, pairs) < 20
    inside = b.parts.mask("jaw", "skull")[T[pairs]].any(axis=(1, 2))
    descr = [d for d in model.descriptors if int(d.key.rstrip("LR")) in JAW_AUS]
    D = b.descriptor_displacements(descr)
    for d, key in zip(D, [x.key for x in descr]):
        P = f.to_face(V + d)
        stretch = np.abs(np.linalg.norm(P[E[:, 0]] - P[E[:, 1]], axis=1) / length - 1)
        for c in inner:
            assert stretch[lab[E[:, 0]] == c].max() < 1e-6, (key, c)  # rigid: no edge longer or shorter
        assert not (flat & inside & (turn_degrees(P, T, pairs) > 40)).any(), key
        if key == "27":
            moved = {c: np.linalg.norm(P[lab == c] - Vf[lab == c], axis=1) for c in inner}
            assert all(moved[c].min() > 0.1 * ed for c in jaw)
            assert all(moved[c].max() == 0 for c in inner if c not in jaw)
