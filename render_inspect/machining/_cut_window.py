"""Which passes the cutting-mechanics kernel (:mod:`._cut_kernel`) visits at a pixel: the
window of passes whose nominal radius lies within W of it, and the proof that lets it skip
the passes before a pass that cuts whatever they left."""

from __future__ import annotations

import math

import numpy as np

from ..core.lazy import njit  # numba, imported on first use
from ._envelope_step import INV_2PI, TWO_PI

__all__: list[str] = []


@njit(cache=True, nogil=True, error_model="numpy")
def _window(t_first, t_last, a, cc, phi, r, sgn, W):
    """First and last pass j whose nominal radius is within W of sgn r (the direct kernel's
    ``_pass_window`` on the whole path's ends)."""
    if cc > 0:
        s_lo = t_first + (a - (r * sgn + W)) / cc
        s_hi = t_first + (a - (r * sgn - W)) / cc
    else:
        s_lo = t_first
        s_hi = t_last
    if s_lo < t_first:
        s_lo = t_first
    if s_hi > t_last:
        s_hi = t_last
    return math.ceil((s_lo - phi) * INV_2PI), math.floor((s_hi - phi) * INV_2PI)


@njit(cache=True, nogil=True, inline="always", error_model="numpy")
def _window_near(t_first, t_last, a, cc, inv_cc, phi, r, W):
    """:func:`_window` (sgn 1) by multiplications with 1 / cc: the two ends' pass numbers
    differ from :func:`_window`'s by rounding (below 1e-10 of a pass up to angles of 1e6
    rad), so they round to the same passes unless within 1e-6 of a whole pass, where
    :func:`_window` itself decides."""
    s_lo = t_first + (a - (r + W)) * inv_cc
    s_hi = t_first + (a - (r - W)) * inv_cc
    if s_lo < t_first:
        s_lo = t_first
    if s_hi > t_last:
        s_hi = t_last
    u0 = (s_lo - phi) * INV_2PI
    u1 = (s_hi - phi) * INV_2PI
    # each end's distance from the pass below it, in floating point only (no round trip
    # through an integer on the way to the test)
    f0 = np.floor(u0)
    f1 = np.floor(u1)
    g0 = u0 - f0
    g1 = u1 - f1
    if 1e-6 < g0 < 1.0 - 1e-6 and 1e-6 < g1 < 1.0 - 1e-6 and abs(u0) < 1e9 and abs(u1) < 1e9:
        return int(f0) + 1, int(f1)
    return _window(t_first, t_last, a, cc, phi, r, 1.0, W)


@njit(cache=True, nogil=True, inline="always", error_model="numpy")
def _head_covered(j0, k, phi, r, t_first, a, cc, dev, f, Rc, half_inv_rc, e_low, rise, ztk, zk, h_max):
    """True where every pass j0 .. k - 1 provably lies at least ``h_max`` above pass k's arc
    ``zk`` at this pixel, so pass k cuts whatever they left (the surface is never below
    the lowest arc passed): the tip of a pass j revolutions before k is at least pass k's
    tip ``ztk`` less j ``rise`` (the most the tip rises in a revolution), and the pass lies
    at least its nominal radius' distance less ``dev`` from the pixel.  The bound grows
    with each earlier pass once its distance dn holds dn f >= rise Rc: the walk stops
    there."""
    target = zk + h_max
    for j in range(k - 1, j0 - 1, -1):
        dn = (a - cc * (phi + TWO_PI * j - t_first)) - r - dev - 1e-12
        if not dn > 0.0:
            return False
        if not ztk - (k - j) * rise + dn * dn * half_inv_rc + e_low - 1e-12 >= target:
            return False
        if dn * f >= rise * Rc:
            return True
    return True
