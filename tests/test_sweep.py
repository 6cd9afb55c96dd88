"""Parameter sweeps: sweep files, points and their identity, the results files, and real
Dask clusters (a LocalCluster of process workers; a scheduler and two workers started as
separate processes on 127.0.0.1), a sweep killed part-way and resumed, failing points.

Every point's Sq is checked against the closed-form feed scallop of a round-nosed tool,
Sq = f^2 / (Rc sqrt(720)) with f the feed per revolution (seed 000; docs/sts.md), which
the turned sinusoidal grid follows within ~1.5 % (its curvature and the sampling)."""

from __future__ import annotations

import csv
import io
import json
import math
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from render_inspect.batch import (
    ResultsLog,
    csv_text,
    expand_points,
    md_text,
    summary_table,
    point_id,
    read_sweep,
    sweep_keys,
    toml_value,
)
from render_inspect.core.errors import InputError, SceneError
from render_inspect.pipeline import find_sweep, run_sweep, shipped_sweeps, sweep_tasks

REPO = Path(__file__).resolve().parents[1]
EXE = Path(sys.executable).parent / "render-inspect"
DASK = Path(sys.executable).parent / "dask"
#: Every process a test starts is bounded by this (seconds).
LIMIT_S = 240

SMALL = """
name = "small"
scene = "sts_sinusoidal_grid"
[set]
"machine.preset" = "ideal"       # the closed form is the kinematic scallop: no servo
"material.preset" = "ideal"      # errors, no minimum chip thickness
"simulation.region" = [-0.05, -0.05, 0.05, 0.05]
"simulation.pixel" = 0.001
"process.workpiece_radius" = 0.1
"process.spindle_rpm" = 100
[grid]
"tool.nose_radius" = [0.2, 0.5, 1.0]
"process.feed_mm_per_min" = [0.4, 1.0]
"""


def _sq_closed_form_nm(rc_mm, feed_mm_per_min, rpm):
    f = feed_mm_per_min / rpm
    return f * f / (rc_mm * math.sqrt(720.0)) * 1e6


def _env():
    """This checkout first on the path (the command runs the code under test)."""
    return {**os.environ, "PYTHONPATH": str(REPO)}


def _check_points(records, n):
    done = [r for r in records if r["status"] == "done"]
    assert len(done) == n, [r.get("error") for r in records]
    for r in done:
        p = r["params"]
        rpm = p.get("process.spindle_rpm") or 100
        expect = _sq_closed_form_nm(p["tool.nose_radius"], p["process.feed_mm_per_min"], rpm)
        assert math.isclose(r["metrics"]["residual"]["Sq_nm"], expect, rel_tol=0.03), (p, expect)
    return done


def _records(out: Path):
    return [json.loads(line) for line in (out / "results.jsonl").read_text().splitlines() if line]


# ----------------------------------------------------------------------- sweep files
def test_grid_zip_points_and_studies_expand(tmp_path):
    f = tmp_path / "s.toml"
    f.write_text("""
scene = "sts_sinusoidal_grid"
[set]
"simulation.pixel" = 0.002
[grid]
"tool.nose_radius" = [0.2, 0.5]
[zip]
"process.spindle_rpm" = [50, 100, 150]
"process.feed_mm_per_min" = [0.5, 1.0, 1.5]
[[points]]
"tool.nose_radius" = 0.3
[[study]]
name = "b"
set = { "tool.nose_radius" = 0.2 }
zip = { "process.spindle_rpm" = [50, 60], "process.feed_mm_per_min" = [0.5, 0.6] }
""")
    spec = read_sweep(f)
    assert spec.name == "s"
    pts = expand_points(spec)
    # 2 x 3 (grid x zip) + 1 point + study b: (0.2, 50, 0.5) is shared, (0.2, 60, 0.6) new
    assert len(pts) == 8
    shared = [p for p in pts if p.overrides["tool.nose_radius"] == 0.2
              and p.overrides["process.spindle_rpm"] == 50]
    assert len(shared) == 1 and shared[0].studies == ["", "b"]
    assert sweep_keys(spec) == ["tool.nose_radius", "process.spindle_rpm", "process.feed_mm_per_min"]
    assert pts[0].overrides == {"simulation.pixel": 0.002, "tool.nose_radius": 0.2,
                                "process.spindle_rpm": 50, "process.feed_mm_per_min": 0.5}


