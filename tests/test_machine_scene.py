"""[machine] and [material] in scenes: presets, overrides, the ideal machine = the
geometric result of the project before these sections existed, following-error metrics
and figures, the RCSE study's comparison and the vibration on steel of Zhang et al."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from numpy.testing import assert_allclose

from render_inspect.errors import SceneError
from render_inspect.core.plugins import literal_values
from render_inspect.machining import (MACHINE_PRESET_NAMES, MACHINE_PRESETS, MATERIAL_PRESET_NAMES,
                                      MATERIAL_PRESETS)
from render_inspect.pipeline import simulate, write_simulation
from render_inspect.processes import MachineConfig, MaterialConfig, machine_of, material_of
from render_inspect.scene import load_scene

IDEAL = ["machine.preset='ideal'", "material.preset='ideal'", "machine.fts_sync_delay_s=0.0"]

#: residuals (nm) of these windows computed by the project's code before [machine] and
#: [material] existed (the direct per-pixel envelope kernel); the ideal machine must
#: reproduce them.  The fast kernel that replaced it rounds the interpolation fraction
#: differently (heights within 1e-12 mm), which moves these statistics by < 1e-9 relative.
RTOL = 1e-9
BEFORE = {
    "sts_sinusoidal_grid": (["simulation.region=[0.3,0.3,0.5,0.5]", "simulation.pixel=0.002"],
                            (6.236199331295275, 7.244244004803849, 24.25320091600097)),
    "compound_sinusoid": (["simulation.region=[1.0,1.0,1.2,1.2]", "simulation.pixel=0.004"],
                          (164.9588732242798, 191.6174254761108, 646.6607089140666)),
    "rcse_circular_array": (["simulation.region=[3.38,-0.1,3.58,0.1]", "simulation.pixel=0.004"],
                            (7.999012375259298, 9.164225832803773, 32.037051515764915)),
}
#: an HTS window cut with second-order servos (no feed-forward) as the slow slide and the
#: FTS of an otherwise ideal machine: the numbers of the package's one servo model (the
#: retired [artifacts.servo] model, a bilinear filter on the program's time axis, gave
#: 595.87, 752.03, 3761.26 nm, 0.08 % apart)
SERVOS = (["simulation.region=[1.0,-0.5,2.0,0.5]", "simulation.pixel=0.005",
           "machine.fts.delay_s=0.002", "machine.fts.bandwidth_hz=1000.0",
           "machine.z.bandwidth_hz=100.0", "metrology.registration='none'"],
          (596.3490387289858, 752.6771682648587, 3763.5917967483383))
RETIRED = ["artifacts.servo.delay_s=0.002", "artifacts.servo.bandwidth_hz=1000.0",
           "artifacts.servo.slow_bandwidth_hz=100.0"]


def test_preset_names_are_the_presets():
    """The schema takes the names of the machining presets themselves (one list)."""
    assert literal_values(MachineConfig, "preset") == MACHINE_PRESET_NAMES == tuple(MACHINE_PRESETS)
    assert literal_values(MaterialConfig, "preset") == MATERIAL_PRESET_NAMES
    assert set(MATERIAL_PRESET_NAMES) == {"ideal"} | set(MATERIAL_PRESETS)


def test_shipped_turning_scenes_cut_on_a_lathe_with_a_material():
    for name in ("sts_sinusoidal_grid", "sts_mla_2x2", "compound_sinusoid", "sts_fig16_overcut",
                 "rcse_circular_array"):
        s = load_scene(name)
        assert s.machine.preset == "sts_lathe" and s.material.preset != "ideal", name
    s = load_scene("hts_toric_msa")
    assert s.machine.preset == "fts"
    assert load_scene("sculpt_quad_mla").material.preset == "die_steel"


@pytest.mark.parametrize("name", sorted(BEFORE))
def test_ideal_machine_and_material_reproduce_the_geometric_result_exactly(name):
    over, (sa, sq, sz) = BEFORE[name]
    m = simulate(load_scene(name, over + IDEAL)).metrics
    assert_allclose([m["residual"]["Sa_nm"], m["residual"]["Sq_nm"], m["residual"]["Sz_nm"]],
                    [sa, sq, sz], rtol=RTOL)
    assert "following_error" not in m and m["machine"]["ideal"]


def test_servos_of_an_ideal_machine_and_their_retired_keys():
    over, (sa, sq, sz) = SERVOS
    m = simulate(load_scene("hts_toric_msa", over + IDEAL)).metrics
    assert_allclose([m["residual"]["Sa_nm"], m["residual"]["Sq_nm"], m["residual"]["Sz_nm"]],
                    [sa, sq, sz], rtol=RTOL)
    assert m["machine"]["preset"] == "ideal" and not m["machine"]["ideal"]
    assert m["servo"]["delay_s"] == 0.002 and m["servo"]["slow_bandwidth_hz"] == 100.0
    # the retired keys name their successors and give the same scene
    with pytest.warns(UserWarning, match=r"artifacts.servo.slow_bandwidth_hz is deprecated: use "
                                         r"machine.z.bandwidth_hz"):
        old = load_scene("hts_toric_msa", over[:2] + over[-1:] + RETIRED + IDEAL)
    assert old.to_dict() == load_scene("hts_toric_msa", over + IDEAL).to_dict()


def test_infinite_bandwidth_without_disturbance_is_the_ideal_machine():
    over, (sa, sq, sz) = BEFORE["sts_sinusoidal_grid"]
    axes = [f"machine.{a}.{k}={v}" for a in ("c", "x", "z", "fts")
            for k, v in (("bandwidth_hz", "inf"), ("delay_s", 0))]
    noise = ["machine.c.noise_urad=0", "machine.x.noise_nm=0", "machine.z.noise_nm=0",
             "machine.fts.noise_nm=0"]
    errors = ["machine.errors.radial_sync=[]", "machine.errors.axial_sync=[]",
              "machine.errors.radial_async_nm=0", "machine.errors.axial_async_nm=0",
              "machine.errors.x_straightness_nm=0", "machine.coupling.mass_kg=0"]
    s = load_scene("sts_sinusoidal_grid", over + axes + noise + errors + ["material.preset='ideal'"])
    assert s.machine.preset == "sts_lathe" and machine_of(s.machine).ideal
    m = simulate(s).metrics["residual"]
    assert_allclose([m["Sa_nm"], m["Sq_nm"], m["Sz_nm"]], [sa, sq, sz], rtol=RTOL)
    ideal = simulate(load_scene("sts_sinusoidal_grid", over + IDEAL)).metrics["residual"]
    assert [m[k] for k in ("Sa_nm", "Sq_nm", "Sz_nm")] == [ideal[k] for k in ("Sa_nm", "Sq_nm", "Sz_nm")]


def test_scene_units_reach_the_machine_and_the_material():
    s = load_scene("sts_sinusoidal_grid", [
        "machine.x.bandwidth_hz=80", "machine.x.noise_nm=3", "machine.c.noise_urad=2",
        "machine.z.acceleration_limit_mm_s2=1000", "machine.errors.radial_sync=[[1, 20.0, 90.0]]",
        "machine.errors.vibration=[[115.0, 4.0, 'z', 0.0]]", "machine.coupling.mass_kg=80",
        "material.friction=0.3", "material.edge_radius_nm=100"])
    m = machine_of(s.machine)
    assert m.x.bandwidth_hz == 80 and m.x.noise_rms == pytest.approx(3e-6)
    assert m.c.noise_rms == pytest.approx(2e-6) and m.z.acceleration_limit == 1000
    assert m.errors.radial_sync == ((1, pytest.approx(2e-5), pytest.approx(math.pi / 2)),)
    assert m.errors.vibration[0][:3] == (115.0, pytest.approx(4e-6), "z")
    assert m.coupling.mass_kg == 80 and m.z.bandwidth_hz == 100.0   # the preset's
    r = material_of(s.material)
    assert r.edge_radius_eff == pytest.approx(100e-6)
    assert r.h_min == pytest.approx(100e-6 * (1 - math.cos(math.pi / 4 - math.atan(0.3) / 2)))


def test_bad_machine_and_material_keys_are_named():
    with pytest.raises(SceneError, match="machine.preset"):
        load_scene("sts_sinusoidal_grid", ["machine.preset='lathe9000'"])
    with pytest.raises(SceneError, match="machine.x.bandwith_hz"):
        load_scene("sts_sinusoidal_grid", ["machine.x.bandwith_hz=3"])
    with pytest.raises(SceneError, match="material.preset"):
        load_scene("sts_sinusoidal_grid", ["material.preset='ideal'", "material.friction=0.2"])
    with pytest.raises(SceneError, match="machine.preset: must be 'ideal' for process.kind = 'sculpt'"):
        load_scene("sculpt_quad_mla", ["machine.preset='sts_lathe'"])
    with pytest.raises(SceneError, match=r"artifacts.servo applies to machine.preset = 'ideal' only"):
        load_scene("hts_toric_msa", ["artifacts.servo.delay_s=0.001",
                                     "simulation.region=[1.0,-0.2,1.4,0.2]", "simulation.pixel=0.01"])


@pytest.mark.slow
def test_following_error_metrics_and_figures(tmp_path):
    s = load_scene("sts_sinusoidal_grid", ["simulation.region=[0.3,0.3,0.45,0.45]",
                                           "simulation.pixel=0.003"])
    sim = simulate(s)
    fe = sim.metrics["following_error"]
    assert set(fe) >= {"x_rms_nm", "x_max_nm", "z_rms_nm", "z_max_nm"}
    assert 0 < fe["x_rms_nm"] < fe["x_max_nm"] < 100
    assert sim.metrics["material"]["material"] == "al6082"
    write_simulation(sim, tmp_path)
    for f in ("following_error.png", "following_error_map.png", "metrics.json"):
        assert (tmp_path / f).stat().st_size > 1000
    m = json.loads((tmp_path / "metrics.json").read_text())
    assert m["following_error"]["x_max_nm"] == pytest.approx(fe["x_max_nm"])
    # the machine as it ran, in the model's units (settings) and as [machine] keys in the
    # scene's units (scene_settings): the same machine, and one a scene takes back
    ran, keys = m["machine"]["settings"], m["machine"]["scene_settings"]
    assert keys["c"]["noise_urad"] == pytest.approx(ran["c"]["noise_rms"] * 1e6)
    assert keys["x"]["noise_nm"] == pytest.approx(ran["x"]["noise_rms"] * 1e6)
    assert keys["errors"]["axial_async_nm"] == pytest.approx(ran["errors"]["axial_async_rms"] * 1e6)
    for (n, a_nm, p_deg), (n0, a_mm, p_rad) in zip(keys["errors"]["axial_sync"], ran["errors"]["axial_sync"]):
        assert (n, a_nm, p_deg) == (n0, pytest.approx(a_mm * 1e6), pytest.approx(math.degrees(p_rad)))
    assert ran["errors"]["axial_sync"]
    back = load_scene("sts_sinusoidal_grid", ["simulation.region=[0.3,0.3,0.45,0.45]",
                                              f"machine.errors.axial_sync={keys['errors']['axial_sync']}",
                                              f"machine.c.noise_urad={keys['c']['noise_urad']}"])
    assert_allclose(machine_of(back.machine).to_dict()["errors"]["axial_sync"],
                    ran["errors"]["axial_sync"], rtol=1e-12)
    # same scene, same seed: the same surface
    again = simulate(s)
    assert_allclose(again.heightmap.machined, sim.heightmap.machined, rtol=0, atol=0)


def test_the_geometric_cuts_error_map_is_drawn_from_the_whole_maps_points():
    """The geometric cut (no material) computes the cutting pass's angle only on the
    points the following-error map draws: the very numbers of the whole map's points."""
    from render_inspect.design import make_surface
    from render_inspect.processes import plan_spiral
    from render_inspect.processes._mechanics import following_error_map_plot, pass_angle_map, turn

    region, pixel = [0.3, 0.3, 0.75, 0.62], 0.001      # 451 x 321 pixels: every 2nd drawn
    s = load_scene("sts_sinusoidal_grid", [f"simulation.region={region}", f"simulation.pixel={pixel}",
                                           "material.preset='ideal'"])
    surface = make_surface(s.design)
    t = turn(s, surface, plan_spiral(s, surface, region=region), burrs=False)
    got = t["plots"]["following_error_map.png"]
    whole = pass_angle_map(t["followed"], region, pixel)
    want = following_error_map_plot(t["followed_path"], whole, region, pixel,
                                    name=s.name)["following_error_map.png"]
    assert got["x_nm"].shape == (161, 226) and np.isfinite(got["x_nm"]).all()
    for k in ("x_nm", "z_nm"):
        assert np.array_equal(got[k], want[k], equal_nan=True), k
    assert got["extent"] == want["extent"] and got["title"] == want["title"]


