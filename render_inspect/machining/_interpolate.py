"""The interpolator of a turning machine's controller: the program's points (t_i, q_i)
evaluated as a command q_c(t), v_c(t), a_c(t) at every servo tick (step 1 of the chain in
:mod:`render_inspect.machining._axes`).

* ``"pvt"`` (position-velocity-time, the interpolation of the compound sinusoidal grid
  study's Nanoform 250, its Table 3): a cubic Hermite segment between consecutive points, with the velocity at each point the slope of
  the parabola through it and its two neighbours (one-sided at the ends);
* ``"linear"`` (G01 blocks): straight segments.
"""

from __future__ import annotations

import numpy as np

from ..core.errors import InputError
from ..core.lazy import njit  # numba, imported on first use
from ..core.threads import over_rows

__all__ = ["check_program", "pvt_velocities", "pvt_command", "pvt_checked", "linear_command"]


def check_program(t: np.ndarray, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    t = np.asarray(t, dtype=np.float64)
    q = np.asarray(q, dtype=np.float64)
    if t.ndim != 1 or t.shape != q.shape or t.size < 2:
        raise InputError(f"t and q must be 1-D arrays of one length >= 2, received {t.shape} "
                         f"and {q.shape}")
    ok = t[1:] > t[:-1]  # (diff > 0, without the differences)
    if not ok.all():
        i = int(np.flatnonzero(~ok)[0])
        raise InputError(f"program times must increase strictly; t[{i}] = {t[i]!r} s, "
                         f"t[{i + 1}] = {t[i + 1]!r} s")
    if not np.all(np.isfinite(q)):
        raise InputError("program positions must be finite")
    return t, q


def pvt_velocities(t: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Velocity at each program point: slope of the parabola through it and its
    neighbours (second-order, uneven steps), one-sided (the segment slope) at the ends.

    Parameters
    ----------
    t, q : (n,) arrays (s, axis unit), n >= 2

    Returns
    -------
    (n,) float64, axis unit / s
    """
    t, q = check_program(t, q)
    s = np.diff(q) / np.diff(t)
    v = np.empty_like(q)
    v[0], v[-1] = s[0], s[-1]
    if q.size > 2:
        h1 = t[1:-1] - t[:-2]
        h2 = t[2:] - t[1:-1]
        v[1:-1] = (h2 * s[:-1] + h1 * s[1:]) / (h1 + h2)
    return v


def _segments(t, tk):
    i = np.searchsorted(t, tk, side="right") - 1
    return np.clip(i, 0, t.size - 2)


def pvt_command(t: np.ndarray, q: np.ndarray, tk: np.ndarray, *,
                velocities: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Position, velocity and acceleration of the PVT (cubic Hermite) command at ``tk``.

    Parameters
    ----------
    t, q : (n,) arrays
        Program times (s, increasing) and positions.
    tk : (m,) array, s
        Evaluation times in [t[0], t[-1]].
    velocities : (n,) array, optional
        Velocities at the points (default :func:`pvt_velocities`).

    Returns
    -------
    q_c, v_c, a_c : (m,) float64 arrays
    """
    t, q = check_program(t, q)
    return pvt_checked(t, q, tk, velocities=velocities)


#: ticks from which the PVT command is computed on threads (fewer: on the calling thread,
#: where handing out the runs would cost more than it saves)
THREADED_TICKS = 65_536


def pvt_checked(t: np.ndarray, q: np.ndarray, tk: np.ndarray, *,
                velocities: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`pvt_command` of a program that :func:`check_program` has passed (float64
    arrays ``t``, ``q``): the point velocities, each tick's segment and the Hermite
    segment in one compiled pass.  ``q`` (and ``velocities``) may be (k, n): k axes
    programmed at the same times, their commands (k, m) rows (each row the numbers of
    its axis alone: the segment and the Hermite basis at a tick are shared)."""
    q = np.ascontiguousarray(q, dtype=np.float64)
    rows = q.reshape(-1, q.shape[-1])
    fill = velocities is None
    v = np.empty(rows.shape) if fill else \
        np.ascontiguousarray(velocities, dtype=np.float64).reshape(rows.shape)
    tk = np.ascontiguousarray(tk, dtype=np.float64)
    pos, vel, acc = (np.empty((rows.shape[0], tk.size)) for _ in range(3))
    t = np.ascontiguousarray(t)
    if fill:
        _pvt_velocities(t, rows, v)
    # long programs: the ticks in runs on threads (each tick's numbers depend on the tick
    # alone: the same numbers whatever the runs)
    if tk.size >= THREADED_TICKS:
        over_rows(_hermite, tk.size, t, rows, v, tk, pos, vel, acc)
    else:
        _hermite(t, rows, v, tk, pos, vel, acc, 0, tk.size)
    if q.ndim == 1:
        return pos[0], vel[0], acc[0]
    return pos, vel, acc


@njit(cache=True, nogil=True)
def _pvt_velocities(t, q, v):
    """The point velocities ``v`` of each axis (row of ``q``): :func:`pvt_velocities`'
    arithmetic, in its order."""
    n = t.size
    for r in range(q.shape[0]):
        # (each segment's step and slope computed once: a point's right-hand ones are the
        # next point's left-hand ones, the same numbers)
        h1 = t[1] - t[0]
        sl = (q[r, 1] - q[r, 0]) / h1
        v[r, 0] = sl
        for j in range(1, n - 1):
            h2 = t[j + 1] - t[j]
            sr = (q[r, j + 1] - q[r, j]) / h2
            v[r, j] = (h2 * sl + h1 * sr) / (h1 + h2)
            h1 = h2
            sl = sr
        v[r, n - 1] = sl


@njit(cache=True, nogil=True, inline="always")
def _count_at_most(t, x):
    """How many of the increasing times ``t`` are <= x (numpy's ``searchsorted(t, x,
    side="right")``, the same index for every x; written here so that the kernel loads
    from numba's cache without numba's library of numpy functions)."""
    lo = 0
    hi = t.size
    while lo < hi:
        mid = (lo + hi) >> 1
        if t[mid] <= x:
            lo = mid + 1
        else:
            hi = mid
    return lo


@njit(cache=True, nogil=True)
def _hermite(t, q, v, tk, pos, vel, acc, k0, k1):
    """The PVT command of each axis (row of ``q``, point velocities ``v``) at the ticks
    tk[k0:k1]: the tick's segment (:func:`_segments`, walked forward along increasing
    ticks from the first tick's, found by a binary search) and its cubic Hermite
    position, velocity and acceleration (the arithmetic of the array expressions it
    replaced, in their order: the same numbers to the bit, whatever the runs)."""
    n = t.size
    na = q.shape[0]
    c = 0  # the number of program times <= the tick
    if k1 > k0 and tk[k0] == tk[k0]:
        c = _count_at_most(t, tk[k0])
    for k in range(k0, k1):
        x = tk[k]
        if x != x:
            j = n - 2  # (a NaN sorts after every time)
        else:
            if c > 0 and t[c - 1] > x:  # (a tick before the last one)
                c = _count_at_most(t, x)
            while c < n and t[c] <= x:
                c += 1
            j = min(max(c - 1, 0), n - 2)
        h = t[j + 1] - t[j]
        hh = h * h
        s = (x - t[j]) / h
        s2 = s * s
        s3 = s2 * s
        # the Hermite basis and its derivatives (each the expression of the formula)
        p0 = 2 * s3 - 3 * s2 + 1
        p1 = s3 - 2 * s2 + s
        p2 = -2 * s3 + 3 * s2
        p3 = s3 - s2
        d0 = 6 * s2 - 6 * s
        d1 = 3 * s2 - 4 * s + 1
        d2 = -6 * s2 + 6 * s
        d3 = 3 * s2 - 2 * s
        a0 = 12 * s - 6
        a1 = 6 * s - 4
        a2 = -12 * s + 6
        a3 = 6 * s - 2
        for r in range(na):
            q0 = q[r, j]
            q1 = q[r, j + 1]
            m0 = v[r, j] * h
            m1 = v[r, j + 1] * h
            pos[r, k] = p0 * q0 + p1 * m0 + p2 * q1 + p3 * m1
            vel[r, k] = (d0 * q0 + d1 * m0 + d2 * q1 + d3 * m1) / h
            acc[r, k] = (a0 * q0 + a1 * m0 + a2 * q1 + a3 * m1) / hh


def linear_command(t: np.ndarray, q: np.ndarray,
                   tk: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Position, velocity and acceleration at ``tk`` of straight-line (G01) moves.

    The velocity is the segment's slope (at a point exactly on a program point, the mean
    of the slopes on either side); the acceleration is zero between points (the
    velocity steps are impulses: the servo sees them through the change of velocity
    between its ticks)."""
    t, q = check_program(t, q)
    tk = np.asarray(tk, dtype=np.float64)
    slope = np.diff(q) / np.diff(t)
    i = _segments(t, tk)
    pos = q[i] + slope[i] * (tk - t[i])
    il = np.clip(np.searchsorted(t, tk, side="left") - 1, 0, t.size - 2)
    vel = 0.5 * (slope[i] + slope[il])
    return pos, vel, np.zeros_like(pos)
