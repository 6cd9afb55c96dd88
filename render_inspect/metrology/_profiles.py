"""What the comparison of two maps looks at: the common window where they differ most,
a map cropped to a window, bilinear profiles along a line, radial sections about a
spindle axis (or lines through a centre), and the statistics of a difference.  Arrays in
(mm, or nm where the name says so), numbers out."""

from __future__ import annotations

from typing import Any, Protocol
from collections.abc import Sequence
import math

import numpy as np
from ..core.lazy import lazy_module

from ..core.errors import RenderInspectError
from ..core.units import MM_TO_NM
from ._params import areal_parameters, extract_section

#: SciPy, imported on first use (render_inspect.core.lazy)
ndimage = lazy_module("scipy.ndimage")

__all__ = ["common_window", "design_features", "crop_window", "line_profile", "difference_stats", "sections",
           "profile_center", "areal_nm", "difference_profiles", "surface_slope"]


#: a design has features of its own (lenslets, elements on a base) when the 90th
#: percentile of its curvature is this many times the median (a sinusoid: about 2)
FEATURE_CURVATURE_RATIO = 5.0


def design_features(design: Any, pixel: float) -> np.ndarray | None:
    """Where a design has features of its own against a smooth base (lenslets on a toric
    base, elements on a plane): a 0/1 map on the design's grid, or None when the design
    is alike everywhere (a sinusoid, lenslets tiling the whole map).

    The features are the pixels whose curvature ``|laplacian(design)|`` is above the
    geometric mean of its median and 90th percentile, used only when the 90th
    percentile is :data:`FEATURE_CURVATURE_RATIO` times the median or more."""
    z = np.asarray(design, dtype=np.float64)
    ok = np.isfinite(z)
    if ok.sum() < 16:
        return None
    zf = np.where(ok, z, np.nanmean(z))
    lap = np.abs(ndimage.laplace(zf)) / (pixel * pixel)
    p50, p90 = np.percentile(lap[ok], [50, 90])
    if not p90 > FEATURE_CURVATURE_RATIO * p50:
        return None
    mask = (lap > math.sqrt(max(p50, 0.0) * p90)) & ok
    return ndimage.binary_opening(mask, iterations=1).astype(np.float64)


