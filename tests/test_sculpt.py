"""Vibration-assisted sculpturing (seed 003): the overcuts come out of the geometry."""

from __future__ import annotations

import math

import numpy as np
import pytest
from numpy.testing import assert_allclose

from render_inspect.design import Plane
from render_inspect.errors import AccessibilityError, InputError, SceneError
from render_inspect.machining import sculpt_line_profile, target_line
from render_inspect.pipeline import plan_program
from render_inspect.pipeline import simulate as simulate_scene
from render_inspect.scene import load_scene

R_LENS = 1.0
P = 0.19975
A_VIB = 0.00075


def _scene(scenes_dir, n=3, extra=()):
    """The paper's scene cut down to an n x n array (whole array, pixel p / 80)."""
    h = n * P / 2
    over = [f"design.rows={n}", f"design.cols={n}",
            f"simulation.region=[{-h}, {-h}, {h}, {h}]", "artifacts.burrs.height=0.0",
            "material.preset='ideal'"]  # the geometry alone (the material: test_material.py)
    return load_scene(scenes_dir / "sculpt_quad_mla.toml", overrides=over + list(extra))


def test_scene_file_has_the_papers_parameters(scenes_dir):
    s = load_scene(scenes_dir / "sculpt_quad_mla.toml")
    assert s.process.kind == "sculpt"
    assert (s.design.lens_radius, s.design.pitch_x, s.tool.nose_radius) == (1.0, P, 1.0)
    assert s.artifacts.vibration.frequency_hz == 104000 and s.artifacts.vibration.amplitude == A_VIB
    assert s.process.feed_mm_per_min == 100 and s.process.arc_length == 0.0025
    assert 3 <= s.design.rows <= 10


def test_vibration_overcut_on_a_slope_is_amplitude_times_slope():
    slope = 0.1
    plane = Plane(slope_x=0.0, slope_y=slope)
    ys, zs = target_line(plane, 0.0, [0.0, 0.05], step=0.0025)
    grid = np.linspace(0.0, 0.05, 201)
    vc = 100 / 60
    z0 = sculpt_line_profile(ys, zs, grid, cutting_speed=vc)
    zv = sculpt_line_profile(ys, zs, grid, cutting_speed=vc, amplitude=A_VIB, frequency_hz=104e3)
    assert_allclose(z0, slope * grid, atol=1e-12)           # no vibration: the target line
    inner = (grid > 2 * A_VIB) & (grid < 0.05 - 2 * A_VIB)
    # the edge carries the Z of every nominal position in [y - A, y + A]: the lowest wins,
    # up to the advance per vibration period (v_c / f = 16 nm: the front-limit cut lines)
    err = zv[inner] - slope * (grid[inner] - A_VIB)
    assert err.min() > -1e-12 and err.max() <= slope * vc / 104e3 * 1.01


def test_amplitude_zero_removes_the_vibration_overcut(scenes_dir):
    s0 = _scene(scenes_dir, extra=["artifacts.vibration.amplitude=0.0"])
    r0 = simulate_scene(s0)
    r_nofreq = simulate_scene(_scene(scenes_dir, extra=["artifacts.vibration.frequency_hz=0.0"]))
    assert r0.metrics["sculpt"]["vibration_overcut_um"] == 0.0
    assert_allclose(r0.heightmap.machined, r_nofreq.heightmap.machined, rtol=0, atol=0)
    # and what is left is the tool-edge overcut alone
    res = r0.heightmap.machined - r0.heightmap.design
    assert np.nanmin(res) == pytest.approx(-r0.metrics["sculpt"]["tool_edge_overcut_um"] * 1e-3)


def test_papers_theoretical_form_errors(scenes_dir):
    """Seed 003 Fig. 5: vibration overcut within 0.1 um, largest at the edges between
    lenslets; tool-edge overcut 0.025 um at the four-lenslet cusp (R = r = 1 mm)."""
    scene = _scene(scenes_dir)
    res = simulate_scene(scene)
    m = res.metrics["sculpt"]
    # vibration: about A x the largest slope along the cut (5.7 deg), and below 0.1 um
    slope = (P / 2) / math.sqrt(R_LENS ** 2 - (P / 2) ** 2)
    assert m["max_slope_deg"] == pytest.approx(5.76, abs=0.05)
    assert 0.06 < m["vibration_overcut_um"] < 0.1
    assert m["vibration_overcut_um"] == pytest.approx(A_VIB * slope * 1e3, rel=0.03)
    # tool edge: the cusp of four lenslets, closed form
    a = P / 2
    cusp = (R_LENS - math.sqrt(R_LENS ** 2 - 2 * a * a)) - 2 * (R_LENS - math.sqrt(R_LENS ** 2 - a * a))
    assert cusp * 1e3 == pytest.approx(0.025, abs=0.001)
    assert m["tool_edge_overcut_um"] == pytest.approx(cusp * 1e3, abs=0.001)

    # where: separate the two overcuts and locate them
    r0 = simulate_scene(_scene(scenes_dir, extra=["artifacts.vibration.amplitude=0.0"]))
    hm, hm0 = res.heightmap, r0.heightmap
    X, Y = np.meshgrid(hm.x, hm.y)
    edge_over = hm0.design - hm0.machined
    j, i = np.unravel_index(np.nanargmax(edge_over), edge_over.shape)
    # at a cell corner (both coordinates on a cell boundary)
    for v in (X[j, i], Y[j, i]):
        frac = (v / P + 0.5) % 1.0           # 0 on a boundary between cells
        assert min(frac, 1 - frac) < 0.02
    # along the target lines (dx = 0) the edge matches the section exactly
    on_line = np.isclose(X, np.round(X / P) * P, atol=1e-9)     # centres at k P (n odd)
    assert np.nanmax(edge_over[on_line]) < 1e-9
    vib_over = hm0.machined - hm.machined
    rows = np.nanmax(vib_over, axis=1)
    yb = hm.y[np.argmax(rows)]
    frac = (yb / P + 0.5) % 1.0
    assert min(frac, 1 - frac) < 0.03          # on an edge between lenslets along y
    centre_rows = np.abs(((hm.y / P + 0.5) % 1.0) - 0.5) < 0.05    # near cell centres
    assert rows[centre_rows].max() < 0.1 * rows.max()


