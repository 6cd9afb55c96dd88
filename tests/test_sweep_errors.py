"""A sweep whose grid holds values out of range is refused before anything runs, with one
line per key: the key, what it must be, how many different values it received and the
first few of them, and the points concerned; however many points the grid has."""

from __future__ import annotations

import re

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
