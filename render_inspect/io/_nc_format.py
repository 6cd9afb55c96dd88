"""The cutting blocks of an NC program written by a compiled loop, in the very text
Python's formatting gives (``N12 G01 C1.500000 X2.250000 Z-0.001000 F97.08643605``, or an
X-Y-Z program's ``N12 G01 X1.500000 Y2.250000 Z-0.001000 F500``).

Python writes a float with ``{:.6f}`` and ``%.10g`` correctly rounded: the decimal nearest
the float's exact binary value, a tie to the even digit.  The loop does the same with
integers: for ``a`` scaled by a power of ten ``m`` (exact in binary64), the product's
rounding error ``e`` is recovered exactly (Dekker's product: ``a m = p + e`` exactly), and
``p + e`` is rounded to the nearest integer by the exact sign of ``(frac(p) - 1/2) + e``.
That holds while ``a m`` stays below 2**52 (``|e|`` then at most 1/4, and ``frac(p) -
1/2`` exact wherever the sign could be in doubt); a number beyond it (more than 4.5e9 at
six places, 4503 at twelve), a feed below 1 or of ten digits or more before the point, or
one whose ten digits round up to the next power of ten, is left to Python: the loop notes
the block and goes on, and the caller writes the blocks noted with Python's formatting in
their places.
"""

from __future__ import annotations

import math

import numpy as np

from ..core.lazy import njit  # numba, imported on first use
# (the powers of ten that binary64 holds exactly)
from ._nc_scan import _EXACT_POW10 as _POW10

__all__ = ["format_turning_rows", "format_linear_rows", "ROW_BYTES_MAX"]

#: the most bytes one block takes (its number, three coordinates, the feed, a line break)
ROW_BYTES_MAX = 200
#: the exactness limit of the scaled product (see the module notes)
_SCALED_MAX = float(2 ** 52)  # not a unit conversion
_I10 = np.array([10 ** k for k in range(19)], dtype=np.int64)
_SPLIT = 134217729.0  # 2**27 + 1 (Veltkamp's split)
_ZERO, _MINUS, _DOT, _SPACE, _LF = (ord(c) for c in "0-. \n")


@njit(cache=True, nogil=True)
def _round_scaled(a, m):
    """The nearest integer to the exact product a m (a >= 0, a m < 2**52), a tie to even."""
    p = a * m
    # Dekker's product: a m = p + e exactly (a and m split into 26-bit halves)
    t = _SPLIT * a
    ah = t - (t - a)
    al = a - ah
    t = _SPLIT * m
    mh = t - (t - m)
    ml = m - mh
    e = ((ah * mh - p) + ah * ml + al * mh) + al * ml
    q0 = math.floor(p)
    d = ((p - q0) - 0.5) + e
    q = np.int64(q0)
    if d > 0.0 or (d == 0.0 and q % 2 == 1):
        q += 1
    return q


@njit(cache=True, nogil=True)
def _put_digits(out, o, v, n):
    """The last n decimal digits of v >= 0 (leading zeros written) at out[o:]; returns the
    next position."""
    for i in range(n - 1, -1, -1):
        out[o + i] = _ZERO + v % 10
        v //= 10
    return o + n


@njit(cache=True, nogil=True)
def _put_int(out, o, v):
    """The decimal digits of v >= 0 at out[o:]; returns the next position."""
    n = 1
    while n < 19 and v >= _I10[n]:
        n += 1
    return _put_digits(out, o, v, n)


