"""Hybrid tool servo (Kong et al. 2020): the split of the program between the slow slide
and the FTS, their servos (the machine's axes), lag -> rotation, ideal servo = commanded."""

from __future__ import annotations

import math

import numpy as np
import pytest
from numpy.testing import assert_allclose

from render_inspect.design import make_surface
from render_inspect.errors import SceneError
from render_inspect.machining import Axis, follow_axis, split_commands
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
        # the FTS of an otherwise ideal machine: a second-order servo without feed-forward
        "machine": {"fts": {"delay_s": delay_s,
                            **({} if bandwidth_hz is None else {"bandwidth_hz": bandwidth_hz})}},
        # the raw positions (the 6-DOF registration of Kong et al. would turn the lag away:
        # test_registration_removes_a_constant_lag)
        "metrology": {"registration": registration},
    })


# ---- the servo: the machine's axis (test_axes.py: the second-order response, the lag) ---
def test_pure_delay_shifts_in_time():
    t = np.linspace(0, 1, 10001)
    x = np.sin(2 * np.pi * 2 * t)
    r = follow_axis(t, x, Axis(delay_s=0.05), rate_hz=10000.0)
    late = r.t >= 0.05
    assert_allclose(r.followed[late], np.sin(2 * np.pi * 2 * (r.t[late] - 0.05)), atol=1e-6)


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
    """Kong et al. 2020's characterisation registers the design to the cut (6 DOF): a constant lag
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
    with pytest.raises(SceneError, match="machine.fts.bandwidth_hz"):
        _lag_scene().with_overrides(["machine.fts.bandwidth_hz=-5"])
    # the retired keys: mapped (and checked) as their successors, unknown ones named
    with pytest.raises(SceneError, match="machine.fts.bandwidth_hz"), pytest.warns(UserWarning):
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
