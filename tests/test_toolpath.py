"""Spiral paths, compensation and accessibility against closed-form answers."""

import math
from pathlib import Path

import numpy as np
import pytest

from render_inspect.design import Plane, SinusoidalGrid, Sphere, make_surface
from render_inspect.errors import AccessibilityError
from render_inspect.processes import plan_spiral
from render_inspect.scene import load_scene
from render_inspect.toolpath import (
    Tool,
    check_accessibility,
    chordal_step_for,
    normal_compensation,
    spiral_ccps,
    z_compensation,
)

REPO = Path(__file__).resolve().parents[1]
GRID = REPO / "scenes" / "sts_sinusoidal_grid.toml"


def _spiral(p, **kw):
    """spiral_ccps with the [process] keys of a scene."""
    return spiral_ccps(feed_per_rev=p.feed_per_rev, sampling=p.sampling,
                       points_per_rev=p.points_per_rev, arc_length=p.arc_length,
                       switch_radius=p.switch_radius, **kw)


def build_toolpath(s, region):
    """The scene's turning program over ``region``."""
    return plan_spiral(s, make_surface(s.design), region=region)


def test_constant_angle_spiral_matches_seed000_formula():
    s = load_scene(GRID, ["process.points_per_rev=360", "process.workpiece_radius=1.0"])
    theta, rho = _spiral(s.process, r_outer=1.0, r_inner=0.5)
    f, S, N = s.process.feed_mm_per_min, s.process.spindle_rpm, 360
    i = np.arange(len(theta))
    np.testing.assert_allclose(rho, 1.0 - i * f / (S * N), atol=1e-12)  # rho_i = Rw - (i-1) f/(S N)
    np.testing.assert_allclose(theta, i * 2 * np.pi / N, atol=1e-12)
    assert len(theta) == round(0.5 * S * N / f) + 1


def test_constant_arc_spiral_has_equal_arc_steps():
    s = load_scene(GRID, ["process.sampling='constant_arc'", "process.arc_length=0.01"])
    theta, rho = _spiral(s.process, r_outer=2.0, r_inner=1.0)
    ds = rho[:-1] * np.diff(theta)  # circumferential arc per step
    np.testing.assert_allclose(ds, 0.01, rtol=2e-3)


def test_hybrid_switches_from_arc_to_angle():
    s = load_scene(GRID, ["process.sampling='hybrid'", "process.arc_length=0.01", "process.switch_radius=1.0",
                          "process.points_per_rev=720"])
    theta, rho = _spiral(s.process, r_outer=2.0, r_inner=0.2)
    dth = np.diff(theta)[:-1]  # the last step ends at r_inner and may be shorter
    rho = rho[:-1]
    inner = rho[1:] < 0.99
    outer = rho[1:] > 1.01
    np.testing.assert_allclose(dth[inner], 2 * np.pi / 720, rtol=1e-9)
    np.testing.assert_allclose((rho[:-1] * dth)[outer], 0.01, rtol=3e-3)


def test_chordal_error_is_bounded_by_the_tolerance():
    # seed 001: E = R' - sqrt(R'^2 - (L/2)^2); L = sqrt(8 R' h - 4 h^2)
    R, h = 5.0, 1e-5
    L = chordal_step_for(h, R)
    assert R - math.sqrt(R * R - (L / 2) ** 2) == pytest.approx(h, rel=1e-9)
    s = load_scene(GRID, ["process.chordal_tolerance=2e-6", "process.points_per_rev=64",
                          "simulation.region=[-0.5,-0.5,0.5,0.5]"])
    path = build_toolpath(s, region=s.simulation.region)
    assert path.meta["chordal_error_max_mm"] <= 2e-6
    assert path.meta["points_per_rev"] > 64
    loose = build_toolpath(s.with_overrides(["process.chordal_tolerance=1.0"]), region=s.simulation.region)
    assert loose.meta["chordal_error_max_mm"] > 2e-6  # 64 points per rev would not meet it


def test_z_compensation_on_a_sphere_is_exact():
    # a ball of radius Rc touching a convex sphere of radius R: the tool tip lies on a
    # sphere of radius R + Rc about the same centre, minus Rc
    R, Rc = 5.0, 0.5
    surf = Sphere(R)
    rho = np.linspace(0.0, 1.5, 50)
    theta = np.zeros_like(rho)
    z = z_compensation(surf, theta, rho, Rc, half_width=Rc)
    centre_z = -R + np.sqrt((R + Rc) ** 2 - rho ** 2)
    np.testing.assert_allclose(z, centre_z - Rc, atol=1e-9)


