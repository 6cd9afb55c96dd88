"""Areal (ISO 25178-2) and profile (ISO 21920-2 / ISO 4287) parameters.

Areal parameters are taken about the mean plane of the valid points (remove the form
first with :func:`remove_form`).  Pixels may be non-square: ``pixel = (pixel_x, pixel_y)``.

Slopes (Sdq, Sdr), ``slope="forward"`` (default, as SurfaceTopography and surfalize):
forward differences along the cell edges, ``zx = (z[i, j+1] - z[i, j]) / pixel_x`` and
``zy = (z[i+1, j] - z[i, j]) / pixel_y``.  Sdq is the root mean square of ``|grad z|`` with
both differences taken at the same corner of each grid cell (SurfaceTopography's
``rms_gradient``); Sdr is the developed area of ISO 25178-2:2021 D.3 (eq. D.15): each
cell is split into two triangles along each diagonal and the two areas are averaged,
divided by the projected area of the cells.  On a map with missing points the gradients
and cells bordering a hole are left out, as SurfaceTopography's ``rms_gradient`` does
(``hole_border="exclude"``; the value with them is reported too): instruments measure
edge effects there, and a few percent of such cells can raise Sdq by tens of percent.  ``slope="central"`` uses central
differences (``numpy.gradient``) at every point and ``sqrt(1 + |grad z|^2) - 1`` for Sdr:
it attenuates slopes near the Nyquist frequency (a sinusoid of period ``p`` pixels
loses a factor ``sin(2 pi / p) / (2 pi / p)``).

Sal and Str come from the autocorrelation function (ISO 25178-2): see
:func:`spatial_parameters`.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
import warnings
from typing import Any

import numpy as np
from ..core.lazy import lazy_module

from ..core.errors import InputError, check_positive, check_range
from ._filters import pixel_xy, valid_mask

#: SciPy, imported on first use (render_inspect.core.lazy)
sfft = lazy_module("scipy.fft")
ndimage = lazy_module("scipy.ndimage")

__all__ = ["areal_parameters", "slope_parameters", "forward_slope_sums", "spatial_parameters", "autocorrelation",
           "SLOPE_ESTIMATORS", "profile_parameters", "extract_section", "section_parameters"]

#: Derivative estimators of :func:`slope_parameters`.
SLOPE_ESTIMATORS = ("forward", "central")


def _border_free(ok: np.ndarray) -> np.ndarray:
    """For each grid corner (r, c) of ``ok`` (True = measured), whether the points
    SurfaceTopography's forward gradient at that corner rests on are all measured: the
    corner, its two neighbours in +x and +y, and the next point beyond each of those
    (``z[r, c..c+2]``, ``z[r+1, c..c+1]``, ``z[r+2, c]``; its linear interpolation
    reaches one point further than the differences).  Points beyond the map count as
    measured.  Shape (ny, nx)."""
    p = np.pad(ok, ((0, 2), (0, 2)), mode="wrap") if _WRAP else np.pad(ok, ((0, 2), (0, 2)), constant_values=True)
    return (p[:-2, :-2] & p[:-2, 1:-1] & p[:-2, 2:] & p[1:-1, :-2] & p[1:-1, 1:-1]
            & p[2:, :-2])


_WRAP = False
#: rows of the map processed at once by :func:`slope_parameters` (bounds its memory)
_SLOPE_ROWS = 256


def forward_slope_sums(z: np.ndarray, ok: np.ndarray, pixel: Sequence[float],
                       corners: tuple[int, int], *, holes: bool) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The sums behind the forward estimator's Sdq and Sdr over the grid corners of rows
    ``corners[0]`` .. ``corners[1] - 1`` of ``z`` (each corner's cell reaches one row and
    column further; the border rule looks two rows further, and rows beyond ``z`` count
    as measured): ``(g2_sum, g2_n, area_sum, area_n)``, each a pair [border left out,
    border included] (the first is the second's copy unless ``holes``).  Sums over row
    bands of a map (each band with the two rows after it) add up to the whole map's."""
    px, py = pixel
    ny = z.shape[0]
    g2_sum, g2_n, area_sum, area_n = np.zeros(2), np.zeros(2, np.int64), np.zeros(2), \
        np.zeros(2, np.int64)
    cz = (px * py) ** 2
    for r0 in range(corners[0], corners[1], _SLOPE_ROWS):
        r1 = min(r0 + _SLOPE_ROWS, corners[1])  # corners r0 .. r1 - 1
        zz = np.where(ok[r0:r1 + 1], z[r0:r1 + 1], np.nan)  # rows r0 .. r1
        dx = np.diff(zz, axis=1)  # x edges
        dy = np.diff(zz, axis=0)  # y edges
        gx, gy = dx[:-1, :] / px, dy[:, :-1] / py  # both at the lower-left corner of each cell
        g2 = gx * gx + gy * gy
        del gx, gy
        gok = np.isfinite(g2)
        # ISO 25178-2:2021 D.3: the cell area as the mean of its two triangulations, i.e.
        # half the sum of the four corner triangles spanned by one x and one y edge
        cxb, cxt = (py * dx[:-1, :]) ** 2, (py * dx[1:, :]) ** 2
        cyl, cyr = (px * dy[:, :-1]) ** 2, (px * dy[:, 1:]) ** 2
        del dx, dy, zz
        area = np.sqrt(cxb + cyl + cz)
        area += np.sqrt(cxb + cyr + cz)
        area += np.sqrt(cxt + cyr + cz)
        area += np.sqrt(cxt + cyl + cz)
        area *= 0.25
        del cxb, cxt, cyl, cyr
        cok = np.isfinite(area)
        g2_sum[1] += g2[gok].sum()
        g2_n[1] += int(gok.sum())
        area_sum[1] += area[cok].sum()
        area_n[1] += int(cok.sum())
        if holes:
            free = _border_free(ok[r0:min(r1 + 2, ny)])[:r1 - r0, :-1]
            gok &= free
            cok &= free
            g2_sum[0] += g2[gok].sum()
            g2_n[0] += int(gok.sum())
            area_sum[0] += area[cok].sum()
            area_n[0] += int(cok.sum())
    if not holes:
        g2_sum[0], g2_n[0], area_sum[0], area_n[0] = g2_sum[1], g2_n[1], area_sum[1], area_n[1]
    return g2_sum, g2_n, area_sum, area_n


