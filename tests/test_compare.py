"""``render-inspect compare``: both variants through simulate -> render -> phase retrieval
-> report, on a tiny scene (real Mitsuba renders, real EXR files)."""

from __future__ import annotations

import base64
import json
import math
import re

import numpy as np
import pytest

from render_inspect.cli import main as cli_main
from render_inspect.errors import InputError
from render_inspect.io import read_exr, write_heightmap_exr
from render_inspect.scene import load_scene

# A small seed-000 Fig. 16-like grid: Ax = Ay = 1 um, l = 0.5 mm, Rc = 0.5 mm, at a low
# feed (0.02 mm/rev: scallops ~100 nm, resolvable by the interferometer's pixels) so that
# the measured height can be checked too.  The uncompensated path overcuts by about
# Rc slope^2 / 2 ~ 80 nm.
TINY = """
name = "tiny_compare"
description = "tiny Fig. 16-like grid for the compare tests"
[design]
type = "sinusoidal_grid"
amplitude_x = 0.001
amplitude_y = 0.001
wavelength_x = 0.5
wavelength_y = 0.5
[tool]
nose_radius = 0.5
[process]
kind = "sts"
spindle_rpm = 50
feed_mm_per_min = 1
workpiece_radius = 1.0
compensation = "z"
points_per_rev = 720
[simulation]
region = [-0.2, -0.2, 0.2, 0.2]
pixel = 0.002
seed = 7
[render.interferometer]
pixel = 0.002
field_of_view = [-0.1, -0.1, 0.1, 0.1]
[render.diffuse]
resolution = 48
spp = 4
"""

VARIANT_FILES = ["heightmap.exr", "toolpath.npz", "interferogram.exr", "interferogram_fringes.png",
                 "residual.png", "filtered.png", "measurement_error.png", "diffuse_micro.png",
                 "diffuse_macro.png", "metrics.json"]
TOP_FILES = ["report.html", "metrics.json", "difference.png", "interferogram_side_by_side.png",
             "interferogram_difference.png", "diffuse_micro_side_by_side.png",
             "diffuse_macro_side_by_side.png", "diffuse_difference.png",
             "residual_side_by_side.png", "residual_difference.png", "filtered_side_by_side.png",
             "measurement_error_side_by_side.png", "measured_residual_side_by_side.png",
             "sections.png", "kinematics.png"]


@pytest.fixture(scope="module")
def compared(tmp_path_factory):
    """Run ``render-inspect compare`` once (CLI), with a measured file for the third
    column: the design sampled on a shifted grid plus a known tilt."""
    from render_inspect.design import make_surface
    from render_inspect.machining import HeightMap

    d = tmp_path_factory.mktemp("compare")
    scene_path = d / "tiny.toml"
    scene_path.write_text(TINY)
    scene = load_scene(scene_path)
    surf = make_surface(scene.design)
    pixel = 0.002
    x = -0.2 + pixel * np.arange(201)
    xx, yy = np.meshgrid(x, x)
    z = surf.height(xx, yy) + 2e-4 * xx + 5e-5  # tilt and piston: registration removes them
    meas = d / "measured.exr"
    write_heightmap_exr(meas, HeightMap(z, z, pixel, (x[0], x[0])))
    out = d / "out"
    rc = cli_main(["compare", str(scene_path), "--out", str(out), "--measured", str(meas),
                   "--repeat", "2"])
    assert rc == 0
    return out, json.loads((out / "metrics.json").read_text())


@pytest.mark.mitsuba
@pytest.mark.slow
def test_compare_writes_all_files(compared):
    out, _ = compared
    for name in TOP_FILES:
        assert (out / name).is_file(), name
    for variant in ("compensated", "uncompensated"):
        for name in VARIANT_FILES:
            assert (out / variant / name).is_file(), f"{variant}/{name}"
    assert not [p for p in out.parent.iterdir() if ".partial-" in p.name]  # atomic


