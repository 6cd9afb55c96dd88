"""Surface-generation simulation against closed-form answers (seed 000, seed 001)."""

import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from render_inspect.errors import MemoryBudgetError
from render_inspect.io import read_heightmap_exr
from render_inspect.machining import residual_metrics, simulate_turning
from render_inspect.pipeline import simulate as simulate_scene
from render_inspect.scene import load_scene
from render_inspect.toolpath import ToolPath

# The direct (reference) cut and envelope models are compiled on their first call, 15 CPU-s
# each from an empty cache: the files that call them run on one worker under `make test`,
# so each is compiled once per run (the two workers compiled them side by side before).
pytestmark = pytest.mark.xdist_group("direct_models")

REPO = Path(__file__).resolve().parents[1]
GRID = REPO / "scenes" / "sts_sinusoidal_grid.toml"
FIG16 = REPO / "scenes" / "sts_fig16_overcut.toml"
#: the commanded geometry: the shipped scenes cut on a lathe preset with a material
IDEAL = ["machine.preset='ideal'", "material.preset='ideal'"]
FLAT = ["design={type='plane'}", "simulation.region=[0.4,-0.05,0.5,0.05]", "simulation.pixel=0.0005",
        *IDEAL]


def test_flat_scallop_height_and_sq():
    s = load_scene(GRID, FLAT)
    Rc, f = s.tool.nose_radius, s.process.feed_per_rev
    res = simulate_scene(s)
    r = res.heightmap.residual
    h = Rc - math.sqrt(Rc ** 2 - (f / 2) ** 2)  # seed 001: H = r - sqrt(r^2 - (f/2)^2)
    assert np.nanmax(r) - np.nanmin(r) == pytest.approx(h, rel=0.01)
    # parabolic scallop z = d^2 / (2 Rc), d uniform on [-f/2, f/2]: Sq = f^2 / (Rc sqrt(720))
    sq = f ** 2 / (Rc * math.sqrt(720))
    assert res.metrics["residual"]["Sq_nm"] == pytest.approx(sq * 1e6, rel=0.02)


def test_z_compensated_path_never_gouges():
    for scene in (GRID, FIG16):
        s = load_scene(scene, ["process.compensation='z'", "simulation.region=[-0.3,-0.3,0.3,0.3]",
                               "simulation.pixel=0.003", *IDEAL])
        res = simulate_scene(s)
        # machined >= design up to the reported linearisation (chordal) error of the path:
        # between programmed points the axes move linearly
        tol = res.metrics["toolpath"]["chordal_error_max_nm"] + 1e-4
        assert res.metrics["residual"]["min_nm"] > -tol
        assert tol < 0.1


def test_uncompensated_overcut_is_rc_slope_squared_over_two():
    slope, Rc = 0.02, 0.5
    s = load_scene(GRID, [f"design={{type='plane', slope_x={slope}}}", "process.compensation='none'",
                          f"tool.nose_radius={Rc}", "process.feed_mm_per_min=0.1",
                          "simulation.region=[0.5,-0.02,0.6,0.02]", "simulation.pixel=0.001", *IDEAL])
    m = simulate_scene(s).metrics["residual"]
    # along +x the radial slope is the plane's slope: overcut Rc s^2 / 2 (minus a small scallop share)
    assert m["min_nm"] == pytest.approx(-Rc * slope ** 2 / 2 * 1e6, rel=0.05)


def test_fig16_uncompensated_surface_shows_overcut_waviness():
    s = load_scene(FIG16, ["simulation.region=[-0.5,-0.5,0.5,0.5]", "simulation.pixel=0.004", *IDEAL])
    none = simulate_scene(s).metrics["residual"]
    zres = simulate_scene(s.with_overrides(["process.compensation='z'"]))
    z = zres.metrics["residual"]
    slope = 2 * math.pi * 0.001 / 0.5
    assert none["min_nm"] < -0.5 * 0.5 * slope ** 2 / 2 * 1e6  # overcut of the order of Rc s^2 / 2
    assert z["min_nm"] > -(zres.metrics["toolpath"]["chordal_error_max_nm"] + 1e-4)
    assert none["Sq_nm"] > z["Sq_nm"]


@pytest.mark.parametrize("key, lo, hi, falls", [("process.spindle_rpm", 50, 150, True),
                                                 ("tool.nose_radius", 0.2, 1.0, True),
                                                 ("process.feed_mm_per_min", 0.2, 1.0, False)])
