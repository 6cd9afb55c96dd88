"""The fast, tileable kernel of the cutting mechanics against the direct model, its tiles
against the whole grid, its cosine, its row blocks; the planner's loops (z compensation,
kinematics) against their array forms; which maps ``simulate`` tiles."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from numpy.testing import assert_allclose

from render_inspect.core import trig
from render_inspect.design import make_surface
from render_inspect.machining import (Grooves, cut_turning, cut_turning_mechanics, cutting_distance,
                                      finish_surface, follow_turning, machined_edges, plan_tiles,
                                      prepare_cut)
from render_inspect.machining import _envelope_path
from render_inspect.machining._cut_grooves import _COS_ARG_MAX, _cos, _groove_sum
from render_inspect.machining._material import MaterialResponse
from render_inspect.machining import compute_tile
from render_inspect.processes import machine_of, plan_spiral, process_of
from render_inspect.scene import load_scene
from render_inspect.toolpath import Tool, ToolPath
from render_inspect.toolpath._compensation import _GOLD, contact_window, z_compensation
from render_inspect.toolpath._kinematics import axis_derivatives

# The direct (reference) cut and envelope models are compiled on their first call, 15 CPU-s
# each from an empty cache: the files that call them run on one worker under `make test`,
# so each is compiled once per run (the two workers compiled them side by side before).
pytestmark = pytest.mark.xdist_group("direct_models")

SCENES = Path(__file__).resolve().parents[1] / "scenes"
GRID = SCENES / "sts_sinusoidal_grid.toml"
#: the equality the fast kernel keeps with the direct model, relative to the map's heights
REL = 1e-9
#: Al 6082 with a 50 nm edge (the shipped grid's material): h_min, kappa, grooves
H_MIN, KAPPA, GROOVE_RMS = 1.2113e-05, 0.0404, 1e-06


def _followed(region, pixel, overrides=(), machine=True):
    """The shipped grid's program over ``region``, followed by the lathe (or not)."""
    scene = load_scene(GRID, [f"simulation.region={list(region)}", f"simulation.pixel={pixel}", *overrides])
    surface = make_surface(scene.design)
    path = plan_spiral(scene, surface, region=region)
    tool = Tool.from_config(scene.tool)
    if not machine:
        return path, tool
    fp = follow_turning(path.t, path.theta, path.rho, path.z, machine_of(scene.machine), seed=0)
    return ToolPath(fp.theta, fp.rho, fp.z, fp.t), tool


def _direct(path, tool, region, pixel, h_min, kappa, grooves_seed):
    """The direct model: every pixel's passes in a per-pixel loop, then the grooves over the
    whole map (what ``turn`` computed before the fast kernel)."""
    c = cut_turning_mechanics(path, nose_radius=tool.nose_radius, half_width=tool.half_width, region=region,
                              pixel=pixel, h_min=h_min, kappa=kappa)
    th = np.asarray(path.theta)
    along = np.interp(np.nan_to_num(c["pass_theta"], nan=th[0]), th, cutting_distance(th, path.rho))
    resp = MaterialResponse(h_min, kappa, 5e-5, 1.0, GROOVE_RMS, True, (1 - kappa) * h_min, "test")
    m, info = finish_surface(c, resp, along=along, seed=grooves_seed)
    return c, m, info


@pytest.mark.parametrize("region, pixel, overrides, machine", [
    ((-0.05, -0.04, 0.06, 0.05), 0.001, (), True),                                  # across the axis
    ((0.31, -0.2, 0.39, -0.14), 0.0005, (), True),                                  # off axis
    ((0.2, 0.2, 0.28, 0.26), 0.001, ("process.compensation='none'",), True),
    ((-0.03, -0.03, 0.04, 0.03), 0.001, ("process.sampling='constant_arc'",), False),  # not constant-angle
])
def test_fast_cut_equals_the_direct_model(region, pixel, overrides, machine):
    path, tool = _followed(region, pixel, overrides, machine)
    c, m, info = _direct(path, tool, region, pixel, H_MIN, KAPPA, 5)
    cp = prepare_cut(path, nose_radius=tool.nose_radius, half_width=tool.half_width, h_min=H_MIN, kappa=KAPPA)
    fast = cut_turning(cp, Grooves.of(rms=GROOVE_RMS, seed=5), region=region, pixel=pixel, block_samples=2000)
    assert np.array_equal(np.isnan(fast["machined"]), np.isnan(m)) and np.isfinite(m).all()
    scale = np.nanmax(np.abs(m))
    assert np.nanmax(np.abs(fast["machined"] - m)) <= REL * scale
    assert_allclose(fast["pass_theta"], c["pass_theta"], rtol=1e-12)
    assert_allclose(fast["added"], c["added"], rtol=0, atol=REL * scale)
    assert c["added"].max() > 0.5 * (1 - KAPPA) * H_MIN            # side flow did happen
    assert math.sqrt(fast["grooves_sumsq"] / fast["grooves_n"]) * 1e6 == \
        pytest.approx(info["grooves_rms_nm"], rel=1e-9)
    assert int(machined_edges(fast["pass_theta"], jump=math.pi).sum()) == info["edge_pixels"]