@pytest.mark.mitsuba
@pytest.mark.slow
def test_compare_metrics_contract_and_overcut(compared):
    _, m = compared
    for key in ("compensated", "uncompensated", "software_version", "seed", "mitsuba_variant"):
        assert key in m
    assert m["seed"] == 7
    for v in ("compensated", "uncompensated"):
        r = m[v]["residual"]
        for k in ("Sa_nm", "Sq_nm", "Sz_nm", "Sp_nm", "Sv_nm", "min_nm"):
            assert np.isfinite(r[k]), (v, k)
        for k in ("rms_nm", "pv_nm", "valid_fraction"):
            assert k in m[v]["measured"]
        assert "Sq_nm" in m[v]["filtered"]
    assert m["compensated"]["compensation"] == "z"
    assert m["uncompensated"]["compensation"] == "none"
    # Z compensation is gouge-free; without it the nose overcuts the slopes by ~ Rc s^2 / 2
    c_min = m["compensated"]["residual"]["min_nm"]
    u_min = m["uncompensated"]["residual"]["min_nm"]
    assert c_min > -1.0
    assert u_min < -30.0
    assert u_min < c_min - 30.0
    assert m["difference"]["machined_pv_nm"] > 30.0


@pytest.mark.mitsuba
@pytest.mark.slow
def test_compare_measured_height_in_interferogram(compared):
    out, m = compared
    ch, attrs = read_exr(out / "compensated" / "interferogram.exr")
    for name in ("intensity", "valid", "height_true", "height_measured", "valid_measured"):
        assert name in ch
    ok = ch["valid_measured"] > 0.5
    assert ok.mean() > 0.9
    err_nm = (ch["height_measured"][ok].astype(float) - ch["height_true"][ok]) * 1e6
    # camera noise on: a few nm; float32 storage of ~1e-3 mm heights adds < 0.1 nm
    assert np.sqrt(np.mean(err_nm ** 2)) < 10.0
    assert m["compensated"]["measured"]["rms_nm"] == pytest.approx(np.sqrt(np.mean(err_nm ** 2)), abs=0.5)
    assert json.loads(attrs["measured"]) if isinstance(attrs["measured"], str) else attrs["measured"]
    # the instrument's view of the residual is close to the truth on the same pixels
    meas = m["compensated"]["measured"]
    assert meas["instrument_residual_Sq_nm"] == pytest.approx(meas["true_residual_Sq_nm"], abs=10.0)


@pytest.mark.mitsuba
@pytest.mark.slow
def test_each_height_exr_is_what_measure_returns(compared, tmp_path):
    # ``render-inspect measure`` on the variant's interferogram.exr (frames and settings,
    # the truth channels ignored) gives the variant's height.exr, bit for bit
    out, _ = compared
    for variant in ("compensated", "uncompensated"):
        rc = cli_main(["measure", str(out / variant / "interferogram.exr"), "--out",
                       str(tmp_path / variant), "-q"])
        assert rc == 0
        a, _ = read_exr(tmp_path / variant / "height.exr")
        b, _ = read_exr(out / variant / "height.exr")
        assert set(a) == set(b) == {"height", "valid", "modulation"}
        for k in a:
            np.testing.assert_array_equal(a[k], b[k], err_msg=f"{variant}: {k}")


@pytest.mark.mitsuba
@pytest.mark.slow
def test_window_difference_comes_from_the_measurements_alone(compared):
    # the measured difference over the common window, formed again from the two
    # height.exr files alone (piston and tilt removed, PSI fringe orders of separate
    # regions taken nearest the largest one's plane), is what metrics.json states
    from render_inspect.metrology import measured_difference

    out, m = compared
    w = m["difference"]["window"]
    assert w["measured"]["form_removed"] == "piston and tilt"
    assert w["measured_piston_removed"]["form_removed"] == "piston"
    h = {}
    for v in ("compensated", "uncompensated"):
        ch, attrs = read_exr(out / v / "height.exr")
        h[v] = np.where(ch["valid"] > 0.5, ch["height"].astype(np.float64), np.nan)
    lam = attrs["effective_wavelength_nm"] * 1e-6
    d, info = measured_difference(h["compensated"], h["uncompensated"],
                                  pixel=attrs["pixel_size_mm"], fringe_order_mm=lam / 2)
    ok = np.isfinite(d)
    rms = float(np.sqrt(np.mean(d[ok] ** 2))) * 1e6
    assert rms == pytest.approx(w["measured"]["rms_nm"], rel=1e-3, abs=1e-3)
    assert abs(w["measured"]["mean_nm"]) < 1e-6  # the piston is gone
    # the truth sits beside it, labelled, with and without the same terms removed
    assert "truth" in w["true"]["source"] and "truth" in w["true_same_form_removed"]["source"]
    assert w["measured"]["rms_nm"] == pytest.approx(w["true_same_form_removed"]["rms_nm"],
                                                    abs=3.0)


