"""Cosine and sine of float64 arrays in one vectorised pass.

numpy takes the C library's scalar ``cos`` and ``sin`` for float64 arrays: 15-30 ns a
value on the machines measured, a third of the planning of a sinusoidal design (its Z
compensation evaluates the design some 25 million times for a 2 x 2 mm window).  These
functions give the same values to within one or two units in the last place, about ten
times faster on large arrays:

- x = k pi/2 + r (Cody-Waite: pi/2 in three parts, the first two with 33 significant bits,
  so that their products with k are exact for |k| < 2^20, the constants of fdlibm's
  reduction; k found by adding 1.5 * 2^52 to x 2/pi, which also leaves k mod 4 in the
  sum's last two bits);
- cos r and sin r by their Taylor series to r^16 and r^17 on |r| <= pi/4 (truncation
  below 3e-18);
- the quadrant k mod 4 swaps them and sets their signs, without a branch.

Values with |x| >= :data:`ARG_MAX`, NaN and infinities take numpy's (the C library's)
cosine and sine.  Every operation is a single IEEE operation (no fused multiply-add), so the
compiled kernel and the numpy form of the same steps (used for small arrays before numba
is loaded: a scene check never waits for the compiler) give the same numbers to the last
bit: the result does not depend on the array's size or on which of the two ran.
"""

from __future__ import annotations

import math
import sys
from typing import Any

import numpy as np

from .lazy import njit

__all__ = ["cos", "sin", "cos_sin", "ARG_MAX"]

#: pi in two parts (the first with 33 significant bits: k pi_1 is exact for k < 2^20), 1/pi
#: and 1.5 * 2^52 (added to a number below 2^51 in magnitude, it rounds it to an integer,
#: whose low bits the sum's last bits hold); the cutting kernel's groove cosine takes them too
PI_1, PI_1T = 3.14159265346825122833e+00, 1.21542010130123844986e-10
INV_PI, ROUND = 3.18309886183790671538e-01, 6755399441055744.0
#: pi / 2 in three parts (the first two of 33 significant bits; fdlibm's pio2_1, pio2_2,
#: pio2_2t) and 2 / pi
_PIO2_1, _PIO2_2, _PIO2_2T = 1.57079632673412561417e+00, 6.07710050630396597660e-11, 2.02226624879595063154e-21
_TWO_OVER_PI = 0.6366197723675814
#: largest |x| the reduction keeps exact (k pi/2 with |k| < 2^20); beyond: numpy's
ARG_MAX = 1.5e6
#: Taylor coefficients (-1)^n / (2n)! (cosine) and (-1)^n / (2n + 1)! (sine), n = 1 .. 8
_C = tuple((-1) ** n / float(np.prod(np.arange(1, 2 * n + 1, dtype=np.float64))) for n in range(1, 9))
_S = tuple((-1) ** n / float(np.prod(np.arange(1, 2 * n + 2, dtype=np.float64))) for n in range(1, 9))
_C1, _C2, _C3, _C4, _C5, _C6, _C7, _C8 = _C
_S1, _S2, _S3, _S4, _S5, _S6, _S7, _S8 = _S
#: below this many values, and while numba is not loaded, the numpy form runs
_SMALL = 4096
#: values per block of a cosine or sine written over its argument (a scratch array of
#: 512 KiB, in the processor's second-level cache)
_IN_PLACE_BLOCK = 65536


@njit(cache=True, nogil=True, inline="always")
def _parts(x):
    """(cos r, sin r, k mod 4) with x = k pi/2 + r."""
    t = x * _TWO_OVER_PI + ROUND
    k = t - ROUND
    r = ((x - k * _PIO2_1) - k * _PIO2_2) - k * _PIO2_2T
    z = r * r
    c = 1.0 + z * (_C1 + z * (_C2 + z * (_C3 + z * (_C4 + z * (_C5 + z * (_C6 + z * (_C7 + z * _C8)))))))
    s = math.copysign(r + r * (z * (_S1 + z * (_S2 + z * (_S3 + z * (_S4 + z * (_S5 + z * (_S6 + z * (_S7 + z * _S8)))))))), r)
    q = np.float64(t).view(np.int64) & 3
    return c, s, q


@njit(cache=True, nogil=True, inline="always")
def _signed(v, negative):
    """v with its sign flipped where ``negative`` (0 or 1)."""
    return np.int64(np.float64(v).view(np.int64) ^ (negative << 63)).view(np.float64)


@njit(cache=True, nogil=True)
def _cos_sin_into(x, c_out, s_out, which):
    """cos x into ``c_out`` (which 0 or 2), sin x into ``s_out`` (which 1 or 2); numpy's
    (the C library's) where |x| >= ARG_MAX or x is not finite.  An output may be ``x``
    itself."""
    n = x.size
    far = 0
    for i in range(n):
        far += not abs(x[i]) < ARG_MAX
    at = np.empty(far, dtype=np.int64)
    fc = np.empty(far)
    fs = np.empty(far)
    if far:
        k = 0
        for i in range(n):
            if not abs(x[i]) < ARG_MAX:
                at[k] = i
                fc[k] = np.cos(x[i])
                fs[k] = np.sin(x[i])
                k += 1
    # (one loop per function: the two in one loop did not vectorise)
    if which == 2:
        for i in range(n):
            c, s, q = _parts(x[i])
            s_out[i] = _signed(c if q & 1 else s, (q >> 1) & 1)
    if which != 1:
        for i in range(n):
            c, s, q = _parts(x[i])
            c_out[i] = _signed(s if q & 1 else c, ((q + 1) >> 1) & 1)
    if which == 1:
        for i in range(n):
            c, s, q = _parts(x[i])
            s_out[i] = _signed(c if q & 1 else s, (q >> 1) & 1)
    for k in range(far):
        if which != 1:
            c_out[at[k]] = fc[k]
        if which != 0:
            s_out[at[k]] = fs[k]


