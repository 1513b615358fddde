"""Texture coordinates for a PDE face.

``transfer_uvs`` copies the source scan's UVs by closest point, as the method
textures its PDE faces (here interpolated barycentrically inside the closest
source triangle rather than taken from the nearest vertex). ``atlas_uvs``
unwraps the PDE face afresh with xatlas.
"""
from __future__ import annotations

import numpy as np

from ..errors import MeshError, PdeFaceError
from ..geometry import ClosestPoint


def transfer_uvs(points, src_vertices, src_triangles, src_corner_uvs) -> tuple[np.ndarray, np.ndarray]:
    """UVs at ``points`` from the closest place on a source mesh.

    Parameters
    ----------
    points : (p, 3) array
        Where UVs are wanted (PDE vertices), same space as the source.
    src_vertices : (n, 3) array
    src_triangles : (t, 3) int array
    src_corner_uvs : (t, 3, 2) array
        UV of each triangle corner (UV seams allowed).

    Returns
    -------
    uv : (p, 2) array
    distance : (p,) array
        How far each point is from the source surface.
    """
    src_corner_uvs = np.asarray(src_corner_uvs, dtype=np.float64)
    if src_corner_uvs.shape != (len(src_triangles), 3, 2):
        raise MeshError(f"source corner UVs must be ({len(src_triangles)}, 3, 2), got {src_corner_uvs.shape}")
    d, tri, bary, _ = ClosestPoint(src_vertices, src_triangles).query(points)
    return np.einsum("pk,pkc->pc", bary, src_corner_uvs[tri]), d


def atlas_uvs(vertices, faces) -> np.ndarray:
    """A fresh UV atlas (xatlas) for polygons ``faces (m, k)``; per-corner UVs (m, k, 2).

    Polygons are fanned into triangles for xatlas; each corner takes the UV
    of the first triangle that holds it.
    """
    try:
        import xatlas
    except ImportError:
        raise PdeFaceError("a fresh atlas needs xatlas: pip install xatlas") from None
    F = np.asarray(faces, dtype=np.int64)
    m, k = F.shape
    tris = np.concatenate([F[:, [0, j, j + 1]] for j in range(1, k - 1)])
    vmap, idx, uv = xatlas.parametrize(np.asarray(vertices, np.float32), tris.astype(np.uint32))
    corner_uv = uv[idx].reshape(k - 2, m, 3, 2)
    out = np.zeros((m, k, 2))
    out[:, 0] = corner_uv[0, :, 0]
    for j in range(1, k - 1):
        out[:, j] = corner_uv[j - 1, :, 1]
    out[:, k - 1] = corner_uv[k - 3, :, 2]
    return out
