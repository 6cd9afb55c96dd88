"""``fit --predict``: the prediction of the next cut carries the fit's uncertainty, over a
window that holds enough periods of the predicted marks, its numbers averaged over where
the marks fall in it.

Fast tests check the propagation against analytic forward models (a linear one: the
uncertainty is exactly sqrt(g^T C g); a quadratic one: the second-order shift is exactly
tr(H C) / 2) and what it says where the fit gives no standard error or does not describe
the measurement; the window against its geometry; and the predicted roughness of an ideal
machine's cut over a series of feeds against the feed scallop (smooth in the feed, Sq =
f^2 / (R sqrt 720)).  The slow tests fit a map that the project's own cut and virtual
instrument made at known keys and check the predicted uncertainty against simulations at
the fitted values +- one standard error, and the shipped lathe's predicted roughness over a
series of feeds."""

from __future__ import annotations

import json
import math
import tempfile
from pathlib import Path

import numpy as np
import pytest

from render_inspect.cli import main
from render_inspect.core.marks import ToolMarks
from render_inspect.fit import (COVERAGE_FACTOR, MIN_PERIODS, PHASES, combine_propagation,
                                phase_average, plan_propagation, prediction_lines,
                                prediction_window)
from render_inspect.io import read_heightmap_exr, write_measurement_exr
from render_inspect.pipeline import run_measure, run_render, simulate
from render_inspect.pipeline import _fit_predict
from render_inspect.pipeline._fit import _evaluation_pixel
from render_inspect.pipeline._fit_model import preset_fill
from render_inspect.scene import apply_overrides, load_scene, scene_from_dict


def _record(values, stderr, corr, *, bounds=None, describes=True, determined=None,
            message="", not_computed=False):
    keys = list(values)
    params = {}
    for i, k in enumerate(keys):
        params[k] = {"value": values[k], "stderr": stderr[k],
                     "determined": True if determined is None else determined[k],
                     "bounds": (bounds or {}).get(k, [-1e9, 1e9]), "start": values[k]}
    c = {a: {b: float(corr[i][j]) for j, b in enumerate(keys)} for i, a in enumerate(keys)}
    return {"parameters": params, "correlation": c, "message": message,
            "identifiability": {"not_computed": "no standard errors"} if not_computed else {},
            "model_check": {"after": {"describes": describes,
                                      "verdict": ("the model describes this measurement"
                                                  if describes else
                                                  "this model does not describe this "
                                                  "measurement: the misfit is 80 times ...")}}}


def _metrics(y: float) -> dict:
    return {"residual": {"Sq_nm": y, "Sa_nm": 0.8 * y, "Sz_nm": 5 * y},
            "scallop": {"height_nm": 2 * y}, "toolpath": {"feed_per_rev_mm": 0.01}}


def _run(record, predict, f):
    prop = plan_propagation(record, predict)
    x0 = np.array([record["parameters"][k]["value"] for k in prop.keys])
    centre = _metrics(f(x0))
    pts = [_metrics(f(np.array([p.values[k] for k in prop.keys]))) for p in prop.points]
    return prop, combine_propagation(prop, centre, pts, seed=3)


def test_a_linear_prediction_gets_exactly_the_gum_uncertainty_with_correlations():
    rec = _record({"a": 2.0, "b": 5.0}, {"a": 0.1, "b": 0.4}, [[1, -0.7], [-0.7, 1]])
    g = np.array([3.0, -1.5])
    prop, unc = _run(rec, [], lambda x: 10.0 + g @ x)
    se = np.array([0.1, 0.4])
    cov = np.array([[1, -0.7], [-0.7, 1]]) * np.outer(se, se)
    q = unc["quantities"]["residual.Sq_nm"]
    assert len(prop.points) == 4 and unc["simulations"] == 5
    assert q["u"] == pytest.approx(math.sqrt(g @ cov @ g), rel=1e-9)
    assert q["U"] == pytest.approx(COVERAGE_FACTOR * q["u"])
    assert q["value"] == pytest.approx(10.0 + g @ [2.0, 5.0])
    assert q["second_order_shift"] == pytest.approx(0.0, abs=1e-9)
    assert q["per_key"]["a"]["sensitivity"] == pytest.approx(3.0, rel=1e-9)
    assert q["per_key"]["b"]["alone"] == pytest.approx(1.5 * 0.4, rel=1e-9)
    # the other numbers scale with it (Sz = 5 Sq)
    assert unc["quantities"]["residual.Sz_nm"]["u"] == pytest.approx(5 * q["u"], rel=1e-9)
    # a number with no spread gets 0, not an error
    assert unc["quantities"]["toolpath.feed_per_rev_mm"]["u"] == 0.0
    assert unc["seed"] == 3 and unc["complete"] and unc["without"] == {}


