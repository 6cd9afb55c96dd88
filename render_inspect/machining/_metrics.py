"""Residual statistics written to metrics.json (nm)."""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from ..core.errors import InputError

MM_TO_NM = 1e6


@njit(cache=True)
def _stats(machined, design):
    n = 0
    s = 0.0
    lo = np.inf
    hi = -np.inf
    for v in range(machined.size):
        r = machined.flat[v] - design.flat[v]
        if math.isfinite(r):
            n += 1
            s += r
            if r < lo:
                lo = r
            if r > hi:
                hi = r
    if n == 0:
        return 0, 0.0, 0.0, 0.0, 0.0, 0.0
    mean = s / n
    sa = 0.0
    sq = 0.0
    for v in range(machined.size):
        r = machined.flat[v] - design.flat[v]
        if math.isfinite(r):
            d = r - mean
            sa += abs(d)
            sq += d * d
    return n, mean, sa / n, math.sqrt(sq / n), lo, hi


def residual_metrics(residual, design=None) -> dict:
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
