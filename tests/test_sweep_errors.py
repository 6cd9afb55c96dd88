"""A sweep whose grid holds values out of range is refused before anything runs, with one
line per key: the key, what it must be, how many different values it received and the
first few of them, and the points concerned; however many points the grid has.  Points
that fail for one reason (before they run or as they run) are one line too, whatever
numbers their messages hold."""

from __future__ import annotations

import csv
import re

import pytest

from conftest import run_main
from render_inspect.pipeline._sweep_check import check_sweep_tasks  # (the message itself)
from render_inspect.errors import InputError

#: inner radii: one allowed, 19 beyond the workpiece radius (5 mm)
INNER = [0.0] + [round(5.5 + 0.01 * i, 2) for i in range(19)]
#: points per revolution: three below the least (8), twelve allowed
PPR = [2, 3, 4, 720, 1000, 1200, 1500, 1800, 2000, 2400, 3000, 3600, 4000, 5000, 6000]
#: nose radii: two not > 0
NOSE = [-0.5, -0.4, 0.3, 0.5, 0.7]


def test_a_grid_of_thousands_of_points_gives_one_line_per_key(tmp_path, capsys):
    """20 x 5 x 15 x 2 = 3000 points, 2928 of them with a value out of range: one line for
    each of the three keys, however many values and points.  A point with a bad nose
    radius (2/5 of the points) or a bad points per revolution (3/15) is named on those
    lines; an inner radius beyond the workpiece is checked once the process's other keys
    are valid (19/20 x 12/15 of the points)."""
    (tmp_path / "big.toml").write_text(f"""scene = "sts_sinusoidal_grid"
[set]
"simulation.region" = [-0.05, -0.05, 0.05, 0.05]
[grid]
"process.inner_radius" = {INNER}
"tool.nose_radius" = {NOSE}
"process.points_per_rev" = {PPR}
"process.spindle_rpm" = [50, 100]
""")
    rc, err = run_main(capsys, "sweep", tmp_path / "big.toml", "--out", tmp_path / "out")
    assert rc == 1 and "Traceback" not in err and not (tmp_path / "out").exists()
    lines = err.strip().splitlines()
    assert "2928 of 3000 points are not valid scenes" in lines[0] and "nothing was run" in lines[0]
    assert lines[1:] == [
        "  tool.nose_radius: must be a finite number in (0, 50]; received 2 values: -0.5, -0.4 "
        "[1200 points: 0, 1, 2, 3, 4, ...]",
        "  process.points_per_rev: must be an integer in [8, 10000000]; received 3 values: 2, 3, 4 "
        "[600 points: 0, 1, 2, 3, 4, ...]",
        "  process.inner_radius: must be < workpiece_radius (5.0); received 19 values: 5.5, "
        "5.51, 5.52, 5.53, 5.54, ... [2280 points: 156, 157, 158, 159, 160, ...]"]


def test_checks_of_several_keys_are_grouped_by_what_they_allow():
    """A check that names its own keys (the feed per revolution against the nose radius)
    is one line per bound it states, every value it received counted; a single value is
    named alone; a complaint without a value keeps its points."""
    invalid = []
    for i, rpm in enumerate((1.0, 2.0, 4.0, 5.0)):
        for j, nose in enumerate((0.01, 0.02)):
            invalid.append({"index": 2 * i + j, "error": (
                "invalid scene 'x.toml':\n  (top level): process.feed_mm_per_min / "
                "process.spindle_rpm (feed per revolution) must be < tool.nose_radius "
                f"({nose} mm), received {1 / rpm:g} mm/rev (feed 1.0 mm/min at {rpm} rpm)")})
    invalid.append({"index": 8, "error": "invalid scene 'x.toml': tool.nose_radius: must be a "
                                         "finite number in (0, 50]; received -1.0"})
    invalid.append({"index": 9, "error": "invalid scene 'x.toml': tool.nose_radus: unknown key"})
    try:
        check_sweep_tasks("s.toml", [{}], invalid)
    except InputError as err:
        lines = str(err).splitlines()
    else:
        raise AssertionError("the sweep was not refused")
    assert "10 of 11 points are not valid scenes" in lines[0]
    assert lines[1:] == [
        "  process.feed_mm_per_min / process.spindle_rpm (feed per revolution) must be < "
        "tool.nose_radius (0.01 mm); received 4 values: 1 mm/rev (feed 1.0 mm/min at 1.0 rpm), "
        "0.5 mm/rev (feed 1.0 mm/min at 2.0 rpm), 0.25 mm/rev (feed 1.0 mm/min at 4.0 rpm), "
        "0.2 mm/rev (feed 1.0 mm/min at 5.0 rpm) [4 points: 0, 2, 4, 6]",
        "  process.feed_mm_per_min / process.spindle_rpm (feed per revolution) must be < "
        "tool.nose_radius (0.02 mm); received 4 values: 1 mm/rev (feed 1.0 mm/min at 1.0 rpm), "
        "0.5 mm/rev (feed 1.0 mm/min at 2.0 rpm), 0.25 mm/rev (feed 1.0 mm/min at 4.0 rpm), "
        "0.2 mm/rev (feed 1.0 mm/min at 5.0 rpm) [4 points: 1, 3, 5, 7]",
        "  tool.nose_radius: must be a finite number in (0, 50]; received -1.0 [point 8]",
        "  tool.nose_radus: unknown key [point 9]"]
    assert not any(re.search(r"\(top level\)", ln) for ln in lines)


