"""``toolpath``, ``characterise`` and ``render`` end with a one-screen summary of their
headline numbers, like ``simulate``, ``measure`` and ``analyze``."""

import subprocess
import sys

import pytest

from render_inspect.pipeline._summaries import characterise_summary, render_summary, toolpath_summary


def test_toolpath_rows():
    rows = dict(toolpath_summary({
        "toolpath": {"points": 1800001, "revolutions": 500, "feed_per_rev_mm": 0.01,
                     "duration_s": 600.0, "chordal_error_max_nm": 0.12, "gouge_max_nm": 0.0,
                     "limits_exceeded": []},
        "accessibility": {"ok": True}}))
    assert rows["points"] == "1,800,001" and rows["feed per revolution"] == "10 um"
    assert rows["cutting time"] == "10.0 min" and rows["machine limits exceeded"] == "none"
    assert rows["tool reaches the whole region"] == "yes"


def test_characterise_rows():
    rows = dict(characterise_summary({"characterise": {
        "objective": {"name": "20x"}, "mode": "psi", "effective_wavelength_nm": 573.6,
        "itf": {"cutoff_per_mm": 1455.0, "cutoff_period_um": 0.6875, "half_transfer_per_mm": 617.0},
        "flat": {"noise_nm": 0.37, "flatness_Sq_nm": 0.369},
        "slope": {"instrument": {"slope_limit_deg": 23.6, "dropout_50_deg": 16.6}}}}))
    assert rows["objective"] == "20x" and rows["noise"] == "0.37 nm"
    assert rows["slope limit"] == "23.6 deg" and "period 0.6875 um" in rows["transfer cut-off"]


def test_render_rows():
    rows = dict(render_summary({"render": {
        "surface": "machined", "mitsuba_variant": "llvm_ad_rgb", "kind": "all", "seed": 0,
        "interferometer": {"mode": "psi", "wavelength_nm": 550.0},
        "diffuse_macro": {"view": "macro", "resolution": [512, 384], "spp": 64},
        "timing_s": {"interferometer": 2.5, "diffuse_macro": 4.0}}}))
    assert rows["surface"] == "machined"
    assert rows["interferometer"] == "psi, 550.0 nm, 2.5 s"
    assert rows["diffuse macro"] == "macro, 512 x 384 px, 64 spp, 4.0 s"


@pytest.mark.slow
def test_toolpath_command_prints_its_summary(tmp_path, tiny_scene):
    r = subprocess.run([sys.executable, "-m", "render_inspect.cli", "toolpath", str(tiny_scene),
                        "--out", str(tmp_path / "tp")], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    lines = r.stdout.strip().splitlines()
    assert 3 <= len(lines) <= 20
    assert "render-inspect toolpath" in lines[0] and "points" in r.stdout
    assert f"output: {(tmp_path / 'tp').resolve()}" in r.stdout