@pytest.mark.slow
def test_seed004_rcse_against_the_conventional_path_on_the_sts_lathe():
    """With the STS lathe preset the grid-interpolated path's reciprocating X has at least
    ten times RCSE's following error, and RCSE lowers Sa and its spread over elements."""
    s = load_scene("rcse_circular_array", ["simulation.region=[3.43,-0.05,3.53,0.05]",
                                           "simulation.pixel=0.004", "rcse.spread_elements=5",
                                           "rcse.spread_window=0.1"])
    c = simulate(s).metrics["rcse"]["comparison"]
    for key in ("rcse", "conventional"):
        assert set(c[key]["following_error"]) >= {"x_rms_nm", "x_max_nm", "z_rms_nm", "z_max_nm"}
    assert c["conventional"]["following_error"]["x_max_nm"] >= 10 * c["rcse"]["following_error"]["x_max_nm"]
    sp = c["spread"]
    assert len(sp["elements"]) == 5 and len({e["ring"] for e in sp["elements"]}) == 5
    assert sp["rcse"]["Sa_mean_nm"] < sp["conventional"]["Sa_mean_nm"]
    assert sp["rcse"]["Sa_sd_nm"] < sp["conventional"]["Sa_sd_nm"]
    assert sp["Sa_mean_reduction_percent"] > 0 and sp["Sa_sd_reduction_percent"] > 0