def slope_parameters(z: np.ndarray, *, pixel: float | tuple[float, float],
                     mask: np.ndarray | None = None, slope: str = "forward",
                     hole_border: str = "exclude") -> dict:
    """Sdq (root mean square gradient) and Sdr (developed interfacial area ratio, %).

    Parameters
    ----------
    z : (ny, nx) array
        Heights, mm (NaN = missing).
    pixel : float or (pixel_x, pixel_y)
        Sampling distances, mm (``z`` and ``pixel`` must share a unit).
    mask : bool array, optional
        ``False`` leaves a point out.
    slope : {"forward", "central"}
        Derivative estimator (see the module docstring).
    hole_border : {"exclude", "include"}
        Forward estimator on a map with points missing: ``exclude`` (default) uses a
        gradient, and the developed area of a cell, only where the points around it are
        measured as SurfaceTopography's ``rms_gradient`` requires (:func:`_border_free`:
        the gradient's points and one more in +x and +y), which leaves out the points
        bordering a hole, where instruments measure edge effects; ``include`` uses every
        gradient whose own differences are measured.  Both values are returned.

    Returns
    -------
    dict
        ``Sdq`` (dimensionless), ``Sdr`` (%), ``n_slope`` (gradients used by Sdq),
        ``n_cells`` (cells used by Sdr), ``slope`` (the estimator), ``hole_border``;
        forward only: ``Sdq_with_border``, ``Sdr_with_border``, ``n_border`` (gradients
        left out next to holes).
    """
    if hole_border not in ("exclude", "include"):
        raise InputError(f"hole_border must be 'exclude' or 'include', got {hole_border!r}")
    z = np.asarray(z, dtype=np.float64)
    px, py = pixel_xy(pixel)
    ok = valid_mask(z, mask)
    nan = float("nan")
    if slope == "forward":
        if min(z.shape) < 2:
            return {"Sdq": nan, "Sdr": nan, "n_slope": 0, "n_cells": 0, "slope": slope,
                    "hole_border": hole_border, "Sdq_with_border": nan,
                    "Sdr_with_border": nan, "n_border": 0}
        holes = not ok.all()
        g2_sum, g2_n, area_sum, area_n = forward_slope_sums(z, ok, (px, py), (0, z.shape[0] - 1),
                                                            holes=holes)
        sdq = [float(np.sqrt(g2_sum[k] / g2_n[k])) if g2_n[k] else nan for k in (0, 1)]
        sdr = [float(100.0 * (area_sum[k] / (area_n[k] * px * py) - 1.0)) if area_n[k] else nan
               for k in (0, 1)]
        k = 0 if hole_border == "exclude" else 1
        return {"Sdq": sdq[k], "Sdr": sdr[k], "n_slope": int(g2_n[k]), "n_cells": int(area_n[k]),
                "slope": slope, "hole_border": hole_border, "Sdq_with_border": sdq[1],
                "Sdr_with_border": sdr[1], "n_border": int(g2_n[1] - g2_n[0])}
    if slope == "central":
        zz = np.where(ok, z, np.nan)
        if min(z.shape) < 2:
            return {"Sdq": nan, "Sdr": nan, "n_slope": 0, "n_cells": 0, "slope": slope,
                    "hole_border": hole_border}
        gy, gx = np.gradient(zz, py, px)
        g2 = gx * gx + gy * gy
        gok = np.isfinite(g2)
        if not gok.any():
            return {"Sdq": nan, "Sdr": nan, "n_slope": 0, "n_cells": 0, "slope": slope,
                    "hole_border": hole_border}
        return {"Sdq": float(np.sqrt(np.mean(g2[gok]))),
                "Sdr": float(100.0 * np.mean(np.sqrt(1.0 + g2[gok]) - 1.0)),
                "n_slope": int(gok.sum()), "n_cells": int(gok.sum()), "slope": slope,
                "hole_border": hole_border}
    raise InputError(f"slope must be one of {SLOPE_ESTIMATORS}, got {slope!r}")


