"""``analyze`` and ``compare --measured`` with profiles: the files they write, the periods
they report, the line they compare along, and the report page in a real browser."""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

# imported at collection, not inside a test: their first import starts a process (uname,
# fc-list), which the quick tier does not allow in a test
import matplotlib.pyplot  # noqa: F401
import numpy as np
import pytest
import SurfaceTopography.IO  # noqa: F401
import surfalize  # noqa: F401
from conftest import real_file

from render_inspect.core.errors import InputError
from render_inspect.io import read_profile
from render_inspect.metrology import evaluate_profile
from render_inspect.pipeline._analyze import run_analyze

SCENES = Path(__file__).resolve().parents[1] / "scenes"


def _real(*parts) -> Path:
    return real_file(*parts)


def test_analyze_a_real_slice(tmp_path):
    src = _real("turned", "1021-WLI-2D.csv")
    out = tmp_path / "a"
    m = run_analyze(src, out, units="um")
    assert (out / "profile.png").stat().st_size > 10_000
    disk = json.loads((out / "metrics.json").read_text())
    assert disk["kind"] == "profile" and disk["input"]["units_from"] == "--units"
    assert disk["n_points"] == 1143 and disk["n_measured"] == 999
    assert set(disk["profile"]) >= {"Ra_nm", "Rq_nm", "Rp_nm", "Rv_nm", "Rz_nm", "Rt_nm", "Rsk",
                                    "Rku", "RSm_mm", "Rdq", "Rmr"}
    p = read_profile(src, units="um")
    ref = evaluate_profile(p.x, p.z, spacing=p.spacing)
    assert m["profile"]["Ra_nm"] == pytest.approx(ref["parameters"]["Ra"] * 1e6, rel=1e-12)
    assert disk["filter"]["chosen_by"] == "ISO 21920-3 from RSm"
    ta = disk["periods"]["through_axis"]
    assert ta["centre_mm"] == pytest.approx(0.536, abs=0.01)
    assert ta["left"]["period_mm"] == pytest.approx(0.0396, rel=0.05)
    assert disk["outliers"]["count"] < 0.01 * disk["n_measured"]


def test_analyze_a_slice_without_units_is_refused(tmp_path):
    src = _real("turned", "1023-WLI-2D.csv")
    out = tmp_path / "a"
    with pytest.raises(InputError, match="does not state its units; say which with --units"):
        run_analyze(src, out)
    assert not out.exists()
    with pytest.raises(InputError, match="--form for a profile"):
        run_analyze(src, out, units="um", form="sphere")


def test_analyze_a_dektak_profile(tmp_path):
    m = run_analyze(_real("more", "st_opdx-3.opdx"), tmp_path / "d")
    assert m["n_points"] == 3001 and m["input"]["units_in_file"]["height"] == "um"
    assert m["filter"]["lambda_c_mm"] == 0.008  # the 50 um trace holds no longer cut-off
    assert any("too short" in w for w in m["warnings"])


def test_analyze_a_map_reports_its_feed_period(tmp_path):
    """Concentric cusps (a turned map, 25 um feed, 0.2 mm tool) saved as .npy: analyze
    reports 25 um as the dominant period, with harmonics."""
    px = 1e-3
    yy, xx = np.mgrid[0:256, 0:256] * px
    r = np.hypot(xx + 0.3, yy - 0.1)
    ph = (r % 0.025) - 0.0125
    z = -(0.2 - np.sqrt(0.04 - ph * ph))
    np.save(tmp_path / "turned.npy", z)
    (tmp_path / "turned.json").write_text(json.dumps({"pixel_mm": px, "units": "mm"}))
    m = run_analyze(tmp_path / "turned.npy", tmp_path / "a")
    dom = m["periods"]["dominant"]
    assert dom["period_mm"] == pytest.approx(0.025, rel=0.03)
    assert dom["harmonics"] and dom["harmonics"][0]["order"] == 2


def _chromium_shot(chromium, html: Path, tmp_path: Path) -> np.ndarray:
    from PIL import Image

    shot = tmp_path / "page.png"
    cmd = [chromium, "--headless", "--no-sandbox", "--disable-gpu", "--disable-quic",
           "--no-first-run", "--disable-background-networking", "--disable-component-update",
           "--disable-sync", f"--user-data-dir={tmp_path / 'profile'}", f"--screenshot={shot}",
           "--window-size=1280,2000", html.resolve().as_uri()]
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0 and shot.is_file(), proc.stderr[-2000:]
    return np.asarray(Image.open(shot).convert("L"), dtype=np.float64)


