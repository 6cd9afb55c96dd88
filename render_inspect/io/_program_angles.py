"""The compiled passes over a program's spindle angle C (deg, as written): which way C
turns (:func:`c_first_step`), C turned on from its wraps (:func:`unwrap_c`), the first
step that turns back (:func:`c_backward`) and each move's time from the spindle's speed
(:func:`c_move_times`).  Each is one pass over the program, without temporaries of its
length beyond what it returns."""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from ..core.lazy import njit  # numba, imported on first use
from ..core.units import MIN_TO_S as _MIN_TO_S  # s per min

__all__ = ["c_first_step", "unwrap_c", "c_backward", "c_move_times"]


@njit(cache=True, nogil=True)
def c_first_step(c: npt.NDArray[np.float64], least: float) -> int:
    """The index of the first move whose C (deg, as written) changes by less than
    ``least`` deg either way (a step of ``least`` or more back is a wrap to a new
    revolution), and not by 0; -1 where there is none.  The sign of that step is the
    way the program turns C."""
    for i in range(c.size - 1):
        d = c[i + 1] - c[i]
        if d != 0 and -least < d < least:
            return i
    return -1


@njit(cache=True, nogil=True)
def unwrap_c(c: npt.NDArray[np.float64]
             ) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64], int, int]:
    """C as written (deg, wrapping every revolution) turned on: each move's step (a
    negative step is a wrap, taken modulo 360) and the summed angle from ``c[0]``.
    Returns (steps, summed angle, negative steps, index of the first)."""
    n = c.size - 1
    dc = np.empty(n)
    nneg = 0
    first = -1
    for i in range(n):
        d = c[i + 1] - c[i]
        if d < 0:
            if nneg == 0:
                first = i
            nneg += 1
            d = d - 360.0 * np.floor(d / 360.0)
        dc[i] = d
    cum = np.empty(n + 1)
    c0 = c[0]
    cum[0] = 0.0 + c0
    s = 0.0
    for i in range(n):
        s = dc[i] if i == 0 else s + dc[i]
        cum[i + 1] = s + c0
    return dc, cum, nneg, first


@njit(cache=True, nogil=True)
def c_backward(c: npt.NDArray[np.float64], least: float) -> int:
    """The index of the first move whose C (deg, as written) steps back by less than
    ``least`` deg (a wrap to a new revolution steps back by more), or -1."""
    for i in range(c.size - 1):
        d = c[i + 1] - c[i]
        if d < 0 and -d < least:
            return i
    return -1


@njit(cache=True, nogil=True, error_model="numpy")  # x / 0: inf, as numpy
def c_move_times(dc: npt.NDArray[np.float64], length: npt.NDArray[np.float64],
                 motion: npt.NDArray[np.int8], rpm: npt.NDArray[np.float64], feed: float,
                 rapid: float, dt: npt.NDArray[np.float64]
                 ) -> tuple[npt.NDArray[np.float64], bool]:
    """The time of each move of a program with C words, s: ``dt`` where the program's F
    words gave it (an empty array otherwise: C at the spindle speed ``rpm``, moves
    without C at ``feed`` mm/min, rapids at ``rapid`` mm/min), and never less than the
    spindle takes to turn C by ``dc`` deg.  Returns (times, whether there are rapids)."""
    n = dc.size
    out = np.empty(n)
    given = dt.size == n
    rapids = False
    for i in range(n):
        least = dc[i] / (360.0 * rpm[i]) * _MIN_TO_S
        if given:
            d = dt[i]
        elif motion[i] == 0:
            d = length[i] / rapid * _MIN_TO_S
            rapids = True
        elif dc[i] == 0:
            d = length[i] / feed * _MIN_TO_S
        else:
            d = dc[i] / (360.0 * rpm[i]) * _MIN_TO_S
        # numpy.maximum: the larger, NaN where either is NaN
        out[i] = d if (d >= least or np.isnan(d)) else least
    return out, rapids
