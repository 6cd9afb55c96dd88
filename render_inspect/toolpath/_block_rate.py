"""The block rate of a program: how many blocks a second the machine's control must read,
interpret and start to follow the program at its planned speed.

Each cutting block of a program moves the tool to one point of the path, so a block lasts
the time between its point and the one before: N points per revolution at S rpm are
N S / 60 blocks a second.  A block of an X-Y-Z program (``G94``, the feed F in mm/min
along the move) lasts its length over the feed: a block of length L mm at F mm/min takes
60 L / F seconds, 0.0025 mm at 100 mm/min 1.5 ms (667 blocks a second).  A control has a least time per block (its interpolation or
block-processing period); a program whose blocks are shorter runs slower than planned (the
spindle no longer turns at the planned speed, the feed per revolution and the time of each
move no longer hold) or stops to wait for blocks.  LinuxCNC, for one, runs a motion segment
no faster than its length over one trajectory period (``tpGetSampleVelocity`` in its
trajectory planner, ``src/emc/tp/tp.c``) and runs that period at the servo period, 1 ms
(``SERVO_PERIOD = 1000000`` ns in its sample configurations): 1000 blocks a second at most.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..core.errors import InputError
from ..core.units import MIN_TO_S, S_TO_MS

__all__ = ["block_rate", "linear_block_rate", "DEFAULT_BLOCK_RATE_LIMIT", "BLOCK_RATE_KEY"]

#: blocks per second a program is checked against when ``process.block_rate_limit_per_s``
#: is not set: one block per millisecond, the 1 ms interpolation period of LinuxCNC's
#: default servo period (see the module notes) and of many CNCs; ultra-precision
#: slow-tool-servo controls take more (set the key to the control's own rate)
DEFAULT_BLOCK_RATE_LIMIT = 1000.0  # not a unit conversion

#: the scene key (``[process]``) of the limit
BLOCK_RATE_KEY = "block_rate_limit_per_s"
#: what a turning program can change where its blocks come too fast
_TURNING_ADVICE = "plan fewer points per revolution or a lower spindle speed"
#: the same of a planned X-Y-Z program
_LINEAR_ADVICE = ("plan longer blocks (a larger process.arc_length) or a lower cutting speed "
                 "(process.feed_mm_per_min)")


def _limit(limit: float | None) -> tuple[float, bool, str]:
    """(the limit, whether the scene set it, where it comes from, in words)."""
    given = limit is not None
    lim = DEFAULT_BLOCK_RATE_LIMIT if limit is None else float(limit)
    if not lim > 0:
        raise InputError(f"process.{BLOCK_RATE_KEY} must be > 0 blocks per second, received {limit!r}")
    source = (f"process.{BLOCK_RATE_KEY}" if given else
              f"default {DEFAULT_BLOCK_RATE_LIMIT:g}: one block per 1 ms interpolation period "
              f"(set process.{BLOCK_RATE_KEY} to the control's own rate)")
    return lim, given, source


def _rates(dt: np.ndarray, limit: float | None, where, advice: str) -> dict[str, Any]:
    """The facts of :func:`block_rate` from the time of each block (``dt``, s; blocks of
    no time are counted, not timed); ``where(k)``: the words saying where the k-th block
    (the shortest) ends, "" if not known."""
    lim, given, source = _limit(limit)
    out: dict[str, Any] = {"blocks": int(dt.size), "max_per_s": None, "median_per_s": None,
                           "min_block_time_s": None, "limit_per_s": lim, "limit_source": source,
                           "limit_from_scene": given,
                           "blocks_over_limit": 0, "ok": True, "warning": None}
    timed = np.flatnonzero(dt > 0)
    if timed.size == 0:
        return out
    rate = 1.0 / dt[timed]
    k = int(np.argmax(rate))
    shortest = float(dt[timed[k]])
    over = int(np.count_nonzero(rate > lim))
    out.update({"max_per_s": float(rate[k]), "median_per_s": float(np.median(rate)),
                "min_block_time_s": shortest, "blocks_over_limit": over, "ok": over == 0})
    if over:
        out["warning"] = (
            f"the program needs {rate[k]:,.0f} blocks/s at the planned speed (blocks of "
            f"{shortest * S_TO_MS:.4g} ms{where(int(timed[k]))}; {over:,} of {timed.size:,} blocks "
            f"over the limit), above process.{BLOCK_RATE_KEY} = {lim:g} "
            f"({'the scene' if given else 'the default'}): a control slower than that runs "
            f"the program slower than planned or waits for blocks; set the key to the "
            f"control's rate, or {advice}")
    return out


def block_rate(t: Any, *, lines: Any = None, limit: float | None = None,
               radius: Any = None, advice: str = _TURNING_ADVICE) -> dict[str, Any]:
    """The blocks per second the control must process to follow a program at its planned
    speed.

    Parameters
    ----------
    t : (n,) array
        The time of each point of the path, s (increasing).
    lines : (n,) array, optional
        The block (file line) each point belongs to, where several points are one block
        (an arc cut as chords, a lathe move sampled while the spindle turns): a block then
        ends at the last point of its line.  Default: each point is the end of a block.
    limit : float, optional
        The control's blocks per second (``process.block_rate_limit_per_s``); None: the
        default :data:`DEFAULT_BLOCK_RATE_LIMIT`.
    radius : (n,) array, optional
        The radius of each point, mm: where the warning says the shortest block lies.
    advice : str
        What the warning suggests besides the control's rate (by default, for a planned
        spiral: fewer points per revolution or a lower spindle speed).

    Returns
    -------
    dict
        ``blocks`` (timed blocks: each after the first point), ``max_per_s`` (1 / the
        shortest block's time), ``median_per_s``, ``min_block_time_s``, ``limit_per_s``,
        ``limit_source`` (the scene key, or the default's reason), ``limit_from_scene``
        (whether the scene set the limit), ``blocks_over_limit``,
        ``ok`` and ``warning`` (one sentence, None when ``ok``).
    """
    _limit(limit)  # (checked before the path is looked at)
    t = np.asarray(t, dtype=np.float64)
    ends = np.arange(t.size)
    if lines is not None and t.size:
        ln = np.asarray(lines)
        ends = np.r_[np.flatnonzero(ln[1:] != ln[:-1]), t.size - 1]
    dt = np.diff(t[ends])

    def where(k: int) -> str:  # (the radius where the shortest block ends)
        if radius is None:
            return ""
        r = float(np.asarray(radius, dtype=np.float64)[ends[k + 1]])
        return f", the shortest ending at radius {abs(r):.4g} mm"

    return _rates(dt, limit, where, advice)


def linear_block_rate(x: Any, y: Any, z: Any, line: Any, feed_mm_per_min: Any, *,
                      limit: float | None = None, advice: str = _LINEAR_ADVICE) -> dict[str, Any]:
    """The blocks per second the control must process to follow an X-Y-Z program (feed
    ``G94``) at its programmed feed: each cutting block moves the tool from one point of a
    line to the next, its length L (mm, in X, Y and Z) at the feed F (mm/min) taking 60 L / F
    seconds.  The moves between the lines (retract, rapid, plunge) are not counted: they
    are few, and slow.

    Parameters
    ----------
    x, y, z : (n,) array
        The points, mm.
    line : (n,) array
        The line each point belongs to: a block joins two consecutive points of one line.
    feed_mm_per_min : float or (n,) array
        The programmed feed, mm/min (an array: the feed of the block ending at each point).
    limit : float, optional
        As :func:`block_rate` takes it.
    advice : str
        What the warning suggests besides the control's rate.

    Returns
    -------
    dict
        :func:`block_rate`'s facts; ``blocks`` counts the cutting blocks within the lines.
    """
    _limit(limit)
    x, y, z = (np.asarray(a, dtype=np.float64) for a in (x, y, z))
    line = np.asarray(line)
    feed = np.broadcast_to(np.asarray(feed_mm_per_min, dtype=np.float64), x.shape)
    inner = np.flatnonzero(line[1:] == line[:-1]) if x.size > 1 else np.zeros(0, np.int64)
    length = np.sqrt(np.diff(x)[inner] ** 2 + np.diff(y)[inner] ** 2 + np.diff(z)[inner] ** 2)
    f = feed[inner + 1]
    if np.any(~(f > 0)):
        raise InputError(f"the feed of an X-Y-Z program must be > 0 mm/min, received "
                         f"{float(f[~(f > 0)][0])!r}")
    dt = length / (f / MIN_TO_S)

    def where(k: int) -> str:  # (the line and point where the shortest block ends)
        j = int(inner[k]) + 1
        return (f", the shortest ending on line {int(line[j])} at X {x[j]:.4g}, Y {y[j]:.4g} "
                f"mm")

    return _rates(dt, limit, where, advice)
