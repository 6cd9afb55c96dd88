"""The grooves the cutting edge leaves, summed at one pixel by the cutting-mechanics kernel
(:mod:`._cut_kernel`): the 128 random Fourier modes of
:func:`~render_inspect.machining.groove_texture` at the pixel's edge position and cutting
distance, in one SIMD pass, each cosine within 3e-16 of numpy's."""

from __future__ import annotations

import math

import numpy as np

from ..core.lazy import njit  # numba, imported on first use
# (the largest |argument| the two-part reduction keeps exact: ARG_MAX)
from ..core.trig import ARG_MAX as _COS_ARG_MAX, INV_PI as _INVPI, PI_1 as _PI_1, PI_1T as _PI_1T, ROUND as _ROUND

__all__: list[str] = []

#: the minimax polynomial 1 + C_1 r^2 + ... + C_8 r^16 of cos r on |r| <= pi / 2 (Remez, the
#: coefficients rounded to doubles one by one: |error| < 4.3e-18); the argument reduced with
#: pi in two parts (:mod:`render_inspect.core.trig`: k pi_1 exact for k < 2^20), 1 / pi and
#: 1.5 * 2^52 (added to x / pi it rounds it to the integer k; the sum's last bit is k's parity)
_C1, _C2, _C3, _C4, _C5, _C6, _C7, _C8 = (
    -0.49999999999999983, 0.04166666666666443, -0.0013888888888787315, 2.4801587279375502e-05,
    -2.7557316542206754e-07, 2.0876568452752614e-09, -1.1463054989391418e-11, 4.610433736698955e-14)


@njit(cache=True, nogil=True, fastmath={"contract"})
def _cos(x):
    """cos(x) for |x| < _COS_ARG_MAX: x = k pi + r (Cody-Waite), cos r by the minimax
    polynomial, its sign flipped where k is odd; branch-free, so a loop over modes vectorises."""
    t = x * _INVPI + _ROUND
    k = t - _ROUND
    r = (x - k * _PI_1) - k * _PI_1T
    z = r * r
    c = 1.0 + z * (_C1 + z * (_C2 + z * (_C3 + z * (_C4 + z * (_C5 + z * (_C6 + z * (_C7 + z * _C8)))))))
    odd = np.float64(t).view(np.int64) << 63
    return np.int64(np.float64(c).view(np.int64) ^ odd).view(np.float64)


@njit(cache=True, nogil=True)
def _groove_arg(ku, kv, ph, i, u, v):
    """Mode i's argument ku_i u + kv_i v + ph_i, rounded as numpy rounds it."""
    return ku[i] * u + kv[i] * v + ph[i]


@njit(cache=True, nogil=True, fastmath={"reassoc"})
def _groove_sum(ku, kv, ph, u, v):
    """sum_i cos(ku_i u + kv_i v + ph_i) in one SIMD pass: three kernels with their own flags,
    which LLVM inlines keeping each instruction's (the arguments rounded as numpy rounds
    them, the cosine with fused multiply-adds, the terms summed in any order)."""
    g = 0.0
    for i in range(ku.size):
        g += _cos(_groove_arg(ku, kv, ph, i, u, v))
    return g


@njit(cache=True)
def _groove_sum_libm(ku, kv, ph, u, v):
    g = 0.0
    for i in range(ku.size):
        g += math.cos(ku[i] * u + kv[i] * v + ph[i])
    return g
