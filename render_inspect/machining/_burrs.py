"""Burrs on sharp edges: a phenomenological model (after Zhang et al. 2022 [1]_, section 4),
the height given as an input (an override of the material model of :mod:`._material`,
whose side flow forms the burrs from the cutting conditions).

Zhang et al. (2022) saw small burrs on the sharp edges between lenslets and named them a
main source of the remaining form error; they explain them by plastic side flow of the
workpiece material: the lateral deformation of Gillespie and Blotter's three burr
mechanisms [2]_ (chip rollover and tearing are the others; this model leaves them out).
The paper gives no burr law, so this is a model, not a derivation:

* where: on *sharp edges* of the machined surface (``edges_from="machined"``, what the
  processes use: the edges where the machine cut them, moved by servo lag), or of the
  design, i.e. where the slope jumps (the gradient is discontinuous, e.g. the cell
  boundaries of a lenslet array or the rim of a lenslet sunk into a base).  An edge is a
  grid line where the slope difference between neighbouring pixel pairs exceeds
  ``edge_angle_deg`` and is a local maximum across the edge; on the machined surface the
  feed marks are smoothed out first (Gaussian of standard deviation ``smoothing``).
* shape: a ridge centred on the edge, h(d) = height * v * cos^2(pi d / width) for the
  distance d < width / 2 from the edge, 0 beyond (material is pushed up, never removed).
* variation: v = max(0, 1 + variation * g(x, y)) with g a unit-variance Gaussian random
  field of correlation length ``correlation_length`` (default 4 x width), built from 64
  random Fourier modes drawn from ``simulation.seed``; g depends on the position in mm
  only, so the same seed gives the same burr at the same place on any grid.
* size: ``height`` and ``width`` are inputs.  They stand for one material and one process:
  side flow grows with the uncut chip thickness (depth of cut) and the tool edge radius,
  and ultrasonic vibration (HFUVAS) reduces it (Zhang et al. 2022: Sz 1.2 um conventional against
  0.13 um with vibration on Mirrax 40); scale ``height`` accordingly.
* assumptions: the burr does not change the cut elsewhere (it is added after the
  envelope), it does not depend on the cutting direction, and the edge position is
  resolved to one pixel.

References
----------
.. [1] C. Zhang, C.-F. Cheung, X. Liang, B. Bulla, "A theoretical and experimental
       investigation of high-frequency ultrasonic vibration-assisted sculpturing of
       optical microstructures," Applied Sciences 12(21), 10937 (2022).
.. [2] L. K. Gillespie, P. T. Blotter, "The formation and properties of machining burrs,"
       Journal of Engineering for Industry 98(1), 66 (1976).
"""

from __future__ import annotations

import math

import numpy as np
from scipy import ndimage

from ..core.errors import InputError, check_range
from ..core.units import MM_TO_UM

__all__ = ["sharp_edges", "machined_sharp_edges", "burr_map", "apply_burrs"]

_MODES = 64


def sharp_edges(design, *, pixel: float, edge_angle_deg: float = 1.0) -> np.ndarray:
    """Pixels on sharp edges of ``design`` (where the slope jumps).

    Parameters
    ----------
    design : (ny, nx) array, mm
    pixel : float, mm
    edge_angle_deg : float
        Smallest slope jump (deg, in (0, 90)) counted as a sharp edge.  A smooth surface of
        radius of curvature rho has a jump of about pixel / rho rad between neighbouring
        pixels, so keep pixel / rho well below this.

    Returns
    -------
    (ny, nx) bool
    """
    z = np.asarray(design, dtype=np.float64)
    if z.ndim != 2:
        raise InputError(f"design must be a 2-D array, received shape {z.shape}")
    check_range("pixel", pixel, 0.0, None, lo_open=True)
    check_range("edge_angle_deg", edge_angle_deg, 0.0, 90.0, lo_open=True, hi_open=True)
    mask = np.zeros(z.shape, dtype=bool)
    for axis in (0, 1):
        zz = np.moveaxis(z, axis, 0)
        if zz.shape[0] < 3:
            continue
        s = np.diff(zz, axis=0) / pixel                     # slope between pixels i, i+1
        j = np.abs(np.arctan(s[1:]) - np.arctan(s[:-1]))    # turn at pixel i (1..n-2), rad
        j = np.nan_to_num(j, nan=0.0)
        jp = np.pad(j, ((1, 1),) + ((0, 0),) * (j.ndim - 1))
        peak = (j > math.radians(edge_angle_deg)) & (j >= jp[:-2]) & (j >= jp[2:])
        m = np.zeros(zz.shape, dtype=bool)
        m[1:-1] = peak
        mask |= np.moveaxis(m, 0, axis)
    return mask


def _random_field(x, y, *, correlation_length: float, seed: int) -> np.ndarray:
    """Unit-variance Gaussian random field with covariance exp(-r^2 / (2 l^2)) at (x, y) mm."""
    rng = np.random.default_rng(seed)
    k = rng.normal(0.0, 1.0 / correlation_length, size=(_MODES, 2))
    phase = rng.uniform(0.0, 2 * math.pi, size=_MODES)
    arg = np.multiply.outer(x, k[:, 0]) + np.multiply.outer(y, k[:, 1]) + phase
    return math.sqrt(2.0 / _MODES) * np.cos(arg).sum(axis=-1)


