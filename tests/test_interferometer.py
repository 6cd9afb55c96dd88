"""The virtual interference microscope over Mitsuba-traced geometry: forward models with
known answers (the imaging model itself is tested on analytic surfaces in
test_instrument.py)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from render_inspect.errors import InputError, SceneError
from render_inspect.instruments import (
    Interferogram,
    acceptance_table,
    read_interferogram_exr,
    render_interferogram,
    write_interferogram_exr,
)
from render_inspect.machining import HeightMap
from render_inspect.metrology import measure_frames
from render_inspect.scene import InterferometerConfig

pytestmark = pytest.mark.mitsuba

LAMBDA_MM = 550e-6


def _plane(tilt_rad, *, n=161, pixel=0.001, along="x"):
    c = np.arange(n) * pixel
    X, Y = np.meshgrid(c, c)
    z = (X if along == "x" else Y) * math.tan(tilt_rad)
    return HeightMap(z, z.copy(), pixel, (0.0, 0.0))


def _cfg(**kw):
    base = dict(pixel=0.001, field_of_view=(0.0105, 0.0105, 0.1495, 0.1495), noise=False,
                subsamples=1, numerical_aperture=0.3, wavelength_nm=550.0, bandwidth_nm=0.0,
                margin=0)
    base.update(kw)
    return InterferometerConfig(**base)


def _phase(ig):
    """4-step retrieval for I_k = a + b cos(phi + k pi / 2)."""
    i0, i1, i2, i3 = ig.frames.astype(np.float64)
    return np.arctan2(i3 - i1, i0 - i2), np.hypot(i3 - i1, i0 - i2) / (i0 + i1 + i2 + i3) * 2


def test_tilted_plane_gives_straight_fringes_at_lambda_eff_over_2_tan_a():
    a = math.radians(0.4)
    ig = render_interferogram(_plane(a), _cfg(), surface="design")
    assert isinstance(ig, Interferogram) and ig.frames.shape[0] == 4
    assert ig.valid.all()
    na = 0.3
    lam_eff = LAMBDA_MM / ((2 / 3) * (1 - (1 - na * na) ** 1.5) / (na * na))  # the NA factor
    assert ig.effective_wavelength_nm == pytest.approx(lam_eff * 1e6, rel=1e-5)
    phi, mod = _phase(ig)
    un = np.unwrap(phi, axis=1)
    centre = slice(20, -20)  # the field is periodic for the model: keep off its borders
    slope = np.polyfit(ig.x[centre], un.mean(axis=0)[centre], 1)[0]  # rad / mm
    spacing = 2 * math.pi / abs(slope)
    assert spacing == pytest.approx(lam_eff / (2 * math.tan(a)), rel=3e-3)
    # straight: the phase does not change along y (fringes parallel to y)
    assert np.ptp((un - un[0:1])[:, centre], axis=0).max() < 1e-3
    # contrast 2 F / (1 + F): F the fraction of the illumination cone returned
    alpha, frac = acceptance_table(na, na)
    f = float(np.interp(a, alpha, frac))
    np.testing.assert_allclose(np.median(mod[:, centre]), 2 * f / (1 + f), atol=0.01)


def test_phase_step_moves_the_fringes_by_the_step_fraction():
    a = math.radians(0.3)
    ig = render_interferogram(_plane(a), _cfg(steps=5, step_rad=math.pi / 3), surface="design")
    period = ig.effective_wavelength_nm * 1e-6 / (2 * math.tan(a))
    k = 2 * math.pi / period
    x = ig.x[20:-20]
    row = ig.frames[:, 70, 20:-20].astype(np.float64)
    # least-squares fit a + b cos(kx) + c sin(kx) gives each frame's fringe position
    basis = np.stack([np.ones_like(x), np.cos(k * x), np.sin(k * x)], axis=1)
    coef = np.linalg.lstsq(basis, row.T, rcond=None)[0]
    c = coef[1] - 1j * coef[2]  # b cos(kx + p) = Re(b e^{ip} e^{ikx})
    shift = np.angle(c / c[0])  # phase of frame j relative to frame 0
    np.testing.assert_allclose(np.unwrap(shift), np.arange(5) * math.pi / 3, atol=5e-3)
    np.testing.assert_allclose(ig.phase_steps, np.arange(5) * math.pi / 3)


def test_light_returns_where_the_objective_accepts_the_slope():
    R, na, pixel = 0.1, 0.3, 0.0005
    c = (np.arange(321) - 160) * pixel  # x in [-0.08, 0.08]: slopes up to asin(0.8)
    X, Y = np.meshgrid(c, c)
    z = np.sqrt(R * R - X * X) - R  # cylinder: sin(slope) = |x| / R
    hm = HeightMap(z, z.copy(), pixel, (c[0], c[0]))
    cfg = _cfg(pixel=pixel, field_of_view=(-0.07525, -0.02025, 0.07525, 0.02025),
               numerical_aperture=na, subsamples=4)
    ig = render_interferogram(hm, cfg, surface="design")
    # the object beam is the fraction of the illumination cone the facet returns
    alpha, frac = acceptance_table(na, na)
    f = np.interp(np.arcsin(np.minimum(np.abs(ig.x) / R, 1)), alpha, frac)
    np.testing.assert_allclose(ig.accepted_fraction[10], f, atol=0.03)
    expect = f >= 0.05
    clear = np.abs(f - 0.05) > 0.02
    # the simulation's light estimate stays with its truth; the camera records every pixel
    light = ig.accepted_fraction >= 0.05
    assert ig.valid.all()
    assert (light[:, clear] == expect[None, clear]).all()
    # light fades towards the slope limit asin(NA) rather than stopping there
    slopes = np.arcsin(np.abs(ig.x[light[10]]) / R)
    assert 0.8 * math.asin(na) < slopes.max() < math.asin(na)
    # a wider aperture lets more through
    ig2 = render_interferogram(hm, cfg.model_copy(update={"numerical_aperture": 0.55}), surface="design")
    assert (ig2.accepted_fraction >= 0.05).sum() > light.sum()
    # what is measured is decided from the frames: a balanced interferometer whose object
    # beam is the fraction F of a mirror's shows the contrast 2 F / (1 + F) at most (the
    # camera pixel averaging dense fringes lowers it), so the instrument's contrast floor
    # (min_modulation 0.05) sits at F = 0.026, not at the 5 % light estimate above: a
    # facet returning 3 % of the light still shows real fringes of 5.3 % contrast.  With
    # a noise-free camera the floor alone decides, clearly on both sides of it.
    m = measure_frames(ig.recorded())
    floor = m.meta["min_modulation"]
    F = ig.accepted_fraction.astype(np.float64)
    contrast = 2 * F / (1 + F)
    dark = contrast < 0.9 * floor
    assert (~expect & clear).sum() * ig.shape[0] > dark.sum() > 0.95 * (~expect & clear).sum() * ig.shape[0]
    assert not m.valid[dark].any()  # no fringes above the floor: nothing is measured there
    assert m.valid[contrast > 1.4 * floor].all()  # fringes well above it: all measured


def test_height_true_equals_the_height_map_at_pixel_centres():
    rng = np.random.default_rng(3)
    n, q = 101, 0.001
    c = np.arange(n) * q
    X, Y = np.meshgrid(c, c)
    design = 2e-4 * np.sin(2 * np.pi * X / 0.07) * np.cos(2 * np.pi * Y / 0.05)
    machined = design + 5e-6 * rng.normal(size=design.shape)
    hm = HeightMap(design, machined, q, (0.0, 0.0))
    # camera pixel 2 q, pixel centres on height-map pixels 10, 12, ..., 88
    cfg = _cfg(pixel=2 * q, field_of_view=(0.009, 0.009, 0.089, 0.089), subsamples=2)
    ig = render_interferogram(hm, cfg)
    assert ig.shape == (40, 40)
    np.testing.assert_allclose(ig.origin, (0.010, 0.010), atol=1e-12)
    # the truth is the pixel's mean of its traced sub-samples (what the pixel
    # integrates); at the pixel centres the trace hits the height map exactly
    from render_inspect.instruments._interferometer import (interferometer_geometry,
                                                            pixel_truth, trace_heights)

    geom = interferometer_geometry(hm, cfg)
    h_sub, _, h_centre = trace_heights(hm, geom, surface="machined", subsamples=2)
    np.testing.assert_allclose(h_centre, machined[10:90:2, 10:90:2], atol=2e-9)
    np.testing.assert_allclose(ig.height_true, pixel_truth(h_sub, h_centre, s=2,
                                                           margin=geom["margin"])[0], atol=1e-12)
    igd = render_interferogram(hm, cfg, surface="design")
    # a smooth surface: the pixel mean is the centre value within the curvature terms
    # (the sub-samples 0.5 um off the centre: (0.5 um)^2 / 2 (h_xx + h_yy), and as much
    # again from the mesh's linear interpolation between vertices 1 um apart: up to
    # 1.2 nm on this 200 nm grid of 50-70 um periods)
    np.testing.assert_allclose(igd.height_true, design[10:90:2, 10:90:2], atol=1.5e-6)


def test_pixel_integrates_intensity_where_fringes_are_dense():
    a = math.radians(5.0)  # ~ 3.3 um fringe spacing, 1 um pixels
    s = 4
    ig = render_interferogram(_plane(a), _cfg(subsamples=s), surface="design")
    point = render_interferogram(_plane(a), _cfg(subsamples=s, fill_factor=1e-4), surface="design")
    _, mod = _phase(ig)
    _, mod_point = _phase(point)
    fringe = 2 * math.tan(a) / (ig.effective_wavelength_nm * 1e-6)  # per mm
    expect = abs(np.sinc(fringe * 0.001))
    assert expect < 0.9
    # the interference term falls by the pixel's box filter; the background does not
    np.testing.assert_allclose(np.median(mod[:, 20:-20]) / np.median(mod_point[:, 20:-20]),
                               expect, atol=0.01)


def test_csi_envelope_peaks_at_the_surface_height():
    a = math.radians(0.8)
    ig = render_interferogram(_plane(a), _cfg(mode="csi", wavelength_nm=600.0, bandwidth_nm=120.0,
                                              scan_step_nm=40.0), surface="design")
    assert ig.mode == "csi" and ig.scan_positions.size == ig.frames.shape[0] > 10
    f = ig.frames.astype(np.float64)
    env = np.abs(f - f.mean(axis=0))
    peak = ig.scan_positions[np.argmax(env, axis=0)]
    # the envelope peak sits at the height, within a quarter of the centre wavelength
    err = ((peak - ig.height_true) * 1e6)[:, 20:-20]  # mm -> nm
    assert np.abs(err).max() < 150.0
    assert abs(np.mean(err)) < 40.0
    # the zero-shift frame is the one nearest z_ref
    i0 = int(np.argmin(np.abs(ig.scan_positions - ig.z_ref)))
    np.testing.assert_array_equal(ig.intensity, ig.frames[i0])


def test_render_is_repeatable_and_noise_uses_the_seed():
    hm = _plane(math.radians(0.2), n=61)
    cfg = _cfg(noise=True, field_of_view=(0.0105, 0.0105, 0.0495, 0.0495), subsamples=2)
    a = render_interferogram(hm, cfg, seed=5)
    b = render_interferogram(hm, cfg, seed=5)
    c = render_interferogram(hm, cfg, seed=6)
    np.testing.assert_array_equal(a.frames, b.frames)
    np.testing.assert_array_equal(a.height_true, b.height_true)
    assert not np.array_equal(a.frames, c.frames)
    assert a.seed == 5 and a.noise and a.variant in ("llvm_ad_rgb", "scalar_rgb", "cuda_ad_rgb")


def test_exr_round_trip_has_the_contract_header(tmp_path):
    hm = _plane(math.radians(0.2), n=41)
    ig = render_interferogram(hm, _cfg(field_of_view=(0.0105, 0.0105, 0.0295, 0.0295)))
    p = write_interferogram_exr(tmp_path / "interferogram.exr", ig, scene={"name": "t"})
    from render_inspect.io import read_exr

    ch, attrs = read_exr(p)
    for name in ("intensity", "frame_000", "frame_003", "valid", "height_true"):
        assert name in ch
    for key in ("pixel_size_mm", "origin_mm", "wavelength_nm", "numerical_aperture", "mode",
                "mitsuba_variant", "phase_steps_rad", "seed", "effective_wavelength_nm",
                "instrument"):
        assert key in attrs
    assert attrs["instrument"]["microscope"]["objective"]["numerical_aperture"] == 0.3
    assert attrs["mitsuba_variant"] == ig.variant and attrs["mode"] == "psi"
    back = read_interferogram_exr(p)
    np.testing.assert_array_equal(back.frames, ig.frames)
    np.testing.assert_array_equal(back.valid, ig.valid)
    np.testing.assert_allclose(back.height_true, ig.height_true, rtol=1e-7)
    assert back.pixel == ig.pixel and back.origin == pytest.approx(ig.origin)
    assert back.effective_wavelength_nm == pytest.approx(ig.effective_wavelength_nm)
    assert back.settings == ig.settings


def test_objective_presets_and_bad_input():
    hm = _plane(0.0, n=41)
    with pytest.raises(InputError, match="field_of_view"):
        render_interferogram(hm, _cfg(field_of_view=(0.0, 0.0, 1.0, 1.0)))
    with pytest.raises(InputError, match="pixel"):
        render_interferogram(hm, _cfg(pixel=0.05, field_of_view=None))
    with pytest.raises(InputError, match="surface"):
        render_interferogram(hm, _cfg(field_of_view=None), surface="ideal")
    with pytest.raises(InputError, match="seed"):
        render_interferogram(hm, _cfg(field_of_view=None), seed=-1)
    # the 50x preset: NA 0.55, its pixel (0.36 mm / 1024), field clipped to the map
    ig = render_interferogram(hm, InterferometerConfig(objective="50x", noise=False, subsamples=1,
                                                       margin=0))
    assert ig.numerical_aperture == 0.55 and ig.pixel == pytest.approx(0.36 / 1024)
    assert ig.shape == (113, 113)  # 0.040 mm (centre span) / (0.36 mm / 1024)
    from render_inspect.scene import scene_from_dict

    base = {"design": {"type": "plane"}}
    with pytest.raises(SceneError, match="render.interferometer.subsamples"):
        scene_from_dict(base).with_overrides(["render.interferometer.subsamples=0"])
    with pytest.raises(SceneError, match="render.interferometer.objective"):
        scene_from_dict(base).with_overrides(["render.interferometer.objective='7x'"])
    with pytest.raises(SceneError, match="illumination_na"):
        scene_from_dict(base).with_overrides(["render.interferometer.illumination_na=0.5"])