def areal_parameters(z: np.ndarray, *, pixel: float | tuple[float, float],
                     mask: np.ndarray | None = None, slope: str = "forward",
                     hole_border: str = "exclude") -> dict:
    """ISO 25178-2 areal parameters of a height map.

    Parameters
    ----------
    z : (ny, nx) array
        Heights (any length unit; Sa..Sz come back in it). NaN marks missing points.
    pixel : float or (pixel_x, pixel_y)
        Sampling distances in the unit of ``z``: Sdq and Sdr are slopes, so ``z`` and
        ``pixel`` must share a unit (pass both in mm).
    mask : bool array, optional
        ``False`` leaves a point out.
    slope : {"forward", "central"}
        Derivative estimator of Sdq and Sdr (:func:`slope_parameters`).
    hole_border : {"exclude", "include"}
        Whether the gradients next to missing points count (:func:`slope_parameters`).

    Returns
    -------
    dict
        ``Sa, Sq, Sp, Sv, Sz, Ssk, Sku`` (heights about the mean; Sv is positive, the depth
        of the lowest valley), ``Sdq`` (root mean square gradient, dimensionless), ``Sdr``
        (developed interfacial area ratio, %), ``n_valid``, ``slope``, ``hole_border``;
        with the forward estimator also ``Sdq_with_border``, ``Sdr_with_border`` (every
        gradient whose differences are measured) and ``n_border``.
    """
    z = np.asarray(z, dtype=np.float64)
    if z.ndim != 2:
        raise InputError(f"z must be a 2-D height map, got shape {z.shape}")
    pxy = pixel_xy(pixel)
    ok = valid_mask(z, mask)
    n = int(ok.sum())
    if n < 2:
        raise InputError(f"areal_parameters: need at least 2 valid (finite, unmasked) points, got {n}")
    v = z[ok]
    d = v - v.mean()
    d2 = d * d
    sq = float(np.sqrt(np.mean(d2)))
    out: dict[str, Any] = {"Sa": float(np.mean(np.abs(d))), "Sq": sq, "Sp": float(d.max()), "Sv": float(-d.min())}
    out["Sz"] = out["Sp"] + out["Sv"]
    out["Ssk"] = float(np.mean(d2 * d) / sq ** 3) if sq > 0 else 0.0
    out["Sku"] = float(np.mean(d2 * d2) / sq ** 4) if sq > 0 else 0.0
    del d, d2
    sp = slope_parameters(z, pixel=pxy, mask=ok, slope=slope, hole_border=hole_border)
    out["Sdq"], out["Sdr"] = sp["Sdq"], sp["Sdr"]
    out["n_valid"] = n
    out["slope"] = slope
    out["hole_border"] = hole_border
    if "Sdq_with_border" in sp:
        out["Sdq_with_border"], out["Sdr_with_border"] = sp["Sdq_with_border"], sp["Sdr_with_border"]
        out["n_border"] = sp["n_border"]
    return out


