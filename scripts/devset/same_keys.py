"""Every descriptor's key on a few heads, kept to check that a change meant to leave them as they are does (issue #35).

    python -m scripts.devset.same_keys DIR [--heads NAME ...]

Each head is fitted, retargeted from the bundled face, bound and keyed as ``bench_keys_devset`` does; its keys go to
``DIR/NAME.npy`` where that file does not exist (run it before the change), else their largest difference from it is
printed (after). ``ict`` is ICT-FaceKit's whole head; the other names are development characters
(``scripts/devset/characters.py``): by default one decimated with its lips joined, a voxel remesh with its lips in
one row of vertices, a whole body, and one with its teeth and eyes as objects of their own.
"""
from __future__ import annotations

import argparse
from pathlib import Path

from pdeface.assets import load_head
from pdeface.au.modelfile import load_face
from pdeface.au.retarget import retarget
from pdeface.head.bind import HeadBinding
from pdeface.surface.fit import fit_face

from scripts.bench.bench_load import compare_keys
from scripts.devset.characters import SPECS, build

HEADS = ("ict", "decimated-cm", "voxel-m", "body-A-cm", "parted-lips-teeth-separate-m")


def head_keys(name):
    """``(k, n, 3)``: every descriptor's key on the head ``name`` (``ict`` or a development character)."""
    if name == "ict":
        mesh, lm = load_head()
        V, T = mesh.vertices, mesh.triangles()[0]
        model = retarget(load_face("default"), fit_face(V, T, V[lm])[0])
        return HeadBinding(model, V, T).descriptor_displacements(model.descriptors)  # as bench_load binds it
    else:
        ch = build(SPECS[name])
        (V, T), L = ch.joined(), ch.landmarks  # as the add-on joins a head's objects
    model = retarget(load_face("default"), fit_face(V, T, L)[0])
    return HeadBinding(model, V, T, landmarks=L).descriptor_displacements(model.descriptors)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("dir", type=Path, help="where the keys are kept (NAME.npy)")
    ap.add_argument("--heads", nargs="+", default=list(HEADS), choices=["ict", *SPECS], metavar="NAME")
    args = ap.parse_args(argv)
    args.dir.mkdir(parents=True, exist_ok=True)
    for name in args.heads:
        print(f"{name}: ", end="")
        compare_keys(head_keys(name), str(args.dir / f"{name}.npy"))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
