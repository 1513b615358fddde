"""The bundled data: the default face model and the ICT-FaceKit neutral scan.

Assets are looked up in ``$PDEFACE_ASSETS``, then the repository's
``assets/`` folder, then the copy an installed package carries
(``pdeface/bundled/``). They derive
from ICT-FaceKit (MIT); its notice travels with them.
"""
from __future__ import annotations

import os
from functools import lru_cache
from pathlib import Path

import numpy as np

from .errors import PdeFaceError
from .mesh import Mesh

DEFAULT = "default"
DEFAULT_FACE = "default_face.npz"
NEUTRAL_SCAN = "ict_neutral_face.npz"
LICENSE = "ICT-FaceKit-LICENSE.txt"
#: The notice that models and meshes derived from the bundled data carry in their metadata.
ICT_NOTICE = ("Derived from ICT-FaceKit, Copyright (c) 2020 USC Institute for Creative Technologies, "
              "MIT License (see assets/ICT-FaceKit-LICENSE.txt).")


def assets_dir() -> Path:
    """The folder holding the bundled assets."""
    here = Path(__file__).resolve().parent
    candidates = [os.environ.get("PDEFACE_ASSETS"), here.parent.parent / "assets", here / "bundled"]
    for c in candidates:
        if c and (Path(c) / DEFAULT_FACE).exists():
            return Path(c)
    raise PdeFaceError("bundled assets not found: set PDEFACE_ASSETS or run python -m scripts.build.build_assets")


def asset_path(name: str) -> Path:
    """Path of one bundled asset file."""
    p = assets_dir() / name
    if not p.exists():
        raise PdeFaceError(f"bundled asset {name!r} is missing from {p.parent}")
    return p


def load_neutral_scan() -> tuple[Mesh, np.ndarray]:
    """The ICT-FaceKit neutral face region (cm, ICT frame) and its 68 landmark indices."""
    with np.load(asset_path(NEUTRAL_SCAN), allow_pickle=False) as z:
        faces = z["faces"].astype(np.int64)
        mesh = Mesh.from_faces(z["vertices"].astype(np.float64), faces)
        mesh.uvs = z["uvs"].astype(np.float64)
        mesh.face_uv_indices = z["face_uvs"].astype(np.int64).ravel()
        return mesh, z["landmarks"].astype(np.int64)


LOW_POLY_FACE = "low_poly_face.npz"


def load_low_poly_face() -> tuple[Mesh, np.ndarray]:
    """A game-density face of another topology on a known surface: MediaPipe's 468-point face mesh
    laid on the ICT neutral scan (cm, ICT frame; ``scripts/build/build_low_poly.py``), and its 68
    landmark points (68, 3). Its notice names ICT-FaceKit (MIT) and MediaPipe (Apache-2.0)."""
    with np.load(asset_path(LOW_POLY_FACE), allow_pickle=False) as z:
        mesh = Mesh.from_faces(z["vertices"].astype(np.float64), z["triangles"].astype(np.int64))
        return mesh, z["landmarks"].astype(np.float64)


ICT_SHAPES = "ict_shapes.npz"


def load_ict_shapes() -> dict:
    """ICT-FaceKit expression shapes and identity meshes as offsets (cm) from the neutral face region.

    Keys are ICT names (``mouthSmile_L``, ``jawOpen``, ``identity000`` ...);
    values are (9409, 3) arrays to add to the neutral scan's vertices.
    """
    with np.load(asset_path(ICT_SHAPES), allow_pickle=False) as z:
        step = float(z["step_cm"])
        return {str(n): o.astype(np.float64) * step for n, o in zip(z["names"], z["offsets"])}


HEAD = "head"
ICT_HEAD = "ict_head.npz"
ICT_HEAD_SHAPES = "ict_head_shapes.npz"
#: ICT-FaceKit's parts of its head: name → first vertex (each runs to the next one's start).
HEAD_PARTS = {"face": 0, "head_and_neck": 9409, "mouth_socket": 11248, "eye_socket_left": 13294,
              "eye_socket_right": 13678, "gums_and_tongue": 14062, "teeth": 17039, "eyeball_left": 21451,
              "eyeball_right": 23021, "lacrimal_fluid_left": 24591, "lacrimal_fluid_right": 24795,
              "eye_blend_left": 24999, "eye_blend_right": 25023, "eye_occlusion_left": 25047,
              "eye_occlusion_right": 25199, "eyelashes_left": 25351, "eyelashes_right": 26035}


def load_head() -> tuple[Mesh, np.ndarray]:
    """ICT-FaceKit's whole generic head (cm, ICT frame) with UVs, and its 68 landmark indices."""
    with np.load(asset_path(ICT_HEAD), allow_pickle=False) as z:
        mesh = Mesh(z["vertices"].astype(np.float64), z["face_counts"].astype(np.int64),
                    z["faces"].astype(np.int64))
        mesh.uvs = z["uvs"].astype(np.float64)
        mesh.face_uv_indices = z["face_uvs"].astype(np.int64)
        return mesh, z["landmarks"].astype(np.int64)


def split_head(mesh: Mesh, groups: dict) -> dict:
    """ICT's head (:func:`load_head`) as objects of their own, as heads are usually exported.

    ``groups`` maps an object name to the :data:`HEAD_PARTS` name prefixes it holds
    (``{"Teeth": ("teeth",)}``); a polygon goes with its first vertex's part. Returns
    ``{name: (Mesh, indices of its vertices in mesh)}`` (without UVs).
    """
    starts = np.array(list(HEAD_PARTS.values()))
    names = np.array(list(HEAD_PARTS))
    offsets = np.r_[0, np.cumsum(mesh.face_counts)]
    part = names[np.searchsorted(starts, mesh.face_indices[offsets[:-1]], side="right") - 1]
    out = {}
    for name, prefixes in groups.items():
        keep = np.flatnonzero(np.isin(part, [n for n in names if n.startswith(tuple(prefixes))]))
        polys = [mesh.face_indices[offsets[k]:offsets[k + 1]] for k in keep]
        used = np.unique(np.concatenate(polys))
        remap = np.full(len(mesh.vertices), -1)
        remap[used] = np.arange(len(used))
        out[name] = (Mesh(mesh.vertices[used], mesh.face_counts[keep], remap[np.concatenate(polys)]), used)
    return out


@lru_cache(maxsize=1)
def generic_head_geometry() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """ICT-FaceKit's generic head as the landmark steps' ICT statistics read it: vertices (cm, ICT frame), triangles
    and the 68 landmark indices, read once per process and read-only (six steps each read the file, ~8 ms a time)."""
    mesh, landmarks = load_head()
    V, T = mesh.vertices, mesh.triangles()[0]
    for a in (V, T, landmarks):
        a.flags.writeable = False
    return V, T, landmarks


def load_head_shapes() -> dict:
    """ICT-FaceKit's shapes and identities as offsets (cm) of every vertex of :func:`load_head`."""
    face = load_ict_shapes()
    with np.load(asset_path(ICT_HEAD_SHAPES), allow_pickle=False) as z:
        step = float(z["step_cm"])
        return {str(n): np.concatenate([face[str(n)], o.astype(np.float64) * step])
                for n, o in zip(z["names"], z["offsets"])}


ICT_HEAD_PRIOR = "ict_head_prior.npz"


GENERIC_FDTS = "ict_generic_fdts.json.gz"