def test_z_compensation_threads_stop_at_their_next_chunk_when_asked(monkeypatch):
    # a stop asked for (the command line's handler) ends the compensation's threads at
    # their next chunk: the call raises it instead of finishing every chunk (the pool's
    # end waits for its threads, so a thread that went on delayed the stop by the rest)
    import signal

    from render_inspect.core import cancel
    import render_inspect.toolpath._compensation as comp

    monkeypatch.setattr(comp, "usable_cpus", lambda: 2)
    rho = np.linspace(0.0, 1.5, 20_000)
    calls = []
    surf = Sphere(5.0)
    height = surf.height

    def asked_once(x, y):  # the stop comes while the first chunk is searched
        calls.append(len(x))
        cancel.request(signal.SIGINT)
        return height(x, y)

    def counted(x, y):
        calls.append(len(x))
        return height(x, y)

    kw = dict(half_width=0.5, chunk=100, max_slope=0.5)
    monkeypatch.setattr(surf, "height", counted)
    z_compensation(surf, np.zeros(100), rho[:100], 0.5, **kw)
    per_chunk, calls[:] = len(calls), []
    monkeypatch.setattr(surf, "height", asked_once)
    try:
        with pytest.raises(KeyboardInterrupt):
            z_compensation(surf, np.zeros_like(rho), rho, 0.5, **kw)
    finally:
        cancel.clear()
    # each of the two threads searched at most the chunk it held (of 200)
    assert 0 < len(calls) <= 2 * per_chunk, (len(calls), per_chunk)


def test_normal_compensation_3d_form_equals_radial_form():
    surf = SinusoidalGrid(0.002, 0.002, 2.5, 2.5)
    rng = np.random.default_rng(0)
    theta = rng.uniform(0, 2 * np.pi, 200)
    rho = rng.uniform(0.1, 2.0, 200)
    rho_t, z_t = normal_compensation(surf, theta, rho, 0.5)
    phi = np.arctan(surf.radial_slope(rho, theta))
    np.testing.assert_allclose(rho_t, rho - 0.5 * np.sin(phi), atol=1e-12)  # seed 000 eq. 6
    np.testing.assert_allclose(z_t, surf.radial_profile(rho, theta) + 0.5 * np.cos(phi) - 0.5, atol=1e-12)


def test_uncompensated_path_gouge_is_reported():
    slope = 0.02
    s = load_scene(GRID, ["design={type='plane', slope_x=0.02}", "process.compensation='none'",
                          "simulation.region=[0.5,-0.05,0.6,0.05]", "tool.nose_radius=0.5"])
    path = build_toolpath(s, region=s.simulation.region)
    assert path.meta["gouge_max_mm"] == pytest.approx(0.5 * slope ** 2 / 2, rel=0.05)
    zc = build_toolpath(s.with_overrides(["process.compensation='z'"]), region=s.simulation.region)
    assert zc.meta["gouge_max_mm"] == 0.0


def test_accessibility_reports_a_too_large_nose_on_a_concave_sphere():
    tool = Tool(0.5)
    rep = check_accessibility(Sphere(-0.4), tool, (-0.1, -0.1, 0.1, 0.1))
    assert not rep["ok"] and not rep["nose_radius"]["ok"]
    assert rep["nose_radius"]["worst"] == pytest.approx(0.4, rel=0.02)  # smallest concave ROC
    assert rep["nose_radius"]["excess_mm"] == pytest.approx(0.1, rel=0.1)
    assert check_accessibility(Sphere(-0.6), tool, (-0.1, -0.1, 0.1, 0.1))["ok"]
    # included angle: 60 deg allows radial slopes up to 30 deg
    rep = check_accessibility(Plane(math.tan(math.radians(35)), 0.0), tool, (0.5, -0.1, 0.7, 0.1))
    assert not rep["included_angle"]["ok"]
    assert rep["included_angle"]["worst"] == pytest.approx(70.0, abs=0.1)


def test_simulation_refuses_an_inaccessible_design_unless_asked(tmp_path):
    from render_inspect.pipeline import run_simulate

    s = load_scene(GRID, ["design={type='sphere', radius=-0.8}", "simulation.region=[-0.05,-0.05,0.05,0.05]",
                          "simulation.pixel=0.005", "process.workpiece_radius=0.2", "tool.nose_radius=1.0"])
    out = tmp_path / "out"
    with pytest.raises(AccessibilityError, match="nose_radius.*allow_gouge"):
        run_simulate(s, out)
    assert not out.exists()  # nothing half-written
    assert not list(tmp_path.iterdir())
    m = run_simulate(s.with_overrides(["process.allow_gouge=true"]), out)
    # Z compensation keeps the too-large nose above the bowl: it cannot reach the bottom
    assert m["residual"]["min_nm"] > 100
