"""Spiral cutting-contact points (CCPs): constant angle, constant arc length, hybrid.

The spiral is Archimedean and runs inward: rho(theta) = r_outer - f_rev theta / (2 pi),
theta cumulative from 0 (Li et al. 2018 [1]_).  The spindle turns at constant speed, so the
time of a point is t = theta / omega whatever the sampling (a PVT controller takes the
uneven time steps of the arc-length samplings).  The hybrid sampling and the chordal-error
bound are those of the compound sinusoidal grid paper [2]_.

References
----------
.. [1] D. Li, Z. Qiao, K. Walton, Y. Liu, J. Xue, B. Wang, X. Jiang, "Theoretical and
       experimental investigation of surface topography generation in slow tool servo
       ultra-precision machining of freeform surfaces," Materials 11(12), 2566 (2018).
       :DOI:`10.3390/ma11122566`
.. [2] "Compound sinusoidal grid surface" machined by slow tool servo diamond turning
       (the project's copy lacks authors, journal and year: docs/references.md).
"""

from __future__ import annotations

from typing import Any
import math

import numpy as np

from ..core import trig
from ..core.errors import InputError, check_range

TWO_PI = 2 * math.pi

__all__ = ["spiral_ccps", "chordal_step_for", "chordal_error", "heights_along", "SAMPLINGS",
           "TWO_PI", "BLOCK"]


def _arc_theta(r_start: float, c: float, s: np.ndarray) -> np.ndarray:
    """theta at arc length s along rho = r_start - c theta (circumferential arc only)."""
    # s(theta) = r_start theta - c theta^2 / 2  ->  theta = (r_start - sqrt(r_start^2 - 2 c s)) / c
    disc = np.maximum(r_start * r_start - 2 * c * s, 0.0)
    return (r_start - np.sqrt(disc)) / c


SAMPLINGS = ("constant_angle", "constant_arc", "hybrid")
#: a last step shorter than this fraction of the first is a duplicate end point
_DUPLICATE_RTOL = 1e-9  # not a unit conversion


def _subdivide(th: np.ndarray, steps: np.ndarray, reps: np.ndarray) -> np.ndarray:
    """Split step i of ``th`` into ``reps[i]`` equal steps (vectorised; the values of
    ``np.linspace(th[i], th[i+1], reps[i] + 1)[1:]``, the interval's end exactly)."""
    i = np.repeat(np.arange(steps.size), reps)
    ends = np.cumsum(reps)
    j = np.arange(1, int(ends[-1]) + 1) - np.repeat(ends - reps, reps)
    out = th[i] + j * (steps[i] / reps[i])
    out[ends - 1] = th[1:]
    return np.concatenate([th[:1], out])


def spiral_ccps(*, feed_per_rev: float, r_outer: float, r_inner: float = 0.0,
                sampling: str = "constant_angle", points_per_rev: int = 3600,
                arc_length: float = 0.005, switch_radius: float = 1.0
                ) -> tuple[np.ndarray, np.ndarray]:
    """CCP angles (cumulative, rad) and radii (mm) of the inward spiral.

    Parameters
    ----------
    feed_per_rev : float
        f, mm per revolution (the spiral pitch).
    r_outer, r_inner : float
        mm; the spiral runs from ``r_outer`` to ``r_inner`` (inclusive).
    sampling : {"constant_angle", "constant_arc", "hybrid"}
        Constant angle (``points_per_rev`` per revolution), constant arc length
        (``arc_length`` mm apart), or hybrid: constant arc length outside
        ``switch_radius``, constant angle inside (the compound sinusoidal grid paper).
    points_per_rev : int
    arc_length, switch_radius : float, mm

    Returns
    -------
    theta, rho : (n,) float64
    """
    f = float(feed_per_rev)
    check_range("feed_per_rev", f, 0.0, None, lo_open=True)
    check_range("r_outer", r_outer, 0.0, None, lo_open=True)
    if not 0 <= r_inner < r_outer:
        raise InputError(f"r_inner must be in [0, r_outer={r_outer}), received {r_inner}")
    if sampling not in SAMPLINGS:
        raise InputError(f"sampling must be one of {SAMPLINGS}, received {sampling!r}")
    N = int(points_per_rev)
    ds = float(arc_length)
    c = f / TWO_PI
    theta_end = (r_outer - r_inner) / c
    mode = sampling
    if mode == "constant_angle":
        n = int(math.ceil(theta_end / (TWO_PI / N)))
        theta = np.arange(n + 1, dtype=np.float64) * (TWO_PI / N)
        theta[-1] = min(theta[-1], theta_end)
    else:
        r_sw = r_inner if mode == "constant_arc" else min(max(switch_radius, r_inner), r_outer)
        # arc-length part from r_outer down to r_sw; the angular step is capped at 2 pi / 8
        theta_sw = (r_outer - r_sw) / c
        s_total = r_outer * theta_sw - c * theta_sw ** 2 / 2
        n_arc = int(math.ceil(s_total / ds))
        th_arc = _arc_theta(r_outer, c, np.linspace(0.0, s_total, n_arc + 1))
        max_step = TWO_PI / 8
        steps = np.diff(th_arc)
        if np.any(steps > max_step):  # near the axis: subdivide the long steps
            th_arc = _subdivide(th_arc, steps, np.maximum(1, np.ceil(steps / max_step).astype(np.int64)))
        if mode == "constant_arc" or theta_sw >= theta_end:
            theta = th_arc
        else:
            dth = TWO_PI / N
            n_in = int(math.ceil((theta_end - theta_sw) / dth))
            th_in = theta_sw + dth * np.arange(1, n_in + 1)
            th_in[-1] = min(th_in[-1], theta_end)
            theta = np.concatenate([th_arc, th_in])
    if theta.size > 2 and theta[-1] - theta[-2] < _DUPLICATE_RTOL * (theta[1] - theta[0]):
        theta = theta[:-1]  # the end clamp left a duplicate point
    rho = r_outer - c * theta
    rho = np.maximum(rho, r_inner)
    return theta, rho


