"""Every key of a few development-set characters written, or compared with those written before: a change meant to
leave the keys as they were (issue #35's speed-ups) checked on MakeHuman heads, beside ``bench_load --keys``' ICT.

Usage: python -m scripts.devset.compare_keys DIR [NAME ...]

Each character (default: ICT-FaceKit's whole head, ``ict``, bound as ``bench_load`` binds it, and six not tuned on:
a head with eyeballs, a decimated one with its lips joined, a voxel remesh with its lips in one row of vertices, a whole
body, one with its teeth and eyes as objects of their own, a Blender-axes one in metres) is built, fitted with its true
landmarks and the bundled descriptors retargeted to it; the fit is kept in DIR, so a second
run binds the same model. Then every pose's key (the descriptors' and the presets' sums, as ``bench_keys_devset``) is
bound (:class:`pdeface.head.bind.HeadBinding`) and written to ``DIR/NAME.npy`` where missing, else compared with it:
the largest difference is printed, and the exit status is 1 where any key differs at all.
"""
from __future__ import annotations

import argparse
import pickle
import sys
import time
from pathlib import Path

import numpy as np
from pdeface.assets import load_head
from pdeface.au.modelfile import load_face
from pdeface.au.retarget import retarget
from pdeface.head.bind import HeadBinding
from pdeface.presets import every_pose
from pdeface.surface.fit import fit_face

from scripts.devset.characters import SPECS, build

NAMES = ("ict", "caucasian-female-young-cm", "decimated-cm", "voxel-m", "body-A-cm", "parted-lips-teeth-separate-m",
         "asian-male-young-blender-m")


def fitted(name, folder):
    """The character's mesh, landmarks and retargeted model, fitted once and kept in ``folder``."""
    path = folder / f"{name}.model.pkl"
    if path.exists():
        return pickle.loads(path.read_bytes())
    if name == "ict":
        mesh, lm = load_head()
        V, T = mesh.vertices, mesh.triangles()[0]
        out = V, T, None, retarget(load_face("default"), fit_face(V, T, V[lm])[0])  # bound without its landmarks
    else:
        ch = build(SPECS[name])
        (V, T), L = ch.joined(), ch.landmarks  # as the add-on joins a head's objects
        out = V, T, L, retarget(load_face("default"), fit_face(V, T, L)[0])
    path.write_bytes(pickle.dumps(out))
    return out


def keys(V, T, L, model):
    """Every pose's key (k, n, 3) and the binding's and the keys' CPU seconds."""
    c = time.process_time()
    b = HeadBinding(model, V, T, landmarks=L)
    bound = time.process_time()
    D = b.displacements(b.every_pose_motion_args(n for n in every_pose(model) if n != "neutral"))
    return D, bound - c, time.process_time() - bound


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("folder", type=Path, help="where the fits and keys are kept")
    ap.add_argument("names", nargs="*", default=NAMES, help="ict, or characters of scripts.devset.characters.SPECS")
    args = ap.parse_args(argv)
    args.folder.mkdir(parents=True, exist_ok=True)
    same = True
    for name in args.names:
        D, bind_s, keys_s = keys(*fitted(name, args.folder))
        path = args.folder / f"{name}.npy"
        said = f"{name}: CPU binding {bind_s:.2f} s, keys {keys_s:.2f} s; "
        same &= compared(D, path, said)
    return 0 if same else 1


def compared(keys, path, said="keys") -> bool:
    """Write ``keys`` (k, n, 3) to ``path`` where it does not exist, else print their largest difference from it
    (after ``said``); whether they are the same (True where written)."""
    path = Path(path)
    if not path.exists():
        np.save(path, keys)
        print(f"{said} ({keys.shape[0]} keys, {keys.shape[1]} vertices) written to {path}")
        return True
    was = np.load(path)
    if was.shape != keys.shape:
        print(f"{said}: {path} holds {was.shape}, this run {keys.shape}: not comparable")
        return False
    diff = np.abs(keys - was).max(axis=(1, 2))
    print(f"{said} against {path}: largest difference {diff.max():.3g} (the head's unit; largest key motion "
          f"{np.abs(was).max():.3g}); {int((diff > 0).sum())} of {len(diff)} keys differ at all")
    return not diff.any()


if __name__ == "__main__":
    sys.exit(main())