def test_the_second_order_terms_of_a_quadratic_are_exact():
    """y = d0 + 1/2 d^T H d (d: the keys' deviation, normal with covariance C): the mean
    shifts by tr(H C) / 2; where H's axes are the covariance's, the variance is
    g^T C g + tr((H C)^2) / 2, which the first order alone misses."""
    cov = np.array([[1, 0.5], [0.5, 1]]) * np.outer([0.2, 0.3], [0.2, 0.3])
    rec = _record({"a": 1.0, "b": -2.0}, {"a": 0.2, "b": 0.3}, [[1, 0.5], [0.5, 1]])
    x0 = np.array([1.0, -2.0])
    for h in (np.array([[4.0, 1.0], [1.0, 2.0]]), 3.0 * np.linalg.inv(cov)):
        _, unc = _run(rec, [], lambda x: 0.5 * (x - x0) @ h @ (x - x0) + (x - x0)[0])
        q = unc["quantities"]["residual.Sq_nm"]
        assert q["second_order_shift"] == pytest.approx(0.5 * np.trace(h @ cov), rel=1e-9)
        # the central differences give the exact gradient at the fitted values
        assert q["u_first_order"] == pytest.approx(math.sqrt(cov[0, 0]), rel=1e-9)
    hc = h @ cov
    assert q["u"] == pytest.approx(math.sqrt(cov[0, 0] + 0.5 * np.trace(hc @ hc)), rel=1e-9)
    assert not q["smooth"]


def test_a_key_set_by_predict_or_without_a_standard_error_is_left_out_and_said():
    rec = _record({"process.feed_mm_per_min": 0.5, "tool.nose_radius": 0.5,
                   "machine.z.delay_s": 0.002},
                  {"process.feed_mm_per_min": 0.001, "tool.nose_radius": 0.003,
                   "machine.z.delay_s": None},
                  np.eye(3), determined={"process.feed_mm_per_min": True,
                                         "tool.nose_radius": True,
                                         "machine.z.delay_s": False})
    prop, unc = _run(rec, ["process.feed_mm_per_min=0.4"], lambda x: 1.0 + x[0])
    assert prop.keys == ["tool.nose_radius"] and len(prop.points) == 2
    assert "set by --predict" in unc["without"]["process.feed_mm_per_min"]
    assert "not determined alone" in unc["without"]["machine.z.delay_s"]
    assert not unc["complete"]
    lines = prediction_lines({"settings": ["process.feed_mm_per_min=0.4"],
                              "measurement_backed": True, "uncertainty": unc})
    text = "\n".join(lines)
    assert "residual Sq = 1.5 +- 0.003 nm (standard uncertainty, k=1; k=2: +- 0.006 nm)" in text
    assert "without the uncertainty of machine.z.delay_s: not determined alone" in text
    # no standard errors at all (--max-evaluations left too few): no simulation, and why
    rec = _record({"tool.nose_radius": 0.5}, {"tool.nose_radius": None}, np.eye(1),
                  message="--max-evaluations 20 left too few evaluations for the standard "
                          "errors' differences", not_computed=True)
    prop = plan_propagation(rec, [])
    assert prop.points == [] and prop.blocked is not None
    assert "--max-evaluations 20 left too few" in prop.blocked


