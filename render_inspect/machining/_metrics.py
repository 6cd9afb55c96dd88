"""Residual statistics written to metrics.json (nm)."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from ..core.lazy import njit  # numba, imported on first use

from ..core.errors import InputError
from ..core.units import MM_TO_NM


def residual_metrics(residual: Any, design: np.ndarray | None = None) -> dict:
    """``Sa_nm, Sq_nm, Sz_nm, Sp_nm, Sv_nm`` of machined - design with the mean removed,
    and ``min_nm``: the signed minimum before the mean is removed (negative = overcut).

    ``residual`` is a HeightMap, or the machined array with ``design`` given, or a residual
    array (mm).  NaNs (uncovered pixels) are ignored and counted in ``valid_fraction``.
    One pass without temporaries (large maps)."""
    if hasattr(residual, "machined"):
        m, d = residual.machined, residual.design
    elif design is not None:
        m, d = np.asarray(residual, dtype=np.float64), np.asarray(design, dtype=np.float64)
    else:
        m = np.asarray(residual, dtype=np.float64)
        d = np.zeros_like(m)
    m = np.ascontiguousarray(m, dtype=np.float64)
    d = np.ascontiguousarray(d, dtype=np.float64)
    n, mean, sa, sq, lo, hi = _stats(m, d)
    if n == 0:
        raise InputError("simulation.region is not machined anywhere: no finite residual value "
                         "(the tool path does not reach the region; move simulation.region onto "
                         "the part or enlarge process.workpiece_radius)")
    sp, sv = hi - mean, mean - lo
    return {"Sa_nm": sa * MM_TO_NM, "Sq_nm": sq * MM_TO_NM,
            "Sp_nm": sp * MM_TO_NM, "Sv_nm": sv * MM_TO_NM, "Sz_nm": (sp + sv) * MM_TO_NM,
            "min_nm": lo * MM_TO_NM, "mean_nm": mean * MM_TO_NM,
            "valid_fraction": n / m.size}


# --- the same statistics reduced over tiles --------------------------------------------
#
# A map computed tile by tile never exists as one array.  Pass 1 (while the tiles are
# computed) keeps per tile the count, mean, sum of squared deviations (M2) and extrema of
# the float64 residual; tiles merge with Chan et al.'s update (exact up to rounding), so
# mean, Sq, Sp, Sv, Sz and min equal the single-array values to float64 rounding.  Sa
# needs the global mean: pass 2 reads the residual back from the store (float32) and sums
# |r - mean| and a histogram over [min, max].  Its error is at most 2^-24 (Sa + |mean|)
# (float32 rounding of each residual), i.e. below 1e-6 nm for residuals of tens of nm.

@njit(cache=True, nogil=True)
def _moments(machined, design):
    n = 0
    s = 0.0
    lo = np.inf
    hi = -np.inf
    for v in range(machined.size):
        r = machined.flat[v] - design.flat[v]
        if math.isfinite(r):
            n += 1
            s += r
            lo = min(lo, r)
            hi = max(hi, r)
    if n == 0:
        return 0, 0.0, 0.0, np.inf, -np.inf
    mean = s / n
    m2 = 0.0
    for v in range(machined.size):
        r = machined.flat[v] - design.flat[v]
        if math.isfinite(r):
            m2 += (r - mean) * (r - mean)
    return n, mean, m2, lo, hi


@njit(cache=True)
def _stats(machined, design):
    n, mean, m2, lo, hi = _moments(machined, design)
    if n == 0:
        return 0, 0.0, 0.0, 0.0, 0.0, 0.0
    sa = 0.0
    for v in range(machined.size):
        r = machined.flat[v] - design.flat[v]
        if math.isfinite(r):
            sa += abs(r - mean)
    return n, mean, sa / n, math.sqrt(m2 / n), lo, hi


def tile_moments(machined: np.ndarray, design: np.ndarray) -> tuple:
    """Pass-1 partial statistics of one tile: (n, mean, M2, min, max) of machined - design
    (mm, NaNs skipped).  Merge with :func:`merge_moments`."""
    m = np.ascontiguousarray(machined, dtype=np.float64)
    d = np.ascontiguousarray(design, dtype=np.float64)
    return tuple(_moments(m, d))


def merge_moments(a: tuple, b: tuple) -> tuple:
    """Combine two (n, mean, M2, min, max) partials (Chan, Golub & LeVeque 1979)."""
    na, ma, qa, loa, hia = a
    nb, mb, qb, lob, hib = b
    if na == 0:
        return b
    if nb == 0:
        return a
    n = na + nb
    delta = mb - ma
    return (n, ma + delta * (nb / n), qa + qb + delta * delta * (na * nb / n), min(loa, lob), max(hia, hib))


@njit(cache=True, nogil=True)
def _abs_dev_hist(residual, mean, lo, hi, counts):
    n = 0
    sa = 0.0
    nb = counts.size
    w = (hi - lo) / nb if hi > lo else 1.0
    for v in range(residual.size):
        r = np.float64(residual.flat[v])
        if math.isfinite(r):
            n += 1
            sa += abs(r - mean)
            k = int((r - lo) / w)
            if k < 0:
                k = 0
            elif k >= nb:
                k = nb - 1
            counts[k] += 1
    return n, sa


def tile_abs_dev(residual: np.ndarray, mean: float, lo: float, hi: float,
                 bins: int = 1024) -> tuple:
    """Pass-2 partials of one tile: (n, sum |r - mean|, histogram counts over [lo, hi] in
    ``bins`` equal bins) of a residual tile (mm, NaNs skipped)."""
    counts = np.zeros(bins, dtype=np.int64)
    n, sa = _abs_dev_hist(np.ascontiguousarray(residual), float(mean), float(lo), float(hi), counts)
    return int(n), float(sa), counts


def metrics_from_moments(moments: tuple, abs_dev: tuple | None, size: int) -> dict:
    """metrics.json ``residual`` entries (as :func:`residual_metrics`) from the merged
    pass-1 moments and pass-2 (n, sum |r - mean|, counts); ``size`` = pixels of the map."""
    n, mean, m2, lo, hi = moments
    if n == 0:
        raise ValueError("residual_metrics: no finite residual values (the path does not cover the region)")
    sp, sv = hi - mean, mean - lo
    out = {"Sq_nm": math.sqrt(m2 / n) * MM_TO_NM, "Sp_nm": sp * MM_TO_NM, "Sv_nm": sv * MM_TO_NM,
           "Sz_nm": (sp + sv) * MM_TO_NM, "min_nm": lo * MM_TO_NM, "mean_nm": mean * MM_TO_NM,
           "valid_fraction": n / size}
    if abs_dev is not None:
        out["Sa_nm"] = abs_dev[1] / abs_dev[0] * MM_TO_NM
    return out
