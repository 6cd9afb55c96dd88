"""ISO 16610-61 areal Gaussian filters (S and L) and form removal.

The Gaussian weighting function of ISO 16610-61 [1]_ is

    s(x) = 1 / (alpha lambda) exp(-pi (x / (alpha lambda))^2),  alpha = sqrt(ln 2 / pi)

so its standard deviation is ``sigma = alpha lambda / sqrt(2 pi)`` (0.1874 lambda), and a
sinusoid of wavelength ``lambda`` (the cut-off or nesting index) is passed at 50 %.
Missing points (NaN or ``mask == False``) are handled by a masked, normalised
convolution: the filter of ``z * w`` divided by the filter of ``w`` (``w`` = 1 where valid).
At the map's edges (``edges=``): ``"normalised"`` (default) uses only the points inside
(the weighting function is cut off and renormalised, so near an edge the filter is
one-sided and passes more of the short wavelengths); ``"mirror"`` extends the map by its
mirror image (ISO 16610-28's symmetric extension [2]_); ``"cut"`` drops the border where
the weighting function reaches outside the map: half the nesting index on every side (the
run-in/run-out of ISO 16610-21 [3]_, 2.7 standard deviations of the Gaussian; the
weights are computed out to 4 standard deviations, so a little of the border still reaches
inside).

References
----------
.. [1] ISO 16610-61:2015, Geometrical product specification (GPS) - Filtration - Part 61:
       Linear areal filters - Gaussian filters.
.. [2] ISO 16610-28, Geometrical product specifications (GPS) - Filtration - Part 28:
       Profile filters: End effects.
.. [3] ISO 16610-21, Geometrical product specifications (GPS) - Filtration - Part 21:
       Linear profile filters: Gaussian filters.
"""

from __future__ import annotations

from collections.abc import Sequence
import math
from typing import Any, cast

import numpy as np
from ..core.lazy import lazy_module

from ..core import cancel
from ..core.errors import InputError, check_positive

#: SciPy, imported on first use (render_inspect.core.lazy)
ndimage = lazy_module("scipy.ndimage")

__all__ = ["GAUSSIAN_ALPHA", "gaussian_sigma", "gaussian_filter", "s_filter", "l_filter",
           "remove_form", "valid_mask", "pixel_xy", "fit_sphere", "EDGE_MODES",
           "gaussian_transmission"]

#: edge handling of the Gaussian filters (see the module docstring)
EDGE_MODES = ("normalised", "mirror", "cut")

#: alpha of the ISO 16610-61 Gaussian weighting function, sqrt(ln 2 / pi) = 0.4697
GAUSSIAN_ALPHA = math.sqrt(math.log(2.0) / math.pi)


def valid_mask(z: np.ndarray, mask: np.ndarray | None = None, *, name: str = "z") -> np.ndarray:
    """Boolean array: finite values of ``z`` that are also ``True`` in ``mask``."""
    z = np.asarray(z)
    ok = np.isfinite(z)
    if mask is not None:
        mask = np.asarray(mask, dtype=bool)
        if mask.shape != z.shape:
            raise InputError(f"mask must have the shape of {name} {z.shape}, got {mask.shape}")
        ok &= mask
    return ok


def pixel_xy(pixel: float | Sequence[float], name: str = "pixel") -> tuple[float, float]:
    """``(pixel_x, pixel_y)`` (mm) from one number (square pixels) or a pair; both > 0."""
    if np.ndim(pixel) == 0:
        check_positive(name, pixel)
        return float(cast(float, pixel)), float(cast(float, pixel))  # (one number: np.ndim 0)
    p = tuple(np.asarray(pixel, dtype=np.float64).ravel())
    if len(p) != 2:
        raise InputError(f"{name} must be one number or (pixel_x, pixel_y) in mm, got {pixel!r}")
    check_positive(f"{name}_x", p[0])
    check_positive(f"{name}_y", p[1])
    return float(p[0]), float(p[1])


