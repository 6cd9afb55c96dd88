"""Axis dynamics of a turning machine: the program as the controller sees it, each axis a
servo, the followed path and the following error.

Chain (one axis; C, X, Z and the fast tool servo alike)
-------------------------------------------------------
1. **Interpolator** (:mod:`render_inspect.machining._interpolate`).  The controller
   receives the program's points (t_i, q_i) and evaluates a command q_c(t), v_c(t), a_c(t)
   at every servo tick t_k = t_0 + k / rate:

   * ``"pvt"`` (position-velocity-time, as in the compound sinusoidal grid study): a cubic
     Hermite segment between consecutive points, with the velocity at each point taken as
     the slope of the parabola through it and its two neighbours (the three-point
     derivative on an uneven time axis; one-sided at the ends).  Position and velocity are
     continuous, acceleration is piecewise linear;
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
   ``acceleration_limit`` bounds u: the *drive's* limit, the motor's peak force over the
   moving mass, a_max = F_peak / m (the feed-forward part alone is clipped to it first);
   while it is exceeded the axis accelerates at the limit and the error grows.  It is not
   the acceleration a program was planned with (a setting of one job, e.g. the 0.2 g of
   the compound sinusoidal grid study): that is checked against the program by the
   kinematics (``process.x_acceleration_limit_mm_s2``).  ``velocity_limit`` bounds q'
   (the amplifier's bus voltage against the motor's back-EMF).

   The loop's transfer from command to position is

       T(s) = (ka s^2 + 2 zeta wn kv s + wn^2) / (s^2 + 2 zeta wn s + wn^2),

   whose low-frequency group delay is 2 zeta (1 - kv) / wn (:func:`loop_lag`): with full
   velocity feed-forward the axis does not lag; what is left is an amplitude error
   (1 - ka) (w / wn)^2 (:func:`loop_response`).

3. **Disturbance.**  Broadband force noise (air/oil bearing, amplifier, floor), white at
   the tick rate, scaled so that the following error it causes has the rms
   ``noise_rms`` in steady state (discrete Lyapunov equation of the loop), from the seed.
   A force noise of two-sided spectral density S_F (N^2/Hz) on a mass m gives
   var(e) = S_F / (4 zeta wn^3 m^2) (:func:`force_noise_rms`), so axes of one machine that
   share the noise sources scale as 1 / (m wn^1.5).  It is drawn in time: a servo's noise
   is a temporal process, and a change of feed redraws it along the part.

4. **Latency.**  ``delay_s`` delays the axis output (communication between controllers).

This is the package's one servo model: with kv = ka = 0 it is the plain second-order
low-pass a tool servo is often described by, so the fast tool servo and the slow slide of
a tool-servo process (``[machine.fts]``, ``[machine.z]``) are two such axes.  The presets
are in :mod:`render_inspect.machining._machines`.

An *ideal* axis (``bandwidth_hz = None``, no noise, no delay) is its command.  A machine
whose axes are all ideal and which has no error motions returns the program unchanged,
so ``preset = "ideal"`` gives the geometric (commanded) result exactly.

Units: linear axes in mm, C in rad; velocities and limits per second; ``noise_rms`` in
the axis unit.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field, fields, replace
from typing import Any

import numpy as np
from numpy.typing import ArrayLike
from ..core.lazy import njit  # numba, imported on first use

from ..core.errors import InputError, check_range
from ..core.units import MM_TO_M, NM_TO_MM
from ._errmotion import ErrorMotions
from ._iir import bilinear_sos, sosfilt
from ._interpolate import check_program, linear_command, pvt_checked

__all__ = ["Axis", "Coupling", "Machine", "AxisResponse", "follow_axis", "second_order_sos",
           "servo_ticks", "loop_lag", "loop_response", "force_noise_rms", "settle_time",
           "SETTLE_DECAY"]

_MAX_TICKS = 60_000_000
TWO_PI = 2.0 * math.pi


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
        Bounds on the axis velocity and on the drive's acceleration (its peak force over
        the moving mass; axis unit / s, / s^2); None = unbounded.
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
    speed (a_x = 0) excites nothing; a reciprocating X does (the RCSE study, Optica 2024: "the
    intense reciprocating motion of the X-axis can destabilize ... leading to significant machining
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

    def deflection(self, t: np.ndarray, x_followed: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(dz, dy) in mm at the uniform ticks ``t`` for the followed X position (mm)."""
        t = np.asarray(t, dtype=np.float64)
        x = np.asarray(x_followed, dtype=np.float64)
        if self.none or t.size < 3:
            return np.zeros_like(t), np.zeros_like(t)
        dt = float(t[1] - t[0])
        # (in place, the operations of (x[2:] - 2 x[1:-1] + x[:-2]) / dt^2 * m and of the
        # products below, in their order)
        a = np.empty_like(x)
        a[0] = a[-1] = 0.0
        mid = a[1:-1]
        np.multiply(2, x[1:-1], out=mid)
        np.subtract(x[2:], mid, out=mid)
        mid += x[:-2]
        mid /= dt * dt                                                   # mm/s^2
        a *= self.mass_kg
        a *= MM_TO_M                                                     # N
        sos = second_order_sos(self.mode_hz, self.mode_damping, dt)
        shaped = sosfilt(sos, a, overwrite_x=True)
        dz = shaped * self.z_compliance_nm_per_n
        dz *= NM_TO_MM
        shaped *= self.y_compliance_nm_per_n
        shaped *= NM_TO_MM
        return dz, shaped


