"""The exported NC program as a diamond-turning control takes it: the modes and the facts
its header states (units, plane, nose compensation off, the feed mode, the source scene,
the tool's nose radius, the date, the software version, the end), the written numbers
against the planned path (1 nm, 1 micro-degree), the file itself (ASCII, LF, a final line
break), and the block rate the control must keep up with (N points per revolution at S
rpm: N S / 60 blocks a second) against ``process.block_rate_limit_per_s``."""

from __future__ import annotations

import json
import logging
import math
import re

import numpy as np
import pytest

from conftest import run_main
from render_inspect.core.toolpath import ToolPath
from render_inspect.errors import InputError, SceneError
from render_inspect.io import read_nc, read_nc_blocks, write_nc
from render_inspect.pipeline import run_toolpath
from render_inspect.fit import scene_hash as scene_sha256
from render_inspect.scene import find_scene, load_scene
from render_inspect.toolpath import DEFAULT_BLOCK_RATE_LIMIT, block_rate

SMALL = ["simulation.region=[-0.05,-0.05,0.05,0.05]", "simulation.pixel=0.005",
         "process.workpiece_radius=0.6"]
#: 1,000,000,000 s after 1970-01-01 UTC
EPOCH, EPOCH_UTC = "1000000000", "2001-09-09T01:46:40Z"


def _spiral(n_rev: int, ppr: int, rpm: float, r0: float = 1.0, seed: int = 7) -> ToolPath:
    """A spiral of ``ppr`` points per revolution at ``rpm``, its heights random (seeded)
    to the last bit, so that the written places round them."""
    k = np.arange(n_rev * ppr + 1)
    theta = 2 * np.pi * k / ppr
    rho = r0 * (1 - k / k[-1])
    z = np.random.default_rng(seed).uniform(-0.002, 0.002, k.size)
    return ToolPath(theta, rho, z, theta / (2 * np.pi * rpm / 60.0), {})


def test_header_states_modes_source_tool_date_and_the_file_is_clean(tmp_path, capsys, monkeypatch):
    monkeypatch.setenv("SOURCE_DATE_EPOCH", EPOCH)
    sets = [a for s in SMALL + ["tool.nose_radius=0.37"] for a in ("--set", s)]
    outs = []
    for name in ("a", "b"):
        rc, err = run_main(capsys, "toolpath", "sts_sinusoidal_grid", "--format", "nc",
                        "--out", tmp_path / name, *sets)
        assert rc == 0, err
        outs.append((tmp_path / name / "toolpath.nc").read_bytes())
    raw = outs[0]
    # the same scene at the same SOURCE_DATE_EPOCH: the same file
    assert outs[1] == raw
    # ASCII, printable, LF line ends, a line break after the last line (M30)
    assert b"\r" not in raw and raw.endswith(b"M30\n")
    assert all(32 <= b < 127 or b == 10 for b in raw)
    lines = raw.decode("ascii").split("\n")[:-1]
    head = {m.group(1): m.group(2) for m in map(re.compile(r"; (\w+): (.*)").fullmatch, lines) if m}
    scene = load_scene("sts_sinusoidal_grid", SMALL + ["tool.nose_radius=0.37"])
    assert head["created_utc"] == EPOCH_UTC
    assert head["software_version"] and head["scene"] == scene.name
    assert head["scene_file"] == "sts_sinusoidal_grid.toml"
    assert head["scene_sha256_as_run"] == scene_sha256(scene.to_dict())
    import hashlib  # (only this check hashes a file)
    assert head["scene_file_sha256"] == hashlib.sha256(find_scene("sts_sinusoidal_grid").read_bytes()).hexdigest()
    assert float(head["nose_radius_mm"]) == 0.37
    assert float(head["spindle_rpm"]) == scene.process.spindle_rpm
    # the modes come before the first motion block: plane, metric, no nose compensation,
    # absolute, inverse time
    first = next(i for i, ln in enumerate(lines) if ln.startswith("N"))
    modes = " ".join(ln for ln in lines[:first] if not ln.startswith(";")).split()
    assert modes == ["G18", "G21", "G40", "G90", "G93"]
    assert lines[-1] == "M30" and sum(ln == "M30" for ln in lines) == 1
    # the counts the header states are the file's
    facts = json.loads((tmp_path / "a" / "toolpath.json").read_text())
    blocks = [ln for ln in lines if ln.startswith("N")]
    assert int(head["blocks"]) == len(blocks) == facts["program_check"]["blocks"]
    rate = facts["toolpath"]["block_rate"]
    assert math.isclose(float(head["block_rate_max_per_s"]), rate["max_per_s"], rel_tol=1e-5)


