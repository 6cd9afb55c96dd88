"""Hybrid tool servo (seed 002): servo dynamics, lag -> rotation, ideal servo = commanded."""

from __future__ import annotations

import math

import numpy as np
import pytest
from numpy.testing import assert_allclose

from render_inspect.design import make_surface
from render_inspect.errors import InputError, SceneError
from render_inspect.machining import (
    followed_path,
    servo_response,
    simulate_turning,
    split_commands,
)
from render_inspect.pipeline import simulate
from render_inspect.processes import plan_spiral
from render_inspect.scene import load_scene, scene_from_dict

simulate_hts = simulate_sts = simulate


def build_toolpath(scene, region):
    """The scene's commanded turning program over ``region``."""
    return plan_spiral(scene, make_surface(scene.design), region=region)


def _lag_scene(*, delay_s=0.0, bandwidth_hz=None, kind="hts", region=(0.55, -0.45, 2.45, 0.75),
               registration="none"):
    """Two concave lenslets on the x axis at r = 1 and 2 mm, on a flat base."""
    return scene_from_dict({
        "name": "lag",
        "design": {"type": "compound",
                   "base": {"type": "plane"},
                   "feature": {"type": "lenslet_array", "cells": "round", "rows": 1, "cols": 2,
                               "pitch_x": 1.0, "pitch_y": 1.0, "center_x": 1.5,
                               "lens_radius": 10.0, "aperture_radius": 0.3}},
        "tool": {"nose_radius": 0.2, "included_angle_deg": 60, "clearance_angle_deg": 15},
        "process": {"kind": kind, "spindle_rpm": 100, "feed_mm_per_min": 1.0,
                    "workpiece_radius": 3.0, "points_per_rev": 1440, "compensation": "z"},
        "simulation": {"region": list(region), "pixel": 0.01, "seed": 1},
        "artifacts": {"servo": {"delay_s": delay_s, "bandwidth_hz": bandwidth_hz}},
        # the raw positions (the 6-DOF registration of seed 002 would turn the lag away:
        # test_registration_removes_a_constant_lag)
        "metrology": {"registration": registration},
    })


# ---- servo_response: the second-order model and the lag ------------------------------
def test_ideal_servo_returns_the_command():
    t = np.linspace(0, 1, 1001)
    x = np.sin(2 * np.pi * 3 * t) + t
    assert_allclose(servo_response(x, t), x, rtol=0, atol=0)


def test_second_order_steady_state_matches_transfer_function():
    fs, fn, zeta, f = 20000.0, 200.0, 0.4, 150.0
    t = np.arange(0, 0.5, 1 / fs)
    x = np.sin(2 * np.pi * f * t)
    y = servo_response(x, t, bandwidth_hz=fn, damping=zeta)
    w = 2 * np.pi * f
    wn = 2 * np.pi * fn
    H = wn ** 2 / (wn ** 2 - w ** 2 + 2j * zeta * wn * w)
    expected = np.abs(H) * np.sin(w * t + np.angle(H))
    tail = t > 0.25                       # transients have died (time constant 2 ms)
    assert_allclose(y[tail], expected[tail], atol=2e-3)


def test_second_order_step_overshoot():
    t = np.arange(0, 0.2, 1e-5)
    x = np.where(t > 0.01, 1.0, 0.0)
    zeta = 0.5
    y = servo_response(x, t, bandwidth_hz=100.0, damping=zeta)
    overshoot = y.max() - 1.0
    assert overshoot == pytest.approx(math.exp(-math.pi * zeta / math.sqrt(1 - zeta ** 2)), abs=2e-3)
    assert y[-1] == pytest.approx(1.0, abs=1e-6)
    assert abs(y[t < 0.01]).max() < 1e-12   # causal: nothing before the step


def test_pure_delay_shifts_in_time():
    t = np.linspace(0, 1, 10001)
    x = np.sin(2 * np.pi * 2 * t)
    y = servo_response(x, t, delay_s=0.05)
    late = t >= 0.05
    assert_allclose(y[late], np.sin(2 * np.pi * 2 * (t[late] - 0.05)), atol=1e-6)