def common_window(diff: np.ndarray, *, pixel: float, origin: Sequence[float], size_mm: float,
                  fixed: Sequence[float] | None = None, design: np.ndarray | None = None) -> dict:
    """The window every close-up of the report shows: ``fixed`` (mm) if given, else a
    square of ``size_mm`` placed where the two variants differ most (the largest mean
    ``|diff|`` over the window, inside the map), or the map's centre when they do not
    differ.  With ``design`` (the design heights on the same grid) of a design with
    features of its own (:func:`design_features`: lenslets, elements), only the
    difference over the features counts, so the window lands on them rather than on the
    base between them.

    Parameters
    ----------
    diff : (ny, nx) array
        Height difference of the two variants (any unit; NaN = not covered).
    design : (ny, nx) array, optional
        The design heights on the same grid, mm.
    pixel, origin
        Grid of ``diff``, mm.
    size_mm : float
        Side of the window.

    Returns
    -------
    dict with ``window`` (x0, y0, x1, y1), mm, and ``peak`` (x, y of the largest
    smoothed ``|diff|`` inside it), mm.
    """
    d = np.abs(np.nan_to_num(np.asarray(diff, dtype=np.float64)))
    ny, nx = d.shape
    x_lo, y_lo = origin[0], origin[1]
    x_hi, y_hi = x_lo + pixel * (nx - 1), y_lo + pixel * (ny - 1)
    if fixed is not None:
        x0, y0, x1, y1 = (float(v) for v in fixed)
    else:
        side = min(float(size_mm), x_hi - x_lo, y_hi - y_lo)
        n = max(1, int(round(side / pixel)))
        feats = design_features(design, pixel) if design is not None else None
        if feats is not None and (d * feats).max() > 0:
            d = d * feats
        if d.max() > 0:
            mean = ndimage.uniform_filter(d, size=n, mode="constant")
            # keep the window inside the map
            h = n // 2
            inner = np.zeros_like(mean, dtype=bool)
            inner[h:ny - (n - h) + 1, h:nx - (n - h) + 1] = True
            if not inner.any():
                inner[:] = True
            i, j = np.unravel_index(np.argmax(np.where(inner, mean, -1)), mean.shape)
            cx, cy = float(x_lo + j * pixel), float(y_lo + i * pixel)
        else:
            cx, cy = (x_lo + x_hi) / 2, (y_lo + y_hi) / 2
        x0 = min(max(cx - side / 2, x_lo), x_hi - side)
        y0 = min(max(cy - side / 2, y_lo), y_hi - side)
        x1, y1 = x0 + side, y0 + side
    j0 = max(0, int(math.floor((x0 - x_lo) / pixel)))
    j1 = min(nx, int(math.ceil((x1 - x_lo) / pixel)) + 1)
    i0 = max(0, int(math.floor((y0 - y_lo) / pixel)))
    i1 = min(ny, int(math.ceil((y1 - y_lo) / pixel)) + 1)
    sub = d[i0:i1, j0:j1]
    if sub.size and sub.max() > 0:
        sm = ndimage.gaussian_filter(sub, sigma=max(1.0, min(sub.shape) / 16), mode="nearest")
        i, j = np.unravel_index(np.argmax(sm), sm.shape)
        peak = (float(x_lo + (j0 + j) * pixel), float(y_lo + (i0 + i) * pixel))
    else:
        peak = ((x0 + x1) / 2, (y0 + y1) / 2)
    return {"window": (float(x0), float(y0), float(x1), float(y1)),
            "peak": (float(peak[0]), float(peak[1]))}


def crop_window(z: np.ndarray, grid: Any,
                window: Sequence[float]) -> tuple[np.ndarray, tuple[float, float, float, float]]:
    """``z`` (on ``grid``'s pixels: ``pixel``, ``origin``) inside ``window`` = (x0, y0, x1,
    y1) (mm), and its pixel-edge extent (x0, x1, y0, y1)."""
    x0, y0, x1, y1 = window
    p = grid.pixel
    ox, oy = grid.origin
    j0 = max(0, int(math.ceil((x0 - ox) / p - 1e-9)))
    j1 = min(z.shape[1], int(math.floor((x1 - ox) / p + 1e-9)) + 1)
    i0 = max(0, int(math.ceil((y0 - oy) / p - 1e-9)))
    i1 = min(z.shape[0], int(math.floor((y1 - oy) / p + 1e-9)) + 1)
    ext = (ox + (j0 - 0.5) * p, ox + (j1 - 0.5) * p, oy + (i0 - 0.5) * p, oy + (i1 - 0.5) * p)
    return z[i0:i1, j0:j1], ext


def line_profile(z: np.ndarray, *, pixel: float, origin: Sequence[float], p0: Sequence[float],
                 p1: Sequence[float], step: float) -> tuple[np.ndarray, np.ndarray]:
    """Bilinear samples of ``z`` along the segment p0 -> p1 (mm): (s, values)."""
    length = math.hypot(p1[0] - p0[0], p1[1] - p0[1])
    n = max(2, int(length / step) + 1)
    s = np.linspace(0.0, length, n)
    x = p0[0] + (p1[0] - p0[0]) * s / length
    y = p0[1] + (p1[1] - p0[1]) * s / length
    col = (x - origin[0]) / pixel
    row = (y - origin[1]) / pixel
    vals = ndimage.map_coordinates(np.nan_to_num(z, nan=np.nan), [row, col], order=1,
                                   mode="constant", cval=np.nan)
    valid = ndimage.map_coordinates(np.isfinite(z).astype(float), [row, col], order=1,
                                    mode="constant", cval=0.0)
    vals = np.where(valid > 0.999, vals, np.nan)
    return s, vals