def second_order_sos(fn: float, zeta: float, dt: float) -> np.ndarray:
    """Unit-gain second-order low-pass at fn (bilinear transform, pre-warped so the
    digital filter has its natural frequency exactly at fn) as second-order sections
    (SciPy's ``bilinear_zpk`` and ``zpk2sos``, to the last bit: :mod:`._iir`)."""
    fs = 1.0 / dt
    wn = TWO_PI * fn
    wa = 2 * fs * math.tan(min(wn / (2 * fs), 0.5 * math.pi * 0.999))
    return bilinear_sos(np.roots([1.0, 2 * zeta * wa, wa * wa]), wa * wa, fs)


def loop_lag(axis: Axis) -> float:
    """Low-frequency lag of ``axis`` (s): its output delay plus the group delay of its loop
    at zero frequency, 2 zeta (1 - kv) / wn (exact first-order term of the phase of T(s)
    in the module docstring); 0 for an ideal axis."""
    lag = float(axis.delay_s)
    if axis.bandwidth_hz is not None:
        lag += 2 * axis.damping * (1.0 - axis.velocity_ff) / (TWO_PI * axis.bandwidth_hz)
    return lag


def loop_response(axis: Axis, frequency_hz: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    """Amplitude ratio |T| and time lag -arg(T) / w (s, delay included) of ``axis`` at
    ``frequency_hz`` (> 0): what a sinusoidal command of that frequency comes out as."""
    f = np.asarray(frequency_hz, dtype=np.float64)
    w = TWO_PI * f
    if axis.bandwidth_hz is None:
        return np.ones_like(w), np.full_like(w, float(axis.delay_s))
    wn, z = TWO_PI * float(axis.bandwidth_hz), float(axis.damping)
    ka, kv = float(axis.acceleration_ff), float(axis.velocity_ff)
    s = 1j * w
    t = (ka * s * s + 2 * z * wn * kv * s + wn * wn) / (s * s + 2 * z * wn * s + wn * wn)
    with np.errstate(invalid="ignore", divide="ignore"):
        lag = np.where(w > 0, -np.angle(t) / w, 0.0)
    return np.abs(t), lag + float(axis.delay_s)


#: the factor by which a loop's start-up transient has decayed after :func:`settle_time`
#: (2^-60: far below the rounding of any position the loop reaches)
SETTLE_DECAY = 2.0 ** -60


def settle_time(axis: Axis, decay: float = SETTLE_DECAY) -> float:
    """Seconds after which a difference in the state of ``axis``'s loop (a different
    command or start before that time) has decayed by ``decay`` (plus its output delay).

    The loop is linear while the drive is within its limits: the difference between two
    runs obeys e'' + 2 zeta wn e' + wn^2 e = 0, whose slowest mode decays as
    exp(-sigma t), sigma = zeta wn (zeta < 1) or wn (zeta - sqrt(zeta^2 - 1)); the
    discretisation over a tick is exact (its eigenvalues are exp(-sigma dt)).  The
    margin takes ln(1 / decay) + 5 time constants (the 5 cover the transient's
    polynomial and oscillation prefactors).  0 for an ideal axis."""
    t = float(axis.delay_s)
    if axis.bandwidth_hz is None:
        return t
    wn, z = TWO_PI * float(axis.bandwidth_hz), float(axis.damping)
    sigma = z * wn if z < 1 else wn * (z - math.sqrt(z * z - 1.0))
    return t + (math.log(1.0 / decay) + 5.0) / sigma


def force_noise_rms(force_psd_n2_hz: float, mass_kg: float, bandwidth_hz: float,
                    damping: float) -> float:
    """Rms following error (m) of a loop wn, zeta on a mass ``mass_kg`` driven by white force
    noise of two-sided spectral density ``force_psd_n2_hz`` (N^2/Hz):
    sqrt(S_F / (4 zeta wn^3 m^2)), the integral of |H|^2 S_F over all frequencies with
    H = 1 / (m (wn^2 - w^2 + 2 i zeta wn w))."""
    check_range("force_psd_n2_hz", force_psd_n2_hz, 0.0, None)
    check_range("mass_kg", mass_kg, 0.0, None, lo_open=True)
    check_range("bandwidth_hz", bandwidth_hz, 0.0, None, lo_open=True)
    check_range("damping", damping, 0.0, None, lo_open=True)
    wn = TWO_PI * bandwidth_hz
    return math.sqrt(force_psd_n2_hz / (4 * damping * wn ** 3 * mass_kg ** 2))


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


#: Taylor terms of :func:`_expm`'s series (its matrix scaled to a 1-norm of at most 1/2:
#: the first term left out is below 0.5^19 / 19! = 1.6e-23 of one)
_EXPM_TERMS = 18
#: doublings of :func:`_noise_scale`'s sum at most (its terms fall as |pole|^(2^k))
_LYAPUNOV_DOUBLINGS = 64


def _expm(m: np.ndarray) -> np.ndarray:
    """The exponential of a small square matrix by scaling and squaring: ``m`` divided by
    2^s (exactly) to a 1-norm of at most 1/2, the Taylor series of that to 18 terms, squared
    s times (Moler & Van Loan, "Nineteen dubious ways to compute the exponential of a
    matrix, twenty-five years later", SIAM Review 45 (2003), method 3).  On the servo
    loops' balanced matrices (:func:`_discrete_loop`) within a few units in the last place
    of SciPy's ``expm`` (tested); it needs no SciPy, whose linear algebra costs a command
    0.05 s to import."""
    m = np.asarray(m, dtype=np.float64)
    norm = float(np.abs(m).sum(axis=0).max())
    s = max(0, math.ceil(math.log2(norm / 0.5))) if norm > 0.5 else 0
    a = m * 2.0 ** -s
    out = np.eye(m.shape[0])
    term = np.eye(m.shape[0])
    for k in range(1, _EXPM_TERMS + 1):
        term = (term @ a) / k
        out = out + term
    for _ in range(s):
        out = out @ out
    return out


def _discrete_loop(wn: float, zeta: float, dt: float):
    """Exact zero-order-hold discretisation of e'' + 2 zeta wn e' + wn^2 e = F: the state
    transition Phi = exp(A dt) and the input's Gamma = int_0^dt exp(A t) dt B, both from
    the exponential of the augmented matrix M = [[A dt, B dt], [0, 0]].  M is balanced
    first (its error and input rows scaled by a power of 2 near wn and its reciprocal,
    exactly): the exponential of D M D^-1 is D exp(M) D^-1, and its entries are all of
    the order of wn dt, where M's span wn^2 dt to dt."""
    b = 2.0 ** round(math.log2(wn)) if wn > 0 else 1.0
    m = np.zeros((3, 3))
    m[0, 1] = b * dt
    m[1, 0] = -wn * (wn / b) * dt
    m[1, 1] = -2.0 * zeta * wn * dt
    m[1, 2] = b * dt
    em = _expm(m)
    phi = np.array([[em[0, 0], em[0, 1] / b], [em[1, 0] * b, em[1, 1]]])
    gam = np.array([em[0, 2] / (b * b), em[1, 2] / b])
    return phi, gam


@njit(cache=True, nogil=True)
def _track(qc, vc, dist, linear, phi, gam, wn, zeta, ka, kv, amax, vmax, dt, e0, de0, out):
    """Followed position ``qc - e`` at each tick of the loop described in the module
    docstring (e the following error).

    Step k (tick k to k + 1): the command's velocity jumps by ``jump`` at the tick
    (straight moves, ``linear``: the change of the step's mean velocity), then moves with
    mean velocity ``v`` (the step's chord) and mean acceleration ``a`` (the change of the
    command's velocity ``vc`` over the step; none for straight moves); the drive feeds
    forward ``ka`` times the acceleration (the velocity step over the tick for straight
    moves), clipped to its limit.  ``v_start`` / ``v_end`` are the command's velocities
    just after tick k and just before tick k + 1."""
    e = e0
    de = de0
    c1 = 2.0 * zeta * wn
    n = qc.size
    out[0] = qc[0] - e
    v_prev = 0.0
    for k in range(n - 1):
        v = (qc[k + 1] - qc[k]) / dt
        if linear:
            jump = v - v_prev if k > 0 else 0.0
            a = 0.0
            ff = ka * jump / dt
            v_start = v
            v_end = v
        else:
            jump = 0.0
            a = (vc[k + 1] - vc[k]) / dt
            ff = ka * a
            v_start = vc[k]
            v_end = vc[k + 1]
        v_prev = v
        if ff < -amax:
            ff = -amax
        elif ff > amax:
            ff = amax
        de += jump
        u = ff + wn * wn * e + c1 * (kv * v - v + de)
        if abs(u) > amax:
            # saturated: the axis itself moves at the limit (integrated in its own
            # coordinates)
            us = (amax if u > 0 else -amax) + dist[k]
            x = qc[k] - e
            xd = v_start - de
            x = x + xd * dt + 0.5 * us * dt * dt
            xd = xd + us * dt
            e = qc[k + 1] - x
            de = v_end - xd
        else:
            f = a - ff + c1 * (1.0 - kv) * v - dist[k]
            e1 = phi[0, 0] * e + phi[0, 1] * de + gam[0] * f
            de = phi[1, 0] * e + phi[1, 1] * de + gam[1] * f
            e = e1
        w = v_end - de
        if w > vmax:
            de = v_end - vmax
        elif w < -vmax:
            de = v_end + vmax
        out[k + 1] = qc[k + 1] - e


def _noise_scale(phi, gam, target_rms: float) -> float:
    """Standard deviation of white tick-rate force noise giving ``target_rms`` following
    error in steady state: P = Phi P Phi^T + G G^T (the discrete Lyapunov equation), P the
    sum over k of Phi^k G G^T Phi^k^T, summed by doubling (P <- P + A P A^T, A <- A^2:
    Smith's method; 2^k terms after k doublings, each term's error a rounding of a sum of
    positive-definite terms).  Within 2e-14 of SciPy's ``solve_discrete_lyapunov`` on the
    shipped machines' loops (tested).

    Raises
    ------
    InputError
        Where the loop's pole is so close to 1 that the sum does not settle in
        ``_LYAPUNOV_DOUBLINGS`` doublings (a loop decaying over more than about 1e17
        ticks: a bandwidth of practically zero for the servo rate).
    """
    a = np.asarray(phi, dtype=np.float64)
    g = np.asarray(gam, dtype=np.float64)
    p = np.outer(g, g)
    for _ in range(_LYAPUNOV_DOUBLINGS):
        p_next = p + a @ p @ a.T
        a = a @ a
        if np.array_equal(p_next, p):
            break
        p = p_next
    else:
        # det Phi = exp(-2 zeta wn dt): the loop's bandwidth x damping / servo rate
        det = float(np.linalg.det(np.asarray(phi, dtype=np.float64)))
        decay = max(0.0, -math.log(det)) / (4 * math.pi) if det > 0 else math.nan
        raise InputError("machine axis: bandwidth_hz x damping / servo_rate_hz must be above about 1e-18 "
                         f"for an axis with noise_rms > 0 (its loop's pole is 1 to double precision), "
                         f"received {decay:.3g}")
    return target_rms / math.sqrt(max(p[0, 0], 1e-300))


def servo_ticks(t0: float, t1: float, rate_hz: float) -> np.ndarray:
    """Servo tick times t0 + k / rate_hz in [t0, t1]."""
    check_range("servo_rate_hz", rate_hz, 0.0, 1e7, lo_open=True)
    n = int(math.floor((t1 - t0) * rate_hz + 1e-9)) + 1
    if n > _MAX_TICKS:
        raise InputError(f"the program lasts {t1 - t0:.4g} s: {n} servo ticks at {rate_hz:g} Hz "
                         f"(> {_MAX_TICKS}); shorten the path (simulation.region) or lower "
                         "machine.servo_rate_hz")
    tk = np.arange(max(n, 2), dtype=np.float64)
    tk /= rate_hz
    tk += t0
    return tk


def follow_axis(t: np.ndarray, q: np.ndarray, axis: Axis, *, rate_hz: float,
                interpolation: str = "pvt", seed: int = 0, ticks: ArrayLike | None = None,
                command: Sequence[np.ndarray] | None = None,
                runs: np.ndarray | None = None) -> AxisResponse:
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
        A command already evaluated at ``ticks`` (e.g. a position-synchronised one); with
        ``runs``, at the runs' ticks only.
    runs : (k, 2) int array, optional
        Follow only these runs of ticks [start, stop) (each started as the program's
        first tick is, the disturbance the same draw as over all ticks); elsewhere the
        axis is its program, linearly interpolated, with no error.  For the part of a
        program that a window needs, after a lead of :func:`settle_time`.

    Returns
    -------
    AxisResponse at the ticks.
    """
    t, q = check_program(t, q)
    if ticks is None:
        ticks = servo_ticks(float(t[0]), float(t[-1]), rate_hz)
    tk = np.asarray(ticks, dtype=np.float64)
    if interpolation not in ("pvt", "linear"):
        raise InputError(f"interpolation must be 'pvt' or 'linear', received {interpolation!r}")
    mask = None
    if runs is not None:
        mask = np.zeros(tk.size, dtype=bool)
        for a, b in np.asarray(runs, dtype=np.int64).reshape(-1, 2):
            mask[a:b] = True
    tr = tk if mask is None else tk[mask]
    if command is None:
        command = (pvt_checked if interpolation == "pvt" else linear_command)(t, q, tr)
    qc, vc, ac = (np.ascontiguousarray(a, dtype=np.float64) for a in command)
    if axis.bandwidth_hz is None:
        followed = qc.copy()
    else:
        phi, gam = _discrete_loop(TWO_PI * float(axis.bandwidth_hz), float(axis.damping),
                                  1.0 / float(rate_hz))
        if axis.noise_rms > 0:
            sd = _noise_scale(phi, gam, float(axis.noise_rms))
            dist = np.random.default_rng(seed).normal(0.0, sd, size=tk.size)
        else:
            dist = np.zeros(tk.size)
        followed = np.empty_like(qc)
        if mask is None:
            _run_followed(qc, vc, tk, dist, axis, phi, gam, rate_hz, interpolation, followed)
        else:
            dist = dist[mask]
            # the runs in the compressed arrays: where the tick index jumps
            cut = np.flatnonzero(np.diff(np.flatnonzero(mask)) > 1) + 1
            for a, b in zip(np.concatenate([[0], cut]), np.concatenate([cut, [qc.size]])):
                sl = slice(int(a), int(b))
                _run_followed(qc[sl], vc[sl], tr[sl], dist[sl], axis, phi, gam, rate_hz,
                              interpolation, followed[sl])
    if mask is not None:  # back onto every tick: the program itself outside the runs
        q_all = np.interp(tk, t, q)
        v_all, a_all = np.zeros(tk.size), np.zeros(tk.size)
        for full, a in ((q_all, qc), (v_all, vc), (a_all, ac)):
            full[mask] = a
        f_all = q_all.copy()
        f_all[mask] = followed
        qc, vc, ac, followed = q_all, v_all, a_all, f_all
    if axis.delay_s > 0:
        followed = np.interp(tk - axis.delay_s, tk, followed)
    return AxisResponse(tk, qc, followed, vc, ac)


def _run_followed(qc, vc, tk, dist, axis: Axis, phi, gam, rate_hz: float,
                  interpolation: str, out: np.ndarray) -> None:
    """Followed position (``qc`` less the following error) at the ticks ``tk`` of one run
    of the loop into ``out``, started in the steady state of the mean velocity over its
    first 1 / fn."""
    if qc.size < 2:
        np.subtract(qc, np.zeros(qc.size), out=out)
        return
    assert axis.bandwidth_hz is not None  # an ideal axis has no loop to run
    dt = 1.0 / float(rate_hz)
    wn = TWO_PI * float(axis.bandwidth_hz)
    zeta = float(axis.damping)
    ka, kv = float(axis.acceleration_ff), float(axis.velocity_ff)
    # start in the steady state of the mean velocity over the first 1 / fn (a ramp's
    # lag), so the statistics hold no start-up transient
    n0 = max(1, min(qc.size - 1, int(rate_hz / float(axis.bandwidth_hz))))
    v0 = (qc[n0] - qc[0]) / (tk[n0] - tk[0]) if qc.size > 1 else 0.0
    f0 = 2 * zeta * wn * (1.0 - kv) * v0
    amax = 1e300 if axis.acceleration_limit is None else float(axis.acceleration_limit)
    vmax = 1e300 if axis.velocity_limit is None else float(axis.velocity_limit)
    _track(np.ascontiguousarray(qc), np.ascontiguousarray(vc), np.ascontiguousarray(dist),
           interpolation == "linear", phi, gam, wn, zeta, ka, kv, amax, vmax, dt,
           float(f0 / (wn * wn)), 0.0, out)
