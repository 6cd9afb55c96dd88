"""The block rate of X-Y-Z programs (sculpturing, raster cutting): each block's length
over the programmed feed, L mm at F mm/min taking 60 L / F seconds, against
``process.block_rate_limit_per_s`` as a turning program's is (a note over the default, a
warning over the scene's own limit)."""

from __future__ import annotations

import json
import logging
import math

import numpy as np
import pytest

from render_inspect.errors import InputError, SceneError
from render_inspect.io import read_program_nc
from render_inspect.pipeline import run_toolpath
from render_inspect.scene import load_scene
from render_inspect.toolpath import DEFAULT_BLOCK_RATE_LIMIT, linear_block_rate


def test_a_known_program_by_hand():
    """Two lines at F = 60 mm/min (1 mm/s).  Line 0: blocks of (dY, dZ) = (0.003, 0.004),
    (0.003, 0), (0.0006, 0): 0.005, 0.003, 0.0006 mm, so 5, 3, 0.6 ms, 200, 333.3, 1666.7
    blocks a second; line 1: one block of 0.01 mm, 10 ms, 100 a second.  The move from
    line 0 to line 1 (0.5 mm in X) is no block of a line."""
    x = np.array([0.0, 0.0, 0.0, 0.0, 0.5, 0.5])
    y = np.array([0.0, 0.003, 0.006, 0.0066, 0.0, 0.01])
    z = np.array([0.0, 0.004, 0.004, 0.004, 0.0, 0.0])
    line = np.array([0, 0, 0, 0, 1, 1])
    r = linear_block_rate(x, y, z, line, 60.0)
    assert r["blocks"] == 4
    assert math.isclose(r["max_per_s"], 1 / 0.0006, rel_tol=1e-9)
    assert math.isclose(r["min_block_time_s"], 0.0006, rel_tol=1e-9)
    assert math.isclose(r["median_per_s"], (200 + 1000 / 3) / 2, rel_tol=1e-9)
    assert r["limit_per_s"] == DEFAULT_BLOCK_RATE_LIMIT and not r["limit_from_scene"]
    assert not r["ok"] and r["blocks_over_limit"] == 1
    w = r["warning"]
    assert "1,667 blocks/s" in w and "blocks of 0.6 ms" in w and "1 of 4 blocks" in w
    assert "the shortest ending on line 0 at X 0, Y 0.0066 mm" in w
    assert "process.block_rate_limit_per_s = 1000 (the default)" in w
    assert "process.arc_length" in w and "process.feed_mm_per_min" in w
    # the scene's limit: above the rate passes, below it fails and says so
    assert linear_block_rate(x, y, z, line, 60.0, limit=2000)["ok"]
    r = linear_block_rate(x, y, z, line, 60.0, limit=250)
    assert r["blocks_over_limit"] == 2 and "= 250 (the scene)" in r["warning"]
    # twice the feed: twice the rate; a feed per block (the block ending at each point)
    assert math.isclose(linear_block_rate(x, y, z, line, 120.0)["max_per_s"], 2 / 0.0006,
                        rel_tol=1e-9)
    feed = np.array([60.0, 60.0, 60.0, 6.0, 60.0, 600.0])  # the short block at 6 mm/min
    r = linear_block_rate(x, y, z, line, feed)
    assert math.isclose(r["max_per_s"], 1 / 0.001, rel_tol=1e-9) and r["ok"]  # line 1: 1 ms
    with pytest.raises(InputError, match="block_rate_limit_per_s must be > 0"):
        linear_block_rate(x, y, z, line, 60.0, limit=0)
    with pytest.raises(InputError, match="feed of an X-Y-Z program must be > 0"):
        linear_block_rate(x, y, z, line, 0.0)


SCULPT = ["design.rows=3", "design.cols=3", "process.arc_length=0.0025",
          "process.feed_mm_per_min=200", "simulation.region=[-0.3,-0.3,0.3,0.3]",
          "simulation.pixel=0.004", "material.preset='ideal'"]


