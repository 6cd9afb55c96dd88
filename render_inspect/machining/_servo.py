"""Hybrid tool servo turning (seed 002): slow slide servo (S3) + fast tool servo (FTS).

Both servos cut along the same inward spiral as STS.  The compensated Z program of the
whole design, z_cmd(t), is split into

* ``hts``: the slow slide's share ``z_base`` = the compensated program of the design's
  *base* (``design.base`` of a compound design, e.g. the toric form), and the FTS stroke
  ``z_fts = z_cmd - z_base`` (the microstructure, e.g. the lenslet array);
* ``fts``: the slow slide's share = the rotationally symmetric part of the program (its
  mean over the centred spindle revolution, with the curvature bias of that window removed
  as 2 M(z) - M(M(z))), the FTS stroke = the rest.

Each servo follows its command through a second-order low-pass
``H(s) = wn^2 / (s^2 + 2 zeta wn s + wn^2)``, wn = 2 pi ``bandwidth_hz`` (None = ideal),
applied causally on the uniformly sampled time axis (bilinear transform, pre-warped at wn,
started at rest on the first command).  The FTS is also late by ``delay_s``: the stroke
meant for spindle angle theta is made at theta + omega tau, so every feature moves along
the circumference by r omega tau (plus the servo's own low-frequency lag 2 zeta / wn): the
outward-growing spiral dislocation pattern seed 002 measured.  The machined surface is the
envelope of the tool nose along the *followed* path.
"""

from __future__ import annotations

import math

import numpy as np

from ..core.errors import InputError, check_range
from ..core.toolpath import ToolPath
from ..toolpath import z_compensation

__all__ = ["servo_response", "split_commands", "followed_path"]

_MAX_SAMPLES = 50_000_000


def _second_order_sos(bandwidth_hz: float, damping: float, dt: float) -> np.ndarray:
    from scipy import signal

    fs = 1.0 / dt
    wn = 2 * math.pi * bandwidth_hz
    # pre-warp so the digital filter has its natural frequency exactly at wn
    wa = 2 * fs * math.tan(min(wn / (2 * fs), 0.5 * math.pi * 0.999))
    poles = np.roots([1.0, 2 * damping * wa, wa * wa])
    z, p, k = signal.bilinear_zpk([], poles, wa * wa, fs)
    return signal.zpk2sos(z, p, np.real(k))


def servo_response(command, t, *, bandwidth_hz: float | None = None, damping: float = 0.7,
                   delay_s: float = 0.0) -> np.ndarray:
    """Position a servo reaches when it is told ``command`` at times ``t``.

    Parameters
    ----------
    command : (n,) array, mm
        Commanded axis position.
    t : (n,) array, s
        Increasing times.  The command is taken as linear between samples (as the machine
        axes interpolate); it is filtered on a uniform grid of the smallest step, refined
        to at least 20 samples per 1 / ``bandwidth_hz``, and read back at ``t``.
    bandwidth_hz : float or None
        Natural frequency fn of the second-order response (its -3 dB bandwidth for
        damping 0.707); None = ideal (no dynamics).
    damping : float
        zeta, > 0.
    delay_s : float
        Pure time lag tau >= 0 (synchronisation error): the output at t is the response at
        t - tau (held at the first command before the start).

    Returns
    -------
    (n,) float64, mm
    """
    x = np.asarray(command, dtype=np.float64)
    t = np.asarray(t, dtype=np.float64)
    if x.ndim != 1 or x.shape != t.shape or x.size < 2:
        raise InputError(f"command and t must be 1-D arrays of one length >= 2, received "
                         f"{x.shape} and {t.shape}")
    dts = np.diff(t)
    if not np.all(dts > 0):
        raise InputError("t must be strictly increasing (s)")
    check_range("delay_s", delay_s, 0.0, None)
    check_range("damping", damping, 0.0, None, lo_open=True)
    y = x.copy()
    if bandwidth_hz is not None:
        check_range("bandwidth_hz", bandwidth_hz, 0.0, None, lo_open=True)
        from scipy import signal

        dt = float(dts.min())
        uniform = float(dts.max() - dt) <= 1e-9 * dt
        # the axes interpolate linearly between points, so the command is the piecewise
        # linear function of t: filter it on a grid of >= 20 samples per 1 / fn
        dt_f = min(dt, 1.0 / (20.0 * float(bandwidth_hz)))
        if uniform and dt_f == dt:
            tu, xu = t, x
        else:
            n = int(math.ceil((t[-1] - t[0]) / dt_f)) + 1
            if n > _MAX_SAMPLES:
                raise InputError(f"servo_response: filtering needs {n} time samples (> {_MAX_SAMPLES}); "
                                 "shorten the path (simulation.region) or lower bandwidth_hz")
            dt = (t[-1] - t[0]) / (n - 1)
            tu = t[0] + dt * np.arange(n)
            xu = np.interp(tu, t, x)
            uniform = False
        sos = _second_order_sos(float(bandwidth_hz), float(damping), dt)
        zi = signal.sosfilt_zi(sos) * xu[0]
        yu, _ = signal.sosfilt(sos, xu, zi=zi)
        y = yu if uniform else np.interp(t, tu, yu)
    if delay_s > 0:
        y = np.interp(t - delay_s, t, y)
    return y


