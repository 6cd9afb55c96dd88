"""What the instrument decides from its own signal, and only from it: which pixels hold
fringes (against the noise the frames show), where it focuses before phase shifting, and
how finely it samples the surface (nothing finer than the pupil passes may come back).
Each test builds frames with the forward model and checks the measurement against what
the model put in."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from render_inspect.core import HeightMap
from render_inspect.instruments import (Microscope, artefacts, autofocus, csi_frames, led,
                                        objective, psi_frames, recommended_subsamples)
from render_inspect.io import read_exr, write_exr
from render_inspect.metrology import (level_map, measure_frames, measured_difference,
                                      psi_noise)
from render_inspect.scene import InterferometerConfig

MIC = Microscope(objective=objective("20x"))
PIXEL = MIC.objective.pixel


def _no_channel(fr):
    """The same frames with the simulator's light estimate gone (every pixel 'valid')."""
    return dataclasses.replace(fr, valid=np.ones(fr.shape, dtype=bool))


# ------------------------------------------------------------------------- validity
def test_psi_noise_estimate_from_the_frames():
    # exact fringes plus white noise of a known level (brighter pixels noisier, as shot
    # noise makes them): the residual of the fringe fit gives it back
    rng = np.random.default_rng(5)
    ny, nx = 64, 96
    steps = np.arange(4) * math.pi / 2
    a = np.where(np.arange(nx)[None, :] < 48, 0.3, 0.7) * np.ones((ny, 1))
    phi = rng.uniform(-math.pi, math.pi, (ny, nx))
    sigma = 0.004 * np.sqrt(a / 0.3)
    frames = np.stack([a + 0.2 * np.cos(phi + d) + sigma * rng.standard_normal((ny, nx))
                       for d in steps])
    sigma_b, info = psi_noise(frames, steps)
    # the 4-step modulation of noise alone is Rayleigh with scale sigma / sqrt(2)
    # (pooled over ~250 pixels a group: a few per cent; the estimate errs on the high side)
    assert float(np.median(sigma_b[:, :40])) == pytest.approx(0.004 / math.sqrt(2), rel=0.15)
    assert float(np.median(sigma_b[:, 56:])) == pytest.approx(
        0.004 * math.sqrt(0.7 / 0.3) / math.sqrt(2), rel=0.15)
    assert info["dof"] == 1


def test_psi_noise_of_dark_pixels_matches_the_camera():
    # no surface in half the field: there the camera sees the reference beam and its
    # temporal noise (shot, read, quantisation); the fixed patterns are the fit's a and b
    s = 3
    h, n = artefacts.flat((32, 64), PIXEL, s)
    h[:, 32 * s:] = np.nan
    fr = psi_frames(h, n, pixel=PIXEL, subsamples=s, microscope=MIC, seed=2)
    sigma_b, _ = psi_noise(fr.frames, fr.phase_steps)
    cam = MIC.camera
    dark = fr.frames[:, :, 40:60]
    e = float(np.mean(dark)) * cam.full_well_e
    q = cam.full_well_e / cam.levels
    predicted = math.sqrt(e + cam.read_noise_e ** 2 + q * q / 12) / cam.full_well_e
    assert float(np.median(sigma_b[:, 40:60])) == pytest.approx(predicted / math.sqrt(2),
                                                                rel=0.15)


def test_dark_pixels_are_not_measured_whatever_the_file_says():
    # half the field has no surface: the camera sees the reference beam and noise there
    s = 3
    h, n = artefacts.flat((48, 96), PIXEL, s)
    h[:, 48 * s:] = np.nan
    fr = psi_frames(h, n, pixel=PIXEL, subsamples=s, microscope=MIC, seed=4)
    assert fr.valid.all()  # the camera records every pixel: the file claims nothing
    m = measure_frames(fr)
    assert m.valid[:, 2:46].mean() > 0.99  # the surface
    # noise alone: false alarms only (away from the edge the field wraps around to)
    assert m.valid[:, 52:92].mean() < 1e-3
    # the same frames with a (wrong) mask in the file give the same map
    lying = dataclasses.replace(fr, valid=np.zeros(fr.shape, dtype=bool))
    np.testing.assert_array_equal(measure_frames(lying).valid, m.valid)
    # the modulation floor alone, set low, lets the noise through: the test can fail
    loose = measure_frames(fr, false_alarm=None, min_modulation=0.005)
    assert loose.valid[:, 52:92].mean() > 0.5


