"""Build the shipped map from MediaPipe's 468 face-mesh points to the 68 Multi-PIE landmarks.

Usage: python -m scripts.build.build_landmark_map [--out core/pdeface/data/landmark_map.json] [--train 14]

Trained on the bundled ICT-FaceKit full heads identity000..(train-1) (the rest
are held out for ``scripts/bench/bench_landmarks.py``), each found as the user's
mesh would be: ICT's frame, and Blender's turned 25° in metres. First pass:
the face-mesh points of each head's render from its true face frame, in that frame,
averaged into the template. Second pass: the full pipeline with that template;
each landmark's weights over its nearest face-mesh points are fitted by
constrained least squares. Needs ``pdeface[landmarks]`` and only the assets.
"""
from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np
from pdeface.assets import ICT_NOTICE, load_head, load_head_shapes
from pdeface.io.files import write_bytes
from pdeface.landmarks.detector import Detector
from pdeface.landmarks.facemap import DEFAULT_MAP, LandmarkMap, fit_map
from pdeface.landmarks.pipeline import detect, face_points, frontal, group_spread
from pdeface.rigid import rotation_vector_matrix
from pdeface.surface.frame import BLENDER_FROM_ICT, face_frame
from scipy.optimize import linear_sum_assignment

#: The poses each training head is seen in: (name, rotation, scale to the mesh unit, unit).
POSES = [("ict", np.eye(3), 1.0, "cm"),
         ("blender-yaw25-m", BLENDER_FROM_ICT @ rotation_vector_matrix([0, np.radians(25), 0]), 0.01, "m"),
         ("pitch-15-roll10", rotation_vector_matrix([np.radians(-15), 0, np.radians(10)]), 10.0, "mm")]


#: About the middle of a face in the face frame (mm; the nose tip is the origin).
FACE_CENTRE_MM = np.array([0.0, -20.0, -25.0])


def mirror_pairs(template) -> np.ndarray:
    """Each template point's mirror image across the face's midplane (x = 0 in the face frame), as the
    one-to-one pairing of least total distance (an involution: midline points pair with themselves)."""
    T = np.asarray(template, np.float64)
    T = T - [np.median(T[:, 0]), 0, 0]
    d = np.linalg.norm(T[:, None] - (T * [-1, 1, 1])[None], axis=2)
    pairs = linear_sum_assignment(d)[1]
    # Keep the pairing symmetric even where two assignments tie.
    return np.where(pairs[pairs] == np.arange(len(T)), pairs, np.arange(len(T)))


def write_map(path, m: LandmarkMap) -> int:
    """Write a landmark map file (:mod:`pdeface.landmarks.facemap`'s format); returns its size in bytes."""
    return write_bytes(path, json.dumps(m.to_json(), separators=(",", ":")).encode())


def heads(names):
    mesh, lm = load_head()
    shapes = load_head_shapes()
    T, _ = mesh.triangles()
    for n in names:
        yield n, mesh.vertices + shapes[n], T, lm


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", type=Path, default=DEFAULT_MAP)
    ap.add_argument("--train", type=int, default=14, help="identities 0..N-1 train the map")
    ap.add_argument("--k", type=int, default=6, help="face-mesh points per landmark")
    args = ap.parse_args(argv)
    names = [f"identity{i:03d}" for i in range(args.train)]
    t0 = time.perf_counter()
    with Detector() as det:
        firsts = []
        for n, V, T, lm in heads(names):
            frame = face_frame(V[lm], "cm")
            # The bootstrap looks from the true face frame (no template yet to find the pose with).
            view = frontal(FACE_CENTRE_MM[None], 1 / frame.scale, frame.rotation.T, frame.origin)
            P, *_ = face_points(V, T, det, view)
            firsts.append(frame.to_face(P))
        template = np.nanmean(np.stack(firsts), axis=0)
        provisional = LandmarkMap(np.zeros((68, 1), np.int64), np.ones((68, 1)), template,
                                  mirror=mirror_pairs(template))
        samples, spreads = [], []
        for n, V, T, lm in heads(names):
            for pose, R, scale, unit in POSES:
                Vp = V @ R.T * scale
                found = detect(Vp, T, unit, provisional, det)
                frame = face_frame(Vp[lm], unit)
                samples.append((frame.to_face(found.mesh_points), frame.to_face(Vp[lm])))
                spreads.append((frame.to_face(found.view_points.reshape(-1, 3)).reshape(found.view_points.shape)))
            print(f"{n}: {time.perf_counter() - t0:.0f} s", flush=True)
    m = fit_map(samples, template, k=args.k, trained_on=names, notice=ICT_NOTICE)
    m.mirror = provisional.mirror
    each = [group_spread(m, views) for views in spreads]
    m.spread_mm = {g: float(np.median([sp[g] for sp in each])) for g in each[0]}
    print("median spread over the frontal renders (mm): " + ", ".join(f"{g} {v:.2f}" for g, v in m.spread_mm.items()))
    L = np.stack([s[1] for s in samples])
    pred = np.stack([m.apply(s[0]) for s in samples])
    err = np.linalg.norm(pred - L, axis=2)
    print(f"training error: inner median {np.median(err[:, 17:]):.2f} mm, p95 {np.percentile(err[:, 17:], 95):.2f}; "
          f"jaw median {np.median(err[:, :17]):.2f} mm")
    write_map(args.out, m)
    print(f"{args.out}: {len(samples)} samples from {len(names)} heads, {args.out.stat().st_size} bytes")


if __name__ == "__main__":
    main()