@pytest.mark.mitsuba
@pytest.mark.slow
def test_compare_same_camera_for_both(compared):
    out, m = compared
    a = m["compensated"]["interferometer"]
    b = m["uncompensated"]["interferometer"]
    for k in ("origin_mm", "pixel_mm", "shape", "numerical_aperture", "wavelength_nm"):
        assert a[k] == b[k], k
    # two measurements, two noise realisations (seeded from the scene's seed, recorded)
    from render_inspect.metrology import measurement_seeds

    assert a["seed"] != b["seed"]
    assert [a["seed"], b["seed"]] == measurement_seeds(m["seed"], 2)
    noise = m["difference"]["window"]["measured"]["noise"]
    assert noise["seeds"] == {"compensated": a["seed"], "uncompensated": b["seed"]}
    # the floor: the two measurements' own noise in quadrature
    assert noise["floor_nm"] == pytest.approx(math.hypot(noise["a_nm"], noise["b_nm"]))
    assert 0.1 < noise["floor_nm"] < 3.0
    res = m["difference"]["window"]["measured"]["resolution"]
    assert res["verdict"] in ("resolved", "not resolved")
    # --repeat 2: the first pair and one more, with two fresh realisations
    rep = m["difference"]["window"]["measured"]["repeat"]
    assert rep["repeats"] == 2 and rep["seeds"][0] == [a["seed"], b["seed"]]
    assert rep["seeds"][1] == measurement_seeds(m["seed"], 2, repeat=1)


@pytest.mark.mitsuba
@pytest.mark.slow
def test_compare_measured_column(compared):
    _, m = compared
    mf = m["measured_file"]
    reg = mf["registration"]
    # registration takes out the known tilt (2e-4 rad about y) and piston (50 nm)
    assert abs(abs(reg["beta_rad"]) - 2e-4) < 2e-5
    assert mf["measured"]["Sq_nm"] < 2.0  # the design itself, after registration
    assert mf["compared_with_simulation"] is True
    # checked before the simulation: it is the design, fully overlapping, tiny residual
    assert mf["checks"]["ok"] and mf["checks"]["overlap"]["fraction"] > 0.99
    assert set(reg["uncertainty"]["sigma"]) == {"tx_mm", "ty_mm", "tz_mm", "alpha_rad",
                                                "beta_rad", "gamma_rad"}
    assert mf["outliers"]["count"] >= 0 and 0 <= mf["outliers"]["fraction"] < 1
    assert mf["pixel_mm"] == [0.002, 0.002] and mf["units"]["lateral"] == "mm"


@pytest.mark.mitsuba
@pytest.mark.slow
def test_report_html_is_self_contained(compared):
    out, _ = compared
    html = (out / "report.html").read_text()
    srcs = re.findall(r'src="([^"]*)"', html)
    assert all(s.startswith("data:image/png;base64,") for s in srcs)
    embedded = {base64.b64decode(s.split(",", 1)[1]) for s in srcs}
    # every top-level figure is in the page, as the very same PNG
    pngs = {p.read_bytes() for p in out.glob("*.png")}
    assert len(pngs) == 13 and embedded == pngs
    assert not re.search(r'(href|src)="(https?:|//|file:)', html)
    assert "<script" not in html
    assert "compensated" in html and "uncompensated" in html and "measured file" in html
    for text in ("coverage of the simulated region", "overlap after registration",
                 "standard uncertainty", "rotation about z (deg)", "outliers (spikes",
                 "units declared in the file"):
        assert text in html, text
    assert "tiny_compare" in html


