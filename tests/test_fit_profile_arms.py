"""``fit`` on both arms of a diameter slice: the other arm's stretch found from the line's
geometry, the arms' disagreement folded into the standard error, and a known answer
(a diameter simulated with a known feed and a lateral scale error on one arm) recovered
within its stated uncertainty, the disagreement reported."""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
import pytest

from render_inspect.core.errors import InputError
from render_inspect.fit import combine_arms

sys.path.insert(0, str(Path(__file__).resolve().parent))
from test_fit_profile import _turned, _write_profile  # noqa: E402

SPACING = 0.00087


class _Prof:
    """What :func:`profile_window` reads of a profile."""

    def __init__(self, x, z):
        self.x, self.z, self.spacing = x, z, SPACING


def test_combine_arms_adds_only_the_excess_of_the_disagreement():
    # arms that agree within their own uncertainty add nothing
    c = combine_arms(10.0, 0.02, 10.01, 0.03, 9.99, 0.03)
    assert c["u_arms"] == 0.0 and c["stderr"] == pytest.approx(0.02)
    assert not c["disagree"]
    # arms 0.6 apart with standard errors 0.03: the excess is the measurement's spread;
    # the joint value (their mean) takes half of it
    c = combine_arms(10.0, 0.02, 10.3, 0.03, 9.7, 0.03)
    u = math.sqrt(0.6 ** 2 - 2 * 0.03 ** 2) / 2
    assert c["u_arms"] == pytest.approx(u) and c["stderr"] == pytest.approx(math.hypot(0.02, u))
    assert c["disagree"] and c["difference_over_stderr"] == pytest.approx(0.6 / math.hypot(
        0.03, 0.03))


def test_other_arm_is_the_window_mirrored_about_the_axis():
    from render_inspect.pipeline._fit_profile import profile_window
    from render_inspect.pipeline._fit_profile_arms import other_arm_window

    scene = _turned()
    x = -0.4 + np.arange(921) * SPACING  # -0.4 .. 0.4 mm
    prof = _Prof(x, np.sin(x * 300.0))
    win = profile_window(prof, scene, line="-0.4,0,0.4,0", at=(0.25, 0.0), window_mm=0.2)
    other, why = other_arm_window(prof, scene, win, 0.04)
    assert why == "" and other["i1"] - other["i0"] == win["i1"] - win["i0"]
    assert other["centre_on_part_mm"][0] == pytest.approx(-0.25, abs=SPACING)
    # a window across the axis, or radii the other arm does not reach, have no other arm
    win = profile_window(prof, scene, line="-0.4,0,0.4,0", at=(0.0, 0.0), window_mm=0.2)
    assert "holds the line's closest point" in other_arm_window(prof, scene, win, 0.04)[1]
    short = _Prof(x[300:], prof.z[300:])  # -0.139 .. 0.4 mm
    win = profile_window(short, scene, line="-0.139,0,0.4,0", at=(0.25, 0.0), window_mm=0.2)
    assert "does not reach" in other_arm_window(short, scene, win, 0.04)[1]
    # a line that misses the axis is not a diameter
    win = profile_window(prof, scene, line="-0.4,0.1,0.4,0.1", at=(0.25, 0.1), window_mm=0.2)
    assert "not a diameter" in other_arm_window(prof, scene, win, 0.04)[1]


def test_arms_both_where_there_is_no_other_arm_is_refused(tmp_path):
    from render_inspect.pipeline import run_fit_profile

    p = tmp_path / "slice.csv"
    s = np.arange(460) * SPACING
    _write_profile(p, s, 1e-4 * np.sin(2 * np.pi * s / 0.036))
    with pytest.raises(InputError, match="--arms both: .*does not reach"):
        run_fit_profile(p, _turned(), ["process.feed_mm_per_min"], tmp_path / "o",
                        line="-0.1,0,0.3,0", at=(0.2, 0.0), window_mm=0.15, arms="both")
    with pytest.raises(InputError, match="--arms must be one of one, both"):
        run_fit_profile(p, _turned(), ["process.feed_mm_per_min"], tmp_path / "o",
                        line="-0.1,0,0.3,0", at=(0.2, 0.0), window_mm=0.15, arms="two")
    assert not (tmp_path / "o").exists()


