"""The harmonic term of the misfit, for an areal map and a profile alike: the feed marks'
fundamental and the amplitudes of its harmonics, predicted against measured."""

from __future__ import annotations

from typing import Protocol, cast

import numpy as np

__all__ = ["harmonic_residuals"]


class _HarmonicTarget(Protocol):
    """What the harmonic term reads of a target (a map's :class:`Target` or a profile's)."""

    @property
    def centroid(self) -> float | None: ...
    @property
    def amplitudes(self) -> np.ndarray: ...
    @property
    def sigma_frequency(self) -> float | None: ...
    @property
    def sigma_amplitudes(self) -> np.ndarray | None: ...


class _HarmonicPrediction(Protocol):
    """What the harmonic term reads of a prediction (a map's or a profile's)."""

    @property
    def centroid(self) -> float | None: ...
    @property
    def amplitudes(self) -> np.ndarray: ...


class _HarmonicSpec(Protocol):
    """The harmonic term's scales of a :class:`MisfitSpec` (or a profile's spec)."""

    @property
    def sigma_frequency(self) -> float: ...
    @property
    def sigma_amplitude(self) -> float: ...


def harmonic_residuals(target: _HarmonicTarget, pred: _HarmonicPrediction,
                       spec: _HarmonicSpec) -> np.ndarray:
    """The harmonic term's residuals (maps and profiles): the fundamental's relative shift
    and each harmonic's amplitude difference, in their sigmas."""
    sf = target.sigma_frequency or spec.sigma_frequency
    if pred.centroid is None or not np.isfinite(pred.centroid):
        df = 1.0 / sf
    else:
        # (the term is used where the target has marks: its centroid is set)
        df = (pred.centroid / cast(float, target.centroid) - 1.0) / sf
    sa: np.ndarray | float | None = target.sigma_amplitudes
    if sa is None:
        sa = spec.sigma_amplitude * max(float(target.amplitudes[0]), 1e-12)
    return np.concatenate([[df], (pred.amplitudes - target.amplitudes) / sa])