def test_compare_missing_measured_file(tmp_path):
    from render_inspect.pipeline import run_compare

    p = tmp_path / "s.toml"
    p.write_text(TINY)
    with pytest.raises(InputError, match="--measured file not found"):
        run_compare(load_scene(p), tmp_path / "out", measured=tmp_path / "nope.x3p")
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("overrides,match", [
    (["metrology.phase_algorithm='5step'"], "needs render.interferometer.steps = 5, got 4"),
    (["metrology.phase_algorithm='4step'", "render.interferometer.step_rad=1.0"],
     "step_rad = pi/2"),
])
def test_compare_refuses_unusable_phase_settings(tmp_path, overrides, match):
    from render_inspect.pipeline import run_compare

    p = tmp_path / "s.toml"
    p.write_text(TINY)
    with pytest.raises(InputError, match=match):
        run_compare(load_scene(p, overrides), tmp_path / "out")
    assert not (tmp_path / "out").exists()


def test_compare_variants_and_render_caps(tmp_path):
    from render_inspect.machining import HeightMap
    from render_inspect.pipeline import (
        COMPARE_MAX_CAMERA_PIXELS,
        COMPARE_MAX_DIFFUSE_RESOLUTION,
        COMPARE_MAX_DIFFUSE_SPP,
        compare_variants,
        preview_render_configs,
    )

    p = tmp_path / "s.toml"
    p.write_text(TINY.replace('compensation = "z"', 'compensation = "none"')
                 .split("[render.interferometer]")[0])
    scene = load_scene(p)
    comp, unc = compare_variants(scene)
    assert comp.process.compensation == "z" and unc.process.compensation == "none"
    assert comp.simulation.seed == unc.simulation.seed == 7
    # no render sizes in the scene: the 20x field (0.9 mm, 1024 px) is cropped around the
    # centre at the objective's pixel; diffuse defaults are capped
    z = np.zeros((601, 601))
    hm = HeightMap(z, z, 0.002, (-0.6, -0.6))
    icfg, dcfg, notes = preview_render_configs(scene, hm)
    from render_inspect.instruments import interferometer_geometry

    g = interferometer_geometry(hm, icfg)
    assert max(g["nx"], g["ny"]) <= COMPARE_MAX_CAMERA_PIXELS
    assert g["pixel"] == pytest.approx(0.9 / 1024)
    assert dcfg.resolution <= COMPARE_MAX_DIFFUSE_RESOLUTION and dcfg.spp <= COMPARE_MAX_DIFFUSE_SPP
    assert len(notes) == 2
    # sizes the scene sets are kept
    p.write_text(TINY)
    icfg2, dcfg2, notes2 = preview_render_configs(load_scene(p), hm)
    assert icfg2.pixel == 0.002 and dcfg2.resolution == 48 and notes2 == []


@pytest.mark.browser
@pytest.mark.mitsuba
@pytest.mark.slow
def test_report_renders_in_headless_chromium(compared, tmp_path, chromium):
    """Open report.html in a real browser and check the screenshot is a page, not blank."""
    import subprocess

    from PIL import Image

    out, _ = compared
    shot = tmp_path / "report.png"
    cmd = [chromium, "--headless", "--no-sandbox", "--disable-gpu", "--disable-quic",
           "--no-first-run", "--disable-background-networking", "--disable-component-update",
           "--disable-sync", f"--user-data-dir={tmp_path / 'profile'}", f"--screenshot={shot}",
           "--window-size=1280,2000", (out / "report.html").resolve().as_uri()]
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert shot.is_file(), proc.stderr[-2000:]
    img = np.asarray(Image.open(shot).convert("L"), dtype=np.float64)
    assert img.shape == (2000, 1280)
    # a page with text, tables and figures: many non-white pixels, real contrast, and
    # content in the lower half too (the first figures, not just a title)
    assert (img < 200).mean() > 0.05
    assert img.std() > 30
    assert (img[1000:] < 200).mean() > 0.02


