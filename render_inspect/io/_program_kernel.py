"""The compiled inner loop of the program scanner: one pass over the bytes of a piece of
a program (comments and spaces already removed, upper case), reading each word, running
each block through the modal state (G groups, units, absolute / incremental positions,
F, S, the spindle clamp) and writing one row per motion block.

A block it cannot read stops the pass with an error code, the byte where it stopped and a
detail (the letter, the G code, the group); :mod:`render_inspect.io._program_scan` turns
that into one line naming the file, the line, the block and the word.
"""

from __future__ import annotations

from typing import TypeVar

import numpy as np
import numpy.typing as npt

from ..core.lazy import njit  # numba, imported on first use
from ..core.units import MIN_TO_S as _MIN_TO_S  # s per min
from ..core.units import MM_TO_M as _MM_TO_M  # m per mm
from ._program_angles import c_backward, c_move_times, unwrap_c
from ._program_integers import POS_LETTERS, undotted_words

__all__ = ["scan_piece", "clean_piece", "sample_moves", "feed_times", "unwrap_c",
           "c_move_times", "c_backward", "STATE_SIZE", "INCR_SLOT",
           "ROW_FIELDS", "ERRORS", "G_GROUP", "GROUP_NAMES", "LETTER_OK", "INIT_STATE"]

# state vector
(_MOTION, _DIST, _FEED, _UNITS, _PLANE, _SPINDLE, _F, _S, _CLAMP, _X, _Y, _Z, _C, _ENDED,
 _HELD, _SYSA, _INCR, _DIR, _XU) = range(19)
STATE_SIZE = 19
INCR_SLOT = _INCR
#: the modal state at the start of a program: G01, G90, G94 (mm/min), G21, G18, G97; then
#: the spindle speed held from G96 (G97 without S), Fanuc lathe G98 / G99 seen, and the
#: places a number without a decimal point counts in mm and deg (0: whole units; the
#: scanner sets it; inches one place more), the spindle's last M03 / M04 / M05 (0: none yet),
#: the unit X was written in (-1: not yet; 0 mm, 1 inch, 2 both: incremental words of the
#: other unit added to it)
INIT_STATE = np.array([1, 90, 94, 21, 18, 97, np.nan, np.nan, np.nan,
                       np.nan, np.nan, np.nan, np.nan, 0, 0, 0, 0, 0, -1], dtype=np.float64)
#: columns of a row (float64; ``rows[k, i]`` is column k of row i): line (in the piece),
#: motion, X, Y, Z, C, I, J, K, R, F, feed mode, S, spindle mode, clamp, plane, written
#: (bits X=1 Y=2 Z=4 C=8), held (1 where G97 came without S after G96: the spindle keeps
#: the speed it had at the switch, S then the surface speed of G96; NaN otherwise), the
#: spindle's last M03 / M04 / M05 (0: none yet; one in the block acts before its move), the
#: unit X's value was written in (as the state's: -1 not yet, 0 mm, 1 inch, 2 both)
ROW_FIELDS = ("line", "motion", "X", "Y", "Z", "C", "I", "J", "K", "R", "F", "feed_mode",
              "S", "spindle_mode", "clamp", "plane", "written", "held", "spindle_dir",
              "x_unit")
_NF = len(ROW_FIELDS)

#: the dtypes :func:`sample_moves` keeps (a program's block index, its motion codes)
_B = TypeVar("_B", bound=np.generic)
_M = TypeVar("_M", bound=np.generic)

GROUP_NAMES = ("motion", "distance", "feed", "units", "plane", "spindle", "radius_comp",
               "no effect", "dwell", "home", "clamp", "refused")
#: G code (integer 0..99) -> group index (-1: not taken)
G_GROUP = np.full(100, -1, dtype=np.int64)
for _g in (0, 1, 2, 3):
    G_GROUP[_g] = 0
for _g in (90, 91):
    G_GROUP[_g] = 1
for _g in (93, 94, 95, 98, 99):  # G98 / G99: Fanuc lathe (system A) per minute / per rev
    G_GROUP[_g] = 2
for _g in (20, 21, 70, 71):
    G_GROUP[_g] = 3
for _g in (17, 18, 19):
    G_GROUP[_g] = 4
for _g in (96, 97):
    G_GROUP[_g] = 5
G_GROUP[40] = 6
for _g in (8, 9, 54, 55, 56, 57, 58, 59, 61, 64, 80):
    G_GROUP[_g] = 7