def test_fast_cut_beyond_the_path_ends_visits_every_pass():
    # a window wider than the path: pixels outside the outermost pass fall back to every
    # pass that reaches, as in the direct kernel
    region, pixel = (4.95, -0.05, 5.3, 0.05), 0.002
    path, tool = _followed(region, pixel, machine=False)
    c, m, _ = _direct(path, tool, region, pixel, H_MIN, KAPPA, 1)
    cp = prepare_cut(path, nose_radius=tool.nose_radius, half_width=tool.half_width, h_min=H_MIN, kappa=KAPPA)
    fast = cut_turning(cp, Grooves.of(rms=GROOVE_RMS, seed=1), region=region, pixel=pixel)
    assert np.isnan(m).any() and np.isfinite(m).any()
    assert np.array_equal(np.isnan(fast["machined"]), np.isnan(m))
    assert np.nanmax(np.abs(fast["machined"] - m)) <= REL * np.nanmax(np.abs(m))


def test_without_minimum_chip_thickness_the_cut_is_the_geometric_envelope():
    region, pixel = (0.1, 0.1, 0.15, 0.14), 0.0005
    path, tool = _followed(region, pixel)
    cp = prepare_cut(path, nose_radius=tool.nose_radius, half_width=tool.half_width)
    fast = cut_turning(cp, Grooves.none(), region=region, pixel=pixel)
    c = cut_turning_mechanics(path, nose_radius=tool.nose_radius, half_width=tool.half_width, region=region,
                              pixel=pixel)
    assert_allclose(fast["machined"], c["machined"], rtol=0, atol=1e-12)
    assert np.all(fast["added"] == 0) and fast["grooves_n"] == 0


@pytest.fixture(scope="module")
def cut_case():
    region, pixel = (-0.03, -0.025, 0.1, 0.07), 0.0005     # 191 x 261 pixels, across the axis
    path, tool = _followed(region, pixel)
    cp = prepare_cut(path, nose_radius=tool.nose_radius, half_width=tool.half_width, h_min=H_MIN, kappa=KAPPA)
    gr = Grooves.of(rms=GROOVE_RMS, seed=2)
    whole = cut_turning(cp, gr, region=region, pixel=pixel)
    return dict(region=region, pixel=pixel, cp=cp, grooves=gr, whole=whole)


class _Flat:
    def height(self, x, y):
        return np.zeros(np.broadcast(x, y).shape)


def test_cut_without_the_displaced_materials_map_keeps_the_other_maps(cut_case):
    """``keep_added=False``: the machined heights and the passes' angles the same bits, the
    largest displaced material the same, no map of it (two maps given, three refused)."""
    c = cut_case
    w = c["whole"]
    shape = w["machined"].shape
    out = [np.full(shape, 7.0), np.full(shape, 7.0)]
    got = cut_turning(c["cp"], c["grooves"], region=c["region"], pixel=c["pixel"], out=out, keep_added=False)
    assert "added" not in got and got["machined"] is out[0] and got["pass_theta"] is out[1]
    for k in ("machined", "pass_theta"):
        assert np.array_equal(got[k], w[k], equal_nan=True), k
    assert got["added_max"] == w["added_max"] > 0
    with pytest.raises(ValueError, match="2 maps"):
        cut_turning(c["cp"], c["grooves"], region=c["region"], pixel=c["pixel"], out=out + [np.empty(shape)],
                    keep_added=False)


