"""Outliers of measured maps and profiles: spikes (the default), or every sharp feature by
the second-difference rule of Kong et al. (2020), step 1.

References
----------
L. Kong, Y. Ma, M. Ren, M. Xu, C.-F. Cheung, "Generation and characterization of
ultra-precision compound freeform surfaces," Science Progress 103(1), 1-12 (2020): the
second-difference k-sigma rule (the ``curvature`` rule here).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from ..core.lazy import lazy_module

from ..core.errors import InputError, check_positive
from ._filters import pixel_xy, valid_mask

#: SciPy, imported on first use (render_inspect.core.lazy)
ndimage = lazy_module("scipy.ndimage")

__all__ = ["detect_outliers", "SPIKE_NEIGHBOUR_SHARE"]


#: a spike's neighbours carry half its second difference each (h against -2 h); a quarter
#: leaves room for the surface under it
SPIKE_NEIGHBOUR_SHARE = 0.25


def detect_outliers(z: np.ndarray, *, pixel: Any, k: float = 3.0,
                    mask: np.ndarray | None = None, replace: bool = True,
                    min_sigma_mm: float = 1e-7,
                    rule: str = "spike") -> tuple[np.ndarray, np.ndarray]:
    """Outliers of a measured map or profile: spikes, not curvature.

    ``rule="spike"`` (the default): a single point raised (or dropped) by ``h`` adds
    ``(h, -2 h, h)`` to the second differences ``f(x - d) - 2 f(x) + f(x + d)`` at the
    point and its two neighbours.  A point is a spike when its second difference exceeds
    ``k`` sigma (``1.4826 * MAD`` of all second differences, at least ``min_sigma_mm``) and
    both neighbours' second differences have the opposite sign and at least
    :data:`SPIKE_NEIGHBOUR_SHARE` of its size -- along x and along y (in the one direction
    a profile or a one-row map has).  The tip of a turning cusp (two tool arcs meeting at
    an edge) changes the slope once: its neighbours keep the small curvature of the arcs;
    a tip rounded by the instrument over a few pixels curves the same way at all of them;
    neither has a spike's signature, so sharp but real features are kept.

    ``rule="curvature"``: the second-difference ``k``-sigma rule of Kong et al. 2020 (step
    1): ``f'' = (f(x - d) + f(x + d) - 2 f(x)) / d^2``; a point whose ``|f'' - median(f'')|``
    exceeds ``k`` sigma (``1.4826 * MAD``, at least ``min_sigma_mm / d^2``) in either
    direction.  It flags every sharp feature, so on a diamond-turned surface it takes the
    cusp tips too (16-33 % of the points of real white-light slices of turned parts).

    ``pixel`` is one number or (pixel_x, pixel_y), mm (a 1-D ``z`` is a profile sampled every
    ``pixel``).  Outliers are replaced by the mean of their valid, non-outlier 3 x 3 (or
    3-point) neighbours (NaN if none).

    Returns
    -------
    cleaned : array like ``z``
        ``z`` with the outliers replaced (a copy; ``z`` itself if ``replace=False``).
    outliers : bool array like ``z``
    """
    if rule not in ("spike", "curvature"):
        raise InputError(f"rule must be 'spike' or 'curvature', received {rule!r}")
    z_in = np.asarray(z, dtype=np.float64)
    one_d = z_in.ndim == 1
    z = z_in[None, :] if one_d else z_in
    if mask is not None and one_d:
        mask = np.asarray(mask)[None, :]
    pxy = pixel_xy(pixel) if not one_d else (float(pixel), float(pixel))
    check_positive("pixel", min(pxy))
    ok = valid_mask(z, mask)
    zz = np.where(ok, z, np.nan)
    if rule == "spike":
        out = _spikes(zz, k=k, floor=min_sigma_mm)
    else:
        out = _curvature_outliers(zz, pxy, k=k, min_sigma_mm=min_sigma_mm)
    if one_d:
        if not replace:
            return z_in, out[0]
        good = ok[0] & ~out[0]
        w = ndimage.uniform_filter1d(good.astype(np.float64), 3, mode="constant") * 3
        s_ = ndimage.uniform_filter1d(np.where(good, z_in, 0.0), 3, mode="constant") * 3
        cleaned = z_in.copy()
        o = out[0]
        with np.errstate(invalid="ignore", divide="ignore"):
            cleaned[o] = np.where(w[o] > 0.5, s_[o] / w[o], np.nan)
        return cleaned, o
    if not replace:
        return z, out
    good = ok & ~out
    w = ndimage.uniform_filter(good.astype(np.float64), 3, mode="constant") * 9
    s = ndimage.uniform_filter(np.where(good, z, 0.0), 3, mode="constant") * 9
    cleaned = z.copy()
    with np.errstate(invalid="ignore", divide="ignore"):
        cleaned[out] = np.where(w[out] > 0.5, s[out] / w[out], np.nan)
    return cleaned, out


def _second_difference(zz: np.ndarray, axis: int) -> np.ndarray:
    """``f(x - d) - 2 f(x) + f(x + d)`` along ``axis`` (NaN at the ends and next to gaps)."""
    a = np.moveaxis(zz, axis, -1)
    f2 = np.full(a.shape, np.nan)
    f2[..., 1:-1] = a[..., :-2] - 2 * a[..., 1:-1] + a[..., 2:]
    return np.moveaxis(f2, -1, axis)


def _spikes(zz: np.ndarray, *, k: float, floor: float) -> np.ndarray:
    """Points whose second differences have a spike's signature along every direction the
    array has (see :func:`detect_outliers`)."""
    flags, seen = [], []
    for axis in (0, 1):
        if zz.shape[axis] < 5:
            continue
        f2 = _second_difference(zz, axis)
        fin = np.isfinite(f2)
        if fin.sum() < 10:
            continue
        med = float(np.median(f2[fin]))
        sigma = max(1.4826 * float(np.median(np.abs(f2[fin] - med))), floor)
        c = np.moveaxis(f2 - med, axis, -1)
        left = np.full(c.shape, np.nan)
        right = np.full(c.shape, np.nan)
        left[..., 1:] = c[..., :-1]
        right[..., :-1] = c[..., 1:]
        with np.errstate(invalid="ignore"):
            def opposite(n):  # a neighbour with a spike's share of the opposite sign
                return ((np.sign(n) == -np.sign(c))
                        & (np.abs(n) > SPIKE_NEIGHBOUR_SHARE * np.abs(c)))
            # next to an end or a gap one neighbour's second difference is not known:
            # the other one decides
            nl, nr = np.isnan(left), np.isnan(right)
            flag = ((np.abs(c) > k * sigma) & ~(nl & nr)
                    & (opposite(left) | nl) & (opposite(right) | nr))
        flags.append(np.moveaxis(flag, -1, axis))
        seen.append(np.moveaxis(np.isfinite(c), -1, axis))
    if not flags:
        return np.zeros(zz.shape, dtype=bool)
    # a spike along every direction in which the point's second difference is known
    out = np.any(seen, axis=0)
    for f, known in zip(flags, seen):
        out &= f | ~known
    return out


def _curvature_outliers(zz, pxy, *, k, min_sigma_mm):
    out = np.zeros(zz.shape, dtype=bool)
    for axis in (0, 1):
        if zz.shape[axis] < 3:
            continue
        f2 = np.full(zz.shape, np.nan)
        sl = [slice(None)] * 2
        sl[axis] = slice(1, -1)
        lo = [slice(None)] * 2
        lo[axis] = slice(0, -2)
        hi = [slice(None)] * 2
        hi[axis] = slice(2, None)
        d = pxy[1] if axis == 0 else pxy[0]
        f2[tuple(sl)] = (zz[tuple(lo)] + zz[tuple(hi)] - 2 * zz[tuple(sl)]) / d ** 2
        fin = np.isfinite(f2)
        if fin.sum() < 10:
            continue
        med = np.median(f2[fin])
        dev = np.abs(f2 - med)
        sigma = max(1.4826 * np.median(dev[fin]), min_sigma_mm / d ** 2)
        out |= fin & (dev > k * sigma)
    return out