def _as_map(z, name="z") -> np.ndarray:
    z = np.asarray(z, dtype=np.float64)
    if z.ndim != 2 or min(z.shape) < 2:
        raise InputError(f"{name} must be a 2-D height map of at least 2 x 2 points, got shape {z.shape}")
    return z


def gaussian_sigma(cutoff: float) -> float:
    """Standard deviation (same unit as ``cutoff``) of the ISO 16610-61 Gaussian weighting
    function for the cut-off / nesting index ``cutoff``: alpha lambda / sqrt(2 pi)."""
    check_positive("cutoff", cutoff)
    return GAUSSIAN_ALPHA * float(cutoff) / math.sqrt(2.0 * math.pi)


def gaussian_transmission(wavelength: float | np.ndarray, cutoff: float) -> Any:
    """Amplitude transmission of the ISO 16610-61 Gaussian mean-line filter for a sinusoid
    of ``wavelength`` (same unit as ``cutoff``): ``exp(-pi (alpha cutoff / wavelength)^2)``
    (0.5 at the cut-off).  The S-filter passes this fraction, the L-filter one minus it."""
    check_positive("cutoff", cutoff)
    w = np.asarray(wavelength, dtype=np.float64)
    return np.exp(-math.pi * (GAUSSIAN_ALPHA * float(cutoff) / w) ** 2)


def _cut_border(out, cutoff, pixel):
    px, py = pixel_xy(pixel)
    n_rows = int(math.ceil(0.5 * float(cutoff) / py - 1e-9))
    n_cols = int(math.ceil(0.5 * float(cutoff) / px - 1e-9))
    if n_rows > 0:
        out[:n_rows] = np.nan
        out[-n_rows:] = np.nan
    if n_cols > 0:
        out[:, :n_cols] = np.nan
        out[:, -n_cols:] = np.nan
    return out


def gaussian_filter(z: np.ndarray, *, pixel: float | tuple[float, float], cutoff: float,
                    mask: np.ndarray | None = None, min_weight: float = 1e-3,
                    edges: str = "normalised") -> np.ndarray:
    """Gaussian mean surface of ``z`` (ISO 16610-61), NaN-aware.

    Parameters
    ----------
    z : (ny, nx) array
        Heights (any unit; returned in the same unit). NaN marks missing points.
    pixel : float or (pixel_x, pixel_y)
        Sampling distance, mm (the filter is isotropic in mm on non-square pixels).
    cutoff : float
        Cut-off wavelength / nesting index lambda, mm (50 % transmission).
    mask : (ny, nx) bool array, optional
        ``False`` marks points to leave out (as NaN does).
    min_weight : float
        Where the normalising weight falls below this (no valid data within reach) the
        result is NaN.
    edges : {"normalised", "mirror", "cut"}
        Edge handling (module docstring): renormalised one-sided weights, mirror
        extension, or NaN within ``cutoff / 2`` of the map's border.

    Returns
    -------
    (ny, nx) array
        The smoothed (mean) surface; NaN where ``z`` was invalid (and, with
        ``edges="cut"``, in the border).
    """
    z = _as_map(z)
    px, py = pixel_xy(pixel)
    if edges not in EDGE_MODES:
        raise InputError(f"edges must be one of {EDGE_MODES}, got {edges!r}")
    sig = gaussian_sigma(cutoff)
    sigma_px = (sig / py, sig / px)  # (rows, columns)
    ok = valid_mask(z, mask)
    if not ok.any():
        raise InputError("gaussian_filter: the map has no valid (finite, unmasked) points")
    w = ok.astype(np.float64)
    mode = "reflect" if edges == "mirror" else "constant"
    num = _gaussian_in_blocks(np.where(ok, z, 0.0), sigma_px, mode)
    den = _gaussian_in_blocks(w, sigma_px, mode)
    out = np.full_like(z, np.nan)
    good = ok & (den > min_weight)
    out[good] = num[good] / den[good]
    if edges == "cut":
        _cut_border(out, cutoff, pixel)
    return out