TINY_MLA = """
name = "tiny_mla"
[design]
type = "lenslet_array"
cells = "round"
rows = 2
cols = 2
pitch_x = 0.2
pitch_y = 0.2
aperture_radius = 0.08
sag = 0.0005
concave = true
[tool]
nose_radius = 0.5
[process]
kind = "sts"
spindle_rpm = 50
feed_mm_per_min = 1
workpiece_radius = 0.5
compensation = "z"
points_per_rev = 720
[simulation]
region = [-0.2, -0.2, 0.2, 0.2]
pixel = 0.002
seed = 1
[render.interferometer]
pixel = 0.004
field_of_view = [-0.1, -0.1, 0.1, 0.1]
[render.diffuse]
resolution = 32
spp = 2
"""


@pytest.mark.mitsuba
@pytest.mark.slow
def test_compare_lenslet_array_table(tmp_path):
    """A 2 x 2 lenslet array: metrics.json carries the ``lenslets`` list of
    docs/formats.md, and the report shows it."""
    from render_inspect.pipeline import run_compare

    p = tmp_path / "mla.toml"
    p.write_text(TINY_MLA)
    m = run_compare(load_scene(p), tmp_path / "out")
    lens = m["lenslets"]
    assert sorted((e["row"], e["col"]) for e in lens) == [(0, 0), (0, 1), (1, 0), (1, 1)]
    for e in lens:
        for k in ("row", "col", "x_mm", "y_mm", "dx_um", "dy_um", "Sa_um", "Sq_um", "PV_um"):
            assert k in e
        assert abs(e["x_mm"]) == pytest.approx(0.1, abs=1e-3)
        assert abs(e["dx_um"]) < 1.0 and abs(e["dy_um"]) < 1.0
        assert e["PV_um"] < 0.5  # feed scallops (~100 nm) dominate the form error
    assert len(m["uncompensated"]["lenslets"]) == 4
    html = (tmp_path / "out" / "report.html").read_text()
    assert ">Lenslets<" in html


def test_parse_vary():
    from render_inspect.pipeline import parse_vary

    assert parse_vary("process.compensation=z,none") == ("process.compensation", ("z", "none"))
    assert parse_vary("tool.nose_radius=0.5, 0.25") == ("tool.nose_radius", (0.5, 0.25))
    assert parse_vary("simulation.region=[0,0,1,1],[0,0,2,2]") == \
        ("simulation.region", ([0, 0, 1, 1], [0, 0, 2, 2]))
    for bad in ("process.compensation", "process.compensation=z", "=a,b", "k=a,b,c"):
        with pytest.raises(InputError, match="--vary"):
            parse_vary(bad)


@pytest.mark.parametrize("name,a,b,key", [
    ("sts_fig16_overcut", "compensated", "uncompensated", "process.compensation"),
    ("compound_sinusoid", "compensated", "uncompensated", "process.compensation"),
    ("hts_toric_msa", "servo_lag", "ideal_servo", "machine.fts, machine.z"),
    ("sculpt_quad_mla", "vibration_on", "vibration_off", "artifacts.vibration.amplitude"),
    ("rcse_circular_array", "rcse", "conventional", "rcse.path"),
])
def test_each_process_kind_has_its_own_pair(name, a, b, key):
    """The process's variants hook picks the pair that means something, and the two scenes
    differ in that key only."""
    from render_inspect.pipeline import compare_pair, compare_variants

    scene = load_scene(name)
    pair = compare_pair(scene)
    assert (pair.a.name, pair.b.name, pair.key) == (a, b, key)
    assert pair.about
    sa, sb = compare_variants(scene)
    da, db = sa.to_dict(), sb.to_dict()
    assert da != db
    for sec in ("design", "simulation", "render"):
        assert da[sec] == db[sec]
    assert sa.simulation.seed == sb.simulation.seed