def test_uneven_time_axis_is_resampled():
    t = np.cumsum(np.r_[0, np.where(np.arange(3999) % 2, 1e-4, 2e-4)])
    x = np.sin(2 * np.pi * 5 * t)
    y = servo_response(x, t, bandwidth_hz=500.0, damping=0.7)
    lag = 2 * 0.7 / (2 * np.pi * 500)     # low-frequency group delay
    late = t > 0.1
    assert_allclose(y[late], np.sin(2 * np.pi * 5 * (t[late] - lag)), atol=2e-3)


@pytest.mark.parametrize("kw, word", [({"bandwidth_hz": -1.0}, "bandwidth_hz"),
                                      ({"delay_s": -0.1}, "delay_s"),
                                      ({"damping": 0.0}, "damping")])
def test_servo_bad_values_are_named(kw, word):
    t = np.linspace(0, 1, 11)
    with pytest.raises(InputError, match=word):
        servo_response(np.zeros(11), t, **kw)


def test_servo_needs_increasing_time():
    with pytest.raises(InputError, match="increasing"):
        servo_response(np.zeros(3), np.array([0.0, 0.2, 0.1]))


# ---- the split and the HTS simulation ------------------------------------------------
def test_split_adds_up_and_fts_of_a_rotational_design_is_zero():
    scene = _lag_scene(kind="fts").with_overrides(
        ['design={type="sphere", radius=50.0}'])
    path = build_toolpath(scene, region=scene.simulation.region)
    zs, zf = split_commands(path, "fts")
    assert_allclose(zs + zf, path.z, atol=1e-15)
    # a sphere about the axis is all slow slide (the split is exact a revolution pair
    # away from the ends of the path, where the averaging windows are complete)
    inner = (path.theta > path.theta[0] + 2 * np.pi) & (path.theta < path.theta[-1] - 2 * np.pi)
    assert np.abs(zf[inner]).max() < 1e-9
    assert np.abs(zf).max() < 1e-3 * np.ptp(path.z)


@pytest.mark.parametrize("kind", ["hts", "fts"])
def test_ideal_servo_without_lag_reproduces_the_commanded_surface(kind):
    scene = _lag_scene(kind=kind)
    res = simulate_hts(scene)
    sts = simulate_sts(scene.with_overrides(["process.kind='sts'"]))
    assert_allclose(res.heightmap.machined, sts.heightmap.machined, rtol=0, atol=1e-12)
    assert res.metrics["servo"]["fts_following_error"]["max_um"] < 1e-9
    assert res.metrics["servo"]["fts_stroke_um"] > 4.0     # the lenslets are on the FTS


def test_followed_path_equals_command_for_an_ideal_servo():
    scene = _lag_scene()
    path = build_toolpath(scene, region=scene.simulation.region)
    zs, zf = split_commands(path, "hts", base=make_surface(scene.design).base,
                            nose_radius=0.2, half_width=0.1)
    sv = scene.artifacts.servo
    fpath, _, _ = followed_path(path, zs, zf, slow_bandwidth_hz=sv.slow_bandwidth_hz,
                                slow_damping=sv.slow_damping, fts_bandwidth_hz=sv.bandwidth_hz,
                                fts_damping=sv.damping, fts_delay_s=sv.delay_s)
    region, px = scene.simulation.region, scene.simulation.pixel
    a = simulate_turning(path, nose_radius=0.2, region=region, pixel=px, half_width=0.1)
    b = simulate_turning(fpath, nose_radius=0.2, region=region, pixel=px, half_width=0.1)
    assert_allclose(a, b, rtol=0, atol=1e-12)


def _fit_dimple_centre(hm, cx, cy, radius):
    """Least-squares paraboloid z = a + b x + c y + d (x^2 + y^2) inside ``radius``."""
    X, Y = np.meshgrid(hm.x, hm.y)
    sel = np.hypot(X - cx, Y - cy) < radius
    A = np.column_stack([np.ones(sel.sum()), X[sel], Y[sel], X[sel] ** 2 + Y[sel] ** 2])
    a, b, c, d = np.linalg.lstsq(A, hm.machined[sel], rcond=None)[0]
    return -b / (2 * d), -c / (2 * d)


