"""Stimulus images: a face posed with AU weights, seen from a view, rendered by the core's numpy renderer.

A face (an *identity*) is ``default`` (the bundled PDE face), ``head`` (the bundled ICT head with every key on
it), a face model (``.npz``: its PDE face), a head rigged by ``pdeface rig`` (its folder or its ``keys.npz``), or
a ``.blend`` made by the add-on (its rigged head, posed by its shape keys named by AU; read by the worker's own
Blender, :func:`pdeface.headless.blender_here`).
Each is posed as its shape keys are in Blender: the rest mesh plus the sum of each AU key times its weight.
Images are grey, lit from the viewer's side (:func:`pdeface.landmarks.render.shade`), framed on the face's
landmarks at rest, so every pose of an identity is seen through the same camera; the same inputs give the same
pixels. A job's ``lights`` light them with directional lights fixed to the face instead (:data:`LIGHTS`), so a
view turns the camera, not the lights.
"""
from __future__ import annotations

import re
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import numpy as np

from ..assets import DEFAULT, HEAD
from ..au.modelfile import load_face
from ..errors import PdeFaceError
from ..facs import au_number, normalise_weights
from ..head.bind import bind_file
from ..landmarks.render import View, rasterise, shade
from ..posing import pose_curves
from ..rig import load_keys
from ..surface.fit import face_mesh
from ..surface.frame import face_frame
from ..surface.model import model_landmarks
from ..units import ESTIMATED

#: Named views: the yaw (degrees) of the camera about the face's vertical, positive towards the subject's left.
VIEWS = {"front": 0.0, "left": 30.0, "right": -30.0}
_YAW = re.compile(r"^yaw(-?\d+(?:\.\d+)?)$")
#: Named lightings: (direction towards the light in the face frame: x to the subject's left, y up, z to the front;
#: strength). ``front`` is the default one, lit from the viewer's side (:func:`pdeface.landmarks.render.shade`).
LIGHTS = {
    "front": None,
    "studio": [((-0.6, 0.5, 1.0), 0.75), ((0.8, 0.1, 0.8), 0.3), ((0.3, 0.8, -1.0), 0.35)],  # key, fill, rim
    "top": [((0.0, 1.0, 0.3), 0.95)],
    "left": [((1.0, 0.15, 0.35), 0.95)],  # from the subject's left
    "right": [((-1.0, 0.15, 0.35), 0.95)],
}
#: Half the image's width, in units of the landmarks' largest extent at rest.
FRAMING = 0.75


def view_yaw(name: str) -> float:
    """The yaw of a view name: ``front``, ``left``, ``right`` or ``yawDEG`` (e.g. ``yaw45``, ``yaw-20``)."""
    if name in VIEWS:
        return VIEWS[name]
    m = _YAW.match(str(name))
    if not m:
        raise PdeFaceError(f"view {name!r}: use {', '.join(VIEWS)} or yawDEG (e.g. yaw45)")
    return float(m.group(1))


def light_spec(light, where="lights"):
    """``(name, lights)`` of a job's light: a name of :data:`LIGHTS`, or a table ``{direction = [x, y, z],
    strength = s, name = "..."}`` (the name defaults to ``custom``); ``lights`` is what
    :func:`pdeface.landmarks.render.shade` takes (None: the default lighting)."""
    if isinstance(light, str):
        if light not in LIGHTS:
            raise PdeFaceError(f"{where}: light {light!r}: use {', '.join(LIGHTS)} or {{direction, strength}}")
        return light, LIGHTS[light]
    d = light.get("direction") if isinstance(light, dict) else None
    strength = light.get("strength", 1.0) if isinstance(light, dict) else None
    if (not isinstance(d, list) or len(d) != 3 or not all(isinstance(x, (int, float)) for x in d)
            or not any(d) or not isinstance(strength, (int, float)) or not 0 < strength <= 4):
        raise PdeFaceError(f"{where}: light {light!r}: a custom light is {{direction = [x, y, z], strength = 0-4}}")
    name = str(light.get("name", "custom"))
    if not re.fullmatch(r"[\w.+-]+", name):
        raise PdeFaceError(f"{where}: light name {name!r}: letters, digits, '.', '+' and '-' only")
    return name, [(tuple(float(x) for x in d), float(strength))]


