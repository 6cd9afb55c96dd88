"""Calibration artefacts as analytic sub-sampled height and normal grids.

The surfaces of ISO 25178-600 / -604 style instrument characterisation: a flat, a tilted
plane, a sinusoid, a step (a rectangular grating), a sphere.  Each returns what the ray
tracer would: heights (mm) and unit normals at the ``s x s`` sub-sample centres of an
``H x W`` camera field of pixel ``pixel`` whose pixel [0, 0] is centred at ``origin``
(row = y).  Heights are exact; normals are the analytic ones (a step's wall is vertical
and never hit).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from ..core.errors import InputError, check_range

__all__ = ["flat", "sinusoid", "sphere", "step", "subsample_grid", "tilted_plane"]


def subsample_grid(shape: Sequence[int], pixel: float, subsamples: int = 1,
                   origin: Sequence[float] = (0.0, 0.0)) -> tuple[np.ndarray, np.ndarray]:
    """Coordinates of the sub-sample centres.

    Returns
    -------
    x : (W*s,) float64, mm;  y : (H*s,) float64, mm
    """
    ny, nx = (int(v) for v in shape)
    s = int(subsamples)
    if ny < 1 or nx < 1 or s < 1:
        raise InputError(f"shape must be (H, W) >= 1 and subsamples >= 1, got {shape}, {subsamples}")
    check_range("pixel", pixel, 0, None, lo_open=True)
    a = pixel / s
    off = (np.arange(s) - (s - 1) / 2) * a
    x = origin[0] + (np.arange(nx)[:, None] * pixel + off[None, :]).ravel()
    y = origin[1] + (np.arange(ny)[:, None] * pixel + off[None, :]).ravel()
    return x, y


def _normals(gx: np.ndarray, gy: np.ndarray) -> np.ndarray:
    n = np.stack(np.broadcast_arrays(-gx, -gy, np.ones_like(gx + gy)), axis=-1).astype(np.float64)
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    return n.astype(np.float32)


def flat(shape: Sequence[int], pixel: float, subsamples: int = 1, *, height: float = 0.0,
         origin: Sequence[float] = (0.0, 0.0)) -> tuple[np.ndarray, np.ndarray]:
    """A flat at ``height`` (mm)."""
    x, y = subsample_grid(shape, pixel, subsamples, origin)
    h = np.full((y.size, x.size), float(height))
    return h, _normals(np.zeros_like(h), np.zeros_like(h))


def tilted_plane(shape: Sequence[int], pixel: float, subsamples: int = 1, *, angle: float,
                 azimuth: float = 0.0,
                 origin: Sequence[float] = (0.0, 0.0)) -> tuple[np.ndarray, np.ndarray]:
    """A plane tilted by ``angle`` (rad) about the field centre, rising along ``azimuth``
    (rad from +x)."""
    check_range("angle", angle, 0, math.pi / 2, hi_open=True)
    x, y = subsample_grid(shape, pixel, subsamples, origin)
    xc, yc = x - x.mean(), y - y.mean()
    t = math.tan(angle)
    gx, gy = t * math.cos(azimuth), t * math.sin(azimuth)
    h = gx * xc[None, :] + gy * yc[:, None]
    return h, _normals(np.full_like(h, gx), np.full_like(h, gy))


def sinusoid(shape: Sequence[int], pixel: float, subsamples: int = 1, *, period: float,
             amplitude: float, phase: float = 0.0,
             origin: Sequence[float] = (0.0, 0.0)) -> tuple[np.ndarray, np.ndarray]:
    """``h = amplitude cos(2 pi x / period + phase)`` (mm), lines along y."""
    check_range("period", period, 0, None, lo_open=True)
    x, y = subsample_grid(shape, pixel, subsamples, origin)
    arg = 2 * math.pi * x / period + phase
    h = np.broadcast_to(amplitude * np.cos(arg)[None, :], (y.size, x.size)).copy()
    g = np.broadcast_to((-amplitude * 2 * math.pi / period * np.sin(arg))[None, :], h.shape)
    return h, _normals(g, np.zeros_like(h))


def step(shape: Sequence[int], pixel: float, subsamples: int = 1, *, height: float,
         x0: float | None = None, x1: float | None = None,
         origin: Sequence[float] = (0.0, 0.0)) -> tuple[np.ndarray, np.ndarray]:
    """A rectangular step: ``height`` (mm) for ``x0 <= x < x1``, 0 elsewhere.

    The default is the middle half of the field, so a periodic field holds one period of
    a rectangular grating (an up and a down edge).
    """
    x, y = subsample_grid(shape, pixel, subsamples, origin)
    span = x[-1] - x[0] + pixel / subsamples
    lo = x[0] + span / 4 if x0 is None else x0
    hi = x[0] + 3 * span / 4 if x1 is None else x1
    prof = np.where((x >= lo) & (x < hi), float(height), 0.0)
    h = np.broadcast_to(prof[None, :], (y.size, x.size)).copy()
    return h, _normals(np.zeros_like(h), np.zeros_like(h))


def sphere(shape: Sequence[int], pixel: float, subsamples: int = 1, *, radius: float,
           centre: Sequence[float] | None = None,
           origin: Sequence[float] = (0.0, 0.0)) -> tuple[np.ndarray, np.ndarray]:
    """A spherical cap of ``radius`` (mm; > 0 convex, < 0 concave), apex height 0 at
    ``centre`` (default the field centre); NaN beyond the sphere's equator."""
    if radius == 0 or not math.isfinite(radius):
        raise InputError(f"radius must be a finite non-zero length (mm), got {radius!r}")
    x, y = subsample_grid(shape, pixel, subsamples, origin)
    cx, cy = (x.mean(), y.mean()) if centre is None else centre
    r2 = (x[None, :] - cx) ** 2 + (y[:, None] - cy) ** 2
    R = abs(float(radius))
    with np.errstate(invalid="ignore"):
        root = np.sqrt(R * R - r2)
    sgn = 1.0 if radius > 0 else -1.0
    h = sgn * (root - R)
    with np.errstate(invalid="ignore", divide="ignore"):
        gx = -sgn * (x[None, :] - cx) / root
        gy = -sgn * (y[:, None] - cy) / root
    h = np.where(r2 < R * R, h, np.nan)
    return h, _normals(gx, gy)