@njit(cache=True, nogil=True)
def _put_fixed(out, o, v, decimals, m):
    """``{:.<decimals>f}`` of v at out[o:] (``m`` = 10**decimals); returns the next
    position, or -1 where the value is beyond the exact range."""
    a = abs(v)
    if not a * m < _SCALED_MAX:
        return -1
    q = _round_scaled(a, m)
    if v < 0.0 or (v == 0.0 and math.copysign(1.0, v) < 0.0):
        out[o] = _MINUS
        o += 1
    scale = _I10[decimals]
    o = _put_int(out, o, q // scale)
    out[o] = _DOT
    return _put_digits(out, o + 1, q % scale, decimals)


@njit(cache=True, nogil=True)
def _put_g10(out, o, v):
    """``%.10g`` of v at out[o:] for 1 <= v < 1e10 written in positional form; returns the
    next position, or -1 for any other value (and where the ten digits round up to the
    next power of ten)."""
    if not (1.0 <= v < 1e10):
        return -1
    x = 0
    while x < 9 and v >= _POW10[x + 1]:
        x += 1
    decimals = 9 - x
    q = _round_scaled(v, _POW10[decimals])
    if q >= _I10[10]:
        return -1
    scale = _I10[decimals]
    o = _put_int(out, o, q // scale)
    frac = q % scale
    if frac == 0:
        return o
    # the fraction without its trailing zeros
    keep = decimals
    while frac % 10 == 0:
        frac //= 10
        keep -= 1
    out[o] = _DOT
    return _put_digits(out, o + 1, frac, keep)


@njit(cache=True, nogil=True)
def _rows(k0, step, axes, letters, feed, f_from, suffix, decimals, out, todo):
    """Blocks ``N<(k0 + j) step> G01 <letters[0]>.. <letters[1]>.. <letters[2]>..``
    (``axes``: (3, n); without the ``N`` word where ``step`` is 0) into out, each
    followed by ``suffix`` where it is given, else by `` F..`` (``feed``) from row f_from
    on; a block it leaves to Python is noted in todo (its row and the byte where it
    belongs) and takes no bytes.  Returns (bytes written, blocks noted)."""
    m = _POW10[decimals]
    o = 0
    n_todo = 0
    for j in range(axes.shape[1]):
        o0 = o
        if step > 0:
            out[o] = 78  # N
            o = _put_int(out, o + 1, (k0 + j) * step)
            out[o] = _SPACE
            o += 1
        for ch in (71, 48, 49):  # "G01"
            out[o] = ch
            o += 1
        for w in range(3):
            if o >= 0:
                out[o] = _SPACE
                out[o + 1] = letters[w]
                o = _put_fixed(out, o + 2, axes[w, j], decimals, m)
        if o >= 0 and suffix.size > 0:
            for ch in suffix:
                out[o] = ch
                o += 1
        elif o >= 0 and j >= f_from:
            out[o] = _SPACE
            out[o + 1] = 70  # F
            o = _put_g10(out, o + 2, feed[j])
        if o < 0:
            todo[2 * n_todo] = j
            todo[2 * n_todo + 1] = o0
            n_todo += 1
            o = o0
            continue
        out[o] = _LF
        o += 1
    return o, n_todo


def _blocks(k0: int, axes: tuple, letters: str, feed: np.ndarray, f_from: int, suffix: str,
            decimals: int, step: int = 1) -> bytes:
    a = np.ascontiguousarray(np.stack(axes), dtype=np.float64)
    feed = np.ascontiguousarray(feed, dtype=np.float64)
    out = np.empty((ROW_BYTES_MAX + len(suffix)) * a.shape[1] + 1, dtype=np.uint8)
    todo = np.empty(2 * a.shape[1], dtype=np.int64)
    n, n_todo = _rows(k0, step, a, np.frombuffer(letters.encode("ascii"), dtype=np.uint8), feed, f_from,
                      np.frombuffer(suffix.encode("ascii"), dtype=np.uint8), decimals, out, todo)
    if n_todo == 0:
        return out[:n].tobytes()
    fmt = ("{:.%df}" % decimals).format
    parts = []
    at = 0
    for j, o in todo[:2 * n_todo].reshape(-1, 2).tolist():
        text = (f"N{(k0 + j) * step} " if step else "") + "G01" + "".join(f" {w}{fmt(float(a[i, j]))}" for i, w in enumerate(letters))
        if suffix:
            text += suffix
        elif j >= f_from:
            text += " F%.10g" % float(feed[j])
        parts += [out[at:o].tobytes(), (text + "\n").encode("ascii")]
        at = o
    parts.append(out[at:n].tobytes())
    return b"".join(parts)


def format_turning_rows(k0: int, c: np.ndarray, x: np.ndarray, z: np.ndarray, feed: np.ndarray,
                        f_from: int, decimals: int, step: int = 1) -> bytes:
    """The cutting blocks ``N<(k0 + j) step> G01 C<c> X<x> Z<z> F<feed>`` (j = 0 .., C, X
    and Z with ``decimals`` places, F as ``%.10g``; no F before row ``f_from``; no ``N``
    word where ``step`` is 0), one per line, the bytes Python's formatting writes."""
    return _blocks(k0, (c, x, z), "CXZ", feed, f_from, "", decimals, step)


def format_linear_rows(k0: int, x: np.ndarray, y: np.ndarray, z: np.ndarray, feed_text: str,
                       step: int = 1) -> bytes:
    """The blocks ``N<(k0 + j) step> G01 X<x> Y<y> Z<z> F<feed_text>`` of an X-Y-Z program
    (six places; no ``N`` word where ``step`` is 0), one per line, the bytes Python's
    ``{:.6f}`` writes."""
    return _blocks(k0, (x, y, z), "XYZ", np.zeros(0), 0, f" F{feed_text}", 6, step)
