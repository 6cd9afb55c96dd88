"""Axis dynamics of a turning machine: the program as the controller sees it, each axis a
servo, the followed path and the following error.

Chain (one axis; C, X, Z and the fast tool servo alike)
-------------------------------------------------------
1. **Interpolator.**  The controller receives the program's points (t_i, q_i) and
   evaluates a command q_c(t), v_c(t), a_c(t) at every servo tick t_k = t_0 + k / rate:

   * ``"pvt"`` (position-velocity-time, the mode seed 001 names): a cubic Hermite segment
     between consecutive points, with the velocity at each point taken as the slope of
     the parabola through it and its two neighbours (the three-point derivative on an
     uneven time axis; one-sided at the ends).  Position and velocity are continuous,
     acceleration is piecewise linear;
   * ``"linear"`` (G01 blocks): straight segments; the velocity jumps at each point and
     the acceleration is the jump divided by the tick (an impulse, as a servo sees it).

2. **Servo.**  A position loop around a rigid axis (mass-normalised, x'' = u + d) with
   proportional-derivative gains that place the closed-loop poles at
   s^2 + 2 zeta wn s + wn^2 (wn = 2 pi ``bandwidth_hz``), plus velocity and acceleration
   feed-forward (gains kv, ka in [0, 1]):

       u = ka a_c + wn^2 (q_c - q) + 2 zeta wn (kv v_c - q')

   In the following error e = q_c - q this is

       e'' + 2 zeta wn e' + wn^2 e = (1 - ka) a_c + 2 zeta wn (1 - kv) v_c - d

   so kv = ka = 0 is the plain second-order low-pass wn^2 / (s^2 + 2 zeta wn s + wn^2)
   and kv = ka = 1 follows any command exactly; what is left is the disturbance d.  The
   equation is integrated exactly over each tick with the command's mean velocity and
   acceleration over the tick (second-order accurate; straight moves enter as velocity
   steps at the ticks).
   ``acceleration_limit`` bounds u (the motor's force limit; the feed-forward part alone
   is clipped to it first): while it is exceeded the axis accelerates at the limit and
   the error grows; ``velocity_limit`` bounds q'.

3. **Disturbance.**  Broadband force noise (air/oil bearing, amplifier, floor), white at
   the tick rate, scaled so that the following error it causes has the rms
   ``noise_rms`` in steady state (discrete Lyapunov equation of the loop), from the seed.

4. **Latency.**  ``delay_s`` delays the axis output (communication between controllers).

An *ideal* axis (``bandwidth_hz = None``, no noise, no delay) is its command.  A machine
whose axes are all ideal and which has no error motions returns the program unchanged,
so ``preset = "ideal"`` gives the geometric (commanded) result exactly.

Units: linear axes in mm, C in rad; velocities and limits per second; ``noise_rms`` in
the axis unit.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, fields, replace

import numpy as np
from numba import njit

from ..core.errors import InputError, check_range
from ._errmotion import ErrorMotions, apply_error_motions

__all__ = ["Axis", "Coupling", "Machine", "FollowedPath", "AxisResponse", "MACHINE_PRESETS",
           "machine_preset", "pvt_command", "linear_command", "follow_axis", "follow_turning",
           "following_error_stats"]

_MAX_TICKS = 60_000_000
TWO_PI = 2.0 * math.pi


# ---------------------------------------------------------------------------------------
# interpolators
# ---------------------------------------------------------------------------------------
def _check_program(t, q) -> tuple[np.ndarray, np.ndarray]:
    t = np.asarray(t, dtype=np.float64)
    q = np.asarray(q, dtype=np.float64)
    if t.ndim != 1 or t.shape != q.shape or t.size < 2:
        raise InputError(f"t and q must be 1-D arrays of one length >= 2, received {t.shape} "
                         f"and {q.shape}")
    dt = np.diff(t)
    bad = np.flatnonzero(~(dt > 0))
    if bad.size:
        i = int(bad[0])
        raise InputError(f"program times must increase strictly; t[{i}] = {t[i]!r} s, "
                         f"t[{i + 1}] = {t[i + 1]!r} s")
    if not np.all(np.isfinite(q)):
        raise InputError("program positions must be finite")
    return t, q


def pvt_velocities(t, q) -> np.ndarray:
    """Velocity at each program point: slope of the parabola through it and its
    neighbours (second-order, uneven steps), one-sided (the segment slope) at the ends.

    Parameters
    ----------
    t, q : (n,) arrays (s, axis unit), n >= 2

    Returns
    -------
    (n,) float64, axis unit / s
    """
    t, q = _check_program(t, q)
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


def pvt_command(t, q, tk, *, velocities=None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
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
    t, q = _check_program(t, q)
    v = pvt_velocities(t, q) if velocities is None else np.asarray(velocities, dtype=np.float64)
    tk = np.asarray(tk, dtype=np.float64)
    i = _segments(t, tk)
    h = t[i + 1] - t[i]
    s = (tk - t[i]) / h
    q0, q1 = q[i], q[i + 1]
    m0, m1 = v[i] * h, v[i + 1] * h
    s2 = s * s
    s3 = s2 * s
    pos = (2 * s3 - 3 * s2 + 1) * q0 + (s3 - 2 * s2 + s) * m0 + (-2 * s3 + 3 * s2) * q1 + (s3 - s2) * m1
    vel = ((6 * s2 - 6 * s) * q0 + (3 * s2 - 4 * s + 1) * m0 + (-6 * s2 + 6 * s) * q1
           + (3 * s2 - 2 * s) * m1) / h
    acc = ((12 * s - 6) * q0 + (6 * s - 4) * m0 + (-12 * s + 6) * q1 + (6 * s - 2) * m1) / (h * h)
    return pos, vel, acc


def linear_command(t, q, tk) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Position, velocity and acceleration at ``tk`` of straight-line (G01) moves.

    The velocity is the segment's slope (at a point exactly on a program point, the mean
    of the slopes on either side); the acceleration is zero between points (the
    velocity steps are impulses: the servo sees them through the change of velocity
    between its ticks)."""
    t, q = _check_program(t, q)
    tk = np.asarray(tk, dtype=np.float64)
    slope = np.diff(q) / np.diff(t)
    i = _segments(t, tk)
    pos = q[i] + slope[i] * (tk - t[i])
    il = np.clip(np.searchsorted(t, tk, side="left") - 1, 0, t.size - 2)
    vel = 0.5 * (slope[i] + slope[il])
    return pos, vel, np.zeros_like(pos)