@pytest.mark.browser
@pytest.mark.slow
def test_compare_a_real_slice_with_a_shipped_scene(tmp_path, chromium, capsys):
    """``compare --measured`` with the 1016 slice (0.01 mm/rev by its program's name) and
    the shipped STS scene (0.01 mm/rev): along the default diameter through the axis, both
    show the feed as their period, the report holds the overlay and the table, and it
    renders in headless Chromium."""
    from render_inspect.cli import main as cli_main

    out = tmp_path / "c"
    assert cli_main(["compare", str(SCENES / "sts_sinusoidal_grid.toml"), "--out", str(out),
                     "--measured", str(_real("turned", "1016-WLI-2D.csv")), "--units", "um"]) == 0
    # the command's one-screen summary on stdout, ending with the report
    said = capsys.readouterr().out
    assert "Ra" in said and "simulated cut" in said and f"report: {(out / 'report.html').resolve()}" in said
    m = json.loads((out / "metrics.json").read_text())
    assert m["kind"] == "profile" and "spindle axis" in m["line_from"]
    p = m["profiles"]
    assert p["measured"]["periods"]["dominant"]["period_mm"] == pytest.approx(0.01, rel=0.05)
    for k in ("simulated_measured", "true"):
        assert p[k]["periods"]["dominant"]["period_mm"] == pytest.approx(0.01, rel=0.02)
        assert p[k]["profile"]["RSm_mm"] == pytest.approx(0.01, rel=0.05)
    # the mirror centres agree after registration (within one feed)
    c_meas = p["measured"]["periods"]["through_axis"]["centre_mm"]
    c_sim = p["simulated_measured"]["periods"]["through_axis"]["centre_mm"]
    assert abs(c_meas - c_sim) < 0.01
    page = (out / "report.html").read_text()
    for text in ("Profiles overlaid", "Parameters side by side", "Ra (nm)", "RSm (um)",
                 "simulated, through the virtual interferometer", "mirror centre"):
        assert text in page
    img = _chromium_shot(chromium, out / "report.html", tmp_path)
    assert (img < 200).mean() > 0.05 and img.std() > 30 and (img[1000:] < 200).mean() > 0.02


@pytest.mark.slow
def test_compare_recovers_a_forward_modelled_profile(tmp_path):
    """The simulated cut along a diameter, written as a text profile shifted by 7 um and
    with its units in the header, compared back along the same line: the shift is
    recovered (the feed marks repeat every 10 um along the line; the mirror centres at
    the axis tell the periods apart) and the measured and true parameters agree."""
    from render_inspect.pipeline._compare_profile import run_compare_profile
    from render_inspect.scene import load_scene

    scene = load_scene(SCENES / "sts_sinusoidal_grid.toml", [])
    line = "-0.15,0.0,0.15,0.0"
    # the truth along the line, sampled anew at 0.5 um from the simulation's own heights
    from render_inspect.metrology import line_profile
    from render_inspect.pipeline._compare_profile import _band_scene
    from render_inspect.pipeline._simulate import simulate

    band, _ = _band_scene(scene, (-0.15, 0.0), (0.15, 0.0))
    hm = simulate(band).heightmap
    s, z = line_profile(hm.machined, pixel=hm.pixel, origin=hm.origin, p0=(-0.143, 0.0),
                        p1=(0.14, 0.0), step=0.5e-3)
    text = "x (um), height (nm)\n" + "".join(f"{a * 1e3:.6f}, {b * 1e6:.6f}\n" for a, b in zip(s, z))
    src = tmp_path / "cut.csv"
    src.write_text(text)
    m = run_compare_profile(scene, tmp_path / "c2", measured=src, line=line,
                            filter_spec="0.0025,0.08")
    assert m["line_from"] == "--line"
    assert m["registration"]["shift_mm"] == pytest.approx(0.007, abs=1e-3)
    assert m["registration"]["correlation"] > 0.95
    pm, pt = m["profiles"]["measured"]["profile"], m["profiles"]["true"]["profile"]
    assert pm["Rq_nm"] == pytest.approx(pt["Rq_nm"], rel=0.1)
    assert pm["RSm_mm"] == pytest.approx(pt["RSm_mm"], rel=0.05)


