"""ICT-FaceKit: its face region and its FACS mapping.

ICT-FaceKit (MIT, (c) 2020 USC Institute for Creative Technologies) ships ARKit
style expression shapes; its README maps FACS AUs to them. This module holds
that table (with left/right variants where ICT has ``_L``/``_R`` shapes; ICT's
``_L`` is the subject's left, +x) and reads an ICT-FaceKit folder.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ..errors import PdeFaceError
from ..facs import split_au_key
from ..io.files import load_json
from ..io.meshio import read_obj
from ..mesh import Mesh

FACE_VERTICES = 9409  # ICT "Face" region: vertices 0-9408
FACE_POLYGONS = 9230  # and polygons 0-9229
NOTICE_SHORT = "ICT-FaceKit (c) 2020 USC Institute for Creative Technologies, MIT License"

_PAIRS = {1: "browInnerUp", 2: "browOuterUp", 4: "browDown", 5: "eyeWide", 6: "cheekSquint", 7: "eyeSquint",
          9: "noseSneer", 11: "mouthUpperUp", 12: "mouthSmile", 14: "mouthDimple", 15: "mouthFrown",
          16: "mouthLowerDown", 20: "mouthStretch", 24: "mouthPress", 33: "cheekPuff", 45: "eyeBlink"}
_SINGLE = {10: ["mouthShrugUpper"], 17: ["mouthShrugLower"], 18: ["mouthPucker"], 22: ["mouthFunnel"],
           27: ["jawOpen"], 28: ["mouthRollLower", "mouthRollUpper"], 29: ["jawForward"],
           61: ["eyeLookOut_L", "eyeLookIn_R"], 62: ["eyeLookOut_R", "eyeLookIn_L"],
           63: ["eyeLookUp_L", "eyeLookUp_R"], 64: ["eyeLookDown_L", "eyeLookDown_R"]}


def _au_shapes() -> dict:
    table = {}
    for au, base in _PAIRS.items():
        table[str(au)] = {f"{base}_L": 1.0, f"{base}_R": 1.0}
        table[f"{au}L"] = {f"{base}_L": 1.0}
        table[f"{au}R"] = {f"{base}_R": 1.0}
    for au, names in _SINGLE.items():
        table[str(au)] = {n: 1.0 for n in names}
    table["30L"] = {"jawLeft": 1.0}
    table["30R"] = {"jawRight": 1.0}
    # ICT has no lips-part or jaw-drop shape: the nearest mixes of its shapes.
    table["25"] = {"jawOpen": 0.2, "mouthLowerDown_L": 0.5, "mouthLowerDown_R": 0.5}
    table["26"] = {"jawOpen": 0.5}
    return table


#: AU key ("12", "12L", "30R") → {ICT shape: weight}.
AU_SHAPES = _au_shapes()
#: Keys whose ICT shapes only approximate the AU.
APPROXIMATIONS = {"25": "0.2 jawOpen + 0.5 mouthLowerDown_L/R (ICT has no lips-part shape)",
                  "26": "0.5 jawOpen (ICT has no jaw-drop shape; jawOpen is closer to AU27)"}


#: ARKit blendshapes that ICT splits into ``_L``/``_R`` shapes but ARKit has once.
ARKIT_UNSIDED = ("browInnerUp", "cheekPuff")


def arkit_name(ict_name: str) -> str:
    """ICT shape name → ARKit blendshape name: ``mouthSmile_L`` → ``mouthSmileLeft``."""
    base, _, side = ict_name.rpartition("_")
    if not base or side not in ("L", "R"):
        return ict_name
    return base if base in ARKIT_UNSIDED else base + ("Left" if side == "L" else "Right")


def _arkit_to_au() -> dict:
    table = {}
    for key, shapes in AU_SHAPES.items():
        if key in APPROXIMATIONS:
            continue
        au, side = split_au_key(key)
        has_sides = not side and f"{au}L" in AU_SHAPES
        for name in shapes:
            arkit = arkit_name(name)
            if arkit in ARKIT_UNSIDED:  # one ARKit shape: the AU as a whole
                if not side:
                    table[arkit.lower()] = [(key, 1.0)]
            elif not has_sides:  # (a pair's shapes go to its sides' keys)
                table.setdefault(arkit.lower(), []).append((key, 1.0 / len(shapes)))
    return table


#: ARKit blendshape (lower case) → [(AU key, share)]: :data:`AU_SHAPES` read backwards; an AU that
#: ICT builds from two shapes (AU28, AU61-64) is the mean of both. The approximations are left out.
ARKIT_TO_AU = _arkit_to_au()


def au_offsets(key: str, shapes: dict) -> np.ndarray:
    """Offsets of AU ``key`` from ICT shape offsets (a mapping ``name → (n, 3)``)."""
    if key not in AU_SHAPES:
        raise PdeFaceError(f"AU{key} has no ICT-FaceKit shapes")
    return sum(w * shapes[name] for name, w in AU_SHAPES[key].items())


def weights_offsets(weights: dict, shapes: dict) -> tuple[np.ndarray, list]:
    """Offsets of AU ``weights`` (key → weight) summed from ICT shapes, and the keys ICT has no shapes for."""
    missing = [k for k in weights if k not in AU_SHAPES]
    total = sum(w * au_offsets(k, shapes) for k, w in weights.items() if k in AU_SHAPES and w)
    if isinstance(total, int):
        raise PdeFaceError(f"none of AU {', '.join(weights)} has ICT-FaceKit shapes")
    return total, missing


def face_region(mesh):
    """The ICT face region of a full-head ICT mesh: (vertices, quads, uvs, quad uv indices)."""
    if len(mesh.vertices) < FACE_VERTICES or len(mesh.face_counts) < FACE_POLYGONS:
        raise PdeFaceError(f"not an ICT-FaceKit head: {len(mesh.vertices)} vertices")
    end = int(mesh.face_counts[:FACE_POLYGONS].sum())
    faces = mesh.face_indices[:end].reshape(FACE_POLYGONS, 4)
    if mesh.face_uv_indices is None:
        return mesh.vertices[:FACE_VERTICES], faces, None, None
    fuv = mesh.face_uv_indices[:end].reshape(FACE_POLYGONS, 4)
    used = np.unique(fuv)
    remap = np.full(len(mesh.uvs), -1)
    remap[used] = np.arange(len(used))
    return mesh.vertices[:FACE_VERTICES], faces, mesh.uvs[used], remap[fuv]


class IctFolder:
    """An ICT-FaceKit folder: the neutral face region, landmarks, shapes as offsets (cm)."""

    def __init__(self, path):

        self.path = Path(path)
        if not (self.path / "generic_neutral_mesh.obj").exists():
            raise PdeFaceError(f"{path}: not an ICT-FaceKit folder (no generic_neutral_mesh.obj)")
        self._read_obj = read_obj
        head = read_obj(self.path / "generic_neutral_mesh.obj")
        self.vertices, self.faces, self.uvs, self.face_uvs = face_region(head)

        data = load_json(self.path / "vertex_indices.json", PdeFaceError)
        try:
            self.landmarks = np.array(data["idx_to_landmark_verts"], dtype=np.int64)
        except (TypeError, KeyError, ValueError) as exc:
            raise PdeFaceError(f"{path}: vertex_indices.json is malformed ({exc})") from None
        self._cache = {}

    def shape(self, name: str) -> np.ndarray:
        """Offset (cm) of one ICT shape or identity mesh from the neutral face region."""
        if name not in self._cache:
            f = self.path / f"{name}.obj"
            if not f.exists():
                raise PdeFaceError(f"{self.path}: missing {f.name}")
            self._cache[name] = self._read_obj(f).vertices[:FACE_VERTICES] - self.vertices
        return self._cache[name]

    def triangles(self) -> np.ndarray:
        """The face region's triangles."""

        return Mesh.from_faces(self.vertices, self.faces).triangles()[0]

    __getitem__ = shape  # a mapping of shape offsets, like the bundled ones