def test_pure_lag_rotates_features_by_omega_tau():
    tau = 0.005
    res = simulate_hts(_lag_scene(delay_s=tau))
    omega = 2 * np.pi * 100 / 60
    rot = omega * tau
    assert res.metrics["servo"]["lag_angle_rad"] == pytest.approx(rot)
    table = {(e["row"], e["col"]): e for e in res.metrics["lenslets"]}
    assert set(table) == {(0, 0), (0, 1)}
    for col, r in ((0, 1.0), (1, 2.0)):
        ex, ey = r * np.cos(rot), r * np.sin(rot)   # rotated by omega tau about the axis
        e = table[(0, col)]
        assert e["x_mm"] == pytest.approx(ex, abs=1.5e-3)
        assert e["y_mm"] == pytest.approx(ey, abs=1.5e-3)
        # an independent paraboloid fit agrees
        fx, fy = _fit_dimple_centre(res.heightmap, ex, ey, 0.25)
        assert fx == pytest.approx(ex, abs=2e-3) and fy == pytest.approx(ey, abs=2e-3)
    # the displacement grows in proportion to the radius (the spiral pattern)
    d1 = math.hypot(table[(0, 0)]["dx_um"], table[(0, 0)]["dy_um"])
    d2 = math.hypot(table[(0, 1)]["dx_um"], table[(0, 1)]["dy_um"])
    assert d2 / d1 == pytest.approx(2.0, rel=0.05)


def test_registration_removes_a_constant_lag():
    """Seed 002's characterisation registers the design to the cut (6 DOF): a constant lag
    is a rigid rotation by omega tau, found by the registration and gone from the
    dislocations that are left."""
    tau = 0.005
    res = simulate_hts(_lag_scene(delay_s=tau, registration="lsq"))
    rot = 2 * np.pi * 100 / 60 * tau
    reg = res.metrics["msa"]["registration"]
    assert reg["gamma_rad"] == pytest.approx(rot, rel=0.02)
    for e in res.metrics["lenslets"]:
        # 52 and 105 um of displacement before registration; ~1 um after (the 10 um grid)
        assert math.hypot(e["dx_um"], e["dy_um"]) < 1.5


def test_finite_bandwidth_adds_its_group_delay():
    fn = 300.0
    res = simulate_hts(_lag_scene(bandwidth_hz=fn))
    lag = 2 * 0.7 / (2 * np.pi * fn)
    rot = 2 * np.pi * 100 / 60 * lag
    e = {(d["row"], d["col"]): d for d in res.metrics["lenslets"]}[(0, 1)]
    assert e["dy_um"] == pytest.approx(2.0 * rot * 1e3, rel=0.15)
    assert res.metrics["servo"]["fts_following_error"]["max_um"] > 0.1


def test_hts_needs_a_compound_design():
    with pytest.raises(SceneError, match="compound"):
        _lag_scene().with_overrides(['design={type="sphere", radius=50.0}'])


def test_servo_scene_keys_are_validated():
    with pytest.raises(SceneError, match="bandwidth_hz"):
        _lag_scene().with_overrides(["artifacts.servo.bandwidth_hz=-5"])
    with pytest.raises(SceneError, match="slow_bandwidth"):
        _lag_scene().with_overrides(["artifacts.servo.slow_bandwidth=5"])


def test_hts_scene_file_loads(scenes_dir):
    scene = load_scene(scenes_dir / "hts_toric_msa.toml")
    assert scene.process.kind == "hts"
    assert scene.machine.preset == "fts" and scene.material.preset == "al6061"
    from render_inspect.design import make_surface

    surf = make_surface(scene.design)
    # every lenslet rim lies on the 15 mm blank
    rims = [math.hypot(x, y) + 0.5 for _, _, x, y in surf.centers()]
    assert len(rims) == 49 and max(rims) < scene.process.workpiece_radius


def test_coarse_time_samples_are_refined_for_a_fast_servo():
    """A 1 kHz servo on a 2.5 kHz path sampling: the linear command is filtered on a fine
    grid, so the result matches the fine-sampled response at the path's samples."""
    t_fine = np.arange(0, 0.2, 1e-6)
    x_fine = np.sin(2 * np.pi * 40 * t_fine)
    t = t_fine[::400]
    x = x_fine[::400]
    x_lin = np.interp(t_fine, t, x)            # what the axes are told between the samples
    ref = servo_response(x_lin, t_fine, bandwidth_hz=1000.0, damping=0.7)[::400]
    y = servo_response(x, t, bandwidth_hz=1000.0, damping=0.7)
    assert_allclose(y, ref, atol=1e-3)     # filtering the 2.5 kHz samples directly: 0.04