G_GROUP[4] = 8
G_GROUP[28] = 9
G_GROUP[50] = 10
G_GROUP[41] = 11
G_GROUP[42] = 11

#: letters a block may hold (G and M may repeat, the others once)
LETTER_OK = np.zeros(26, dtype=np.bool_)
for _ch in "XYZCUVWHIJKRFSNOTPQDLGM":
    LETTER_OK[ord(_ch) - 65] = True

#: error codes
ERRORS = {1: "bad byte", 2: "no number", 3: "number without letter", 4: "bad number",
          5: "word not taken", 6: "twice", 7: "unknown G", 8: "refused G", 9: "same group",
          10: "G50 axes", 11: "absolute and incremental", 12: "system A cycle",
          13: "F without a decimal point under increments"}
#: the words that are positions or angles (X Y Z C, U V W H, I J K R)
_IS_POS = np.zeros(26, dtype=np.bool_)
_IS_POS[POS_LETTERS] = True

_INCH = 25.4
#: one foot, m (S of constant surface speed in inch units is in feet per minute)
_FOOT_M = 12 * _INCH * _MM_TO_M
_POW10 = 10.0 ** np.arange(40)
#: what :func:`clean_piece` does with a byte: 0 keep, 1 drop (space, tab, CR), 2 upper
#: case, 3 a comment '(', 4 a comment ';', 5 hand the piece to the general way
_CLEAN = np.zeros(256, dtype=np.uint8)
_CLEAN[[32, 9, 13]] = 1
_CLEAN[97:123] = 2
_CLEAN[40] = 3
_CLEAN[59] = 4
_CLEAN[128:] = 5
_CLEAN[[41, 37, 58, 47]] = 5


@njit(cache=True, nogil=True)
def clean_piece(raw: npt.NDArray[np.uint8], out: npt.NDArray[np.uint8]) -> tuple[int, int]:
    """The bytes ``raw`` of a piece as the scanner reads them, written to ``out``: upper
    case, ``( )`` comments (closed on their line) and ``;`` comments removed, spaces,
    tabs and carriage returns dropped.  Returns (bytes written, 1), or (0, 0) where the
    piece holds anything else to handle (a byte that is not ASCII, a ``(`` or ``)``
    without its pair, a ``;`` comment holding one, ``%``, ``:``, ``/``): the caller then
    reads the piece the general way, which also names what is wrong."""
    n = raw.size
    m = 0
    i = 0
    while i < n:
        c = raw[i]
        k = _CLEAN[c]
        if k == 0:  # kept as it is
            out[m] = c
            m += 1
            i += 1
            continue
        if k == 1:  # space, tab, CR
            i += 1
            continue
        if k == 2:  # lower case
            out[m] = c - 32
            m += 1
            i += 1
            continue
        if k == 3:  # ( .. ) on one line, no ( inside
            j = i + 1
            while j < n:
                d = raw[j]
                if d == 40 or d == 41 or d == 10 or d > 127:
                    break
                j += 1
            if j < n and raw[j] == 41:
                i = j + 1
                continue
            return 0, 0
        if k == 4:  # ; to the end of the line
            j = i + 1
            while j < n:
                d = raw[j]
                if d == 10:
                    break
                if d == 40 or d == 41 or d > 127:
                    return 0, 0
                j += 1
            i = j
            continue
        return 0, 0  # not ASCII, ')', '%', ':', '/'
    return m, 1