# ---------------------------------------------------------------------------------------
# servo
# ---------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Axis:
    """One servo axis.

    Parameters
    ----------
    bandwidth_hz : float or None
        Closed-loop natural frequency fn of the position loop; None = ideal (the axis is
        its command).
    damping : float
        zeta of the closed loop, > 0.
    velocity_ff, acceleration_ff : float
        Feed-forward gains kv, ka in [0, 1] (1 = perfectly tuned).
    velocity_limit, acceleration_limit : float or None
        Bounds on the axis velocity and on the commanded acceleration (axis unit / s,
        / s^2); None = unbounded.
    noise_rms : float
        Steady-state rms of the following error caused by broadband force disturbance
        (axis unit), >= 0.
    delay_s : float
        Output latency, >= 0.
    """

    bandwidth_hz: float | None = None
    damping: float = 0.7
    velocity_ff: float = 0.0
    acceleration_ff: float = 0.0
    velocity_limit: float | None = None
    acceleration_limit: float | None = None
    noise_rms: float = 0.0
    delay_s: float = 0.0

    def __post_init__(self):
        if self.bandwidth_hz is not None:
            check_range("bandwidth_hz", self.bandwidth_hz, 0.0, 1e6, lo_open=True)
        check_range("damping", self.damping, 0.0, 10.0, lo_open=True)
        check_range("velocity_ff", self.velocity_ff, 0.0, 1.0)
        check_range("acceleration_ff", self.acceleration_ff, 0.0, 1.0)
        for k in ("velocity_limit", "acceleration_limit"):
            v = getattr(self, k)
            if v is not None:
                check_range(k, v, 0.0, None, lo_open=True)
        check_range("noise_rms", self.noise_rms, 0.0, None)
        check_range("delay_s", self.delay_s, 0.0, 10.0)
        if self.bandwidth_hz is None and self.noise_rms > 0:
            raise InputError("noise_rms needs a finite bandwidth_hz (the disturbance acts "
                             f"through the servo loop), received noise_rms = {self.noise_rms}")

    @property
    def ideal(self) -> bool:
        return self.bandwidth_hz is None and self.noise_rms == 0 and self.delay_s == 0

    def to_dict(self) -> dict:
        return {f.name: getattr(self, f.name) for f in fields(self)}