def test_vary_makes_its_own_pair_and_clears_keys():
    from render_inspect.pipeline import compare_pair, compare_variants

    scene = load_scene("sts_fig16_overcut")
    pair = compare_pair(scene, "process.compensation=normal,z")
    assert (pair.a.name, pair.b.name) == ("compensation_normal", "compensation_z")
    sa, sb = compare_variants(scene, "process.compensation=normal,z")
    assert sa.process.compensation == "normal" and sb.process.compensation == "z"
    # the HTS ideal servo: the machine's slow slide and FTS without loop, latency and noise
    hts = compare_variants(load_scene("hts_toric_msa"))[1]
    for ax in (hts.machine.fts, hts.machine.z):
        assert math.isinf(ax.bandwidth_hz) and ax.delay_s == 0 and ax.noise_nm == 0
    # the servos of an ideal machine (the retired [artifacts.servo] keys become them): the
    # same pair, the FTS and slide ideal on the right
    with pytest.warns(UserWarning, match="artifacts.servo.delay_s is deprecated"):
        legacy = load_scene("hts_toric_msa", ["machine.preset='ideal'", "artifacts.servo.delay_s=0.002",
                                              "artifacts.servo.bandwidth_hz=1000.0"])
    assert legacy.machine.fts.delay_s == 0.002 and legacy.machine.fts.bandwidth_hz == 1000.0
    assert compare_pair(legacy).key == "machine.fts, machine.z"
    hts = compare_variants(legacy)[1]
    assert math.isinf(hts.machine.fts.bandwidth_hz) and hts.machine.fts.delay_s == 0


def test_common_window_sits_on_the_largest_difference():
    from render_inspect.pipeline import common_window

    d = np.zeros((201, 301))
    d[150:170, 40:60] = 5.0  # a blob at x = -0.5 + 0.01 * 50, y = -1 + 0.01 * 160
    cw = common_window(d, pixel=0.01, origin=(-1.0, -1.0), size_mm=0.4)
    x0, y0, x1, y1 = cw["window"]
    assert x1 - x0 == pytest.approx(0.4) and y1 - y0 == pytest.approx(0.4)
    assert x0 <= -0.5 <= x1 and y0 <= 0.6 <= y1
    np.testing.assert_allclose(cw["peak"], (-0.5, 0.6), atol=0.05)
    # inside the map even when the difference is at its edge
    d2 = np.zeros((201, 301))
    d2[0:5, 0:5] = 1.0
    x0, y0, x1, y1 = common_window(d2, pixel=0.01, origin=(0.0, 0.0), size_mm=0.5)["window"]
    assert x0 >= -1e-9 and y0 >= -1e-9 and x1 <= 3.0 and y1 <= 2.0
    # no difference: the centre
    x0, y0, x1, y1 = common_window(np.zeros((101, 101)), pixel=0.01, origin=(0.0, 0.0),
                                   size_mm=0.2)["window"]
    assert (x0 + x1) / 2 == pytest.approx(0.5) and (y0 + y1) / 2 == pytest.approx(0.5)


@pytest.mark.mitsuba
@pytest.mark.slow
def test_overcut_shows_in_the_waviness_map(compared):
    """Fig. 16: the S-filter (chosen from the feed) removes the scallop, and the overcut of
    the uncompensated path is what differs between the two waviness maps."""
    out, m = compared
    f = m["filters"]
    feed = 1.0 / 50
    assert f["s_filter_mm"] > feed  # above the feed: the marks are filtered out
    assert f["mark_transmission"] < 0.05
    assert f["edges"] in ("cut", "mirror") and f["reasons"]
    c, u = m["compensated"]["filtered"], m["uncompensated"]["filtered"]
    # Z compensation leaves (almost) no waviness; no compensation leaves the overcut
    assert c["Sq_nm"] < 5.0 < u["Sq_nm"]
    assert m["difference"]["filtered_Sq_nm_change"] < -5.0
    html = (out / "report.html").read_text()
    assert "S-filter" in html and ("cut on every side" in html or "mirror" in html)