def test_a_fit_that_does_not_describe_the_measurement_marks_its_prediction():
    rec = _record({"tool.nose_radius": 0.5}, {"tool.nose_radius": 0.01}, np.eye(1),
                  describes=False)
    prop = plan_propagation(rec, [])
    assert prop.points == [] and "does not describe" in (prop.blocked or "")
    lines = prediction_lines({"settings": ["process.spindle_rpm=40"],
                              "measurement_backed": False, "note": "the fit's verdict ...",
                              "uncertainty": None, "no_uncertainty": prop.blocked,
                              "values": {"residual.Sq_nm": 6.2}})
    assert lines[0].startswith("prediction (process.spindle_rpm=40): NOT a "
                               "measurement-backed forecast")
    assert "residual Sq = 6.2 nm (uncertainty not known)" in "\n".join(lines)


def test_a_point_beyond_a_bound_is_pulled_in_and_the_difference_scaled():
    rec = _record({"a": 0.05}, {"a": 0.1}, np.eye(1), bounds={"a": [0.0, 1.0]})
    prop, unc = _run(rec, [], lambda x: 7.0 * x[0])
    minus = [p for p in prop.points if p.side < 0][0]
    assert minus.step == pytest.approx(0.25) and minus.values["a"] == pytest.approx(0.025)
    assert unc["quantities"]["residual.Sq_nm"]["u"] == pytest.approx(0.7, rel=1e-9)


# ------------------------------------------------------------------ the prediction's window
def test_the_window_holds_enough_periods_and_moves_across_the_marks():
    """The fit's window is kept where it holds MIN_PERIODS periods of the marks across it
    (grown about its centre where it holds fewer), and its positions move across the marks
    by quarters of their period: radially for a turned part's rings, along the cut for
    linear marks; a cut without periodic marks is read over the fit's window alone."""
    w = [0.28, -0.055, 0.39, 0.055]
    rings = ToolMarks("circular", 0.01, 0.5, scallop=True)
    win = prediction_window(w, rings)
    assert win.region == w and not win.grown and win.periods == pytest.approx(11.0)
    assert len(win.regions()) == PHASES == 4
    for j, r in enumerate(win.regions()):  # on the x axis the radius is x
        assert r == pytest.approx([w[0] + j * 0.0025, w[1], w[2] + j * 0.0025, w[3]], abs=1e-15)
    # off the axis's line the positions move along the radius through the window's centre
    off = prediction_window([0.3, 0.3, 0.4, 0.4], rings)
    dx, dy = off.shifts[1]
    assert dx == pytest.approx(0.0025 / math.sqrt(2)) and dy == pytest.approx(dx)
    # a coarse feed: the window grown about its centre to MIN_PERIODS periods
    coarse = prediction_window(w, ToolMarks("circular", 0.05, 0.5, scallop=True))
    assert coarse.grown and coarse.periods == pytest.approx(MIN_PERIODS)
    x0, y0, x1, y1 = coarse.region
    assert x1 - x0 == pytest.approx(MIN_PERIODS * 0.05) and (x0 + x1) / 2 == pytest.approx(0.335)
    d = coarse.describe()
    assert d["fit_window_mm"] == w and d["grown"] and d["positions"] == 4
    assert "grown to hold them" in d["description"]
    # linear marks repeat along their direction
    lin = prediction_window(w, ToolMarks("linear", 0.004, 0.5, direction=(0.0, 2.0)))
    assert lin.shifts[2] == pytest.approx((0.0, 0.002)) and not lin.grown
    none = prediction_window(w, None)
    assert none.regions() == [w] and none.describe()["positions"] == 1


def test_the_positions_numbers_are_averaged_and_their_spread_given():
    ms = [{"residual": {"Sq_nm": v, "Sz_nm": 5 * v, "valid_fraction": 1.0},
           "scallop": {"height_nm": 7.0 + i}, "toolpath": {"feed_per_rev_mm": 0.01}}
          for i, v in enumerate((1.0, 2.0, 3.0, 2.0))]
    avg, spread = phase_average(ms)
    assert avg["residual"]["Sq_nm"] == 2.0 and avg["residual"]["Sz_nm"] == 10.0
    assert spread["residual.Sq_nm"] == pytest.approx(math.sqrt(0.5))
    assert avg["scallop"]["height_nm"] == 7.0  # not the window's: the first position's