def test_shipped_sweeps_resolve(tmp_path):
    assert {"fig15_small", "fig15"} <= set(shipped_sweeps())
    small = find_sweep("fig15_small")
    tasks, invalid, keys = sweep_tasks(read_sweep(small), small, tmp_path)
    assert len(tasks) == 9 and not invalid
    assert keys == ["tool.nose_radius", "process.feed_mm_per_min"]
    full = find_sweep("fig15.toml")
    tasks, invalid, keys = sweep_tasks(read_sweep(full), full, tmp_path)
    # panels a (10 x 5), b (5 x 5), c (5 x 10) share 5 + 10 + 5 points, 1 of them thrice
    assert len(tasks) == 50 + 25 + 50 - 5 - 10 - 5 + 1 and not invalid
    triple = [t for t in tasks if len(t["studies"]) == 3]
    # the sweep keys, then the keys [set] fixes for every point
    assert len(triple) == 1 and triple[0]["params"] == {
        "process.spindle_rpm": 100, "tool.nose_radius": 0.5, "process.feed_mm_per_min": 0.6,
        "machine.preset": "ideal", "material.preset": "ideal", "process.workpiece_radius": 0.25,
        "simulation.pixel": 0.001, "simulation.region": [-0.15, -0.15, 0.15, 0.15]}


def test_point_identity_is_the_resolved_scene(tmp_path):
    a = tmp_path / "a.toml"
    a.write_text(SMALL)
    b = tmp_path / "b.toml"  # same points written differently: 1 vs 1.0, keys in another order
    b.write_text(SMALL.replace("[0.2, 0.5, 1.0]", "[0.2, 0.50, 1]").replace(
        '"simulation.pixel" = 0.001\n', "").replace('[set]\n', '[set]\n"simulation.pixel" = 1e-3\n'))
    ta, _, _ = sweep_tasks(read_sweep(a), a, tmp_path)
    tb, _, _ = sweep_tasks(read_sweep(b), b, tmp_path)
    assert sorted(t["id"] for t in ta) == sorted(t["id"] for t in tb)
    assert len({t["id"] for t in ta}) == 6
    assert point_id({"x": 1, "y": [1, 2]}) == point_id({"y": [1, 2], "x": 1})


@pytest.mark.parametrize("text, needle", [
    ('scene = "sts_sinusoidal_grid"\n[grid]\n"tool.nose_radius" = []', "grid: must give at least one value"),
    ('scene = "sts_sinusoidal_grid"\n[zip]\n"tool.nose_radius" = [1, 2]\n"process.spindle_rpm" = [1]',
     "zip lists must all have the same length"),
    ('scene = "sts_sinusoidal_grid"\n[grid]\nnose_radius = [0.1]', "dotted scene key"),
    ('scene = "sts_sinusoidal_grid"\nworkers = 3', "workers: unknown key"),
    ('scene = "sts_sinusoidal_grid"\n[run]\nmeasure = true', "measure = true needs render"),
    ('[grid]\n"tool.nose_radius" = [0.1]', "scene: is required here"),
])
def test_bad_sweep_files_name_the_key(tmp_path, text, needle):
    f = tmp_path / "bad.toml"
    f.write_text(text)
    with pytest.raises(InputError, match="invalid sweep file") as err:
        read_sweep(f)
    assert needle in str(err.value)


def test_toml_values_round_trip():
    import tomllib

    for v in [1, 0.1, 1e-7, -2.5, True, "z", [0.1, -1, 2], {"a": 1, "b": [1.5]}, "a \"q\""]:
        assert tomllib.loads(f"v = {toml_value(v)}")["v"] == v


# ----------------------------------------------------------------------- results files
def test_results_log_skips_a_cut_line_and_keeps_one_record_per_point(tmp_path):
    log = ResultsLog(tmp_path / "results.jsonl")
    log.append({"id": "a", "status": "done", "metrics": {"residual": {"Sq_nm": 1.0}}})
    with open(log.path, "ab") as fh:  # a kill in the middle of a write
        fh.write(b'{"id": "b", "status": "do')
    assert list(log.read()) == ["a"]
    log.append({"id": "b", "status": "failed", "error": "x"})
    log.append({"id": "b", "status": "done", "metrics": {}})
    recs = log.read()
    assert list(recs) == ["a", "b"] and recs["b"]["status"] == "done"
    log.rewrite(recs.values())
    assert [json.loads(x)["id"] for x in log.path.read_text().splitlines()] == ["a", "b"]
    text = csv_text([{"id": "a", "status": "done", "params": {"k": 0.5},
                      "metrics": {"residual": {"Sq_nm": 1.25}, "lenslets": [1, 2]}}], ["k"])
    head, row = text.splitlines()
    assert head.split(",")[:3] == ["id", "status", "k"] and "metrics.residual.Sq_nm" in head
    assert "metrics.lenslets" not in head and row.startswith("a,done,0.5,")