@pytest.mark.parametrize("text,match", [("1,2,3", "four numbers"), ("0,0,0,0", "two different"),
                                        ("a,b,c,d", "four numbers"), ("0,0,nan,1", "four numbers")])
def test_line_option_is_checked(text, match):
    from render_inspect.pipeline._compare_profile import parse_line

    with pytest.raises(InputError, match=f"--line must .*{match}"):
        parse_line(text)


def test_compare_profile_needs_a_line_without_a_spindle_axis(tmp_path):
    """A sculptured part has no spindle axis: without --line the command stops before
    simulating, naming the option."""
    from render_inspect.pipeline._compare_profile import run_compare_profile
    from render_inspect.scene import load_scene

    src = tmp_path / "p.csv"
    src.write_text("x (um), z (nm)\n" + "".join(f"{i}, {np.sin(i / 3):.4f}\n" for i in range(200)))
    scene = load_scene(SCENES / "sculpt_quad_mla.toml", [])
    with pytest.raises(InputError, match="--line X0,Y0,X1,Y1 .* no spindle axis"):
        run_compare_profile(scene, tmp_path / "c", measured=src)
    assert not (tmp_path / "c").exists()


def test_cli_analyze_a_profile(tmp_path, capsys):
    from render_inspect.cli import main as cli_main

    src = _real("turned", "1022-WLI-2D.csv")
    out = tmp_path / "a"
    assert cli_main(["analyze", str(src), "--out", str(out), "--units", "um",
                     "--filter", "0.0025,0.08"]) == 0
    m = json.loads((out / "metrics.json").read_text())
    assert m["filter"] == {**m["filter"], "lambda_s_mm": 0.0025, "lambda_c_mm": 0.08,
                           "chosen_by": "--filter"}
    shown = capsys.readouterr().out
    assert "Ra, Rq" in shown and "through the axis" in shown