@dataclass(frozen=True)
class Coupling:
    """Reaction-force coupling of the X slide into the tool-part loop.

    The X slide (moving mass ``mass_kg``, which carries the spindle headstock on a T-base
    lathe) is driven by a force m a_x whose reaction loads the machine frame.  Through the
    frame's cross-compliance the tool and the part move apart along Z (surface normal)
    and Y (cutting direction): d = c m a_x, shaped by the frame mode ``mode_hz`` /
    ``mode_damping`` (second-order, unit static gain).  A path whose X moves at constant
    speed (a_x = 0) excites nothing; a reciprocating X does (seed 004: "the intense
    reciprocating motion of the X-axis can destabilize ... leading to significant machining
    errors in the sensitive direction").

    Parameters
    ----------
    mass_kg : float
    z_compliance_nm_per_n, y_compliance_nm_per_n : float
        Static cross-compliance from the X drive force to the relative tool-part
        displacement along Z and Y.
    mode_hz, mode_damping : float
    """

    mass_kg: float = 0.0
    z_compliance_nm_per_n: float = 0.0
    y_compliance_nm_per_n: float = 0.0
    mode_hz: float = 100.0
    mode_damping: float = 0.05

    def __post_init__(self):
        check_range("coupling.mass_kg", self.mass_kg, 0.0, 1e5)
        check_range("coupling.z_compliance_nm_per_n", self.z_compliance_nm_per_n, 0.0, 1e4)
        check_range("coupling.y_compliance_nm_per_n", self.y_compliance_nm_per_n, 0.0, 1e4)
        check_range("coupling.mode_hz", self.mode_hz, 0.0, 1e6, lo_open=True)
        check_range("coupling.mode_damping", self.mode_damping, 0.0, 10.0, lo_open=True)

    @property
    def none(self) -> bool:
        return self.mass_kg == 0 or (self.z_compliance_nm_per_n == 0 and self.y_compliance_nm_per_n == 0)

    def to_dict(self) -> dict:
        return {f.name: getattr(self, f.name) for f in fields(self)}

    def deflection(self, t, x_followed) -> tuple[np.ndarray, np.ndarray]:
        """(dz, dy) in mm at the uniform ticks ``t`` for the followed X position (mm)."""
        from scipy import signal

        t = np.asarray(t, dtype=np.float64)
        x = np.asarray(x_followed, dtype=np.float64)
        if self.none or t.size < 3:
            return np.zeros_like(t), np.zeros_like(t)
        dt = float(t[1] - t[0])
        a = np.zeros_like(x)
        a[1:-1] = (x[2:] - 2 * x[1:-1] + x[:-2]) / (dt * dt)           # mm/s^2
        force = self.mass_kg * a * 1e-3                                  # N
        sos = _second_order_sos(self.mode_hz, self.mode_damping, dt)
        shaped = signal.sosfilt(sos, force)
        return (shaped * self.z_compliance_nm_per_n * 1e-6,
                shaped * self.y_compliance_nm_per_n * 1e-6)


def _second_order_sos(fn: float, zeta: float, dt: float) -> np.ndarray:
    """Unit-gain second-order low-pass at fn (bilinear, pre-warped)."""
    from scipy import signal

    fs = 1.0 / dt
    wn = TWO_PI * fn
    wa = 2 * fs * math.tan(min(wn / (2 * fs), 0.5 * math.pi * 0.999))
    z, p, k = signal.bilinear_zpk([], np.roots([1.0, 2 * zeta * wa, wa * wa]), wa * wa, fs)
    return signal.zpk2sos(z, p, np.real(k))


@dataclass
class AxisResponse:
    """Command and followed position of one axis at the servo ticks.

    Attributes
    ----------
    t : (m,) s;  command, followed, error (= command - followed) : (m,) axis unit;
    velocity, acceleration : (m,) the interpolated command's derivatives.
    """

    t: np.ndarray
    command: np.ndarray
    followed: np.ndarray
    velocity: np.ndarray
    acceleration: np.ndarray

    @property
    def error(self) -> np.ndarray:
        return self.command - self.followed


def _discrete_loop(wn: float, zeta: float, dt: float):
    """Exact zero-order-hold discretisation of e'' + 2 zeta wn e' + wn^2 e = F."""
    from scipy.linalg import expm

    a = np.array([[0.0, 1.0], [-wn * wn, -2.0 * zeta * wn]])
    m = np.zeros((3, 3))
    m[:2, :2] = a * dt
    m[1, 2] = dt
    em = expm(m)
    return np.ascontiguousarray(em[:2, :2]), np.ascontiguousarray(em[:2, 2])


