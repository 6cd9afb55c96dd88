"""The measured cutting edge: edge files, the kernels' nose at the contact angle, the form
error the edge imprints and its compensation."""

from __future__ import annotations

import math

import numpy as np
import pytest

from render_inspect.core.errors import InputError
from render_inspect.core.toolpath import ToolPath
from render_inspect.machining import simulate_turning
from render_inspect.toolpath import EdgeProfile, read_edge_file, z_compensation

NM = 1e-6  # mm per nm


class _Bowl:
    """z = s r^2 / (2 Rd): a concave bowl (s = +1) or a dome (s = -1); slope s r / Rd."""

    def __init__(self, Rd, s):
        self.Rd, self.s = Rd, s

    def height(self, x, y):
        return self.s * (np.asarray(x) ** 2 + np.asarray(y) ** 2) / (2 * self.Rd)


def _wavy(amp_nm=300.0, period_deg=40.0, phase_deg=40.0):
    return EdgeProfile.from_harmonics([(amp_nm, period_deg, phase_deg)])


def _spiral(r_out, r_in, f, n_rev_pts):
    revs = (r_out - r_in) / f
    n = int(round(revs * n_rev_pts)) + 1
    th = np.linspace(0.0, revs * 2 * math.pi, n)
    rho = r_out - f * th / (2 * math.pi)
    return th, rho


