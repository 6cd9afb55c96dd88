"""Axis kinematics: derivatives on non-uniform time axes, maxima, limit warnings, plots."""

from __future__ import annotations

import math

import numpy as np
import pytest
from numpy.testing import assert_allclose

from render_inspect.errors import InputError
from render_inspect.processes import StsProcessConfig as ProcessConfig
from render_inspect.report import plot_kinematics
from render_inspect.toolpath import (
    ToolPath,
    axis_derivatives,
    kinematics,
    limits_from_process,
)


def _nonuniform_t(n=400, seed=3):
    rng = np.random.default_rng(seed)
    return np.cumsum(rng.uniform(0.5e-3, 1.5e-3, n))


def test_derivatives_exact_for_quadratics_on_nonuniform_time():
    t = _nonuniform_t()
    q = 3.0 - 2.0 * t + 5.0 * t * t
    v, a, j = axis_derivatives(t, q)
    assert_allclose(v, -2.0 + 10.0 * t, atol=1e-9)
    assert_allclose(a, 10.0, rtol=1e-6)
    assert np.max(np.abs(j)) < 1e-3 * 10.0 / (t[-1] - t[0])


def test_derivatives_of_a_cubic_converge():
    # smoothly graded steps (as constant-arc sampling gives): errors O(h) -> small
    u = np.linspace(0.0, 1.0, 2001)
    t = u + 0.5 * u * u
    q = 0.7 * t ** 3
    v, a, j = axis_derivatives(t, q)
    assert_allclose(v[1:-1], 2.1 * t[1:-1] ** 2, atol=2e-6)
    assert_allclose(a[1:-1], 4.2 * t[1:-1], atol=2e-3)
    assert_allclose(j[2:-2], 4.2, rtol=2e-3)


def _sine_path(n=20000, amp=0.001, freq=3.0, vx=-0.004):
    t = np.linspace(0.0, 2.0, n)
    rho = 4.0 + vx * t
    z = amp * np.sin(2 * math.pi * freq * t)
    theta = 2 * math.pi * 0.7 * t
    return ToolPath(theta, rho, z, t, {})


def test_kinematics_recovers_known_maxima():
    amp, freq, vx = 0.001, 3.0, -0.004
    k = kinematics(_sine_path(amp=amp, freq=freq, vx=vx))
    w = 2 * math.pi * freq
    assert k["x_velocity_max_mm_s"] == pytest.approx(abs(vx), rel=1e-6)
    assert k["x_acceleration_max_mm_s2"] < 1e-5  # rounding of rho ~ 4 mm over dt = 1e-4 s
    assert k["x_reversals"] == 0
    assert k["z_velocity_max_mm_s"] == pytest.approx(amp * w, rel=1e-4)
    assert k["z_acceleration_max_mm_s2"] == pytest.approx(amp * w * w, rel=1e-3)
    assert k["z_jerk_max_mm_s3"] == pytest.approx(amp * w ** 3, rel=2e-2)
    assert k["c_velocity_max_rad_s"] == pytest.approx(2 * math.pi * 0.7, rel=1e-9)
    assert k["warnings"] == [] and k["limits"] == {}


def test_limit_warnings_say_where():
    path = _sine_path()
    proc = ProcessConfig(z_velocity_limit_mm_s=0.01, x_velocity_limit_mm_s=1.0)
    assert limits_from_process(proc) == {"x_velocity_limit_mm_s": 1.0, "z_velocity_limit_mm_s": 0.01}
    k = kinematics(path, limits=proc)
    assert list(k["limits_exceeded"]) == ["z_velocity_limit_mm_s"]
    (w,) = k["warnings"]
    assert "Z velocity exceeds process.z_velocity_limit_mm_s = 0.01 mm/s" in w
    # first exceedance: |vz| = A w |cos(w t)| > 0.01 already at t = 0
    assert "first at t = 0.0000 s, radius 4.0000 mm" in w
    assert "worst 0.01885" in w
    # a dict works too, and a limit above the maximum gives no warning
    assert kinematics(path, limits={"z_velocity_limit_mm_s": 1.0})["warnings"] == []


def test_kinematics_bad_input():
    p = _sine_path(10)
    with pytest.raises(InputError, match="unknown kinematic limit"):
        kinematics(p, limits={"x_speed": 1.0})
    with pytest.raises(InputError, match="x_velocity_limit_mm_s must be > 0"):
        kinematics(p, limits={"x_velocity_limit_mm_s": -1.0})
    t = np.array([0.0, 1.0, 1.0, 2.0])
    with pytest.raises(InputError, match=r"strictly increasing.*t\[1\]"):
        axis_derivatives(t, np.zeros(4))
    with pytest.raises(InputError, match="at least 3"):
        axis_derivatives(np.array([0.0, 1.0]), np.zeros(2))


@pytest.mark.slow
def test_plot_kinematics_writes_png(tmp_path):
    from PIL import Image

    a = _sine_path(20_000)
    rng = np.random.default_rng(0)
    b = ToolPath(a.theta, a.rho + rng.uniform(-1e-3, 1e-3, a.rho.size), a.z, a.t, {})
    out = plot_kinematics(a, tmp_path / "k.png", reference=b)
    with Image.open(out) as im:
        assert im.size[0] > 800 and im.size[1] > 600
    assert not list(tmp_path.glob(".*tmp"))
