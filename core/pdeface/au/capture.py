"""AU descriptors from scans: an AU mesh against the neutral the face was fitted to.

Same topology: the curves' material points are read off the AU mesh exactly.
Other topology (a scan of the same person): the AU mesh is aligned on the
feature points the AU does not move, then the neutral's curve points are
projected onto it.
"""
from __future__ import annotations

import numpy as np

from ..errors import LandmarkError, PdeFaceError
from ..geometry import similarity
from ..landmark_scheme import FEATURE_NAMES
from ..surface.frame import feature_points
from .descriptor import Descriptor, descriptor_from_points

#: Feature points each AU group moves (the method's Table 5-6 idea); the others anchor the alignment.
_BROWS = ["brow_outer_right", "brow_inner_right", "brow_inner_left", "brow_outer_left"]
_EYES = ["eye_outer_right", "eye_inner_right", "eye_inner_left", "eye_outer_left"]
_NOSE = ["nose_wing_right", "nose_wing_left", "nose_bottom"]
_MOUTH = ["mouth_corner_right", "lip_upper", "mouth_corner_left", "lip_center", "lip_lower", "chin"]
MOVED_FEATURES = {1: _BROWS, 2: _BROWS, 4: _BROWS, 5: _BROWS + _EYES, 6: _EYES + _NOSE, 7: _EYES,
                  9: _BROWS[1:3] + _NOSE + _MOUTH, 10: _NOSE + _MOUTH, 11: _NOSE + _MOUTH}
for _au in (41, 42, 43, 44, 45, 46, 61, 62, 63, 64):
    MOVED_FEATURES[_au] = _BROWS + _EYES


def moved_features(au: int) -> list:
    """Names of the feature points AU ``au`` moves (mouth and nose for lower-face AUs)."""
    return MOVED_FEATURES.get(int(au), _NOSE + _MOUTH)


def rigid_align(src: np.ndarray, dst: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """Rotation R and translation t minimising |R src + t - dst|; and the RMS residual."""

    _, R, t = similarity(src, dst, scale=False)
    rms = float(np.sqrt(((src @ R.T + t - dst) ** 2).sum(1).mean()))
    return R, t, rms


def align_to_neutral(model, au_vertices, au_landmarks, au: int, max_rms_mm: float = 4.0) -> np.ndarray:
    """Bring a scan of the same person (other topology) into the neutral's face frame.

    The AU scan's feature points that the AU does not move are aligned
    rigidly to the neutral's. Returns the AU vertices in the face frame (mm).

    Raises
    ------
    LandmarkError
        When the alignment residual exceeds ``max_rms_mm``: not the same
        person, or landmarks in another order.
    """

    F_au = model.frame.to_face(feature_points(au_landmarks))
    moved = set(moved_features(au))
    anchor = np.array([n not in moved for n in FEATURE_NAMES])
    R, t, rms = rigid_align(F_au[anchor], model.features[anchor])
    if rms > max_rms_mm:
        raise LandmarkError(
            f"the AU mesh does not align with the neutral face (residual {rms:.1f} mm over "
            f"{anchor.sum()} unmoved feature points, limit {max_rms_mm} mm): is it the same person, "
            "with landmarks in the same order?")
    return model.frame.to_face(au_vertices) @ R.T + t


def fit_descriptor(model, sampler, neutral_vertices, au_vertices, au, side="both", au_triangles=None,
                   au_landmarks=None, source="", notice="") -> Descriptor:
    """Descriptor of an AU mesh against the neutral mesh the model was fitted to.

    With the neutral's topology (same vertex count, no ``au_triangles``) the
    curve material points are read off the AU mesh exactly. Otherwise the AU
    mesh is aligned on the feature points the AU does not move (needs
    ``au_landmarks``) and the neutral's curve points are projected onto it.
    """
    neutral_points = sampler.sample(model.frame.to_face(neutral_vertices))
    au_vertices = np.asarray(au_vertices, np.float64)
    if not np.isfinite(au_vertices).all():
        raise PdeFaceError("AU mesh has NaN or inf vertices")
    if au_triangles is None:
        if len(au_vertices) != len(neutral_vertices):
            raise PdeFaceError(f"AU mesh has {len(au_vertices)} vertices, the neutral {len(neutral_vertices)}: "
                               "give its triangles and landmarks to project instead")
        au_points = sampler.sample(model.frame.to_face(au_vertices))
    else:
        if au_landmarks is None:
            raise LandmarkError("an AU mesh of another topology needs its own 68 landmarks for the alignment")

        from ..surface.curves import project_samples  # scipy: loaded only when a mesh is projected
        Vf = align_to_neutral(model, au_vertices, au_landmarks, au)
        au_points = project_samples(neutral_points, Vf, np.asarray(au_triangles), sampler.status,
                                    sampler.groove_mix).sample(Vf)
    return descriptor_from_points(neutral_points, au_points, au, side, model.n_modes, source, notice)