#: an ideal machine and material cutting a flat part: the commanded geometry alone, whose
#: roughness across the feed marks is the feed scallop's
FLAT = ["machine.preset='ideal'", "material.preset='ideal'", "design={type='plane'}",
        "tool.nose_radius=0.525"]
#: the fit's window of the command-line tests: 0.11 mm at 0.28..0.39 mm on the x axis
SERIES_WINDOW = [0.28, -0.055, 0.39, 0.055]


def _series(overrides, feeds_per_rev):
    """The prediction of the next cut at each feed per revolution (mm) on the shipped grid
    scene with ``overrides``, over SERIES_WINDOW at the evaluations' pixel, without
    uncertainty (no fitted key): the headline numbers and the last prediction."""
    scene = load_scene("sts_sinusoidal_grid", overrides)
    rows, pr = [], {}
    with tempfile.TemporaryDirectory() as tmp:
        for i, f in enumerate(feeds_per_rev):
            (Path(tmp) / str(i)).mkdir()
            pr = _fit_predict.predict_next_cut(
                Path(tmp) / str(i), scene.to_dict(), [f"process.feed_mm_per_min={f * 50!r}"],
                preset_fill(scene), SERIES_WINDOW, {"parameters": {}, "model_check": {}},
                _evaluation_pixel)
            rows.append([pr["values"][f"residual.{k}_nm"] for k in ("Sq", "Sa", "Sz")])
    return np.array(rows), pr


def test_the_ideal_cuts_predicted_roughness_is_the_feed_scallop_smooth_in_the_feed():
    """An ideal machine's flat cut predicted at 13 feeds of 0.006..0.012 mm/rev: Sq is the
    parabolic scallop's f^2 / (R sqrt 720) within 0.3 % (read over the window at one place
    of the marks it was 0.9908..1.0020 of it), Sa its 4 H / (9 sqrt 3) within 0.3 % and Sz
    the circle's H = R - sqrt(R^2 - f^2 / 4) within 0.1 %; Sq is convex in the feed as
    f^2 is, its second difference within 0.03 nm of the scallop's 0.0355 nm (-0.097 to
    +0.19 nm before the numbers were averaged over where the marks fall).  The prediction
    says which window it used."""
    r = 0.525
    f = np.linspace(0.006, 0.012, 13)
    got, pr = _series(FLAT, f)
    sq = f ** 2 / (r * math.sqrt(720.0)) * 1e6
    h = (r - np.sqrt(r * r - f * f / 4)) * 1e6
    sa = 4 * f ** 2 / (8 * r) / (9 * math.sqrt(3.0)) * 1e6
    assert np.abs(got[:, 0] / sq - 1).max() < 3e-3, got[:, 0] / sq
    assert np.abs(got[:, 1] / sa - 1).max() < 3e-3, got[:, 1] / sa
    assert np.abs(got[:, 2] / h - 1).max() < 1e-3, got[:, 2] / h
    d2, d2_scallop = np.diff(got[:, 0], 2), np.diff(sq, 2)
    assert np.all(d2 > 0) and np.abs(d2 - d2_scallop).max() < 0.03, d2
    assert np.all(np.diff(got[:, 1], 2) > 0)
    w = pr["window"]
    assert w["region_mm"] == SERIES_WINDOW and w["positions"] == 4 and not w["grown"]
    assert w["marks"] == "circular" and w["periods"] == pytest.approx(0.11 / 0.012)
    text = "\n".join(prediction_lines(pr))
    assert "window 0.11 x 0.11 mm at x 0.28..0.39, y -0.055..0.055 mm: 9.17 periods" in text
    assert "over where the marks fall in the window: +- " in text


