"""A simulation of a window plans each revolution in full only over the sector that reaches
it: the points it keeps are the whole-revolution plan's, bit for bit; what the machine
follows and the material cuts in the window is the same to rounding (the servo loops'
transient after the sparse program between the sectors decays within the lead); regions
that hold the spindle axis, the revolution-mean split and programs to write out keep whole
revolutions."""

from __future__ import annotations

import math

import numpy as np
import pytest

from render_inspect.design import make_surface
from render_inspect.machining import Axis, follow_axis, machine_preset, settle_time, window_margins
from render_inspect.machining._axes import SETTLE_DECAY
from render_inspect.pipeline._simulate import simulate
from render_inspect.processes import process_of
from render_inspect.processes._contract import Process
from render_inspect.processes._turning import TurningProcess
from render_inspect.scene import load_scene
from render_inspect.toolpath import Tool, plan_turning, sector_plan

#: max |dz| (mm) between a window cut from its sectors and from whole revolutions: rounding
#: of heights of a few um (the loops' transient has decayed by 2^-60)
ROUNDING_MM = 1e-15


def _plans(name, over, region):
    scene = load_scene(name, [f"simulation.region={list(region)}"] + over)
    proc = process_of(scene)
    cfg = proc.inputs_of(scene)
    surface = make_surface(scene.design)
    return [proc.plan(cfg, surface, region=tuple(region), sectors=s) for s in (False, True)]


def test_sector_points_are_the_whole_revolution_plan_points_bit_for_bit():
    whole, sec = _plans("sts_fig16_overcut", [], (1.0, 1.0, 1.25, 1.25))
    a, b = whole.program, sec.program
    assert b.points < 0.35 * a.points
    i = np.searchsorted(a.theta, b.theta)
    for k in ("theta", "rho", "z", "t", "ccp_z"):
        assert np.array_equal(getattr(a, k)[i], getattr(b, k)), k
    info = b.meta["sectors"]
    assert info["points_whole_revolutions"] == a.points and info["points_kept"] == b.points
    # the same revolutions, first and last point included
    assert b.theta[0] == a.theta[0] and b.theta[-1] == a.theta[-1]
    # every point of the window's sector (and the lead before it) is kept
    omega = 2 * math.pi * 50 / 60
    a0, a1 = info["sector_rad"]
    lead = info["lead_s"] * omega
    inside = np.mod(a.theta - (a0 - lead), 2 * math.pi) <= (a1 - a0) + lead
    assert np.isin(a.theta[inside], b.theta).all()
    # the window's corners lie inside the sector
    for x, y in ((1.0, 1.0), (1.25, 1.0), (1.0, 1.25), (1.25, 1.25)):
        assert a0 < math.atan2(y, x) < a1
    # the facts of the sectors' own segments: no chord between the sectors counts
    assert b.meta["chordal_error_max_mm"] <= a.meta["chordal_error_max_mm"]


def test_regions_holding_the_axis_the_fts_split_and_normal_compensation_keep_whole_revolutions():
    whole, sec = _plans("sts_fig16_overcut", [], (-0.3, -0.3, 0.3, 0.3))
    assert "sectors" not in sec.program.meta
    assert np.array_equal(whole.program.z, sec.program.z)
    # fts: the slow slide's share is the mean over whole revolutions
    over = ["process.kind='fts'", "process.workpiece_radius=1.4"]
    whole, sec = _plans("hts_toric_msa", over, (0.55, 0.55, 0.95, 0.95))
    assert "sectors" not in sec.program.meta and sec.program.points == whole.program.points
    whole, sec = _plans("sts_fig16_overcut", ["process.compensation='normal'"], (1.0, 1.0, 1.25, 1.25))
    assert "sectors" not in sec.program.meta and sec.program.points == whole.program.points


def test_sector_plan_refuses_sectors_that_keep_most_points():
    theta = np.arange(0, 20 * 2 * math.pi, 2 * math.pi / 360)
    keep, _ = sector_plan(theta, (1.0, 1.0, 1.2, 1.2), 0.05, lead_rad=0.1, lag_rad=0.0)
    assert keep is not None and keep.mean() < 0.25
    assert sector_plan(theta, (1.0, 1.0, 1.2, 1.2), 0.05, lead_rad=5.0, lag_rad=0.0)[0] is None
    assert sector_plan(theta, (-1.0, -1.0, 1.2, 1.2), 0.05, lead_rad=0.1, lag_rad=0.0)[0] is None