@njit(cache=True)
def _track(pos, v_step, a_step, jump, ff_step, v_start, v_end, dist, phi, gam, wn, zeta, kv,
           amax, vmax, dt, e0, de0, out):
    """Following error at each tick of the loop described in the module docstring.

    Step k (tick k to k + 1): the command's velocity jumps by ``jump[k]`` at the tick
    (straight moves), then moves with mean velocity ``v_step[k]`` and mean acceleration
    ``a_step[k]``; the drive feeds forward ``ff_step[k]`` (already clipped to its limit).
    ``v_start`` / ``v_end`` are the command's velocities just after tick k and just before
    tick k + 1."""
    e = e0
    de = de0
    c1 = 2.0 * zeta * wn
    n = pos.size
    out[0] = e
    for k in range(n - 1):
        de += jump[k]
        v = v_step[k]
        a = a_step[k]
        ff = ff_step[k]
        u = ff + wn * wn * e + c1 * (kv * v - v + de)
        if abs(u) > amax:
            # saturated: the axis itself moves at the limit (integrated in its own
            # coordinates)
            us = (amax if u > 0 else -amax) + dist[k]
            x = pos[k] - e
            xd = v_start[k] - de
            x = x + xd * dt + 0.5 * us * dt * dt
            xd = xd + us * dt
            e = pos[k + 1] - x
            de = v_end[k] - xd
        else:
            f = a - ff + c1 * (1.0 - kv) * v - dist[k]
            e1 = phi[0, 0] * e + phi[0, 1] * de + gam[0] * f
            de = phi[1, 0] * e + phi[1, 1] * de + gam[1] * f
            e = e1
        w = v_end[k] - de
        if w > vmax:
            de = v_end[k] - vmax
        elif w < -vmax:
            de = v_end[k] + vmax
        out[k + 1] = e


def _noise_scale(phi, gam, target_rms: float) -> float:
    """Standard deviation of white tick-rate force noise giving ``target_rms`` following
    error in steady state (discrete Lyapunov equation P = Phi P Phi^T + G G^T)."""
    from scipy.linalg import solve_discrete_lyapunov

    p = solve_discrete_lyapunov(phi, np.outer(gam, gam))
    return target_rms / math.sqrt(max(p[0, 0], 1e-300))


def servo_ticks(t0: float, t1: float, rate_hz: float) -> np.ndarray:
    """Servo tick times t0 + k / rate_hz in [t0, t1]."""
    check_range("servo_rate_hz", rate_hz, 0.0, 1e7, lo_open=True)
    n = int(math.floor((t1 - t0) * rate_hz + 1e-9)) + 1
    if n > _MAX_TICKS:
        raise InputError(f"the program lasts {t1 - t0:.4g} s: {n} servo ticks at {rate_hz:g} Hz "
                         f"(> {_MAX_TICKS}); shorten the path (simulation.region) or lower "
                         "machine.servo_rate_hz")
    return t0 + np.arange(max(n, 2)) / rate_hz


def follow_axis(t, q, axis: Axis, *, rate_hz: float, interpolation: str = "pvt",
                seed: int = 0, ticks=None, command=None) -> AxisResponse:
    """Follow one axis's program through its interpolator and servo.

    Parameters
    ----------
    t, q : (n,) arrays
        Program times (s) and positions (axis unit).
    axis : Axis
    rate_hz : float
        Servo (interpolation) rate.
    interpolation : {"pvt", "linear"}
    seed : int
        Seed of the disturbance noise.
    ticks : (m,) array, optional
        Tick times (default :func:`servo_ticks` over the program).
    command : (q_c, v_c, a_c), optional
        A command already evaluated at ``ticks`` (e.g. a position-synchronised one).

    Returns
    -------
    AxisResponse at the ticks.
    """
    t, q = _check_program(t, q)
    if ticks is None:
        ticks = servo_ticks(float(t[0]), float(t[-1]), rate_hz)
    tk = np.asarray(ticks, dtype=np.float64)
    linear = interpolation == "linear"
    if command is None:
        if interpolation == "pvt":
            command = pvt_command(t, q, tk)
        elif interpolation == "linear":
            command = linear_command(t, q, tk)
        else:
            raise InputError(f"interpolation must be 'pvt' or 'linear', received {interpolation!r}")
    qc, vc, ac = (np.ascontiguousarray(a, dtype=np.float64) for a in command)
    if axis.bandwidth_hz is None:
        followed = qc.copy()
    else:
        dt = 1.0 / float(rate_hz)
        wn = TWO_PI * float(axis.bandwidth_hz)
        zeta = float(axis.damping)
        phi, gam = _discrete_loop(wn, zeta, dt)
        if axis.noise_rms > 0:
            sd = _noise_scale(phi, gam, float(axis.noise_rms))
            dist = np.random.default_rng(seed).normal(0.0, sd, size=qc.size)
        else:
            dist = np.zeros(qc.size)
        ka, kv = float(axis.acceleration_ff), float(axis.velocity_ff)
        # start in the steady state of the mean velocity over the first 1 / fn (a ramp's
        # lag), so the statistics hold no start-up transient
        n0 = max(1, min(qc.size - 1, int(rate_hz / float(axis.bandwidth_hz))))
        v0 = (qc[n0] - qc[0]) / (tk[n0] - tk[0]) if qc.size > 1 else 0.0
        f0 = 2 * zeta * wn * (1.0 - kv) * v0
        err = np.empty(qc.size)
        amax = 1e300 if axis.acceleration_limit is None else float(axis.acceleration_limit)
        vmax = 1e300 if axis.velocity_limit is None else float(axis.velocity_limit)
        v_step = np.diff(qc) / dt
        if linear:
            # straight moves: constant velocity inside each step, steps at the ticks
            a_step = np.zeros_like(v_step)
            jump = np.concatenate([[0.0], np.diff(v_step)])
            ff = np.clip(ka * jump / dt, -amax, amax)
            v_start = v_end = v_step
        else:
            a_step = np.diff(vc) / dt
            jump = np.zeros_like(v_step)
            ff = np.clip(ka * a_step, -amax, amax)
            v_start, v_end = vc[:-1], vc[1:]
        _track(qc, v_step, a_step, jump, ff, np.ascontiguousarray(v_start),
               np.ascontiguousarray(v_end), dist, phi, gam, wn, zeta, kv, amax, vmax, dt,
               f0 / (wn * wn), 0.0, err)
        followed = qc - err
    if axis.delay_s > 0:
        followed = np.interp(tk - axis.delay_s, tk, followed)
    return AxisResponse(tk, qc, followed, vc, ac)


