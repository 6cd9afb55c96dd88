"""One pass over the blocks of a program for :func:`~render_inspect.toolpath.verify_blocks`:
where each of its checks of the moves first fails (rapids in the clearance plane,
vertical plunges and retracts that reach it, the longest cutting move; a turning
program's spindle speed and X and Z velocities), which blocks are points of the cut, and
the counts and the lowest rapid its facts give.  The same comparisons of the same
numbers as the array form it replaced, block by block."""

from __future__ import annotations

import math

import numpy as np

from ..core.lazy import njit  # numba, imported on first use
from ..core.toolpath import ROLE_CUT, ROLE_PLUNGE, ROLE_RETRACT, Blocks

__all__ = ["scan_blocks"]


@njit(cache=True, nogil=True, inline="always")
def _less_rounding(d, rnd):
    """numpy.maximum(|d| - 2 rnd, 0): a move less the rounding of the written places at
    either end (NaN stays NaN)."""
    m = abs(d) - 2 * rnd
    return m if (m > 0.0 or m != m) else 0.0


@njit(cache=True, nogil=True, inline="always")
def _turning_speeds(c, x, z, motion, feed, rnd, to_s, rpm_max, vx_max, vz_max, first):
    """The first block of a turning program whose C axis turns faster than ``rpm_max``
    (``first[0]``), whose X or Z axis moves faster than ``vx_max`` / ``vz_max``
    (``first[1]``, ``first[2]``); NaN: not checked, -1: none.  A feed block (after the
    first block) lasts ``to_s / feed`` s (inverse time), any other block counts as no
    speed; each axis's move is less the rounding ``rnd`` of the written places at
    either end.  (A feed block of no feed counts as no speed: the program is refused
    for it before its speeds are looked at.)"""
    for k in range(first.size):
        first[k] = -1
    for i in range(c.size):
        fm = i > 0 and motion[i] == 1 and feed[i] != 0.0
        dt = to_s / feed[i] if fm else math.nan
        rpm = 0.0
        if fm:
            turns = _less_rounding(c[i] - c[i - 1], rnd) * (math.pi / 180.0) / (2 * math.pi)
            rpm = turns / dt * to_s
        if first[0] < 0 and rpm > rpm_max:
            first[0] = i
        vx = vz = 0.0
        if fm and dt > 0:
            vx = _less_rounding(x[i] - x[i - 1], rnd) / dt
            vz = _less_rounding(z[i] - z[i - 1], rnd) / dt
        if first[1] < 0 and vx > vx_max:
            first[1] = i
        if first[2] < 0 and vz > vz_max:
            first[2] = i


@njit(cache=True, nogil=True)
def _scan(x, y, z, motion, role, a1, a2, zc, rnd, max_step, cutpt, first, counts, feed, to_s,
          limits, speeds):
    """The first block failing each check (``first``, -1: none): 0 a rapid leaves the
    clearance plane ``zc``, 1 a plunge or retract moves ``a1`` or ``a2`` (the axes other
    than Z), 2 a plunge or retract does not reach the plane, 3 a plunge moves up or a
    retract down, 4 a cutting move is longer than ``max_step`` (NaN: not checked); 5
    is 1 when a rapid follows the first block.  The points of the cut (``cutpt``), and
    ``counts``: rapids, plunges, retracts, cuts.  Returns the lowest end of the rapids
    after the first block (NaN if any is NaN).  With ``limits`` (the spindle speed and
    the X and Z velocities a turning program, C ``a1``, X ``a2``, Z ``z``, may not
    exceed; inverse-time ``feed``), ``speeds`` (:func:`_turning_speeds`)."""
    n = z.size
    for k in range(first.size):
        first[k] = -1
    for k in range(counts.size):
        counts[k] = 0
    low_z = zc - rnd
    half = rnd / 2
    long_step = max_step + 4 * rnd
    lowest = math.inf
    seen = False
    lowest_nan = False
    for i in range(n):
        zi = z[i]
        zs = z[i - 1] if i > 0 else zi
        rapid = motion[i] == 0
        r = role[i]
        if rapid:
            counts[0] += 1
        if r == ROLE_PLUNGE:
            counts[1] += 1
        elif r == ROLE_RETRACT:
            counts[2] += 1
        elif r == ROLE_CUT:
            counts[3] += 1
        if rapid and first[0] < 0 and (zi < low_z or zs < low_z):
            first[0] = i
        feedmove = not rapid and r != ROLE_CUT
        if feedmove and first[1] < 0 and i > 0 and (
                abs(a1[i] - a1[i - 1]) > half or abs(a2[i] - a2[i - 1]) > half):
            first[1] = i
        # (the higher end, as numpy.maximum: NaN when either end is NaN)
        if feedmove and first[2] < 0 and zi < low_z and zs < low_z:
            first[2] = i
        if first[3] < 0 and ((r == ROLE_PLUNGE and zi > zs) or (r == ROLE_RETRACT and zi < zs)):
            first[3] = i
        if r == ROLE_CUT and first[4] < 0 and i > 0:
            dx = x[i] - x[i - 1]
            dy = y[i] - y[i - 1]
            dz = zi - z[i - 1]
            if math.sqrt(dx * dx + dy * dy + dz * dz) > long_step:
                first[4] = i
        # the lower ends of plunges and retracts are points of the cut
        lower = feedmove and zi <= zs
        if not lower and i + 1 < n and motion[i + 1] != 0 and role[i + 1] != ROLE_CUT:
            lower = z[i + 1] >= zi
        cutpt[i] = (r == ROLE_CUT or lower) and math.isfinite(x[i]) and math.isfinite(y[i])
        if rapid and i > 0:
            seen = True
            if zi != zi or zs != zs:
                lowest_nan = True
            else:
                lowest = min(lowest, zi, zs)
    first[5] = 1 if seen else -1
    if limits.size:
        _turning_speeds(a1, a2, z, motion, feed, rnd, to_s, limits[0], limits[1], limits[2],
                        speeds)
    return math.nan if lowest_nan else lowest