def test_a_different_command_before_the_settle_time_leaves_no_trace_after_it():
    """Two commands that differ (by a stroke of 5 um) only before t_s: the followed
    positions after t_s + settle_time differ by less than SETTLE_DECAY times the difference
    the stroke caused, to rounding; the disturbance is the same draw."""
    rate = 20_000.0
    t = np.linspace(0.0, 1.0, 10001)
    q = 1e-3 * np.sin(2 * np.pi * 37 * t)
    q2 = q.copy()
    ts = 0.1
    q2[t < ts] += 5e-3 * np.sin(2 * np.pi * 211 * t[t < ts])
    for ax in (machine_preset("sts_lathe").z, machine_preset("fts").fts,
               Axis(bandwidth_hz=30.0, damping=1.5, noise_rms=1e-6)):
        a = follow_axis(t, q, ax, rate_hz=rate, seed=4)
        b = follow_axis(t, q2, ax, rate_hz=rate, seed=4)
        d = np.abs(a.followed - b.followed)
        early = d[(a.t > ts - 0.02) & (a.t < ts)].max()
        assert early > 1e-6  # the stroke did move the axis
        late = d[a.t > ts + settle_time(ax)]
        assert late.size and late.max() <= max(SETTLE_DECAY * early, 1e-18), (ax, late.max())


def test_window_margins_cover_the_slide_and_servo_loops():
    m = machine_preset("fts")
    lead, lag = window_margins(m)
    assert lead == pytest.approx(max(settle_time(m.z), settle_time(m.fts)))
    assert lag == pytest.approx(2 / m.servo_rate_hz)
    late = m.with_overrides({"fts_sync_delay_s": 0.0013})
    assert window_margins(late)[0] == pytest.approx(lead + 0.0013)
    assert window_margins(machine_preset("ideal")) == (0.0, 2 / 10_000.0)


def _simulate_both(monkeypatch, name, over):
    out = []
    for sectors in (False, True):
        if sectors:
            monkeypatch.undo()
        else:
            monkeypatch.setattr(TurningProcess, "plan_window", Process.plan_window)
        out.append(simulate(load_scene(name, over)))
    return out


@pytest.mark.parametrize("name, over", [
    ("sts_fig16_overcut", ["simulation.region=[1.0,1.0,1.2,1.2]", "simulation.pixel=0.002",
                           "process.workpiece_radius=1.8"]),
    ("hts_toric_msa", ["simulation.region=[0.55,0.55,0.8,0.8]", "simulation.pixel=0.005",
                       "process.workpiece_radius=1.2"]),
])
def test_a_window_cut_from_its_sectors_is_the_window_cut_from_whole_revolutions(monkeypatch, name, over):
    """The shipped machines (servo noise, error motions, the X slide's reaction force, the
    FTS synchronised to the spindle) and materials (grooves, texture, burrs)."""
    whole, sec = _simulate_both(monkeypatch, name, over)
    assert "sectors" in sec.plan.program.meta and "sectors" not in whole.plan.program.meta
    a, b = whole.heightmap.machined, sec.heightmap.machined
    assert np.array_equal(np.isnan(a), np.isnan(b))
    assert np.nanmax(np.abs(a - b)) < ROUNDING_MM
    # the same servo ticks, fewer planned points
    mw, ms = whole.metrics, sec.metrics
    assert mw["machine"]["ticks"] == ms["machine"]["ticks"]
    # the Z slide (and the FTS) followed over the sectors' ticks only
    assert "ticks_in_sectors" not in mw["machine"]
    assert ms["machine"]["ticks_in_sectors"] < 0.6 * ms["machine"]["ticks"]
    assert ms["toolpath"]["points"] < 0.5 * mw["toolpath"]["points"]
    assert ms["residual"]["Sq_nm"] == pytest.approx(mw["residual"]["Sq_nm"], rel=1e-12)
    fe = ms["following_error"]
    assert all(math.isfinite(v) for v in fe.values()) and fe["z_rms_nm"] > 0