def test_a_bad_source_date_epoch_is_one_line(tmp_path, monkeypatch):
    for bad in ("yesterday", "-5", "1e9", "999999999999999"):
        monkeypatch.setenv("SOURCE_DATE_EPOCH", bad)
        with pytest.raises(InputError, match=r"SOURCE_DATE_EPOCH must be whole seconds .* received"):
            write_nc(tmp_path / "p.nc", _spiral(1, 16, 50))
    assert not (tmp_path / "p.nc").exists()


def test_round_trip_to_the_written_places(tmp_path):
    """Every written X, Z (mm) and C (deg) is the planned value to 6 places (within half
    a unit of the last place: 0.5 nm, 0.5 micro-degree) and reads back as written; the
    time of every point within 1e-6 s."""
    path = _spiral(3, 997, 37.0, r0=4.2)  # C steps that are not round decimals
    nc = write_nc(tmp_path / "p.nc", path)
    back = read_nc(nc)
    assert back.points == path.points
    assert np.max(np.abs(back.rho - path.rho)) <= 0.5e-6 + 1e-15
    assert np.max(np.abs(back.z - path.z)) <= 0.5e-6 + 1e-15
    c_plan = np.degrees(path.theta)
    assert np.max(np.abs(np.degrees(back.theta) - c_plan)) <= 0.5e-6 * (1 + 1e-9)
    assert np.max(np.abs(back.t - path.t)) < 1e-6
    # the random heights really were rounded (the check above can fail)
    assert np.max(np.abs(back.z - path.z)) > 0.4e-6
    # each block's numbers: the planned values rounded to 6 places
    blocks = read_nc_blocks(nc)
    assert np.array_equal(blocks.axes["Z"], np.round(path.z, 6))


def test_block_rate_of_a_known_path():
    """N points per revolution at S rpm: N S / 60 blocks a second, every block."""
    for ppr, rpm in ((3600, 50.0), (720, 1000.0), (100, 30.0)):
        path = _spiral(2, ppr, rpm)
        r = block_rate(path.t, radius=path.rho)
        want = ppr * rpm / 60.0
        assert math.isclose(r["max_per_s"], want, rel_tol=1e-9)
        assert math.isclose(r["median_per_s"], want, rel_tol=1e-9)
        assert math.isclose(r["min_block_time_s"], 1 / want, rel_tol=1e-9)
        assert r["blocks"] == path.points - 1 and r["limit_per_s"] == DEFAULT_BLOCK_RATE_LIMIT
        assert r["ok"] == (want <= DEFAULT_BLOCK_RATE_LIMIT)
        assert r["blocks_over_limit"] == (0 if r["ok"] else r["blocks"])
    # the limit set: 3000 blocks/s against 4000 passes, against 2999 fails
    path = _spiral(2, 3600, 50.0)
    assert block_rate(path.t, limit=4000)["ok"]
    r = block_rate(path.t, limit=2999, radius=path.rho)
    assert not r["ok"] and "3,000 blocks/s" in r["warning"]
    assert "process.block_rate_limit_per_s = 2999 (the scene)" in r["warning"]
    # one short block among long ones: the largest rate is its own
    t = np.array([0.0, 0.01, 0.02, 0.0205, 0.03])
    r = block_rate(t)
    assert math.isclose(r["max_per_s"], 2000.0) and r["blocks_over_limit"] == 1
    # points of one block (an arc as chords): the block ends at its last point
    r = block_rate(t, lines=[1, 2, 2, 3, 3])
    assert r["blocks"] == 2 and math.isclose(r["max_per_s"], 1 / 0.01) and r["ok"]
    with pytest.raises(InputError, match="block_rate_limit_per_s must be > 0"):
        block_rate(t, limit=0)


