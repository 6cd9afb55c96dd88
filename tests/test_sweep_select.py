"""The point to machine: each point's machining time (the whole part's program), the
``[select]`` bounds and the best point meeting them; the sweep file's own mistakes (empty
tables, misspelt keys with the nearest name); the size check before a large sweep; and a
sweep interrupted with Ctrl-C (SIGINT) on a LocalCluster that goes on where it stopped."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from render_inspect.batch import SelectConfig, machining_time, read_sweep, select_point
from render_inspect.core.errors import InputError
from render_inspect.pipeline import run_sweep

REPO = Path(__file__).resolve().parents[1]
EXE = Path(sys.executable).parent / "render-inspect"
LIMIT_S = 240

CUT = """
name = "cut"
scene = "sts_sinusoidal_grid"
[set]
"machine.preset" = "ideal"
"material.preset" = "ideal"
"simulation.region" = [-0.04, -0.04, 0.04, 0.04]
"simulation.pixel" = 0.002
"process.workpiece_radius" = 0.1
"tool.nose_radius" = 0.5
[grid]
"process.feed_mm_per_min" = [0.2, 0.6, 1.0]
"process.spindle_rpm" = [50, 150]
[select]
[select.at_most]
"residual.Sq_nm" = 2.0
"""


def _sq_nm(feed, rpm, rc=0.5):
    """The feed scallop of a round nose, Sq = f^2 / (Rc sqrt 720) (docs/sts.md), nm."""
    f = feed / rpm
    return f * f / (rc * 720 ** 0.5) * 1e6


def _env():
    return {**os.environ, "PYTHONPATH": str(REPO)}


# ------------------------------------------------------------------- machining time
def test_machining_time_of_a_spiral_is_the_radius_over_the_feed_rate():
    scene = {"process": {"kind": "sts", "spindle_rpm": 100.0, "feed_mm_per_min": 0.5,
                         "workpiece_radius": 5.0, "inner_radius": 1.0}}
    mt = machining_time(scene, {"toolpath": {"feed_per_rev_mm": 0.005}})
    assert mt["time_min"] == pytest.approx(4.0 / 0.5)  # 4 mm of radius at 0.5 mm/min
    assert mt["time_s"] == pytest.approx(480.0)
    assert "800 revolutions" in mt["of"]
    # a feed the simulation planned (process.scallop_bound_nm) is the one that counts
    half = machining_time(scene, {"toolpath": {"feed_per_rev_mm": 0.0025}})
    assert half["time_min"] == pytest.approx(16.0)
    # a program read from a file: not known before it is read
    assert machining_time({"process": {**scene["process"], "program": "p.nc"}}, {}) is None


def test_machining_time_of_sculpturing_is_its_target_lines_at_the_cutting_speed():
    scene = {"process": {"kind": "sculpt", "feed_mm_per_min": 60.0},
             "design": {"rows": 10, "cols": 4, "pitch_y": 0.2}}
    mt = machining_time(scene, {})
    assert mt["time_s"] == pytest.approx(4 * 10 * 0.2 / 1.0)  # 8 mm at 1 mm/s


# ------------------------------------------------------------------------ selection
def _rec(i, feed, rpm, sq, t):
    return {"id": f"p{i}", "index": i, "status": "done",
            "params": {"process.feed_mm_per_min": feed, "process.spindle_rpm": rpm},
            "metrics": {"residual": {"Sq_nm": sq}, "machining": {"time_min": t}}}


def test_the_best_point_meets_the_bounds_at_the_shortest_machining_time():
    recs = [_rec(0, 0.2, 50, 1.2, 30.0), _rec(1, 0.6, 50, 10.7, 10.0),
            _rec(2, 0.6, 150, 1.2, 10.0), _rec(3, 1.0, 150, 3.3, 6.0),
            {"id": "p4", "index": 4, "status": "failed", "params": {}}]
    sel = SelectConfig(at_most={"residual.Sq_nm": 2.0})
    got = select_point(recs, sel)
    assert got["best"]["id"] == "p2" and got["meeting"] == 2 and got["finished"] == 4
    # none meets: the closest is the one whose bound is exceeded least (3.3 vs 1.0)
    got = select_point(recs, SelectConfig(at_most={"residual.Sq_nm": 1.0}))
    assert got["best"] is None and got["closest"]["id"] == "p0"
    assert got["closest"]["excess"] == pytest.approx(0.2)
    # a lower bound and another metric to minimise
    got = select_point(recs, SelectConfig(minimize="residual.Sq_nm",
                                          at_least={"machining.time_min": 8.0}))
    assert got["best"]["id"] == "p0"


def test_a_misspelt_select_metric_is_named_with_the_nearest_one():
    got = select_point([_rec(0, 0.2, 50, 1.2, 30.0)],
                       SelectConfig(at_most={"residual.Sq_mn": 2.0}))
    assert got["best"] is None
    assert "'residual.Sq_mn' (did you mean 'residual.Sq_nm'?)" in got["error"]


# ----------------------------------------------------------------------- sweep file
def _bad(tmp_path, text):
    p = tmp_path / "bad.toml"
    p.write_text('scene = "sts_sinusoidal_grid"\n' + text)
    with pytest.raises(InputError) as err:
        read_sweep(p, sections=["process", "tool", "simulation"])
    msg = str(err.value)
    assert "\n" not in msg, msg
    return msg


def test_sweep_file_mistakes_are_one_line_each(tmp_path):
    assert "an empty grid table" in _bad(tmp_path, "[grid]\n")
    assert "an empty zip table in [[study]]" in _bad(tmp_path, '[[study]]\nname = "a"\nzip = {}\n')
    assert "did you mean 'grid'?" in _bad(tmp_path, '[gird]\n"process.spindle_rpm" = [50]\n')
    assert "did you mean 'minimize'?" in _bad(tmp_path, '[select]\nminimise = "x.y"\n')
    assert "did you mean 'at_most'?" in _bad(tmp_path, '[select.at_mots]\n"x.y" = 1\n')
    msg = _bad(tmp_path, '[select.at_most]\n"Sq" = 1\n')
    assert "must be a dotted metric name" in msg and "'Sq'" in msg


# ------------------------------------------------------- size check (nothing runs)
def test_a_large_sweep_needs_yes_and_says_its_size_first(tmp_path, monkeypatch):
    import render_inspect.pipeline._sweep_report as rep

    monkeypatch.setattr(rep, "CONFIRM_POINTS", 4)
    (tmp_path / "cut.toml").write_text(CUT)
    with pytest.raises(InputError) as err:
        run_sweep(tmp_path / "cut.toml", tmp_path / "out", workers=1)
    msg = str(err.value)
    assert "6 points to run" in msg and "--yes" in msg and " on 1 worker" in msg
    assert not (tmp_path / "out").exists()  # nothing written


# ---------------------------------------------------- a real sweep, interrupted
def _records(out):
    return [json.loads(line) for line in (out / "results.jsonl").read_text().splitlines()]


@pytest.mark.slow
def test_interrupted_sweep_goes_on_and_names_the_point_to_machine(tmp_path):
    """SIGINT to the command halfway (a LocalCluster of one process worker): the finished
    points are kept, the same command runs only the missing ones, with the same numbers
    as a sweep run in one go; the summary gives each point's machining time and the best
    point meeting Sq <= 2 nm at the shortest one."""
    (tmp_path / "cut.toml").write_text(CUT)
    cmd = [str(EXE), "sweep", "cut.toml", "--out", "out", "--workers", "1"]
    proc = subprocess.Popen(cmd, cwd=tmp_path, env=_env(), stdout=subprocess.DEVNULL,
                            stderr=subprocess.PIPE, text=True)
    results = tmp_path / "out" / "results.jsonl"
    t0 = time.monotonic()
    try:
        while not (results.exists() and len(results.read_text().splitlines()) >= 2):
            assert proc.poll() is None and time.monotonic() - t0 < LIMIT_S, "no two points"
            time.sleep(0.05)
    finally:
        proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=LIMIT_S)
    before = {r["id"]: r for r in _records(tmp_path / "out")}
    if len(before) < 6:  # stopped part-way (a fast machine may have finished)
        assert proc.returncode == 130, err[-2000:]
        assert "interrupted" in err and "Traceback" not in err
    res = subprocess.run(cmd, cwd=tmp_path, env=_env(), capture_output=True, text=True,
                         timeout=LIMIT_S)
    assert res.returncode == 0, res.stderr[-3000:]
    info = json.loads((tmp_path / "out" / "sweep.json").read_text())
    # points finished by the worker as the command stopped are adopted from their folders
    assert info["done"] == 6 and info["ran"] + info["recovered"] == 6 - len(before)
    recs = {r["id"]: r for r in _records(tmp_path / "out")}
    for i, r in before.items():  # kept as they were, not run again
        assert recs[i]["seconds"] == r["seconds"] and recs[i]["worker"] == r["worker"]
    again = subprocess.run([str(EXE), "sweep", "cut.toml", "--out", "fresh", "--workers", "1"],
                           cwd=tmp_path, env=_env(), capture_output=True, text=True,
                           timeout=LIMIT_S)
    assert again.returncode == 0, again.stderr[-3000:]
    fresh = {r["id"]: r for r in _records(tmp_path / "fresh")}
    assert set(fresh) == set(recs)
    for i, r in recs.items():  # the same seed: the same numbers
        assert r["metrics"]["residual"] == fresh[i]["metrics"]["residual"]
        p = r["params"]
        assert r["metrics"]["residual"]["Sq_nm"] == pytest.approx(
            _sq_nm(p["process.feed_mm_per_min"], p["process.spindle_rpm"]), rel=0.05)
        # the whole part: 0.1 mm of radius at the feed rate
        assert r["metrics"]["machining"]["time_min"] == pytest.approx(
            0.1 / p["process.feed_mm_per_min"])
    # Sq <= 2 nm: (0.2, 50) 1.18 nm, (0.2, 150) 0.13, (0.6, 150) 1.18; the shortest of
    # these is 0.6 mm/min (10 s), at 150 rpm
    best = info["select"]["best"]
    assert best["params"]["process.feed_mm_per_min"] == 0.6
    assert best["params"]["process.spindle_rpm"] == 150
    assert info["select"]["meeting"] == 3
    summary = (tmp_path / "out" / "summary.md").read_text()
    assert "Best point meeting residual.Sq\\_nm \\<= 2" in summary or \
        "Best point meeting residual.Sq_nm \\<= 2" in summary
    assert "| machining.time_min |" in summary
    assert "Best point meeting" in res.stderr  # said on the console too
