"""The features of a prediction and its residuals against a target, for either kind of
measurement: an areal map (:mod:`._features`), a profile (:mod:`._profile`) or both arms
of a profile along a diameter (:mod:`._arms`)."""

from __future__ import annotations

from collections.abc import Sequence
from typing import cast

import numpy as np

from ._arms import ArmsPrediction, ArmsTarget, arms_features, arms_residuals
from ._features import Prediction, Target
from ._features import predict_features as _map_features
from ._features import residual_vector as _map_residuals
from ._profile import (ProfilePrediction, ProfileTarget, predict_profile_features,
                       profile_residual_vector)

__all__ = ["features", "residuals"]


def features(z: np.ndarray, target: Target | ProfileTarget | ArmsTarget,
             values: Sequence[float] | np.ndarray | None = None, *,
             measured: bool = False) -> Prediction | ProfilePrediction | ArmsPrediction:
    """:func:`~._features.predict_features` or, for a profile's target,
    :func:`~._profile.predict_profile_features` (each arm's, for both arms')."""
    if isinstance(target, ArmsTarget):
        return arms_features(z, target, values, measured=measured)
    if isinstance(target, ProfileTarget):
        return predict_profile_features(z, target, values, measured=measured)
    return _map_features(z, target, values, measured=measured)


def residuals(pred: Prediction | ProfilePrediction | ArmsPrediction,
              target: Target | ProfileTarget | ArmsTarget
              ) -> tuple[np.ndarray, np.ndarray, dict]:
    """:func:`~._features.residual_vector` or, for a profile's target,
    :func:`~._profile.profile_residual_vector` (``pred``: a prediction of the target's
    own kind, from :func:`features`)."""
    if isinstance(target, ArmsTarget):
        return arms_residuals(cast(ArmsPrediction, pred), target)
    if isinstance(target, ProfileTarget):
        return profile_residual_vector(cast(ProfilePrediction, pred), target)
    return _map_residuals(cast(Prediction, pred), target)