@njit(cache=True, nogil=True)
def _end_block(st: npt.NDArray[np.float64], have: npt.NDArray[np.bool_],
               val: npt.NDArray[np.float64], gs: npt.NDArray[np.float64], ng: int,
               ms: npt.NDArray[np.float64], nm: int, line: int, rows: npt.NDArray[np.float64],
               nrow: int, seen_g: npt.NDArray[np.bool_], seen_m: npt.NDArray[np.bool_],
               flags: npt.NDArray[np.bool_], dot: npt.NDArray[np.bool_],
               undotted: npt.NDArray[np.float64], n_dot: int, n_undot: int
               ) -> tuple[int, int, int]:
    """Run one block through the modal state; write its row when it moves. Returns
    (rows written so far, error code, detail).  ``dot``: whether each word was written
    with a decimal point; ``n_dot``, ``n_undot``: the block's nonzero position and angle
    words with and without one; ``undotted``: see :func:`scan_piece`."""
    grp_seen = 0  # bit k: a G code of group k in this block
    dwell = False
    home = False
    clamp = False
    spindle_was = st[_SPINDLE]
    cycle_g = False  # G90 or G94: a cycle with axis words in Fanuc lathe system A
    for k in range(ng):
        g = gs[k]
        gi = int(g)
        if gi != g or gi < 0 or gi > 99 or G_GROUP[gi] < 0:
            return nrow, 7, k
        grp = G_GROUP[gi]
        seen_g[gi] = True
        if grp == 11:
            return nrow, 8, k
        if grp <= 6 and (grp_seen >> grp) & 1:
            return nrow, 9, grp
        grp_seen |= 1 << grp
        if gi == 90 or gi == 94:
            cycle_g = True
        if grp == 0:
            st[_MOTION] = g
        elif grp == 1:
            st[_DIST] = g
        elif grp == 2:
            if gi == 98 or gi == 99:  # Fanuc lathe system A: per minute, per revolution
                st[_SYSA] = 1.0
                st[_FEED] = 94.0 if gi == 98 else 95.0
            else:
                st[_FEED] = g
        elif grp == 3:
            st[_UNITS] = g
        elif grp == 4:
            st[_PLANE] = g
        elif grp == 5:
            st[_SPINDLE] = g
        elif grp == 8:
            dwell = True
        elif grp == 9:
            home = True
        elif grp == 10:
            clamp = True
    for k in range(nm):
        m = ms[k]
        mi = int(m)
        if mi == m and 0 <= mi <= 99:
            seen_m[mi] = True
        if m == 2 or m == 30:
            st[_ENDED] = 1.0
        elif m == 3 or m == 4 or m == 5:  # the spindle's direction, or stopped
            st[_DIR] = m
        elif m == 0 or m == 1:  # program stop, optional stop (flags 2 and 3)
            flags[2 + mi] = True
    if dwell:
        flags[0] = True
    if home:
        flags[1] = True
    inch = st[_UNITS] == 20 or st[_UNITS] == 70
    scale = _INCH if inch else 1.0
    # X, Z, U, W letters: 23, 25, 20, 22
    if cycle_g and st[_SYSA] != 0:
        for li in (23, 25, 20, 22):
            if have[li]:
                return nrow, 12, li
    if clamp:
        for li in (23, 25, 20, 22):
            if have[li]:
                return nrow, 10, li
        if have[18]:  # S
            st[_CLAMP] = val[18]
    elif have[18]:
        # S of constant surface speed in inch units: feet per minute, kept as m/min
        st[_S] = val[18] * (_FOOT_M if inch and st[_SPINDLE] == 96 else 1.0)
        st[_HELD] = 0.0
    elif spindle_was == 96 and st[_SPINDLE] == 97:
        st[_HELD] = 1.0  # G97 without S: the speed at the switch is kept
    if st[_SPINDLE] == 96:
        st[_HELD] = 0.0
    places = int(st[_INCR])
    if have[5] and places and not dot[5] and val[5] != 0:  # F: controls differ
        return nrow, 13, int(st[_FEED]) + (1000 if inch else 0)
    if have[5]:  # F
        st[_F] = val[5] * (1.0 if st[_FEED] == 93 else scale)
    non_motion = dwell or home or clamp
    written = 0
    if not non_motion:
        undotted[0] += n_dot
        if n_undot:  # (a call of its own: the usual block's pass stays as fast)
            undotted_words(have, val, dot, undotted, n_undot, line, places, inch)
        inc = st[_DIST] == 91
        # (axis letter, incremental letter, state slot, bit, scaled)
        for ax in range(4):
            if ax == 0:
                la, lu, slot, bit = 23, 20, _X, 1
            elif ax == 1:
                la, lu, slot, bit = 24, 21, _Y, 2
            elif ax == 2:
                la, lu, slot, bit = 25, 22, _Z, 4
            else:
                la, lu, slot, bit = 2, 7, _C, 8
            sc = scale if ax < 3 else 1.0
            if have[la] and have[lu]:
                return nrow, 11, la
            if have[la]:
                if inc:
                    st[slot] = st[slot] + val[la] * sc
                else:
                    st[slot] = val[la] * sc
                written |= bit
            elif have[lu]:
                st[slot] = st[slot] + val[lu] * sc
                written |= bit
            if ax == 0 and (have[la] or have[lu]):  # the unit X's value is written in
                u = 1.0 if inch else 0.0
                st[_XU] = u if (have[la] and not inc) or st[_XU] == u else 2.0
    if written:
        r = nrow
        rows[0, r] = line
        rows[1, r] = st[_MOTION]
        rows[2, r] = st[_X]
        rows[3, r] = st[_Y]
        rows[4, r] = st[_Z]
        rows[5, r] = st[_C]
        rows[6, r] = val[8] * scale if have[8] else np.nan     # I
        rows[7, r] = val[9] * scale if have[9] else np.nan     # J
        rows[8, r] = val[10] * scale if have[10] else np.nan   # K
        rows[9, r] = val[17] * scale if have[17] else np.nan   # R
        rows[10, r] = st[_F]
        rows[11, r] = st[_FEED]
        rows[12, r] = st[_S]
        rows[13, r] = st[_SPINDLE]
        rows[14, r] = st[_CLAMP]
        rows[15, r] = st[_PLANE]
        rows[16, r] = written
        rows[17, r] = 1.0 if st[_HELD] != 0 else np.nan
        rows[18, r] = st[_DIR]
        rows[19, r] = st[_XU]
        nrow += 1
    return nrow, 0, 0