def test_sculpturing_program_reports_and_warns_its_block_rate(tmp_path, caplog):
    """``toolpath`` of a sculpturing scene at 200 mm/min with 2.5 um steps (about 1333
    blocks a second): ``toolpath.block_rate`` as the written program's blocks give it
    (their lengths over the F words read back), a note over the default limit, a warning
    over the scene's, nothing under it; the summary row shows it."""
    with caplog.at_level(logging.INFO, logger="render_inspect"):
        run_toolpath(load_scene("sculpt_quad_mla", SCULPT), tmp_path / "a", fmt="nc")
    rate = json.loads((tmp_path / "a" / "toolpath.json").read_text())["toolpath"]["block_rate"]
    # the same from the file: the time of each block within a line (its length at F)
    prog = read_program_nc(tmp_path / "a" / "toolpath.nc")
    same = np.diff(prog.line) == 0
    dt = np.diff(prog.t)[same]
    assert rate["blocks"] == int(same.sum())
    assert math.isclose(rate["max_per_s"], 1 / dt.min(), rel_tol=1e-3)
    assert math.isclose(rate["median_per_s"], float(np.median(1 / dt)), rel_tol=1e-3)
    # 200 mm/min over steps of about 2.5 um (the cells cut into equal steps of at most
    # 2.5 um along Y, a little longer with the slope in Z): 1333 blocks a second
    assert math.isclose(rate["median_per_s"], 200 / 60 / 0.0025, rel_tol=0.01)
    assert not rate["ok"] and not rate["limit_from_scene"]
    said = [r for r in caplog.records if "blocks/s" in r.getMessage()]
    assert len(said) == 1 and said[0].levelno == logging.INFO
    assert said[0].getMessage().startswith("note: ") and "(the default)" in said[0].getMessage()
    caplog.clear()
    with caplog.at_level(logging.WARNING, logger="render_inspect"):
        run_toolpath(load_scene("sculpt_quad_mla", SCULPT + ["process.block_rate_limit_per_s=1200"]),
                     tmp_path / "b", fmt="npz")
    said = [r for r in caplog.records if "blocks/s" in r.getMessage()]
    assert len(said) == 1 and said[0].levelno == logging.WARNING and "(the scene)" in said[0].getMessage()
    caplog.clear()
    with caplog.at_level(logging.INFO, logger="render_inspect"):
        run_toolpath(load_scene("sculpt_quad_mla", SCULPT + ["process.block_rate_limit_per_s=5000"]),
                     tmp_path / "c", fmt="npz")
    facts = json.loads((tmp_path / "c" / "toolpath.json").read_text())
    assert facts["toolpath"]["block_rate"]["ok"] and facts["toolpath"]["block_rate"]["limit_per_s"] == 5000
    assert not [r for r in caplog.records if "blocks/s" in r.getMessage()]
    from render_inspect.pipeline._summaries import toolpath_summary  # (the rows printed)
    rows = dict(toolpath_summary(facts))
    assert rows["block rate, max"] == f"{rate['max_per_s']:,.0f} blocks/s (limit 5,000)"


def test_the_sculpturing_limit_key_is_checked_and_left_out_without_it():
    scene = load_scene("sculpt_quad_mla", ["process.block_rate_limit_per_s=1500"])
    assert scene.to_dict()["process"]["block_rate_limit_per_s"] == 1500
    with pytest.raises(SceneError, match=r"block_rate_limit_per_s: must be a finite number in "
                                         r"\(0, 10000000\]; received 0"):
        load_scene("sculpt_quad_mla", ["process.block_rate_limit_per_s=0"])
    assert "block_rate_limit_per_s" not in load_scene("sculpt_quad_mla").to_dict()["process"]


def test_a_raster_program_read_from_a_file_has_its_block_rate(tmp_path):
    """An X-Y-Z program file at F60 (1 mm/s): blocks of 5 um along Y (200 a second) and,
    at each line's end, one of 0.5 um (2000 a second, over the default 1000)."""
    from render_inspect.design import make_surface
    from render_inspect.processes import process_of

    rows = ["G90 G94 G21 G17 F60"]
    for xk in (-0.099875, 0.099875):
        rows += [f"G00 X{xk} Y-0.2 Z0.05", "G01 Z0.0"]
        rows += [f"G01 Y{-0.2 + 0.005 * k:.4f} Z0.0" for k in range(1, 80)]
        rows += ["G01 Y0.1955 Z0.0", "G01 Z0.05"]
    p = tmp_path / "raster.nc"
    p.write_text("\n".join(rows) + "\n")
    sc = load_scene("sculpt_quad_mla", ["design.rows=2", "design.cols=2",
                                        "simulation.region=[-0.19975,-0.19975,0.19975,0.19975]",
                                        f"process.program={json.dumps(str(p))}"])
    proc = process_of(sc)
    cfg = proc.inputs_of(sc)
    rate = proc.plan(cfg, make_surface(sc.design)).facts["toolpath"]["block_rate"]
    assert math.isclose(rate["max_per_s"], 2000.0, rel_tol=1e-9)
    assert math.isclose(rate["median_per_s"], 200.0, rel_tol=1e-9)
    assert rate["blocks_over_limit"] == 2 and not rate["ok"]
    assert "2,000 blocks/s" in rate["warning"] and "fewer, longer blocks" in rate["warning"]