# ----------------------------------------------------------------------- Dask clusters
@pytest.mark.slow
def test_local_cluster_of_process_workers_from_a_script(tmp_path):
    """The Python API from a script (guarded by ``if __name__ == "__main__":``, which
    process workers need): a LocalCluster of 2 process workers runs 6 points."""
    (tmp_path / "small.toml").write_text(SMALL)
    (tmp_path / "run.py").write_text(
        "import json, os\n"
        "from render_inspect.pipeline import run_sweep\n"
        "if __name__ == '__main__':\n"
        "    info = run_sweep('small.toml', 'out', workers=2)\n"
        "    print(json.dumps({'info': info, 'pid': os.getpid()}))\n")
    res = subprocess.run([sys.executable, "run.py"], cwd=tmp_path, capture_output=True, text=True,
                         timeout=LIMIT_S, env=_env())
    assert res.returncode == 0, res.stderr[-3000:]
    got = json.loads(res.stdout.strip().splitlines()[-1])
    info, client_pid = got["info"], got["pid"]
    assert info["workers"] == 2 and info["done"] == 6 and info["failed"] == 0
    assert info["dashboard"].startswith("http://127.0.0.1:")
    out = tmp_path / "out"
    done = _check_points(_records(out), 6)
    pids = {int(r["worker"].rsplit(":", 1)[1]) for r in done}
    assert client_pid not in pids and len(pids) == 2  # two worker processes did the work
    for r in done:
        folder = out / r["folder"]
        assert {"metrics.json", "point.json", "residual.png", "scene.json"} <= {
            p.name for p in folder.iterdir()}
    csv_lines = (out / "results.csv").read_text().splitlines()
    assert len(csv_lines) == 7
    assert (out / "summary.md").read_text().count("| done |") == 6
    pngs = sorted(p.name for p in out.glob("*.png"))
    assert len(pngs) == 3 and all((out / p).stat().st_size > 5000 for p in pngs)  # 2 curves + 1 map


def _wait_for(cond, timeout, what):
    t0 = time.monotonic()
    while not cond():
        if time.monotonic() - t0 > timeout:
            raise AssertionError(f"timed out waiting for {what}")
        time.sleep(0.2)


@pytest.mark.slow
def test_existing_cluster_scheduler_and_two_workers_on_loopback(tmp_path):
    """``dask scheduler`` and two ``dask worker`` processes on 127.0.0.1, as one would
    start them on other machines; the sweep connects with --scheduler."""
    sched_file = tmp_path / "scheduler.json"
    procs = []
    try:
        procs.append(subprocess.Popen(
            [str(DASK), "scheduler", "--host", "127.0.0.1", "--port", "0", "--no-dashboard",
             "--scheduler-file", str(sched_file)], cwd=tmp_path, env=_env(),
            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL))
        _wait_for(sched_file.exists, 60, "the scheduler file")
        time.sleep(0.5)
        address = json.loads(sched_file.read_text())["address"]
        assert address.startswith("tcp://127.0.0.1:")
        for name in ("w1", "w2"):
            procs.append(subprocess.Popen(
                [str(DASK), "worker", address, "--host", "127.0.0.1", "--nthreads", "1",
                 "--no-nanny", "--no-dashboard", "--name", name], cwd=tmp_path, env=_env(),
                stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL))
        from distributed import Client

        with Client(address, timeout="30s") as c:
            c.wait_for_workers(2, timeout=120)
        (tmp_path / "small.toml").write_text(SMALL)
        res = subprocess.run([str(EXE), "sweep", "small.toml", "--out", "out", "--scheduler",
                              address], cwd=tmp_path, capture_output=True, text=True,
                             timeout=LIMIT_S, env=_env())
        assert res.returncode == 0, res.stderr[-3000:]
        assert f"Dask: 2 workers at {address}" in res.stderr
        done = _check_points(_records(tmp_path / "out"), 6)
        pids = {int(r["worker"].rsplit(":", 1)[1]) for r in done}
        assert pids == {procs[1].pid, procs[2].pid}  # the two worker processes ran them
    finally:
        for p in procs[::-1]:
            p.terminate()
        for p in procs:
            try:
                p.wait(timeout=30)
            except subprocess.TimeoutExpired:
                p.kill()
                p.wait()