def _full_correlation(a):
    """Linear (zero-padded) autocorrelation sum of ``a``: shape (2 ny - 1, 2 nx - 1), zero
    lag at (ny - 1, nx - 1).  The power spectrum is formed in place and the lags are
    copied out of the periodic result quadrant by quadrant (no rolled copy), so the peak
    is the spectrum, the periodic result and the output."""
    ny, nx = a.shape
    shape = (sfft.next_fast_len(2 * ny - 1, real=True), sfft.next_fast_len(2 * nx - 1, real=True))
    f = sfft.rfft2(a, shape)
    power = f.imag * f.imag
    f.real *= f.real
    f.real += power
    f.imag[...] = 0.0
    del power
    full = sfft.irfft2(f, shape, overwrite_x=True)
    del f
    out = np.empty((2 * ny - 1, 2 * nx - 1))
    # lag t sits at index t (t >= 0) or shape + t (t < 0) of the periodic result
    rows = ((slice(0, ny - 1), slice(shape[0] - ny + 1, shape[0])), (slice(ny - 1, 2 * ny - 1), slice(0, ny)))
    cols = ((slice(0, nx - 1), slice(shape[1] - nx + 1, shape[1])), (slice(nx - 1, 2 * nx - 1), slice(0, nx)))
    for ro, ri in rows:
        for co, ci in cols:
            out[ro, co] = full[ri, ci]
    return out


def _acf(z, mask=None, *, keep_pairs: bool = True):
    """(acf, pairs) of :func:`autocorrelation`, formed in place (``pairs`` None unless
    ``keep_pairs``; for a map without missing points it is not needed)."""
    z = np.asarray(z, dtype=np.float64)
    ok = valid_mask(z, mask)
    n_ok = int(ok.sum())
    if n_ok < 4:
        raise InputError(f"autocorrelation: need at least 4 valid points, got {n_ok}")
    ny, nx = z.shape
    zc = np.where(ok, z - z[ok].mean(), 0.0)
    acf = _full_correlation(zc)
    del zc
    if ok.all():  # pairs at lag (ty, tx): (ny - |ty|) (nx - |tx|)
        ry = (ny - np.abs(np.arange(1 - ny, ny))).astype(np.float64)
        rx = (nx - np.abs(np.arange(1 - nx, nx))).astype(np.float64)
        acf /= ry[:, None]
        acf /= rx[None, :]
        cnt = np.outer(ry, rx).astype(np.int64) if keep_pairs else None
    else:
        cnt = _full_correlation(ok.astype(np.float64))
        np.rint(cnt, out=cnt)
        with np.errstate(invalid="ignore", divide="ignore"):
            acf /= np.maximum(cnt, 1.0)
        acf[cnt < 0.5] = np.nan
        cnt = cnt.astype(np.int64)
    c0 = acf[ny - 1, nx - 1]
    if not c0 > 0:
        raise InputError("autocorrelation: the heights have zero variance (a flat map)")
    acf /= c0
    return acf, cnt


def autocorrelation(z: np.ndarray, *, mask: np.ndarray | None = None) -> np.ndarray:
    """Areal autocorrelation function of the mean-removed heights.

    ``f(tx, ty) = sum z(x, y) z(x + tx, y + ty) / N(tx, ty)`` over the pairs of valid points
    ``N(tx, ty)`` that overlap at lag (tx, ty) (the unbiased linear estimator: no
    wrap-around, no suppression of long lags; missing points simply do not pair),
    divided by its value at zero lag.  Computed with zero-padded FFTs.

    Returns
    -------
    acf : (2 ny - 1, 2 nx - 1) array
        Zero lag at index (ny - 1, nx - 1); NaN where no pairs overlap.
    pairs : same shape, int
        Number of point pairs behind each lag.
    """
    return _acf(z, mask)


