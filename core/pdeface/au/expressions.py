"""Mixing descriptors and the linear shape basis.

Mixers combine the descriptors of several AUs per coefficient (the FAS
system's idea): ``sum`` (default, linear: Σ wᵢ Dᵢ), ``average`` (each
coefficient's sum divided by how many weighted AUs act on that curve) and
``max`` (each coefficient from the weighted AU with the largest magnitude).
Weights are clamped to [0, 1]; FACS letters A-E are accepted (see
:mod:`pdeface.facs`). Presets and the mixers' names live in :mod:`pdeface.presets`;
posing a face with any mixer, the muscles' included, in :mod:`pdeface.posing`.
"""
from __future__ import annotations

import numpy as np

from ..errors import PdeFaceError
from ..facs import clamp_weights, normalise_weights, parse_weight, split_au_key
from ..presets import MIXERS
from ..surface.fit import face_mesh
from ..surface.grid import key_grids
from ..surface.sampling import mesh_resolution
from .descriptor import no_descriptors


def mix(descriptors: dict, weights: dict, mixer: str = "sum") -> tuple[np.ndarray, np.ndarray]:
    """Combine weighted descriptors into one change of coefficients and residual.

    Parameters
    ----------
    descriptors : dict
        AU key → :class:`~pdeface.au.descriptor.Descriptor` (one layout).
    weights : dict
        AU key → weight; keys must be in ``descriptors``.
    mixer : {'sum', 'average', 'max'}

    Returns
    -------
    dC : (K, N+1, 3) array
    dR : (K, J, 3) array
    """
    if mixer not in MIXERS:
        raise PdeFaceError(f"unknown mixer {mixer!r}; use one of {', '.join(MIXERS)}")
    if mixer.startswith("muscle-"):
        raise PdeFaceError(f"the {mixer} mixer mixes muscle activations: pose the face with pose_curves")
    if not descriptors:
        raise PdeFaceError(no_descriptors())
    layout = next(iter(descriptors.values())).layout
    K, J, N = layout
    dC, dR = np.zeros((K, N + 1, 3)), np.zeros((K, J, 3))
    count = np.zeros(K)
    for key, w in weights.items():
        w = parse_weight(w, f"AU{key}")
        if key not in descriptors:
            raise PdeFaceError(f"AU{key} has no descriptor in this face (has: {', '.join(sorted(descriptors, key=split_au_key))})")
        d = descriptors[key]
        if d.layout != layout:
            raise PdeFaceError(f"AU{key}: descriptor layout {d.layout} differs from {layout}")
        if w == 0:
            continue
        C, R = d.dense()
        C, R = w * C, w * R
        if mixer == "max":
            np.copyto(dC, C, where=np.abs(C) > np.abs(dC))
            np.copyto(dR, R, where=np.abs(R) > np.abs(dR))
        else:
            dC += C
            dR += R
        count[d.curves] += 1
    if mixer == "average":
        div = np.maximum(count, 1)[:, None, None]
        dC, dR = dC / div, dR / div
    return dC, dR



class ShapeBasis:
    """The posed face as a linear function of AU weights (``sum`` mixer).

    ``vertices(W) = neutral + W @ deltas``: one matrix product per batch of
    faces, in the source mesh's space, same vertex order as
    :func:`pdeface.surface.fit.face_mesh`. This is what Blender shape keys are.
    """

    def __init__(self, model, resolution="default", assembly=None, dtype=np.float32):
        su, sv = mesh_resolution(model, resolution)
        self.keys = [d.key for d in model.descriptors]
        self.neutral = face_mesh(model, (su, sv), assembly).vertices
        n = len(model.descriptors)
        # Stored vertex-major (column-major deltas): sgemm with the short AU axis innermost is fastest.
        self._deltas_t = np.empty((self.neutral.size, n), dtype)
        for first, grids in key_grids(model, su, sv, assembly):  # a few AUs per solve: float64 only meanwhile
            D = model.frame.to_user_vectors(grids.reshape(-1, grids.shape[2], 3))  # (vertices, m, 3)
            self._deltas_t[:, first:first + grids.shape[2]] = D.transpose(0, 2, 1).reshape(-1, grids.shape[2])
        self.neutral_flat = self.neutral.ravel().astype(dtype)

    @property
    def deltas(self) -> np.ndarray:
        """(n_keys, n_vertices * 3) vertex offsets of each AU at weight 1."""
        return self._deltas_t.T

    def weights_matrix(self, weights: dict) -> np.ndarray:
        """One row of weights in :attr:`keys` order."""
        w = np.zeros(len(self.keys), dtype=self.deltas.dtype)
        for k, v in normalise_weights(weights).items():
            if k not in self.keys:
                raise PdeFaceError(f"AU{k} has no descriptor in this face")
            w[self.keys.index(k)] = v
        return w

    def vertices(self, W: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
        """Faces for weight rows ``W (B, n_keys)`` → (B, n_vertices, 3).

        ``out`` (B, n_vertices * 3), when given, is filled and reused, which
        keeps batch evaluation allocation-free.
        """
        W = clamp_weights(np.atleast_2d(np.asarray(W, dtype=self._deltas_t.dtype)))
        if out is None:
            out = np.empty((len(W), self._deltas_t.shape[0]), dtype=self._deltas_t.dtype)
        np.matmul(W, self.deltas, out=out)
        out += self.neutral_flat
        return out.reshape(len(W), -1, 3)
