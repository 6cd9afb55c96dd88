"""Axis dynamics: PVT interpolation, the servo loop with feed-forward and limits, machine
presets, position vs time synchronisation, reaction-force coupling."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose

from render_inspect.errors import InputError
from render_inspect.machining import (Axis, Coupling, Machine, follow_axis, follow_turning,
                                      linear_command, machine_preset, pvt_command)
from render_inspect.machining._interpolate import pvt_velocities


# ---- interpolators ----------------------------------------------------------------------
def test_pvt_is_exact_for_a_quadratic_on_uneven_steps():
    rng = np.random.default_rng(0)
    t = np.cumsum(rng.uniform(0.5e-3, 2e-3, 200))
    q = 0.3 + 2.0 * t - 7.0 * t * t
    tk = np.linspace(t[0], t[-1], 5000)
    pos, vel, acc = pvt_command(t, q, tk)
    # the three-point velocities are exact for a parabola, so is the cubic Hermite
    # inside; only the one-sided end velocities are not: compare away from the ends
    inner = (tk > t[1]) & (tk < t[-2])
    assert_allclose(pos[inner], (0.3 + 2.0 * tk - 7.0 * tk * tk)[inner], atol=1e-13)
    assert_allclose(vel[inner], (2.0 - 14.0 * tk)[inner], atol=1e-10)
    assert_allclose(acc[inner], -14.0, atol=1e-6)
    assert_allclose(pvt_velocities(t, q)[1:-1], (2.0 - 14.0 * t)[1:-1], atol=1e-10)


def test_pvt_passes_through_the_points_and_linear_moves_are_straight():
    t = np.array([0.0, 1.0, 2.5, 3.0])
    q = np.array([0.0, 1.0, -1.0, 2.0])
    assert_allclose(pvt_command(t, q, t)[0], q, atol=1e-14)
    pos, vel, _ = linear_command(t, q, np.array([0.5, 1.75, 2.75]))
    assert_allclose(pos, [0.5, 0.0, 0.5], atol=1e-14)
    assert_allclose(vel, [1.0, -4 / 3, 6.0], atol=1e-14)
    # on a program point: the mean of the slopes either side
    assert_allclose(linear_command(t, q, np.array([1.0]))[1], [0.5 * (1.0 - 4 / 3)], atol=1e-14)


def test_program_times_must_increase():
    with pytest.raises(InputError, match="increase strictly"):
        pvt_command([0.0, 1.0, 1.0], [0.0, 1.0, 2.0], [0.5])


# ---- the servo loop ---------------------------------------------------------------------
def _sine(f_hz, rate=20000.0, dur=0.4):
    t = np.arange(0, dur, 1 / rate)
    return t, np.sin(2 * np.pi * f_hz * t) * 1e-3


def test_ideal_axis_is_its_command():
    t, q = _sine(50.0)
    r = follow_axis(t, q, Axis(), rate_hz=20000.0)
    assert_allclose(r.followed, r.command, atol=0)


@pytest.mark.parametrize("zeta", [0.3, 0.7])
def test_no_feed_forward_is_the_second_order_low_pass(zeta):
    fn, f = 200.0, 120.0
    t, q = _sine(f)
    r = follow_axis(t, q, Axis(bandwidth_hz=fn, damping=zeta), rate_hz=20000.0)
    w, wn = 2 * np.pi * f, 2 * np.pi * fn
    H = wn ** 2 / (wn ** 2 - w ** 2 + 2j * zeta * wn * w)
    tail = r.t > 0.25
    expected = 1e-3 * np.abs(H) * np.sin(w * r.t + np.angle(H))
    # exact integration with the tick-mean inputs: within 0.1 % of the stroke at 20 kHz
    assert_allclose(r.followed[tail], expected[tail], atol=1e-6)


def test_ramp_lag_is_2_zeta_v_over_wn_times_one_minus_kv():
    v, fn, zeta = 0.02, 40.0, 0.7
    t = np.linspace(0, 2.0, 2001)
    for kv in (0.0, 0.5):
        r = follow_axis(t, 5.0 - v * t, Axis(bandwidth_hz=fn, damping=zeta, velocity_ff=kv),
                        rate_hz=5000.0)
        lag = 2 * zeta * (1 - kv) * (-v) / (2 * np.pi * fn)
        assert_allclose(r.error[r.t > 0.2], lag, rtol=1e-6, atol=1e-12)


def test_full_feed_forward_follows_exactly_without_disturbance():
    t, q = _sine(300.0)
    r = follow_axis(t, q, Axis(bandwidth_hz=50.0, velocity_ff=1.0, acceleration_ff=1.0),
                    rate_hz=20000.0)
    assert np.max(np.abs(r.error)) < 1e-15


def test_disturbance_gives_the_requested_following_error_rms_and_is_seeded():
    t = np.linspace(0, 20.0, 11)
    q = np.full_like(t, 1.0)
    ax = Axis(bandwidth_hz=50.0, velocity_ff=1.0, acceleration_ff=1.0, noise_rms=5e-6)
    a = follow_axis(t, q, ax, rate_hz=5000.0, seed=3)
    b = follow_axis(t, q, ax, rate_hz=5000.0, seed=3)
    c = follow_axis(t, q, ax, rate_hz=5000.0, seed=4)
    assert_allclose(np.sqrt(np.mean(a.error ** 2)), 5e-6, rtol=0.1)
    assert_allclose(a.followed, b.followed, atol=0)
    assert not np.allclose(a.followed, c.followed)


def test_acceleration_and_velocity_limits_hold():
    # a 1 mm step programmed in 1 ms: far beyond what the axis may do
    t = np.array([0.0, 0.1, 0.101, 1.0])
    q = np.array([0.0, 0.0, 1.0, 1.0])
    amax, vmax = 2000.0, 20.0
    r = follow_axis(t, q, Axis(bandwidth_hz=40.0, velocity_ff=1.0, acceleration_ff=1.0,
                               acceleration_limit=amax, velocity_limit=vmax),
                    rate_hz=10000.0, interpolation="linear")
    dt = 1e-4
    v = np.diff(r.followed) / dt
    a = np.diff(v) / dt
    # the clamp acts on the velocity at the ticks; the mean over a tick may exceed it by
    # the acceleration within the tick (amax dt / vmax = 1 %)
    assert np.max(np.abs(v)) <= vmax * 1.011
    assert np.percentile(np.abs(a), 99) <= amax * 1.01
    # it travels at the limit most of the way and still arrives
    assert np.count_nonzero(np.abs(v) > 0.99 * vmax) * dt > 0.035  # 1 mm / 20 mm/s - ramps
    assert abs(r.followed[-1] - 1.0) < 1e-6


def test_bad_axis_settings_are_named():
    with pytest.raises(InputError, match="damping"):
        Axis(bandwidth_hz=10.0, damping=0.0)
    with pytest.raises(InputError, match="velocity_ff"):
        Axis(velocity_ff=1.5)
    with pytest.raises(InputError, match="noise_rms needs a finite bandwidth_hz"):
        Axis(noise_rms=1e-6)


# ---- machines ---------------------------------------------------------------------------
def _spiral(n_rev=6, P=720, rpm=60.0, r0=2.0, f=0.005):
    k = np.arange(n_rev * P + 1)
    th = k * 2 * np.pi / P
    return th / (2 * np.pi * rpm / 60.0), th, r0 - f * k / P


def test_ideal_machine_returns_the_program_unchanged():
    t, th, rho = _spiral()
    z = 1e-3 * np.sin(7 * th)
    fp = follow_turning(t, th, rho, z, machine_preset("ideal"))
    assert fp.ideal
    for a, b in ((fp.t, t), (fp.theta, th), (fp.rho, rho), (fp.z, z)):
        assert_allclose(a, b, atol=0)
    assert fp.following_error()["x_max_nm"] == 0.0


def test_presets_and_overrides():
    m = machine_preset("sts_lathe", {"x.bandwidth_hz": 80.0, "z": {"damping": 0.5},
                                     "coupling": {"mass_kg": 0.0}})
    assert m.x.bandwidth_hz == 80.0 and m.z.damping == 0.5 and m.coupling.none
    assert m.z.bandwidth_hz == machine_preset("sts_lathe").z.bandwidth_hz
    assert not m.ideal and machine_preset("ideal").ideal
    assert "acceleration_limit" in machine_preset("sts_lathe").sources
    with pytest.raises(InputError, match="machine.preset must be one of"):
        machine_preset("lathe9000")
    with pytest.raises(InputError, match=r"unknown machine.x setting\(s\) \['bandwith_hz'\]"):
        machine_preset("sts_lathe", {"x.bandwith_hz": 3})
    with pytest.raises(InputError, match="unknown machine setting 'spindle'"):
        machine_preset("sts_lathe", {"spindle": 1})


def test_reciprocating_x_has_ten_times_the_following_error_of_a_smooth_spiral():
    """Seed 004's mechanism on bare arrays: snapping the spiral to a 5 um row grid makes X
    reciprocate; the STS lathe preset follows the smooth spiral within its noise floor."""
    t, th, rho = _spiral(n_rev=10, P=1440, rpm=42.0, r0=3.7)
    y = rho * np.sin(th)
    rho_conv = np.hypot(rho * np.cos(th), np.rint(y / 0.005) * 0.005)
    z = np.zeros_like(rho)
    m = machine_preset("sts_lathe")
    smooth = follow_turning(t, th, rho, z, m, seed=1).following_error()
    recip = follow_turning(t, th, rho_conv, z, m, seed=1).following_error()
    assert recip["x_max_nm"] >= 10 * smooth["x_max_nm"]
    assert smooth["x_max_nm"] < 40.0


def test_position_synchronised_fts_follows_the_spindle_time_synchronised_does_not():
    """A spindle with a constant lag (no velocity feed-forward): the position-synchronised
    stroke belongs to the angle the spindle is really at, the time-synchronised one lags."""
    t, th, rho = _spiral(n_rev=3, P=3600, rpm=100.0)
    z_fts = 2e-3 * np.sin(12 * th)
    base = {"c": {"bandwidth_hz": 50.0, "velocity_ff": 0.0, "acceleration_ff": 0.0,
                  "noise_rms": 0.0},
            "x": {"noise_rms": 0.0}, "z": {"noise_rms": 0.0},
            "fts": {"bandwidth_hz": None, "noise_rms": 0.0}, "errors": {"radial_sync": (),
            "axial_sync": (), "radial_async_rms": 0.0, "axial_async_rms": 0.0,
            "x_straightness_rms": 0.0}, "coupling": {"mass_kg": 0.0}}
    omega = 2 * np.pi * 100 / 60
    lag = 2 * 0.7 * omega / (2 * np.pi * 50.0)  # rad, the C axis's ramp lag
    for sync, expect_shift in (("position", 0.0), ("time", lag)):
        m = machine_preset("fts", {**base, "fts_sync": sync})
        fp = follow_turning(t, th, rho, z_fts, m, z_fts=z_fts)
        keep = fp.t > 0.2
        # the stroke made at the real spindle angle, against the design at that angle
        want = 2e-3 * np.sin(12 * (fp.theta[keep] + expect_shift))
        assert_allclose(fp.commanded["z_fts"][keep], want, atol=2e-3 * 12 * 2e-4)


def test_reaction_coupling_is_silent_for_constant_x_speed_and_scales_with_force():
    c = Coupling(mass_kg=100.0, z_compliance_nm_per_n=0.5, y_compliance_nm_per_n=0.0,
                 mode_hz=1000.0, mode_damping=0.7)
    t = np.arange(0, 0.5, 1e-4)
    dz, _ = c.deflection(t, 3.0 - 0.01 * t)
    assert np.max(np.abs(dz)) < 1e-15
    f = 20.0  # well below the mode: static gain
    x = 1e-3 * np.sin(2 * np.pi * f * t)
    dz, _ = c.deflection(t, x)
    a_amp = 1e-3 * (2 * np.pi * f) ** 2                      # mm/s^2
    expected = 100.0 * a_amp * 1e-3 * 0.5 * 1e-6            # N * nm/N -> mm
    assert_allclose(np.max(np.abs(dz[t > 0.2])), expected, rtol=0.02)


def test_machine_validation():
    with pytest.raises(InputError, match="interpolation"):
        Machine(interpolation="spline")
    with pytest.raises(InputError, match="fts_sync"):
        Machine(fts_sync="clock")
