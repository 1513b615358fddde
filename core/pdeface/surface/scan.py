"""A scan to fit or pose: a mesh file or a bundled scan, with its 68 landmarks."""
from __future__ import annotations

import numpy as np

from ..assets import DEFAULT, HEAD, load_head, load_neutral_scan
from ..io.meshio import read_mesh
from ..mesh import Mesh
from .frame import landmark_points, read_landmarks


def load_scan(arg, landmarks=None) -> tuple[Mesh, np.ndarray | None]:
    """A scan and its 68 landmark positions from a path, ``"default"`` (the bundled ICT neutral face
    region) or ``"head"`` (the bundled ICT whole head).

    ``landmarks`` is a landmarks JSON file; without one, a path's landmarks are
    None and the bundled scans' are their own.
    """
    if arg in (DEFAULT, HEAD):
        mesh, idx = load_neutral_scan() if arg == DEFAULT else load_head()
        lm = mesh.vertices[idx]
    else:
        mesh, lm = read_mesh(arg), None
    mesh.validate(str(arg))
    if landmarks:
        idx, pts = read_landmarks(landmarks)
        lm = landmark_points(mesh.vertices, idx, pts)
    return mesh, lm