def scan_blocks(blocks: Blocks, x: np.ndarray, y: np.ndarray, z: np.ndarray, zc: float,
                rnd: float, max_step: float | None, *, to_s: float = 60.0,
                rpm_max: float | None = None, v_max: dict | None = None) -> dict:
    """The checks of the moves of ``blocks`` (tool tip ``x``, ``y``, ``z`` at the end of
    each), with the clearance plane ``zc``, the written places' step ``rnd`` and the
    longest planned cutting move ``max_step`` (None: not checked): a dict of the first
    failing block of each check (``low``, ``sideways``, ``short``, ``direction``,
    ``step``; None: none), ``cutpt`` (the points of the cut), the counts (``rapids``,
    ``plunges``, ``retracts``, ``cuts``) and ``rapid_lowest`` (the lowest end of a rapid
    after the first block, NaN if any is NaN; None: no rapid after the first block).
    For a turning program, ``speeds``: where its C axis first turns faster than
    ``rpm_max`` (key ``C``) and its X and Z axes first move faster than ``v_max`` (axis
    -> mm/s) allows (keys ``X``, ``Z``; None: nowhere, or not checked); ``to_s``:
    seconds per minute (the feed is inverse time, 1/min)."""
    others = [a for a in blocks.axes if a != "Z"]
    if len(others) != 2:
        raise ValueError(f"a program of two axes beside Z, received {list(blocks.axes)}")
    n = blocks.count
    cutpt = np.empty(n, dtype=np.bool_)
    first = np.empty(6, dtype=np.int64)
    counts = np.empty(4, dtype=np.int64)
    f64 = (lambda a: np.ascontiguousarray(a, dtype=np.float64))
    i8 = (lambda a: np.ascontiguousarray(a, dtype=np.int8))
    turning = blocks.dialect == "turning"
    if turning:  # (C and X, in this order, for the speeds)
        others = ["C", "X"]
    lim = (lambda v: math.nan if v is None else float(v))
    v_max = v_max or {}
    limits = np.array([lim(rpm_max), lim(v_max.get("X")), lim(v_max.get("Z"))] if turning
                      else [], dtype=np.float64)
    speeds = np.full(3, -1, dtype=np.int64)
    lowest = _scan(f64(x), f64(y), f64(z), i8(blocks.motion), i8(blocks.role),
                   f64(blocks.axes[others[0]]), f64(blocks.axes[others[1]]), float(zc),
                   float(rnd), math.nan if max_step is None else float(max_step), cutpt,
                   first, counts, f64(blocks.feed), float(to_s), limits, speeds)
    at = [int(i) if i >= 0 else None for i in first]
    return {"low": at[0], "sideways": at[1], "short": at[2], "direction": at[3],
            "step": at[4], "cutpt": cutpt,
            "rapids": int(counts[0]), "plunges": int(counts[1]), "retracts": int(counts[2]),
            "cuts": int(counts[3]), "rapid_lowest": None if at[5] is None else float(lowest),
            "speeds": {k: int(i) if i >= 0 else None for k, i in zip(("C", "X", "Z"), speeds)}}