def test_sculpt_is_deterministic_and_records_the_seed(scenes_dir):
    scene = _scene(scenes_dir, extra=["artifacts.burrs.height=0.0002", "artifacts.burrs.width=0.01",
                                      "simulation.seed=11"])
    a = simulate_scene(scene)
    b = simulate_scene(scene)
    assert_allclose(a.heightmap.machined, b.heightmap.machined, rtol=0, atol=0)
    assert a.metrics["burrs"]["seed"] == 11 and a.heightmap.meta["seed"] == 11
    assert a.metrics["burrs"]["max_added_um"] > 0.1


def test_sculpt_needs_quad_cells(scenes_dir):
    with pytest.raises(SceneError, match="quad"):
        _scene(scenes_dir).with_overrides(
            ['design={type="lenslet_array", cells="round", rows=3, cols=3, pitch_x=0.2, '
             'pitch_y=0.2, lens_radius=1.0, aperture_radius=0.09}'])


def test_clearance_smaller_than_the_slope_is_refused(scenes_dir):
    scene = _scene(scenes_dir, extra=["tool.clearance_angle_deg=5"])
    with pytest.raises(AccessibilityError, match="clearance_angle_deg"):
        simulate_scene(scene)
    ok = simulate_scene(scene.with_overrides(["process.allow_gouge=true"]))
    assert np.isfinite(ok.heightmap.machined).all()


def test_line_profile_bad_input_is_named():
    ys = np.array([0.0, 0.1])
    with pytest.raises(InputError, match="cutting_speed"):
        sculpt_line_profile(ys, ys, ys, cutting_speed=0.0)
    with pytest.raises(InputError, match="amplitude"):
        sculpt_line_profile(ys, ys, ys, cutting_speed=1.0, amplitude=-1.0)
    with pytest.raises(InputError, match="edges"):
        target_line(Plane(), 0.0, [0.1, 0.0], step=0.01)


def test_a_window_matches_the_whole_array(scenes_dir):
    """Simulating a window of the array cuts only the cells that reach it, with the same
    result there as the whole array."""
    full = simulate_scene(_scene(scenes_dir, n=5))
    h = 5 * P / 2
    k = P        # a window from the centre of lenslet (3, 3) to the top-right corner
    win = simulate_scene(_scene(scenes_dir, n=5, extra=[f"simulation.region=[{k}, {k}, {h}, {h}]"]))
    a, b = full.heightmap, win.heightmap
    j0 = int(round((b.origin[1] - a.origin[1]) / a.pixel))
    i0 = int(round((b.origin[0] - a.origin[0]) / a.pixel))
    sub = a.machined[j0:j0 + b.shape[0], i0:i0 + b.shape[1]]
    assert_allclose(b.machined, sub, rtol=0, atol=1e-12)
    assert win.metrics["sculpt"]["target_points"] < full.metrics["sculpt"]["target_points"]


def test_sculpt_program_follows_the_design_along_the_lines(scenes_dir):
    from render_inspect.design import make_surface

    scene = _scene(scenes_dir)
    p = plan_program(scene).program
    prog = {"x": p.x, "y": p.y, "z": p.z, "t": p.t, "line": p.line}
    surf = make_surface(scene.design)
    assert sorted(set(np.round(prog["x"], 9))) == pytest.approx([-P, 0.0, P])
    assert_allclose(prog["z"], surf.height(prog["x"], prog["y"]), atol=1e-15)
    assert np.all(np.diff(prog["t"]) >= 0)
    # each line takes 3 p / v_c at 100 mm/min
    assert prog["t"][-1] == pytest.approx(3 * (3 * P) / (100 / 60))
    # the samples are at most 2.5 um apart and include every cell edge
    for k in range(3):
        y = prog["y"][prog["line"] == k]
        assert np.diff(y).max() <= 0.0025 + 1e-12
        for e in (-1.5 * P, -0.5 * P, 0.5 * P, 1.5 * P):
            assert np.isclose(y, e, atol=1e-12).any()