@pytest.mark.slow
def test_scheduler_that_does_not_answer_is_one_clear_error(tmp_path):
    (tmp_path / "small.toml").write_text(SMALL)
    res = subprocess.run([str(EXE), "sweep", "small.toml", "--out", "out", "--scheduler",
                          "tcp://127.0.0.1:9"], cwd=tmp_path, capture_output=True, text=True,
                         timeout=LIMIT_S, env=_env())
    assert res.returncode == 1
    assert "--scheduler tcp://127.0.0.1:9: no Dask scheduler answered" in res.stderr
    assert "Traceback" not in res.stderr
    res = subprocess.run([str(EXE), "sweep", "small.toml", "--out", "out", "--workers", "0"],
                         cwd=tmp_path, capture_output=True, text=True, timeout=LIMIT_S, env=_env())
    assert res.returncode == 1 and "--workers must be an integer in [1, 1024], got 0" in res.stderr
    res = subprocess.run([str(EXE), "sweep", "small.toml", "--out", "out", "--workers", "2",
                          "--scheduler", "tcp://127.0.0.1:9"], cwd=tmp_path, capture_output=True,
                         text=True, timeout=LIMIT_S, env=_env())
    assert res.returncode == 2  # usage error: the two exclude each other


KILL = SMALL.replace('"simulation.region" = [-0.05, -0.05, 0.05, 0.05]',
                     '"simulation.region" = [-0.15, -0.15, 0.15, 0.15]').replace(
    '"process.workpiece_radius" = 0.1', '"process.workpiece_radius" = 0.25').replace(
    '"process.feed_mm_per_min" = [0.4, 1.0]', '"process.feed_mm_per_min" = [0.4, 0.7, 1.0]').replace(
    '"tool.nose_radius" = [0.2, 0.5, 1.0]', '"tool.nose_radius" = [0.2, 0.3, 0.5, 1.0]')