def difference_stats(d: np.ndarray) -> dict:
    """rms, PV and mean (nm) of the finite values of a difference map (nm)."""
    d = np.asarray(d, dtype=np.float64)
    d = d[np.isfinite(d)]
    if not d.size:
        return {"rms_nm": None, "pv_nm": None, "mean_nm": None}
    return {"rms_nm": float(np.sqrt(np.mean(d * d))), "pv_nm": float(np.ptp(d)),
            "mean_nm": float(d.mean())}


def sections(z: np.ndarray, design: np.ndarray | None, *, pixel: float, origin: Sequence[float],
             center: Sequence[float], angles_deg: Sequence[float],
             filtered: np.ndarray | None = None, through: bool = False) -> list[dict]:
    """Profiles of ``z`` (and of ``design``, ``filtered`` on the same grid) at the section
    angles ``angles_deg`` through ``center``: radial from it (``through`` False, a turned
    part's spindle axis) or a line through it: [{angle_deg, s, machined, design,
    filtered}, ...] (sections with fewer than two valid points are left out)."""
    def sec(m: np.ndarray, ang: float) -> np.ndarray:
        return _one_section(m, pixel=pixel, origin=origin, center=center, angle=ang,
                            through=through)[1]

    out = []
    for ang in angles_deg:
        s, zm = _one_section(z, pixel=pixel, origin=origin, center=center, angle=ang,
                             through=through)
        if np.isfinite(zm).sum() >= 2:
            out.append({"angle_deg": float(ang), "s": s, "machined": zm,
                        "design": None if design is None else sec(design, ang),
                        "filtered": None if filtered is None else sec(filtered, ang)})
    return out


def _one_section(z: np.ndarray, *, pixel: float, origin: Sequence[float],
                 center: Sequence[float], angle: float,
                 through: bool) -> tuple[np.ndarray, np.ndarray]:
    if not through:
        return extract_section(z, pixel=pixel, origin=origin, kind="radial", center=center,
                               angle=np.radians(angle))
    ny, nx = np.shape(z)
    half = 0.5 * min(nx, ny) * pixel
    c, s_ = math.cos(math.radians(angle)), math.sin(math.radians(angle))
    p0 = (center[0] - half * c, center[1] - half * s_)
    p1 = (center[0] + half * c, center[1] + half * s_)
    s, v = line_profile(np.asarray(z, float), pixel=pixel, origin=origin, p0=p0, p1=p1,
                         step=pixel)
    return s - half, v


def profile_center(grid: Any, axis: Sequence[float] | None = None) -> tuple[float, float]:
    """Where sections of a map start: the spindle ``axis`` (x, y) of a turned part when it
    lies in the map, else the map's centre."""
    x0, x1, y0, y1 = grid.extent
    if axis is not None and x0 <= axis[0] <= x1 and y0 <= axis[1] <= y1:
        return (float(axis[0]), float(axis[1]))
    return ((x0 + x1) / 2, (y0 + y1) / 2)


def areal_nm(z: np.ndarray, pixel: float | tuple[float, float]) -> dict:
    """Sa, Sq, Sp, Sv, Sz (nm) of a map in mm (None when it has fewer than two values)."""
    ok = np.isfinite(z)
    if ok.sum() < 2:
        return {"Sa_nm": None, "Sq_nm": None, "Sz_nm": None}
    p = areal_parameters(z, pixel=pixel)
    return {f"{k}_nm": p[k] * MM_TO_NM for k in ("Sa", "Sq", "Sp", "Sv", "Sz")}


class _PixelGrid(Protocol):
    """A map's grid: its pixel (mm) and the centre of pixel [0, 0] (mm)."""

    @property
    def pixel(self) -> float: ...
    @property
    def origin(self) -> Sequence[float]: ...


