"""The drive's limit against a program's planned acceleration, the loop's lag and amplitude
under feed-forward, the force-noise scaling between axes, and the FTS's timing against the
spindle: each against a forward model with a known answer."""

from __future__ import annotations

import math

import numpy as np
import pytest
from numpy.testing import assert_allclose

from render_inspect.core.units import STANDARD_GRAVITY_MM_S2
from render_inspect.machining import (Axis, follow_axis, follow_turning, force_noise_rms,
                                      loop_lag, loop_response, machine_preset)
from render_inspect.machining._axes import _discrete_loop, _noise_scale
from render_inspect.processes import machine_of
from render_inspect.processes._servo import servo_lags
from render_inspect.scene import load_scene

G = STANDARD_GRAVITY_MM_S2


def _spiral(n_rev=10, P=1440, rpm=42.0, r0=3.7, f=0.005):
    k = np.arange(n_rev * P + 1)
    th = 2 * np.pi * k / P
    return th / (2 * np.pi * rpm / 60), th, r0 - f * k / P


def test_the_drive_limit_is_the_motor_force_over_the_moving_mass():
    m = machine_preset("sts_lathe")
    assert m.x.acceleration_limit == pytest.approx(1500.0 / 150.0 * 1e3)     # 1.02 g
    assert m.z.acceleration_limit == pytest.approx(1500.0 / 75.0 * 1e3)      # 2.04 g
    assert m.x.acceleration_limit > 0.9 * G and m.z.acceleration_limit > 1.9 * G
    assert "peak motor force" in m.sources["acceleration_limit"]
    # the compound sinusoidal grid study's 0.2 g is that job's programmed acceleration: a
    # kinematics limit of the scene, not the drive's
    s = load_scene("compound_sinusoid")
    assert s.process.x_acceleration_limit_mm_s2 == pytest.approx(0.2 * G, rel=1e-5)
    assert machine_of(s.machine).x.acceleration_limit > 0.9 * G


def test_row_snapped_x_does_not_saturate_the_drive():
    """The RCSE study's conventional path: CCPs snapped to 5 um rows make X jump by up to
    2.5 um every few milliseconds.  The drive (1 g) follows it as the linear loop does; a
    0.2 g limit (the planned acceleration used as a drive limit) saturated and let X
    wander microns further."""
    t, th, rho = _spiral()
    y = rho * np.sin(th)
    rho_conv = np.hypot(rho * np.cos(th), np.rint(y / 0.005) * 0.005)
    quiet = {"x.noise_rms": 0.0, "errors": None, "coupling": {"mass_kg": 0.0}}
    kw = {"seed": 1}
    z = np.zeros_like(rho)
    drive = follow_turning(t, th, rho_conv, z, machine_preset("sts_lathe", quiet), **kw)
    linear = follow_turning(t, th, rho_conv, z, machine_preset(
        "sts_lathe", {**quiet, "x.acceleration_limit": None, "x.velocity_limit": None}), **kw)
    planned = follow_turning(t, th, rho_conv, z, machine_preset(
        "sts_lathe", {**quiet, "x.acceleration_limit": 0.2 * G}), **kw)
    e_drive = drive.following_error()["x_max_nm"]
    assert e_drive == pytest.approx(linear.following_error()["x_max_nm"], rel=1e-9)
    assert planned.following_error()["x_max_nm"] > 1.5 * e_drive


@pytest.mark.parametrize("kv, ka", [(0.0, 0.0), (0.6, 0.3), (0.95, 0.5), (1.0, 0.9)])
def test_loop_lag_and_response_against_the_simulated_loop(kv, ka):
    """A ramp lags by 2 zeta (1 - kv) / wn (loop_lag); a sinusoid comes out with the
    amplitude |T| and the time lag -arg T / w of the loop with feed-forward
    (loop_response), as the time-stepped loop shows."""
    ax = Axis(bandwidth_hz=100.0, damping=0.7, velocity_ff=kv, acceleration_ff=ka, delay_s=2e-4)
    rate = 50_000.0
    t = np.linspace(0.0, 0.5, 501)
    v = 3.0
    r = follow_axis(t, v * t, ax, rate_hz=rate)
    tail = r.t > 0.3
    # the output is the loop's followed position delayed by delay_s
    lag = (r.command[tail] - r.followed[tail]) / v
    assert_allclose(lag, loop_lag(ax), rtol=1e-3, atol=1e-9)
    f = 37.0
    t = np.arange(0.0, 0.6, 1 / rate)
    q = 1e-3 * np.sin(2 * np.pi * f * t)
    r = follow_axis(t, q, ax, rate_hz=rate)
    amp, lag = loop_response(ax, f)
    tail = r.t > 0.3
    want = 1e-3 * amp * np.sin(2 * np.pi * f * (r.t - lag))
    assert_allclose(r.followed[tail], want[tail], atol=2e-3 * 1e-3)


