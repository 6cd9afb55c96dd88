"""``--max-evaluations N`` is a hard limit: the search, the standard errors' differences,
the misfit profiles and each arm's own estimate all come out of N; a budget that leaves
too few for the standard errors gives none and says so.  A fit that ends in a window whose
marks are not one family prints no standard error anywhere, the arms' line included; a
virtual instrument that does not follow the simulated cut is named as the cause of a
period that is off."""

from __future__ import annotations

import sys
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from render_inspect.core.errors import InputError
from render_inspect.fit import (ArmsTarget, EvaluationCache, Evaluator, FreeParameter,
                                MisfitSpec, ProfileSpec, arm_estimates, make_profile_target,
                                make_target, solve)
from render_inspect.fit._arms import arms_text
from render_inspect.fit._solve import BudgetExhausted

sys.path.insert(0, str(Path(__file__).resolve().parent))
from test_fit import _cusps  # noqa: E402

TRUTH = {"f": 0.0104, "R": 0.47, "w": 4e-6}


def _model(task):
    """An analytic forward model: marks of feed ``f`` (the free key), the nose radius and
    waviness of the truth."""
    z, _ = _cusps(task["f"], TRUTH["R"], n=192, amp_wave=TRUTH["w"])
    return z, {}


def _fit(tmp_path, n_max, **kw):
    z, px = _cusps(TRUTH["f"], TRUTH["R"], n=192, amp_wave=TRUTH["w"])
    target = make_target(z, pixel=(px, px), origin=(0.0, 0.0), spec=MisfitSpec())
    params = [FreeParameter("f", 0.0100, 0.005, 0.02, 0.001)]
    ev = Evaluator(params, target, lambda vals: {"f": vals["f"]}, _model,
                   EvaluationCache(tmp_path / f"cache{n_max}"), max_evaluations=n_max)
    return solve(params, ev, **kw), ev


@pytest.mark.parametrize("n_max", [6, 9, 14])
def test_max_evaluations_is_never_passed(tmp_path, n_max):
    """Budgets the search runs out of: every evaluation (the standard errors' too) within
    N, the count and the status message saying the same number."""
    res, ev = _fit(tmp_path, n_max, profile_points=1)
    assert ev.count <= n_max and res.evaluations == ev.count, (ev.count, n_max)
    assert res.status == "budget", res.message
    assert f"--max-evaluations {n_max}" in res.message
    assert res.budget["max_evaluations"] == n_max
    assert res.budget["search"] + res.budget["kept_for_standard_errors"] == n_max
    if not np.all(np.isfinite(res.stderr)):
        assert "no standard errors" in res.message


@pytest.mark.parametrize("n_max, rel", [(40, 0.03), (80, 1e-3)])
def test_the_feed_is_recovered_within_the_budget_and_its_standard_error(tmp_path, n_max, rel):
    """The known feed recovered within N evaluations: the standard error (taken within N
    too) covers the distance to the truth, whether the search ran out or not."""
    res, ev = _fit(tmp_path, n_max, profile_points=1)
    assert ev.count <= n_max and res.evaluations <= n_max
    assert res.values[0] == pytest.approx(TRUTH["f"], rel=rel)
    assert np.isfinite(res.stderr[0]) and res.stderr[0] > 0
    assert abs(res.values[0] - TRUTH["f"]) <= 2 * res.stderr[0] + 1e-6 * TRUTH["f"]


def _arms_target():
    spacing, n, lag = 0.00087, 300, 30

    def cusps(period, count, phase=0.0):
        x = np.arange(count) * spacing + phase
        u = np.mod(x, period) - period / 2
        return u * u / (2 * 0.2)

    arms = [make_profile_target(cusps(p, n, ph), spacing=spacing, lag=lag, spec=ProfileSpec())
            for p, ph in ((0.040, 0.003), (0.0412, 0.011))]
    return ArmsTarget(arms), cusps, n + 2 * lag


def test_arm_estimates_stop_at_the_budget_and_say_so():
    target, cusps, count = _arms_target()

    class Capped:
        """Three evaluations allowed: the one at the solution, not the scan's four."""

        def __init__(self):
            self.target, self.count, self.max_evaluations = target, 0, 3

        def evaluate(self, xs, budget=True):
            if self.count + len(xs) > self.max_evaluations:
                raise BudgetExhausted()
            self.count += len(xs)
            return [SimpleNamespace(height=np.vstack([cusps(float(x[0]), count)] * 2),
                                    values=np.array(x), error=None) for x in xs]

    par = FreeParameter("process.feed_mm_per_min", 0.04, 0.02, 0.08, 0.004)
    ev = Capped()
    est = arm_estimates([par], ev, [0.0406], [0.0001])
    assert est.get("budget") and "--max-evaluations 3" in est["error"]
    assert ev.count <= 3


def test_arms_line_gives_no_standard_error_where_the_fit_gives_none():
    comb = {"difference_relative": -0.015, "difference_over_stderr": 4.7, "disagree": True,
            "stderr_fit": 0.0035, "u_arms": 0.019, "stderr": 0.02}
    text = arms_text("process.feed_mm_per_min", comb, 2.644, 2.684, unit=10.0,
                     stderr=False)
    assert "from the fit" not in text and "combined" not in text
    assert "no standard error" in text and "-1.5 %" in text
    assert "0.19 from the arms" in arms_text("k", comb, 2.644, 2.684, unit=10.0)
    # each number with its unit where one is given
    text = arms_text("process.feed_mm_per_min", comb, 2.644, 2.684, unit=10.0,
                     unit_name="um")
    assert "the window's arm 26.44 um, the other arm 26.84 um" in text
    assert "(0.035 um from the fit, 0.19 um from the arms, 0.2 um combined)" in text


def _period_check(cut_period_mm):
    from render_inspect.pipeline._fit_profile import _check_before

    target = SimpleNamespace(peak=1 / 0.04107)  # measured 41.07 um
    pred = SimpleNamespace(centroid=1 / 0.03825)  # the scene through its instrument
    family = {"one_family": True, "reason": ""}
    return _check_before(target, pred, ["tool.nose_radius"], None, family,
                         cut_period=lambda: cut_period_mm, mode="psi")


def test_an_instrument_that_does_not_follow_the_cut_is_named():
    # the simulated cut's marks are 40.8 um: the virtual measurement (38.25) lost them
    with pytest.raises(InputError) as err:
        _period_check(0.0408)
    msg = str(err.value)
    assert "render.interferometer.mode" in msg and "'psi'" in msg and "csi" in msg
    assert "\n" not in msg
    # the cut itself at 38.25 um: the scene's path, not its instrument, is off
    with pytest.raises(InputError, match="check the window's place"):
        _period_check(0.03825)
