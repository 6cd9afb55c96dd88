"""The block rate of a program: how many blocks a second the machine's control must read,
interpret and start to follow the program at its planned speed.

Each cutting block of a program moves the tool to one point of the path, so a block lasts
the time between its point and the one before: N points per revolution at S rpm are
N S / 60 blocks a second.  A control has a least time per block (its interpolation or
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
from ..core.units import S_TO_MS

__all__ = ["block_rate", "DEFAULT_BLOCK_RATE_LIMIT", "BLOCK_RATE_KEY"]

#: blocks per second a program is checked against when ``process.block_rate_limit_per_s``
#: is not set: one block per millisecond, the 1 ms interpolation period of LinuxCNC's
#: default servo period (see the module notes) and of many CNCs; ultra-precision
#: slow-tool-servo controls take more (set the key to the control's own rate)
DEFAULT_BLOCK_RATE_LIMIT = 1000.0  # not a unit conversion

#: the scene key (``[process]``) of the limit
BLOCK_RATE_KEY = "block_rate_limit_per_s"


def block_rate(t: Any, *, lines: Any = None, limit: float | None = None,
               radius: Any = None) -> dict[str, Any]:
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

    Returns
    -------
    dict
        ``blocks`` (timed blocks: each after the first point), ``max_per_s`` (1 / the
        shortest block's time), ``median_per_s``, ``min_block_time_s``, ``limit_per_s``,
        ``limit_source`` (the scene key, or the default's reason), ``limit_from_scene``
        (whether the scene set the limit), ``blocks_over_limit``,
        ``ok`` and ``warning`` (one sentence, None when ``ok``).
    """
    given = limit is not None
    lim = DEFAULT_BLOCK_RATE_LIMIT if limit is None else float(limit)
    if not lim > 0:
        raise InputError(f"process.{BLOCK_RATE_KEY} must be > 0 blocks per second, received {limit!r}")
    t = np.asarray(t, dtype=np.float64)
    ends = np.arange(t.size)
    if lines is not None and t.size:
        ln = np.asarray(lines)
        ends = np.r_[np.flatnonzero(ln[1:] != ln[:-1]), t.size - 1]
    te = t[ends]
    dt = np.diff(te)
    source = (f"process.{BLOCK_RATE_KEY}" if given else
              f"default {DEFAULT_BLOCK_RATE_LIMIT:g}: one block per 1 ms interpolation period "
              f"(set process.{BLOCK_RATE_KEY} to the control's own rate)")
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
        where = ""
        if radius is not None:  # (the radius where the shortest block ends)
            r = float(np.asarray(radius, dtype=np.float64)[ends[timed[k] + 1]])
            where = f", the shortest ending at radius {abs(r):.4g} mm"
        out["warning"] = (
            f"the program needs {rate[k]:,.0f} blocks/s at the planned speed (blocks of "
            f"{shortest * S_TO_MS:.4g} ms{where}; {over:,} of {timed.size:,} blocks over the "
            f"limit), above process.{BLOCK_RATE_KEY} = {lim:g} "
            f"({'the scene' if given else 'the default'}): a control slower than that runs "
            f"the program slower than planned or waits for blocks; set the key to the "
            f"control's rate, or plan fewer points per revolution or a lower spindle speed")
    return out
