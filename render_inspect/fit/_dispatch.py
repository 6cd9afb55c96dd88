"""The features of a prediction and its residuals against a target, for either kind of
measurement: an areal map (:mod:`._features`) or a profile (:mod:`._profile`)."""

from __future__ import annotations

from ._features import predict_features as _map_features
from ._features import residual_vector as _map_residuals
from ._profile import ProfileTarget, predict_profile_features, profile_residual_vector
from ._arms import ArmsTarget, arms_features, arms_residuals

__all__ = ["features", "residuals"]


def features(z, target, values=None, *, measured: bool = False):
    """:func:`~._features.predict_features` or, for a profile's target,
    :func:`~._profile.predict_profile_features`."""
    if isinstance(target, ArmsTarget):
        return arms_features(z, target, values, measured=measured)
    if isinstance(target, ProfileTarget):
        return predict_profile_features(z, target, values, measured=measured)
    return _map_features(z, target, values, measured=measured)


def residuals(pred, target):
    """:func:`~._features.residual_vector` or, for a profile's target,
    :func:`~._profile.profile_residual_vector`."""
    if isinstance(target, ArmsTarget):
        return arms_residuals(pred, target)
    if isinstance(target, ProfileTarget):
        return profile_residual_vector(pred, target)
    return _map_residuals(pred, target)