def spatial_parameters(z: np.ndarray, *, pixel: float | tuple[float, float],
                       mask: np.ndarray | None = None, s: float = 0.2, n_directions: int = 360,
                       min_pairs_fraction: float = 0.05) -> dict:
    """Autocorrelation length Sal and texture aspect ratio Str (ISO 25178-2).

    The decay length in a direction is the lag distance at which the autocorrelation
    function (:func:`autocorrelation`) first falls to ``s`` along the ray from zero lag
    (linear interpolation between samples of the bilinearly interpolated ACF, rays every
    ``180 / n_directions`` degrees; the ACF is point-symmetric).  Sal is the shortest
    decay length (ISO: the horizontal distance of the fastest decay to ``s``); Str is the
    shortest over the longest.  A direction in which the ACF stays above ``s`` as far as
    the lags are supported by at least ``min_pairs_fraction`` of the points has no decay
    length within the field: Str is then undefined (NaN) and Sal comes from the
    directions that decay (NaN if none does).

    Parameters
    ----------
    z : (ny, nx) array
        Heights (form removed), mm; NaN = missing.
    pixel : float or (pixel_x, pixel_y)
        mm.
    s : float
        Threshold, 0 < s < 1 (ISO 25178-3 default 0.2).

    Returns
    -------
    dict
        ``Sal_mm``, ``Str``, ``s``, ``decays_in_all_directions`` (bool),
        ``fastest_direction_rad`` and ``slowest_direction_rad`` (from +x towards +y),
        ``longest_decay_mm`` (NaN when some direction does not decay).
    """
    check_range("s", s, 0.0, 1.0, lo_open=True, hi_open=True)
    px, py = pixel_xy(pixel)
    z = np.asarray(z, dtype=np.float64)
    ny, nx = z.shape
    n_valid = int(valid_mask(z, mask).sum())
    full = n_valid == z.size
    field, cnt = _acf(z, mask, keep_pairs=not full)
    # lags without enough pairs end a ray (inf spreads through the interpolation)
    min_pairs = max(4, min_pairs_fraction * n_valid)
    if full:  # pairs (ny - |ty|) (nx - |tx|), row by row
        ry = ny - np.abs(np.arange(1 - ny, ny))
        rx = nx - np.abs(np.arange(1 - nx, nx))
        for i in np.nonzero(ry * rx.min() < min_pairs)[0]:
            field[i, ry[i] * rx < min_pairs] = np.inf
    else:
        field[cnt < min_pairs] = np.inf
        del cnt
    np.nan_to_num(field, copy=False, nan=np.inf, posinf=np.inf)
    cy, cx = ny - 1, nx - 1
    theta = np.arange(int(n_directions)) * (np.pi / int(n_directions))
    sin_t, cos_t = np.sin(theta), np.cos(theta)
    step = 0.25 * min(px, py)
    rmax = np.hypot(px * (nx - 1), py * (ny - 1))
    r = np.arange(0.0, rmax + step, step)
    nt = theta.size
    lengths = np.full(nt, np.nan)
    ended = np.zeros(nt, dtype=bool)  # the ray left the supported lags without decaying
    prev = np.ones(nt)  # ACF at the last sample of the previous chunk (1 at zero lag)
    acc_sum, acc_n = np.zeros(nt), np.zeros(nt)
    chunk = 256
    for start in range(1, r.size, chunk):
        act = np.nonzero(np.isnan(lengths) & ~ended)[0]
        if act.size == 0:
            break
        rr = r[start:start + chunk]
        rows = cy + np.outer(sin_t[act], rr) / py
        cols = cx + np.outer(cos_t[act], rr) / px
        inside = (rows >= 0) & (rows <= 2 * ny - 2) & (cols >= 0) & (cols <= 2 * nx - 2)
        vals = ndimage.map_coordinates(field, [rows, cols], order=1, mode="constant", cval=np.inf)
        known = inside & np.isfinite(vals)
        n = rr.size
        first_unknown = np.where(known.all(axis=1), n, np.argmin(known, axis=1))
        below = (vals <= s) & known
        first_below = np.where(below.any(axis=1), np.argmax(below, axis=1), n)
        dec = first_below < first_unknown
        i, j = act[dec], first_below[dec]
        v1 = vals[dec, j]
        v0 = np.where(j > 0, vals[dec, np.maximum(j - 1, 0)], prev[i])
        r0 = rr[j] - step
        frac = np.where(v0 != v1, (v0 - s) / (v0 - v1), 0.0)
        lengths[i] = r0 + frac * step
        ended[act[~dec & (first_unknown < n)]] = True
        kv = np.where(known, vals, 0.0)
        acc_sum[act] += kv.sum(axis=1)
        acc_n[act] += known.sum(axis=1)
        prev[act] = vals[:, -1]
    decays = np.isfinite(lengths)
    out: dict[str, Any] = {"s": float(s), "decays_in_all_directions": bool(decays.all())}
    if not decays.any():
        warnings.warn(f"Sal: the autocorrelation does not fall to s = {s} within the field in "
                      f"any direction; the field is too small for the correlation length",
                      RuntimeWarning, stacklevel=2)
        out.update({"Sal_mm": float("nan"), "Str": float("nan"), "fastest_direction_rad": None,
                    "slowest_direction_rad": None, "longest_decay_mm": float("nan")})
        return out
    k = int(np.nanargmin(lengths))
    out["Sal_mm"] = float(lengths[k])
    out["fastest_direction_rad"] = float(theta[k])
    if decays.all():
        m = int(np.nanargmax(lengths))
        out["longest_decay_mm"] = float(lengths[m])
        out["slowest_direction_rad"] = float(theta[m])
        out["Str"] = float(lengths[k] / lengths[m])
    else:
        # the most persistent of the directions that do not decay: highest mean ACF
        acf_mean = acc_sum / np.maximum(acc_n, 1)
        m = int(np.argmax(np.where(decays, -np.inf, acf_mean)))
        out["longest_decay_mm"] = float("nan")
        out["slowest_direction_rad"] = float(theta[m])
        out["Str"] = float("nan")
    return out


