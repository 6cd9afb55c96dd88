"""Areal (ISO 25178-2) and profile (ISO 21920-2 / ISO 4287) parameters.

Areal parameters are taken about the mean plane of the valid points (remove the form
first with :func:`remove_form`).  Sdq and Sdr use central differences (``numpy.gradient``,
one-sided at the border and next to missing points); Sdr integrates
``sqrt(1 + zx^2 + zy^2) - 1`` over the valid points, in %.
"""

from __future__ import annotations

import numpy as np
from scipy import ndimage

from ..core.errors import InputError, check_positive
from ._filters import valid_mask

__all__ = ["areal_parameters", "profile_parameters", "extract_section", "section_parameters"]


def areal_parameters(z, *, pixel: float, mask=None) -> dict:
    """ISO 25178-2 areal parameters of a height map.

    Parameters
    ----------
    z : (ny, nx) array
        Heights (any length unit; Sa..Sz come back in it). NaN marks missing points.
    pixel : float
        Sampling distance in the unit of ``z`` **and** mm-consistent with it: Sdq and Sdr
        are slopes, so ``z`` and ``pixel`` must share a unit (pass both in mm).
    mask : bool array, optional
        ``False`` leaves a point out.

    Returns
    -------
    dict
        ``Sa, Sq, Sp, Sv, Sz, Ssk, Sku`` (heights about the mean; Sv is positive, the depth
        of the lowest valley), ``Sdq`` (root mean square gradient, dimensionless), ``Sdr``
        (developed interfacial area ratio, %), ``n_valid``.
    """
    z = np.asarray(z, dtype=np.float64)
    if z.ndim != 2:
        raise InputError(f"z must be a 2-D height map, got shape {z.shape}")
    check_positive("pixel", pixel)
    ok = valid_mask(z, mask)
    n = int(ok.sum())
    if n < 2:
        raise InputError(f"areal_parameters: need at least 2 valid (finite, unmasked) points, got {n}")
    v = z[ok]
    d = v - v.mean()
    d2 = d * d
    sq = float(np.sqrt(np.mean(d2)))
    out = {"Sa": float(np.mean(np.abs(d))), "Sq": sq, "Sp": float(d.max()), "Sv": float(-d.min())}
    out["Sz"] = out["Sp"] + out["Sv"]
    out["Ssk"] = float(np.mean(d2 * d) / sq ** 3) if sq > 0 else 0.0
    out["Sku"] = float(np.mean(d2 * d2) / sq ** 4) if sq > 0 else 0.0
    del d, d2
    zz = z if ok.all() else np.where(ok, z, np.nan)
    if min(z.shape) >= 2:
        gy, gx = np.gradient(zz, float(pixel))
        g2 = gx * gx + gy * gy
        gok = np.isfinite(g2)
        if gok.any():
            out["Sdq"] = float(np.sqrt(np.mean(g2[gok])))
            out["Sdr"] = float(100.0 * np.mean(np.sqrt(1.0 + g2[gok]) - 1.0))
        else:
            out["Sdq"] = out["Sdr"] = float("nan")
    out["n_valid"] = n
    return out


def profile_parameters(profile, *, spacing: float, n_sampling: int = 5) -> dict:
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


def extract_section(z, *, pixel: float, origin=(0.0, 0.0), kind: str = "radial",
                    center=(0.0, 0.0), angle: float = 0.0, radius: float | None = None,
                    r_min: float = 0.0, r_max: float | None = None, step: float | None = None):
    """Extract a radial or circumferential section from a height map (bilinear).

    Parameters
    ----------
    z : (ny, nx) array
        Heights (row 0 = smallest y), NaN = missing.
    pixel : float
        mm.
    origin : (x, y)
        Centre of pixel [0, 0], mm.
    kind : {"radial", "circumferential"}
        ``"radial"``: along the ray from ``center`` at ``angle`` (rad) from ``r_min`` to
        ``r_max``; ``"circumferential"``: the full circle of ``radius`` about ``center``.
    step : float, optional
        Distance between samples along the section, mm (default ``pixel``).

    Returns
    -------
    s, values : (n,) arrays
        Arc length along the section (mm) and interpolated heights (NaN where any of the
        four neighbours is missing or the point is outside the map).
    """
    z = np.asarray(z, dtype=np.float64)
    check_positive("pixel", pixel)
    step = float(step or pixel)
    check_positive("step", step)
    ny, nx = z.shape
    cx, cy = center
    if kind == "radial":
        if r_max is None:
            xs = origin[0] + pixel * np.array([0, nx - 1])
            ys = origin[1] + pixel * np.array([0, ny - 1])
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
    col = (px - origin[0]) / pixel
    row = (py - origin[1]) / pixel
    ok = np.isfinite(z)
    vals = ndimage.map_coordinates(np.where(ok, z, 0.0), [row, col], order=1, mode="constant",
                                   cval=np.nan)
    bad = ndimage.map_coordinates((~ok).astype(np.float64), [row, col], order=1, mode="constant",
                                  cval=1.0)
    inside = (row >= 0) & (row <= ny - 1) & (col >= 0) & (col <= nx - 1)
    vals = np.where(inside & (bad < 1e-9), vals, np.nan)
    return s, vals


def section_parameters(z, *, pixel: float, origin=(0.0, 0.0), center=(0.0, 0.0),
                       angles=(0.0,), radii=(), n_sampling: int = 5) -> dict:
    """Ra, Rq, Rz on radial sections (at ``angles``, rad) and circumferential sections
    (at ``radii``, mm) of a map.  Returns ``{"radial": [...], "circumferential": [...]}``,
    each entry the :func:`profile_parameters` dict plus ``angle_rad`` / ``radius_mm``;
    sections with too few valid points are skipped and listed under ``"skipped"``."""
    out = {"radial": [], "circumferential": [], "skipped": []}
    for a in angles:
        _, v = extract_section(z, pixel=pixel, origin=origin, kind="radial", center=center,
                               angle=float(a))
        if np.isfinite(v).sum() < 2 * n_sampling:
            out["skipped"].append({"angle_rad": float(a)})
            continue
        out["radial"].append({"angle_rad": float(a),
                              **profile_parameters(v, spacing=pixel, n_sampling=n_sampling)})
    for r in radii:
        _, v = extract_section(z, pixel=pixel, origin=origin, kind="circumferential",
                               center=center, radius=float(r))
        if np.isfinite(v).sum() < 2 * n_sampling:
            out["skipped"].append({"radius_mm": float(r)})
            continue
        out["circumferential"].append({"radius_mm": float(r),
                                       **profile_parameters(v, spacing=pixel, n_sampling=n_sampling)})
    return out
