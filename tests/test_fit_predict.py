"""``fit --predict``: the prediction of the next cut carries the fit's uncertainty.

Fast tests check the propagation against analytic forward models (a linear one: the
uncertainty is exactly sqrt(g^T C g); a quadratic one: the second-order shift is exactly
tr(H C) / 2) and what it says where the fit gives no standard error or does not describe
the measurement.  The slow tests fit a map that the project's own cut and virtual
instrument made at known keys and check the predicted uncertainty against simulations at
the fitted values +- one standard error."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from render_inspect.cli import main
from render_inspect.fit import (COVERAGE_FACTOR, combine_propagation, plan_propagation,
                                prediction_lines)
from render_inspect.io import read_heightmap_exr
from render_inspect.pipeline import run_measure, run_render, simulate
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


def _simulate_prediction(out: Path, rec: dict, values: dict):
    """The prediction simulated here, independently of ``fit``: the fitted scene
    (scene.json) with ``values`` changed and the next cut's setting, over the fit window at
    the prediction's pixel."""
    data = json.loads((out / "scene.json").read_text())
    items = [f"{k}={v!r}" for k, v in values.items()] + [
        NEXT, f"simulation.region={json.dumps(rec['placement']['window_mm'])}",
        f"simulation.pixel={rec['prediction']['simulation_pixel_mm']!r}"]
    return simulate(scene_from_dict(apply_overrides(data, items), "(test)"))


@pytest.mark.slow
def test_the_prediction_carries_the_fits_uncertainty(tmp_path, caplog):
    """The quiet lathe's cut at known keys, fitted for the nose radius and the feed, the
    next cut predicted at 40 rpm: (a) the prediction at the fitted values is the one
    simulation of the fitted scene, bit for bit; (b) the stated uncertainty agrees with
    simulations at the fitted values +- one standard error of each key: the cusp height
    (smooth in the keys) to 2 %, and every brute-force Sq and Sz within the expanded
    uncertainty (k = 2) of the predicted value."""
    truth = _truth(tmp_path / "truth", quiet=True)
    out = tmp_path / "fit"
    rec, pm, lines = _fit(truth, out, "tool.nose_radius,process.feed_mm_per_min", caplog)
    assert rec["model_check"]["after"]["describes"]
    unc = pm["prediction"]["uncertainty"]
    assert pm["prediction"]["measurement_backed"] is True
    assert rec["prediction"]["uncertainty"] == unc
    assert unc["keys"] == ["tool.nose_radius", "process.feed_mm_per_min"]
    assert unc["simulations"] == 5 and unc["complete"] and unc["seed"] == 0
    assert "outside --max-evaluations" in unc["budget"]
    q = unc["quantities"]
    # (a) the prediction at the fitted values: the same simulation as before, bit for bit
    centre = _simulate_prediction(out, rec, {})
    assert centre.metrics["residual"] == pm["residual"]
    assert q["residual.Sq_nm"]["value"] == pm["residual"]["Sq_nm"]
    hm = read_heightmap_exr(out / "predict" / "heightmap.exr")
    assert np.array_equal(hm.machined, centre.heightmap.machined.astype(np.float32))
    # (b) brute force: each key at +- its standard error, the other at its fitted value
    p = rec["parameters"]
    keys = unc["keys"]
    se = np.array([p[k]["stderr"] for k in keys])
    brute = {}
    for k, s in zip(keys, se):
        for side in (1, -1):
            brute[k, side] = _simulate_prediction(out, rec, {k: p[k]["value"] + side * s}).metrics
    corr = np.array([[rec["correlation"][a][b] for b in keys] for a in keys])
    cov = corr * np.outer(se, se)
    g = np.array([(brute[k, 1]["scallop"]["height_nm"] - brute[k, -1]["scallop"]["height_nm"])
                  / (2 * s) for k, s in zip(keys, se)])
    h = q["scallop.height_nm"]
    for j, k in enumerate(keys):
        assert h["per_key"][k]["sensitivity"] == pytest.approx(g[j], rel=0.02)
    assert h["u_first_order"] == pytest.approx(math.sqrt(g @ cov @ g), rel=0.02)
    assert h["smooth"] and h["u"] > 0
    for path in ("residual.Sq_nm", "residual.Sz_nm"):
        group, name = path.split(".")
        for m in brute.values():
            assert abs(m[group][name] - q[path]["value"]) <= q[path]["U"], (path, m[group][name],
                                                                            q[path])
    # said in the summary and on the page, with units and both coverage factors
    text = "\n".join(lines)
    assert "prediction (process.spindle_rpm=40), the fitted keys' uncertainty propagated" in text
    assert f"residual Sq = {q['residual.Sq_nm']['value']:.4g} +- " in text
    assert "(standard uncertainty, k=1; k=2: +- " in text
    html = (out / "fit.html").read_text()
    assert "standard uncertainty (k=1)" in html and "expanded (k=2)" in html


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
    assert pr["values"]["residual.Sq_nm"] == pm["residual"]["Sq_nm"]
    first = next(i for i, t in enumerate(lines) if t.startswith("prediction ("))
    assert lines[first].startswith("prediction (process.spindle_rpm=40): NOT a "
                                   "measurement-backed forecast")
    assert "Not a measurement-backed forecast" in (tmp_path / "fit" / "fit.html").read_text()
