"""Residual (scallop) height between neighbouring passes on curved sections, and the
largest feed that keeps it within a bound (the compound sinusoidal grid paper [1]_,
eqs. 9-13).

Geometry.  A section of radius R is cut by a nose of radius r whose centres, one feed
apart, lie on the offset curve at distance r; ``feed`` f is the distance between
neighbouring tool centres (the chord, as in the paper).  With u = (f / 2)^2,
s = sqrt(r^2 - u) and the signed curvature k = 1 / R (k > 0 convex: the section bulges
towards the tool; k < 0 concave, |R| > r; k = 0 flat):

    convex   H = sqrt((R + r)^2 - u) - s - R              (eq. 11)
    concave  H = |R| - sqrt((|R| - r)^2 - u) - s          (eq. 10)
    flat     H = r - s                                    (eq.  9)

all three are the single expression, free of cancellation for small k,

    H = 2 (r - s) / (1 + k s + sqrt((1 + k r)^2 - k^2 u)),

and its inverse (eq. 12, f1 - f3) is

    c = (2 (r - H) - k H^2) / (2 (1 + k H)),    f = 2 sqrt(r^2 - c^2).

For a given spacing of the tool centres a concave section leaves the largest scallop
(the centres lie on a circle smaller than the section), a convex one the smallest.
The planner (:func:`plan_feed`) samples the radial sections of a surface, takes at each
point the largest feed meeting the bound and converts it to the X spacing per revolution
(feed per rev = f cos(phi), phi the radial slope angle: the tool centres step f along the
section); the result is the minimum over the points (eq. 13).

References
----------
.. [1] "Compound sinusoidal grid surface" machined by slow tool servo diamond turning
       (the project's copy lacks authors, journal and year: docs/references.md).
"""

from __future__ import annotations

from typing import Any
from collections.abc import Iterable
import math

import numpy as np

from ..core.errors import InputError, check_range
from ..core.units import MM_TO_NM

__all__ = ["scallop_height", "feed_for_scallop", "max_feed_for_scallop", "plan_feed"]


def _check_k(k, r):
    k = np.asarray(k, dtype=np.float64)
    if np.any(k * r <= -1.0):
        bad = float(np.min(k))
        raise InputError(f"a concave section needs a radius larger than the nose radius {r} mm; "
                         f"curvature {bad:.6g} 1/mm (radius {-1 / bad:.6g} mm) is too tight")
    return k


def scallop_height(feed: np.ndarray | float, nose_radius: float,
                   curvature: np.ndarray | float = 0.0) -> np.ndarray:
    """Residual height H (mm) between passes ``feed`` mm apart.

    Parameters
    ----------
    feed : array_like, mm (0 <= f <= 2 r)
    nose_radius : float, mm
    curvature : array_like, 1/mm
        Signed section curvature k = 1 / R: > 0 convex (towards the tool), < 0 concave.

    Returns
    -------
    ndarray (broadcast of ``feed`` and ``curvature``), mm
    """
    r = float(check_range("nose_radius", nose_radius, 0.0, None, lo_open=True))
    f = np.asarray(feed, dtype=np.float64)
    if np.any(f < 0) or np.any(f > 2 * r):
        raise InputError(f"feed must be in [0, 2 x nose_radius = {2 * r}] mm, received "
                         f"{float(np.min(f))} .. {float(np.max(f))}")
    k = _check_k(curvature, r)
    u = 0.25 * f * f
    s = np.sqrt(r * r - u)
    return 2 * (r - s) / (1 + k * s + np.sqrt((1 + k * r) ** 2 - k * k * u))


def feed_for_scallop(height: np.ndarray | float, nose_radius: float,
                     curvature: np.ndarray | float = 0.0) -> np.ndarray:
    """Largest distance f (mm) between tool centres that leaves the residual ``height``
    (mm, 0 <= H < r) on a section of signed ``curvature`` (1/mm): eq. 12 of the compound
    sinusoidal grid paper."""
    r = float(check_range("nose_radius", nose_radius, 0.0, None, lo_open=True))
    H = np.asarray(height, dtype=np.float64)
    if np.any(H < 0) or np.any(H >= r):
        raise InputError(f"scallop height must be in [0, nose_radius = {r}) mm, received "
                         f"{float(np.min(H))} .. {float(np.max(H))}")
    k = _check_k(curvature, r)
    c = (2 * (r - H) - k * H * H) / (2 * (1 + k * H))
    return 2 * np.sqrt(np.maximum(r * r - c * c, 0.0))


