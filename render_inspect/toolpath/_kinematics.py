"""Axis kinematics of a turning path: X, Z and C positions, velocities, accelerations and
jerk in time, their maxima, machine-limit warnings and plots in the style of the RCSE paper's Figs. 8-9.

Machine axes: X = rho (mm), Z = z (mm, tool tip), C = theta (rad, cumulative), each a
function of the time ``t`` of the path (s).  Derivatives are finite differences on the
path's own, possibly non-uniform, time axis:

- velocity: second-order central difference for unequal steps (``numpy.gradient``),
  second-order one-sided at the ends;
- acceleration: the three-point second difference for unequal steps
  ``2 [h1 q(i+1) - (h1 + h2) q(i) + h2 q(i-1)] / (h1 h2 (h1 + h2))`` (h1 = t(i) - t(i-1),
  h2 = t(i+1) - t(i); exact for quadratics), ends copied from their neighbours;
- jerk: ``numpy.gradient`` of the acceleration.

Every maximum is of the absolute value.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from ..core.lazy import njit  # numba, imported on first use

from ..core.errors import InputError
from ..core.toolpath import ToolPath, turns_m04

__all__ = ["axis_derivatives", "kinematics", "limits_from_process", "LIMIT_KEYS", "turning_axes",
           "axes_derivatives"]

#: scene key (``[process]``) -> (axis, derivative order, label, unit)
LIMIT_KEYS = {
    "x_velocity_limit_mm_s": ("x", 1, "X velocity", "mm/s"),
    "x_acceleration_limit_mm_s2": ("x", 2, "X acceleration", "mm/s^2"),
    "z_velocity_limit_mm_s": ("z", 1, "Z velocity", "mm/s"),
    "z_acceleration_limit_mm_s2": ("z", 2, "Z acceleration", "mm/s^2"),
}


def _check_time(t: np.ndarray) -> None:
    if t.size >= 2:
        dt = np.diff(t)
        bad = np.flatnonzero(~(dt > 0))
        if bad.size:
            i = int(bad[0])
            raise InputError(f"ToolPath.t must be strictly increasing for kinematics; "
                             f"t[{i}] = {t[i]!r} s and t[{i + 1}] = {t[i + 1]!r} s "
                             f"({bad.size} such steps)")


@njit(cache=True, nogil=True)
def _gradient(t, f, edge_order, out):
    """``numpy.gradient(f, t, edge_order=edge_order)`` into ``out``: the same formulas in
    the same order (uniform steps, when every step equals the first, the plain ones)."""
    n = f.size
    h0 = t[1] - t[0]
    uniform = True
    for i in range(1, n - 1):
        if t[i + 1] - t[i] != h0:
            uniform = False
            break
    for i in range(1, n - 1):
        if uniform:
            out[i] = (f[i + 1] - f[i - 1]) / (2.0 * h0)
        else:
            dx1 = t[i] - t[i - 1]
            dx2 = t[i + 1] - t[i]
            a = -(dx2) / (dx1 * (dx1 + dx2))
            b = (dx2 - dx1) / (dx1 * dx2)
            c = dx1 / (dx2 * (dx1 + dx2))
            out[i] = a * f[i - 1] + b * f[i] + c * f[i + 1]
    if edge_order == 1:
        out[0] = (f[1] - f[0]) / (h0 if uniform else t[1] - t[0])
        out[n - 1] = (f[n - 1] - f[n - 2]) / (h0 if uniform else t[n - 1] - t[n - 2])
        return
    if uniform:
        a, b, c = -1.5 / h0, 2.0 / h0, -0.5 / h0
    else:
        dx1 = t[1] - t[0]
        dx2 = t[2] - t[1]
        a = -(2. * dx1 + dx2) / (dx1 * (dx1 + dx2))
        b = (dx1 + dx2) / (dx1 * dx2)
        c = - dx1 / (dx2 * (dx1 + dx2))
    out[0] = a * f[0] + b * f[1] + c * f[2]
    if uniform:
        a, b, c = 0.5 / h0, -2.0 / h0, 1.5 / h0
    else:
        dx1 = t[n - 2] - t[n - 3]
        dx2 = t[n - 1] - t[n - 2]
        a = (dx2) / (dx1 * (dx1 + dx2))
        b = - (dx2 + dx1) / (dx1 * dx2)
        c = (2. * dx2 + dx1) / (dx2 * (dx1 + dx2))
    out[n - 1] = a * f[n - 3] + b * f[n - 2] + c * f[n - 1]


@njit(cache=True, nogil=True)
def _second(t, q, a):
    """The three-point second difference for unequal steps, ends copied."""
    n = q.size
    for i in range(1, n - 1):
        h1 = t[i] - t[i - 1]
        h2 = t[i + 1] - t[i]
        a[i] = 2.0 * (h1 * q[i + 1] - (h1 + h2) * q[i] + h2 * q[i - 1]) / (h1 * h2 * (h1 + h2))
    a[0] = a[1]
    a[n - 1] = a[n - 2]


@njit(cache=True, nogil=True, inline="always")
def _abs_max(a):
    """max |a_i| (NaN if any is NaN, as numpy's)."""
    m = 0.0
    for i in range(a.size):
        v = abs(a[i])
        if not v <= m:
            m = v
            if v != v:
                return v
    return m


@njit(cache=True, nogil=True, inline="always")
def _reversals(v, eps):
    """Sign changes of v among its values with |v| > eps."""
    n = 0
    last = 0.0
    for i in range(v.size):
        if abs(v[i]) > eps:
            sg = 1.0 if v[i] > 0 else -1.0
            if last != 0.0 and sg != last:
                n += 1
            last = sg
    return n


@njit(cache=True, nogil=True)
def _maxima(vx, ax, jx, vz, az, jz, vc, eps, out):
    """The largest |value| of each of the seven series (into ``out``, in this order);
    returns the sign changes of ``vx`` among its values with |v| > ``eps``."""
    out[0] = _abs_max(vx)
    out[1] = _abs_max(ax)
    out[2] = _abs_max(jx)
    out[3] = _abs_max(vz)
    out[4] = _abs_max(az)
    out[5] = _abs_max(jz)
    out[6] = _abs_max(vc)
    return _reversals(vx, eps)


def axis_derivatives(t: np.ndarray, q: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Velocity, acceleration and jerk of the samples ``q(t)`` on a non-uniform time axis.

    Parameters
    ----------
    t : (n,) array, s, strictly increasing (n >= 3)
    q : (n,) array, axis position (any unit u)

    Returns
    -------
    v, a, j : (n,) float64 arrays, u/s, u/s^2, u/s^3
    """
    t = np.asarray(t, dtype=np.float64)
    q = np.asarray(q, dtype=np.float64)
    if t.shape != q.shape or t.ndim != 1:
        raise InputError(f"t and q must be 1-D arrays of one length, received {t.shape} and {q.shape}")
    if t.size < 3:
        raise InputError(f"kinematics needs at least 3 path points, received {t.size}")
    _check_time(t)
    t = np.ascontiguousarray(t)
    q = np.ascontiguousarray(q)
    v, a, j = np.empty_like(q), np.empty_like(q), np.empty_like(q)
    _gradient(t, q, 2, v)
    _second(t, q, a)
    _gradient(t, a, 1, j)
    return v, a, j


def turning_axes(path: ToolPath, data: dict | None = None) -> dict:
    """The machine axes of a turning path: ``X`` (radius, mm) and ``Z`` (tool tip, mm);
    with the servo split of a tool-servo program (``data`` holding ``z_slow`` and
    ``z_fts``, mm): ``Z`` = the slow slide's command and ``FTS`` = the fast tool servo's
    stroke instead."""
    axes = {"X": np.asarray(path.rho, dtype=np.float64)}
    data = data or {}
    zs, zf = data.get("z_slow"), data.get("z_fts")
    if zs is not None and zf is not None and np.size(zs) == np.size(path.rho):
        axes["Z"] = np.asarray(zs, dtype=np.float64)
        axes["FTS"] = np.asarray(zf, dtype=np.float64)
    else:
        axes["Z"] = np.asarray(path.z, dtype=np.float64)
    return axes


def axes_derivatives(t: np.ndarray, axes: dict) -> dict:
    """:func:`axis_derivatives` (v, a, j) of each axis of ``axes`` (name -> positions at
    the times ``t``) that moves (at least 3 points, not all equal)."""
    t = np.asarray(t, dtype=np.float64)
    out = {}
    for name, q in axes.items():
        q = np.asarray(q, dtype=np.float64)
        if q.size >= 3 and np.ptp(q) > 0:
            out[name] = axis_derivatives(t, q)
    return out


def limits_from_process(process_cfg: Any) -> dict:
    """The machine limits of a ``[process]`` section (or dict) that are set, by scene key."""
    out = {}
    for key in LIMIT_KEYS:
        val = process_cfg.get(key) if isinstance(process_cfg, dict) else getattr(process_cfg, key, None)
        if val is not None:
            out[key] = float(val)
    return out


def _at(path, i: int) -> str:
    return (f"t = {path.t[i]:.4f} s, radius {path.rho[i]:.4f} mm, "
            f"C = {math.degrees(-path.theta[i] if turns_m04(path) else path.theta[i]):.2f} deg")


def kinematics(path: ToolPath, *, limits: dict | None = None,
               valid: np.ndarray | None = None, derivatives: dict | None = None) -> dict:
    """Axis kinematics of a tool path and warnings where it exceeds the machine limits.

    Parameters
    ----------
    path : ToolPath
        X = ``rho``, Z = ``z``, C = ``theta`` at times ``t`` (strictly increasing).
    limits : dict or ProcessConfig, optional
        ``x_velocity_limit_mm_s``, ``x_acceleration_limit_mm_s2``, ``z_velocity_limit_mm_s``,
        ``z_acceleration_limit_mm_s2`` (None or absent: not checked).
    valid : (n,) bool array, optional
        The points whose derivatives count (a window's program planned in sectors: the
        points of the sectors, whose neighbours two either side are the program's own;
        not the joins to the sparse points between them).  Default: all.
    derivatives : dict, optional
        The (v, a, j) of ``X`` (``path.rho``) and ``Z`` (``path.z``) at the times
        ``path.t``, where the caller has them (:func:`axes_derivatives` of
        :func:`turning_axes`); an axis missing is computed here.  They are not changed.

    Returns
    -------
    dict
        ``x_velocity_max_mm_s``, ``x_acceleration_max_mm_s2``, ``x_jerk_max_mm_s3``,
        ``z_velocity_max_mm_s``, ``z_acceleration_max_mm_s2``, ``z_jerk_max_mm_s3``,
        ``c_velocity_max_rad_s``, ``x_velocity_mean_mm_s`` (mean of |vX|),
        ``x_reversals`` (sign changes of the X velocity), ``duration_s``,
        ``limits`` (the limits checked), ``limits_exceeded`` (scene key -> points over the
        limit), ``warnings`` (list of str: what, by how much, where: time and radius).
    """
    if limits is None:
        lim = {}
    elif isinstance(limits, dict):
        lim = {k: float(v) for k, v in limits.items() if v is not None}
    else:
        lim = limits_from_process(limits)
    unknown = sorted(set(lim) - set(LIMIT_KEYS))
    if unknown:
        raise InputError(f"unknown kinematic limit(s) {unknown}; allowed: {sorted(LIMIT_KEYS)}")
    for k, v in lim.items():
        if not v > 0:
            raise InputError(f"{k} must be > 0, received {v}")
    t = np.asarray(path.t, dtype=np.float64)
    given = derivatives or {}
    vx, ax, jx = given["X"] if "X" in given else axis_derivatives(t, path.rho)
    vz, az, jz = given["Z"] if "Z" in given else axis_derivatives(t, path.z)
    vc = np.empty_like(t)
    _gradient(t, np.ascontiguousarray(path.theta, dtype=np.float64), 2, vc)
    ok = None
    if valid is not None:
        # (the caller's arrays are left as they are)
        if "X" in given:
            vx, ax, jx = vx.copy(), ax.copy(), jx.copy()
        if "Z" in given:
            vz, az, jz = vz.copy(), az.copy(), jz.copy()
        ok = np.asarray(valid, dtype=bool).copy()
        for k in (1, 2):  # the stencils of the derivatives (jerk: two either side)
            ok[k:] &= ok[:-k].copy()
            ok[:-k] &= ok[k:].copy()
        for arr in (vx, ax, jx, vz, az, jz, vc):
            arr[~ok] = 0.0
    series = {("x", 1): vx, ("x", 2): ax, ("z", 1): vz, ("z", 2): az}
    top = np.empty(7)
    reversals = _maxima(vx, ax, jx, vz, az, jz, vc, 1e-12, top)
    out: dict[str, Any] = {
        "x_velocity_max_mm_s": float(top[0]),
        "x_acceleration_max_mm_s2": float(top[1]),
        "x_jerk_max_mm_s3": float(top[2]),
        "z_velocity_max_mm_s": float(top[3]),
        "z_acceleration_max_mm_s2": float(top[4]),
        "z_jerk_max_mm_s3": float(top[5]),
        "c_velocity_max_rad_s": float(top[6]),
        "x_velocity_mean_mm_s": float(np.mean(np.abs(vx if ok is None else vx[ok]))),
        "x_reversals": int(reversals),
        "duration_s": float(t[-1] - t[0]),
        "limits": dict(lim),
        "limits_exceeded": {},
        "warnings": [],
    }
    for key, value in lim.items():
        axis, order, label, unit = LIMIT_KEYS[key]
        mag = np.abs(series[(axis, order)])
        over = np.flatnonzero(mag > value)
        if over.size:
            worst = int(np.argmax(mag))
            out["limits_exceeded"][key] = int(over.size)
            out["warnings"].append(
                f"{label} exceeds process.{key} = {value:g} {unit} at {over.size} of {mag.size} "
                f"points: first at {_at(path, int(over[0]))}; worst {mag[worst]:.4g} {unit} at "
                f"{_at(path, worst)}")
    return out