@pytest.mark.parametrize("args,match", [
    ([], "does not state its units; say which with --units um|mm|nm"),
    (["--units", "inch"], "--units must be one of um, mm, nm"),
    (["--units", "um", "--filter", "0.8,0.08"], "lambda_s (0.8 mm) must be smaller"),
    (["--units", "um", "--filter", ",2.5"], "too short for lambda_c = 2.5 mm"),
    (["--units", "um", "--x3p"], "is a profile"),
])
def test_cli_analyze_profile_bad_input_one_line(tmp_path, capsys, args, match):
    from render_inspect.cli import main as cli_main

    out = tmp_path / "bad"
    assert cli_main(["analyze", str(_real("turned", "1016-WLI-2D.csv")), "--out", str(out),
                     *args]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and match in err[0] and "Traceback" not in err[0]
    assert not out.exists()


def test_cli_compare_profile_options_need_a_profile(tmp_path, capsys):
    from render_inspect.cli import main as cli_main

    rc = cli_main(["compare", str(SCENES / "sts_sinusoidal_grid.toml"), "--out",
                   str(tmp_path / "c"), "--line", "0,0,1,0"])
    assert rc == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--line is for --measured PROFILE" in err[0]


def test_registration_is_bounded_by_the_spindle_axis_on_the_line():
    """Turned marks repeat every feed, so correlation alone can lock onto a match whole
    periods away: with the line through the spindle axis, the search stays within one
    period of where the measured mirror centre meets the axis, and finds the shift there
    (a forward-modelled pair: the same spiral's scallops, noisy, the measured trace
    starting 0.2 mm before its mirror centre)."""
    from render_inspect.pipeline._compare_profile import _register, axis_on_line, registration_period
    from render_inspect.scene import load_scene

    f, step, rc = 0.04, 0.5e-3, 0.2
    rng = np.random.default_rng(3)

    def scallops(s, centre):
        r = np.abs(s - centre)
        u = (r + 0.013) % f - f / 2  # the spiral's phase: scallops about the axis, not on it
        return u * u / (2 * rc)

    s_sim = np.arange(0, 0.8 + step / 2, step)
    axis_s = 0.4
    z_sim = scallops(s_sim, axis_s) + rng.normal(0, 2e-6, s_sim.size)
    s_meas = np.arange(0, 0.6 + step / 2, step)
    cm = 0.2 + 0.0105  # the measured mirror centre, 10.5 um off where the line put it
    z_meas = scallops(s_meas, cm) + rng.normal(0, 2e-6, s_meas.size)
    shift, corr, how, null = _register(s_meas, z_meas, s_sim, z_sim, spacing=step, period=f,
                                       axis_s=axis_s)
    assert "mirror centre" in how and "spindle axis" in how and corr > 0.9
    # (the correlation an unrelated profile of the same spectrum reaches in that search)
    assert null is not None and -1.0 <= null <= 1.0
    assert shift == pytest.approx(axis_s - cm, abs=2 * step)
    # without the axis the search is bounded by the heights' centre alone
    shift, corr, how, _ = _register(s_meas, z_meas, s_sim, z_sim, spacing=step, period=f)
    assert "spindle axis" not in how and "mirror centre" in how

    scene = load_scene(SCENES / "sts_sinusoidal_grid.toml", [])
    assert axis_on_line(scene, (-0.3, 0.0), (0.3, 0.0), tolerance=0.005) == pytest.approx(0.3)
    assert axis_on_line(scene, (-0.3, 0.01), (0.3, 0.01), tolerance=0.005) is None
    assert axis_on_line(scene, (0.1, 0.0), (0.3, 0.0), tolerance=0.005) is None
    # the measured profile's own period; the scene's planned feed where it has none (too short)
    assert registration_period(scene, z_meas, spacing=step) == pytest.approx(f, rel=0.05)
    assert registration_period(scene, np.zeros(8), spacing=step) == pytest.approx(
        scene.process.feed_mm_per_min / scene.process.spindle_rpm)


@pytest.mark.slow
def test_a_failed_virtual_measurement_is_not_registered_against(tmp_path):
    """The turned example scene on its planned spiral (39.6 um per revolution on a
    paraboloid) imaged by phase shifting, which loses fringe orders on the paraboloid's
    slopes: the virtual measurement fails.  A profile cut from the simulated cut itself,
    shifted by 7 um, is then registered against the cut as the instrument sees it (not
    against the failed measurement, whose lost orders it would align to): the shift comes
    back within 1 um, the registration beats chance, and the json and the summary say
    what it was registered against."""
    from render_inspect.metrology import line_profile
    from render_inspect.pipeline._compare_profile import _band_scene, run_compare_profile
    from render_inspect.pipeline._simulate import simulate
    from render_inspect.pipeline._summaries import profile_compare_summary
    from render_inspect.scene import load_scene

    text = (Path(__file__).resolve().parents[1] / "docs" / "examples" / "turned" / "scene.toml")
    spiral = tmp_path / "spiral.toml"
    spiral.write_text("".join(line for line in text.read_text().splitlines(keepends=True)
                              if not line.startswith("program = ")))
    scene = load_scene(spiral, [])
    assert scene.render.interferometer.mode == "psi"
    band, _ = _band_scene(scene, (-0.4, 0.0), (0.4, 0.0))
    hm = simulate(band).heightmap
    s, z = line_profile(hm.machined, pixel=hm.pixel, origin=hm.origin, p0=(-0.393, 0.0),
                        p1=(0.39, 0.0), step=0.8712e-3)
    src = tmp_path / "cut.csv"
    src.write_text("x (um), height (nm)\n"
                   + "".join(f"{a * 1e3:.6f}, {b * 1e6:.6f}\n" for a, b in zip(s, z)))
    m = run_compare_profile(scene, tmp_path / "c", measured=src, line="-0.4,0,0.4,0")
    assert m["virtual_measurement"]["status"] == "failed"
    reg = m["registration"]
    assert reg["against"] == "cut_as_seen" and "failed" in reg["against_why"]
    assert reg["shift_mm"] == pytest.approx(0.007, abs=1e-3)
    assert reg["reliable"] and reg["correlation"] > reg["null_correlation"]
    _, lines = profile_compare_summary(m)
    assert "registration against the cut as the instrument sees it" in lines[0]
    assert "against the cut as the instrument sees it" in (tmp_path / "c" / "report.html").read_text()