#: multiply-adds of one block of :func:`_gaussian_in_blocks` (about 0.1-0.3 s)
_BLOCK_WORK = 2e8


def _gaussian_in_blocks(a, sigma_px, mode: str):
    """``ndimage.gaussian_filter(a, sigma_px, mode=mode, truncate=4.0)`` (the same numbers:
    the separable filter along the rows' axis, then the columns'), computed a band of lines
    at a time with a stop check between bands: a long cut-off on a large map takes minutes
    in one call otherwise, deaf to Ctrl-C."""
    out = np.asarray(a, dtype=np.float64)
    for axis, sigma in enumerate(sigma_px):
        if sigma <= 1e-15:  # (as ndimage skips it)
            continue
        taps = 2 * int(4.0 * float(sigma) + 0.5) + 1
        length = out.shape[axis]
        lines = out.shape[1 - axis]
        step = max(1, int(_BLOCK_WORK // max(length * taps, 1)))
        res = np.empty_like(out)
        for i0, i1 in cancel.blocks(lines, step):
            band = (slice(None), slice(i0, i1)) if axis == 0 else (slice(i0, i1), slice(None))
            ndimage.gaussian_filter1d(out[band], float(sigma), axis=axis, mode=mode,
                                      truncate=4.0, output=res[band])
        out = res
    return out


def s_filter(z: np.ndarray, *, pixel: float | tuple[float, float], nesting_index: float,
             mask: np.ndarray | None = None, edges: str = "normalised") -> np.ndarray:
    """S-filter: remove wavelengths shorter than ``nesting_index`` (mm) by Gaussian
    smoothing (``edges``: see :func:`gaussian_filter`)."""
    return gaussian_filter(z, pixel=pixel, cutoff=nesting_index, mask=mask, edges=edges)


def l_filter(z: np.ndarray, *, pixel: float | tuple[float, float], nesting_index: float,
             mask: np.ndarray | None = None, edges: str = "normalised") -> np.ndarray:
    """L-filter: remove wavelengths longer than ``nesting_index`` (mm): ``z`` minus its
    Gaussian mean surface (``edges``: see :func:`gaussian_filter`)."""
    z = _as_map(z)
    return z - gaussian_filter(z, pixel=pixel, cutoff=nesting_index, mask=mask, edges=edges)


def _legendre_design(u, v, degree):
    from numpy.polynomial import legendre

    cols = []
    eye = np.eye(degree + 1)
    pu = [legendre.legval(u, eye[i]) for i in range(degree + 1)]
    pv = [legendre.legval(v, eye[i]) for i in range(degree + 1)]
    for total in range(degree + 1):
        for i in range(total + 1):
            cols.append(pu[i] * pv[total - i])
    return np.stack(cols, axis=-1)


def _sag(kappa, rho2):
    """Sphere sag of curvature ``kappa`` (1/mm) at squared distance ``rho2`` from its apex,
    in the form that stays exact as ``kappa`` -> 0: kappa rho^2 / (1 + sqrt(1 - kappa^2 rho^2))."""
    arg = 1.0 - kappa * kappa * rho2
    return np.where(arg >= 0, kappa * rho2 / (1.0 + np.sqrt(np.maximum(arg, 0.0))), np.nan)


def fit_sphere(z: np.ndarray, *, pixel: float | tuple[float, float],
               origin: Sequence[float] = (0.0, 0.0), mask: np.ndarray | None = None,
               max_points: int = 200_000,
               seed: int = 0) -> dict:
    """Least-squares sphere (vertical distances) through a height map.

    Start: the paraboloid ``c0 + c1 x + c2 y + c3 (x^2 + y^2)`` (curvature ``2 c3``, apex
    at ``-(c1, c2) / (2 c3)``); then the exact sphere ``z = z0 + sag(kappa, (x - a)^2 +
    (y - b)^2)`` is fitted by scipy ``least_squares`` (trust region) on at most
    ``max_points`` points (a seeded random subset).

    Parameters
    ----------
    z : (ny, nx) array
        Heights, mm (NaN = missing).
    pixel : float or (pixel_x, pixel_y)
        mm.
    origin : (x, y)
        Centre of pixel [0, 0], mm.

    Returns
    -------
    dict
        ``radius_mm`` (signed: > 0 when the centre lies above the surface, i.e. concave
        up; ``inf`` for a plane), ``apex_mm`` (x, y, z of the apex), ``curvature_per_mm``,
        ``rms_mm`` (residual RMS), ``form`` ((ny, nx) array, mm).
    """
    from scipy.optimize import least_squares

    z = _as_map(z)
    px, py = pixel_xy(pixel)
    ok = valid_mask(z, mask)
    if ok.sum() < 4:
        raise InputError(f"fit_sphere: need at least 4 valid points, got {int(ok.sum())}")
    ny, nx = z.shape
    x = origin[0] + px * np.arange(nx)
    y = origin[1] + py * np.arange(ny)
    xm, ym = float(x.mean()), float(y.mean())  # work about the field centre (conditioning)
    xx, yy = np.meshgrid(x - xm, y - ym)
    fx, fy, fz = xx[ok], yy[ok], z[ok]
    if fz.size > max_points:
        idx = np.sort(np.random.default_rng(seed).choice(fz.size, max_points, replace=False))
        fx, fy, fz = fx[idx], fy[idx], fz[idx]
    a = np.column_stack([np.ones_like(fx), fx, fy, fx * fx + fy * fy])
    c, *_ = np.linalg.lstsq(a, fz, rcond=None)
    half = 0.5 * np.hypot(px * (nx - 1), py * (ny - 1))
    kappa0 = 2.0 * c[3]
    if abs(kappa0) * half < 1e-9 * max(1.0, half):  # not a unit conversion: a tolerance
        # no measurable curvature: the best sphere is the plane (infinite radius)
        form = c[0] + c[1] * xx + c[2] * yy
        res = np.where(ok, z - form, np.nan)
        return {"radius_mm": float("inf"), "curvature_per_mm": 0.0,
                "apex_mm": [xm, ym, float(c[0])], "rms_mm": float(np.sqrt(np.nanmean(res ** 2))),
                "form": form}
    a0, b0 = -c[1] / kappa0, -c[2] / kappa0
    z0 = c[0] - 0.5 * kappa0 * (a0 * a0 + b0 * b0)

    def resid(p):
        r = fz - p[2] - _sag(p[3], (fx - p[0]) ** 2 + (fy - p[1]) ** 2)
        # where the sag is undefined: a residual far above any finite one
        far = 1e3 * (np.nanmax(np.abs(fz)) + 1.0)  # not a unit conversion
        return np.where(np.isfinite(r), r, far)

    scale = [half, half, max(float(np.ptp(fz)), 1e-9), abs(kappa0)]
    sol = least_squares(resid, [a0, b0, z0, kappa0], x_scale=scale, method="trf",
                        xtol=1e-14, ftol=1e-15, gtol=1e-15, max_nfev=200)
    ca, cb, cz, kap = sol.x
    form = cz + _sag(kap, (xx - ca) ** 2 + (yy - cb) ** 2)
    res = np.where(ok, z - form, np.nan)
    if not np.isfinite(form[ok]).all():
        raise InputError("fit_sphere: the best-fit sphere is smaller than the map (radius "
                         f"{1 / abs(kap):.4g} mm); the data is not a spherical cap")
    return {"radius_mm": float(1.0 / kap), "curvature_per_mm": float(kap),
            "apex_mm": [float(ca + xm), float(cb + ym), float(cz)],
            "rms_mm": float(np.sqrt(np.nanmean(res ** 2))), "form": form}


def remove_form(z: np.ndarray, *, pixel: float | Sequence[float], method: str = "plane",
                degree: int = 2, design: Any = None,
                origin: Sequence[float] = (0.0, 0.0),
                mask: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Remove the form of a height map.

    Parameters
    ----------
    z : (ny, nx) array
        Heights, mm (NaN = missing).
    pixel : float or (pixel_x, pixel_y)
        Sampling distance, mm.
    method : {"none", "plane", "polynomial", "sphere", "design"}
        ``"none"``: nothing (parameters are taken about the mean anyway);
        ``"plane"``: least-squares plane; ``"polynomial"``: least-squares 2-D Legendre
        polynomial of total degree ``degree`` in coordinates scaled to [-1, 1];
        ``"sphere"``: least-squares sphere (:func:`fit_sphere`);
        ``"design"``: subtract ``design`` (a same-shape array, or an object with
        ``height(x, y)`` evaluated on the grid of ``origin``/``pixel``) and then the mean.
        The design must already be registered to the map (see :func:`register_lsq`).
    degree : int
        Polynomial degree for ``method="polynomial"`` (1..10).
    design : array or Surface, optional
        Required for ``method="design"``.
    origin : (x, y)
        Centre of pixel [0, 0], mm (used with a Surface design and the sphere).
    mask : bool array, optional
        Points to use for the fit (and to keep); ``False`` and NaN are left out.

    Returns
    -------
    residual, form : (ny, nx) arrays
        ``residual = z - form``; NaN where ``z`` is invalid.
    """
    z = _as_map(z)
    px, py = pixel_xy(pixel)
    ok = valid_mask(z, mask)
    if not ok.any():
        raise InputError("remove_form: the map has no valid (finite, unmasked) points")
    ny, nx = z.shape
    if method == "none":
        form = np.zeros_like(z)
    elif method in ("plane", "polynomial"):
        deg = 1 if method == "plane" else int(degree)
        if not 1 <= deg <= 10:
            raise InputError(f"degree must be in [1, 10], got {degree!r}")
        nterms = (deg + 1) * (deg + 2) // 2
        if ok.sum() < nterms:
            raise InputError(f"remove_form: {method} of degree {deg} needs at least {nterms} valid "
                             f"points, the map has {int(ok.sum())}")
        u = np.linspace(-1.0, 1.0, nx) if nx > 1 else np.zeros(1)
        v = np.linspace(-1.0, 1.0, ny) if ny > 1 else np.zeros(1)
        uu, vv = np.meshgrid(u, v)
        a = _legendre_design(uu, vv, deg)
        coef, *_ = np.linalg.lstsq(a[ok], z[ok], rcond=None)
        form = a @ coef
    elif method == "sphere":
        form = fit_sphere(z, pixel=(px, py), origin=origin, mask=ok)["form"]
    elif method == "design":
        if design is None:
            raise InputError("remove_form: method='design' needs design= (array or Surface)")
        if hasattr(design, "height"):
            x = origin[0] + px * np.arange(nx)
            y = origin[1] + py * np.arange(ny)
            d = np.broadcast_to(design.height(x[None, :], y[:, None]), z.shape).astype(np.float64)
        else:
            d = np.asarray(design, dtype=np.float64)
            if d.shape != z.shape:
                raise InputError(f"remove_form: design shape {d.shape} differs from the map's {z.shape}")
        ok &= np.isfinite(d)
        if not ok.any():
            raise InputError("remove_form: design and map have no valid points in common")
        form = d + np.mean((z - d)[ok])
    else:
        raise InputError(f"method must be one of 'none', 'plane', 'polynomial', 'sphere', "
                         f"'design', got {method!r}")
    res = np.where(ok, z - form, np.nan)
    return res, form