def _numpy_form(x: np.ndarray, which: int) -> tuple[np.ndarray | None, np.ndarray | None]:
    """The kernel's steps with numpy (the same operations in the same order: the same bits)."""
    with np.errstate(invalid="ignore"):  # (infinities: numpy's NaN below, as the kernel's)
        t = x * _TWO_OVER_PI + ROUND
        k = t - ROUND
        r = ((x - k * _PIO2_1) - k * _PIO2_2) - k * _PIO2_2T
        z = r * r
        c = 1.0 + z * (_C1 + z * (_C2 + z * (_C3 + z * (_C4 + z * (_C5 + z * (_C6 + z * (_C7 + z * _C8)))))))
        s = np.copysign(r + r * (z * (_S1 + z * (_S2 + z * (_S3 + z * (_S4 + z * (_S5 + z * (
            _S6 + z * (_S7 + z * _S8)))))))), r)
        q = t.view(np.int64) & 3
        odd = (q & 1).astype(bool)
        far = ~(np.abs(x) < ARG_MAX)
        cos_x = sin_x = None
        if which != 1:
            cos_x = (np.where(odd, s, c).view(np.int64) ^ ((((q + 1) >> 1) & 1) << 63)).view(np.float64)
            if far.any():
                cos_x[far] = np.cos(x[far])
        if which != 0:
            sin_x = (np.where(odd, c, s).view(np.int64) ^ (((q >> 1) & 1) << 63)).view(np.float64)
            if far.any():
                sin_x[far] = np.sin(x[far])
    return cos_x, sin_x


def _run(x: Any, which: int, out: np.ndarray | None = None) -> tuple[Any, Any]:
    a = np.asarray(x)
    if a.dtype != np.float64 and a.dtype.kind not in "biu":
        # float32, complex, objects: numpy's own
        if which == 2:
            return np.cos(a), np.sin(a)
        f = np.cos if which == 0 else np.sin
        return (f(a) if out is None else f(a, out=out)), None
    if out is not None and (not isinstance(out, np.ndarray) or out.dtype != np.float64
                            or out.shape != a.shape or not out.flags.c_contiguous):
        raise ValueError(f"out must be a C-contiguous float64 array of shape {a.shape}")
    flat = np.ascontiguousarray(a, dtype=np.float64).reshape(-1)
    if flat.size < _SMALL and "numba" not in sys.modules:
        c, s = _numpy_form(flat, which)
    else:
        c = np.empty(flat.size) if which != 1 else flat[:0]
        s = np.empty(flat.size) if which != 0 else flat[:0]
        if out is not None and which != 2:  # (written in place: ``out`` may be x itself)
            c, s = (out.reshape(-1), s) if which == 0 else (c, out.reshape(-1))
        if out is not None and which != 2 and out.ctypes.data == flat.ctypes.data:
            _in_place(flat, which)
        else:
            _cos_sin_into(flat, c, s, which)
    if which == 2:
        return _shaped(c, a), _shaped(s, a)
    v = c if which == 0 else s
    if out is None:
        return _shaped(v, a), None
    if v is not None and not np.shares_memory(v, out):
        out.reshape(-1)[:] = v
    return out, None


def _in_place(x: np.ndarray, which: int) -> None:
    """cos x (which 0) or sin x (which 1) written over x, a block at a time through a
    scratch array: the kernel's loop over an output that is its input cannot be
    vectorised (the compiled loop checks the two for overlap and takes its one-value-at-
    a-time form), about 5 x slower.  The same numbers (each value is its own)."""
    scratch = np.empty(min(x.size, _IN_PLACE_BLOCK))
    for a in range(0, x.size, _IN_PLACE_BLOCK):
        part = x[a:a + _IN_PLACE_BLOCK]
        v = scratch[:part.size]
        _cos_sin_into(part, v, v, which)
        part[:] = v


def _shaped(v: np.ndarray | None, a: np.ndarray) -> Any:
    assert v is not None
    return np.float64(v[0]) if a.ndim == 0 else v.reshape(a.shape)


def cos(x: Any, out: np.ndarray | None = None) -> Any:
    """cos x (float64, x's shape; a numpy float for a scalar), within two units in the last
    place of numpy's; other float types and complex numbers: numpy's.  ``out``: a
    C-contiguous float64 array of x's shape to write it into (x itself allowed)."""
    return _run(x, 0, out)[0]


def sin(x: Any, out: np.ndarray | None = None) -> Any:
    """sin x, as :func:`cos`."""
    return _run(x, 1, out)[0]


def cos_sin(x: Any) -> tuple[Any, Any]:
    """(cos x, sin x) from one pass over x, as :func:`cos` and :func:`sin`."""
    return _run(x, 2)