def difference_profiles(true_diff: np.ndarray, grid: _PixelGrid, measured_diff: np.ndarray,
                        measured_grid: _PixelGrid, residuals: tuple[np.ndarray, np.ndarray], *,
                        window: Sequence[float], peak: Sequence[float]) -> dict:
    """The difference of two maps over a common window, and its profile through the
    largest difference.

    Parameters
    ----------
    true_diff : (ny, nx) array
        The difference of the two true maps on ``grid`` (nm).
    grid
        ``pixel`` and ``origin`` of ``true_diff`` and ``residuals`` (mm).
    measured_diff : array
        The difference of the two measurements on ``measured_grid`` (nm).
    residuals : (a, b)
        The two maps' residuals on ``grid`` (nm), profiled along the same line.
    window : (x0, y0, x1, y1)
        The common window, mm.
    peak : (x, y)
        Where the difference is largest (mm); kept a tenth of the window inside it.

    Returns
    -------
    dict
        ``true_window`` and ``true_extent`` (the true difference cropped to the window),
        ``line`` (the profile's end points, along the direction in which the difference
        changes most), ``along_x``, ``peak``, the profiles ``s``, ``true``, ``a``, ``b``
        (on ``grid``) and ``s_measured``, ``measured`` (on ``measured_grid``), and
        ``metrics`` (``window``: the window, the peak, the rms / PV / mean of both
        differences, the profile's line).
    """
    true_win, true_ext = crop_window(true_diff, grid, window)
    x0, y0, x1, y1 = window
    px, py = peak
    px = min(max(px, x0 + 0.1 * (x1 - x0)), x1 - 0.1 * (x1 - x0))
    py = min(max(py, y0 + 0.1 * (y1 - y0)), y1 - 0.1 * (y1 - y0))
    # the profile runs along the direction in which the difference changes most
    with np.errstate(invalid="ignore"):
        gy, gx = np.gradient(np.nan_to_num(true_win)) if min(true_win.shape) > 2 else (0, 0)
    along_x = float(np.mean(np.abs(gx))) >= float(np.mean(np.abs(gy)))
    line = ((x0, py), (x1, py)) if along_x else ((px, y0), (px, y1))
    s, prof = line_profile(true_diff, pixel=grid.pixel, origin=grid.origin, p0=line[0],
                           p1=line[1], step=grid.pixel)
    _, pa = line_profile(residuals[0], pixel=grid.pixel, origin=grid.origin, p0=line[0],
                         p1=line[1], step=grid.pixel)
    _, pb = line_profile(residuals[1], pixel=grid.pixel, origin=grid.origin, p0=line[0],
                         p1=line[1], step=grid.pixel)
    sm, pm = line_profile(measured_diff, pixel=measured_grid.pixel, origin=measured_grid.origin,
                          p0=line[0], p1=line[1], step=measured_grid.pixel)
    metrics = {"window": {"window_mm": [x0, y0, x1, y1], "largest_difference_mm": [px, py],
                          "true": difference_stats(true_win),
                          "measured": difference_stats(measured_diff),
                          "profile_mm": [list(line[0]), list(line[1])]}}
    return {"true_window": true_win, "true_extent": true_ext, "line": line, "along_x": along_x,
            "peak": (px, py), "s": s, "true": prof, "a": pa, "b": pb, "s_measured": sm,
            "measured": pm, "metrics": metrics}


def surface_slope(surface: Any, window: Sequence[float], n: int = 257) -> float | None:
    """Largest slope (rad, the 99.9th percentile) of ``surface`` over ``window`` = (x0, y0,
    x1, y1) (mm) from n x n samples; None when the surface cannot be sampled there."""
    x0, y0, x1, y1 = (float(v) for v in window)
    try:
        x = np.linspace(x0, x1, n)
        y = np.linspace(y0, y1, n)
        z = np.asarray(surface.height(x[None, :], y[:, None]), dtype=np.float64)
        gy, gx = np.gradient(z, y, x)
    except RenderInspectError:
        return None
    g = np.hypot(gx, gy)
    g = g[np.isfinite(g)]
    return float(np.arctan(np.percentile(g, 99.9))) if g.size else None
