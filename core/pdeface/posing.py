"""Posing a face: AU weights and a mixer → the posed curves.

The one place that chooses between the descriptors' mixers (:func:`pdeface.au.expressions.mix`)
and the muscles' (:func:`pdeface.muscles.aus.muscle_pose`), so it sits above both.
"""
from __future__ import annotations

from .au.expressions import mix
from .facs import normalise_weights
from .muscles.aus import MUSCLE_MIXERS, muscle_pose


def pose_curves(model, weights: dict, mixer: str = "sum"):
    """Coefficients and residual of ``model`` posed with AU ``weights``.

    The ``muscle-*`` mixers combine the AUs' muscle activations (the bundled muscle table's,
    :mod:`pdeface.muscles.aus`) instead of their descriptors.
    """
    if mixer in MUSCLE_MIXERS:
        dC, dR = muscle_pose(model, normalise_weights(weights), mixer)
        return model.coefficients + dC, model.residual + dR
    descriptors = {d.key: d for d in model.descriptors}
    dC, dR = mix(descriptors, normalise_weights(weights), mixer)
    return model.coefficients + dC, model.residual + dR
