"""RCSE spiral paths (seed 004): CCPs exactly on the design, monotone radius, ratchet and
shuttle, stitching, and the conventional grid-interpolated comparison."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from numpy.testing import assert_allclose

from render_inspect.design import make_surface
from render_inspect.errors import InputError, SceneError
from render_inspect.pipeline import simulate, write_simulation
from render_inspect.scene import load_scene
from render_inspect.toolpath import (
    RingLayout,
    Tool,
    conventional_ccps,
    paper_layout,
    rcse_ccps,
    rcse_toolpath,
)


def build_rcse_toolpath(s, region):
    """The scene's RCSE program over ``region``."""
    p = s.process
    return rcse_toolpath(RingLayout.from_config(s.design), Tool.from_config(s.tool),
                         workpiece_radius=p.workpiece_radius, pitch=p.feed_per_rev,
                         points_per_rev=p.points_per_rev, spindle_rpm=p.spindle_rpm,
                         inner_radius=p.inner_radius, compensation=p.compensation, region=region)


SCENE = Path(__file__).resolve().parents[1] / "scenes" / "rcse_circular_array.toml"


@pytest.fixture(scope="module")
def scene():
    return load_scene(SCENE)


@pytest.fixture(scope="module")
def full_ccps(scene):
    layout = RingLayout.from_config(scene.design)
    p = scene.process
    return rcse_ccps(layout, r_outer=p.workpiece_radius, pitch=p.feed_per_rev,
                     points_per_rev=p.points_per_rev)


def test_paper_case_point_count_and_layout(scene, full_ccps):
    # 9.5 mm region, 5 um pitch, 0.25 deg step: 950 revolutions x 1440 + 1 CCPs
    assert scene.process.points_per_rev == 1440 and scene.process.feed_per_rev == pytest.approx(0.005)
    assert full_ccps.theta.size == 950 * 1440 + 1
    layout = RingLayout.from_config(scene.design)
    assert layout.overlaps(gap=0.05) == []
    assert layout.outer_radius <= scene.process.workpiece_radius + 1e-12
    assert layout.sphere_radius == pytest.approx((0.4 ** 2 + 0.002 ** 2) / 0.004)
    # the scene's layout is the documented paper_layout()
    pl = paper_layout()
    assert_allclose(pl.ring_radii, layout.ring_radii)
    assert pl.counts == layout.counts
    # 36 elements of 0.4 mm do not fit on the outer ring: reported, with the radius needed
    bad = RingLayout((4.35,), (36,), 0.4, 0.002)
    msg = bad.overlaps()
    assert msg and "36 elements need a radius >=" in msg[0]


def test_rcse_radius_monotone_and_exact_spiral(full_ccps):
    rho, th = full_ccps.rho, full_ccps.theta
    assert np.all(np.diff(rho) < 0)
    assert np.all(np.diff(th) > 0)
    assert_allclose(rho, 4.75 - 0.005 * th / (2 * math.pi), atol=1e-12)
    assert rho[0] == 4.75 and rho[-1] == pytest.approx(0.0, abs=1e-12)


def test_rcse_ccps_lie_on_the_design_surface(scene, full_ccps):
    surface = make_surface(scene.design)  # the design module's LensletRings
    c = full_ccps
    sel = slice(None, None, 7)  # every 7th CCP of the 1.37 M (all rings, all elements)
    z_design = surface.height(c.x[sel], c.y[sel])
    assert np.max(np.abs(z_design - c.z[sel])) < 1e-12
    # and the elements are really there: about 60 % of the CCPs lie on elements
    on = c.ring >= 0
    assert 0.4 < on.mean() < 0.8
    assert np.min(c.z[on]) == pytest.approx(-0.002, abs=2e-7)


def test_ratchet_and_shuttle(scene, full_ccps):
    """One element pitch later (P / N samples) the CCP has the same local angle, a radius
    smaller by the shuttle D = d dtheta / (2 pi), and the height of the basic element at
    that shuttled position."""
    layout = RingLayout.from_config(scene.design)
    c = full_ccps
    P, d = 1440, 0.005
    ring = 3  # radius 3.48 mm, 24 elements: 60 samples per element
    N = layout.counts[ring]
    step = P // N
    D = d * (2 * math.pi / N) / (2 * math.pi)
    idx = np.flatnonzero((c.ring == ring))[::50]
    idx = idx[idx + step < c.k.size]
    assert idx.size > 100
    assert_allclose(c.rho[idx] - c.rho[idx + step], D, atol=1e-12)
    # basic element (n = 0) evaluated at the shuttled radius and the same local angle
    R, a = layout.ring_radii[ring], layout.element_radius
    phi = ((c.k[idx] % P) * (2 * math.pi / P)) - c.element[idx] * (2 * math.pi / N)
    phi = (phi + math.pi) % (2 * math.pi) - math.pi
    r2 = c.rho[idx] - D
    u, v = r2 * np.cos(phi) - R, r2 * np.sin(phi)
    assert_allclose(c.z[idx + step], layout.element_height(u * u + v * v), atol=1e-13)
    assert np.all(c.element[idx + step][np.isin(c.ring[idx + step], [ring])] ==
                  (c.element[idx] + 1)[np.isin(c.ring[idx + step], [ring])] % N)


