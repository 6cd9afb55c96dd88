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
import time

import numpy as np

from ..errors import InputError, SceneError, check_range
from ._heightmap import HeightMap
from ._result import SimulationResult

__all__ = ["servo_response", "split_commands", "followed_path", "simulate_hts",
           "hts_lenslet_metrics"]

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
            from ..toolpath import z_compensation

            check_range("nose_radius", nose_radius, 0.0, None, lo_open=True)
            z_slow = z_compensation(base, theta, rho, nose_radius, half_width=half_width)
    else:
        raise InputError(f"kind must be 'hts' or 'fts', received {kind!r}")
    z_slow = np.asarray(z_slow, dtype=np.float64)
    return z_slow, z - z_slow


def followed_path(path, z_slow, z_fts, servo_cfg):
    """The path the tool really follows: each command through its servo
    (``[artifacts.servo]``: ``slow_bandwidth_hz, slow_damping`` for the slow slide,
    ``bandwidth_hz, damping, delay_s`` for the FTS).

    Returns
    -------
    ToolPath (theta, rho and t of ``path``; z = followed slow + followed FTS), and the two
    followed commands (z_slow_f, z_fts_f).
    """
    from ..toolpath import ToolPath

    t = np.asarray(path.t, dtype=np.float64)
    zs = servo_response(z_slow, t, bandwidth_hz=servo_cfg.slow_bandwidth_hz,
                        damping=servo_cfg.slow_damping)
    zf = servo_response(z_fts, t, bandwidth_hz=servo_cfg.bandwidth_hz,
                        damping=servo_cfg.damping, delay_s=servo_cfg.delay_s)
    meta = dict(path.meta)
    meta["servo"] = "followed"
    return ToolPath(path.theta, path.rho, zs + zf, path.t, meta), zs, zf


def hts_lenslet_metrics(machined, base_grid, feature, *, pixel: float, origin) -> list[dict]:
    """``lenslets`` metrics of a lenslet array on a base: the machined map minus the base,
    matched lenslet by lenslet to the feature (metrology's ``lenslet_table``)."""
    import warnings

    from ..metrology._msa import lenslet_table

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # lenslets cut by the region's border are left out
        return lenslet_table((machined - base_grid, pixel, tuple(origin)), feature,
                             aperture_radius=getattr(feature, "aperture_radius", None))


def _error_stats(err) -> dict:
    err = np.asarray(err)
    return {"rms_um": float(np.sqrt(np.mean(err * err)) * 1e3), "max_um": float(np.max(np.abs(err)) * 1e3)}


def simulate_hts(scene) -> SimulationResult:
    """Simulate hybrid (``process.kind = "hts"``) or fast (``"fts"``) tool servo turning.

    Scene keys used: everything STS uses (``design``, ``tool``, ``process``,
    ``simulation``), plus ``[artifacts.servo] delay_s, bandwidth_hz, damping,
    slow_bandwidth_hz, slow_damping``.  ``hts`` needs ``design.type = "compound"`` (base on
    the slow slide, feature on the FTS).

    Returns
    -------
    SimulationResult
        ``toolpath``: the commanded program (extra attributes ``z_slow``, ``z_fts``,
        ``z_followed``); ``metrics``: ``residual``, ``toolpath``, ``servo`` (settings, the
        lag angle omega tau, strokes and following errors) and, when the feature is a
        lenslet array, ``lenslets`` (dislocations and form errors).
    """
    from ..design import make_surface
    from ..toolpath import Tool, build_toolpath
    from ._metrics import residual_metrics
    from ._sts import check_memory, design_grid, toolpath_metrics, turned_grid

    kind = scene.process.kind
    if kind not in ("hts", "fts"):
        raise SceneError(f"simulate_hts handles process.kind 'hts' or 'fts', received {kind!r}")
    if kind == "hts" and scene.design.type != "compound":
        raise SceneError("process.kind = 'hts' needs design.type = 'compound' ([design.base] on the "
                         "slow slide, [design.feature] on the fast tool servo), received "
                         f"design.type = {scene.design.type!r}; use process.kind = 'fts' for a "
                         "single surface")
    timing = {}
    check_memory(scene)
    surface = make_surface(scene.design)
    sim = scene.simulation
    tool = Tool.from_config(scene.tool)
    servo = scene.artifacts.servo

    t0 = time.perf_counter()
    path = build_toolpath(scene, surface, region=sim.region)
    base = surface.base if kind == "hts" else None
    z_slow, z_fts = split_commands(path, kind, base=base, nose_radius=tool.nose_radius,
                                   compensation=scene.process.compensation,
                                   half_width=tool.half_width)
    timing["toolpath"] = time.perf_counter() - t0
    check_memory(scene, path.points)

    t0 = time.perf_counter()
    fpath, zs_f, zf_f = followed_path(path, z_slow, z_fts, servo)
    timing["servo"] = time.perf_counter() - t0

    machined, design = turned_grid(scene, surface, fpath, timing)

    from ._burrs import apply_burrs

    origin = (sim.region[0], sim.region[1])
    machined, burr_info = apply_burrs(machined, design, pixel=sim.pixel, origin=origin,
                                      cfg=scene.artifacts.burrs, seed=sim.seed)
    timing["simulate"] = timing["servo"] + timing["envelope"] + timing["design"]

    omega = 2 * math.pi * scene.process.spindle_rpm / 60.0
    lag = servo.delay_s + (2 * servo.damping / (2 * math.pi * servo.bandwidth_hz)
                           if servo.bandwidth_hz else 0.0)
    r_max = float(np.max(path.rho)) if path.points else 0.0
    servo_m = {"kind": kind, "delay_s": servo.delay_s, "bandwidth_hz": servo.bandwidth_hz,
               "damping": servo.damping, "slow_bandwidth_hz": servo.slow_bandwidth_hz,
               "slow_damping": servo.slow_damping, "omega_rad_s": omega,
               "lag_angle_rad": omega * servo.delay_s,
               "effective_lag_s": lag, "effective_lag_angle_rad": omega * lag,
               "max_circumferential_shift_um": r_max * omega * lag * 1e3,
               "fts_stroke_um": float(np.ptp(z_fts) * 1e3) if z_fts.size else 0.0,
               "slow_stroke_um": float(np.ptp(z_slow) * 1e3) if z_slow.size else 0.0,
               "fts_following_error": _error_stats(zf_f - z_fts),
               "slow_following_error": _error_stats(zs_f - z_slow)}
    meta = {"process": kind, "compensation": scene.process.compensation, "seed": sim.seed,
            "servo": {k: servo_m[k] for k in ("delay_s", "bandwidth_hz", "damping",
                                               "slow_bandwidth_hz", "slow_damping")}}
    hm = HeightMap(design, machined, sim.pixel, origin, scene.to_dict(), meta)
    metrics = {"residual": residual_metrics(hm), "toolpath": toolpath_metrics(path),
               "servo": servo_m, "burrs": burr_info}
    feature = getattr(surface, "feature", surface)
    if hasattr(feature, "centers") and getattr(feature, "kind", "") == "lenslet_array":
        t0 = time.perf_counter()
        base_grid = design_grid(surface.base, sim.region, sim.pixel) if hasattr(surface, "base") \
            else np.zeros_like(design)
        metrics["lenslets"] = hts_lenslet_metrics(machined, base_grid, feature, pixel=sim.pixel,
                                                  origin=origin)
        timing["lenslets"] = time.perf_counter() - t0
    path.z_slow, path.z_fts, path.z_followed = z_slow, z_fts, fpath.z
    return SimulationResult(hm, path, metrics, timing)