def test_no_prediction_uncertainty_skips_its_simulations_and_says_so(tmp_path, monkeypatch):
    """A fit with a standard error of the nose radius: the prediction's uncertainty takes
    its two points' simulations at each of the window's positions (4 + 2 x 4); with
    uncertainty off only the prediction's own 4 run, and its output says the uncertainty
    was not computed."""
    calls = []
    real = _fit_predict.simulate
    monkeypatch.setattr(_fit_predict, "simulate", lambda s: calls.append(s) or real(s))
    scene = load_scene("sts_sinusoidal_grid", FLAT)
    rec = _record({"tool.nose_radius": 0.525}, {"tool.nose_radius": 0.003}, np.eye(1),
                  bounds={"tool.nose_radius": [0.01, 50.0]})
    args = (scene.to_dict(), ["process.feed_mm_per_min=0.4"], preset_fill(scene),
            SERIES_WINDOW, rec, _evaluation_pixel)
    (tmp_path / "on").mkdir()
    on = _fit_predict.predict_next_cut(tmp_path / "on", *args)
    assert len(calls) == 12 and on["uncertainty"]["simulations"] == 12
    assert on["uncertainty"]["points"] == 3 and on["uncertainty"]["window_positions"] == 4
    assert "3 points x 4 window positions = 12 simulations" in "\n".join(prediction_lines(on))
    calls.clear()
    (tmp_path / "off").mkdir()
    off = _fit_predict.predict_next_cut(tmp_path / "off", *args, uncertainty=False)
    assert len(calls) == 4
    assert off["uncertainty"] is None and off["uncertainty_skipped"] is True
    assert "--no-prediction-uncertainty" in off["no_uncertainty"]
    assert off["values"] == on["values"]
    lines = prediction_lines(off)
    assert lines[0].startswith("prediction (process.feed_mm_per_min=0.4): uncertainty not "
                               "computed: --no-prediction-uncertainty")
    assert "residual Sq = " in lines[2] and "(uncertainty not computed;" in lines[2]
    saved = json.loads((tmp_path / "off" / "predict" / "metrics.json").read_text())
    assert saved["prediction"]["uncertainty_skipped"] is True


def test_no_prediction_uncertainty_is_refused_without_a_prediction(tmp_path, capsys):
    z = np.zeros((32, 32))
    meas = write_measurement_exr(tmp_path / "height.exr", z, np.ones_like(z, bool),
                                 pixel=0.001, origin=(0.3, -0.05),
                                 attrs={"objective": "20x", "mode": "psi"})
    prof = tmp_path / "slice.csv"
    prof.write_text("x (um), height (um)\n" + "".join(f"{i:.1f}, 0.0\n" for i in range(200)))
    for measured, message in (
            (meas, "--no-prediction-uncertainty is for --predict: no prediction was asked"),
            (prof, "--no-prediction-uncertainty is for a measured map")):
        rc = main(["fit", str(measured), "--scene", "sts_sinusoidal_grid", "--free",
                   "tool.nose_radius", "--no-prediction-uncertainty", "--out",
                   str(tmp_path / "out")])
        err = capsys.readouterr().err.strip().splitlines()
        assert rc == 1 and len(err) == 1 and message in err[0], err
        assert not (tmp_path / "out").exists()


# ------------------------------------------------------------------ the command line
#: the random parts of the shipped lathe and material set to 0 (as in tests/test_fit.py)
QUIET = ["machine.x.noise_nm=0", "machine.z.noise_nm=0", "machine.c.noise_urad=0",
         "machine.errors.radial_async_nm=0", "machine.errors.axial_async_nm=0",
         "material.texture_nm=0"]
#: the truth: nose radius 0.525 mm and feed 0.51 mm/min (the shipped scene: 0.514, 0.5)
TOOL = ["tool.nose_radius=0.525", "process.feed_mm_per_min=0.51"]
#: the field (mm) and the fit window: 0.11 mm, 8.6 feed periods (tests/test_fit.py)
FIELD = (0.25, -0.1, 0.45, 0.1)
WINDOW = "0.11"
#: the next cut: the spindle slowed from 50 to 40 rpm (a feed per revolution 25 % longer),
#: so that both fitted keys (the nose radius and the feed in mm/min) reach the prediction
NEXT = "process.spindle_rpm=40"