def test_the_ideal_machine_cuts_the_same_window_from_its_sectors(monkeypatch):
    over = ["simulation.region=[1.0,1.0,1.2,1.2]", "simulation.pixel=0.002",
            "process.workpiece_radius=1.8", "machine.preset='ideal'", "material.preset='ideal'"]
    whole, sec = _simulate_both(monkeypatch, "sts_fig16_overcut", over)
    a, b = whole.heightmap.machined, sec.heightmap.machined
    # (the envelope of the program's own points: on whole revolutions their angles are a
    # uniform grid, looked up by division; in sectors by the table: rounding apart)
    assert np.array_equal(np.isnan(a), np.isnan(b)) and np.nanmax(np.abs(a - b)) < ROUNDING_MM


def test_a_program_to_write_out_keeps_whole_revolutions():
    """The toolpath command plans a servo process's region as a program to write: never
    in sectors."""
    from render_inspect.pipeline._toolpath import plan_program

    scene = load_scene("hts_toric_msa", ["simulation.region=[0.55,0.55,0.8,0.8]",
                                         "process.workpiece_radius=1.2"])
    plan = plan_program(scene)
    assert "sectors" not in plan.program.meta
    tool = Tool.from_config(scene.tool)
    assert plan.program.points == plan_turning(
        make_surface(scene.design), tool, workpiece_radius=1.2,
        feed_per_rev=scene.process.feed_per_rev, spindle_rpm=scene.process.spindle_rpm,
        compensation=scene.process.compensation, sampling=scene.process.sampling,
        points_per_rev=scene.process.points_per_rev, arc_length=scene.process.arc_length,
        switch_radius=scene.process.switch_radius, inner_radius=scene.process.inner_radius,
        chordal_tolerance=scene.process.chordal_tolerance,
        region=(0.55, 0.55, 0.8, 0.8), check_access=False).points


def test_an_axis_followed_over_runs_is_the_axis_followed_over_every_tick_after_the_lead():
    """follow_axis with ``runs``: inside each run, after settle_time, the followed path of
    the whole program to rounding (the same disturbance draw); outside, the program."""
    rate = 5000.0
    t = np.linspace(0.0, 3.0, 3001)
    q = 1e-3 * np.sin(2 * np.pi * 3.1 * t) + 0.01 * t
    ax = machine_preset("sts_lathe").z
    whole = follow_axis(t, q, ax, rate_hz=rate, seed=9)
    runs = np.array([[1000, 3000], [6000, 9000], [12000, 15001]])
    part = follow_axis(t, q, ax, rate_hz=rate, seed=9, runs=runs)
    assert np.array_equal(part.t, whole.t)
    lead = int(math.ceil(settle_time(ax) * rate))
    for a, b in runs:
        d = np.abs(part.followed[a + lead:b] - whole.followed[a + lead:b])
        assert d.max() < 1e-18
        assert np.abs(part.followed[a:a + 20] - whole.followed[a:a + 20]).max() > 1e-9
    out = np.ones(part.t.size, dtype=bool)
    for a, b in runs:
        out[a:b] = False
    assert np.array_equal(part.followed[out], np.interp(part.t[out], t, q))
    assert np.all(part.error[out] == 0)


def test_the_kinematics_of_a_windowed_program_are_those_of_its_sectors():
    """The joins between the sectors and the sparse points between them are not the
    program's motion: the Z jerk and acceleration of the sectors' own points stay within
    those of whole revolutions."""
    from render_inspect.processes._turning import toolpath_facts

    scene = load_scene("sts_fig16_overcut", ["simulation.region=[1.0,1.0,1.25,1.25]"])
    whole, sec = _plans("sts_fig16_overcut", [], (1.0, 1.0, 1.25, 1.25))
    kw, ks = (toolpath_facts(p.program, scene.process) for p in (whole, sec))
    for k in ("z_jerk_max_mm_s3", "z_acceleration_max_mm_s2", "z_velocity_max_mm_s",
              "x_velocity_max_mm_s", "c_velocity_max_rad_s"):
        assert 0 < ks[k] <= kw[k] * (1 + 1e-9), k
    assert ks["sectors"]["points_kept"] == sec.program.points


