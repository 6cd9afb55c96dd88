"""``compare --measured PROFILE``'s checks and summaries, and the turned compare's feed from
a program read from a file: known answers built with forward models."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from render_inspect.core.marks import ToolMarks
from render_inspect.core.units import MM_TO_NM
from render_inspect.instruments import (Microscope, artefacts, csi_frames, led, objective,
                                        recommended_subsamples)
from render_inspect.metrology import line_profile, measure_frames
from render_inspect.core.toolpath import ToolPath
from render_inspect.pipeline import _compare as cmp
from render_inspect.pipeline import _compare_profile as cp
from render_inspect.pipeline._compare_profile_checks import cut_as_seen
from render_inspect.pipeline._summaries import profile_compare_summary
from render_inspect.report._comparison import _variant_rows

SPACING = 0.001  # mm
LAMBDA_EFF = 573.6  # nm


def _scallops(n=900, period=0.04, r=0.2):
    """A turned profile: arcs of the nose radius every feed period (mm)."""
    s = np.arange(n) * SPACING
    u = (s % period) - period / 2
    return s, r - np.sqrt(r * r - u * u)


def test_virtual_measurement_with_a_lost_fringe_order_is_failed():
    s, cut = _scallops()
    rng = np.random.default_rng(1)
    sigma_mm = 0.8e-6
    noise = np.full(s.size, sigma_mm)
    good = cut + rng.normal(0, sigma_mm, s.size)
    ok = cp._measurement_check(good, cut, noise, lambda_eff_nm=LAMBDA_EFF, mode="psi",
                               rt_sim=1.0, rt_true=1.0)
    assert ok["status"] == "ok" and ok["departing"] == 0
    assert abs(ok["noise_nm"] - 0.8) < 1e-9
    # a region 50 points long lost one fringe order (lambda_eff / 2)
    bad = good.copy()
    bad[300:350] += LAMBDA_EFF / 2 * 1e-6
    chk = cp._measurement_check(bad, cut, noise, lambda_eff_nm=LAMBDA_EFF, mode="psi",
                                rt_sim=1.0, rt_true=1.0)
    assert chk["status"] == "failed" and chk["departing"] == 50 and chk["longest_run"] == 50
    assert chk["threshold_nm"] == LAMBDA_EFF / 4
    # two lone points off (a dropout's edges) and a tilt (the instrument's levelling): not
    # a failed measurement; three in a row are
    lone = good + np.linspace(0, 400e-6, good.size)
    lone[[100, 500]] += LAMBDA_EFF / 2 * 1e-6
    ok2 = cp._measurement_check(lone, cut, noise, lambda_eff_nm=LAMBDA_EFF, mode="psi",
                                rt_sim=1.0, rt_true=1.0)
    assert ok2["status"] == "ok" and ok2["departing"] == 2 and ok2["longest_run"] == 1
    lone[[501, 502]] += LAMBDA_EFF / 2 * 1e-6
    three = cp._measurement_check(lone, cut, noise, lambda_eff_nm=LAMBDA_EFF, mode="psi",
                                  rt_sim=1.0, rt_true=1.0)
    assert three["status"] == "failed" and three["longest_run"] == 3
    w = cp._measurement_warning(chk)
    assert "render.interferometer.mode" in w and "CSI" in w


def test_noisy_instrument_threshold_follows_its_noise():
    s, cut = _scallops()
    rng = np.random.default_rng(2)
    sigma_mm = 40e-6  # 40 nm: 5 sigma = 200 nm > lambda_eff / 4
    meas = cut + rng.normal(0, sigma_mm, s.size)
    chk = cp._measurement_check(meas, cut, np.full(s.size, sigma_mm), lambda_eff_nm=LAMBDA_EFF,
                                mode="csi", rt_sim=1.0, rt_true=1.0)
    assert chk["threshold_nm"] == 200.0
    assert chk["status"] == "ok"


def test_registration_recovers_a_shift_and_refuses_an_unrelated_profile():
    rng = np.random.default_rng(3)
    n = 1000
    # a simulated measurement with features beyond the marks (a random waviness)
    sim = np.convolve(rng.normal(0, 1, n + 40), np.ones(20) / 20, "valid")[:n] * 1e-4
    s = np.arange(n) * SPACING
    shift = 37
    meas = sim[shift:shift + 700] + rng.normal(0, 2e-6, 700)
    s_meas = np.arange(700) * SPACING
    got, r, _, null = cp._register(s_meas, meas, s, sim, spacing=SPACING, period=None)
    assert round(got / SPACING) == shift
    assert null is not None and r > null
    other = np.convolve(rng.normal(0, 1, 740), np.ones(20) / 20, "valid")[:700] * 1e-4
    _, r2, _, null2 = cp._register(s_meas, other, s, sim, spacing=SPACING, period=None)
    assert r2 <= null2
    reg = {"correlation": r2, "null_correlation": null2, "beats_chance": False,
           "reliable": False}
    assert "not reliable" in cp._registration_warning(reg)


def test_profile_compare_summary_shows_numbers_and_warnings():
    prof = {"profile": {"Ra_nm": 10.0, "Rq_nm": 12.0, "Rt_nm": 50.0, "Rku": 3.0,
                        "RSm_mm": 0.04},
            "periods": {"dominant": {"period_mm": 0.04}}}
    m = {"kind": "profile", "profiles": {"measured": prof, "simulated_measured": prof,
                                         "true": prof},
         "registration": {"shift_mm": 0.001, "correlation": 0.1, "null_correlation": 0.3,
                          "reliable": False},
         "filter": {"lambda_s_mm": 0.0025, "lambda_c_mm": 0.08},
         "warnings": ["the registration is not reliable"]}
    rows, lines = profile_compare_summary(m)
    assert rows[0] == ("Ra", "10 nm", "10 nm", "10 nm")
    assert ("dominant period", "40 um", "40 um", "40 um") in rows
    assert any(x.startswith("WARNING: the registration") for x in lines)


def test_cli_prints_the_profile_compare_summary(capsys, tmp_path):
    from render_inspect.cli._summary import _print_profile_compare_summary

    m = {"kind": "profile", "scene": "s", "input": {"path": "/x/1021-WLI-2D.csv"},
         "profiles": {}, "registration": {}, "filter": {}, "warnings": ["it failed"]}
    _print_profile_compare_summary(m, str(tmp_path), 1.0)
    text = capsys.readouterr().out
    assert "1021-WLI-2D.csv" in text and "WARNING: it failed" in text
    assert f"report: {tmp_path.resolve() / 'report.html'}" in text


def test_variant_rows_name_the_files_not_their_folder():
    variants = [{"name": "a", "label": "process.program = /long/common/folder/1022-x.nc",
                 "values": {"process.program": "/long/common/folder/1022-x.nc"}},
                {"name": "b", "label": "process.program = /long/common/folder/1023-y.nc",
                 "values": {"process.program": "/long/common/folder/1023-y.nc"}}]
    assert _variant_rows(variants) == [("process.program", "1022-x.nc", "1023-y.nc")]


def _spiral(feed_inner, feed_outer, r_change, r_max=1.0, per_rev=400):
    """A spiral inwards whose feed per revolution is ``feed_outer`` beyond ``r_change`` and
    ``feed_inner`` inside it (mm)."""
    theta, rho, r, th = [], [], r_max, 0.0
    while r > 0:
        f = feed_outer if r > r_change else feed_inner
        theta.append(th)
        rho.append(r)
        th += 2 * np.pi / per_rev
        r -= f / per_rev
    theta, rho = np.array(theta), np.array(rho)
    return ToolPath(theta, rho, np.zeros_like(rho), theta.copy(), {})


def test_program_feed_over_the_region_sets_scallop_and_filter(tmp_path):
    """A program whose feed changes with the radius: the simulated region's scallop is the
    feed at the region's own radii (the process states it), and compare's filters follow
    it; a planned path states none."""
    import json

    from render_inspect.io import write_nc
    from render_inspect.pipeline import simulate
    from render_inspect.scene import load_scene

    nc = write_nc(tmp_path / "p.nc", _spiral(0.02, 0.04, 0.3))
    scene = load_scene("sts_sinusoidal_grid", [
        "design={type='plane'}", "tool.nose_radius=0.2", "machine.preset='ideal'",
        "material.preset='ideal'", "simulation.region=[-0.1,-0.05,0.1,0.05]",
        "simulation.pixel=0.005", "process.workpiece_radius=1.0",
        f"process.program={json.dumps(str(nc))}"])
    metrics = simulate(scene).metrics
    assert abs(metrics["program"]["feed_per_rev_region_um"] - 20.0) < 1e-3
    assert abs(metrics["scallop"]["feed_per_rev_mm"] - 0.02) < 1e-6
    # scallop height of a 20 um feed with a 0.2 mm nose: f^2 / 8R = 250 nm
    assert abs(metrics["scallop"]["height_nm"] - 250.0) < 1.0
    v = SimpleNamespace(name="prog", sim=SimpleNamespace(metrics=metrics))
    p = SimpleNamespace(name="planned", sim=SimpleNamespace(metrics={"scallop": {}}))
    feeds = cmp._program_feeds([v, p])
    assert set(feeds) == {"prog"} and abs(feeds["prog"] - 0.02) < 1e-9
    marks = ToolMarks(pattern="circular", period_mm=0.0396, nose_radius_mm=0.2, scallop=True)
    assert cmp._marks_of_programs(marks, feeds).period_mm == feeds["prog"]
    assert cmp._marks_of_programs(marks, {}) is marks


@pytest.mark.parametrize("name,n", [("5x", 48), ("2.5x", 32)])
def test_a_correct_measurement_of_sharp_edges_follows_the_cut_as_the_instrument_sees_it(name, n):
    """A rectangular grating 600 nm deep (two sharp edges) measured by the full imaging
    model (coherence scanning; a 5x objective with a 3.5 um camera pixel, a 2.5x with a
    7 um one) and read along a line at 0.5 um, as a finer measured profile is: the
    measurement is right (coherence scanning finds the step's fringe order), but against
    the cut as sampled the objective's rounding of the edges and the interpolation
    between pixel centres depart at both edges, and the check called it failed; against
    the cut as the instrument sees it (:func:`cut_as_seen`) it follows, at a fraction of
    the rms.  The same measurement with a lost fringe order over three camera pixels is
    failed, and the points that depart are that stretch alone."""
    mic = Microscope(objective=objective(name), source=led(570.0, bandwidth_nm=100.0))
    p = mic.objective.pixel
    s = max(recommended_subsamples(p, mic, max_slope=0.0), 4)
    a = p / s
    x0 = -(s - 1) * a / 2  # the first sub-sample's centre; pixel centres at j p
    h, nrm = artefacts.step((4, n), p, s, height=600e-6)
    r = measure_frames(csi_frames(h, nrm, pixel=p, subsamples=s, microscope=mic, seed=1))
    p0, p1, step = (2 * p, 1.5 * p), ((n - 3) * p, 1.5 * p), 0.5e-3

    def along(z, pixel, origin):
        return line_profile(z, pixel=pixel, origin=origin, p0=p0, p1=p1, step=step)[1]

    meas = along(np.where(r.valid, r.height, np.nan), p, (0.0, 0.0))
    noise = along(r.height_noise, p, (0.0, 0.0))
    sampled = along(h, a, (x0, x0))
    seen = along(cut_as_seen(h, pixel=a, origin=(x0, x0), microscope=mic, camera_pixel=p,
                             camera_origin=(0.0, 0.0), camera_shape=(4, n)), p, (0.0, 0.0))
    lam = mic.effective_wavelength_nm()
    kw = {"lambda_eff_nm": lam, "mode": "csi", "rt_sim": None, "rt_true": None}
    old = cp._measurement_check(meas, sampled, noise, **kw)
    assert old["status"] == "failed"
    ok = cp._measurement_check(meas, seen, noise, **kw)
    assert ok["status"] == "ok" and ok["departing"] == 0
    assert ok["rms_departure_nm"] < 0.5 * old["rms_departure_nm"]
    # a lost fringe order over three camera pixels of the lower terrace
    lost = np.where(r.valid, r.height, np.nan)
    lost[:, 4:7] += lam / 2 / MM_TO_NM
    half = along(lost, p, (0.0, 0.0))
    moved = int(np.count_nonzero(np.abs(half - meas) > lam / 4 / MM_TO_NM))
    bad = cp._measurement_check(half, seen, noise, **kw)
    assert bad["status"] == "failed" and abs(bad["departing"] - moved) <= 2
    assert cp._measurement_check(half, sampled, noise, **kw)["departing"] > moved + 2