# ---------------------------------------------------------------------------------------
# the machine
# ---------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Machine:
    """A C-X-Z turning machine with an optional fast tool servo.

    Parameters
    ----------
    name : str
    servo_rate_hz : float
        Rate at which the interpolator evaluates the commands and the loops run.
    interpolation : {"pvt", "linear"}
    c, x, z, fts : Axis
        Spindle angle (rad), radial slide X (mm), axial slide Z (mm), fast tool servo (mm,
        along Z).
    fts_sync : {"position", "time"}
        How the FTS stroke is timed: ``"position"`` evaluates the stroke at the measured
        (followed) spindle angle, ``"time"`` plays it against the clock.
    errors : ErrorMotions or None
        Spindle and slide error motions and tool-part vibration
        (:class:`~render_inspect.machining._errmotion.ErrorMotions`).
    coupling : Coupling
        Reaction-force coupling of the X slide into the tool-part loop.
    sources : dict
        Where each preset value comes from (text).
    """

    name: str = "custom"
    servo_rate_hz: float = 10_000.0
    interpolation: str = "pvt"
    c: Axis = field(default_factory=Axis)
    x: Axis = field(default_factory=Axis)
    z: Axis = field(default_factory=Axis)
    fts: Axis = field(default_factory=Axis)
    fts_sync: str = "position"
    errors: object = None
    coupling: Coupling = field(default_factory=Coupling)
    sources: dict = field(default_factory=dict, compare=False)

    def __post_init__(self):
        check_range("servo_rate_hz", self.servo_rate_hz, 0.0, 1e7, lo_open=True)
        if self.interpolation not in ("pvt", "linear"):
            raise InputError(f"machine.interpolation must be 'pvt' or 'linear', received "
                             f"{self.interpolation!r}")
        if self.fts_sync not in ("position", "time"):
            raise InputError(f"machine.fts_sync must be 'position' or 'time', received {self.fts_sync!r}")
        for k in ("c", "x", "z", "fts"):
            if not isinstance(getattr(self, k), Axis):
                raise InputError(f"machine.{k} must be an Axis, received {type(getattr(self, k)).__name__}")

    @property
    def ideal(self) -> bool:
        """All axes ideal and no error motions: the program is followed exactly."""
        no_err = self.errors is None or getattr(self.errors, "none", True)
        return (all(getattr(self, k).ideal for k in ("c", "x", "z", "fts")) and no_err
                and self.coupling.none)

    def to_dict(self) -> dict:
        d = {"name": self.name, "servo_rate_hz": self.servo_rate_hz,
             "interpolation": self.interpolation, "fts_sync": self.fts_sync}
        for k in ("c", "x", "z", "fts"):
            d[k] = getattr(self, k).to_dict()
        d["errors"] = None if self.errors is None else self.errors.to_dict()
        d["coupling"] = self.coupling.to_dict()
        return d

    def with_overrides(self, overrides: dict | None) -> "Machine":
        """A copy with ``overrides`` applied: ``{"x": {"bandwidth_hz": 80}, "servo_rate_hz":
        5000}`` or dotted keys ``{"x.bandwidth_hz": 80}``; ``errors`` takes an
        ErrorMotions or a dict of its fields."""
        if not overrides:
            return self
        nested: dict = {}
        for key, val in overrides.items():
            parts = key.split(".")
            d = nested
            for p in parts[:-1]:
                d = d.setdefault(p, {})
            if isinstance(val, dict) and parts[-1] in d and isinstance(d[parts[-1]], dict):
                d[parts[-1]].update(val)
            else:
                d[parts[-1]] = val
        kw = {}
        for key, val in nested.items():
            if key in ("c", "x", "z", "fts"):
                if isinstance(val, Axis):
                    kw[key] = val
                    continue
                if not isinstance(val, dict):
                    raise InputError(f"machine.{key} overrides must be a table of axis settings, "
                                     f"received {val!r}")
                names = {f.name for f in fields(Axis)}
                bad = sorted(set(val) - names)
                if bad:
                    raise InputError(f"unknown machine.{key} setting(s) {bad}; allowed: {sorted(names)}")
                kw[key] = replace(getattr(self, key), **val)
            elif key == "coupling":
                if isinstance(val, Coupling):
                    kw[key] = val
                else:
                    names = {f.name for f in fields(Coupling)}
                    bad = sorted(set(val) - names)
                    if bad:
                        raise InputError(f"unknown machine.coupling setting(s) {bad}; allowed: "
                                         f"{sorted(names)}")
                    kw[key] = replace(self.coupling, **val)
            elif key == "errors":
                if val is None or isinstance(val, ErrorMotions):
                    kw[key] = val
                else:
                    base = self.errors if self.errors is not None else ErrorMotions()
                    kw[key] = base.with_overrides(val)
            elif key in ("name", "servo_rate_hz", "interpolation", "fts_sync"):
                kw[key] = val
            else:
                raise InputError(f"unknown machine setting {key!r}; allowed: name, servo_rate_hz, "
                                 "interpolation, fts_sync, c, x, z, fts, errors, coupling")
        return replace(self, **kw)