@dataclass
class Identity:
    """A face to pose: its rest vertices and triangles in the face frame (mm, looking +z, up +y), and how a pose
    moves them."""

    name: str
    vertices: np.ndarray
    triangles: np.ndarray
    landmarks: np.ndarray
    keys: dict | None = None  # AU key → (n, 3) deltas (face frame), for meshes posed by their shape keys
    model: object = None  # the face model, for a PDE face posed by its curves

    def posed(self, weights: dict) -> np.ndarray:
        """The vertices (face frame) posed with AU ``weights`` (key → weight)."""
        weights = {k: w for k, w in normalise_weights(weights).items() if w}
        if self.model is not None:
            C, R = pose_curves(self.model, weights, "sum")
            mesh = face_mesh(self.model, coefficients=C, residual=R)
            return self.model.frame.to_face(mesh.vertices)
        V = self.vertices.copy()
        for k, w in weights.items():
            if k not in self.keys:
                raise PdeFaceError(f"face {self.name}: no key for AU{k}")
            V += w * self.keys[k]
        return V

    def has(self, key: str) -> bool:
        if self.model is not None:
            return key in {d.key for d in self.model.descriptors}
        return key in self.keys


@lru_cache(maxsize=8)
def load_identity(face: str, aus: tuple = ()) -> Identity:
    """The identity ``face`` (see the module's doc), cached per process: a batch worker binds a head once.

    ``aus`` are the AU keys a job poses (a head's keys are made for those only).
    """
    if is_blend(face):
        from ..headless import blender_here

        data = blender_here().blend_identity(face)
        # the add-on names a key by its AU and what it does ("AU12 Lip Corner Puller")
        keys = {name.split()[0][2:]: d for name, d in zip(data["names"], data["deltas"]) if name.startswith("AU")}
        keys = {k: d for k, d in keys.items() if k in aus or not aus}  # the job's: a head has ~80 keys
        return Identity(face, data["vertices"], data["triangles"], data["landmarks"], keys=keys)
    if face == DEFAULT or (Path(face).is_file() and not _is_keys_file(face)):
        model = load_face(face)
        mesh = face_mesh(model)
        V = model.frame.to_face(mesh.vertices)
        return Identity(face, V, mesh.triangles()[0], model_landmarks(model), model=model)
    if face == HEAD:
        model = load_face(DEFAULT)
        mesh, binding = bind_file(model, HEAD)
        have = {d.key for d in model.descriptors}
        missing = [k for k in aus if k not in have]
        if missing:
            raise PdeFaceError(f"face head: no key for AU{missing[0]}")
        D = binding.pose_displacements([({k: 1.0}, "sum") for k in aus]) if aus else np.zeros((0, 0, 3))
        rest = binding.frame.to_face(mesh.vertices)
        keys = {k: binding.frame.to_face(mesh.vertices + d) - rest for k, d in zip(aus, D)}
        return Identity(face, rest, mesh.triangles()[0], model_landmarks(model), keys=keys)
    path = Path(face)
    keys_file = path / "keys.npz" if path.is_dir() else path
    data = load_keys(keys_file)
    frame = face_frame(data["landmarks"], None if data["unit"] == ESTIMATED else data["unit"])  # older rigs wrote it
    rest = frame.to_face(data["vertices"])
    keys = {}
    for name, d in zip(data["names"], data["deltas"]):
        if name.startswith("AU"):
            keys[name[2:]] = frame.to_face(data["vertices"] + d) - rest
    return Identity(face, rest, data["triangles"], frame.to_face(data["landmarks"]), keys=keys)