def test_sub_paths_are_stitched_end_to_end(scene, full_ccps):
    layout = RingLayout.from_config(scene.design)
    sp = full_ccps.sub_paths()
    assert np.all(sp[:, 2] <= sp[:, 3])
    assert np.all(sp[1:, 2] > sp[:-1, 3])  # in cutting order, no CCP shared or skipped twice
    # every element of every ring is visited
    visited = {(int(r), int(e)) for r, e in sp[:, :2]}
    assert len(visited) == sum(layout.counts)
    # inside one ring's band, consecutive sub-paths belong to neighbouring elements
    r3 = sp[sp[:, 0] == 3]
    dn = np.diff(r3[:, 1]) % layout.counts[3]
    assert np.all(dn == 1)


def test_window_is_a_window_of_the_full_spiral(scene, full_ccps):
    layout = RingLayout.from_config(scene.design)
    w = rcse_ccps(layout, r_outer=4.75, pitch=0.005, points_per_rev=1440, r_range=(3.0, 3.2))
    assert w.rho.min() >= 3.0 - 1e-12 and w.rho.max() <= 3.2 + 1e-12
    k = w.k
    assert_allclose(w.z, full_ccps.z[k], atol=0)
    assert_allclose(w.theta, full_ccps.theta[k], atol=0)


def test_conventional_path_reciprocates_and_has_profile_error(scene):
    layout = RingLayout.from_config(scene.design)
    surface = make_surface(scene.design)
    c = rcse_ccps(layout, r_outer=4.75, pitch=0.005, points_per_rev=1440, r_range=(1.7, 1.8))
    g = 0.005
    conv = conventional_ccps(surface, c.theta, c.rho, grid_spacing=g)
    dev = conv["rho"] - c.rho
    assert np.max(np.abs(dev)) <= g / 2 + 1e-12
    assert np.max(np.abs(dev)) > 0.4 * g  # the X axis really jumps by up to g/2
    assert np.count_nonzero(np.diff(conv["rho"]) > 0) > 100  # X moves outward: reciprocation
    e = conv["profile_error"]
    assert np.max(np.abs(e)) > 1e-6  # > 1 nm
    # without snapping to rows, X is the spiral and only the interpolation error remains
    conv2 = conventional_ccps(surface, c.theta, c.rho, grid_spacing=g, snap_to_rows=False,
                              interpolation="cubic")
    assert_allclose(conv2["rho"], c.rho)
    assert 0 < np.max(np.abs(conv2["profile_error"])) < np.max(np.abs(e))


def test_conventional_interpolation_is_exact_on_a_plane():
    """Known answer: bilinear interpolation of a plane is exact.  Without snapping the
    profile error is 0; with snapping, the CCP is the plane at (x, nearest row y) while the
    machine (C = theta, X = its polar radius) puts the tool elsewhere on the plane: the
    error is exactly the plane's height difference between the two points."""
    plane = make_surface({"type": "plane", "slope_x": 0.01, "slope_y": -0.02})
    th = np.linspace(0, 40 * math.pi, 5000)
    rho = 1.0 - 0.005 * th / (2 * math.pi)
    g = 0.01
    conv = conventional_ccps(plane, th, rho, grid_spacing=g, snap_to_rows=False)
    assert np.max(np.abs(conv["profile_error"])) < 1e-15
    conv = conventional_ccps(plane, th, rho, grid_spacing=g, snap_to_rows=True)
    x, y_row = rho * np.cos(th), g * np.rint(rho * np.sin(th) / g)
    assert_allclose(conv["z"], plane.height(x, y_row), atol=1e-15)
    assert_allclose(conv["rho"], np.hypot(x, y_row), atol=1e-15)
    xm, ym = conv["rho"] * np.cos(th), conv["rho"] * np.sin(th)
    assert_allclose(conv["profile_error"], plane.height(x, y_row) - plane.height(xm, ym), atol=1e-15)
    assert np.max(np.abs(conv["profile_error"])) > 1e-5