def _um(v):
    return v * 1e-3


#: Machine presets.  The numbers and where they come from are in ``sources`` and in
#: docs/machine_and_material.md; every one can be overridden.
MACHINE_PRESETS: dict = {}


def _register_presets():
    g = 9806.65  # mm/s^2
    MACHINE_PRESETS["ideal"] = Machine(
        name="ideal", sources={"all": "no dynamics, no error motions: the commanded path"})
    # A Nanoform 250 / Nanotech 350FG class slow-tool-servo lathe (hydrostatic or air-bearing
    # slides with linear motors, air-bearing spindle).  The X slide carries the headstock
    # (seed 004: "the X-axis is connected to the heavier headstock"), hence a lower
    # bandwidth than Z.
    sts_errors = ErrorMotions(
        radial_sync=((2, _um(0.005), 0.3), (3, _um(0.003), 1.1)),
        radial_async_rms=_um(0.002), axial_sync=((2, _um(0.003), 0.7), (3, _um(0.002), 2.0)),
        axial_async_rms=_um(0.002), async_bandwidth_hz=200.0,
        x_straightness_rms=_um(0.05), x_straightness_length=50.0)
    MACHINE_PRESETS["sts_lathe"] = Machine(
        name="sts_lathe", servo_rate_hz=5000.0, interpolation="pvt",
        c=Axis(bandwidth_hz=60.0, damping=0.7, velocity_ff=1.0, acceleration_ff=0.9,
               noise_rms=1.0e-6),
        x=Axis(bandwidth_hz=40.0, damping=0.7, velocity_ff=0.95, acceleration_ff=0.5,
               acceleration_limit=0.2 * g, velocity_limit=50.0, noise_rms=_um(0.003)),
        z=Axis(bandwidth_hz=100.0, damping=0.7, velocity_ff=0.95, acceleration_ff=0.5,
               acceleration_limit=0.2 * g, velocity_limit=50.0, noise_rms=_um(0.003)),
        errors=sts_errors,
        coupling=Coupling(mass_kg=150.0, z_compliance_nm_per_n=0.3, y_compliance_nm_per_n=0.3,
                          mode_hz=120.0, mode_damping=0.05),
        sources={
            "servo_rate_hz": "5 kHz: PMAC-class motion controllers of diamond-turning "
                             "lathes run their servo loops at 2-10 kHz (assumed)",
            "interpolation": "PVT, as in seed 001 (Table 3)",
            "acceleration_limit": "0.2 g slide acceleration, seed 001 Table 3 (Nanoform 250)",
            "x.bandwidth_hz": "40 Hz: the X slide carries the spindle headstock (seed 004), "
                              "hence the heavier, slower axis (assumed)",
            "z.bandwidth_hz": "100 Hz: tool-side Z slide, lighter (assumed)",
            "feed_forward": "slides: velocity feed-forward 0.95, acceleration feed-forward "
                            "0.5 (feed-forward gains are tuned to 90-100 %; assumed); "
                            "C: 1.0 / 0.9",
            "noise_rms": "3 nm following-error floor per slide: seed 004 measured a 16 nm "
                         "maximum X following error on a smooth path, and seed 000's measured "
                         "Sq (7.1 +- 0.3 nm) leaves ~2-3 nm rms for everything beyond the feed "
                         "scallop (6.7-7.2 nm)",
            "coupling": "X carriage with the headstock 150 kg; cross-compliance from the X "
                        "drive force to the tool-part loop 0.3 nm/N along Z and Y, about 5 % "
                        "of the 5-10 nm/N direct loop compliance of such lathes; frame mode "
                        "120 Hz, damping 0.05 (all assumed)",
            "x_straightness": "0.05 um rms, 50 mm correlation: seed 001 Table 1 gives "
                              "0.2 um straightness over the 220 mm travel (a long-wave bow)",
            "spindle": "radial / axial synchronous error motion 5 / 3 nm at 2 upr, 3 / 2 nm "
                       "at 3 upr, 2 nm asynchronous: within the <= 25-50 nm motion accuracy "
                       "quoted for air-bearing spindles of such lathes and small enough for "
                       "seed 000's measured Sq (assumed)"})
    MACHINE_PRESETS["fts"] = replace(
        MACHINE_PRESETS["sts_lathe"], name="fts", servo_rate_hz=20000.0,
        fts=Axis(bandwidth_hz=2000.0, damping=0.6, velocity_ff=1.0, acceleration_ff=0.9,
                 noise_rms=_um(0.002)),
        fts_sync="position",
        sources={**MACHINE_PRESETS["sts_lathe"].sources,
                 "servo_rate_hz": "20 kHz: fast-tool-servo controllers sample at 10-50 kHz "
                                  "(assumed)",
                 "fts.bandwidth_hz": "2 kHz closed-loop bandwidth of a piezo FTS with a "
                                     "stroke of tens of um (typical 1-3 kHz; assumed)",
                 "fts.feed_forward": "velocity 1.0, acceleration 0.9: FTS controllers feed "
                                     "the stroke's derivatives forward (inverse model) to "
                                     "track within a small fraction of the stroke (assumed)",
                 "fts_sync": "position: the FTS reads the spindle encoder (seed 002 names "
                             "position and time synchronisation)"})