def is_blend(face: str) -> bool:
    return str(face).lower().endswith(".blend")


def bound_once(face: str) -> bool:
    """Whether the identity ``face`` is worth preparing once for a whole job (:func:`save_identity`): binding the
    bundled head, or starting Blender to read a ``.blend``, takes seconds each worker would spend again."""
    return face == HEAD or is_blend(face)


def save_identity(identity: Identity, path) -> None:
    """Write an identity posed by its keys to ``path`` (``.npz``, atomically), as :func:`load_saved` reads it."""
    from ..io.files import npz_bytes, write_bytes

    names = sorted(identity.keys)
    deltas = np.stack([identity.keys[k] for k in names]) if names else np.zeros((0, *identity.vertices.shape))
    write_bytes(path, npz_bytes({"format": "pdeface-identity", "name": identity.name, "vertices": identity.vertices,
                                 "triangles": identity.triangles, "landmarks": identity.landmarks,
                                 "names": np.array(names, dtype=str), "deltas": deltas}, compress=False))


@lru_cache(maxsize=8)
def load_saved(path) -> Identity:
    """The identity :func:`save_identity` wrote to ``path`` (cached per process)."""
    from ..io.files import load_npz

    z = load_npz(path, "pdeface-identity", "prepared identity")
    return Identity(str(z["name"]), z["vertices"], z["triangles"], z["landmarks"],
                    keys={str(k): d for k, d in zip(z["names"], z["deltas"])})


def _is_keys_file(path) -> bool:
    """Whether ``path`` is a keys file (``pdeface rig``'s ``keys.npz``) rather than a face model."""
    try:
        with np.load(path, allow_pickle=False) as z:
            return "deltas" in z.files
    except (OSError, ValueError):
        return False  # not an archive: the face model's reader says what it is


def render_identity(identity: Identity, weights: dict, view: str, size: int, samples: int = 1,
                    background: float = 0.0, lights=None) -> np.ndarray:
    """An (size, size, 3) uint8 image of ``identity`` posed with ``weights`` seen from ``view``, lit by
    ``lights`` (see :func:`light_spec`; None: from the viewer's side).

    ``samples`` per pixel (1, 4, 9, ...: a square) are rendered on a finer grid and averaged (anti-aliasing).
    """
    yaw = np.radians(view_yaw(view))
    L = identity.landmarks[np.isfinite(identity.landmarks).all(axis=1)]
    lo, hi = L.min(axis=0), L.max(axis=0)
    sub = max(1, round(float(np.sqrt(samples))))
    camera = View.looking([np.sin(yaw), 0.0, np.cos(yaw)], [0.0, 1.0, 0.0], (lo + hi) / 2,
                          FRAMING * float((hi - lo).max()), size * sub)
    V = identity.posed(weights)
    T = identity.triangles
    img = shade(V, T, rasterise(V, T, camera), background=background, lights=lights).astype(np.float64)
    if sub > 1:
        img = img.reshape(size, sub, size, sub).mean(axis=(1, 3))
    grey = np.round(img).astype(np.uint8)
    return np.repeat(grey[:, :, None], 3, axis=2)


def label_row(weights: dict, aus: list) -> dict:
    """OpenFace's columns for AU ``weights``: ``AUxx_r`` (0-5) and ``AUxx_c`` (0/1) for each AU number of
    ``aus``; an AU's sides (12L, 12R) count as the AU at the larger weight."""
    by_number = {}
    for k, w in normalise_weights(weights).items():
        n = au_number(k)
        by_number[n] = max(by_number.get(n, 0.0), float(w))
    row = {f"AU{n:02d}_r": round(5 * by_number.get(n, 0.0), 3) for n in aus}
    row |= {f"AU{n:02d}_c": int(by_number.get(n, 0.0) > 0) for n in aus}
    return row
