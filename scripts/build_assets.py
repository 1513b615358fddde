"""Build the bundled assets from an ICT-FaceKit folder.

Usage: python scripts/build_assets.py ICT_DIR [--out assets]

Writes, all derived from ICT-FaceKit (MIT, notice copied alongside):
  ict_neutral_face.npz   the neutral face region (vertices 0-9408, cm) with UVs and landmarks
  default_face.npz       the PDE face model fitted to it (default layout)
  ict_shapes.npz         the 53 expression shapes and 20 identity meshes as offsets from
                         the neutral face region (int16, OFFSET_STEP cm steps)
  ICT-FaceKit-LICENSE.txt
"""
from __future__ import annotations

import argparse
import json
import shutil
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "core"))

from pdeface.fit import fit_face  # noqa: E402
from pdeface.meshio import read_obj  # noqa: E402
from pdeface.model import ICT_NOTICE, save_model  # noqa: E402

FACE_VERTICES = 9409  # ICT-FaceKit "Face" region: vertices 0-9408
FACE_POLYGONS = 9230  # and polygons 0-9229
OFFSET_STEP = 2e-4  # cm per int16 step of stored offsets (2 µm; range ±6.5 cm)


def face_region(mesh):
    """The ICT face region of a full-head mesh as (vertices, quads, uvs, quad uvs)."""
    end = mesh.face_starts[FACE_POLYGONS]
    faces = mesh.face_indices[:end].reshape(FACE_POLYGONS, 4)
    fuv = mesh.face_uv_indices[:end].reshape(FACE_POLYGONS, 4)
    used = np.unique(fuv)
    remap = np.full(len(mesh.uvs), -1)
    remap[used] = np.arange(len(used))
    return mesh.vertices[:FACE_VERTICES], faces, mesh.uvs[used], remap[fuv]


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("ict_dir", type=Path)
    ap.add_argument("--out", type=Path, default=Path(__file__).resolve().parent.parent / "assets")
    args = ap.parse_args(argv)
    src = args.ict_dir
    args.out.mkdir(parents=True, exist_ok=True)
    neutral = read_obj(src / "generic_neutral_mesh.obj")
    landmarks = np.array(json.loads((src / "vertex_indices.json").read_text())["idx_to_landmark_verts"])
    V, F, UV, FUV = face_region(neutral)
    np.savez_compressed(args.out / "ict_neutral_face.npz", vertices=V.astype(np.float32), faces=F.astype(np.int32),
                        uvs=UV.astype(np.float32), face_uvs=FUV.astype(np.int32), landmarks=landmarks.astype(np.int32),
                        notice=np.array(ICT_NOTICE))
    names = json.loads((src / "vertex_indices.json").read_text())["expressions"]
    names += [f"identity{i:03d}" for i in range(20)]
    offsets = np.empty((len(names), FACE_VERTICES, 3), np.int16)
    for k, name in enumerate(names):
        d = read_obj(src / f"{name}.obj").vertices[:FACE_VERTICES] - V
        q = np.round(d / OFFSET_STEP)
        if np.abs(q).max() > 32767:
            raise SystemExit(f"{name}: offset too large for int16 at {OFFSET_STEP} cm")
        offsets[k] = q
        print(f"  {name}: max offset {np.abs(d).max():.3f} cm", file=sys.stderr)
    np.savez_compressed(args.out / "ict_shapes.npz", names=np.array(names), offsets=offsets,
                        step_cm=np.array(OFFSET_STEP), notice=np.array(ICT_NOTICE))
    shutil.copyfile(src / "LICENSE", args.out / "ICT-FaceKit-LICENSE.txt")
    # Fit on the float32 copy the package ships, so the model matches what users load.
    V32 = V.astype(np.float32).astype(np.float64)
    T = np.concatenate([F[:, [0, 1, 2]], F[:, [0, 2, 3]]])
    model, sampler = fit_face(V32, T, V32[landmarks], unit="cm", source="ICT-FaceKit generic neutral (face region)")
    model.notice = ICT_NOTICE
    size = save_model(args.out / "default_face.npz", model)
    print(f"default_face.npz: {size} bytes; curve points {sampler.summary()}")
    for p in sorted(args.out.iterdir()):
        print(f"{p.name}: {p.stat().st_size} bytes")


if __name__ == "__main__":
    main()
