"""Tool-path export: NC program and CSV round trips, format dispatch, bad input."""

from __future__ import annotations

import math

import numpy as np
import pytest
from numpy.testing import assert_allclose

from render_inspect.errors import InputError
from render_inspect.io import (
    CSV_COLUMNS,
    export_program,
    read_csv,
    read_nc,
    read_toolpath_npz,
    write_csv,
    write_nc,
)
from render_inspect.toolpath import ToolPath


def _path(n=3000, seed=1):
    rng = np.random.default_rng(seed)
    theta = np.cumsum(rng.uniform(0.001, 0.01, n))
    rho = 4.75 - 0.005 * theta / (2 * math.pi) + rng.normal(0, 1e-4, n)
    z = 0.002 * np.sin(7 * theta) - 0.001
    t = 12.5 + theta / (2 * math.pi * 42 / 60) + rng.uniform(0, 1e-5, n)
    t = np.maximum.accumulate(t + np.arange(n) * 1e-9)
    return ToolPath(theta, rho, z, t, {"spindle_rpm": 42, "compensation": "z"})


def test_nc_round_trip_to_stated_precision(tmp_path):
    p = _path()
    f = write_nc(tmp_path / "toolpath.nc", p, header={"scene": "rcse_circular_array"})
    q = read_nc(f)
    assert q.points == p.points
    assert_allclose(np.degrees(q.theta), np.degrees(p.theta), atol=5.0001e-7)  # 1e-6 deg
    assert_allclose(q.rho, p.rho, atol=5.0001e-7)  # 1 nm
    assert_allclose(q.z, p.z, atol=5.0001e-7)
    assert_allclose(q.t, p.t, atol=1e-6)
    assert q.meta["scene"] == "rcse_circular_array" and q.meta["spindle_rpm"] == "42"
    text = f.read_text().splitlines()
    assert text[0].startswith("; render_inspect generic C-X-Z")
    assert any(line.startswith("; software_version:") for line in text)
    assert "G90 G93" in text
    assert text[-1] == "M30"
    blocks = [line for line in text if line.startswith("N")]
    assert blocks[1].split()[:2] == ["N2", "G01"] and blocks[1].split()[-1].startswith("F")
    # higher precision on request
    q9 = read_nc(write_nc(tmp_path / "p9.nc", p, decimals=9))
    assert_allclose(q9.rho, p.rho, atol=5.0001e-10)


def test_nc_reader_handles_modal_words_and_comments(tmp_path):
    prog = tmp_path / "hand.nc"
    prog.write_text("; t0_s: 1.0\n%\n(generic program)\nG90 G93\n"
                    "N10 G01 C0 X2.0 Z0.0 ; start\n"
                    "N20 C90 F60 (1 s)\n"
                    "N30 X1.5 Z-0.001 F30\n"
                    "M30\n")
    q = read_nc(prog)
    assert_allclose(np.degrees(q.theta), [0, 90, 90])
    assert_allclose(q.rho, [2.0, 2.0, 1.5])
    assert_allclose(q.z, [0.0, 0.0, -0.001])
    assert_allclose(q.t, [1.0, 2.0, 4.0])


def test_nc_bad_input(tmp_path):
    p = _path(5)
    bad_t = ToolPath(p.theta, p.rho, p.z, np.array([0.0, 1.0, 1.0, 2.0, 3.0]))
    with pytest.raises(InputError, match=r"strictly increasing.*t\[1\]"):
        write_nc(tmp_path / "a.nc", bad_t)
    with pytest.raises(InputError, match="decimals"):
        write_nc(tmp_path / "a.nc", p, decimals=2)
    prog = tmp_path / "bad.nc"
    prog.write_text("G90 G93\nN1 G01 C0 X1 Z0\nN2 C1 X1 Z0 F10 @@\n")
    with pytest.raises(InputError, match=r"bad.nc:3: cannot parse '@@'"):
        read_nc(prog)
    prog.write_text("G90 G93\nN1 G01 C0 X1 Z0\nN2 C1 X1 Z0\n")
    with pytest.raises(InputError, match=r":3: motion block without an F"):
        read_nc(prog)
    prog.write_text("N1 G01 C0 Z0\n")
    with pytest.raises(InputError, match="lacks the X word"):
        read_nc(prog)
    with pytest.raises(InputError, match="not found"):
        read_nc(tmp_path / "missing.nc")


def test_csv_round_trip_exact(tmp_path):
    p = _path()
    f = write_csv(tmp_path / "toolpath.csv", p)
    assert f.read_text().splitlines()[0] == "t_s,c_deg,x_mm,z_mm,theta_rad,rho_mm,y_mm"
    q = read_csv(f)
    for name in ("theta", "rho", "z", "t"):
        assert np.array_equal(getattr(q, name), getattr(p, name)), name
    d = np.loadtxt(f, delimiter=",", skiprows=1)
    col = dict(zip(CSV_COLUMNS, d.T))
    assert_allclose(col["x_mm"], p.x, rtol=0, atol=1e-15)
    assert_allclose(col["y_mm"], p.y, rtol=0, atol=1e-15)
    assert_allclose(col["c_deg"], np.degrees(p.theta), rtol=1e-15)


def test_export_dispatch(tmp_path):
    p = _path(50)
    for fmt, name in (("npz", "toolpath.npz"), ("csv", "toolpath.csv"), ("nc", "toolpath.nc")):
        f = export_program(p, tmp_path / "out", fmt=fmt, header={"scene": "x"})
        assert f.name == name and f.is_file()
    q = read_toolpath_npz(tmp_path / "out" / "toolpath.npz")
    assert_allclose(q.rho, p.rho)
    with pytest.raises(InputError, match=r"--format must be one of \['csv', 'nc', 'npz'\], received 'gcode'"):
        export_program(p, tmp_path, fmt="gcode")
    bad = tmp_path / "h.csv"
    bad.write_text("a,b\n1,2\n")
    with pytest.raises(InputError, match="CSV header must be"):
        read_csv(bad)


def test_rcse_path_exports_and_parses_back(tmp_path):
    from pathlib import Path

    from render_inspect.pipeline import plan_program
    from render_inspect.processes import process_of
    from render_inspect.scene import load_scene

    scene = load_scene(Path(__file__).resolve().parents[1] / "scenes" / "rcse_circular_array.toml",
                       ["process.workpiece_radius=1.3", "process.inner_radius=1.2"])
    path = plan_program(scene).program
    process = process_of(scene)
    f = export_program(path, tmp_path, fmt="nc",
                       header=process.program_header(process.inputs_of(scene)))
    q = read_nc(f)
    assert q.meta["scene"] == "rcse_circular_array" and q.meta["spindle_rpm"] == "42.0"
    assert q.meta["compensation"] == "z" and int(q.meta["points"]) == path.points
    assert_allclose(q.rho, path.rho, atol=5.0001e-7)
    assert_allclose(q.z, path.z, atol=5.0001e-7)
    assert_allclose(q.theta, path.theta, atol=math.radians(5.0001e-7))
    assert_allclose(q.t, path.t, atol=1e-6)
    assert np.all(np.diff(q.rho) < 0)  # X still descends monotonically after the round trip
