"""The clearance plane lies above the design's true highest point, not a sampled one; the
verifier checks every rapid against the design along its move and takes its limits from
the machine and the scene's physics, never from the program it checks.

The hard case is a narrow peak (0.3 mm high, 0.7 um wide) between the samples of any
grid: a clearance plane set from 257^2 samples of the design lay 0.2 mm below it."""

from __future__ import annotations

import json

import numpy as np
import pytest

from render_inspect.design import ExpressionSurface, make_surface, max_height
from render_inspect.design import height_interval
from render_inspect.errors import InputError
from render_inspect.io import program_blocks
from render_inspect.pipeline import plan_program, run_toolpath
from render_inspect.processes import process_of
from render_inspect.scene import load_scene
from render_inspect.toolpath import PartModel, plan_links, verify_blocks

SPIKE = "0.3*exp(-((x-0.6037)**2 + (y-0.0043)**2)/(2*0.0007**2))"
SPIKE_SCENE = f"""
name = "spike"
[design]
type = "expression"
expr = "{SPIKE}"
[tool]
nose_radius = 0.5
[process]
kind = "sts"
spindle_rpm = 50
feed_mm_per_min = 0.5
workpiece_radius = 1.0
points_per_rev = 360
allow_gouge = true
[simulation]
region = [-0.1, -0.1, 0.1, 0.1]
pixel = 0.005
[machine]
preset = "ideal"
[material]
preset = "ideal"
"""


def _spike_scene(tmp_path, *sets):
    p = tmp_path / "spike.toml"
    p.write_text(SPIKE_SCENE)
    return load_scene(str(p), list(sets))


def test_a_grid_misses_the_narrow_peak_the_bound_does_not():
    s = ExpressionSurface(SPIKE)
    u = np.linspace(-1, 1, 257)
    X, Y = np.meshgrid(u, u)
    sampled = float(s.height(X, Y)[X ** 2 + Y ** 2 <= 1].max())
    assert sampled < 0.01  # the case: every sample misses the peak
    b = max_height(s, ("disc", 0.0, 0.0, 1.0), tolerance=1e-6)
    assert b.method == "interval"
    assert 0.3 - 1e-6 <= b.low <= 0.3 <= b.high <= 0.3 + 2e-6


@pytest.mark.parametrize("expr", [
    "x**2 - y**3 + sin(3*x*y)", "exp(-x*x) * cos(5*y) / (2 + x)", "sqrt(x*x + y*y + 1) - abs(x)",
    "tanh(4*x) * cosh(y) + arctan(x - y) - log(3 + x)", "hypot(x, y) * minimum(x, y) + x**0.5",
    "maximum(sin(7*x), cos(11*y)) - (x - 0.1)**-2 * 1e-3", "tan(x) + sinh(y) - log10(2 + y)",
])
def test_the_interval_bound_holds_every_value_in_its_box(expr):
    """Interval arithmetic over the formula: every height at a point of a box lies in the
    box's bound (random boxes, 200 points each)."""
    s = ExpressionSurface(expr)
    rng = np.random.default_rng(7)
    for _ in range(40):
        x0, y0 = rng.uniform(0.2, 1.0, 2)
        w, h = rng.uniform(1e-4, 0.5, 2)
        lo, hi = height_interval(s, x0, y0, x0 + w, y0 + h)
        px = rng.uniform(x0, x0 + w, 200)
        py = rng.uniform(y0, y0 + h, 200)
        try:
            z = s.height(px, py)
        except InputError:
            continue
        assert np.all(z >= lo) and np.all(z <= hi), (expr, x0, y0, w, h)


def test_a_design_without_a_formula_bound_is_bounded_by_a_dense_evaluation_and_its_slope():
    scene = load_scene("sts_mla_2x2")
    s = make_surface(scene.design)
    b = max_height(s, ("disc", 0.0, 0.0, 2.0))
    assert b.method == "dense"
    u = np.linspace(-2, 2, 1601)
    X, Y = np.meshgrid(u, u)
    fine = float(s.height(X, Y)[X ** 2 + Y ** 2 <= 4].max())
    assert b.low <= fine + 1e-12 and fine <= b.high


def test_the_clearance_plane_clears_the_narrow_peak(tmp_path):
    scene = _spike_scene(tmp_path)
    run_toolpath(scene, tmp_path / "o", fmt="nc")
    check = json.loads((tmp_path / "o" / "toolpath.json").read_text())["program_check"]
    top = 0.3 + scene.process.depth_of_cut
    assert check["part_top_mm"] >= top
    assert check["clearance_z_mm"] >= top + scene.process.clearance - 1e-6
    assert check["rapids_above_design_min_mm"] >= scene.process.clearance - 1e-6


def test_a_rapid_over_the_peak_is_refused_along_its_move(tmp_path):
    """With the part's top taken from samples (the old plane), the rapids stay in the
    plane, and only the check along the move sees the peak under them."""
    scene = _spike_scene(tmp_path)
    process = process_of(scene)
    cfg = process.inputs_of(scene)
    surface = make_surface(scene.design)
    plan = plan_program(scene, surface=surface)
    part = process.program_part(cfg, surface, plan)
    sampled = PartModel(part.height, part.outline, stock=part.stock,
                        half_width=part.half_width, bound=part.bound)
    links = plan_links(sampled, program_z=plan.program.z)
    assert links.clearance_z < 0.3  # the plane of samples lies under the peak
    blocks = program_blocks(plan.program, links)
    with pytest.raises(InputError, match="rapid passes .* above the design"):
        verify_blocks(blocks, sampled, process.program_limits(cfg), links, check_cuts=False)


def test_the_verifier_takes_the_plunge_limit_from_the_machine_and_the_cutting_speed(tmp_path):
    base = ["design.rows=3", "design.cols=3"]
    scene = load_scene("sculpt_quad_mla", base + ["process.plunge_feed_mm_per_min=100000"])
    with pytest.raises(InputError, match=r"feed 100000 mm/min over the 3000 mm/min machine"):
        run_toolpath(scene, tmp_path / "a", fmt="nc")
    scene = load_scene("sculpt_quad_mla", base + ["process.plunge_feed_mm_per_min=500"])
    with pytest.raises(InputError, match=r"500 mm/min, over the 100 mm/min of the cutting speed"):
        run_toolpath(scene, tmp_path / "b", fmt="nc")
    assert not (tmp_path / "a").exists() and not (tmp_path / "b").exists()


def test_a_huge_depth_of_cut_cannot_lift_the_plane_past_the_machines_travel(tmp_path):
    scene = _spike_scene(tmp_path, "process.depth_of_cut=1e6")
    with pytest.raises(InputError, match=r"Z 1000000\.\d+ mm outside the travel \[-300, 300\]"):
        run_toolpath(scene, tmp_path / "o", fmt="nc")
    assert not (tmp_path / "o").exists()
