"""Morris elementary effects: the design (one factor at a time, each once, on the level
grid), the indices against functions whose elementary effects are known in closed form, and
a Morris sweep run on Dask whose indices follow the feed scallop's closed form."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from numpy.testing import assert_allclose

from render_inspect.batch import (MorrisConfig, elementary_effects, morris_design,
                                  morris_indices, morris_unit_design, read_sweep)
from render_inspect.core.errors import InputError


def test_trajectories_change_one_factor_at_a_time_by_delta():
    k, r, p = 5, 12, 4
    u = morris_unit_design(k, r, p, seed=3)
    assert u.shape == (r, k + 1, k)
    delta = p / (2 * (p - 1))
    levels = np.arange(p) / (p - 1)
    assert np.all(np.min(np.abs(u[..., None] - levels), axis=-1) < 1e-12)   # on the grid
    for traj in u:
        d = np.diff(traj, axis=0)
        assert np.all(np.count_nonzero(np.abs(d) > 1e-12, axis=1) == 1)    # one at a time
        assert_allclose(np.abs(d).sum(axis=1), delta, atol=1e-12)
        assert sorted(np.argmax(np.abs(d), axis=1)) == list(range(k))      # each once
    assert_allclose(morris_unit_design(k, r, p, seed=3), u)
    assert not np.allclose(morris_unit_design(k, r, p, seed=4), u)
    with pytest.raises(ValueError, match="even"):
        morris_unit_design(3, 2, 3)


def test_elementary_effects_of_a_linear_function_with_one_interaction():
    """y = sum a_i u_i + b u_0 u_1: EE_i = a_i exactly for the linear factors (sigma 0),
    EE_0 = a_0 + b u_1 and EE_1 = a_1 + b u_0 (between a and a + b, sigma > 0)."""
    a = np.array([2.0, -1.0, 0.5, 0.0, 3.0])
    b = 4.0
    u = morris_unit_design(a.size, 40, 4, seed=1)
    y = (u * a).sum(axis=-1) + b * u[..., 0] * u[..., 1]
    ee = elementary_effects(u, y)
    for i in (2, 3, 4):
        assert_allclose(ee[:, i], a[i], atol=1e-12)
    for i in (0, 1):
        assert np.all(ee[:, i] >= a[i] - 1e-12) and np.all(ee[:, i] <= a[i] + b + 1e-12)
        assert ee[:, i].std() > 0.5
    # the interaction's elementary effects are the other factor's level at the step
    for t in range(u.shape[0]):
        d = np.diff(u[t], axis=0)
        j = int(np.flatnonzero(np.abs(d[:, 0]) > 0)[0])
        assert ee[t, 0] == pytest.approx(a[0] + b * u[t, j, 1])


def _config(**kw):
    spec = {"trajectories": 20, "levels": 4, "seed": 2, "outputs": ["y"],
            "factor": [{"key": "a.lin", "low": 1.0, "high": 3.0},
                       {"key": "a.log", "low": 10.0, "high": 1000.0, "log": True},
                       {"key": "a.none", "low": 0.0, "high": 5.0}]}
    spec.update(kw)
    return MorrisConfig.model_validate(spec)


def test_indices_in_factor_units_linear_and_logarithmic():
    """y = 2 v_lin + 3 ln(v_log): mu* = 2 (3 - 1) and 3 ln(100), sigma 0; an inert factor
    gets mu* = 0.  Results are found by the factor values (a lookup)."""
    cfg = _config()
    design = cfg.design()
    table = {}
    for traj in design:
        for p in traj:
            table[tuple(sorted(p.items()))] = {"y": 2 * p["a.lin"] + 3 * math.log(p["a.log"])}
    res = morris_indices(cfg, lambda p: table.get(tuple(sorted(p.items()))))
    ind = res["indices"]["y"]
    assert ind["a.lin"]["mu_star"] == pytest.approx(4.0)
    assert ind["a.log"]["mu_star"] == pytest.approx(3 * math.log(100.0))
    assert ind["a.none"]["mu_star"] == 0.0
    assert ind["a.lin"]["sigma"] == pytest.approx(0.0, abs=1e-9)
    assert res["ranking"]["y"] == ["a.log", "a.lin", "a.none"]
    assert res["complete"] == cfg.trajectories
    # values stay inside the ranges, the log factor on its logarithmic levels
    vals = sorted({p["a.log"] for traj in design for p in traj})
    assert_allclose(vals, [10.0, 10.0 * 100 ** (1 / 3), 10.0 * 100 ** (2 / 3), 1000.0])
    # a missing result drops its trajectory's effects, not the rest
    first = tuple(sorted(design[0][0].items()))
    res2 = morris_indices(cfg, lambda p: None if tuple(sorted(p.items())) == first
                          else table.get(tuple(sorted(p.items()))))
    assert res2["complete"] == cfg.trajectories - 1


@pytest.mark.parametrize("bad, needle", [
    ({"levels": 3}, "levels must be even"),
    ({"factor": [{"key": "a.b", "low": 2.0, "high": 1.0}]}, "high must be > low"),
    ({"factor": [{"key": "a.b", "low": 0.0, "high": 1.0, "log": True}]}, "low must be > 0"),
    ({"factor": [{"key": "ab", "low": 0.0, "high": 1.0}]}, "dotted scene key"),
])
def test_bad_designs_name_the_key(bad, needle):
    with pytest.raises(Exception, match=needle):
        _config(**bad)


MORRIS_SWEEP = """
name = "morris_small"
scene = "sts_sinusoidal_grid"
[set]
"machine.preset" = "ideal"
"material.preset" = "ideal"
"simulation.region" = [-0.04, -0.04, 0.04, 0.04]
"simulation.pixel" = 0.001
"process.workpiece_radius" = 0.1
"process.spindle_rpm" = 100
[morris]
trajectories = 2
levels = 4
seed = 5
outputs = ["residual.Sq_nm"]
[[morris.factor]]
key = "process.feed_mm_per_min"
low = 0.4
high = 1.0
[[morris.factor]]
key = "simulation.seed"
low = 0
high = 9
integer = true
"""


@pytest.mark.slow
def test_morris_sweep_on_dask_follows_the_scallop(tmp_path):
    """A Morris sweep on a LocalCluster: the feed's elementary effects are the change of
    the feed scallop's Sq = f^2 / (R sqrt 720) (within the 3 % the turned grid follows it);
    the seed has no effect on an ideal machine and material (mu* = 0)."""
    from render_inspect.pipeline import run_sweep

    path = tmp_path / "morris_small.toml"
    path.write_text(MORRIS_SWEEP)
    spec = read_sweep(path)
    assert len(spec.studies()) == 1 and spec.studies()[0].name == "morris"
    info = run_sweep(path, tmp_path / "out", workers=1, progress=False)
    assert info["failed"] == 0
    m = json.loads((tmp_path / "out" / "morris.json").read_text())
    assert m["complete"] == 2
    ind = m["indices"]["residual.Sq_nm"]
    assert ind["simulation.seed"]["mu_star"] == 0.0
    r = 0.514
    sq = lambda fpm: (fpm / 100) ** 2 / (r * math.sqrt(720.0)) * 1e6  # noqa: E731
    cfg = spec.morris
    expect = []
    for traj in cfg.design():
        for p0, p1 in zip(traj[:-1], traj[1:]):
            if p0["process.feed_mm_per_min"] != p1["process.feed_mm_per_min"]:
                du = (p1["process.feed_mm_per_min"] - p0["process.feed_mm_per_min"]) / 0.6
                expect.append(abs(sq(p1["process.feed_mm_per_min"])
                                  - sq(p0["process.feed_mm_per_min"])) / abs(du))
    assert ind["process.feed_mm_per_min"]["mu_star"] == pytest.approx(np.mean(expect), rel=0.05)
    assert (tmp_path / "out" / "morris_residual_Sq_nm.png").stat().st_size > 5000
    assert "Morris elementary effects" in (tmp_path / "out" / "summary.md").read_text()


def test_shipped_sensitivity_sweeps_expand():
    from render_inspect.pipeline import find_sweep
    from render_inspect.scene import scene_sections

    for name in ("sensitivity_sts_grid", "sensitivity_sculpt", "sensitivity_rcse",
                 "sensitivity_hts"):
        spec = read_sweep(find_sweep(name), sections=scene_sections())
        assert spec.morris is not None
        k = len(spec.morris.factor)
        pts = [p for st in spec.studies() for p in st.points]
        assert len(pts) == spec.morris.trajectories * (k + 1)
    with pytest.raises(InputError, match="morris"):
        bad = find_sweep("sensitivity_sts_grid").read_text().replace(
            'key = "material.edge_radius_nm"', 'key = "materiel.edge_radius_nm"')
        import tempfile
        from pathlib import Path
        with tempfile.TemporaryDirectory() as d:
            p = Path(d) / "bad.toml"
            p.write_text(bad)
            read_sweep(p, sections=scene_sections())
