"""``render-inspect measure`` (height from frames and settings alone, from an EXR or a
TIFF / PNG stack) and ``render-inspect characterise`` (the instrument's own numbers)."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from numpy.testing import assert_allclose
from PIL import Image

from render_inspect.cli import main
from render_inspect.instruments import (
    Camera,
    Microscope,
    artefacts,
    csi_frames,
    led,
    objective,
    psi_frames,
)
from render_inspect.io import read_exr, write_frames_exr

UM = 1e-3
NM = 1e-6


def _frames(mode="psi", *, noise=False, p=0.5 * UM, n=48):
    # a gentle, small sinusoid (well inside the pass band, linear regime) plus a piston
    h, nrm = artefacts.sinusoid((n, n), p, period=n * p / 2, amplitude=20 * NM)
    h = h + 2e-3
    src = led() if mode == "csi" else None
    mic = Microscope(objective=objective("20x"), camera=Camera(noise=noise),
                     **({"source": src} if src else {}))
    fn = psi_frames if mode == "psi" else csi_frames
    return fn(h, nrm, pixel=p, microscope=mic, origin=(0.1, -0.2)), h


def _write(path, fr, h):
    write_frames_exr(path, fr, extra_channels={"height_true": h})


@pytest.mark.parametrize("mode,alg", [("psi", "auto"), ("psi", "hariharan"), ("csi", "envelope"),
                                      ("csi", "envelope+phase")])
@pytest.mark.slow
def test_measure_exr_writes_height_and_metrics(tmp_path, mode, alg, capsys):
    fr, h = _frames(mode)
    src = tmp_path / "interferogram.exr"
    _write(src, fr, h)
    out = tmp_path / "m"
    assert main(["measure", str(src), "--out", str(out), "--algorithm", alg]) == 0
    ch, attrs = read_exr(out / "height.exr")
    assert {"height", "valid", "modulation"} <= set(ch)
    assert attrs["pixel_size_mm"] == fr.pixel and attrs["units"] == "mm"
    assert attrs["origin_mm"] == [0.1, -0.2]
    assert attrs["effective_wavelength_nm"] == pytest.approx(fr.effective_wavelength_nm)
    assert attrs["instrument"]["microscope"]["objective"]["name"] == "20x"
    ok = ch["valid"] > 0.5
    assert ok.mean() > 0.95 and np.isnan(ch["height"][~ok]).all()
    # the measured map is the surface as the objective transfers it (the sinusoid at the
    # instrument transfer function), up to a constant: no truth was used to place it
    mic = Microscope(objective=objective("20x"), **({"source": led()} if mode == "csi" else {}))
    period = h.shape[1] * fr.pixel / 2
    seen = 2e-3 + (h - 2e-3) * float(mic.itf(1 / period))
    d = ch["height"][ok] - seen[ok]
    if alg == "envelope":
        # the coherence envelope alone over-reads small structures (it is what makes
        # batwings at steps): the sinusoid comes back larger, not smaller
        assert np.std(ch["height"][ok]) > np.std(seen[ok])
        tol = 10.0
    else:
        tol = 0.5 if mode == "psi" else 1.0
    assert_allclose(d - np.median(d), 0.0, atol=tol * NM)
    if mode == "csi":  # CSI is absolute in the scanner's frame
        assert abs(np.median(d)) < 10 * NM
    m = json.loads((out / "metrics.json").read_text())
    assert m["measure"]["mode"] == mode and m["measure"]["ignored_channels"] == ["height_true"]
    sq = m["measure"]["height"]["Sq_nm"]
    expect = 20 / math.sqrt(2) * float(mic.itf(1 / period))
    assert sq > expect if alg == "envelope" else sq == pytest.approx(expect, rel=0.05)
    assert (out / "height.png").is_file()
    # a one-screen summary: the headline numbers and where the files are
    text = capsys.readouterr().out
    assert f"render-inspect measure: {src.name}" in text
    assert "measured pixels" in text and "fringes above the noise" in text
    from render_inspect.report import fmt_quantity

    assert f"Sq {fmt_quantity(sq, 'nm')}" in text
    assert str(out.resolve()) in text.replace("\n", "")


@pytest.mark.slow
def test_measure_tiff_stack_and_png_folder(tmp_path):
    fr, h = _frames("psi", noise=True)
    adu = np.rint(fr.frames * 4095).astype(np.uint16)
    settings = {"mode": "psi", "pixel_size_um": fr.pixel / UM, "wavelength_nm": 550,
                "effective_wavelength_nm": fr.effective_wavelength_nm,
                "phase_steps_rad": fr.phase_steps.tolist(), "full_scale": 4095,
                "origin_mm": [0.1, -0.2]}
    tif = tmp_path / "stack.tif"
    pages = [Image.fromarray(a[::-1]) for a in adu]  # image row 0 = top = largest y
    pages[0].save(tif, save_all=True, append_images=pages[1:])
    (tmp_path / "stack.json").write_text(json.dumps(settings))
    out = tmp_path / "m_tif"
    assert main(["measure", str(tif), "--out", str(out)]) == 0
    ch, _attrs = read_exr(out / "height.exr")
    ok = ch["valid"] > 0.5
    d = ch["height"][ok] - h[ok]
    assert ok.mean() > 0.95 and np.std(d) < 3 * NM  # transfer function and camera noise
    # an 8-bit PNG folder with settings.json; steps as one step_rad
    folder = tmp_path / "pngs"
    folder.mkdir()
    for k, a in enumerate(np.rint(fr.frames * 255).astype(np.uint8)):
        Image.fromarray(a[::-1]).save(folder / f"frame_{k:02d}.png")
    s8 = dict(settings, full_scale=255)
    s8.pop("phase_steps_rad")
    s8["step_rad"] = math.pi / 2
    (folder / "settings.json").write_text(json.dumps(s8))
    out2 = tmp_path / "m_png"
    assert main(["measure", str(folder), "--out", str(out2)]) == 0
    ch2, _ = read_exr(out2 / "height.exr")
    ok2 = ch2["valid"] > 0.5
    d2 = ch2["height"][ok2] - h[ok2]
    assert ok2.mean() > 0.95 and np.std(d2) < 6 * NM  # 8 bits: coarser
    assert_allclose(ch2["height"][ok2], ch["height"][ok2], atol=5 * NM)


def test_measure_bad_input_is_one_line(tmp_path, capsys):
    fr, h = _frames("psi")
    src = tmp_path / "f.exr"
    _write(src, fr, h)
    assert main(["measure", str(src), "--out", str(tmp_path / "o"), "--algorithm", "envelope"]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "algorithm for PSI frames" in err[0]
    tif = tmp_path / "s.tif"
    Image.fromarray(np.zeros((4, 4), np.uint8)).save(tif)
    assert main(["measure", str(tif), "--out", str(tmp_path / "o")]) == 1
    assert "settings file" in capsys.readouterr().err
    (tmp_path / "s.json").write_text(json.dumps({"mode": "psi", "wavelength_nm": 550}))
    assert main(["measure", str(tif), "--out", str(tmp_path / "o")]) == 1
    assert "pixel_size_mm" in capsys.readouterr().err
    assert not (tmp_path / "o").exists()  # nothing half-written


@pytest.mark.slow
def test_characterise_reports_transfer_step_slope_and_noise(tmp_path):
    out = tmp_path / "c"
    assert main(["characterise", "--objective", "20x", "--out", str(out), "--quick"]) == 0
    m = json.loads((out / "metrics.json").read_text())["characterise"]
    assert m["objective"]["numerical_aperture"] == 0.4
    itf = m["itf"]
    assert itf["cutoff_period_um"] == pytest.approx(0.55 / 0.8, rel=1e-6)
    for row in itf["table"]:  # measured through the optics vs the model's linear theory
        assert row["itf_optics"] == pytest.approx(row["itf_model"], abs=0.02)
        if row["frequency_per_mm"] > itf["cutoff_per_mm"]:
            assert row["itf_optics"] < 0.01
            # nothing beyond the cut-off comes back at the camera pixel either: no false
            # grating folds into the pupil
            back = row["itf_instrument"] if row["itf_instrument"] is not None \
                else row["aliased_instrument"]
            assert back < 0.02
        if row["frequency_per_mm"] > itf["camera_nyquist_per_mm"]:  # no transfer value there
            assert row["itf_instrument"] is None and row["aliased_instrument"] is not None
    bw = {r["step_nm"]: r for r in m["step"]["csi"]["table"]}
    for row in bw.values():
        # a step is symmetric under a half-turn about its edge: the error is odd about it,
        # the two lobes equal and opposite (which one is "larger" is a rounding error, so
        # neither the reported height nor its width may depend on it)
        lo, hi = row["batwing_low_side_nm"], row["batwing_high_side_nm"]
        assert lo == pytest.approx(-hi, rel=0.01, abs=0.01)
        assert row["batwing_pv_nm"] == pytest.approx(abs(lo) + abs(hi), rel=1e-9)
        assert row["batwing_height_nm"] == max(abs(lo), abs(hi)) >= 0
        assert row["batwing_width_um"] == pytest.approx(
            0.5 * (row["batwing_low_side_width_um"] + row["batwing_high_side_width_um"]))
    # below the coherence length (3 um of height for 600/120 nm) a batwing of tens of nm,
    # smaller than the step; far above it none
    assert 10 < bw[100.0]["batwing_height_nm"] < 100
    assert bw[100.0]["batwing_pv_nm"] > 20 and bw[5000.0]["batwing_pv_nm"] < 4
    assert 0.2 < m["step"]["psi_edge_width_10_90_um"] < 1.5
    limit = math.degrees(math.asin(0.4))
    for key in ("instrument", "optics"):
        assert 0.5 * limit < m["slope"][key]["dropout_50_deg"] < limit
    assert any(r["frequency_per_mm"] > 1.5 * itf["cutoff_per_mm"] for r in itf["table"])
    assert 0.2 < m["flat"]["noise_nm"] < 1.0
    for name in ("itf.csv", "itf.png", "step.csv", "step.png", "slope.csv", "slope.png",
                 "flat_noise.png"):
        assert (out / name).is_file()
    head = (out / "itf.csv").read_text().splitlines()[0]
    assert head.startswith("frequency_per_mm,period_um,itf_optics")


@pytest.mark.parametrize("settings, words", [
    ({"mode": "psi", "pixel_size_um": 1.0, "pixel_size_mm": 0.5, "wavelength_nm": 550},
     "both pixel_size_mm (0.5) and pixel_size_um (1.0): give one"),
    ({"mode": "psi", "pixel_size_um": 1.0, "wavelength_nm": 550, "wavelenght_nm": 600},
     "unknown key 'wavelenght_nm'; did you mean 'wavelength_nm'?"),
    ({"mode": "psi", "pixel_size_um": 1.0, "wavelength_nm": "550"},
     "wavelength_nm must be a number, received '550'"),
    ({"mode": "psi", "pixel_size_um": 1.0, "wavelength_nm": 550, "effective_wavelength_nm": 1e308},
     "effective_wavelength_nm must be in [200, 4000]"),
    ({"mode": "psi", "pixel_size_um": -1.0, "wavelength_nm": 550},
     "pixel_size_um must be > 0, received -1.0"),
])
def test_a_settings_file_with_a_mistake_is_refused_naming_the_key(tmp_path, settings, words):
    """A settings JSON is checked as a scene is: no key ignored, none contradicting another,
    every number a number in its range (one line naming the key the user wrote)."""
    from render_inspect.errors import InputError
    from render_inspect.io import read_frame_stack

    stack = tmp_path / "frames"
    stack.mkdir()
    for i in range(4):
        Image.fromarray(np.full((8, 8), 60 * i, dtype=np.uint8)).save(stack / f"f{i}.png")
    (stack / "settings.json").write_text(json.dumps(settings))
    with pytest.raises(InputError) as e:
        read_frame_stack(stack)
    assert words in str(e.value) and "\n" not in str(e.value), str(e.value)
