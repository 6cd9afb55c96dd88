"""The compiled reader of a run of blocks in the writers' own form (``N12 G01 C1.5 X2.25
Z-0.001 F97.5``, or ``G01 C1.5 ...`` without block numbers, the words in a fixed order):
one pass over the bytes that checks every line and reads its numbers, in place of a
regular expression over the run and numpy's passes over its characters.

It takes only the writers' form with plain numbers (block number and motion digits,
``-?\\d+\\.\\d+`` for the axes, ``\\d+(\\.\\d+)?`` for ``F``, one space before each
word, a line break after the last) and reads each number as :func:`float` does: its digits
as an integer, divided by the power of ten of its decimals (both exact in binary64 for up
to 15 digits, so the one rounding of the division gives the correctly rounded value),
``-0.0`` where a negative zero is written.  Anything else it leaves to the general reader
(:mod:`render_inspect.io._nc_parse`): a run with another form, an ``F`` with an exponent,
a number of more than 15 digits.
"""

from __future__ import annotations

import numpy as np

from ..core.lazy import njit  # numba, imported on first use

__all__ = ["scan_uniform", "FORM_OK", "FORM_OTHER", "FORM_LONG", "MAX_DIGITS"]

#: :func:`scan_uniform`'s answers: read; not the writers' plain form; a number of more
#: than :data:`MAX_DIGITS` digits
FORM_OK, FORM_OTHER, FORM_LONG = 0, 1, 2
#: the most digits of a number read exactly (its integer below 2**53)
MAX_DIGITS = 15
#: the powers of ten that binary64 holds exactly
_EXACT_POW10 = np.array([float(10 ** k) for k in range(23)])
_N, _G, _ZERO, _ONE, _NINE, _SPACE, _LF, _MINUS, _DOT, _F = (ord(c) for c in "NG019 \n-.F")


@njit(cache=True, nogil=True)
def _number(raw, p, n, signed, fraction, pow10):
    """The number at byte p: (status, value, next byte); ``signed``: a '-' may lead;
    ``fraction``: 0 no '.', 1 a '.' and digits must follow, 2 they may."""
    neg = False
    if signed and p < n and raw[p] == _MINUS:
        neg = True
        p += 1
    mant = 0
    digits = 0
    start = p
    while p < n and _ZERO <= raw[p] <= _NINE:
        mant = mant * 10 + (raw[p] - _ZERO) if digits < 18 else mant
        digits += 1
        p += 1
    if p == start:
        return FORM_OTHER, 0.0, p
    decimals = 0
    if fraction > 0 and p < n and raw[p] == _DOT:
        p += 1
        start = p
        while p < n and _ZERO <= raw[p] <= _NINE:
            mant = mant * 10 + (raw[p] - _ZERO) if digits < 18 else mant
            digits += 1
            p += 1
        decimals = p - start
        if decimals == 0:
            return FORM_OTHER, 0.0, p
    elif fraction == 1:
        return FORM_OTHER, 0.0, p
    if digits > MAX_DIGITS:
        return FORM_LONG, 0.0, p
    v = float(mant) / pow10[decimals]
    return FORM_OK, (-v if neg else v), p


@njit(cache=True, nogil=True)
def _scan(raw, letters, pow10, numbered):
    n = raw.size
    lines = 0
    for i in range(n):
        if raw[i] == _LF:
            lines += 1
    k = 2 + letters.size
    vals = np.empty((lines, k))
    long = False
    p = 0
    row = 0
    while p < n:
        # N<digits> G0<0|1> (G0<0|1> alone in a program without block numbers: -1)
        if numbered:
            if raw[p] != _N:
                return FORM_OTHER, vals[:0]
            status, v, p = _number(raw, p + 1, n, False, 0, pow10)
            if status == FORM_OTHER:
                return FORM_OTHER, vals[:0]
            long = long or status == FORM_LONG
            vals[row, 0] = v
            if p >= n or raw[p] != _SPACE:
                return FORM_OTHER, vals[:0]
            p += 1
        else:
            vals[row, 0] = -1.0
        if p + 3 > n or raw[p] != _G or raw[p + 1] != _ZERO \
                or not (raw[p + 2] == _ZERO or raw[p + 2] == _ONE):
            return FORM_OTHER, vals[:0]
        vals[row, 1] = float(raw[p + 2] - _ZERO)
        p += 3
        for w in range(letters.size):
            if p + 2 > n or raw[p] != _SPACE or raw[p + 1] != letters[w]:
                return FORM_OTHER, vals[:0]
            feed = letters[w] == _F
            status, v, p = _number(raw, p + 2, n, not feed, 2 if feed else 1, pow10)
            if status == FORM_OTHER:
                return FORM_OTHER, vals[:0]
            long = long or status == FORM_LONG
            vals[row, 2 + w] = v
        if p >= n or raw[p] != _LF:
            return FORM_OTHER, vals[:0]
        p += 1
        row += 1
    return (FORM_LONG if long else FORM_OK), vals


def scan_uniform(region: str, words: str, numbered: bool = True) -> tuple[int, np.ndarray]:
    """(status, values) of a run of block lines (ASCII, each ending with a line break)
    that all carry exactly ``words`` (e.g. ``"CXZF"``, in that order), each after its
    block number (``numbered``) or with none: :data:`FORM_OK` and the (lines, 2 +
    len(words)) values N (-1 without block numbers), G, then the words'; else
    :data:`FORM_OTHER` (a line not in the writers' plain form) or :data:`FORM_LONG` (a
    number of more than :data:`MAX_DIGITS` digits), with no values."""
    raw = np.frombuffer(region.encode("ascii"), dtype=np.uint8)
    letters = np.frombuffer(words.encode("ascii"), dtype=np.uint8)
    status, vals = _scan(raw, letters, _EXACT_POW10, bool(numbered))
    return int(status), vals