@pytest.mark.parametrize("tile", [64, 128])
def test_cut_tiles_with_their_halo_equal_the_whole_grid(cut_case, tile):
    c = cut_case
    w = c["whole"]
    shape = w["machined"].shape
    sums = {"grooves_sumsq": 0.0, "grooves_n": 0, "edge_pixels": 0, "added_max": -math.inf}
    stride = 7
    coarse = np.full((-(-shape[0] // stride), -(-shape[1] // stride)), np.nan)
    for t in plan_tiles(shape, tile):
        _, m, part = compute_tile(c["cp"], _Flat(), c["region"][:2], c["pixel"], t, grooves=c["grooves"],
                                  shape=shape, stride=stride)
        # bit for bit: each pixel depends only on the path and its position
        assert np.array_equal(m, w["machined"][t.row:t.row + t.rows, t.col:t.col + t.cols], equal_nan=True), t
        for k in ("grooves_sumsq", "grooves_n", "edge_pixels"):
            sums[k] += part[k]
        sums["added_max"] = max(sums["added_max"], part["added_max"])
        i0, j0, a = part["pass_theta"]
        coarse[i0:i0 + a.shape[0], j0:j0 + a.shape[1]] = a
    assert sums["grooves_n"] == w["grooves_n"]
    assert sums["grooves_sumsq"] == pytest.approx(w["grooves_sumsq"], rel=1e-12)
    assert sums["added_max"] == w["added_max"]
    assert sums["edge_pixels"] == int(machined_edges(w["pass_theta"], jump=math.pi).sum())
    assert np.array_equal(coarse, w["pass_theta"][::stride, ::stride], equal_nan=True)


def test_row_blocks_report_progress_and_stop_when_asked(cut_case):
    c = cut_case
    seen = []
    out = cut_turning(c["cp"], c["grooves"], region=c["region"], pixel=c["pixel"], block_samples=5000,
                      progress=lambda done, total: seen.append((done, total)))
    assert np.array_equal(out["machined"], c["whole"]["machined"], equal_nan=True)
    rows = c["whole"]["machined"].shape[0]
    assert len(seen) > 5 and seen[-1] == (rows, rows) and all(a[0] < b[0] for a, b in zip(seen, seen[1:]))

    class Stop(Exception):
        pass

    def stop(done, total):
        if done > total // 2:
            raise Stop

    with pytest.raises(Stop):
        cut_turning(c["cp"], c["grooves"], region=c["region"], pixel=c["pixel"], block_samples=5000,
                    progress=stop)


def _dwell_path(rng):
    """Angles of 3000 uneven steps, about 5 % of them repeated points (a dwell), and their
    lookup table (table, first angle, bin width)."""
    from render_inspect.machining import _envelope_path

    steps = rng.uniform(0.0, 2e-3, 3000)
    steps[rng.random(steps.size) < 0.05] = 0.0          # repeated angles (a dwell)
    theta = np.concatenate([[0.3], 0.3 + np.cumsum(steps)])
    return (theta, *_envelope_path._lookup_table(theta))


def test_one_pass_lookup_serves_every_kernel_and_brackets_the_angle():
    """The envelope's and the cutting kernel's pass lookup are one function; from either
    bin arithmetic it finds the segment holding the angle, on a path with uneven steps and
    repeated points, for angles between points and on them."""
    from render_inspect.machining import _cut_kernel, _cutting, _envelope
    from render_inspect.machining import _envelope_step as step

    # (one Python function; lazy or already made by numba, whichever ran first)
    assert _cut_kernel._lookup_bin.py_func is step._lookup_bin.py_func
    assert _cutting._lookup.py_func is _envelope._lookup.py_func is step._lookup.py_func
    assert not hasattr(_cut_kernel, "_find")
    rng = np.random.default_rng(4)
    theta, tab, t0, w = _dwell_path(rng)
    iw = 1.0 / w
    s_all = np.concatenate([rng.uniform(theta[0], theta[-1], 4000), theta[::7]])
    for s in s_all:
        for i in (step._lookup(theta, tab, t0, w, s), step._lookup_bin(theta, tab, int((s - t0) * iw), s)):
            assert 0 <= i <= theta.size - 2
            assert theta[i] <= s <= theta[i + 1], (s, i)


def test_the_segment_remembered_from_the_previous_pixel_is_the_tables():
    """The cutting kernel looks for a pass's segment first where the same pass was at the
    previous pixel: it finds the table lookup's segment (the same index, which decides a
    pass on a path point) for angles that move a little or far, between points, on them,
    on repeated points and beyond the path's ends, for passes that share a slot."""
    from render_inspect.machining import _cut_kernel
    from render_inspect.machining._envelope_step import _lookup_bin

    rng = np.random.default_rng(5)
    theta, tab, t0, w = _dwell_path(rng)
    iw = 1.0 / w
    seen = np.full(2 * _cut_kernel._SEEN, _cut_kernel._NO_PASS, dtype=np.int64)
    span = theta[-1] - theta[0]
    moves = np.where(rng.random(20_000) < 0.02, rng.uniform(-0.3, 0.3, 20_000),
                     rng.normal(0.0, 1.5e-3, 20_000))
    s_walk = theta[0] + np.mod(0.5 * span + np.cumsum(moves), span)
    on_points = rng.random(s_walk.size) < 0.2
    s_walk[on_points] = theta[rng.integers(0, theta.size, on_points.sum())]
    s_walk[::997] = theta[-1] + 1e-9
    s_walk[::1009] = theta[0] - 1e-9
    passes = rng.choice([-3, 0, 1, 2, 61, 64, 65], s_walk.size)   # 1 and 65, 0 and 64 share a slot
    found = 0
    for s, j in zip(s_walk, passes):
        i = _cut_kernel._segment(theta, tab, t0, iw, s, j, seen)
        assert i == _lookup_bin(theta, tab, int((s - t0) * iw), s), (s, j)
        found += seen[2 * (j % _cut_kernel._SEEN)] == j
    assert found == s_walk.size


def test_the_kernels_cosine_is_numpys_to_the_last_bits():
    """Within 3e-16 of numpy's cosine, over the reduction's whole range: random arguments,
    multiples of pi / 2 (k odd and even, r = +-pi / 2 where cos r is 0) and the arguments
    next to them, small ones, and the largest the kernel allows."""
    rng = np.random.default_rng(0)
    k = np.arange(-40, 41)
    top = np.arange(1, 101) * 4773.0          # multiples of pi near _COS_ARG_MAX
    x = np.concatenate([rng.uniform(-_COS_ARG_MAX, _COS_ARG_MAX, 4000), rng.uniform(-10, 10, 4000),
                        k * (math.pi / 2), np.nextafter(k * (math.pi / 2), np.inf), top * math.pi,
                        (top + 0.5) * math.pi, -(top + 0.5) * math.pi, [_COS_ARG_MAX, -_COS_ARG_MAX, 0.0]])
    got = np.array([_cos(v) for v in x])
    assert np.max(np.abs(got - np.cos(x))) < 3e-16


@pytest.mark.parametrize("modes", [1, 4, 37, 128, 1000])
def test_the_kernels_groove_sum_is_numpys_sum_of_cosines(modes):
    """The kernel's sum of the modes' cosines (one vectorised pass, the terms in any order)
    equals the exact sum of numpy's cosines of numpy's arguments to 2^-52 (sum |cos_i| + 2 n):
    each cosine within 2 eps, the summation within one ulp of sum |cos_i|; for the model's
    128 modes within 2^-52 sum |cos_i| alone.  Arguments to the reduction's limit: a
    rounding of the argument other than numpy's (an FMA) is 1e-11 off there."""
    rng = np.random.default_rng(modes)
    g = Grooves.of(rms=1e-6, seed=modes, modes=modes)
    vmax = 0.95 * _COS_ARG_MAX / np.max(np.abs(g.kv))
    uv = np.concatenate([np.stack([rng.uniform(-0.5, 0.5, 300), rng.uniform(0.0, 1e4, 300)], axis=1),
                         np.stack([rng.uniform(-0.05, 0.05, 300), rng.uniform(-vmax, vmax, 300)], axis=1)])
    for u, v in uv:
        c = np.cos(g.ku * u + g.kv * v + g.ph)
        err = abs(_groove_sum(g.ku, g.kv, g.ph, u, v) - math.fsum(c))
        bound = 2.0 ** -52 * (np.sum(np.abs(c)) + (0 if modes == 128 else 2 * modes))
        assert err <= bound, (u, v, err, bound)


def test_the_kernels_grooves_are_those_of_groove_texture():
    from render_inspect.machining import groove_texture

    rng = np.random.default_rng(3)
    u, v = rng.uniform(-0.1, 0.1, 500), rng.uniform(0.0, 500.0, 500)
    g = Grooves.of(rms=2e-6, seed=9, across_length=0.002, along_length=0.1)
    ref = groove_texture(u, v, rms=2e-6, seed=9, across_length=0.002, along_length=0.1)
    mine = np.array([sum(np.cos(g.ku * a + g.kv * b + g.ph)) for a, b in zip(u, v)]) * g.scale
    assert_allclose(mine, ref, rtol=0, atol=1e-18)


# ---- the planner's loops ----------------------------------------------------------------
def _z_compensation_arrays(surface, theta, rho, Rc, *, max_slope, half_width, samples=9):
    """z_compensation as it was written on arrays (the reference of the loops)."""
    w = contact_window(Rc, max_slope, half_width)
    offs = np.linspace(-w, w, samples)
    step = offs[1] - offs[0]
    iterations = max(4, int(math.ceil(math.log(math.sqrt(2e-10 * Rc) / (2 * step)) / math.log(_GOLD))))
    cs, sn = trig.cos_sin(theta)  # (the angles' cosines as the package takes them)

    def gfun(d):
        u = rho + d
        return surface.height(u * cs, u * sn) - (Rc - np.sqrt(Rc * Rc - d * d))

    g = np.stack([gfun(o) for o in offs], axis=1)
    k = np.argmax(g, axis=1)
    best = g[np.arange(g.shape[0]), k]
    lo, hi = np.maximum(offs[k] - step, -w), np.minimum(offs[k] + step, w)
    c, d = hi - _GOLD * (hi - lo), lo + _GOLD * (hi - lo)
    gc, gd = gfun(c), gfun(d)
    for _ in range(iterations):
        left = gc > gd
        hi = np.where(left, d, hi)
        lo = np.where(left, lo, c)
        c_new = np.where(left, hi - _GOLD * (hi - lo), d)
        d_new = np.where(left, c, lo + _GOLD * (hi - lo))
        ge = gfun(np.where(left, c_new, d_new))
        gc, gd = np.where(left, ge, gd), np.where(left, gc, ge)
        c, d = c_new, d_new
    return np.maximum(best, np.maximum(gc, gd))


@pytest.mark.parametrize("scene", ["sts_sinusoidal_grid", "compound_sinusoid", "sts_mla_2x2"])
def test_z_compensation_loops_equal_the_array_form(scene):
    s = load_scene(SCENES / f"{scene}.toml")
    surface = make_surface(s.design)
    rng = np.random.default_rng(1)
    theta = np.sort(rng.uniform(0, 3000, 70_000))          # two chunks, on two threads
    rho = rng.uniform(0.0, 3.0, theta.size)
    kw = dict(max_slope=surface.max_slope((-3.6, -3.6, 3.6, 3.6)), half_width=0.5 * s.tool.nose_radius)
    got = z_compensation(surface, theta, rho, s.tool.nose_radius, **kw)
    assert np.array_equal(got, _z_compensation_arrays(surface, theta, rho, s.tool.nose_radius, **kw))


@pytest.mark.parametrize("t", [np.cumsum(np.random.default_rng(0).uniform(0.5, 1.5, 500)),
                               np.arange(500) * 0.25])
def test_kinematics_loops_equal_numpys_differences(t):
    q = np.sin(t) + np.random.default_rng(1).normal(size=t.size)
    v, a, j = axis_derivatives(t, q)
    assert np.array_equal(v, np.gradient(q, t, edge_order=2))
    h1, h2 = t[1:-1] - t[:-2], t[2:] - t[1:-1]
    want = 2.0 * (h1 * q[2:] - (h1 + h2) * q[1:-1] + h2 * q[:-2]) / (h1 * h2 * (h1 + h2))
    assert np.array_equal(a[1:-1], want) and a[0] == a[1] and a[-1] == a[-2]
    assert np.array_equal(j, np.gradient(a, t, edge_order=1))
    from render_inspect.toolpath import kinematics

    k = kinematics(ToolPath(np.cumsum(np.full(t.size, 0.01)), q, np.cos(t), t))
    s = np.sign(v[np.abs(v) > 1e-12])
    assert k["x_reversals"] == np.count_nonzero(s[1:] != s[:-1]) > 10
    assert k["x_velocity_max_mm_s"] == np.max(np.abs(v)) and k["x_jerk_max_mm_s3"] == np.max(np.abs(j))


# ---- which maps simulate tiles ------------------------------------------------------------
@pytest.mark.parametrize("scene", ["sts_sinusoidal_grid", "hts_toric_msa", "rcse_circular_array",
                                   "compound_sinusoid", "sts_mla_2x2", "sts_fig16_overcut"])
def test_every_shipped_turning_scene_is_tiled_at_whole_part_size(scene):
    from render_inspect.pipeline import TILED_SAMPLES, wants_tiles

    s = load_scene(SCENES / f"{scene}.toml")
    r = s.process.workpiece_radius
    assert process_of(s).tile_refusal(process_of(s).inputs_of(s)) is None
    whole = s.with_overrides([f"simulation.region={[-r, -r, r, r]}", "simulation.max_memory_gb=1000"])
    ny, nx = whole.simulation.shape
    assert wants_tiles(whole) == (ny * nx > TILED_SAMPLES)
    assert not wants_tiles(s)                     # the shipped window runs in memory
    assert wants_tiles(whole.with_overrides(["simulation.max_memory_gb=0.01"]))


def test_a_process_without_a_tiled_simulation_refuses_in_one_line(tmp_path, capsys, monkeypatch):
    """The sculpting process has no tiled simulation: its steps refuse with the user's
    line (an InputError naming process.kind), and ``simulate --tiled`` exits 1 with it."""
    from render_inspect.cli import main
    from render_inspect.core.errors import InputError

    s = load_scene(SCENES / "sculpt_quad_mla.toml")
    proc = process_of(s)
    cfg = proc.inputs_of(s)
    refusal = proc.tile_refusal(cfg)
    assert "process.kind = 'sculpt' has no tiled simulation" in refusal
    with pytest.raises(InputError, match="has no tiled simulation"):
        proc.tiled_memory(cfg)
    with pytest.raises(InputError, match="has no tiled simulation"):
        proc.envelope(cfg, None, None)
    assert main(["simulate", str(SCENES / "sculpt_quad_mla.toml"), "--tiled",
                 "--out", str(tmp_path / "out")]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "has no tiled simulation" in err[0], err
    assert not (tmp_path / "out").exists()
    # a process that says it tiles but lacks a step: its author is told what to add
    monkeypatch.setattr(type(proc), "tile_refusal", lambda self, cfg: None)
    with pytest.raises(TypeError, match=r"must define tiled_memory\(\)"):
        proc.tiled_memory(cfg)


@pytest.mark.slow
def test_simulate_tiles_the_shipped_scene_as_it_runs_in_memory(tmp_path):
    """The shipped grid (lathe, Al 6082) cut tile by tile: the same heights and the same
    facts of the machine and the material as in memory, and the following-error figures."""
    import json
    import subprocess
    import sys

    from render_inspect.io import ZarrHeightMap, read_exr

    def cli(*args):
        return subprocess.run([sys.executable, "-m", "render_inspect.cli", "simulate", str(GRID), *args,
                               "--set", "simulation.region=[-0.2,-0.15,0.22,0.2]", "-q"],
                              capture_output=True, text=True, check=True)

    cli("--out", str(tmp_path / "mem"))
    cli("--out", str(tmp_path / "tiled"), "--tiled", "--tile", "128")
    a, b = (json.loads((tmp_path / d / "metrics.json").read_text()) for d in ("mem", "tiled"))
    assert b["machine"] == a["machine"] and b["following_error"] == a["following_error"]
    assert b["material"].keys() == a["material"].keys()
    for k, v in a["material"].items():
        assert b["material"][k] == (pytest.approx(v, rel=1e-12) if isinstance(v, float) else v), k
    for k in ("Sq_nm", "Sz_nm", "min_nm", "mean_nm"):
        assert b["residual"][k] == pytest.approx(a["residual"][k], rel=1e-12), k
    assert b["tiles"]["count"] == 12
    ch, _ = read_exr(tmp_path / "mem" / "heightmap.exr")
    assert np.array_equal(ZarrHeightMap(tmp_path / "tiled" / "heightmap.zarr").read("machined"), ch["machined"],
                          equal_nan=True)
    names = {f.name for f in (tmp_path / "tiled").iterdir()}
    assert {"following_error.png", "following_error_map.png", "kinematics.png"} <= names


def _radial_slope_arrays(theta, rho, z):
    """:func:`path_radial_slope` as numpy array expressions (its definition)."""
    k = np.searchsorted(theta, theta + _envelope_path.TWO_PI)
    ok = k < theta.size
    i = np.flatnonzero(ok)
    k = k[ok]
    k0 = np.maximum(k - 1, 0)
    dt = theta[k] - theta[k0]
    fr = np.where(dt > 0, (theta[i] + _envelope_path.TWO_PI - theta[k0]) / np.where(dt > 0, dt, 1), 0.0)
    dr = np.abs(rho[k0] + fr * (rho[k] - rho[k0]) - rho[i])
    dz = np.abs(z[k0] + fr * (z[k] - z[k0]) - z[i])
    good = dr > 0
    return float(np.max(dz[good] / dr[good])) if good.any() else 0.0


def test_the_paths_radial_slope_in_one_merge_equals_the_array_form():
    # uneven steps, repeated angles (dwells), a NaN height, a path that ends inside its
    # first revolution's reach: the merge gives the array form's value to the last bit
    rng = np.random.default_rng(11)
    for trial in range(300):
        n = int(rng.integers(3, 600))
        theta = np.sort(rng.uniform(0.0, rng.uniform(1.0, 80.0), n))
        if trial % 3 == 0:
            theta = np.round(theta, 1)
        rho = rng.normal(size=n)
        z = rng.normal(size=n)
        if trial % 17 == 0:
            z[rng.integers(n)] = np.nan
        with np.errstate(invalid="ignore"):
            got = _envelope_path.path_radial_slope(theta, rho, z)
            want = _radial_slope_arrays(theta, rho, z) if theta[-1] - theta[0] > _envelope_path.TWO_PI else 0.0
        assert got == want or (np.isnan(got) and np.isnan(want)), trial
    # the planned path of the shipped grid scene, followed by its lathe
    path, _ = _followed((0.2, 0.2, 0.3, 0.3), 0.001)
    th, rh, zz = (np.asarray(a, dtype=np.float64) for a in (path.theta, path.rho, path.z))
    assert _envelope_path.path_radial_slope(th, rh, zz) == _radial_slope_arrays(th, rh, zz) > 0
    # angles that go back (not a turning path's): the array form itself
    back = np.array([0.0, 3.0, 2.0, 9.0, 12.0, 20.0])
    vals = rng.normal(size=(2, back.size))
    assert _envelope_path.path_radial_slope(back, *vals) == _radial_slope_arrays(back, *vals)


def _heights_at_brute(theta, z, s):
    """Every height the path has at angle s: its points' there, else the interpolation."""
    at = z[theta == s]
    return at if at.size else np.array([np.interp(s, theta, z)])


def test_the_paths_revolution_step_is_the_least_and_largest_change_at_any_angle():
    # uneven steps, many revolutions or barely more than one, dwells (repeated angles, the
    # path then has several heights at one angle): the values are the least and the
    # largest z(s + 2 pi) - z(s) over every angle and every height there (z linear between
    # points), found by brute force at the points, one revolution from them and between
    rng = np.random.default_rng(12)
    two_pi = _envelope_path.TWO_PI
    for trial in range(200):
        n = int(rng.integers(3, 300))
        theta = np.cumsum(rng.uniform(0.01, 1.0, n)) * rng.uniform(0.2, 3.0)
        if trial % 4 == 0:  # dwells: some angles repeated
            theta = np.sort(np.concatenate([theta, rng.choice(theta, size=max(1, n // 10))]))
        z = rng.normal(size=theta.size) * 10.0 ** rng.uniform(-6, 0)
        if trial % 5 == 1:  # heights that fall by about a step each revolution
            z = z * 0.1 - 0.5 * theta * np.abs(z).max()
        got = _envelope_path.path_revolution_step(theta, z)
        if theta[-1] - theta[0] <= two_pi:
            assert got == (0.0, 0.0), trial
            continue
        lo, hi = theta[0], theta[-1] - two_pi
        s = np.concatenate([theta, theta - two_pi, np.linspace(lo, hi, 10 * theta.size)])
        s = np.unique(s[(s >= lo) & (s <= hi)])
        diffs = [np.subtract.outer(_heights_at_brute(theta, z, v + two_pi), _heights_at_brute(theta, z, v))
                 for v in s]
        want = (min(d.min() for d in diffs), max(d.max() for d in diffs))
        tol = 1e-12 * np.abs(z).max()
        assert abs(got[0] - want[0]) <= tol and abs(got[1] - want[1]) <= tol, trial
    # heights that fall 3 um a revolution: -3 um both
    th = np.linspace(0.0, 30.0, 50)
    assert _envelope_path.path_revolution_step(th, -0.003 * th / two_pi) == pytest.approx((-0.003, -0.003), rel=1e-12)
    # a dwell that drops 1 um at one angle: the revolution before it sees both heights
    th2 = np.r_[th[:20], th[19], th[20:]]
    z2 = np.r_[np.zeros(20), -0.001 * np.ones(th.size - 19)]
    assert _envelope_path.path_revolution_step(th2, z2) == pytest.approx((-0.001, 0.0), abs=1e-15)
    # angles that go back, a height that is not finite: unknown
    z = np.sin(th)
    for bad_th, bad_z in ((th[::-1].copy(), z), (th, np.r_[z[:-1], np.nan])):
        assert _envelope_path.path_revolution_step(bad_th, bad_z) == (-math.inf, math.inf)


@pytest.mark.parametrize("variant", ["plain", "across the axis", "worn", "edge", "no side flow", "NaN heights"])
def test_the_kernels_pass_proofs_change_no_pixel(variant):
    # the kernel skips passes it proves change nothing, from the path's least and largest
    # change of height per revolution (z_rev): on the shipped grid's program followed by its lathe
    # every map equals, bit for bit, the kernel that looks up every pass of the window
    # (z_rev unknown)
    from dataclasses import replace

    from render_inspect.toolpath import EdgeProfile

    region = (-0.03, -0.02, 0.03, 0.02) if variant == "across the axis" else (0.31, -0.05, 0.37, -0.01)
    pixel = 0.0005
    path, tool = _followed(region, pixel)
    if variant == "NaN heights":
        z = np.array(path.z, dtype=np.float64)
        z[z.size // 3] = np.nan
        path = ToolPath(path.theta, path.rho, z, path.t)
    kw = dict(nose_radius=tool.nose_radius, half_width=tool.half_width, h_min=H_MIN, kappa=KAPPA)
    if variant == "worn":
        th = np.asarray(path.theta)
        kw["h_min_points"] = H_MIN * (1.0 + 3.0 * (th - th[0]) / (th[-1] - th[0]))
    if variant == "edge":
        kw["edge"] = EdgeProfile.from_harmonics([(40.0, 25.0, 10.0)])
    if variant == "no side flow":
        kw["side_flow"] = False
    cp = prepare_cut(path, **kw)
    if variant == "NaN heights":
        assert cp.z_rev == (-math.inf, math.inf)
        return
    assert -1e-3 < cp.z_rev[0] <= cp.z_rev[1] < 1e-3 and cp.z_rev[1] > 0
    grooves = Grooves.of(rms=GROOVE_RMS, seed=3)
    proved = cut_turning(cp, grooves, region=region, pixel=pixel)
    every = cut_turning(replace(cp, z_rev=(-math.inf, math.inf)), grooves, region=region, pixel=pixel)
    for k in ("machined", "pass_theta", "added"):
        assert np.array_equal(proved[k], every[k], equal_nan=True), k
    assert proved["grooves_sumsq"] == every["grooves_sumsq"] and proved["added_max"] == every["added_max"]


@pytest.mark.parametrize("amplitude, dwells", [(2e-5, False), (5e-5, False), (2e-4, False), (5e-5, True)])
def test_the_pass_proofs_hold_where_heights_flip_each_revolution(amplitude, dwells):
    # heights that swing +-A with 2.5 waves a revolution: at one angle the next revolution
    # is 2 A away (z_rev = +-2 A), so passes further out can cut; the proofs keep every
    # pixel, and half those changes pixels (the proofs skip passes here, and no more than
    # they may).  With dwells: every 97th point repeated 0.5 A higher
    from dataclasses import replace

    f, r0 = 0.005, 0.4
    th = np.linspace(0.0, r0 / f * 2 * math.pi, int(r0 / f * 720) + 1)
    z = amplitude * np.cos(2.5 * th)
    rho = r0 - f * th / (2 * math.pi)
    if dwells:
        at = np.arange(5, th.size - 5, 97)
        th, rho = np.insert(th, at, th[at]), np.insert(rho, at, rho[at])
        z = np.insert(z, at, z[at] + 0.5 * amplitude)
    path = ToolPath(th, rho, z, th)
    region, pixel = (0.1, -0.02, 0.16, 0.02), 0.0005
    cp = prepare_cut(path, nose_radius=0.5, half_width=0.25, h_min=1e-5, kappa=0.05)
    lo, hi = cp.z_rev
    assert (lo, hi) == pytest.approx((-2 * amplitude, 2 * amplitude), rel=1e-6) or \
        (dwells and -3 * amplitude < lo <= -2 * amplitude and 2 * amplitude <= hi < 3 * amplitude)
    every = cut_turning(replace(cp, z_rev=(-math.inf, math.inf)), Grooves.none(), region=region, pixel=pixel)
    proved = cut_turning(cp, Grooves.none(), region=region, pixel=pixel)
    for k in ("machined", "pass_theta", "added"):
        assert np.array_equal(proved[k], every[k], equal_nan=True), k
    wrong = cut_turning(replace(cp, z_rev=(lo / 2, hi / 2)), Grooves.none(), region=region, pixel=pixel)
    assert np.sum(wrong["machined"] != every["machined"]) > 100


def test_the_pass_window_by_multiplications_is_the_windows():
    # the pass numbers of the window's ends, formed with 1 / cc, are those of the division
    # (random spirals up to 1e5 rad; ends placed on a whole pass and 1e-12 of one beside it)
    from render_inspect.machining._cut_window import _window, _window_near

    rng = np.random.default_rng(21)
    for trial in range(20000):
        cc = 10.0 ** rng.uniform(-5, -1)
        t_first = rng.uniform(-10.0, 10.0)
        t_last = t_first + 10.0 ** rng.uniform(0, 5)
        a = cc * (t_last - t_first) * rng.uniform(0.5, 1.0)
        r = rng.uniform(0.0, a)
        W = 10.0 ** rng.uniform(-4, -1)
        phi = rng.uniform(0.0, 2 * math.pi)
        if trial % 3 == 1:  # the window's outer end on a whole pass (and beside it)
            s_lo = t_first + (a - (r + W)) / cc
            phi = s_lo - 2 * math.pi * math.floor((s_lo - t_first) / (2 * math.pi)) + rng.choice([0.0, 1e-12, -1e-12])
        want = _window(t_first, t_last, a, cc, phi, r, 1.0, W)
        assert _window_near(t_first, t_last, a, cc, 1.0 / cc, phi, r, W) == want, trial
    # the nearness test at its bound: the first end at pass k + d, d from 0 (on the pass)
    # through 1e-6 of it (either side) to far from it, for negative and large k too (a
    # window clipped by the path's ends)
    cc = 0.01 / (2 * math.pi)
    t_first, a = 0.0, 5.0
    t_last = a / cc * 0.999
    near = (0.0, 1e-15, -1e-15, 1e-12, -1e-12, 1e-9, -1e-9, 1e-7, -1e-7, 1e-6, -1e-6, 1.0000001e-6,
            -1.0000001e-6, 0.3, -0.3, 0.5)
    for _ in range(400):
        phi = rng.uniform(0.0, 2 * math.pi)
        W = rng.uniform(0.001, 0.05)
        k = int(rng.integers(-3, 500))
        for d in near:
            r = a - W - (2 * math.pi * (k + d) + phi - t_first) * cc
            for rr in (r, r + 1e-13, r - 1e-13):
                want = _window(t_first, t_last, a, cc, phi, rr, 1.0, W)
                assert _window_near(t_first, t_last, a, cc, 1.0 / cc, phi, rr, W) == want, (phi, rr, W, d)