def _truth(folder: Path, *, quiet: bool) -> Path:
    """The shipped grid scene cut at TOOL over FIELD, imaged by the virtual interferometer
    and measured: ``height.exr``."""
    x0, y0, x1, y1 = FIELD
    m = 0.03
    scene = load_scene("sts_sinusoidal_grid", [
        *(QUIET if quiet else []), *TOOL, "simulation.pixel=0.0005",
        f"simulation.region=[{x0 - m}, {y0 - m}, {x1 + m}, {y1 + m}]",
        f"render.interferometer.field_of_view=[{x0}, {y0}, {x1}, {y1}]"])
    run_render(scene, folder / "render", kind="interferometer")
    run_measure(folder / "render" / "interferogram.exr", folder / "measure")
    return folder / "measure" / "height.exr"


def _fit(measured: Path, out: Path, free: str, caplog) -> tuple[dict, dict, list[str]]:
    caplog.clear()
    with caplog.at_level("INFO", logger="render_inspect"):
        assert main(["fit", str(measured), "--scene", "sts_sinusoidal_grid", "--free", free,
                     "--seed", "1", "--global", "0", "--profile-points", "0", "--window",
                     WINDOW, *[f"--set={s}" for s in QUIET], "--predict", NEXT,
                     "--out", str(out)]) == 0
    lines = [r.getMessage() for r in caplog.records if r.name == "render_inspect"]
    rec = json.loads((out / "fit.json").read_text())
    return rec, json.loads((out / "predict" / "metrics.json").read_text()), lines


def _simulate_prediction(out: Path, rec: dict, values: dict, region: list[float]):
    """The prediction simulated here, independently of ``fit``: the fitted scene
    (scene.json) with ``values`` changed and the next cut's setting, over ``region`` at the
    prediction's pixel."""
    data = json.loads((out / "scene.json").read_text())
    items = [f"{k}={v!r}" for k, v in values.items()] + [
        NEXT, f"simulation.region={json.dumps(region)}",
        f"simulation.pixel={rec['prediction']['simulation_pixel_mm']!r}"]
    return simulate(scene_from_dict(apply_overrides(data, items), "(test)"))


def _positions(rec: dict) -> list[list[float]]:
    """The regions of the prediction window's positions, from fit.json."""
    w = rec["prediction"]["window"]
    x0, y0, x1, y1 = w["region_mm"]
    return [[x0 + dx, y0 + dy, x1 + dx, y1 + dy] for dx, dy in w["shifts_mm"]]


def _averaged(out: Path, rec: dict, values: dict) -> dict:
    """The prediction's residual numbers at ``values``: the mean over the positions."""
    ms = [_simulate_prediction(out, rec, values, r).metrics for r in _positions(rec)]
    return {**ms[0], "residual": {k: float(np.mean([m["residual"][k] for m in ms]))
                                  for k in ("Sq_nm", "Sa_nm", "Sz_nm")}}


