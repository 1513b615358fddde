"""Build the bundled assets from an ICT-FaceKit folder.

Usage: python -m scripts.build.build_assets ICT_DIR [--out assets]
       python -m scripts.build.build_assets --refit-face [--out assets]

Writes, all derived from ICT-FaceKit (MIT, notice copied alongside):
  ict_neutral_face.npz   the neutral face region (vertices 0-9408, cm) with UVs and landmarks
  ict_shapes.npz         the 53 expression shapes and 20 identity meshes as offsets from
                         the neutral face region (int16, OFFSET_STEP cm steps)
  ict_head.npz           the whole generic head (26,719 vertices: face, head and neck, mouth,
                         teeth, eyes, lashes; cm) with UVs, landmarks and ICT's part ranges
  ict_head_shapes.npz    the same 53 shapes and 20 identities for the rest of the head
                         (vertices 9409-26718; the face region's are in ict_shapes.npz)
  default_face.npz       the PDE face model fitted to the neutral (default layout), carrying a
                         descriptor for every AU ICT-FaceKit maps (pdeface.au.ict.AU_SHAPES)
  ICT-FaceKit-LICENSE.txt

``--refit-face`` refits default_face.npz alone from the bundled neutral and shapes (the same
float32 vertices and int16 offsets the full build fits on), after a change to the fit; then run
``build_muscles.py`` (its muscle AUs), ``build_fdts.py`` and ``build_head_prior.py`` again.
"""
from __future__ import annotations

import argparse
import json
import shutil
from pathlib import Path

import numpy as np
from pdeface.assets import ICT_NOTICE
from pdeface.au.capture import fit_descriptor
from pdeface.au.descriptorfile import descriptor_to_bytes
from pdeface.au.ict import APPROXIMATIONS, AU_SHAPES, FACE_VERTICES, NOTICE_SHORT, IctFolder, au_offsets
from pdeface.au.modelfile import load_model, model_nbytes, save_model
from pdeface.facs import key_side
from pdeface.mesh import Mesh
from pdeface.surface.fit import fit_face
from pdeface.surface.sampling import adaptive_resolution, forget_resolution

OFFSET_STEP = 2e-4  # cm per int16 step of stored offsets (2 µm; range ±6.5 cm)


def keep_mesh_steps(path):
    """Choose the default resolution of the model file at ``path`` as it reads back (its curves in the file's
    steps, its kept landmarks) and write it into the file, so meshing it does not choose again; the size. Steps
    the file carries already are chosen again."""
    model = load_model(path)
    forget_resolution(model)
    rows, cols = adaptive_resolution(model)
    print(f"  mesh steps: {sum(rows) + 1} rows × {sum(cols) + 1} columns")
    return save_model(path, model)