def test_fts_lag_under_feed_forward_is_zero_not_2_zeta_over_wn():
    """The fts preset's FTS (2 kHz, zeta 0.6, kv 1, ka 0.9): no lag at low frequency
    (2 zeta / wn = 95 us was reported before); the slow slide (100 Hz, zeta 0.7, kv 0.95):
    111 us; the relative lag is the FTS's timing against the spindle minus the slide's."""
    m = machine_preset("fts")
    lags = servo_lags(m, omega=10.0, r_max=5.0)
    assert lags["effective_lag_s"] == 0.0
    assert lags["slow_lag_s"] == pytest.approx(2 * 0.7 * 0.05 / (2 * math.pi * 100.0))
    assert lags["relative_lag_s"] == pytest.approx(-lags["slow_lag_s"])
    m2 = machine_preset("fts", {"fts_sync_delay_s": 1.3e-3})
    lags2 = servo_lags(m2, omega=10.0, r_max=5.0)
    assert lags2["effective_lag_s"] == pytest.approx(1.3e-3)
    assert lags2["max_circumferential_shift_um"] == pytest.approx(5.0 * 10.0 * 1.3e-3 * 1e3)
    # no feed-forward: the plain second-order lag
    m3 = machine_preset("fts", {"fts": {"velocity_ff": 0.0}})
    assert servo_lags(m3, omega=1.0, r_max=1.0)["effective_lag_s"] == pytest.approx(
        2 * 0.6 / (2 * math.pi * 2000.0))


def test_force_noise_rms_is_the_continuous_limit_of_the_discrete_loop():
    """White force noise of spectral density S_F on a mass m under a loop wn, zeta:
    var = S_F / (4 zeta wn^3 m^2); the loop's discrete noise (a constant force over each
    tick) of variance sd^2 is S_F = m^2 sd^2 dt."""
    fn, zeta, dt, m = 40.0, 0.7, 1 / 50_000.0, 150.0
    phi, gam = _discrete_loop(2 * math.pi * fn, zeta, dt)
    target = 3e-9                       # m
    sd = _noise_scale(phi, gam, target)  # m/s^2 per tick
    psd = (m * sd) ** 2 * dt
    assert force_noise_rms(psd, m, fn, zeta) == pytest.approx(target, rel=2e-3)
    # one spectrum on two slides: rms scales as 1 / (m wn^1.5)
    x, z = machine_preset("sts_lathe").x, machine_preset("sts_lathe").z
    ratio = (150.0 / 75.0) * (x.bandwidth_hz / z.bandwidth_hz) ** 1.5
    assert z.noise_rms / x.noise_rms == pytest.approx(ratio)


def test_fts_sync_delay_shifts_the_stroke_against_the_spindle():
    """A stroke late by tau is the stroke the program meant for the spindle angle of tau
    earlier: z_fts(theta - omega tau); early (tau < 0) the other way."""
    rpm = 100.0
    k = np.arange(3 * 3600 + 1)
    th = 2 * np.pi * k / 3600
    t = th / (2 * np.pi * rpm / 60)
    rho = 2.0 - 0.01 * k / 3600
    z_fts = 2e-3 * np.sin(12 * th)
    omega = 2 * np.pi * rpm / 60
    quiet = {"c": {"bandwidth_hz": None, "noise_rms": 0.0}, "x": {"noise_rms": 0.0},
             "z": {"noise_rms": 0.0}, "fts": {"bandwidth_hz": None, "noise_rms": 0.0},
             "errors": None, "coupling": {"mass_kg": 0.0}}
    for sync in ("position", "time"):
        for tau in (1.3e-3, -0.8e-3):
            m = machine_preset("fts", {**quiet, "fts_sync": sync, "fts_sync_delay_s": tau})
            fp = follow_turning(t, th, rho, z_fts, m, z_fts=z_fts)
            keep = (fp.t > 0.05) & (fp.t < fp.t[-1] - 0.05)
            want = 2e-3 * np.sin(12 * (fp.theta[keep] - omega * tau))
            assert_allclose(fp.commanded["z_fts"][keep], want, atol=2e-3 * 12 * 3e-4)