def _revolution_mean(theta, z):
    """Mean of z over the centred spindle revolution [theta - pi, theta + pi] (the
    rotationally symmetric part of a turning program), by the cumulative integral."""
    c = np.concatenate([[0.0], np.cumsum(0.5 * (z[1:] + z[:-1]) * np.diff(theta))])
    lo = np.clip(theta - math.pi, theta[0], theta[-1])
    hi = np.clip(theta + math.pi, theta[0], theta[-1])
    width = hi - lo
    mean = (np.interp(hi, theta, c) - np.interp(lo, theta, c)) / np.where(width > 0, width, 1.0)
    return np.where(width > 0, mean, z)


def split_commands(path, kind: str, *, base=None, nose_radius: float | None = None,
                   compensation: str = "z", half_width: float | None = None):
    """Split a turning program into the slow slide's and the FTS's commands.

    Parameters
    ----------
    path : ToolPath
        The compensated program of the whole design (tool tip).
    kind : {"hts", "fts"}
        ``hts``: slow slide = the program of ``base``; ``fts``: slow slide = the
        revolution mean of the program.
    base : Surface
        The base surface (``hts`` only).
    nose_radius, half_width : float, mm
        Tool nose radius and arc half-width (``hts`` with compensation).
    compensation : {"none", "normal", "z"}
        How the base program is compensated (``normal`` uses the Z form on the path's radii,
        which keeps the split in Z only).

    Returns
    -------
    z_slow, z_fts : (n,) float64, mm; z_slow + z_fts == path.z.
    """
    z = np.asarray(path.z, dtype=np.float64)
    if kind == "fts":
        th = np.asarray(path.theta, dtype=np.float64)
        m1 = _revolution_mean(th, z)
        # the window mean of a curved radial profile sits (F'' / 2) var(d rho) off it;
        # 2 M(z) - M(M(z)) cancels that term (harmonics in theta are removed by both)
        z_slow = 2 * m1 - _revolution_mean(th, m1)
    elif kind == "hts":
        if base is None:
            raise InputError("split_commands(kind='hts') needs the base surface")
        theta, rho = path.theta, path.rho
        if compensation == "none":
            z_slow = base.height(rho * np.cos(theta), rho * np.sin(theta))
        else:
            check_range("nose_radius", nose_radius, 0.0, None, lo_open=True)
            z_slow = z_compensation(base, theta, rho, nose_radius, half_width=half_width)
    else:
        raise InputError(f"kind must be 'hts' or 'fts', received {kind!r}")
    z_slow = np.asarray(z_slow, dtype=np.float64)
    return z_slow, z - z_slow


def followed_path(path, z_slow, z_fts, *, slow_bandwidth_hz: float | None = None,
                  slow_damping: float = 0.7, fts_bandwidth_hz: float | None = None,
                  fts_damping: float = 0.7, fts_delay_s: float = 0.0):
    """The path the tool really follows: the slow slide's command through its servo
    (``slow_bandwidth_hz``, ``slow_damping``) plus the FTS's through its own
    (``fts_bandwidth_hz``, ``fts_damping``, late by ``fts_delay_s``); see
    :func:`servo_response`.

    Returns
    -------
    ToolPath (theta, rho and t of ``path``; z = followed slow + followed FTS), and the two
    followed commands (z_slow_f, z_fts_f).
    """
    t = np.asarray(path.t, dtype=np.float64)
    zs = servo_response(z_slow, t, bandwidth_hz=slow_bandwidth_hz, damping=slow_damping)
    zf = servo_response(z_fts, t, bandwidth_hz=fts_bandwidth_hz, damping=fts_damping,
                        delay_s=fts_delay_s)
    meta = dict(path.meta)
    meta["servo"] = "followed"
    return ToolPath(path.theta, path.rho, zs + zf, path.t, meta), zs, zf