def write_default_face(V32, T, landmarks, shapes, out):
    """Fit the PDE face on the neutral (triangles ``T``) and give it a descriptor per AU ICT-FaceKit maps;
    write default_face.npz."""
    model, sampler = fit_face(V32, T, V32[landmarks], unit="cm", source="ICT-FaceKit generic neutral (face region)")
    model.notice = ICT_NOTICE
    for key in AU_SHAPES:
        au, side = key_side(key)
        d = fit_descriptor(model, sampler, V32, V32 + au_offsets(key, shapes), au, side,
                           source="ICT-FaceKit: " + " + ".join(f"{w:g} {n}" for n, w in AU_SHAPES[key].items()),
                           notice=NOTICE_SHORT)
        if key in APPROXIMATIONS:
            d.extra["approximation"] = APPROXIMATIONS[key]
        model.descriptors.append(d)
        span = f"{d.curves.min()}-{d.curves.max()}" if len(d.curves) else "---"
        print(f"  AU{key:4s} curves {span} ({len(d.curves)}), {len(descriptor_to_bytes(d))} bytes")
    save_model(out / "default_face.npz", model)
    size = keep_mesh_steps(out / "default_face.npz")
    print(f"default_face.npz: {size} bytes ({model_nbytes(model)} face model + {len(model.descriptors)} descriptors); "
          f"curve points {sampler.summary()}")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("ict_dir", type=Path, nargs="?")
    ap.add_argument("--refit-face", action="store_true", help="refit default_face.npz alone from the bundled assets")
    ap.add_argument("--out", type=Path, default=Path(__file__).resolve().parents[2] / "assets")
    args = ap.parse_args(argv)
    if args.refit_face:
        from pdeface.assets import load_ict_shapes, load_neutral_scan

        mesh, landmarks = load_neutral_scan()
        write_default_face(mesh.vertices, mesh.triangles()[0], landmarks, load_ict_shapes(), args.out)
        return
    if args.ict_dir is None:
        ap.error("give ICT_DIR, or --refit-face")
    ict = IctFolder(args.ict_dir)
    out = args.out
    out.mkdir(parents=True, exist_ok=True)
    V = ict.vertices
    np.savez_compressed(out / "ict_neutral_face.npz", vertices=V.astype(np.float32), faces=ict.faces.astype(np.int32),
                        uvs=ict.uvs.astype(np.float32), face_uvs=ict.face_uvs.astype(np.int32),
                        landmarks=ict.landmarks.astype(np.int32), notice=np.array(ICT_NOTICE))
    names = json.loads((args.ict_dir / "vertex_indices.json").read_text())["expressions"]
    names += [f"identity{i:03d}" for i in range(20)]
    offsets = np.empty((len(names), len(V), 3), np.int16)
    for k, name in enumerate(names):
        q = np.round(ict.shape(name) / OFFSET_STEP)
        if np.abs(q).max() > 32767:
            raise SystemExit(f"{name}: offset too large for int16 at {OFFSET_STEP} cm")
        offsets[k] = q
    np.savez_compressed(out / "ict_shapes.npz", names=np.array(names), offsets=offsets,
                        step_cm=np.array(OFFSET_STEP), notice=np.array(ICT_NOTICE))
    write_head(args.ict_dir, names, out)
    shutil.copyfile(args.ict_dir / "LICENSE", out / "ICT-FaceKit-LICENSE.txt")
    # Fit on exactly what the package ships (float32 vertices, int16 offsets).
    V32 = V.astype(np.float32).astype(np.float64)
    shapes = {n: offsets[k].astype(np.float64) * OFFSET_STEP for k, n in enumerate(names)}
    write_default_face(V32, Mesh.from_faces(V32, ict.faces).triangles()[0], ict.landmarks, shapes, out)
    for p in sorted(out.iterdir()):
        print(f"{p.name}: {p.stat().st_size} bytes")


def write_head(ict_dir, names, out):
    """The whole generic head and its shapes' offsets beyond the face region."""
    from pdeface.assets import HEAD_PARTS
    from pdeface.io.meshio import read_obj

    head = read_obj(ict_dir / "generic_neutral_mesh.obj")
    landmarks = json.loads((ict_dir / "vertex_indices.json").read_text())["idx_to_landmark_verts"]
    np.savez_compressed(out / "ict_head.npz", vertices=head.vertices.astype(np.float32),
                        face_counts=head.face_counts.astype(np.uint8), faces=head.face_indices.astype(np.int32),
                        uvs=head.uvs.astype(np.float32), face_uvs=head.face_uv_indices.astype(np.int32),
                        landmarks=np.array(landmarks, np.int32), part_names=np.array(list(HEAD_PARTS)),
                        part_starts=np.array(list(HEAD_PARTS.values()), np.int32), notice=np.array(ICT_NOTICE))
    rest = slice(FACE_VERTICES, None)
    offsets = np.empty((len(names), len(head.vertices) - FACE_VERTICES, 3), np.int16)
    for k, name in enumerate(names):
        q = np.round((read_obj(ict_dir / f"{name}.obj").vertices[rest] - head.vertices[rest]) / OFFSET_STEP)
        if np.abs(q).max() > 32767:
            raise SystemExit(f"{name}: offset too large for int16 at {OFFSET_STEP} cm")
        offsets[k] = q
    np.savez_compressed(out / "ict_head_shapes.npz", names=np.array(names), offsets=offsets,
                        step_cm=np.array(OFFSET_STEP), notice=np.array(ICT_NOTICE))


if __name__ == "__main__":
    main()