def chordal_step_for(tolerance: float, radius_of_curvature: float) -> float:
    """Largest CCP spacing L whose chord stays within ``tolerance`` of a section of radius
    R' (the compound sinusoidal grid paper): L = sqrt(8 R' h - 4 h^2)."""
    h, R = float(tolerance), abs(float(radius_of_curvature))
    if not np.isfinite(R) or R <= 0:
        return math.inf
    return math.sqrt(max(8 * R * h - 4 * h * h, 0.0))


#: points of a path evaluated at a time: the arrays of one block and the design's own
#: temporaries stay in the processor's cache (the values do not depend on it)
BLOCK = 16384


def _float64(h: Any, n: int) -> bool:
    return isinstance(h, np.ndarray) and h.dtype == np.float64 and h.shape == (n,)


def heights_along(surface: Any, rho: np.ndarray, cs: np.ndarray, sn: np.ndarray) -> np.ndarray:
    """The design's heights at the points (rho cos, rho sin) of a path (``cs``, ``sn``:
    the cosines and sines of its angles), :data:`BLOCK` points at a time: the same
    numbers as ``surface.height(rho * cs, rho * sn)``, and the design's own error for
    the whole path where it fails."""
    n = rho.size
    if n <= BLOCK:
        return surface.height(rho * cs, rho * sn)
    out = np.empty(n)
    try:
        for a in range(0, n, BLOCK):
            b = min(a + BLOCK, n)
            h = surface.height(rho[a:b] * cs[a:b], rho[a:b] * sn[a:b])
            if not _float64(h, b - a):  # (a design of other heights: as it gives them)
                return surface.height(rho * cs, rho * sn)
            out[a:b] = h
    except InputError:
        surface.height(rho * cs, rho * sn)  # (its message tells of the whole path)
        raise
    return out


def chordal_error(surface: Any, theta: np.ndarray, rho: np.ndarray,
                  z_ccp: np.ndarray) -> np.ndarray:
    """Linearisation error at each segment's midpoint: |F(mid) - (z_i + z_{i+1}) / 2|, mm.

    The axes interpolate linearly in (C, X, Z), so the mid-point lies on the spiral at the
    mean angle and radius.  (Evaluated :data:`BLOCK` segments at a time.)"""
    n = theta.size - 1
    if n > BLOCK:
        out = np.empty(n)
        try:
            for a in range(0, n, BLOCK):
                b = min(a + BLOCK, n)
                tm = 0.5 * (theta[a + 1:b + 1] + theta[a:b])
                rm = 0.5 * (rho[a + 1:b + 1] + rho[a:b])
                cs, sn = trig.cos_sin(tm)
                zm = surface.height(rm * cs, rm * sn)
                if not _float64(zm, b - a):
                    break
                out[a:b] = np.abs(zm - 0.5 * (z_ccp[a + 1:b + 1] + z_ccp[a:b]))
            else:
                return out
        except InputError:
            pass  # (the error again, over the whole path, below)
    tm = 0.5 * (theta[1:] + theta[:-1])
    rm = 0.5 * (rho[1:] + rho[:-1])
    cs, sn = trig.cos_sin(tm)
    zm = surface.height(rm * cs, rm * sn)
    return np.abs(zm - 0.5 * (z_ccp[1:] + z_ccp[:-1]))