def profile_parameters(profile: np.ndarray, *, spacing: float, n_sampling: int = 5) -> dict:
    """Profile parameters Ra, Rq, Rz, Rp, Rv, Rt (ISO 21920-2 / ISO 4287).

    Parameters
    ----------
    profile : (n,) array
        Heights along the section (NaN points are dropped; a profile with gaps is treated
        as contiguous, so filter or interpolate first where that matters).
    spacing : float
        Distance between points, mm (only used to report the lengths).
    n_sampling : int
        Number of sampling lengths the evaluation length is split into. ``Rz`` is the mean
        over the sampling lengths of (highest peak - lowest valley) in each, as ISO 4287;
        ``Rt`` is the peak-to-valley over the whole evaluation length.

    Returns
    -------
    dict
        ``Ra, Rq, Rz, Rp, Rv, Rt`` (unit of ``profile``; Rp/Rv are the means over the
        sampling lengths), ``evaluation_length_mm``, ``n_sampling``, ``n_points``.
    """
    p = np.asarray(profile, dtype=np.float64).ravel()
    check_positive("spacing", spacing)
    p = p[np.isfinite(p)]
    n_sampling = int(n_sampling)
    if n_sampling < 1:
        raise InputError(f"n_sampling must be >= 1, got {n_sampling}")
    if p.size < 2 * n_sampling:
        raise InputError(f"profile_parameters: need at least {2 * n_sampling} valid points for "
                         f"n_sampling={n_sampling}, got {p.size}")
    d = p - p.mean()
    parts = np.array_split(d, n_sampling)
    rp = np.mean([q.max() for q in parts])
    rv = np.mean([-q.min() for q in parts])
    return {"Ra": float(np.mean(np.abs(d))), "Rq": float(np.sqrt(np.mean(d * d))),
            "Rz": float(np.mean([q.max() - q.min() for q in parts])), "Rp": float(rp),
            "Rv": float(rv), "Rt": float(d.max() - d.min()),
            "evaluation_length_mm": float(spacing * (p.size - 1)), "n_sampling": n_sampling,
            "n_points": int(p.size)}


