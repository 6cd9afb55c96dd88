"""``fit`` on a measured profile: a known answer from the forward model recovered, the
window's checks, and bad profiles refused in one line."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tomllib
from pathlib import Path

import numpy as np
import pytest

from render_inspect.core.errors import InputError
from render_inspect.fit._profile import (ProfileSpec, make_profile_target, profile_family,
                                         predict_profile_features, profile_residual_vector)

REPO = Path(__file__).resolve().parents[1]
SCENE = REPO / "docs" / "examples" / "turned" / "scene.toml"


def _turned(feed=3.96, nose=0.2):
    """The example turned scene with a planned spiral of one feed per revolution (its
    program left out), seen in white light."""
    from render_inspect.scene import scene_from_dict

    d = tomllib.loads(SCENE.read_text())
    d["process"].pop("program", None)
    d["process"]["feed_mm_per_min"] = feed
    d["tool"]["nose_radius"] = nose
    d["render"]["interferometer"]["mode"] = "csi"
    return scene_from_dict(d, "turned (planned spiral)")


def _write_profile(path, s_mm, z_mm):
    lines = ["x (um), height (um)"]
    lines += [f"{s * 1e3:.6f}, " + ("" if not np.isfinite(z) else f"{z * 1e3:.7f}")
              for s, z in zip(s_mm, z_mm)]
    path.write_text("\n".join(lines) + "\n")


# ----------------------------------------------------------------------- features
def _cusps(n=400, spacing=0.00087, period=0.04, radius=0.2, phase=0.0):
    x = np.arange(n) * spacing + phase
    u = np.mod(x, period) - period / 2
    return u * u / (2 * radius)


def test_profile_features_are_translation_invariant_and_find_the_period():
    spec = ProfileSpec()
    z = _cusps()
    t = make_profile_target(z[20:-20], spacing=0.00087, lag=20, spec=spec)
    assert 1.0 / t.peak == pytest.approx(0.04, rel=2e-3)
    # the same cusps shifted by a third of a period: registered, the residual vanishes
    shifted = _cusps(phase=0.04 / 3)
    p = predict_profile_features(shifted, t)
    d, a, terms = profile_residual_vector(p, t)
    # (a window of 8.3 periods: the phase moves the windowed amplitudes a little)
    assert terms["harmonics"] < 0.05 and terms["params"] < 0.1
    assert terms["profile"] < 0.1
    # a 5 % coarser feed moves the frequency residual by about 5 % / sigma
    p2 = predict_profile_features(_cusps(period=0.042), t)
    d2, _, terms2 = profile_residual_vector(p2, t)
    assert abs(d2[np.argmax(np.abs(d2))]) > 10
    assert terms2["harmonics"] > 100 * terms["harmonics"]


def test_profile_family_flags_a_varying_period_and_the_axis():
    spacing = 0.00087
    x = np.arange(400) * spacing
    # the period grows 20 % along the window: a feed that varies with the radius
    period = 0.03 * (1 + 0.2 * x / x[-1])
    phase = np.cumsum(spacing / period)
    z = (np.mod(phase, 1.0) - 0.5) ** 2 * 1e-3
    fam = profile_family(z, spacing)
    assert not fam["one_family"] and "changes" in fam["reason"]
    one = profile_family(_cusps(), spacing)
    assert one["one_family"], one
    axis = profile_family(_cusps(), spacing, axis_at_mm=0.1)
    assert not axis["one_family"] and "spindle axis" in axis["reason"]


# ---------------------------------------------------------------------- refusals
def test_profile_without_units_is_refused_naming_the_option(tmp_path):
    from render_inspect.pipeline import run_fit_profile

    p = tmp_path / "slice.csv"
    p.write_text("".join(f"{i * 0.87:.3f},{0.1 * np.sin(i / 7):.5f}\n" for i in range(300)))
    with pytest.raises(InputError) as err:
        run_fit_profile(p, _turned(), ["process.feed_mm_per_min"], tmp_path / "out")
    assert "--units" in str(err.value)
    assert not (tmp_path / "out").exists()


def test_profile_window_off_the_line_or_the_profile_is_refused(tmp_path):
    from render_inspect.pipeline import run_fit_profile

    p = tmp_path / "slice.csv"
    _write_profile(p, np.arange(300) * 0.00087, 1e-4 * np.sin(np.arange(300) / 7.0))
    with pytest.raises(InputError, match="--window"):
        run_fit_profile(p, _turned(), ["process.feed_mm_per_min"], tmp_path / "o",
                        line="0.1,0,0.5,0", at=(0.3, 0.0), window_mm=0.4)
    with pytest.raises(InputError, match="off the line"):
        run_fit_profile(p, _turned(), ["process.feed_mm_per_min"], tmp_path / "o",
                        line="0.1,0,0.5,0", at="0.2,0.05", window_mm=0.1)
    with pytest.raises(InputError, match="--at register is for a measured map"):
        run_fit_profile(p, _turned(), ["process.feed_mm_per_min"], tmp_path / "o",
                        line="0.1,0,0.5,0", at="register")
    with pytest.raises(InputError, match="with a program"):
        from render_inspect.scene import load_scene

        run_fit_profile(p, load_scene(SCENE), ["process.feed_mm_per_min"], tmp_path / "o",
                        line="0.1,0,0.5,0", window_mm=0.2)


@pytest.mark.slow
def test_cli_profile_without_units_one_line(tmp_path):
    p = tmp_path / "slice.csv"
    p.write_text("".join(f"{i * 0.87:.3f},{0.1 * np.sin(i / 7):.5f}\n" for i in range(300)))
    env = dict(os.environ, PYTHONPATH=str(REPO))
    r = subprocess.run([sys.executable, "-m", "render_inspect.cli", "fit", str(p), "--scene",
                        str(SCENE), "--free", "tool.nose_radius", "--out",
                        str(tmp_path / "out")], capture_output=True, text=True, env=env,
                       timeout=300)
    assert r.returncode == 1, r.stderr
    err = [line for line in r.stderr.splitlines() if line.strip()]
    assert len(err) == 1 and "--units" in err[0] and "Traceback" not in r.stderr, r.stderr
    assert not (tmp_path / "out").exists()


# -------------------------------------------------------------------- known answer
@pytest.mark.slow
def test_fit_profile_recovers_feed_and_nose_radius(tmp_path):
    """A profile simulated with a known feed (36 um/rev) and nose radius (0.25 mm) through
    the virtual white-light interferometer (its noise on) is fitted back from the scene's
    39.6 um/rev and 0.2 mm: each within two of its standard errors."""
    from render_inspect.pipeline import run_fit_profile
    from render_inspect.pipeline._fit_profile import simulate_profile

    truth = {"process.feed_mm_per_min": 3.6, "tool.nose_radius": 0.25}
    s, z = simulate_profile(_turned(feed=3.6, nose=0.25), (0.1, 0.0), (0.5, 0.0), 0.00087,
                            seed=7)
    p = tmp_path / "simulated.csv"
    _write_profile(p, s, z)
    # a window of 0.15 mm (4 periods) holds both keys: recovered 0.01-0.13 % off, within
    # 0.7 of their standard errors (measured on the profiles of seeds 7 and 11)
    rec = run_fit_profile(p, _turned(), ["process.feed_mm_per_min,tool.nose_radius"],
                          tmp_path / "fit", line="0.1,0,0.5,0", at=(0.3, 0.0), window_mm=0.15,
                          global_points=0, max_evaluations=60, profile_points=0,
                          cache=tmp_path / "cache")
    assert rec["one_family"] and rec["model_check"]["after"]["describes"], rec["model_check"]
    for k, v in truth.items():
        par = rec["parameters"][k]
        assert par["stderr"] is not None and par["stderr"] > 0, par
        assert abs(par["value"] - v) <= 2 * par["stderr"], (k, par)
        assert abs(par["value"] / v - 1) < 0.05, (k, par)
    assert rec["feed_per_rev_mm"]["value"] == pytest.approx(0.036, rel=0.01)
    # every number of the summary's values with its unit
    feed_line = next(t for t in rec["summary"] if t.startswith("process.feed_mm_per_min = "))
    assert feed_line.count("mm/min") == 3, feed_line   # value, standard error, start
    nose_line = next(t for t in rec["summary"] if t.startswith("tool.nose_radius = "))
    assert nose_line.count(" mm") == 3, nose_line
    saved = json.loads((tmp_path / "fit" / "fit.json").read_text())
    assert saved["kind"] == "profile" and saved["status"] == rec["status"]
    assert (tmp_path / "fit" / "fit.html").is_file()


@pytest.mark.slow
def test_fit_profile_through_the_axis_gives_no_confident_number(tmp_path):
    """A window across the spindle axis holds two mirrored families of marks: the fit says
    so and prints no standard error."""
    from render_inspect.pipeline import run_fit_profile
    from render_inspect.pipeline._fit_profile import simulate_profile

    s, z = simulate_profile(_turned(feed=3.6), (-0.15, 0.0), (0.15, 0.0), 0.00087, seed=3)
    p = tmp_path / "through_axis.csv"
    _write_profile(p, s, z)
    # (what is checked is said before and after the solve, whatever it ends at: the
    # solve is given the two start candidates only)
    rec = run_fit_profile(p, _turned(), ["process.feed_mm_per_min"], tmp_path / "fit",
                          line="-0.15,0,0.15,0", window_mm=0.2, global_points=0,
                          max_evaluations=2, profile_points=0, cache=tmp_path / "cache")
    assert not rec["one_family"]
    assert "spindle axis" in rec["status_note"]
    assert rec["parameters"]["process.feed_mm_per_min"]["stderr"] is None
    assert not rec["model_check"]["after"]["describes"]
    assert any("not a measurement" in line for line in rec["summary"])


@pytest.mark.slow
def test_a_profile_the_model_cannot_describe_gives_no_confident_number(tmp_path):
    """The part measured by another instrument than the scene's: the phase-shifting
    interferometer's profile (which loses fringe orders on the marks' slopes: its marks'
    period reads 38.1 um for a 36 um/rev cut) fitted through the white-light one.  The fit
    ends at some feed (38.4 um/rev), but the verdict says the model does not describe the
    measurement, and the value is given as no measurement: no standard error, not
    confident, in fit.json, the summary and fit.html (its standard error under the model,
    0.61 um/rev, would put the true 36 um/rev four of them away)."""
    from render_inspect.pipeline import run_fit_profile
    from render_inspect.pipeline._fit_profile import simulate_profile

    psi = _turned(feed=3.6, nose=0.25)
    psi = psi.model_copy(update={"render": psi.render.model_copy(update={
        "interferometer": psi.render.interferometer.model_copy(update={"mode": "psi"})})})
    s, z = simulate_profile(psi, (0.1, 0.0), (0.5, 0.0), 0.00087, seed=7)
    p = tmp_path / "profile.csv"
    _write_profile(p, s, z)
    rec = run_fit_profile(p, _turned(), ["process.feed_mm_per_min"], tmp_path / "fit",
                          line="0.1,0,0.5,0", at=(0.3, 0.0), window_mm=0.15,
                          global_points=0, max_evaluations=30, profile_points=0,
                          cache=tmp_path / "cache")
    after = rec["model_check"]["after"]
    assert not after["describes"], after
    assert after["verdict"].startswith("this model does not describe this measurement")
    par = rec["parameters"]["process.feed_mm_per_min"]
    assert par["stderr"] is None and par["confident"] is False, par
    assert rec["feed_per_rev_mm"]["stderr"] is None
    assert rec["status_note"].startswith("not a measurement: the model does not describe")
    line = next(t for t in rec["summary"] if t.startswith("process.feed_mm_per_min = "))
    assert "not a measurement" in line and "no standard error" in line and "mm/min" in line
    saved = json.loads((tmp_path / "fit" / "fit.json").read_text())
    assert saved["parameters"]["process.feed_mm_per_min"]["stderr"] is None
    page = (tmp_path / "fit" / "fit.html").read_text()
    assert "not a measurement" in page and "does not describe" in page
