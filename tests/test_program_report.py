"""The findings of a machine program read from a file in ``report.html``: a program with
a known gouge (one point programmed 2 um below the design) shows it, with its file line,
in its own section beside the feed per revolution (table and figure)."""

from __future__ import annotations

import json
import re

import numpy as np
import pytest

#: paraboloid design and the spiral programmed on it (bare C X Z point list, 0.5 deg per
#: point, 10 um per revolution from radius 0.3 mm inwards)
_R = -10.0
_FEED = 0.01
_STEP_DEG = 0.5
_GOUGE_INDEX = 18000  # radius 0.05 mm: inside the simulated region
_GOUGE_MM = 0.002

SCENE = """
name = "program_gouge"
description = "a program with one point 2 um below the design"
[design]
type = "paraboloid"
radius_x = -10.0
radius_y = -10.0
[tool]
nose_radius = 0.5
[process]
kind = "sts"
spindle_rpm = 50
feed_mm_per_min = 0.5
workpiece_radius = 0.35
compensation = "z"
points_per_rev = 720
program = "gouge.nc"
[simulation]
region = [-0.08, -0.08, 0.08, 0.08]
pixel = 0.002
seed = 3
[render.interferometer]
pixel = 0.002
field_of_view = [-0.06, -0.06, 0.06, 0.06]
[render.diffuse]
resolution = 32
spp = 2
"""


def _gouge_program(folder):
    """The spiral as a point list with one point ``_GOUGE_MM`` below the design (file
    line ``_GOUGE_INDEX + 1``)."""
    revs = 0.3 / _FEED
    n = int(round(revs * 360 / _STEP_DEG)) + 1
    c_cum = np.arange(n) * _STEP_DEG
    x = 0.3 - _FEED * c_cum / 360.0
    z = -x ** 2 / (2 * _R)
    z[_GOUGE_INDEX] -= _GOUGE_MM
    c = np.where((c_cum % 360 == 0) & (c_cum > 0), 360.0, c_cum % 360)
    p = folder / "gouge.nc"
    p.write_text("".join(f"C{c[i]:.4f} X{x[i]:.6f} Z{z[i]:.6f}\n" for i in range(n)))
    return p


def _scene(folder):
    _gouge_program(folder)
    p = folder / "scene.toml"
    p.write_text(SCENE)
    return p


def test_program_section_lists_the_gouge(tmp_path):
    """The section built from the program's own checks (the reader, the process's plan)
    names the finding, its depth and its file line, and the feed per revolution."""
    from render_inspect.design import make_surface
    from render_inspect.processes import process_of
    from render_inspect.report import HtmlReport, program_section
    from render_inspect.scene import load_scene

    sc = load_scene(_scene(tmp_path))
    proc = process_of(sc)
    cfg = proc.inputs_of(sc)
    plan = proc.plan(cfg, make_surface(sc.design))
    m = {"program": plan.facts["program"], "toolpath": plan.facts["toolpath"]}
    rep = HtmlReport("t")
    assert program_section(rep, {"program": m, "planned": {"toolpath": {}}},
                           ("program", "planned"), {"feed_per_rev_program": b"\x89PNG"})
    page = rep.render()
    assert "Machine program read from a file" in page
    assert "gouge.nc (point list)" in page
    row = re.search(r"<tr><td class=\"k\">cutting moves end below the design</td>(.*?)</tr>",
                    page).group(1)
    cells = re.findall(r"<td>(.*?)</td>", row)
    assert cells[0] == "1"  # one point
    assert cells[1] == "2000 nm"  # 2 um deep
    assert cells[2] == str(_GOUGE_INDEX + 1)  # its file line
    assert "feed per revolution, median" in page and "10.0 um" in page
    assert "data:image/png;base64," in page
    # a comparison of two planned programs has no such section
    rep2 = HtmlReport("t")
    assert not program_section(rep2, {"a": {"toolpath": {}}, "b": {}}, ("a", "b"), {})
    assert "Machine program" not in rep2.render()


@pytest.mark.mitsuba
@pytest.mark.slow
def test_compare_report_shows_the_program_gouge(tmp_path, capsys):
    """``compare`` of the program against the planned path: report.html has the program's
    section with the gouge (depth, file line) and the feed-per-revolution figure; the
    variant's metrics.json holds the finding.  The report's title, the summary's heading
    and ``run_name`` name the program beside the scene (the program's variant too, the
    planned one by the scene alone)."""
    from render_inspect.cli import main as cli_main

    scene = _scene(tmp_path)
    out = tmp_path / "out"
    assert cli_main(["compare", str(scene), "--out", str(out)]) == 0
    page = (out / "report.html").read_text()
    name = "program_gouge, program gouge.nc"
    assert f"<title>render_inspect comparison: {name}</title>" in page
    assert f"render-inspect compare: {name} (" in capsys.readouterr().out
    assert "Machine program read from a file" in page
    sec = page.split("Machine program read from a file", 2)[-1]
    assert "program: gouge.nc (point list)" in sec
    assert "cutting moves end below the design" in sec
    assert f"<td>{_GOUGE_INDEX + 1}</td>" in sec
    assert "the feed per revolution" in sec and "data:image/png;base64," in sec
    assert (out / "program" / "feed_per_rev.png").is_file()
    m = json.loads((out / "metrics.json").read_text())
    (f,) = m["program"]["program"]["findings"]
    assert f["kind"] == "below_design" and f["worst_line"] == _GOUGE_INDEX + 1
    assert f["worst_nm"] == pytest.approx(2000, abs=1)
    assert "program" not in m["planned"]
    assert m["run_name"] == m["program"]["run_name"] == name and m["scene"]["name"] == "program_gouge"
    assert m["planned"]["run_name"] == "program_gouge"
