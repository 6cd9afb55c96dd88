"""The toolpath command for every process kind, and simulate's extra figures."""

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

REPO = Path(__file__).resolve().parents[1]


def _cli(*args):
    return subprocess.run([sys.executable, "-m", "render_inspect.cli", *map(str, args)],
                          capture_output=True, text=True)


@pytest.mark.parametrize("fmt", ["npz", "csv", "nc"])
@pytest.mark.slow
def test_sculpt_program_export(tmp_path, fmt):
    out = tmp_path / fmt
    p = _cli("toolpath", REPO / "scenes" / "sculpt_quad_mla.toml", "--out", out, "--format", fmt)
    assert p.returncode == 0, p.stderr
    f = out / f"toolpath.{fmt}"
    assert f.stat().st_size > 1000
    if fmt == "csv":
        rows = np.loadtxt(f, delimiter=",", skiprows=1)
        assert rows.shape[1] == 5 and np.all(np.diff(rows[:, 0]) >= 0)  # time never runs back


@pytest.mark.slow
def test_sts_nc_program_parses_back(tmp_path):
    from render_inspect.io import read_nc
    from render_inspect.toolpath import ToolPath

    out = tmp_path / "nc"
    p = _cli("toolpath", REPO / "scenes" / "sts_fig16_overcut.toml", "--out", out, "--format", "nc",
             "--set", "process.workpiece_radius=0.3")
    assert p.returncode == 0, p.stderr
    back = read_nc(out / "toolpath.nc")
    assert isinstance(back, ToolPath) and back.points == 3 * 3600 + 1
    assert np.all(np.diff(back.rho) <= 1e-6)  # inward spiral


@pytest.mark.slow
def test_simulate_on_a_lenslet_array_writes_the_lenslets_table(tmp_path):
    import json

    out = tmp_path / "mla"
    p = _cli("simulate", REPO / "scenes" / "sts_mla_2x2.toml", "--out", out,
             "--set", "simulation.region=[-4,-4,4,4]", "--set", "simulation.pixel=0.02",
             "--set", "machine.preset='ideal'")
    assert p.returncode == 0, p.stderr
    lens = json.loads((out / "metrics.json").read_text())["lenslets"]
    assert len(lens) == 4
    for e in lens:
        assert set(e) >= {"row", "col", "x_mm", "y_mm", "dx_um", "dy_um", "Sa_um", "Sq_um", "PV_um"}
        # the commanded STS path: the lenslets stay where they were designed
        assert abs(e["dx_um"]) < 0.5 and abs(e["dy_um"]) < 0.5
        assert e["PV_um"] < 0.1  # the turning marks only (~24 nm)