@pytest.mark.slow
def test_csi_sphere_noise_beyond_the_slope_limit_is_not_measured():
    # a CSI sphere whose slopes reach 1.25 asin(NA): beyond asin(NA) no light returns, the
    # envelope there is noise.  Sampled finely enough that the steep facets cannot fold
    # into the pupil (5 sub-samples at 20x).
    cm = Microscope(objective=objective("20x"), source=led(600.0, bandwidth_nm=120.0))
    n, c, s = 64, 6, 5
    alpha = math.asin(cm.na)
    r_edge = 0.5 * n * PIXEL
    radius = r_edge / math.sin(1.25 * alpha)
    h, nrm = artefacts.sphere((n + 2 * c, n + 2 * c), PIXEL, s, radius=radius)
    fr = _no_channel(csi_frames(h, nrm, pixel=PIXEL, subsamples=s, microscope=cm, seed=0,
                                crop=c))
    x = PIXEL * np.arange(n + 2 * c)
    r = np.hypot(x[None, :] - x.mean(), x[:, None] - x.mean())[c:-c, c:-c]
    slope = np.arcsin(np.clip(r / radius, 0, 1))
    beyond = (slope > alpha) & (r <= r_edge)
    gentle = slope < 0.5 * alpha
    m = measure_frames(fr, algorithm="envelope")
    assert m.valid[beyond].mean() < 0.01
    assert m.valid[gentle].mean() > 0.99
    # the modulation floor alone (0.05) sits below the CSI noise: most of it passed
    old = measure_frames(fr, algorithm="envelope", false_alarm=None)
    assert old.valid[beyond].mean() > 0.5


# ------------------------------------------------------------------------ autofocus
@pytest.mark.parametrize("make", ["flat", "sphere"])
def test_autofocus_finds_the_surface_from_the_fringes(make):
    s = 3
    if make == "flat":
        h, n = artefacts.flat((48, 48), PIXEL, s, height=0.0123)
    else:
        h, n = artefacts.sphere((48, 48), PIXEL, s, radius=0.5)
        h = h + 0.0045
    z, info = autofocus(h, n, pixel=PIXEL, subsamples=s, microscope=MIC)
    assert info["found"]
    fin = h[np.isfinite(h)]
    # in focus on the part: within the depth of focus of its heights
    depth = 1.0 / MIC.coherence_sigma()
    assert fin.min() - depth < z < fin.max() + depth
    if make == "flat":
        assert z == pytest.approx(0.0123, abs=0.05 * depth)
    # moving the part moves the focus with it (the scan follows the fringes)
    z2, _ = autofocus(h + 0.002, n, pixel=PIXEL, subsamples=s, microscope=MIC)
    assert z2 - z == pytest.approx(0.002, abs=0.05 * depth)


def test_psi_frames_record_the_focus_they_used():
    h, n = artefacts.flat((32, 32), PIXEL, height=0.0007)
    fr = psi_frames(h, n, pixel=PIXEL, microscope=MIC, seed=0)
    assert fr.settings["focus"]["method"].startswith("largest mean fringe amplitude")
    assert fr.z_ref == pytest.approx(fr.settings["focus"]["z_mm"])
    fr2 = psi_frames(h, n, pixel=PIXEL, microscope=MIC, seed=0, z_ref=0.0)
    assert fr2.settings["focus"]["method"] == "set by the user" and fr2.z_ref == 0.0