def machine_preset(name: str = "ideal", overrides: dict | None = None) -> Machine:
    """A machine preset (``"ideal"``, ``"sts_lathe"``, ``"fts"``) with ``overrides``
    (see :meth:`Machine.with_overrides`)."""
    if not MACHINE_PRESETS:
        _register_presets()
    if name not in MACHINE_PRESETS:
        raise InputError(f"machine.preset must be one of {sorted(MACHINE_PRESETS)}, received {name!r}")
    return MACHINE_PRESETS[name].with_overrides(overrides)


# ---------------------------------------------------------------------------------------
# following a turning program
# ---------------------------------------------------------------------------------------
@dataclass
class FollowedPath:
    """The path a turning machine really follows.

    Attributes
    ----------
    t, theta, rho, z : (m,) arrays
        Tick times (s) and the tool-tip position relative to the part (rad cumulative,
        mm, mm) after the servos and the error motions: what the envelope cuts.
    commanded : dict
        The interpolated commands at the ticks: ``theta, rho, z, z_slow, z_fts``.
    errors : dict
        Following errors (command - followed) at the ticks: ``c`` (rad), ``x``, ``z``
        (Z slide), ``fts`` (mm).
    ideal : bool
        True when the program was returned unchanged (ideal machine).
    machine : Machine
    """

    t: np.ndarray
    theta: np.ndarray
    rho: np.ndarray
    z: np.ndarray
    commanded: dict
    errors: dict
    ideal: bool
    machine: Machine

    def following_error(self) -> dict:
        """:func:`following_error_stats` of this path."""
        return following_error_stats(self.errors)


def following_error_stats(errors: dict) -> dict:
    """``{x_rms_nm, x_max_nm, z_rms_nm, z_max_nm, c_rms_urad, c_max_urad, fts_rms_nm,
    fts_max_nm}`` of following-error arrays (mm; rad for ``c``)."""
    out = {}
    for k, unit, scale in (("x", "nm", 1e6), ("z", "nm", 1e6), ("c", "urad", 1e6), ("fts", "nm", 1e6)):
        e = np.asarray(errors.get(k, np.zeros(1)), dtype=np.float64)
        e = e[np.isfinite(e)]
        out[f"{k}_rms_{unit}"] = float(np.sqrt(np.mean(e * e)) * scale) if e.size else 0.0
        out[f"{k}_max_{unit}"] = float(np.max(np.abs(e)) * scale) if e.size else 0.0
    return out