@njit(cache=True, nogil=True)
def scan_piece(a: npt.NDArray[np.uint8], st: npt.NDArray[np.float64], rows: npt.NDArray[np.float64],
               seen_g: npt.NDArray[np.bool_], seen_m: npt.NDArray[np.bool_],
               seen_letter: npt.NDArray[np.bool_], flags: npt.NDArray[np.bool_],
               undotted: npt.NDArray[np.float64]) -> tuple[int, int, int, int, int, int]:
    """Scan the bytes ``a`` (see the module docstring) from the state ``st`` (updated in
    place).  ``undotted`` (6 numbers, updated in place) counts the nonzero position and
    angle words of the moves written with a decimal point and without one, and holds the
    first without one: its letter index (-1: none yet), value as written, line in the
    piece and unit (0 mm, 1 inch, 2 deg).  Returns (rows written, blocks, error code,
    byte position, detail, lines)."""
    n = a.size
    have = np.zeros(26, dtype=np.bool_)
    dot = np.zeros(26, dtype=np.bool_)
    val = np.zeros(26)
    gs = np.zeros(32)
    ms = np.zeros(32)
    ng = 0
    nm = 0
    n_dot = 0
    n_undot = 0
    nrow = 0
    blocks = 0
    line = 0
    any_word = False
    i = 0
    while i < n:
        c = a[i]
        if c == 10:
            if any_word:
                blocks += 1
                nrow, err, det = _end_block(st, have, val, gs, ng, ms, nm, line, rows, nrow,
                                            seen_g, seen_m, flags, dot, undotted, n_dot,
                                            n_undot)
                if err:
                    return nrow, blocks, err, i - 1, det, line
                have[:] = False
                ng = 0
                nm = 0
                n_dot = 0
                n_undot = 0
                any_word = False
                if st[_ENDED] != 0:
                    return nrow, blocks, 0, i, 0, line
            line += 1
            i += 1
            continue
        if c < 65 or c > 90:
            if (48 <= c <= 57) or c == 46 or c == 43 or c == 45:
                return nrow, blocks, 3, i, 0, line
            return nrow, blocks, 1, i, 0, line
        li = c - 65
        if not LETTER_OK[li]:
            return nrow, blocks, 5, i, li, line
        seen_letter[li] = True
        wpos = i
        i += 1
        neg = False
        if i < n and (a[i] == 45 or a[i] == 43):
            neg = a[i] == 45
            i += 1
        mant = 0
        frac = 0
        nd = 0
        ndot = 0
        skipped = 0
        while i < n:
            d = a[i]
            if 48 <= d <= 57:
                if nd < 18:
                    mant = mant * 10 + (d - 48)
                    if ndot:
                        frac += 1
                elif not ndot:
                    skipped += 1  # digits past 18 before the point: powers of ten
                nd += 1
            elif d == 46:
                ndot += 1
            else:
                break
            i += 1
        if nd == 0:
            if ndot == 0 and (i >= n or a[i] == 10 or (65 <= a[i] <= 90)) and i == wpos + 1:
                return nrow, blocks, 2, wpos, li, line
            return nrow, blocks, 4, wpos, li, line
        if ndot > 1:
            return nrow, blocks, 4, wpos, li, line
        if i < n and (a[i] == 43 or a[i] == 45):
            return nrow, blocks, 4, wpos, li, line
        if mant < 9007199254740992:
            v = mant / _POW10[frac]
        else:
            v = float(mant) / _POW10[frac]
        if skipped:
            v = v * _POW10[skipped]
        if neg:
            v = -v
        any_word = True
        if li == 6:  # G
            if ng >= 32:
                return nrow, blocks, 9, wpos, 0, line
            gs[ng] = v
            ng += 1
        elif li == 12:  # M
            if nm < 32:
                ms[nm] = v
                nm += 1
        else:
            if have[li]:
                return nrow, blocks, 6, wpos, li, line
            have[li] = True
            val[li] = v
            dot[li] = ndot > 0
            if _IS_POS[li] and mant != 0:
                if ndot:
                    n_dot += 1
                else:
                    n_undot += 1
    if any_word:
        blocks += 1
        nrow, err, det = _end_block(st, have, val, gs, ng, ms, nm, line, rows, nrow,
                                    seen_g, seen_m, flags, dot, undotted, n_dot, n_undot)
        if err:
            return nrow, blocks, err, n - 1, det, line
    return nrow, blocks, 0, n, 0, line