def test_zhang_steel_burrs_follow_the_depth_of_cut_and_conventional_steel_is_flagged():
    """Zhang et al.'s (2022) steel, 3 x 3 lenslets: the edge burrs come from the material's
    burr law (uncut chip thickness, exit angle, ductility): doubling the finishing layer
    doubles them; the vibration does not change the material (no source relates the
    contact ratio to the surface); continuous cutting of the steel is reported as outside
    the model."""
    p = 0.19975
    base = ["design.rows=3", "design.cols=3", f"simulation.pixel={p / 40}",
            f"simulation.region=[{-1.5 * p},{-1.5 * p},{1.5 * p},{1.5 * p}]"]
    out = {}
    for amp, depth in ((0.00075, 0.001), (0.00075, 0.002), (0.0, 0.001)):
        sim = simulate(load_scene("sculpt_quad_mla", base + [f"artifacts.vibration.amplitude={amp}",
                                                            f"process.depth_of_cut={depth}"]))
        out[amp, depth] = sim.metrics
    b1, b2 = out[0.00075, 0.001]["burrs"], out[0.00075, 0.002]["burrs"]
    assert b1["edge_pixels"] > 0 and b1["chip_thickness_um"] == pytest.approx(1.0)
    assert b2["height_max_um"] == pytest.approx(2 * b1["height_max_um"], rel=1e-9)
    # the turn at the lenslet edges: 2 atan(s / r) at the edge midpoints, more at the corners
    assert b1["turn_max_deg"] >= math.degrees(2 * math.atan(p / 2 / 1.0)) * 0.97
    cs, uv = out[0.0, 0.001]["material"], out[0.00075, 0.001]["material"]
    assert uv["validity"] is None and "outside the model" in cs["validity"]
    assert cs["kappa"] == uv["kappa"] and cs["h_min_nm"] == uv["h_min_nm"]


