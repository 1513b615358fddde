"""Generic FDTs from ICT-FaceKit: every bundled AU and the six basic expressions over identities.

Ground truth of an identity's expression is the identity's neutral plus ICT's
shape offsets (:mod:`pdeface.au.ict`); a basic expression is its preset's AU
weights (the method's Table 5-3) summed the same way, without the AUs ICT has
no shape for (anger's AU23). ``scripts/build/build_fdts.py`` writes them to the
assets; ``scripts/bench/bench_fdt.py`` measures them on identities left out.
"""
from __future__ import annotations

from ..au.ict import AU_SHAPES, NOTICE_SHORT, au_offsets, weights_offsets
from ..facs import normalise_weights
from ..presets import BASIC_EXPRESSIONS, PRESETS
from .deform import NeutralFace
from .table import generic


def ict_targets(shapes) -> dict:
    """Name → ICT offsets (face region) of every AU key ICT maps and of the six basic expressions."""
    out = {k: au_offsets(k, shapes) for k in AU_SHAPES}
    for name in BASIC_EXPRESSIONS:
        out[name] = weights_offsets(normalise_weights(PRESETS[name].weights), shapes)[0]
    return out


def identity_fits(vertices, triangles, landmarks, shapes, identity, targets, models=("3d",)) -> dict:
    """``{model: {name: FaceFit}}`` of one ICT identity (``identity000``...) for each target."""
    V = vertices + shapes[identity]
    face = NeutralFace(V, triangles, V[landmarks])
    return {m: {name: face.fit(V + off, m, name) for name, off in targets.items()} for m in models}


def generic_fdts(per_identity, model="3d", source="") -> list:
    """Generic FDTs (mean ± σ) of every target from ``[identity_fits(...)[model], ...]``."""
    names = list(per_identity[0])
    return [generic([fits[name].fdt for fits in per_identity], name, source=source, notice=NOTICE_SHORT)
            for name in names]