_TWO_PI = 2 * np.pi


@njit(cache=True, nogil=True, error_model="numpy")  # x / 0: inf, as numpy
def sample_moves(x: npt.NDArray[np.float64], z: npt.NDArray[np.float64], dt: npt.NDArray[np.float64],
                 n_sub: npt.NDArray[np.int64], rpm: npt.NDArray[np.float64], blk: npt.NDArray[_B],
                 motion: npt.NDArray[_M], total: int
                 ) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64], npt.NDArray[np.float64],
                            npt.NDArray[np.float64], npt.NDArray[_B], npt.NDArray[_M]]:
    """The moves of an X-Z lathe program sampled while the spindle turns at ``rpm`` (one
    speed per move): move ``j`` (from point ``j`` to ``j + 1``, taking ``dt[j]`` s) in
    ``n_sub[j]`` equal steps.  Returns (x, z, t, theta, block, motion) of the ``total``
    points, the first point and then each step's end; theta and t are summed step by step
    from 0 (as ``numpy.cumsum`` does)."""
    xo = np.empty(total)
    zo = np.empty(total)
    to = np.empty(total)
    th = np.empty(total)
    bo = np.empty(total, dtype=blk.dtype)
    mo = np.empty(total, dtype=motion.dtype)
    xo[0] = x[0]
    zo[0] = z[0]
    to[0] = 0.0
    th[0] = 0.0
    bo[0] = blk[0]
    mo[0] = motion[0]
    k = 1
    ts = 0.0
    ang = 0.0
    for j in range(n_sub.size):
        n = n_sub[j]
        nf = float(n)
        x0 = x[j]
        dx = x[j + 1] - x[j]
        z0 = z[j]
        dz = z[j + 1] - z[j]
        d = dt[j] / nf
        w = _TWO_PI * rpm[j] / _MIN_TO_S * d
        b = blk[j + 1]
        m = motion[j + 1]
        for q in range(1, n + 1):
            u = float(q) / nf
            xo[k] = x0 + dx * u
            zo[k] = z0 + dz * u
            if k == 1:
                ts = d
                ang = w
            else:
                ts = ts + d
                ang = ang + w
            to[k] = ts
            th[k] = ang
            bo[k] = b
            mo[k] = m
            k += 1
    return xo, zo, to, th, bo, mo


@njit(cache=True, nogil=True, error_model="numpy")  # x / 0: inf, as numpy
def feed_times(length: npt.NDArray[np.float64], fmode: npt.NDArray[np.int16],
               fval: npt.NDArray[np.float64], motion: npt.NDArray[np.int8],
               rpm: npt.NDArray[np.float64], feed: float, rapid: float
               ) -> tuple[npt.NDArray[np.float64], bool, bool]:
    """The time of each move of a program with F words, s: G93 (1 / F min), G94 (length
    / F), G95 (length / (F rpm)); moves before the first F at ``feed`` mm/min, rapids at
    ``rapid`` mm/min.  Returns (times, whether a move had no F, whether there are
    rapids)."""
    n = length.size
    dt = np.empty(n)
    missing = False
    rapids = False
    for i in range(n):
        if motion[i] == 0:
            dt[i] = length[i] / rapid * _MIN_TO_S
            rapids = True
            continue
        f = fval[i]
        if not np.isfinite(f):
            dt[i] = length[i] / feed * _MIN_TO_S
            missing = True
            continue
        m = fmode[i]
        if m == 93:
            dt[i] = _MIN_TO_S / f
        elif m == 94:
            dt[i] = length[i] / f * _MIN_TO_S
        elif m == 95:
            dt[i] = length[i] / (f * rpm[i]) * _MIN_TO_S
        else:
            dt[i] = np.nan
    return dt, missing, rapids