@pytest.mark.slow
def test_the_prediction_carries_the_fits_uncertainty(tmp_path, caplog):
    """The quiet lathe's cut at known keys, fitted for the nose radius and the feed, the
    next cut predicted at 40 rpm: (a) the prediction at the fitted values is the mean of
    the simulations of the fitted scene over the window's four positions, the first (the
    fit's window) written bit for bit; (b) the stated uncertainty agrees with simulations
    at the fitted values +- one standard error of each key (averaged over the positions as
    the prediction is): the cusp height's sensitivities to 2 % and Sq's to 10 %, both
    linear in the keys (their second-order part below their first; read over the window at
    one place of the marks, Sq's second order was 17 times its first), and every
    brute-force Sq within the expanded uncertainty (k = 2) of the predicted value, or
    within as many standard uncertainties as the point lies standard deviations of the
    keys' joint distribution away where that is more, Sz within it widened by twice its
    spread over the positions."""
    truth = _truth(tmp_path / "truth", quiet=True)
    out = tmp_path / "fit"
    rec, pm, lines = _fit(truth, out, "tool.nose_radius,process.feed_mm_per_min", caplog)
    assert rec["model_check"]["after"]["describes"]
    unc = pm["prediction"]["uncertainty"]
    assert pm["prediction"]["measurement_backed"] is True
    assert rec["prediction"]["uncertainty"] == unc
    assert unc["keys"] == ["tool.nose_radius", "process.feed_mm_per_min"]
    assert unc["simulations"] == 20 and unc["points"] == 5 and unc["window_positions"] == 4
    assert unc["complete"] and unc["seed"] == 0
    assert "outside --max-evaluations" in unc["budget"]
    q = unc["quantities"]
    # (a) the prediction at the fitted values: the window's positions simulated here
    w = rec["prediction"]["window"]
    assert w["region_mm"] == rec["placement"]["window_mm"] and not w["grown"]
    assert w["positions"] == 4 and w["periods"] > MIN_PERIODS
    first = _simulate_prediction(out, rec, {}, _positions(rec)[0])
    assert first.metrics["residual"] == pm["residual"]
    hm = read_heightmap_exr(out / "predict" / "heightmap.exr")
    assert np.array_equal(hm.machined, first.heightmap.machined.astype(np.float32))
    centre = _averaged(out, rec, {})
    for path in ("residual.Sq_nm", "residual.Sa_nm", "residual.Sz_nm"):
        assert q[path]["value"] == pytest.approx(centre["residual"][path.split(".")[1]],
                                                 rel=1e-12)
    # (b) brute force: each key at +- its standard error, the other at its fitted value
    p = rec["parameters"]
    keys = unc["keys"]
    se = np.array([p[k]["stderr"] for k in keys])
    brute = {}
    for k, s in zip(keys, se):
        for side in (1, -1):
            brute[k, side] = _averaged(out, rec, {k: p[k]["value"] + side * s})
    corr = np.array([[rec["correlation"][a][b] for b in keys] for a in keys])
    cov = corr * np.outer(se, se)
    # (Sq, a statistic of the simulated window, to 10 %: a standard error of the feed moves
    # it by 0.3-0.6 %, and what is left of where the marks fall moves the mean over the
    # window's positions by up to 0.1 % of Sq (measured: 0.013 nm of 12.1 nm between the
    # feed's two brute-force points at +- 0.17 %), an error of each simulated number that
    # the comparison allows for: in the brute-force difference over the two standard
    # errors, and in the prediction's, which takes its per-key sensitivities from
    # differences along the covariance's eigen-directions (steps of one standard deviation
    # along each: with the keys correlated at 0.95 the shorter is about a fifth of the
    # feed's standard error, and the error of a difference along it is divided by that
    # step, then shared out to the keys by the directions' components))
    w, v = np.linalg.eigh(cov)
    along = np.abs(v) @ (1.0 / np.sqrt(w))   # per key: sum over directions |v_ki| / sd_i
    for path, rel in (("scallop.height_nm", 0.02), ("residual.Sq_nm", 0.10)):
        group, name = path.split(".")
        g = np.array([(brute[k, 1][group][name] - brute[k, -1][group][name]) / (2 * s)
                      for k, s in zip(keys, se)])
        sampled = 0.0 if path.startswith("scallop") else 1e-3 * q[path]["value"]
        for j, k in enumerate(keys):
            assert abs(q[path]["per_key"][k]["sensitivity"] - g[j]) <= \
                rel * abs(g[j]) + sampled / 2 * (1.0 / se[j] + along[j]), (path, k, g[j])
        assert q[path]["u_first_order"] == pytest.approx(math.sqrt(g @ cov @ g), rel=rel)
        assert q[path]["smooth"] and q[path]["u"] > 0, q[path]
    # every brute-force Sq within the expanded uncertainty; Sz, the window's extreme, within
    # it widened by twice its spread over where the marks fall (its own sampling scatter,
    # which the parameters' uncertainty does not hold).  A brute-force point moves one key
    # by its standard error with the other held, which the keys' joint distribution makes
    # unlikely where they are correlated: it lies sqrt(s_k^2 (C^-1)_kk) standard deviations
    # of that distribution from the fitted values (1 / sqrt(1 - 0.95^2) = 3.2 here), and a
    # number linear in the keys moves there by at most that many standard uncertainties
    # (Cauchy-Schwarz); so each point within the larger of k = 2 and its own distance
    reach = se * np.sqrt(np.diag(np.linalg.inv(cov)))
    spread = pm["prediction"]["window_spread"]
    for path, wide in (("residual.Sq_nm", 0.0), ("residual.Sz_nm", 2 * spread["residual.Sz_nm"])):
        group, name = path.split(".")
        for (k, _), m in brute.items():
            far = max(q[path]["coverage_factor"], float(reach[keys.index(k)]))
            assert abs(m[group][name] - q[path]["value"]) <= far * q[path]["u"] + wide, (
                path, k, m[group][name], q[path])
    # said in the summary and on the page, with units and both coverage factors
    text = "\n".join(lines)
    assert "prediction (process.spindle_rpm=40), the fitted keys' uncertainty propagated" in text
    assert "5 points x 4 window positions = 20 simulations" in text
    assert "  window 0.1099 x 0.1099 mm at x 0.2951..0.4049" in text
    assert f"residual Sq = {q['residual.Sq_nm']['value']:.4g} +- " in text
    assert "(standard uncertainty, k=1; k=2: +- " in text
    html = (out / "fit.html").read_text()
    assert "standard uncertainty (k=1)" in html and "expanded (k=2)" in html
    assert "spread over where the marks fall" in html and "Window 0.1099 x 0.1099 mm" in html


