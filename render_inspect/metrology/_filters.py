"""ISO 16610-61 areal Gaussian filters (S and L) and form removal.

The Gaussian weighting function of ISO 16610-61 is

    s(x) = 1 / (alpha lambda) exp(-pi (x / (alpha lambda))^2),  alpha = sqrt(ln 2 / pi)

so its standard deviation is ``sigma = alpha lambda / sqrt(2 pi)`` (0.1874 lambda), and a
sinusoid of wavelength ``lambda`` (the cut-off or nesting index) is passed at 50 %.
Missing points (NaN or ``mask == False``) are handled by a masked, normalised
convolution: the filter of ``z * w`` divided by the filter of ``w`` (``w`` = 1 where valid).
At the map's edges (``edges=``): ``"normalised"`` (default) uses only the points inside
(the weighting function is cut off and renormalised, so near an edge the filter is
one-sided and passes more of the short wavelengths); ``"mirror"`` extends the map by its
mirror image (ISO 16610-28's symmetric extension); ``"cut"`` drops the border where the
weighting function reaches outside the map: half the nesting index on every side (the
run-in/run-out of ISO 16610-21, 4.7 standard deviations of the Gaussian).
"""

from __future__ import annotations

import math

import numpy as np
from scipy import ndimage

from ..core.errors import InputError, check_positive

__all__ = ["GAUSSIAN_ALPHA", "gaussian_sigma", "gaussian_filter", "s_filter", "l_filter",
           "remove_form", "valid_mask", "EDGE_MODES", "gaussian_transmission"]

#: edge handling of the Gaussian filters (see the module docstring)
EDGE_MODES = ("normalised", "mirror", "cut")

#: alpha of the ISO 16610-61 Gaussian weighting function, sqrt(ln 2 / pi) = 0.4697
GAUSSIAN_ALPHA = math.sqrt(math.log(2.0) / math.pi)


def valid_mask(z, mask=None, *, name: str = "z") -> np.ndarray:
    """Boolean array: finite values of ``z`` that are also ``True`` in ``mask``."""
    z = np.asarray(z)
    ok = np.isfinite(z)
    if mask is not None:
        mask = np.asarray(mask, dtype=bool)
        if mask.shape != z.shape:
            raise InputError(f"mask must have the shape of {name} {z.shape}, got {mask.shape}")
        ok &= mask
    return ok


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


def gaussian_transmission(wavelength, cutoff):
    """Amplitude transmission of the ISO 16610-61 Gaussian mean-line filter for a sinusoid
    of ``wavelength`` (same unit as ``cutoff``): ``exp(-pi (alpha cutoff / wavelength)^2)``
    (0.5 at the cut-off).  The S-filter passes this fraction, the L-filter one minus it."""
    check_positive("cutoff", cutoff)
    w = np.asarray(wavelength, dtype=np.float64)
    return np.exp(-math.pi * (GAUSSIAN_ALPHA * float(cutoff) / w) ** 2)


def _cut_border(out, cutoff, pixel):
    n = int(math.ceil(0.5 * float(cutoff) / float(pixel) - 1e-9))
    if n > 0:
        out[:n] = np.nan
        out[-n:] = np.nan
        out[:, :n] = np.nan
        out[:, -n:] = np.nan
    return out


def gaussian_filter(z, *, pixel: float, cutoff: float, mask=None, min_weight: float = 1e-3,
                    edges: str = "normalised"):
    """Gaussian mean surface of ``z`` (ISO 16610-61), NaN-aware.

    Parameters
    ----------
    z : (ny, nx) array
        Heights (any unit; returned in the same unit). NaN marks missing points.
    pixel : float
        Sampling distance, mm.
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
    check_positive("pixel", pixel)
    if edges not in EDGE_MODES:
        raise InputError(f"edges must be one of {EDGE_MODES}, got {edges!r}")
    sigma_px = gaussian_sigma(cutoff) / float(pixel)
    ok = valid_mask(z, mask)
    if not ok.any():
        raise InputError("gaussian_filter: the map has no valid (finite, unmasked) points")
    w = ok.astype(np.float64)
    mode = "reflect" if edges == "mirror" else "constant"
    num = ndimage.gaussian_filter(np.where(ok, z, 0.0), sigma_px, mode=mode, truncate=4.0)
    den = ndimage.gaussian_filter(w, sigma_px, mode=mode, truncate=4.0)
    out = np.full_like(z, np.nan)
    good = ok & (den > min_weight)
    out[good] = num[good] / den[good]
    if edges == "cut":
        _cut_border(out, cutoff, pixel)
    return out


def s_filter(z, *, pixel: float, nesting_index: float, mask=None, edges: str = "normalised"):
    """S-filter: remove wavelengths shorter than ``nesting_index`` (mm) by Gaussian
    smoothing (``edges``: see :func:`gaussian_filter`)."""
    return gaussian_filter(z, pixel=pixel, cutoff=nesting_index, mask=mask, edges=edges)


def l_filter(z, *, pixel: float, nesting_index: float, mask=None, edges: str = "normalised"):
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


def remove_form(z, *, pixel: float, method: str = "plane", degree: int = 2, design=None,
                origin=(0.0, 0.0), mask=None):
    """Remove the form of a height map.

    Parameters
    ----------
    z : (ny, nx) array
        Heights, mm (NaN = missing).
    pixel : float
        Sampling distance, mm.
    method : {"none", "plane", "polynomial", "design"}
        ``"plane"``: least-squares plane; ``"polynomial"``: least-squares 2-D Legendre
        polynomial of total degree ``degree`` in coordinates scaled to [-1, 1];
        ``"design"``: subtract ``design`` (a same-shape array, or an object with
        ``height(x, y)`` evaluated on the grid of ``origin``/``pixel``) and then the mean.
        The design must already be registered to the map (see :func:`register_lsq`).
    degree : int
        Polynomial degree for ``method="polynomial"`` (1..10).
    design : array or Surface, optional
        Required for ``method="design"``.
    origin : (x, y)
        Centre of pixel [0, 0], mm (used with a Surface design).
    mask : bool array, optional
        Points to use for the fit (and to keep); ``False`` and NaN are left out.

    Returns
    -------
    residual, form : (ny, nx) arrays
        ``residual = z - form``; NaN where ``z`` is invalid.
    """
    z = _as_map(z)
    check_positive("pixel", pixel)
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
    elif method == "design":
        if design is None:
            raise InputError("remove_form: method='design' needs design= (array or Surface)")
        if hasattr(design, "height"):
            x = origin[0] + pixel * np.arange(nx)
            y = origin[1] + pixel * np.arange(ny)
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
        raise InputError(f"method must be one of 'none', 'plane', 'polynomial', 'design', got {method!r}")
    res = np.where(ok, z - form, np.nan)
    return res, form
