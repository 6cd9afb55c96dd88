"""What the cutting-mechanics kernel (:mod:`._cut_kernel`) takes besides the path: the
random Fourier modes of the edge's grooves, the cutting distance along the path and the
radial window of the passes that can take part in a pixel's cut."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..core.errors import check_range

__all__ = ["Grooves", "cutting_distance", "mechanics_window"]

TWO_PI = 2 * math.pi


def cutting_distance(theta: np.ndarray, rho: np.ndarray) -> np.ndarray:
    """Cumulative cutting distance (mm) along a turning path at its points: the arc length
    of the tool's circle, sum 0.5 (|rho_i| + |rho_(i+1)|) (theta_(i+1) - theta_i)."""
    th = np.asarray(theta, dtype=np.float64)
    r = np.abs(np.asarray(rho, dtype=np.float64))
    return np.concatenate([[0.0], np.cumsum(0.5 * (r[1:] + r[:-1]) * np.diff(th))])


def mechanics_window(nose_radius: float, f: float, slope: float, h_min: float,
                     half_width: float) -> float:
    """Radial window (mm) of the passes that can take part in a pixel's cut: the geometric
    window 2.1 Rc m + f / 2 widened by one feed (the cusp's pass is always visited) and by
    the ploughed band h_min 4 Rc / f."""
    return min(half_width, 2.1 * nose_radius * slope + 1.5 * f + h_min * 4 * nose_radius / max(f, 1e-12)
               + 1e-9)


@dataclass(frozen=True)
class Grooves:
    """The random Fourier modes of :func:`~render_inspect.machining.groove_texture`
    (the same draws from the same seed) and the scale rms sqrt(2 / modes)."""

    ku: np.ndarray
    kv: np.ndarray
    ph: np.ndarray
    scale: float

    @classmethod
    def of(cls, *, rms: float, seed: int, across_length: float = 0.001, along_length: float = 0.05,
           modes: int = 128) -> "Grooves":
        check_range("rms", rms, 0.0, 1.0)
        check_range("across_length", across_length, 0.0, None, lo_open=True)
        check_range("along_length", along_length, 0.0, None, lo_open=True)
        if rms == 0:
            z = np.zeros(0)
            return cls(z, z, z, 0.0)
        rng = np.random.default_rng(seed)
        ku = rng.normal(0.0, 1.0 / across_length, size=modes)
        kv = rng.normal(0.0, 1.0 / along_length, size=modes)
        ph = rng.uniform(0.0, TWO_PI, size=modes)
        return cls(ku, kv, ph, rms * math.sqrt(2.0 / modes))

    @classmethod
    def none(cls) -> "Grooves":
        return cls.of(rms=0.0, seed=0)