def _cut(surface, edge_plan, edge_cut, *, Rc=0.5, hw=0.25, f=0.001):
    """Machined strip along +x (r 0.2 .. 0.45 mm) by a path planned with ``edge_plan`` and
    cut by a tool with ``edge_cut`` (the path reaches every contact: tool axis 0.02 .. 0.75 mm)."""
    th, rho = _spiral(0.75, 0.02, f, 360)
    z = z_compensation(surface, th, rho, Rc, max_slope=0.5, half_width=hw, edge=edge_plan)
    path = ToolPath(th, rho, z, th)
    region = (0.2, -0.002, 0.45, 0.002)
    m = simulate_turning(path, nose_radius=Rc, half_width=hw, region=region, pixel=0.002, edge=edge_cut)
    x = 0.2 + 0.002 * np.arange(m.shape[1])
    return x, m[m.shape[0] // 2]


@pytest.mark.slow
@pytest.mark.parametrize("sign", [1, -1])
def test_measured_edge_imprints_the_forward_model_form_error(sign):
    """A tool tracing a slope of angle theta touches the edge at theta: a wavy edge moves
    the surface by -delta(theta) along the normal (derived independently of the kernels)."""
    surf = _Bowl(1.0, sign)
    edge = _wavy()
    x, m0 = _cut(surf, None, None)
    _, m1 = _cut(surf, None, edge)
    theta = np.arctan(sign * x / 1.0)  # contact angle on the edge: 11 .. 24 deg
    predicted = -edge.deviation(theta)  # along the normal
    measured = (m1 - m0) * np.cos(theta)
    # the model is first order in the edge's slope: the contact moves along the wavy edge by
    # g' / k (g' = delta' / Rc its slope, k the curvature of the nose against the path),
    # lowering the surface by g'^2 / (2 k), here below 10 nm; within 10 % of the amplitude
    assert np.ptp(predicted) > 200 * NM
    assert np.max(np.abs(measured - predicted)) < 30 * NM
    # the contact angles span the waviness periods: the signs and the side of the edge count
    assert np.corrcoef(measured, predicted)[0, 1] > 0.99


@pytest.mark.slow
def test_edge_compensation_removes_the_form_error():
    surf = _Bowl(1.0, 1)
    edge = _wavy(amp_nm=300.0, period_deg=12.0)
    x, ref = _cut(surf, None, None)  # circular nose on its own path: scallops only
    _, plain = _cut(surf, None, edge)  # the wavy edge on the circle's path
    _, comp = _cut(surf, edge, edge)  # the path planned against the edge
    err_plain = np.max(np.abs(plain - ref))
    err_comp = np.max(np.abs(comp - ref))
    assert err_plain > 250 * NM
    assert err_comp < 0.05 * err_plain


def test_circular_nose_unchanged_by_an_empty_edge():
    """No edge and an edge of zero deviation give the same surface (the circle's branch is
    the kernels' own arithmetic)."""
    th, rho = _spiral(0.3, 0.05, 0.01, 90)
    path = ToolPath(th, rho, 0.01 * rho ** 2, th)
    region = (0.05, 0.0, 0.15, 0.02)
    a = simulate_turning(path, nose_radius=0.2, half_width=0.1, region=region, pixel=0.005)
    b = simulate_turning(path, nose_radius=0.2, half_width=0.1, region=region, pixel=0.005,
                         edge=EdgeProfile(np.array([-1.0, 1.0]), np.zeros(2)))
    assert np.array_equal(np.isnan(a), np.isnan(b)) and np.nanmax(np.abs(a - b)) <= 1e-15


def test_height_table_is_the_edge_geometry():
    """The table's nose height at offset d is that of the point r(theta) sin theta = d."""
    Rc, hw = 0.5, 0.25
    edge = _wavy(400.0, 15.0, 10.0)
    tab = edge.height_table(Rc, hw)
    d0, idw = tab[0], tab[1]
    for th in np.radians([-25.0, -7.0, 0.0, 3.0, 21.0]):
        r = Rc + edge.deviation(th)
        d, z = r * math.sin(th), Rc - r * math.cos(th)
        u = (d - d0) * idw
        k = int(u)
        g = tab[3 + k] + (u - k) * (tab[4 + k] - tab[3 + k])
        # linear interpolation over 61 nm steps of the offset: within 0.01 nm
        assert abs(Rc - math.sqrt(Rc * Rc - d * d) + g - z) < 1e-8
    assert tab[2] <= 0


# ------------------------------------------------------------------ edge files
def test_angle_layout_reads(tmp_path):
    p = tmp_path / "edge.csv"
    ang = np.linspace(-40, 40, 81)
    dev = 150 * np.sin(np.radians(ang) * 20)
    p.write_text("# measured edge\nangle_deg, deviation_nm\n" +
                 "\n".join(f"{a:.3f}, {d:.6f}" for a, d in zip(ang, dev)))
    e = read_edge_file(p)
    assert np.max(np.abs(np.degrees(e.angle) - ang)) <= 1e-9
    assert np.max(np.abs(e.delta / NM - dev)) <= 1e-6
    assert e.source == "edge.csv"


def test_angle_layout_in_micrometres_tab_separated(tmp_path):
    p = tmp_path / "edge.txt"
    p.write_text("angle_deg\tdeviation_um\n" + "\n".join(f"{a}\t{0.1 * (a % 2)}" for a in range(-10, 11)))
    e = read_edge_file(p)
    assert e.deviation(math.radians(1.0)) == pytest.approx(0.1e-3)


def test_xz_layout_reads(tmp_path):
    """Points of a wavy edge in an arbitrary frame give back its deviation and radius."""
    Rc = 0.5
    th = np.radians(np.linspace(-45, 45, 301))
    delta = 250 * NM * np.cos(2 * np.pi * th / np.radians(10.0))
    xc, zc = 3.0, 7.0  # the centre, anywhere
    x = xc + (Rc + delta) * np.sin(th)
    z = zc - (Rc + delta) * np.cos(th)
    p = tmp_path / "edge_xz.csv"
    p.write_text("x_um, z_um\n" + "\n".join(f"{a * 1e3:.9f}, {b * 1e3:.9f}" for a, b in zip(x, z)))
    e = read_edge_file(p, nose_radius=Rc)
    assert e.fitted_radius == pytest.approx(Rc, abs=100 * NM)
    # the fitted circle takes up the part of the waviness a circle can (to first order a
    # radius and a centre shift: 1, sin, cos of the angle); the rest comes back
    A = np.column_stack([np.ones_like(th), np.sin(th), np.cos(th)])

    def less_circle(v):
        return v - A @ np.linalg.lstsq(A, v, rcond=None)[0]

    got = e.deviation(th)
    assert np.ptp(less_circle(delta)) > 400 * NM
    assert np.max(np.abs(less_circle(got) - less_circle(delta))) <= 2 * NM


@pytest.mark.parametrize("text, needle", [
    ("1, 2\n3, 4\n", "first line must name the two columns"),
    ("angle_deg, deviation\n" + "1, 2\n" * 10, "deviation column must name its unit"),
    ("angle_deg, deviation_nm\n" + "".join(f"{a}, 0\n" for a in range(9)) + "9, x\n", "line 11"),
    ("angle_deg, deviation_nm\n0, 1\n1, 2\n", "at least 8 rows"),
    ("angle_deg, deviation_nm\n" + "".join(f"{a}, 0\n" for a in (0, 1, 2, 3, 2, 5, 6, 7, 8)), "angles must increase"),
    ("speed, power\n" + "1, 2\n" * 10, "header must be"),
    ("angle_deg, deviation_nm\n" + "".join(f"{a}, 0, 1\n" for a in range(10)), "2 numbers"),
])
def test_malformed_edge_file_one_line(tmp_path, text, needle):
    p = tmp_path / "bad.csv"
    p.write_text(text)
    with pytest.raises(InputError) as err:
        read_edge_file(p)
    msg = str(err.value)
    assert needle in msg and "\n" not in msg and "bad.csv" in msg


def test_scene_reads_the_edge_relative_to_the_scene(tmp_path):
    from render_inspect.scene import load_scene
    from render_inspect.toolpath import Tool

    (tmp_path / "edges").mkdir()
    (tmp_path / "edges" / "e.csv").write_text(
        "angle_deg, deviation_nm\n" + "\n".join(f"{a}, {100 * math.cos(a)}" for a in range(-30, 31)))
    scene = tmp_path / "s.toml"
    scene.write_text('name = "e"\n[design]\ntype = "sinusoidal_grid"\namplitude_x = 0.001\n'
                     'amplitude_y = 0.001\nwavelength_x = 0.5\nwavelength_y = 0.5\n'
                     '[tool]\nnose_radius = 0.5\nedge_profile = "edges/e.csv"\n'
                     'waviness = [[50, 10, 0]]\n[process]\nkind = "sts"\ncompensation = "edge"\n')
    cfg = load_scene(scene)
    tool = Tool.from_config(cfg.tool)
    assert tool.edge is not None and "e.csv" in tool.edge.source
    assert tool.edge.deviation(0.0) == pytest.approx((100 + 50) * NM, rel=1e-6)
    # the edge keys appear in the written scene once set, never for a circular nose
    assert cfg.to_dict()["tool"]["waviness"] == [[50.0, 10.0, 0.0]]
    assert "edge_profile" not in load_scene("sts_fig16_overcut").to_dict()["tool"]


def test_edge_compensation_needs_an_edge():
    from render_inspect.core.errors import SceneError
    from render_inspect.scene import load_scene

    with pytest.raises(SceneError, match="tool.edge_profile or tool.waviness"):
        load_scene("sts_fig16_overcut", ["process.compensation=edge"])


@pytest.mark.slow
def test_material_kernel_and_tiles_use_the_edge():
    """The cutting-mechanics kernel without mechanics (h_min = 0, no recovery, no grooves)
    cuts the envelope of the same measured edge, and a tile of it equals the whole run."""
    from render_inspect.machining._envelope import envelope_fill, prepare_envelope
    from render_inspect.machining._cut_kernel import Grooves, cut_turning, prepare_cut

    surf = _Bowl(1.0, 1)
    edge = _wavy(300.0, 12.0)
    th, rho = _spiral(0.4, 0.02, 0.002, 180)
    z = z_compensation(surf, th, rho, 0.5, max_slope=0.5, half_width=0.25)
    path = ToolPath(th, rho, z, th)
    region = (0.1, -0.004, 0.25, 0.004)
    env = simulate_turning(path, nose_radius=0.5, half_width=0.25, region=region, pixel=0.002, edge=edge)
    plain = simulate_turning(path, nose_radius=0.5, half_width=0.25, region=region, pixel=0.002)
    cp = prepare_cut(path, nose_radius=0.5, half_width=0.25, edge=edge, side_flow=False)
    cut = cut_turning(cp, Grooves.none(), region=region, pixel=0.002)["machined"]
    assert np.nanmax(np.abs(env - plain)) > 100 * NM
    assert np.array_equal(np.isnan(cut), np.isnan(env)) and np.nanmax(np.abs(cut - env)) <= 1e-12
    # a tile from its slice of the path equals the same pixels of the whole grid
    ep = prepare_envelope(path, nose_radius=0.5, half_width=0.25, edge=edge)
    whole = np.empty(env.shape)
    envelope_fill(ep, region[:2], 0.002, whole)
    tile_region = (region[0] + 64 * 0.002, region[1], region[2], region[3])
    sl = ep.slice_for(tile_region)
    assert sl.edge is ep.edge
    tile = np.empty((whole.shape[0], whole.shape[1] - 64))
    envelope_fill(sl, region[:2], 0.002, tile, start=(0, 64))
    assert np.array_equal(tile, whole[:, 64:], equal_nan=True)


_WAVY_SCENE = """
name = "wavy_bowl"
[design]
type = "sphere"
radius = -1.0
[tool]
nose_radius = 0.5
waviness = [[300, 12, 40]]
[process]
kind = "sts"
spindle_rpm = 100
feed_mm_per_min = 0.2
workpiece_radius = 0.6
points_per_rev = 720
compensation = "{comp}"
[simulation]
region = [0.2, -0.006, 0.45, 0.006]
pixel = 0.002
"""


@pytest.mark.slow
def test_simulate_reports_the_edge_imprint_and_its_compensation(tmp_path):
    """``simulate`` of a wavy edge: ``metrics["tool_edge"]`` and ``tool_edge.png``; planned
    for the circular nose the form error is the predicted imprint, planned against the edge
    it is gone."""
    import json
    import subprocess
    import sys

    out = {}
    for comp in ("z", "edge"):
        scene = tmp_path / f"{comp}.toml"
        scene.write_text(_WAVY_SCENE.format(comp=comp))
        r = subprocess.run([sys.executable, "-m", "render_inspect.cli", "-q", "simulate", str(scene),
                            "--out", str(tmp_path / comp)], capture_output=True, text=True, timeout=900)
        assert r.returncode == 0, r.stderr
        assert (tmp_path / comp / "tool_edge.png").stat().st_size > 1000
        m = json.loads((tmp_path / comp / "metrics.json").read_text())
        out[comp] = m["tool_edge"]
    z, e = out["z"], out["edge"]
    assert z["compensation"] == "z" and e["compensation"] == "edge"
    assert z["imprint_predicted_rms_nm"] > 150
    assert z["form_error_rms_nm"] == pytest.approx(z["imprint_predicted_rms_nm"], rel=0.1)
    assert e["form_error_rms_nm"] < 0.05 * z["form_error_rms_nm"]



_GPU_EDGE_CHECK = '''
import math, sys
import numpy as np
sys.path.insert(0, sys.argv[1])
from test_tool_edge import _Bowl, _spiral, _wavy
from render_inspect.core.toolpath import ToolPath
from render_inspect.machining._envelope import prepare_envelope, envelope_fill
from render_inspect.machining._envelope_gpu import cuda_available, envelope_fill_gpu
from render_inspect.toolpath import z_compensation
assert cuda_available()
th, rho = _spiral(0.06, 0.0, 0.002, 90)
z = z_compensation(_Bowl(1.0, 1), th, rho, 0.05, max_slope=0.1, half_width=0.025)
ep = prepare_envelope(ToolPath(th, rho, z, th), nose_radius=0.05, half_width=0.025, edge=_wavy(200.0, 12.0))
assert ep.uniform and ep.edge.size
region, shape = (-0.01, -0.008, 0.01, 0.009), (18, 21)
cpu = envelope_fill(ep, region[:2], 0.001, np.empty(shape))
gpu = envelope_fill_gpu(ep, region[:2], 0.001, np.empty(shape))
assert np.array_equal(np.isnan(cpu), np.isnan(gpu))
print(float(np.nanmax(np.abs(cpu - gpu))))
'''


@pytest.mark.slow
@pytest.mark.parametrize("simulator", [
    pytest.param(True, id="cuda-simulator"),
    pytest.param(False, id="cuda-device", marks=pytest.mark.gpu),
])
def test_gpu_kernel_cuts_the_measured_edge(simulator):
    """The GPU twin of the envelope kernel reads the same edge table (across the axis)."""
    import os
    import subprocess
    import sys
    from pathlib import Path

    from render_inspect.machining._envelope_gpu import cuda_available

    if not simulator and not cuda_available():
        pytest.skip("no CUDA device")
    env = dict(os.environ, NUMBA_ENABLE_CUDASIM="1" if simulator else "0")
    p = subprocess.run([sys.executable, "-c", _GPU_EDGE_CHECK, str(Path(__file__).parent)], env=env,
                       capture_output=True, text=True, timeout=900)
    assert p.returncode == 0, p.stderr[-2000:]
    assert float(p.stdout.strip().splitlines()[-1]) < 1e-12


@pytest.mark.parametrize("value, needle", [("[[-5, 10, 0]]", "amplitude"), ("[[100, 0, 0]]", "period")])
def test_waviness_out_of_range_one_line(value, needle):
    from render_inspect.core.errors import SceneError
    from render_inspect.scene import load_scene

    with pytest.raises(SceneError) as err:
        load_scene("sts_fig16_overcut", [f"tool.waviness={value}"])
    assert needle in str(err.value) and "\n" not in str(err.value)
