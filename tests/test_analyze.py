"""``render-inspect analyze`` on real instrument files and on forward-model maps, and
``compare --measured`` refusing a file that does not belong to the design before anything
is simulated."""

from __future__ import annotations

import json

import numpy as np
import pytest
from conftest import real_file
from numpy.testing import assert_allclose

from render_inspect.cli import main as cli_main
from render_inspect.core.errors import InputError
from render_inspect.io import read_surface, write_x3p
from render_inspect.metrology import analyze_map
from render_inspect.scene import load_scene

KEYS = {"Sa_nm", "Sq_nm", "Sz_nm", "Sp_nm", "Sv_nm", "Ssk", "Sku", "Sdq", "Sdr_percent",
        "Sal_mm", "Str"}


def _real(name):
    return real_file(name)


@pytest.mark.slow
def test_analyze_non_square_x3p_writes_metrics_png_x3p(tmp_path, capsys):
    import surfalize
    from PIL import Image

    src = _real("mountainsmap_x3p-2.x3p")
    out = tmp_path / "a"
    rc = cli_main(["analyze", str(src), "--out", str(out), "--form", "plane", "--x3p"])
    assert rc == 0
    m = json.loads((out / "metrics.json").read_text())
    assert set(m["areal"]) == KEYS
    assert_allclose(m["pixel_mm"], [1.27656509837346e-4, 3.14582113527746e-4], rtol=1e-9)
    assert m["shape"] == [650, 650] and m["valid_fraction"] == 1.0
    assert m["form"]["method"] == "plane" and m["outliers"]["method"] == "none"
    assert m["outliers"]["count"] > 0 and 0 < m["outliers"]["fraction"] < 1
    assert m["units"]["lateral"] == "mm" and m["input"]["units_in_file"] == {"lateral": "m",
                                                                           "vertical": "m"}
    assert m["input"]["reader"].startswith("x3pio")
    # the same numbers as the library call
    ref = analyze_map(read_surface(src), form="plane").metrics["areal"]
    for k in KEYS - {"Str"}:
        assert_allclose(m["areal"][k], ref[k], rtol=1e-12, err_msg=k)
    assert m["areal"]["Str"] is None  # the lay runs across the whole field
    png = Image.open(out / "height.png")
    assert png.format == "PNG" and png.size[1] > png.size[0]  # 83 x 204 um field, drawn to scale
    s = surfalize.Surface.load(str(out / "height.x3p"))  # third-party reader
    assert_allclose([s.step_x * 1e-3, s.step_y * 1e-3], m["pixel_mm"], rtol=1e-12)
    assert_allclose(s.Sq(), m["areal"]["Sq_nm"] * 1e-3, rtol=1e-9)
    cap = capsys.readouterr()
    assert "done" in cap.err
    # a one-screen summary on stdout: the headline numbers and the output folder
    assert f"render-inspect analyze: {src.name}" in cap.out and "Sa, Sq" in cap.out
    from render_inspect.report import fmt_quantity

    assert fmt_quantity(m["areal"]["Sq_nm"], "nm") in cap.out
    assert str(out.resolve()) in cap.out.replace("\n", "")


@pytest.mark.slow
def test_analyze_sphere_outliers_and_filter_on_a_forward_model(tmp_path):
    px, py = 0.002, 0.003
    ny, nx = 150, 200
    xx, yy = np.meshgrid(px * np.arange(nx), py * np.arange(ny))
    radius = 20.0
    rough = 2e-5 * np.sin(2 * np.pi * xx / 0.02) * np.sin(2 * np.pi * yy / 0.03)
    z = radius - np.sqrt(radius ** 2 - (xx - 0.2) ** 2 - (yy - 0.22) ** 2) + rough
    z[40, 50] += 5e-3  # one spike
    np.save(tmp_path / "m.npy", z)
    (tmp_path / "m.json").write_text(json.dumps({"pixel_mm": [px, py], "units": "mm"}))
    out = tmp_path / "s"
    assert cli_main(["analyze", str(tmp_path / "m.npy"), "--out", str(out), "--form", "sphere",
                     "--outliers", "sigma", "--filter", ",0.1"]) == 0
    m = json.loads((out / "metrics.json").read_text())
    assert_allclose(m["form"]["radius_mm"], radius, rtol=1e-3)
    assert m["outliers"]["left_out"] and m["outliers"]["count"] >= 1
    assert m["outliers"]["fraction"] == pytest.approx(m["outliers"]["count"] / z.size)
    assert m["filter"] == {**m["filter"], "S_mm": None, "L_mm": 0.1}
    # the L-filter at 0.1 mm keeps the 0.02 / 0.03 mm texture: Sq ~ its rms 10 nm
    assert_allclose(m["areal"]["Sq_nm"], 10.0, rtol=0.05)
    assert m["pixel_mm"] == [px, py] and m["shape"] == [ny, nx]
    assert not (out / "height.x3p").exists()