# ------------------------------------------------------------------------- sampling
def _grating_map(period, amplitude=10e-6, hp=0.05e-3, n=701):
    x = (np.arange(n) - n // 2) * hp
    xx, _ = np.meshgrid(x, x)
    z = amplitude * np.cos(2 * np.pi * xx / period)
    return HeightMap(np.zeros_like(z), z, hp, (x[0], x[0]))


def _returned_grating(ig):
    m = measure_frames(ig.recorded())
    prof = np.nanmean(np.where(m.valid, m.height, np.nan), axis=0)
    prof = prof[np.isfinite(prof)] - np.nanmean(prof)
    return float(np.sqrt(np.mean(prof ** 2))) * 1e6  # nm rms


@pytest.mark.mitsuba
def test_a_grating_finer_than_the_pupil_passes_comes_back_as_nothing():
    # 10 nm of 0.3 um period: its first order leaves the NA 0.4 pupil (cut-off 0.69 um)
    from render_inspect.instruments import render_interferogram

    hm = _grating_map(0.3e-3)
    fov = (-0.011, -0.011, 0.011, 0.011)
    auto = render_interferogram(hm, InterferometerConfig(field_of_view=fov, noise=False), seed=1)
    samp = auto.settings["model"]["surface_sampling"]
    assert samp["chosen_from"] == "the surface's content" and auto.subsamples > 3
    assert samp["aliased_rms_nm"] <= samp["tolerance_nm"]
    assert _returned_grating(auto) < 0.1  # nm: nothing
    # three sub-samples (the pupil's own need) fold it into a false 12-14 um grating; the
    # under-sampling diagnostic says so
    three = render_interferogram(hm, InterferometerConfig(field_of_view=fov, noise=False,
                                                          subsamples=3), seed=1)
    assert _returned_grating(three) > 3.0
    assert three.settings["model"]["surface_sampling"]["aliased_rms_nm"] > 5.0


@pytest.mark.mitsuba
def test_a_grating_the_pupil_passes_is_unchanged_by_the_finer_sampling():
    from render_inspect.instruments import render_interferogram

    hm = _grating_map(10e-3, hp=0.5e-3, n=121)  # 10 um period: well inside the pupil
    fov = (-0.02, -0.02, 0.02, 0.02)
    ig = render_interferogram(hm, InterferometerConfig(field_of_view=fov, noise=False), seed=1)
    assert ig.settings["model"]["surface_sampling"]["aliased_rms_nm"] <= 0.1
    # ITF ~0.95 at 100 /mm (docs/instrument.md): 10 nm * 0.95 / sqrt(2)
    assert _returned_grating(ig) == pytest.approx(10 * 0.95 / math.sqrt(2), rel=0.08)


# ------------------------------------------------------------------------ levelling
def test_level_map_removes_plane_and_moves_regions_by_whole_orders():
    rng = np.random.default_rng(0)
    ny, nx, p = 40, 60, 1e-3
    order = 287e-6
    x = np.arange(nx)[None, :] * np.ones((ny, 1))
    z = 5e-4 + 3e-6 * x + rng.normal(0, 1e-7, (ny, nx))
    z[:, 35:38] = np.nan  # a gap: two regions, the larger on the left
    z[:, 38:] += 4 * order
    out, info = level_map(z, pixel=p, fringe_order_mm=order)
    assert info["regions"] == 2 and info["reordered"] == [{"pixels": ny * (nx - 38), "orders": 4}]
    assert np.nanstd(out) < 2e-7 and abs(np.nanmean(out)) < 1e-7
    assert info["tilt_x_urad"] == pytest.approx(3e-6 / p * 1e6, rel=1e-3)
    d, dinfo = measured_difference(z + 1e-5, z, pixel=p)
    assert np.nanmax(np.abs(d)) < 1e-12 and dinfo["piston_nm"] == pytest.approx(10.0)


@pytest.mark.mitsuba
def test_measure_gives_the_same_map_without_the_simulators_channels(tmp_path):
    from render_inspect.instruments import render_interferogram, write_interferogram_exr
    from render_inspect.pipeline import run_measure

    x = (np.arange(121) - 60) * 1e-3
    xx, yy = np.meshgrid(x, x)
    z = 2.0 - np.sqrt(4.0 - xx ** 2 - yy ** 2)  # a sphere: fringes, steep towards the edge
    ig = render_interferogram(HeightMap(z, z, 1e-3, (x[0], x[0])),
                              InterferometerConfig(pixel=0.002, field_of_view=(-0.05, -0.05,
                                                                                0.05, 0.05)),
                              seed=3)
    path = tmp_path / "interferogram.exr"
    write_interferogram_exr(path, ig, scene={"name": "t"})
    run_measure(path, tmp_path / "a")
    ch, attrs = read_exr(path)
    stripped = tmp_path / "frames_only.exr"
    write_exr(stripped, {k: v for k, v in ch.items()
                         if k not in ("valid", "height_true", "accepted_fraction")}, attrs)
    run_measure(stripped, tmp_path / "b")
    a, _ = read_exr(tmp_path / "a" / "height.exr")
    b, _ = read_exr(tmp_path / "b" / "height.exr")
    for k in a:
        np.testing.assert_array_equal(a[k], b[k])
    assert 0.5 < float(np.mean(a["valid"])) <= 1.0