def test_the_compiled_pvt_command_is_the_array_formula_bit_for_bit():
    """The interpolator's compiled pass gives the numbers of the array expressions it
    replaced, to the bit (the shipped scenes' results do not move)."""
    from render_inspect.machining import pvt_command
    from render_inspect.machining._interpolate import _segments, pvt_velocities

    rng = np.random.default_rng(3)
    for scale in (1e-6, 1e-3, 1.0, 50.0):
        t = np.cumsum(rng.uniform(1e-4, 1e-2, 3000))
        q = rng.normal(size=t.size) * scale
        tk = np.sort(np.concatenate([rng.uniform(t[0], t[-1], 20000), t[::7]]))
        v = pvt_velocities(t, q)
        i = _segments(t, tk)
        h = t[i + 1] - t[i]
        s = (tk - t[i]) / h
        q0, q1, m0, m1 = q[i], q[i + 1], v[i] * h, v[i + 1] * h
        s2 = s * s
        s3 = s2 * s
        ref = ((2 * s3 - 3 * s2 + 1) * q0 + (s3 - 2 * s2 + s) * m0 + (-2 * s3 + 3 * s2) * q1 + (s3 - s2) * m1,
               ((6 * s2 - 6 * s) * q0 + (3 * s2 - 4 * s + 1) * m0 + (-6 * s2 + 6 * s) * q1
                + (3 * s2 - 2 * s) * m1) / h,
               ((12 * s - 6) * q0 + (6 * s - 4) * m0 + (-12 * s + 6) * q1 + (6 * s - 2) * m1) / (h * h))
        for a, b in zip(pvt_command(t, q, tk), ref):
            assert np.array_equal(a, b)


def test_the_pvt_command_on_threads_is_the_one_pass_to_the_bit():
    """A long program's ticks are interpolated in runs on threads: each tick's numbers
    are those of one pass over all ticks (ticks out of order and NaN ticks included)."""
    from render_inspect.machining._interpolate import (THREADED_TICKS, _hermite, _pvt_velocities,
                                                       pvt_checked)

    rng = np.random.default_rng(8)
    t = np.cumsum(rng.uniform(1e-4, 1e-2, 5000))
    q = np.stack([rng.normal(size=t.size), np.cumsum(rng.normal(size=t.size))])
    tk = np.sort(rng.uniform(t[0] - 0.01, t[-1] + 0.01, 3 * THREADED_TICKS))
    tk[1000:1040] = tk[1000:1040][::-1]     # a stretch of ticks going back
    tk[::997] = np.nan
    got = pvt_checked(t, q, tk)
    v = np.empty(q.shape)
    _pvt_velocities(t, q, v)
    want = tuple(np.empty((2, tk.size)) for _ in range(3))
    _hermite(t, q, v, tk, *want, 0, tk.size)
    for a, b in zip(got, want):
        assert np.array_equal(a, b, equal_nan=True)


def test_the_pvt_commands_segment_search_is_numpys_searchsorted():
    """The PVT command's binary search gives numpy's ``searchsorted(t, x, side="right")``
    for every x: before, on and between the times, repeated times, beyond the ends and
    infinite."""
    from render_inspect.machining._interpolate import _count_at_most

    rng = np.random.default_rng(3)
    for n in (1, 2, 3, 7, 64, 1000):
        t = np.sort(rng.integers(0, 20, n).astype(np.float64) * 0.25)
        xs = np.concatenate([t, t - 1e-12, t + 1e-12, rng.uniform(-1, 6, 50),
                             [-np.inf, np.inf, t[0] - 1.0, t[-1] + 1.0]])
        for x in xs:
            assert _count_at_most(t, x) == np.searchsorted(t, x, side="right"), (n, x)


@pytest.mark.slow
def test_the_tiled_simulation_of_a_window_cuts_its_sectors_as_in_memory(tmp_path):
    from render_inspect.io import ZarrHeightMap
    from render_inspect.pipeline import run_simulate_tiled

    scene = load_scene("sts_fig16_overcut", ["simulation.region=[1.0,1.0,1.3,1.3]",
                                             "simulation.pixel=0.001", "process.workpiece_radius=2.0"])
    run_simulate_tiled(scene, tmp_path / "t", tile=128)
    sim = simulate(scene)
    assert "sectors" in sim.plan.program.meta
    z = ZarrHeightMap(tmp_path / "t" / "heightmap.zarr").read("machined")
    assert np.array_equal(z, sim.heightmap.machined.astype(np.float32), equal_nan=True)