@pytest.mark.parametrize("args,match", [
    (["nope.plu"], "measured file not found"),
    (["SOURCES.md"], "unknown measured file format '.md'"),
    (["truemap_tmd-1.tmd", "--filter", "1,0.5"], "filter L"),
    # tmd-1: 300 x 300 points of 63.2 um, an 18.96 mm field
    (["truemap_tmd-1.tmd", "--filter", "0.0025,0.8"],
     "--filter S must lie within 0.126 .. 19 mm on this map (300 x 300 points of 0.0632 x "
     "0.0632 mm: two pixels to the field's smaller side), received 0.0025 mm (shorter than "
     "two pixels)"),
    (["truemap_tmd-1.tmd", "--filter", ",25"], "--filter L must lie within 0.126 .. 19 mm"),
    (["truemap_tmd-1.tmd", "--filter", "1e-9,1e300"], "--filter S must lie within"),
    (["truemap_tmd-1.tmd", "--filter", ",1e308"], "received 1e+308 mm (longer than the map)"),
    (["truemap_tmd-1.tmd", "--filter", "250,8000"],
     "the value looks like micrometres: --filter 0.25,8 (mm) was probably meant"),
])
def test_analyze_bad_input_one_line_exit_1_nothing_written(tmp_path, capsys, args, match):
    out = tmp_path / "bad"
    # a file that does not exist is one of the cases: only the others are read
    path = tmp_path / args[0] if args[0] == "nope.plu" else real_file(args[0])
    argv = ["analyze", str(path), "--out", str(out), *args[1:]]
    assert cli_main(argv) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and match in err[0] and "Traceback" not in err[0]
    assert not out.exists()


SCENE = """
name = "grid_check"
[design]
type = "sinusoidal_grid"
amplitude_x = 0.002
amplitude_y = 0.002
wavelength_x = 2.5
wavelength_y = 2.5
[tool]
nose_radius = 0.514
[process]
kind = "sts"
spindle_rpm = 50
feed_mm_per_min = 0.5
workpiece_radius = 5.0
[simulation]
region = [-0.45, -0.45, 0.45, 0.45]
pixel = 0.002
seed = 0
"""


@pytest.fixture()
def grid_scene(tmp_path, monkeypatch):
    """A sinusoidal-grid scene whose simulation must never start: the checks come first."""
    import render_inspect.pipeline._compare as pc

    def no_simulation(*a, **k):
        raise AssertionError("compare simulated before checking the measured file")

    monkeypatch.setattr(pc, "simulate", no_simulation)
    p = tmp_path / "grid.toml"
    p.write_text(SCENE)
    return p


def _virtual_measurement(scene_path, tmp_path, *, scale=1.0):
    from render_inspect.design import make_surface

    d = make_surface(load_scene(scene_path).design)
    px = 0.002
    x = -0.45 + px * np.arange(450)
    xx, yy = np.meshgrid(x, x)
    z = d.height(xx + 0.004, yy - 0.003) + 1e-4
    z = z + np.random.default_rng(0).normal(0, 5e-6, z.shape)
    p = tmp_path / f"virtual_{scale:g}.x3p"
    write_x3p(p, z * scale, pixel=px * scale, origin=(x[0] * scale, x[0] * scale))
    return p