#: a sweep of 8 points whose tool paths are each over a tiny memory budget, each by its
#: own amount (the feed sets the path's length)
OVER_BUDGET = """scene = "sts_sinusoidal_grid"
[set]
"machine.preset" = "ideal"
"material.preset" = "ideal"
"simulation.region" = [-0.05, -0.05, 0.05, 0.05]
"process.workpiece_radius" = 0.1
"process.spindle_rpm" = 100
"simulation.max_memory_gb" = 0.001
[grid]
"process.feed_mm_per_min" = [0.4, 0.5, 0.6, 0.7, 0.8, 0.9, 1.0, 1.1]
"""


def test_points_over_the_memory_budget_are_one_line(tmp_path, capsys):
    """Eight points over the memory budget, each by its own estimate: one line, the
    numbers that differ between the points given as their ranges, the eight points."""
    (tmp_path / "mem.toml").write_text(OVER_BUDGET)
    rc, err = run_main(capsys, "sweep", tmp_path / "mem.toml", "--out", tmp_path / "out")
    assert rc == 1 and "Traceback" not in err and not (tmp_path / "out").exists()
    lines = err.strip().splitlines()
    assert "8 of 8 points are not valid scenes" in lines[0], lines
    (line,) = lines[1:]
    assert re.fullmatch(
        r"  the tool path \(\S+ \.\. \d+ points\) would need about [\d.]+ \.\. [\d.]+ MiB, "
        r"more than the memory budget of 1\.02 MiB \(simulation\.max_memory_gb = 0\.001\); "
        r"to fit, set process\.points_per_rev <= \d+ \.\. \d+ \(now 3600\) or "
        r"process\.feed_mm_per_min >= [\d.]+ \.\. [\d.]+ mm/min \(now 0\.4 \.\. 1\.1 mm/min\); "
        r"or shrink simulation\.region / process\.workpiece_radius "
        r"\[8 points: 0, 1, 2, 3, 4, \.\.\.\]", line), line


def test_failed_points_are_one_line_per_reason():
    """The message of a sweep whose points failed as they ran: one line per reason (the
    messages alike but for their numbers), its count of the sweep's points, the points,
    the numbers that differ as their ranges; a reason of one point as it is."""
    from render_inspect.pipeline import sweep_failure
    from render_inspect.pipeline._sweep_check import failure_lines

    def off(i, lo):
        return {"index": i, "status": "failed", "error": (
            f"simulation.region [0.3, 0.3, 0.35, 0.35] mm lies outside the turned part: the "
            f"tool reaches it only between {lo} and {lo + 0.13:g} mm from the spindle axis")}

    recs = [off(2, 0.41), off(5, 0.39), {"index": 6, "status": "failed",
                                         "error": "MemoryError: out of memory"}, off(7, 0.4)]
    info = {"points": 8, "done": 4, "failed": 4, "pending": 0,
            "failure_lines": failure_lines(recs, 8)}
    msg = sweep_failure(info, "out").splitlines()
    assert msg[0].startswith("4 of 8 points failed (their errors are in out/summary.md and "
                             "results.csv); 4 points are done; rerun with --retry-failed")
    assert msg[1:] == [
        "  3 of 8 points (2, 5, 7): simulation.region [0.3, 0.3, 0.35, 0.35] mm lies outside "
        "the turned part: the tool reaches it only between 0.39 .. 0.41 and 0.52 .. 0.54 mm "
        "from the spindle axis",
        "  1 of 8 points (6): MemoryError: out of memory"]


@pytest.mark.slow  # a Dask worker process runs the points
def test_points_failing_alike_as_they_run_are_one_line(tmp_path, capsys):
    """Six points whose region lies off the part fail as they run: exit 1, one line for
    the six (no table of six failed rows); each point's own error in results.csv."""
    (tmp_path / "off.toml").write_text(OVER_BUDGET.replace(
        '"simulation.max_memory_gb" = 0.001', "").replace(
        "[-0.05, -0.05, 0.05, 0.05]", "[0.3, 0.3, 0.35, 0.35]").replace(
        "[0.4, 0.5, 0.6, 0.7, 0.8, 0.9, 1.0, 1.1]", "[0.4, 1.0]") + '"tool.nose_radius" = [0.2, 0.5, 1.0]\n')
    out = tmp_path / "out"
    rc, err = run_main(capsys, "sweep", tmp_path / "off.toml", "--out", out, "--workers", "1")
    assert rc == 1 and "Traceback" not in err
    assert "| point |" not in err
    tail = err[err.index("render-inspect sweep: error: "):].strip().splitlines()
    assert tail[0].startswith("render-inspect sweep: error: 6 of 6 points failed")
    (line,) = tail[1:]
    assert line.startswith("  6 of 6 points (0, 1, 2, 3, 4, ...): simulation.region [0.3, 0.3, "
                           "0.35, 0.35] mm lies outside the turned part: the tool reaches it "
                           "only between "), line
    with open(out / "results.csv", newline="") as f:
        errors = [r["error"] for r in csv.DictReader(f)]
    assert len(errors) == 6 and len(set(errors)) == 6
    assert all("lies outside the turned part" in e and " .. " not in e for e in errors)
