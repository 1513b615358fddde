"""Build the whole-head prior: what the PDE face and its harmonic extension miss on ICT-FaceKit's head.

Usage: python -m scripts.build.build_head_prior [--identities 10-19] [-o assets/ict_head_prior.npz]

Fits the PDE face on the bundled generic head and on each training identity's head, gives each
the bundled descriptors (retargeted, as ``pdeface retarget`` does), binds the head without a
prior, and keeps for every AU key ICT-FaceKit has shapes for: its curve-point motion on the
generic face and the residual, truth (ICT expression − neutral) minus the binding, at every
vertex of the head (eyeballs excluded: ICT's do not move, gaze turns them), averaged over the
heads vertex by vertex (they share ICT's topology). Averaged, the residual is less the generic
head's own: on identities 000-009, which it never saw, the face median rose 0.010 on average
against the generic head's alone. Identities 000-009 are left out by default so that
``bench_head.py`` can measure heads the prior never saw. See :mod:`pdeface.head.prior`. Needs
the assets only; about 30 s.
"""
from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
from pdeface.assets import ICT_HEAD, ICT_HEAD_PRIOR, ICT_NOTICE, assets_dir, load_head, load_head_shapes
from pdeface.au.ict import AU_SHAPES, au_offsets
from pdeface.au.modelfile import load_face
from pdeface.au.retarget import face_size, retarget
from pdeface.errors import ModelFormatError
from pdeface.head.bind import HeadBinding, descriptor_motion_args
from pdeface.head.prior import FORMAT, STEP_MM, HeadPrior
from pdeface.surface.fit import fit_face


def save_prior(path, prior: HeadPrior, frame: np.ndarray, head: str, step_mm: float = STEP_MM, identities=None):
    """Write a prior file (:mod:`pdeface.head.prior`'s format) of the head asset ``head`` (``frame``: its 4×4
    map to the face frame)."""
    identities = prior.identities if identities is None else identities
    carried = np.nonzero(np.abs(prior.residuals).max(axis=(0, 2)) >= step_mm)[0]
    q = np.round(prior.residuals[:, carried] / step_mm)
    if np.abs(q).max(initial=0) > np.iinfo(np.int16).max:
        raise ModelFormatError(f"residuals too large for steps of {step_mm} mm")
    np.savez_compressed(path, format=np.array(FORMAT), keys=np.array(prior.keys),
                        features=prior.features.astype(np.float16), residuals=q.astype(np.int16),
                        step_mm=np.array(step_mm), carried=carried.astype(np.int32), kind=prior.kind.astype(np.int8),
                        frame=np.asarray(frame, np.float64), head=np.array(head),
                        curve_points=prior.curve_points.astype(np.float32), face_size=np.asarray(prior.face_size),
                        ridge=np.array(prior.ridge), notice=np.array(prior.notice),
                        identities=np.array(list(identities), np.int64))


def head_samples(V, T, lm, shapes, source, unit="cm"):
    """``(binding, keys, features, residuals)`` of a head: the prior-free binding's residual per AU key (mm)."""
    model, _ = fit_face(V, T, V[lm], unit=unit)
    model = retarget(source, model)
    b = HeadBinding(model, V, T, prior=None)
    eyes = b.parts.mask("eye_L", "eye_R")
    keys, features, residuals = [], [], []
    for d in model.descriptors:
        if d.key not in AU_SHAPES:
            continue
        dC, dR, jaw, gaze, _ = descriptor_motion_args(d)
        truth = b.frame.scale * au_offsets(d.key, shapes) @ b.frame.rotation.T
        r = truth - b.face_motion(dC, dR, jaw, gaze, with_prior=False)
        r[eyes] = 0.0
        keys.append(d.key)
        features.append(model.curve_points(dC, dR))
        residuals.append(r)
    return b, keys, np.array(features), np.array(residuals)


#: Identities whose heads the bundled prior is learned from (with the generic head's).
TRAINING_IDENTITIES = range(10, 20)


def build(source=None, identities=TRAINING_IDENTITIES):
    """The prior of the bundled generic head (and ``identities``' heads), and the frame taking the head asset to
    its face frame."""
    source = load_face("default") if source is None else source
    head, lm = load_head()
    T, _ = head.triangles()
    shapes = load_head_shapes()
    b, keys, X, Y = head_samples(head.vertices, T, lm, shapes, source)
    residuals = [Y]
    for i in identities:
        _, keys_i, _, Y_i = head_samples(head.vertices + shapes[f"identity{i:03d}"], T, lm, shapes, source)
        if keys_i != keys:
            raise SystemExit(f"identity{i:03d} gave other AU keys than the generic head")
        residuals.append(Y_i)
    prior = HeadPrior(keys, X, np.mean(residuals, axis=0), b.Vf, T, b.parts.kind, b.model.curve_points(),
                      face_size(b.model), notice=ICT_NOTICE, identities=tuple(identities))
    return prior, b.frame.matrix()


def identity_range(text):
    """``10-19`` or ``3,5,8`` or ``none``."""
    if text == "none":
        return []
    if "-" in text:
        a, b = (int(x) for x in text.split("-"))
        return list(range(a, b + 1))
    return [int(x) for x in text.split(",")]


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--identities", type=identity_range, default=list(TRAINING_IDENTITIES),
                    help="identities learned from besides the generic head: 10-19 (default), 3,5,8 or none")
    ap.add_argument("-o", "--out", default=str(assets_dir() / ICT_HEAD_PRIOR))
    args = ap.parse_args(argv)
    prior, frame = build(identities=args.identities)
    save_prior(args.out, prior, frame, ICT_HEAD)
    size = Path(args.out).stat().st_size
    print(f"wrote {args.out}: {len(prior.keys)} AU keys from the generic head and {len(args.identities)} "
          f"identities, {size / 1e6:.2f} MB")


if __name__ == "__main__":
    main()