def max_feed_for_scallop(height: float, nose_radius: float,
                         curvatures: Iterable[float] = (0.0,)) -> float:
    """f <= min over ``curvatures`` of :func:`feed_for_scallop` (the compound sinusoidal
    grid paper, eq. 13), mm."""
    k = np.atleast_1d(np.asarray(curvatures, dtype=np.float64))
    if k.size == 0:
        raise InputError("curvatures must hold at least one value")
    return float(np.min(feed_for_scallop(height, nose_radius, k)))


def plan_feed(surface: Any, *, nose_radius: float, scallop_bound: float, r_outer: float,
              r_inner: float = 0.0, n_radii: int = 64, n_angles: int = 72,
              spindle_rpm: float | None = None) -> dict:
    """The largest feed per revolution keeping the scallop within ``scallop_bound``
    everywhere on the radial sections between ``r_inner`` and ``r_outer``.

    Parameters
    ----------
    surface : object with ``section_curvature(x, y, direction)`` and
        ``radial_slope(rho, theta)`` (a design Surface)
    nose_radius, scallop_bound, r_outer, r_inner : float, mm
    n_radii, n_angles : int
        Sampling of the radial sections (radii uniform in (r_inner, r_outer], angles
        uniform in [0, 2 pi)).
    spindle_rpm : float, optional
        If given, the feed rate in mm/min is reported too.

    Returns
    -------
    dict
        ``feed_per_rev_mm`` (X spacing per revolution), ``feed_mm_per_min`` (or None),
        ``centre_spacing_mm`` (f along the section at the limiting point),
        ``limiting_point_mm`` (x, y), ``limiting_curvature_per_mm``,
        ``limiting_slope_deg``, ``flat_feed_mm`` (compound sinusoidal grid paper, eq. 9 alone),
        ``scallop_bound_nm``, ``curvature_range_per_mm`` (min, max sampled).
    """
    r = float(check_range("nose_radius", nose_radius, 0.0, None, lo_open=True))
    check_range("scallop_bound", scallop_bound, 0.0, r, lo_open=True, hi_open=True)
    check_range("r_outer", r_outer, 0.0, None, lo_open=True)
    if not 0.0 <= r_inner < r_outer:
        raise InputError(f"r_inner must be in [0, r_outer = {r_outer}) mm, received {r_inner}")
    check_range("n_radii", n_radii, 1, 100_000)
    check_range("n_angles", n_angles, 1, 100_000)
    rad = r_inner + (r_outer - r_inner) * (np.arange(1, int(n_radii) + 1) / int(n_radii))
    ang = 2 * math.pi * np.arange(int(n_angles)) / int(n_angles)
    rr, aa = np.meshgrid(rad, ang, indexing="ij")
    x, y = rr * np.cos(aa), rr * np.sin(aa)
    # section_curvature > 0 where the section is concave; here k > 0 means convex
    k = -np.asarray(surface.section_curvature(x, y, aa), dtype=np.float64)
    slope = np.asarray(surface.radial_slope(rr, aa), dtype=np.float64)
    too_tight = k * r <= -1.0
    if np.any(too_tight):
        i = np.unravel_index(int(np.argmin(k)), k.shape)
        raise InputError(f"the tool nose (radius {r} mm) does not fit the concave section at "
                         f"({x[i]:.4g}, {y[i]:.4g}) mm (radius of curvature {-1 / k[i]:.4g} mm); "
                         "choose a smaller tool.nose_radius")
    f = feed_for_scallop(scallop_bound, r, k)
    fx = f / np.sqrt(1.0 + slope * slope)
    i = np.unravel_index(int(np.argmin(fx)), fx.shape)
    feed = float(fx[i])
    return {"feed_per_rev_mm": feed,
            "feed_mm_per_min": feed * float(spindle_rpm) if spindle_rpm else None,
            "centre_spacing_mm": float(f[i]),
            "limiting_point_mm": [float(x[i]), float(y[i])],
            "limiting_curvature_per_mm": float(k[i]),
            "limiting_slope_deg": float(math.degrees(math.atan(abs(slope[i])))),
            "flat_feed_mm": float(feed_for_scallop(scallop_bound, r, 0.0)),
            "scallop_bound_nm": float(scallop_bound) * MM_TO_NM,
            "curvature_range_per_mm": [float(np.min(k)), float(np.max(k))]}