@pytest.mark.slow
def test_killed_sweep_resumes_and_ends_with_every_point_once(tmp_path):
    (tmp_path / "kill.toml").write_text(KILL)
    cmd = [str(EXE), "sweep", "kill.toml", "--out", "out", "--workers", "2"]
    proc = subprocess.Popen(cmd, cwd=tmp_path, env=_env(), start_new_session=True,
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    results = tmp_path / "out" / "results.jsonl"
    try:
        _wait_for(lambda: results.exists() and len(results.read_text().splitlines()) >= 2,
                  LIMIT_S, "two finished points")
    finally:
        os.killpg(proc.pid, signal.SIGKILL)  # the client, its scheduler and its workers
        proc.wait(timeout=60)
    before = {r["id"]: r for r in _records(tmp_path / "out")}
    assert 2 <= len(before) < 12, len(before)
    res = subprocess.run(cmd, cwd=tmp_path, capture_output=True, text=True, timeout=LIMIT_S,
                         env=_env())
    assert res.returncode == 0, res.stderr[-3000:]
    info = json.loads((tmp_path / "out" / "sweep.json").read_text())
    assert info["done"] == 12 and info["skipped"] + info["recovered"] >= len(before)
    assert info["ran"] == 12 - info["skipped"] - info["recovered"]
    recs = _records(tmp_path / "out")
    ids = [r["id"] for r in recs]
    assert len(ids) == len(set(ids)) == 12  # every point exactly once
    _check_points(recs, 12)
    for i, r in before.items():  # finished before the kill: kept, not run again
        after = next(x for x in recs if x["id"] == i)
        assert after["worker"] == r["worker"] and after["seconds"] == r["seconds"]
    assert not list((tmp_path / "out" / "points").glob(".*partial*"))
    assert len(list((tmp_path / "out" / "points").iterdir())) == 12


@pytest.mark.slow
def test_a_sweep_with_an_invalid_point_is_refused_before_any_point_runs(tmp_path):
    """A misspelt key inside [grid], a value out of range, a point over its memory budget:
    the whole sweep is checked first, one message lists each complaint with its points,
    and nothing runs or is written."""
    (tmp_path / "bad.toml").write_text(SMALL.replace(
        '"process.feed_mm_per_min" = [0.4, 1.0]', '"process.feed_mm_per_min" = [0.4, 1.0]\n'
        '"tool.nose_radus" = [0.1, 0.2]') + """
[[points]]                       # over its memory budget
"tool.nose_radius" = 0.3
"simulation.max_memory_gb" = 1e-6
[[points]]                       # no such nose radius
"tool.nose_radius" = -1.0
""")
    res = subprocess.run([str(EXE), "sweep", "bad.toml", "--out", "out"], cwd=tmp_path,
                         capture_output=True, text=True, timeout=LIMIT_S, env=_env())
    assert res.returncode == 1 and "Traceback" not in res.stderr
    err = res.stderr
    assert "14 of 14 points are not valid scenes" in err and "nothing was run" in err
    assert "tool.nose_radus: unknown key (not allowed here; check the spelling); did you mean " \
           "'nose_radius'? [12 points: 0, 1, 2, 3, 4, ...]" in err
    assert "simulation.max_memory_gb" in err and "tool.nose_radius" in err and "-1.0" in err
    assert "the other points are done" not in err
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("text, needle", [
    ('[[plot]]\nkind = "curves"\nx = "tool.nose_radius"\nname = "../../evil"', "plot name must be a file name"),
    ('[[plot]]\nkind = "curves"\nx = "tool.nose_radius"\nname = "/tmp/evil"', "plot name must be a file name"),
    ('[[plot]]\nkind = "curves"\nx = "tool.nose_radius"\nname = ".hidden"', "plot name must be a file name"),
    ('[[study]]\nname = "a/b"', "study name must be a file name"),
    ('[[study]]\nname = "x\\ny"', "study name must be a file name"),
    ('[grid]\n"tool.nose_radius" = [' + ", ".join(["0.1"] * 1000) + ']\n"process.spindle_rpm" = ['
     + ", ".join(["1"] * 1000) + ']\n"simulation.seed" = [' + ", ".join(["1"] * 1000) + "]",
     "has 1,000,000,000 points (grid 1000 x 1000 x 1000), more than the 10,000"),
])
def test_names_that_are_not_file_names_and_huge_grids_are_refused(tmp_path, text, needle):
    f = tmp_path / "s.toml"
    f.write_text('scene = "sts_sinusoidal_grid"\n' + text)
    t0 = time.monotonic()
    with pytest.raises(InputError) as err:
        read_sweep(f)
    assert needle in str(err.value) and time.monotonic() - t0 < 5


def test_a_sweep_where_nothing_varies_is_one_point_of_a_checked_scene(tmp_path):
    (tmp_path / "s.toml").write_text('scene = "sts_sinusoidal_grid"\n[set]\n"tool.nose_radius" = 0.3\n')
    tasks, invalid, keys = sweep_tasks(read_sweep(tmp_path / "s.toml"), tmp_path / "s.toml", tmp_path)
    assert len(tasks) == 1 and not invalid and keys == []
    assert tasks[0]["params"] == {"tool.nose_radius": 0.3}
    (tmp_path / "p.toml").write_text('scene = "/etc/passwd"\n')
    with pytest.raises(SceneError, match=r"scene = '/etc/passwd': scene file '/etc/passwd' is not "
                                         r"valid TOML"):
        run_sweep(tmp_path / "p.toml", tmp_path / "out")
    assert not (tmp_path / "out").exists()


def test_results_csv_and_summary_are_safe_to_open():
    """Text cells that a spreadsheet would read as a formula are written as text (OWASP);
    Markdown in names, values and errors cannot start a heading or break the table."""
    recs = [{"id": "=HYPERLINK(\"x\")", "status": "failed", "studies": ["@SUM(A1)"],
             "params": {"design.expr": "+1\n# injected", "tool.nose_radius": -0.5},
             "error": "-2+3 failed\n| x |", "seconds": 1.0}]
    text = csv_text(recs, ["design.expr", "tool.nose_radius"],
                    columns={"tool.nose_radius": "tool.nose_radius_mm"})
    rows = list(csv.reader(io.StringIO(text)))
    assert rows[0][:4] == ["id", "status", "design.expr", "tool.nose_radius_mm"]
    assert rows[1][:4] == ["'=HYPERLINK(\"x\")", "failed", "'+1\n# injected", "-0.5"]
    assert rows[1][4] == "'@SUM(A1)" and rows[1][7] == "'-2+3 failed"
    for row in rows:
        for cell in row:
            assert not cell.startswith(("=", "+", "@", "\t", "\r")) and not (
                cell.startswith("-") and not _is_number(cell)), cell
    md = summary_table(recs, ["design.expr"])
    assert not any(ln.lstrip().startswith("#") for ln in md.splitlines())
    assert len(md.strip().splitlines()) == 3 and md.splitlines()[2].count(" | ") == 4
    assert md_text("a\n# b") == "a # b" and md_text("# b") == "\\# b"
    assert md_text("tool.nose_radius") == "tool.nose_radius"


def _is_number(text):
    try:
        float(text)
    except ValueError:
        return False
    return True


@pytest.mark.slow
def test_failing_points_are_recorded_and_the_sweep_goes_on(tmp_path):
    """A point that is a valid scene but fails when it runs (its region lies off the
    turned part) is recorded; the others run; the message says how many are done."""
    (tmp_path / "fail.toml").write_text(SMALL.replace('[grid]\n"tool.nose_radius" = [0.2, 0.5, 1.0]',
                                                      '[grid]\n"tool.nose_radius" = [0.5, 1.0]') + """
[[points]]                       # fails when it runs: the region lies off the part
"tool.nose_radius" = 0.3
"simulation.region" = [0.3, 0.3, 0.35, 0.35]
""")
    cmd = [str(EXE), "sweep", "fail.toml", "--out", "out", "--workers", "1"]
    res = subprocess.run(cmd, cwd=tmp_path, capture_output=True, text=True, timeout=LIMIT_S,
                         env=_env())
    assert res.returncode == 1, res.stderr[-3000:]
    assert "1 of 5 points failed" in res.stderr and "4 points are done" in res.stderr
    assert "Traceback" not in res.stderr
    recs = _records(tmp_path / "out")
    assert len(recs) == 5
    _check_points([r for r in recs if r["params"]["tool.nose_radius"] in (0.5, 1.0)], 4)
    (off,) = [r for r in recs if r["params"]["tool.nose_radius"] == 0.3]
    assert off["status"] == "failed" and off["error_type"] == "InputError"
    assert "lies outside the turned part" in off["error"] and off["folder"] is None
    summary = (tmp_path / "out" / "summary.md").read_text()
    assert "failed" in summary and "Fixed for every point: machine.preset = \"ideal\"" in summary
    head = (tmp_path / "out" / "results.csv").read_text().splitlines()[0].split(",")
    # units in the scene keys' columns; the keys [set] fixes are columns too
    assert head[:9] == ["id", "status", "tool.nose_radius_mm", "process.feed_mm_per_min",
                        "simulation.region_mm", "machine.preset", "material.preset",
                        "simulation.pixel_mm", "process.workpiece_radius_mm"]
    assert "process.spindle_rpm" in head
    info = json.loads((tmp_path / "out" / "sweep.json").read_text())
    assert info["columns"]["tool.nose_radius"] == "tool.nose_radius_mm"
    # a rerun runs nothing (failed points are finished too) ...
    res = subprocess.run(cmd, cwd=tmp_path, capture_output=True, text=True, timeout=LIMIT_S,
                         env=_env())
    assert res.returncode == 1 and "(0 to run, 5 finished before)" in res.stderr
    # ... unless asked to retry them: still failing, still one record each
    res = subprocess.run(cmd + ["--retry-failed"], cwd=tmp_path, capture_output=True, text=True,
                         timeout=LIMIT_S, env=_env())
    assert res.returncode == 1 and "(1 to run, 4 finished before)" in res.stderr
    assert len(_records(tmp_path / "out")) == 5


@pytest.mark.slow
def test_a_plot_of_a_metric_no_point_has_says_so(tmp_path):
    """A [[plot]] naming a metric the points do not have (a misspelling) draws an empty plot
    that says which metric, and the sweep says it once, with the name meant."""
    import logging

    (tmp_path / "pm.toml").write_text(
        'scene = "sts_sinusoidal_grid"\n[set]\n"simulation.region" = [-0.05, -0.05, 0.05, 0.05]\n'
        '"simulation.pixel" = 0.005\n"process.workpiece_radius" = 0.6\n'
        '[grid]\n"tool.nose_radius" = [0.3]\n'
        '[[plot]]\nkind = "curves"\nx = "tool.nose_radius"\ny = "residual.Sqq_nm"\n')
    said: list[str] = []
    handler = logging.Handler()
    handler.emit = lambda record: said.append(record.getMessage())  # type: ignore[method-assign]
    log = logging.getLogger("render_inspect")
    log.addHandler(handler)
    try:
        run_sweep(tmp_path / "pm.toml", tmp_path / "out", progress=False)
    finally:
        log.removeHandler(handler)
    assert any("no finished point has the metric 'residual.Sqq_nm'; did you mean "
               "'residual.Sq_nm'?" in s for s in said), said
    assert (tmp_path / "out" / "plot_00_curves.png").stat().st_size > 1000