def test_the_scallop_of_the_feed_used_is_reported_always():
    s = load_scene("sts_sinusoidal_grid", ["simulation.region=[0.3,0.3,0.4,0.4]",
                                           "simulation.pixel=0.005"] + IDEAL)
    m = simulate(s).metrics["scallop"]
    f, r = 0.01, 0.514
    assert m["feed_per_rev_mm"] == pytest.approx(f) and m["nose_radius_mm"] == r
    assert m["height_nm"] == pytest.approx((r - math.sqrt(r * r - f * f / 4)) * 1e6)
    assert m["Sq_nm"] == pytest.approx(f * f / (r * math.sqrt(720)) * 1e6)
    assert m["Sa_nm"] == pytest.approx(4 * (f * f / (8 * r)) / (9 * math.sqrt(3)) * 1e6)


def test_scallop_bound_plans_the_feed():
    s = load_scene("sts_sinusoidal_grid", ["process.scallop_bound_nm=50",
                                           "simulation.region=[0.3,0.3,0.4,0.4]",
                                           "simulation.pixel=0.005"] + IDEAL)
    sim = simulate(s)
    plan = sim.metrics["toolpath"]["scallop_plan"]
    f = sim.metrics["toolpath"]["feed_per_rev_mm"]
    assert f == pytest.approx(plan["feed_per_rev_mm"])
    assert sim.metrics["scallop"]["feed_per_rev_mm"] == pytest.approx(f)   # the feed used
    # on the gentle grid the planned feed is close to the flat-section value
    r = s.tool.nose_radius
    assert f == pytest.approx(2 * math.sqrt(50e-6 * (2 * r - 50e-6)), rel=0.1)
    assert np.isfinite(sim.metrics["residual"]["Sz_nm"])