def test_toolpath_reports_and_warns_the_block_rate(tmp_path, caplog):
    """``toolpath`` on a scene of 400 points per revolution at 300 rpm (2000 blocks/s):
    ``toolpath.block_rate`` says it, the summary row says it, and a warning names the
    limit (a note over the default, the control unknown; a warning over the scene's own
    limit); with the scene's limit above it, nothing."""
    base = SMALL + ["process.points_per_rev=400", "process.spindle_rpm=300",
                    "process.feed_mm_per_min=15"]
    with caplog.at_level(logging.INFO, logger="render_inspect"):
        run_toolpath(load_scene("sts_sinusoidal_grid", base), tmp_path / "a", fmt="nc")
    rate = json.loads((tmp_path / "a" / "toolpath.json").read_text())["toolpath"]["block_rate"]
    assert math.isclose(rate["max_per_s"], 400 * 300 / 60, rel_tol=1e-6)
    assert not rate["ok"] and rate["limit_per_s"] == 1000 and rate["limit_source"].startswith("default") and not rate["limit_from_scene"]
    said = [r for r in caplog.records if "blocks/s" in r.getMessage()]
    assert len(said) == 1 and "process.block_rate_limit_per_s = 1000 (the default)" in said[0].getMessage()
    assert said[0].levelno == logging.INFO and said[0].getMessage().startswith("note: ")
    caplog.clear()
    with caplog.at_level(logging.WARNING, logger="render_inspect"):
        run_toolpath(load_scene("sts_sinusoidal_grid", base + ["process.block_rate_limit_per_s=1500"]),
                     tmp_path / "c", fmt="nc")
    said = [r for r in caplog.records if "blocks/s" in r.getMessage()]
    assert len(said) == 1 and said[0].levelno == logging.WARNING and "(the scene)" in said[0].getMessage()
    caplog.clear()
    with caplog.at_level(logging.WARNING, logger="render_inspect"):
        run_toolpath(load_scene("sts_sinusoidal_grid", base + ["process.block_rate_limit_per_s=2500"]),
                     tmp_path / "b", fmt="nc")
    rate = json.loads((tmp_path / "b" / "toolpath.json").read_text())["toolpath"]["block_rate"]
    assert rate["ok"] and rate["limit_per_s"] == 2500 and rate["warning"] is None
    assert not [r for r in caplog.records if "blocks/s" in r.getMessage()]
    from render_inspect.pipeline._summaries import toolpath_summary  # (the rows printed)
    rows = dict(toolpath_summary(json.loads((tmp_path / "b" / "toolpath.json").read_text())))
    assert rows["block rate, max"] == "2,000 blocks/s (limit 2,500)"


def test_the_limit_key_is_checked_and_left_out_of_scenes_without_it():
    with pytest.raises(SceneError, match="block_rate_limit_per_s"):
        load_scene("sts_sinusoidal_grid", ["process.block_rate_limit_per_s=0"])
    assert "block_rate_limit_per_s" not in load_scene("sts_sinusoidal_grid").to_dict()["process"]


def test_the_new_and_the_old_header_are_read_by_the_fast_reader(tmp_path, monkeypatch):
    """The mode blocks are the writers' own: a program with them is read in bulk, and one
    written before them (``G90 G93`` alone) reads the same."""
    from render_inspect.io import _nc_parse  # (the line-by-line reader, made to fail)

    nc = write_nc(tmp_path / "p.nc", _spiral(2, 64, 50))
    old = tmp_path / "old.nc"
    old.write_text(nc.read_text().replace("G18 G21 G40\n", ""))
    monkeypatch.setattr(_nc_parse, "_blocks_line_by_line",
                        lambda path: pytest.fail(f"{path} was read line by line"))
    a, b = read_nc_blocks(nc), read_nc_blocks(old)
    assert {18.0, 21.0, 40.0, 90.0, 93.0} <= set(a.meta["_modes"])
    for k in ("C", "X", "Z"):
        assert np.array_equal(a.axes[k], b.axes[k])