def extract_section(z: np.ndarray, *, pixel: float | tuple[float, float],
                    origin: Sequence[float] = (0.0, 0.0), kind: str = "radial",
                    center: Sequence[float] = (0.0, 0.0), angle: float = 0.0,
                    radius: float | None = None,
                    r_min: float = 0.0, r_max: float | None = None,
                    step: float | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Extract a radial or circumferential section from a height map (bilinear).

    Parameters
    ----------
    z : (ny, nx) array
        Heights (row 0 = smallest y), NaN = missing.
    pixel : float or (pixel_x, pixel_y)
        mm.
    origin : (x, y)
        Centre of pixel [0, 0], mm.
    kind : {"radial", "circumferential"}
        ``"radial"``: along the ray from ``center`` at ``angle`` (rad) from ``r_min`` to
        ``r_max``; ``"circumferential"``: the full circle of ``radius`` about ``center``.
    step : float, optional
        Distance between samples along the section, mm (default the smaller pixel).

    Returns
    -------
    s, values : (n,) arrays
        Arc length along the section (mm) and interpolated heights (NaN where any of the
        four neighbours is missing or the point is outside the map).
    """
    z = np.asarray(z, dtype=np.float64)
    sx, sy = pixel_xy(pixel)
    step = float(step or min(sx, sy))
    check_positive("step", step)
    ny, nx = z.shape
    cx, cy = center
    if kind == "radial":
        if r_max is None:
            xs = origin[0] + sx * np.array([0, nx - 1])
            ys = origin[1] + sy * np.array([0, ny - 1])
            r_max = float(np.max(np.hypot(xs[:, None] - cx, ys[None, :] - cy)))
        if not r_max > r_min:
            raise InputError(f"r_max must be > r_min ({r_min} mm), got {r_max}")
        s = np.arange(r_min, r_max + 1e-12, step)
        px, py = cx + s * np.cos(angle), cy + s * np.sin(angle)
        s = s - r_min
    elif kind == "circumferential":
        if radius is None:
            raise InputError("extract_section: kind='circumferential' needs radius= (mm)")
        check_positive("radius", radius)
        n = max(8, int(np.ceil(2 * np.pi * radius / step)))
        t = np.arange(n) * (2 * np.pi / n)
        px, py = cx + radius * np.cos(t), cy + radius * np.sin(t)
        s = radius * t
    else:
        raise InputError(f"kind must be 'radial' or 'circumferential', got {kind!r}")
    col = (px - origin[0]) / sx
    row = (py - origin[1]) / sy
    ok = np.isfinite(z)
    vals = ndimage.map_coordinates(np.where(ok, z, 0.0), [row, col], order=1, mode="constant",
                                   cval=np.nan)
    bad = ndimage.map_coordinates((~ok).astype(np.float64), [row, col], order=1, mode="constant",
                                  cval=1.0)
    inside = (row >= 0) & (row <= ny - 1) & (col >= 0) & (col <= nx - 1)
    vals = np.where(inside & (bad < 1e-9), vals, np.nan)
    return s, vals


def section_parameters(z: np.ndarray, *, pixel: float | tuple[float, float],
                       origin: Sequence[float] = (0.0, 0.0), center: Sequence[float] = (0.0, 0.0),
                       angles: Iterable[float] = (0.0,), radii: Iterable[float] = (),
                       n_sampling: int = 5) -> dict:
    """Ra, Rq, Rz on radial sections (at ``angles``, rad) and circumferential sections
    (at ``radii``, mm) of a map.  Returns ``{"radial": [...], "circumferential": [...]}``,
    each entry the :func:`profile_parameters` dict plus ``angle_rad`` / ``radius_mm``;
    sections with too few valid points are skipped and listed under ``"skipped"``."""
    out: dict[str, list] = {"radial": [], "circumferential": [], "skipped": []}
    for a in angles:
        _, v = extract_section(z, pixel=pixel, origin=origin, kind="radial", center=center,
                               angle=float(a))
        if np.isfinite(v).sum() < 2 * n_sampling:
            out["skipped"].append({"angle_rad": float(a)})
            continue
        out["radial"].append({"angle_rad": float(a),
                              **profile_parameters(v, spacing=min(pixel_xy(pixel)), n_sampling=n_sampling)})
    for r in radii:
        _, v = extract_section(z, pixel=pixel, origin=origin, kind="circumferential",
                               center=center, radius=float(r))
        if np.isfinite(v).sum() < 2 * n_sampling:
            out["skipped"].append({"radius_mm": float(r)})
            continue
        out["circumferential"].append({"radius_mm": float(r),
                                       **profile_parameters(v, spacing=min(pixel_xy(pixel)), n_sampling=n_sampling)})
    return out