@pytest.mark.parametrize("which,reason", [
    # the real files' registrations take several seconds each
    pytest.param("ski", "registration residual RMS", marks=pytest.mark.slow),
    pytest.param("x3p-2", "overlaps 0.0% of the smaller", marks=pytest.mark.slow),
    ("small", "lateral registration is undetermined"),
])
def test_compare_refuses_a_mismatch_before_simulating(grid_scene, tmp_path, capsys, which, reason):
    path = {"ski": _real("alicona_ski.x3p"), "x3p-2": _real("mountainsmap_x3p-2.x3p"),
            "small": None}[which]
    if path is None:  # the design measured correctly, then read 1000 x too small
        path = _virtual_measurement(grid_scene, tmp_path, scale=1e-3)
    out = tmp_path / "cmp"
    rc = cli_main(["compare", str(grid_scene), "--out", str(out), "--measured", str(path)])
    assert rc == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "does not match the design" in err[0] and reason in err[0]
    assert "--force" in err[0]
    assert not out.exists()


@pytest.mark.slow
def test_check_measured_accepts_the_design_and_reports_uncertainty(grid_scene, tmp_path):
    from render_inspect.design import make_surface
    from render_inspect.pipeline import check_measured, expected_sq_mm

    scene = load_scene(grid_scene)
    assert_allclose(expected_sq_mm(scene), 0.01 ** 2 / (12 * np.sqrt(5) * 0.514))
    path = _virtual_measurement(grid_scene, tmp_path)
    m, comp = check_measured(path, scene, make_surface(scene.design))
    ch = comp.metrics["checks"]
    assert ch["ok"] and ch["overlap"]["fraction"] > 0.98
    reg = comp.metrics["registration"]
    # measured(x) = design(x + 4 um, y - 3 um): the design moved by (-4, +3) um
    assert_allclose([reg["tx_mm"], reg["ty_mm"]], [-0.004, 0.003], atol=3e-4)
    u = reg["uncertainty"]
    assert 0 < u["shift_mm"] < 1e-3 and set(u["sigma"]) >= {"tx_mm", "ty_mm", "gamma_rad"}
    assert comp.metrics["outliers"]["count"] >= 0 and "fraction" in comp.metrics["outliers"]
    # --force lets a refused file through, with the reasons kept
    with pytest.raises(InputError, match="does not match the design"):
        check_measured(_real("alicona_ski.x3p"), scene, make_surface(scene.design))
    _, forced = check_measured(_real("alicona_ski.x3p"), scene, make_surface(scene.design),
                               force=True)
    assert not forced.metrics["checks"]["ok"] and forced.metrics["checks"]["refusals"]


@pytest.mark.slow
def test_analyze_warns_about_hole_borders_and_mostly_empty_maps(tmp_path, capsys):
    """Digital Surf sur-2: Sdq/Sdr without the gradients bordering its 117 missing points
    (as SurfaceTopography), both values in metrics.json and a warning; a map 88 %
    unmeasured: a warning naming the share."""
    out = tmp_path / "a"
    assert cli_main(["analyze", str(_real("digitalsurf_sur-2.sur")), "--out", str(out)]) == 0
    m = json.loads((out / "metrics.json").read_text())
    h = m["holes"]
    assert h["n_unmeasured"] == 117 and h["n_border_gradients"] > 0
    assert h["Sdq_with_border"] > 1.05 * m["areal"]["Sdq"]
    assert any("border the map's 117 missing points" in w for w in m["warnings"])
    z = np.random.default_rng(0).normal(0, 1e-5, (80, 80))
    z[:, :71] = np.nan
    np.save(tmp_path / "e.npy", z)
    (tmp_path / "e.json").write_text(json.dumps({"pixel_mm": 0.001}))
    assert cli_main(["analyze", str(tmp_path / "e.npy"), "--out", str(tmp_path / "e")]) == 0
    m = json.loads((tmp_path / "e" / "metrics.json").read_text())
    assert any(w.startswith("89% of the map is not measured") for w in m["warnings"])


@pytest.mark.parametrize("z, match", [
    (np.full((30, 30), 1e300), "heights must lie within +-10000 mm"),
    (np.full((30, 30), np.iinfo(np.uint64).max, dtype=np.uint64), "received values up to 1.84e+19 mm"),
    (np.full((30, 30), np.nan), "no valid (finite) heights"),
])
def test_analyze_implausible_maps_one_line_exit_1(tmp_path, capsys, z, match):
    np.save(tmp_path / "m.npy", z)
    (tmp_path / "m.json").write_text(json.dumps({"pixel_mm": 0.001}))
    out = tmp_path / "o"
    assert cli_main(["analyze", str(tmp_path / "m.npy"), "--out", str(out)]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and match in err[0] and "internal error" not in err[0]
    assert not out.exists()