@pytest.mark.slow
def test_a_fit_that_does_not_describe_the_part_says_so_at_the_predictions_top(tmp_path,
                                                                             caplog):
    """The shipped lathe's cut (its random parts on) fitted with a scene whose random parts
    are 0: the misfit is thousands of times the noise floor the model expects, the verdict
    is that it does not describe the measurement, and the prediction says so first, with
    no uncertainty and no further simulation."""
    truth = _truth(tmp_path / "truth", quiet=False)
    rec, pm, lines = _fit(truth, tmp_path / "fit", "tool.nose_radius", caplog)
    assert not rec["model_check"]["after"]["describes"]
    pr = pm["prediction"]
    assert pr["measurement_backed"] is False and pr["uncertainty"] is None
    assert "does not describe" in pr["no_uncertainty"] and "model's, not the part's" in pr["note"]
    # the mean over the window's positions, the one number the summary and fit.json give
    assert pr["values"]["residual.Sq_nm"] == rec["prediction"]["residual"]["Sq_nm"]
    assert pr["window"]["positions"] == 4
    first = next(i for i, t in enumerate(lines) if t.startswith("prediction ("))
    assert lines[first].startswith("prediction (process.spindle_rpm=40): NOT a "
                                   "measurement-backed forecast")
    assert "Not a measurement-backed forecast" in (tmp_path / "fit" / "fit.html").read_text()


@pytest.mark.slow
def test_the_shipped_lathes_predicted_roughness_is_smooth_in_the_feed():
    """The shipped lathe (its random parts 0) predicted at 13 feeds of 0.008..0.012
    mm/rev: Sq and Sa rise with the feed and are convex in it, their second differences
    within 0 .. 0.05 nm (the scallop's alone is 0.0355 nm; read over the window at one
    place of the marks they were -0.038 .. +0.151 nm for Sq, -0.050 .. +0.167 nm for
    Sa).  Sz, the extreme of the window, stays the roughest: its second differences are
    within +-0.5 nm (of 29-48 nm), no more than four times the largest spread of Sz over
    the positions."""
    got, pr = _series(QUIET + ["tool.nose_radius=0.525"], np.linspace(0.008, 0.012, 13))
    for k in (0, 1):
        d2 = np.diff(got[:, k], 2)
        assert np.all(np.diff(got[:, k]) > 0) and d2.min() > 0 and d2.max() < 0.05, d2
    assert np.abs(np.diff(got[:, 2], 2)).max() < 0.5
