"""A program read back names the file lines of its findings, whatever its dialect, and a
program exported after it was read from a file says it is that program (not the scene's
feed and compensation, which it does not follow)."""

from __future__ import annotations

import json
import math

import numpy as np

from render_inspect.core.toolpath import ToolPath
from render_inspect.io import read_program, write_nc
from render_inspect.pipeline import run_toolpath
from render_inspect.scene import load_scene

SMALL = ["simulation.region=[-0.05,-0.05,0.05,0.05]", "simulation.pixel=0.005",
         "process.workpiece_radius=0.6"]


def _spiral(n_rev: int = 3, per_rev: int = 36, r0: float = 0.5, feed: float = 0.01) -> ToolPath:
    k = np.arange(n_rev * per_rev + 1)
    theta = 2 * math.pi * k / per_rev
    rho = r0 - feed * k / per_rev
    return ToolPath(theta, rho, np.zeros_like(rho), k * 0.01, {})


def test_the_project_s_own_program_gives_each_point_its_file_line(tmp_path):
    path = write_nc(tmp_path / "p.nc", _spiral())
    imp = read_program(path, part_radius=1.0)
    text = path.read_text().splitlines()
    assert imp.dialect == "render_inspect turning"
    assert imp.file_line.shape == (imp.program.points,) and np.all(imp.file_line > 0)
    # each point's line holds its own C word (the file's 1-based line)
    for i in (0, 1, 17, imp.program.points - 1):
        line = text[imp.file_line[i] - 1]
        c = float(line.split("C")[1].split()[0])
        assert math.isclose(c, math.degrees(imp.program.theta[i]), abs_tol=1e-6), line


def test_an_exported_program_read_from_a_file_is_named_as_that_program(tmp_path):
    nc = write_nc(tmp_path / "in.nc", _spiral(n_rev=20, r0=0.55, feed=0.0123))
    scene = load_scene("sts_sinusoidal_grid", SMALL + [f"process.program={json.dumps(str(nc))}"])
    run_toolpath(scene, tmp_path / "out", fmt="nc")
    head = [ln for ln in (tmp_path / "out" / "toolpath.nc").read_text().splitlines()
            if ln.startswith(";")]
    assert "; program: in.nc" in head
    assert not any(ln.startswith("; compensation: z") for ln in head)
    facts = json.loads((tmp_path / "out" / "toolpath.json").read_text())
    # the program's own feed per revolution, not the scene's process.feed_per_rev
    assert math.isclose(facts["toolpath"]["feed_per_rev_mm"], 0.0123, rel_tol=1e-3)