def burr_map(design, *, pixel: float, origin=(0.0, 0.0), height: float, width: float,
             variation: float = 0.3, seed: int = 0, edge_angle_deg: float = 1.0,
             correlation_length: float | None = None, edges=None) -> np.ndarray:
    """Height (mm, >= 0) that burrs add on the sharp edges of ``design``.

    Parameters
    ----------
    design : (ny, nx) array, mm (row 0 = smallest y)
    pixel : float, mm
    origin : (x, y) of pixel [0, 0], mm (positions of the seeded variation)
    height, width : float, mm
        Nominal burr height and full base width (>= 0; either 0 gives no burrs).
    variation : float
        Relative seeded variation along the edges, in [0, 1].
    seed : int
        Seed of the variation (``simulation.seed``).
    edge_angle_deg : float
        See :func:`sharp_edges`.
    correlation_length : float, optional
        mm; default 4 x ``width``.
    edges : (ny, nx) bool, optional
        Edge pixels; detected with :func:`sharp_edges` if None.

    Returns
    -------
    (ny, nx) float64
    """
    check_range("burrs.height", height, 0.0, 0.1)
    check_range("burrs.width", width, 0.0, 1.0)
    check_range("burrs.variation", variation, 0.0, 1.0)
    design = np.asarray(design, dtype=np.float64)
    out = np.zeros(design.shape)
    if height == 0 or width == 0:
        return out
    mask = sharp_edges(design, pixel=pixel, edge_angle_deg=edge_angle_deg) if edges is None \
        else np.asarray(edges, dtype=bool)
    if mask.shape != design.shape:
        raise InputError(f"edges must have the design's shape {design.shape}, received {mask.shape}")
    if not mask.any():
        return out
    dist, (iy, ix) = ndimage.distance_transform_edt(~mask, return_indices=True)
    d = dist * pixel
    near = d < width / 2
    if not near.any():
        return out
    ell = correlation_length if correlation_length is not None else 4.0 * width
    check_range("burrs.correlation_length", ell, 0.0, None, lo_open=True)
    ex = origin[0] + pixel * ix[near]
    ey = origin[1] + pixel * iy[near]
    v = np.maximum(1.0 + variation * _random_field(ex, ey, correlation_length=ell, seed=seed), 0.0)
    out[near] = height * v * np.cos(np.pi * d[near] / width) ** 2
    return out


def machined_sharp_edges(machined, *, pixel: float, smoothing: float = 0.0,
                         edge_angle_deg: float = 1.0) -> np.ndarray:
    """Sharp edges of the *machined* surface: :func:`sharp_edges` of the map smoothed by
    a Gaussian of standard deviation ``smoothing`` (mm; 0 = none), which removes the feed
    marks so that only the edges of the cut form remain, where the machine put them
    (shifted by servo lag, not on the design's edges).  NaN pixels are filled from their
    nearest valid neighbour first."""
    check_range("smoothing", smoothing, 0.0, None)
    z = np.asarray(machined, dtype=np.float64)
    bad = ~np.isfinite(z)
    if bad.all():
        return np.zeros(z.shape, dtype=bool)
    if bad.any():
        idx = ndimage.distance_transform_edt(bad, return_distances=False, return_indices=True)
        z = z[tuple(idx)]
    if smoothing > 0:
        z = ndimage.gaussian_filter(z, smoothing / pixel, mode="nearest")
    return sharp_edges(z, pixel=pixel, edge_angle_deg=edge_angle_deg) & ~bad


def apply_burrs(machined, design, *, pixel: float, origin=(0.0, 0.0), height: float,
                width: float, variation: float = 0.3, edge_angle_deg: float = 1.0,
                correlation_length: float | None = None, seed: int = 0,
                edges_from: str = "design", smoothing: float = 0.0):
    """Add burrs (:func:`burr_map`, same parameters) to ``machined``.

    ``edges_from``: ``"design"`` puts them on the design's sharp edges, ``"machined"`` on
    the machined surface's (:func:`machined_sharp_edges` with ``smoothing``, mm).

    Returns
    -------
    machined : (ny, nx) float64, mm (a new array; NaN stays NaN)
    info : dict
        The settings, the seed, the edge-pixel count and the largest added height (um):
        what goes into ``metrics["burrs"]``.
    """
    if edges_from not in ("design", "machined"):
        raise InputError(f"edges_from must be 'design' or 'machined', received {edges_from!r}")
    info = {"model": "cos^2 ridge on sharp edges, seeded multiplicative variation",
            "height_mm": height, "width_mm": width, "variation": variation,
            "edge_angle_deg": edge_angle_deg, "correlation_length_mm": correlation_length,
            "seed": int(seed), "edge_pixels": 0, "max_added_um": 0.0, "edges_from": edges_from}
    machined = np.array(machined, dtype=np.float64, copy=True)
    if height == 0 or width == 0:
        return machined, info
    if edges_from == "design":
        edges = sharp_edges(design, pixel=pixel, edge_angle_deg=edge_angle_deg)
    else:
        edges = machined_sharp_edges(machined, pixel=pixel, smoothing=smoothing,
                                     edge_angle_deg=edge_angle_deg)
        info["smoothing_mm"] = smoothing
    b = burr_map(design, pixel=pixel, origin=origin, height=height, width=width,
                 variation=variation, seed=seed, edge_angle_deg=edge_angle_deg,
                 correlation_length=correlation_length, edges=edges)
    machined += b
    info["edge_pixels"] = int(edges.sum())
    info["max_added_um"] = float(b.max() * MM_TO_UM)
    return machined, info