def _stretch_arm(s, z, *, axis_s, scale, side):
    """The profile with the arm on ``side`` (-1: positions below the axis) stretched
    laterally by ``scale`` about the axis (an instrument's scale error on that arm)."""
    out = z.copy()
    arm = (s - axis_s) * side > 0
    src = axis_s + (s[arm] - axis_s) / scale
    out[arm] = np.interp(src, s, z)
    return out


@pytest.mark.slow
def test_both_arms_recover_the_feed_and_report_a_scale_error_on_one_arm(tmp_path):
    """A diameter simulated through the virtual white-light interferometer with a 36 um/rev
    feed, its negative arm stretched laterally by 3 % (an instrument's scale error on that
    side: marks 3 % further apart, cusps as deep): the window on the positive arm fitted with
    both arms.  The window's arm's own estimate is the feed; the stretched arm's reads
    higher (its marks' period pulls it up, its cusps' depth, which a larger feed would
    deepen, holds it back); the summary says the arms disagree, and the joint feed is within
    two of its standard errors of 36 um/rev (the arms' term is in them)."""
    from render_inspect.pipeline import run_fit_profile
    from render_inspect.pipeline._fit_profile import simulate_profile

    s, z = simulate_profile(_turned(feed=3.6), (-0.36, 0.0), (0.36, 0.0), SPACING, seed=5)
    z = _stretch_arm(s, z, axis_s=0.36, scale=1.03, side=-1)
    p = tmp_path / "diameter.csv"
    _write_profile(p, s, z)
    key = "process.feed_mm_per_min"
    rec = run_fit_profile(p, _turned(), [key], tmp_path / "fit", line="-0.36,0,0.36,0",
                          at=(0.25, 0.0), window_mm=0.2, global_points=0,
                          max_evaluations=30, profile_points=0, cache=tmp_path / "cache")
    arms = rec["arms"]
    assert arms["fitted"] == "both", arms
    assert [a["arm"] for a in arms["arms"]] == ["window", "other"]
    assert arms["arms"][1]["centre_on_part_mm"][0] == pytest.approx(-0.25, abs=0.002)
    # the measured periods: the stretched arm's 3 % longer
    periods = [a["measured_period_um"] for a in arms["arms"]]
    assert periods[1] / periods[0] == pytest.approx(1.03, abs=0.01), periods
    a = arms["parameters"][key]
    assert a["window_arm"]["value"] == pytest.approx(3.6, rel=0.006), a
    assert a["other_arm"]["value"] / a["window_arm"]["value"] - 1 > 0.012, a
    assert a["disagree"], a
    par = rec["parameters"][key]
    assert par["stderr_fit"] < par["stderr"] and par["stderr_arms"] > 0, par
    assert abs(par["value"] - 3.6) <= 2 * par["stderr"], par
    fpr = rec["feed_per_rev_mm"]
    assert abs(fpr["value"] - 0.036) <= 2 * fpr["stderr"], fpr
    assert any("the arms disagree" in line for line in rec["summary"]), rec["summary"]
    assert rec["model_check"]["after"]["describes"], rec["model_check"]["after"]
    # one arm: no other arm in the record, nor in the standard error (the record's shape
    # is what is checked: the solve is given the two start candidates only)
    one = run_fit_profile(p, _turned(), [key], tmp_path / "one", line="-0.36,0,0.36,0",
                          at=(0.25, 0.0), window_mm=0.2, global_points=0,
                          max_evaluations=2, profile_points=0, cache=tmp_path / "cache1",
                          arms="one")
    assert one["arms"]["fitted"] == "one" and "stderr_arms" not in one["parameters"][key]