def test_build_rcse_toolpath_uncompensated_equals_ccps(scene):
    s = scene.with_overrides(["process.compensation='none'"])
    path = build_rcse_toolpath(s, region=(3.3, -0.1, 3.5, 0.1))
    surface = make_surface(s.design)
    assert_allclose(path.z, surface.height(path.x, path.y), atol=1e-12)
    assert_allclose(path.t, path.theta / (2 * math.pi * 42 / 60))
    assert path.meta["method"] == "rcse" and path.meta["compensation"] == "none"
    assert 0 < path.meta["chordal_error_max_mm"] < 1e-4  # linear C-X-Z between exact CCPs
    # Z compensation keeps X and lifts the tip off the concave spheres (R >> Rc: by ~0)
    pz = build_rcse_toolpath(scene, region=(3.3, -0.1, 3.5, 0.1))
    assert_allclose(pz.rho, path.rho)
    assert np.all(pz.z >= path.z - 1e-12)
    assert_allclose(pz.ccp_z, path.z)


def test_bad_input_is_named():
    layout = paper_layout()
    with pytest.raises(InputError, match="pitch"):
        rcse_ccps(layout, r_outer=4.75, pitch=0.0, points_per_rev=1440)
    with pytest.raises(InputError, match="points_per_rev"):
        rcse_ccps(layout, r_outer=4.75, pitch=0.005, points_per_rev=7)
    with pytest.raises(InputError, match="r_range"):
        rcse_ccps(layout, r_outer=4.75, pitch=0.005, points_per_rev=1440, r_range=(6.0, 7.0))
    with pytest.raises(SceneError, match="lenslet_rings"):
        RingLayout.from_config({"type": "sphere", "radius": 10.0})
    with pytest.raises(InputError, match="depth"):
        RingLayout((1.0,), (4,), 0.4, 0.5)
    with pytest.raises(InputError, match="grid_spacing"):
        conventional_ccps(layout, np.zeros(3), np.ones(3), grid_spacing=-1.0)
    with pytest.raises(InputError, match="interpolation"):
        conventional_ccps(layout, np.zeros(3), np.ones(3), grid_spacing=0.01, interpolation="spline")


def test_rcse_section_defaults_and_values(scene):
    assert scene.rcse.grid_spacing == 0.005
    st = scene.with_overrides(["rcse.grid_spacing=0.01", "rcse.interpolation='cubic'"]).rcse
    assert st.grid_spacing == 0.01 and st.interpolation == "cubic" and st.snap_to_rows is True


@pytest.mark.slow
def test_simulate_rcse_small_window(scene, tmp_path):
    # the commanded geometry (the lathe's and the material's effects: test_machine_scene.py)
    s = scene.with_overrides(["simulation.region=[0.81, -0.06, 0.93, 0.06]", "simulation.pixel=0.004",
                              "process.x_velocity_limit_mm_s=0.5", "machine.preset='ideal'",
                              "material.preset='ideal'"])
    res = simulate(s)
    write_simulation(res, tmp_path)
    m = res.metrics
    # gouge-free (Z compensation) and feed scallops of about f^2 / (8 Rc) = 31 nm
    assert m["residual"]["min_nm"] > -1e-3
    assert 5 < m["residual"]["Sz_nm"] < 60
    tp = m["toolpath"]
    assert tp["x_reversals"] == 0 and tp["warnings"] == []
    assert tp["x_velocity_max_mm_s"] == pytest.approx(0.005 * 42 / 60, rel=1e-6)
    cmp_ = m["rcse"]["comparison"]
    assert cmp_["rcse"]["profile_error_max_nm"] < 1e-6
    assert cmp_["conventional"]["x_reversals"] > 100
    assert cmp_["conventional"]["x_velocity_max_mm_s"] > 100 * cmp_["rcse"]["x_velocity_max_mm_s"]
    assert cmp_["conventional"]["profile_error_max_nm"] > 1.0
    # both machined: the RCSE residual is the one of the simulation itself
    assert cmp_["rcse"]["residual"]["Sq_nm"] == pytest.approx(m["residual"]["Sq_nm"])
    assert cmp_["conventional"]["residual"]["Sz_nm"] > cmp_["rcse"]["residual"]["Sz_nm"]
    assert (tmp_path / "rcse_kinematics.png").stat().st_size > 10_000
    assert res.heightmap.meta["process"] == "rcse"
    # kinematics.png: X of the RCSE path against the conventional one (the axis that matters)
    assert (tmp_path / "kinematics.png").stat().st_size > 10_000


def test_rcse_rejects_overlapping_elements(scene):
    # the scene refuses such a layout when it is loaded, naming the keys
    with pytest.raises(SceneError, match=r"design.element_radius: must let the 36 elements of "
                                         r"ring 4 \(radius 4.35 mm\) sit side by side"):
        scene.with_overrides(["design.counts=[6, 12, 18, 24, 36]"])