def follow_turning(t, theta, rho, z, machine: Machine, *, z_fts=None, seed: int = 0,
                   fts_theta=None) -> FollowedPath:
    """The path a turning program is cut along on ``machine``.

    Parameters
    ----------
    t, theta, rho, z : (n,) arrays
        The program: times (s, increasing), spindle angle C (rad, cumulative), X (mm) and
        the tool-tip Z (mm, slow slide + FTS).
    machine : Machine
    z_fts : (n,) array, optional
        The fast tool servo's share of ``z`` (mm); the Z slide gets ``z - z_fts``.  None:
        everything on the Z slide.
    seed : int
        Seed of the disturbances and the asynchronous error motions (each axis and error
        source draws from its own stream derived from it).
    fts_theta : (n,) array, optional
        The spindle angle each FTS stroke belongs to (default ``theta``), for
        position synchronisation.

    Returns
    -------
    FollowedPath
        With the program unchanged when ``machine.ideal``.
    """
    t, theta = _check_program(t, theta)
    rho = np.asarray(rho, dtype=np.float64)
    z = np.asarray(z, dtype=np.float64)
    if rho.shape != t.shape or z.shape != t.shape:
        raise InputError(f"theta, rho, z and t must have one length, received {theta.shape}, "
                         f"{rho.shape}, {z.shape}, {t.shape}")
    zf_prog = np.zeros_like(z) if z_fts is None else np.asarray(z_fts, dtype=np.float64)
    if zf_prog.shape != z.shape:
        raise InputError(f"z_fts must have the path's length {z.size}, received {zf_prog.shape}")
    zs_prog = z - zf_prog
    if machine.ideal:
        zero = np.zeros_like(z)
        return FollowedPath(t.copy(), theta.copy(), rho.copy(), z.copy(),
                            {"theta": theta, "rho": rho, "z": z, "z_slow": zs_prog, "z_fts": zf_prog},
                            {"c": zero, "x": zero, "z": zero, "fts": zero}, True, machine)
    ss = np.random.SeedSequence(int(seed))
    s_c, s_x, s_z, s_f, s_e = (int(s.generate_state(1)[0]) for s in ss.spawn(5))
    rate = machine.servo_rate_hz
    tk = servo_ticks(float(t[0]), float(t[-1]), rate)
    kw = {"rate_hz": rate, "interpolation": machine.interpolation, "ticks": tk}
    rc = follow_axis(t, theta, machine.c, seed=s_c, **kw)
    rx = follow_axis(t, rho, machine.x, seed=s_x, **kw)
    rz = follow_axis(t, zs_prog, machine.z, seed=s_z, **kw)
    if z_fts is None:
        zf_cmd = np.zeros_like(tk)
        zf = zf_cmd
    else:
        if machine.fts_sync == "position":
            # the FTS evaluates its stroke table at the measured spindle angle
            th_ref = theta if fts_theta is None else np.asarray(fts_theta, dtype=np.float64)
            th_meas = np.maximum.accumulate(rc.followed)
            # time at which the program meant that angle, then the PVT stroke there
            t_equiv = np.interp(th_meas, th_ref, t)
            cmd = pvt_command(t, zf_prog, t_equiv) if machine.interpolation == "pvt" else \
                linear_command(t, zf_prog, t_equiv)
            rf = follow_axis(t, zf_prog, machine.fts, seed=s_f, command=cmd, **kw)
        else:
            rf = follow_axis(t, zf_prog, machine.fts, seed=s_f, **kw)
        zf_cmd, zf = rf.command, rf.followed
    theta_f = np.maximum.accumulate(rc.followed)
    rho_f = rx.followed
    z_f = rz.followed + zf
    errors = {"c": rc.error, "x": rx.error, "z": rz.error,
              "fts": (zf_cmd - zf) if z_fts is not None else np.zeros_like(tk)}
    commanded = {"theta": rc.command, "rho": rx.command, "z": rz.command + zf_cmd,
                 "z_slow": rz.command, "z_fts": zf_cmd}
    if not machine.coupling.none:
        dz, dy = machine.coupling.deflection(tk, rx.followed)
        z_f = z_f + dz
        theta_f = np.maximum.accumulate(theta_f + dy / np.maximum(np.abs(rho_f), 1e-6))
    if machine.errors is not None and not machine.errors.none:
        theta_f, rho_f, z_f = apply_error_motions(tk, theta_f, rho_f, z_f, machine.errors, seed=s_e)
    return FollowedPath(tk, theta_f, rho_f, z_f, commanded, errors, False, machine)