def test_arm_estimates_find_each_arms_own_period():
    """Ideal cusps whose period is the fitted value (a forward model in a few lines): two
    arms measured at 40.0 and 41.2 um, the joint solution between them; each arm's own
    estimate is its own period, and the arms' disagreement is folded in."""
    from types import SimpleNamespace

    from render_inspect.fit import ArmsTarget, FreeParameter, arm_estimates
    from render_inspect.fit._profile import ProfileSpec, make_profile_target

    n, lag = 300, 40

    def cusps(period, count, phase=0.0):
        x = np.arange(count) * SPACING + phase
        u = np.mod(x, period) - period / 2
        return u * u / (2 * 0.2)

    arms = []
    for period, phase in ((0.040, 0.003), (0.0412, 0.011)):
        t = make_profile_target(cusps(period, n, phase), spacing=SPACING, lag=lag,
                                spec=ProfileSpec())
        arms.append(t)
    target = ArmsTarget(arms)

    class Evaluator:
        def __init__(self):
            self.target = target
            self.count = 0

        def evaluate(self, xs, budget=True):
            out = []
            for x in xs:
                self.count += 1
                z = cusps(float(x[0]), n + 2 * lag)
                out.append(SimpleNamespace(height=np.vstack([z, z]), values=np.array(x),
                                           error=None))
            return out

    ev = Evaluator()
    par = FreeParameter("process.feed_mm_per_min", 0.04, 0.02, 0.08, 0.004)
    est = arm_estimates([par], ev, [0.0406], [0.0001])
    a, b = est["arms"]
    assert a["values"][0] == pytest.approx(0.040, rel=2e-3), est["scans"]
    assert b["values"][0] == pytest.approx(0.0412, rel=2e-3), est["scans"]
    assert a["stderr"][0] > 0.0001 and b["stderr"][0] > 0.0001
    c = combine_arms(0.0406, 0.0001, a["values"][0], a["stderr"][0], b["values"][0],
                     b["stderr"][0])
    assert c["disagree"] and c["stderr"] > 0.0005


@pytest.mark.parametrize("s_first", [0.0, 0.123456789, -0.31415926, 1.0 / 3.0])
def test_the_simulated_band_lies_on_the_lattice_of_its_pixel(s_first):
    # wherever the stretch of the line lies, the region an evaluation simulates has its
    # corners on whole multiples of the simulation pixel (the grid's nodes fall under the
    # marks at the same places), holds the interferometer's field, and is no larger than
    # the band grown by one pixel more each way
    from render_inspect.pipeline._fit_profile_arms import _band

    px = 0.00025
    u = (math.cos(0.3), math.sin(0.3))
    fov, region, line = _band((0.7, -0.2), u, s_first, 400, 0.0011, px)
    k = np.asarray(region) / px
    assert np.allclose(k, np.round(k), rtol=0, atol=1e-9), k
    assert region[0] <= fov[0] and region[1] <= fov[1] and region[2] >= fov[2] \
        and region[3] >= fov[3]
    assert line["s0"] == s_first and line["count"] == 400
    grown = [fov[0] - region[0], fov[1] - region[1], region[2] - fov[2], region[3] - fov[3]]
    assert max(grown) - min(grown) < px + 1e-12


@pytest.mark.slow
def test_two_windows_of_a_line_see_the_same_cut_where_they_overlap():
    # the bands of two windows of one line (starting 10.3 pixels apart along it) sample
    # the same cut at the positions they share: their grids' nodes are the same points of
    # the part.  (Before, each band's grid sat where its window put it, and the cusps
    # sampled between its nodes differed by the interpolation: nanometres)
    from render_inspect.pipeline._fit import _evaluation_pixel
    from render_inspect.pipeline._fit_profile_arms import _band
    from render_inspect.pipeline._fit_profile_model import simulated_cut

    scene = _turned()
    d = scene.model_dump(mode="json")
    d["machine"] = {"preset": "ideal"}
    d["material"] = {"preset": "ideal"}
    px = _evaluation_pixel(scene)
    p0, u, step, count = (0.1, 0.0), (1.0, 0.0), 0.00087, 60
    shared = {"p0": list(p0), "direction": list(u), "s0": 0.2 + 10 * step, "step": step,
              "count": count - 10}
    cuts = []
    for s0 in (0.2, 0.2 + 10.3 * px):
        _, region, _ = _band(p0, u, s0, count, step, px)
        sim = {**d["simulation"], "region": region, "pixel": px}
        cuts.append(simulated_cut({"scene": {**d, "simulation": sim}, "seed": 0,
                                   "line": shared}))
    assert np.isfinite(cuts[0]).all() and np.isfinite(cuts[1]).all()
    assert np.ptp(cuts[0]) > 1e-5      # the marks (tens of nm) are there to be sampled
    np.testing.assert_allclose(cuts[1], cuts[0], rtol=0, atol=1e-12)