@pytest.mark.mitsuba
@pytest.mark.slow
def test_exaggeration_and_scale_in_every_diffuse_image(compared):
    from PIL import Image

    out, m = compared
    for variant in ("compensated", "uncompensated"):
        for view in ("micro", "macro"):
            ex = m[variant]["diffuse"][view]["vertical_exaggeration"]
            png = Image.open(out / variant / f"diffuse_{view}.png")
            assert float(png.text["vertical_exaggeration"]) == pytest.approx(ex)
            assert float(png.text["mm_per_px"]) > 0
            assert f"{ex:g}x" in png.text["Comment"]
            _, attrs = read_exr(out / variant / f"diffuse_{view}.exr")
            assert float(attrs["vertical_exaggeration"]) == pytest.approx(ex)
            assert float(attrs["mm_per_px"]) == pytest.approx(m[variant]["diffuse"][view]["mm_per_px"])
            # the caption is written into the picture: the top-left corner is not the render
            raw = read_exr(out / variant / f"diffuse_{view}.exr")[0]["R"]
            img = np.asarray(png.convert("RGB"), dtype=float)
            assert img.shape[:2] == raw.shape
            assert img[2:12, 4:120].std() > 20  # black text on a light box
    # the macro view is the whole turned part: a disc of the workpiece radius
    assert m["windows"]["part"] == {"shape": "disc", "center": [0.0, 0.0], "radius": 1.0}
    assert m["compensated"]["diffuse"]["macro"]["iridescence"] is True


@pytest.mark.mitsuba
@pytest.mark.slow
def test_report_table_states_measured_and_both_truths_and_how_formed(compared):
    # the table of Figure 1: measured, true like with like (the truth at the camera pixels
    # both measured with the same piston and tilt removed) and true raw, each said how
    # it was formed; and whether the measured difference is resolved
    from render_inspect.report._format import fmt_quantity

    out, m = compared
    html = (out / "report.html").read_text()
    w = m["difference"]["window"]
    for label, block in (("measured by the virtual interferometer", w["measured"]),
                         ("true, like with like", w["true_same_form_removed"]),
                         ("true, raw", w["true"])):
        row = re.search(rf"<td[^>]*>{re.escape(label)}</td><td[^>]*>([^<]*)</td>", html)
        assert row, label
        assert row.group(1) == fmt_quantity(block["rms_nm"], "nm")
    assert "how the number is formed" in html and "nothing removed" in html
    assert "Is the measured difference resolved?" in html
    assert "aligned to its truth by one piston per region" not in html


@pytest.mark.mitsuba
@pytest.mark.slow
def test_compare_repeat_measures_the_difference_repeatability(tmp_path):
    # both variants measured three times with fresh camera noise: the spread of the
    # difference over the repeats is the two measurements' noise, which each
    # measurement's own estimate predicts (floor = sqrt(n_a^2 + n_b^2))
    from render_inspect.pipeline import run_compare

    small = (TINY.replace("region = [-0.2, -0.2, 0.2, 0.2]", "region = [-0.1, -0.1, 0.1, 0.1]")
             .replace("field_of_view = [-0.1, -0.1, 0.1, 0.1]",
                      "field_of_view = [-0.05, -0.05, 0.05, 0.05]"))
    p = tmp_path / "small.toml"
    p.write_text(small)
    m = run_compare(load_scene(p), tmp_path / "out", repeat=3)
    meas = m["difference"]["window"]["measured"]
    rep = meas["repeat"]
    assert rep["repeats"] == 3 and len(rep["rms_nm"]) == 3 and len(rep["seeds"]) == 3
    assert len({s for pair in rep["seeds"] for s in pair}) == 6  # six realisations
    assert rep["rms_nm"][0] == pytest.approx(meas["rms_nm"])
    assert rep["pixel_repeatability_nm"] == pytest.approx(meas["noise"]["floor_nm"], rel=0.25)
    assert rep["mean_map"]["verdict"] in ("resolved", "not resolved")
    with pytest.raises(InputError, match="--repeat must be an integer from 1 to 100"):
        run_compare(load_scene(p), tmp_path / "bad", repeat=0)