def test_seed000_fig15_trends(key, lo, hi, falls):
    base = ["simulation.region=[0.3,0.3,0.45,0.45]", "simulation.pixel=0.0005"]
    sq = [simulate_scene(load_scene(GRID, base + [f"{key}={v}"])).metrics["residual"]["Sq_nm"] for v in (lo, hi)]
    assert (sq[1] < sq[0]) if falls else (sq[1] > sq[0])


def test_envelope_of_a_hand_made_path_on_the_axis():
    # one revolution at constant radius and height: a circular groove of the nose profile
    theta = np.linspace(0, 4 * np.pi, 4001)
    rho = np.full_like(theta, 0.3)
    path = ToolPath(theta, rho, np.zeros_like(theta), theta / 10)
    z = simulate_turning(path, nose_radius=0.5, region=(0.2, 0.0, 0.4, 0.0), pixel=0.01)
    x = 0.2 + 0.01 * np.arange(21)
    np.testing.assert_allclose(z[0], 0.5 - np.sqrt(0.25 - (x - 0.3) ** 2), atol=1e-12)


@pytest.mark.slow
def test_memory_estimate_refuses_oversized_requests():
    s = load_scene(GRID, ["simulation.region=[-5,-5,5,5]", "simulation.pixel=0.0001", "simulation.max_memory_gb=1"])
    with pytest.raises(MemoryBudgetError, match=r"GiB.*simulation.max_memory_gb.*simulation.pixel"):
        simulate_scene(s)


def test_residual_metrics_known_values():
    r = np.array([[1.0, -1.0], [1.0, -1.0]]) * 1e-6
    m = residual_metrics(r)
    assert m["Sa_nm"] == pytest.approx(1.0) and m["Sq_nm"] == pytest.approx(1.0)
    assert m["Sz_nm"] == pytest.approx(2.0) and m["min_nm"] == pytest.approx(-1.0)


@pytest.mark.slow
def test_simulate_cli_writes_contract_files(tmp_path):
    out = tmp_path / "sim"
    cmd = [sys.executable, "-m", "render_inspect.cli", "simulate", str(GRID), "--out", str(out),
           "--set", "simulation.region=[0.2,0.2,0.3,0.3]", "--set", "simulation.pixel=0.002"]
    subprocess.run(cmd, check=True, capture_output=True)
    assert {"heightmap.exr", "metrics.json", "toolpath.npz", "residual.png"} <= {p.name for p in out.iterdir()}
    m = json.loads((out / "metrics.json").read_text())
    for k in ("Sa_nm", "Sq_nm", "Sz_nm", "Sp_nm", "Sv_nm", "min_nm"):
        assert k in m["residual"]
    for k in ("points", "revolutions", "feed_per_rev_mm"):
        assert k in m["toolpath"]
    assert {"toolpath", "simulate"} <= set(m["timing_s"]) and m["samples"] == 51 * 51
    assert m["compensation"] == "z" and m["software_version"]
    hm = read_heightmap_exr(out / "heightmap.exr")
    assert hm.pixel == 0.002 and hm.origin == (0.2, 0.2)
    from render_inspect.io import read_exr

    ch, attrs = read_exr(out / "heightmap.exr")
    assert set(ch) == {"design", "machined", "residual"}
    assert attrs["units"] == "mm" and attrs["scene"]["name"] == "sts_sinusoidal_grid"
    np.testing.assert_allclose(ch["residual"], (hm.machined - hm.design), atol=1e-9)
    tp = np.load(out / "toolpath.npz")
    assert set(tp.files) == {"theta", "rho", "x", "y", "z", "t"}
    # bad input: clear error, exit code 1, nothing written
    bad = tmp_path / "bad"
    p = subprocess.run(cmd[:6] + [str(bad), "--set", "tool.nose_radius=-1"], capture_output=True, text=True)
    assert p.returncode == 1 and "tool.nose_radius" in p.stderr and not bad.exists()


@pytest.mark.slow
def test_help_is_fast_and_imports_no_engine():
    code = ("import sys, render_inspect.cli as c\n"
            "try:\n    c.main(['--help'])\nexcept SystemExit:\n    pass\n"
            "heavy = [m for m in ('mitsuba', 'drjit', 'bpy', 'numba', 'scipy', 'matplotlib', 'OpenEXR') if m in sys.modules]\n"
            "print(heavy)")
    p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert p.stdout.strip().splitlines()[-1] == "[]"


def test_same_inputs_same_outputs(tmp_path):
    s = load_scene(GRID, ["simulation.region=[0.1,0.1,0.2,0.2]", "simulation.pixel=0.002"])
    a, b = simulate_scene(s).heightmap, simulate_scene(s).heightmap
    assert np.array_equal(a.machined, b.machined, equal_nan=True)
