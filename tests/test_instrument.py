"""The virtual interference microscope's imaging model (render_inspect.instruments) and
measuring from its frames alone (render_inspect.metrology.measure_frames).

Every test builds a known answer with a forward model (analytic surfaces, the textbook
transfer functions, a direct Kirchhoff summation) and recovers it."""

import math

import numpy as np
import pytest
from numpy.testing import assert_allclose

from render_inspect.errors import InputError
from render_inspect.instruments import (
    OBJECTIVES,
    Camera,
    Disturbances,
    Frames,
    Microscope,
    acceptance_table,
    artefacts,
    csi_frames,
    expose,
    interference_intensity,
    led,
    monochromatic,
    normals_from_heights,
    objective,
    psi_frames,
    recommended_subsamples,
    spectrum_table,
    unit_transfer_table,
)
from render_inspect.metrology import measure_frames

UM = 1e-3  # um -> mm
NM = 1e-6  # nm -> mm


def _mic(na=0.4, *, na_ill=None, source=None, noise=False, **cam):
    return Microscope(objective=objective("20x", numerical_aperture=na), illumination_na=na_ill,
                      source=source or monochromatic(550.0), camera=Camera(noise=noise, **cam))


def _incoherent_otf(u):
    u = np.clip(np.asarray(u, dtype=float), 0, 1)
    return 2 / np.pi * (np.arccos(u) - u * np.sqrt(1 - u * u))


def _fit_sinusoid(profile, x, period):
    a = np.stack([np.cos(2 * np.pi * x / period), np.sin(2 * np.pi * x / period),
                  np.ones_like(x)], axis=1)
    c = np.linalg.lstsq(a, profile, rcond=None)[0]
    return math.hypot(c[0], c[1])


# ----------------------------------------------------------------------- transfer function
def test_unit_transfer_function_is_the_pupil_overlap():
    # filled pupil: the mass passed at Q is the overlap of two discs (the incoherent OTF
    # shape) times the Kirchhoff factor |K|^2 / (2 k_zo K) >= 1; coherent: a hard cut at NA
    u, kappa, g = unit_transfer_table(0.4, 0.4)
    mass = g.sum(axis=1)
    assert_allclose(mass[0], 1.0, atol=1e-9)
    otf = _incoherent_otf(u / 0.8)
    assert np.all(mass >= otf - 0.01)
    assert_allclose(mass, otf, atol=0.025)
    assert mass[u > 0.8 - 1e-9].max() == 0.0
    # the mean axial frequency of a flat mirror: 2 <cos theta> over the filled pupil
    na = 0.4
    mean_cos = (2 / 3) * (1 - (1 - na * na) ** 1.5) / (na * na)
    assert_allclose(np.sum(kappa * g[0]), 2 * mean_cos, rtol=2e-6)
    u, _, g = unit_transfer_table(0.4, 0.0)
    mass = g.sum(axis=1)
    co = np.sqrt(1 - u ** 2)
    kirchhoff = (u ** 2 + (1 + co) ** 2) / (2 * co * (1 + co))
    inside = u < 0.399
    assert_allclose(mass[inside], kirchhoff[inside], rtol=1e-9)


def test_effective_wavelength_is_the_na_factor():
    for na in (0.13, 0.4, 0.55):
        mic = _mic(na)
        mean_cos = (2 / 3) * (1 - (1 - na * na) ** 1.5) / (na * na)
        assert_allclose(mic.effective_wavelength_nm(), 550.0 / mean_cos, rtol=1e-5)
    # one on-axis plane wave: a mirror sends it straight back, K = 2 k
    assert_allclose(_mic(0.4, na_ill=0.0).effective_wavelength_nm(), 550.0, rtol=1e-9)


def test_model_matches_direct_kirchhoff_summation():
    # coherent on-axis illumination, one wavelength: the image is
    # X(x, z) = sum over pupil frequencies q of F(q) O_K(q) box(q) exp(i q x - i K (z - zbar))
    # with K = k + k_z(q), F = |K|^2 / (2 k_z K), O_K = DFT of exp(i K (h - zbar)): a direct
    # sum over the discrete frequencies against the binned, FFT-based model
    lam, na, n, p = 550.0, 0.4, 64, 0.1 * UM
    k = 2 * math.pi / (lam * NM)
    mic = _mic(na, na_ill=0.0)
    x = p * np.arange(n)
    span = n * p
    xx, yy = np.meshgrid(x, x)
    h = (80 * NM * np.cos(2 * np.pi * 3 * xx / span + 0.3)
         + 50 * NM * np.sin(2 * np.pi * (2 * xx + 5 * yy) / span)
         + 30 * NM * np.cos(2 * np.pi * 7 * yy / span))
    z = h.mean() + np.array([-100, 0, 120, 400]) * NM
    _, info = interference_intensity(h, normals_from_heights(h, p), pixel=p, microscope=mic,
                                     z_positions=z, kz_tolerance=0.1, return_field=True)
    q = 2 * np.pi * np.fft.fftfreq(n, d=p)
    qx, qy = np.meshgrid(q, q)
    qr = np.hypot(qx, qy)
    assert np.min(np.abs(qr - k * na)) > 0.05 * (q[1] - q[0])  # no frequency on the pupil edge
    zb = h.mean()
    direct = np.zeros((z.size, n, n), dtype=complex)
    for iy, ix in zip(*np.nonzero(qr < k * na)):
        fx, fy = qx[iy, ix], qy[iy, ix]
        kz = math.sqrt(k * k - fx * fx - fy * fy)
        kk = k + kz
        f = (fx * fx + fy * fy + kk * kk) / (2 * kz * kk)
        o = np.sum(np.exp(1j * kk * (h - zb) - 1j * (fx * xx + fy * yy)))
        box = np.sinc(fx * p / (2 * np.pi)) * np.sinc(fy * p / (2 * np.pi))
        wave = np.exp(1j * (fx * xx + fy * yy)) / n ** 2
        for j, zz in enumerate(z):
            direct[j] += f * o * box * wave * np.exp(-1j * kk * (zz - zb))
    assert_allclose(info["field"], direct, atol=2e-3 * np.abs(direct).max())


def test_axial_binning_converges():
    # the frames do not depend on the axial bin width beyond the stated tolerance
    p = 0.2 * UM
    h, nrm = artefacts.sphere((96, 96), p, radius=0.3)
    mic = _mic(0.4, source=monochromatic(550.0, bandwidth_nm=20.0))
    z = np.array([-0.2, 0.0, 0.3]) * UM
    a, ia = interference_intensity(h, nrm, pixel=p, microscope=mic, z_positions=z, kz_tolerance=0.5)
    b, ib = interference_intensity(h, nrm, pixel=p, microscope=mic, z_positions=z, kz_tolerance=0.1)
    assert ib["axial_bins"] > 2 * ia["axial_bins"]
    assert_allclose(a, b, atol=0.03 * b.max())


# ------------------------------------------------------------------------ grating transfer
def _grating_ratio(period_um, mic, *, amp_nm=10.0, p_um=0.1, field_um=20.0):
    p = p_um * UM
    nper = max(1, round(field_um / period_um))
    n = round(nper * period_um / p_um)
    period = n * p / nper  # an integer number of periods in the (periodic) field
    h, nrm = artefacts.sinusoid((8, n), p, period=period, amplitude=amp_nm * NM)
    m = measure_frames(psi_frames(h, nrm, pixel=p, microscope=mic))
    x = p * np.arange(n)
    return _fit_sinusoid(np.nanmean(m.height, axis=0), x, period) / (amp_nm * NM), period


@pytest.mark.parametrize("na", [0.4, 0.55])
def test_grating_transfer_partially_coherent(na):
    # filled illumination aperture: the transfer follows the overlap of the illumination
    # and pupil discs (incoherent-OTF shape) and is zero beyond 1/period = 2 NA / lambda
    mic = _mic(na)
    lam_c = 550.0 * NM
    fc = 2 * na / lam_c
    p = 0.1 * UM
    for period_um in (5.0, 2.0, 1.0, 0.8, 0.6, 0.45, 0.3):
        ratio, period = _grating_ratio(period_um, mic)
        f = 1 / period
        box = np.sinc(f * p)  # the camera pixel integrates intensity over its area
        if f >= fc:
            assert ratio < 0.01, (period_um, ratio)
            continue
        # the Kirchhoff obliquity factor lifts the scalar textbook curve by up to ~0.04
        assert_allclose(ratio, _incoherent_otf(f / fc) * box, atol=0.05, err_msg=str(period_um))
        assert_allclose(ratio, mic.itf(f) * box, atol=0.01, err_msg=str(period_um))


@pytest.mark.parametrize("na", [0.4, 0.55])
def test_grating_transfer_coherent(na):
    # one on-axis plane wave: everything up to NA / lambda passes, nothing beyond
    mic = _mic(na, na_ill=0.0)
    fc = na / (550.0 * NM)
    for period_um in (5.0, 2.0, 0.45 / na * 1.35, 0.55 / na * 0.85, 0.6):
        ratio, period = _grating_ratio(period_um, mic)
        f = 1 / period
        if f < 0.95 * fc:
            assert_allclose(ratio, np.sinc(f * 0.1 * UM), atol=0.06, err_msg=str(period_um))
        elif f > 1.02 * fc:
            assert ratio < 0.01, (period_um, ratio)


def test_fine_gratings_at_20x_are_lost_or_aliased_as_a_real_objective_does():
    p, s, n = OBJECTIVES["20x"].pixel, 4, 128

    def measured_spectrum(period_um, mic):
        period = n * p / round(n * p / (period_um * UM))
        h, nrm = artefacts.sinusoid((4, n), p, s, period=period, amplitude=10 * NM)
        m = measure_frames(psi_frames(h, nrm, pixel=p, subsamples=s, microscope=mic))
        prof = np.nanmean(m.height, axis=0)
        return period, np.abs(np.fft.rfft(prof - prof.mean())) * 2 / n / (10 * NM)

    # 0.4 um at NA 0.4: beyond 2 NA / lambda, nothing comes back (no false grating)
    _, spec = measured_spectrum(0.4, _mic(0.4))
    assert spec.max() < 0.005
    # 0.6 um at NA 0.55: inside the pass band, above the camera's Nyquist frequency:
    # a weak alias at the folded frequency, ITF times the pixel's box filter
    mic = _mic(0.55)
    period, spec = measured_spectrum(0.6, mic)
    f_alias = abs(1 / period - round(p / period) / p)
    j = round(f_alias * n * p)
    assert spec[j] == spec.max()
    assert_allclose(spec[j], mic.itf(1 / period) * abs(np.sinc(p / period)), atol=0.005)
    assert spec[j] < 0.05


# ------------------------------------------------------------------------------ CSI step
def _batwing(step_nm, *, na=0.4, lam=600.0, bw=120.0, p_um=0.05, n=800):
    mic = _mic(na, source=led(lam, bandwidth_nm=bw))
    p = p_um * UM
    h, nrm = artefacts.step((4, n), p, height=step_nm * NM)
    m = measure_frames(csi_frames(h, nrm, pixel=p, microscope=mic))
    err = (np.nanmean(m.height, axis=0) - h[0]) / NM
    err -= np.median(err)
    edge = n // 4  # the rising edge
    up = err[edge:edge + int(3 / p_um)]
    i = int(np.argmax(up))
    width = (i + int(np.argmax(up[i:] < up[i] / 2))) * p_um
    return float(up[i]), width, m


def test_batwing_reports_both_lobes_whatever_rounding_favours():
    # an odd error profile about a rising edge: undershoot below, overshoot above; a
    # one-ulp change that makes either lobe the larger one changes nothing reported
    from render_inspect.metrology import batwing

    x = np.arange(-60, 61) * 0.05
    lobe = 30.0 * np.exp(-((np.abs(x) - 0.8) / 0.4) ** 2)
    err = np.sign(x) * lobe
    results = []
    for tweak in (-1, 0, 1):
        e = err.copy()
        e[x > 0] = np.nextafter(e[x > 0], e[x > 0] + tweak) if tweak else e[x > 0]
        results.append(batwing(e, x, edge=0.0, side_length=3.0, exclude=0.05))
    for r in results:
        assert r.low == pytest.approx(-30.0, rel=1e-3) and r.high == pytest.approx(30.0, rel=1e-3)
        assert r.peak_to_valley == pytest.approx(60.0, rel=1e-3)
        assert r.height == pytest.approx(results[0].height, rel=1e-12)
        assert r.width == pytest.approx(results[0].width, rel=1e-12)
        assert 0.8 < r.low_width == r.high_width < 1.5
    # a falling edge swaps which terrace is upper
    f = batwing(-err, x, edge=0.0, side_length=3.0, exclude=0.05, rising=False)
    assert f.high == pytest.approx(30.0, rel=1e-3) and f.low == pytest.approx(-30.0, rel=1e-3)


def test_csi_batwing_below_coherence_length_not_above():
    h60, w60, _ = _batwing(60)
    assert h60 > 10 and w60 > 0.3  # overshoot of tens of nm over about a micrometre
    h5000, _, m = _batwing(5000)  # far beyond the coherence length (~1.5 um)
    assert abs(h5000) < 2.0
    assert m.valid.mean() > 0.95


@pytest.mark.slow
def test_batwing_trends_follow_wavelength_and_na():
    # Zhang et al. 2024: narrower at shorter wavelength, wider at lower NA
    _, w600, _ = _batwing(60, lam=600.0, bw=120.0)
    _, w450, _ = _batwing(60, lam=450.0, bw=90.0)
    _, w55, _ = _batwing(60, na=0.55)
    assert w450 < 0.85 * w600
    assert w600 > 1.1 * w55


def test_psi_step_shows_2pi_ambiguity_csi_recovers_it():
    p, n = 0.1 * UM, 400
    h, nrm = artefacts.step((8, n), p, height=350 * NM)  # > lambda / 4

    def step_of(m):
        prof = np.nanmean(m.height, axis=0)
        return (np.nanmean(prof[150:250]) - np.nanmean(np.r_[prof[:50], prof[350:]])) / NM

    psi = psi_frames(h, nrm, pixel=p, microscope=_mic(0.4))
    lam_eff = psi.effective_wavelength_nm
    assert_allclose(step_of(measure_frames(psi)), 350 - lam_eff / 2, atol=3.0)
    csi = csi_frames(h, nrm, pixel=p, microscope=_mic(0.4, source=led()))
    assert_allclose(step_of(measure_frames(csi)), 350, atol=5.0)


# ------------------------------------------------------------------ slopes, sphere, pixel
@pytest.mark.slow
def test_tilted_plane_contrast_fades_to_zero_at_asin_na():
    na, p = 0.4, 0.05 * UM
    mic = _mic(na, source=monochromatic(550.0, bandwidth_nm=10.0))
    alpha, frac = acceptance_table(na, na)
    limit = math.degrees(math.asin(na))
    mods = []
    for deg in (0, 5, 10, 15, 20, 22, limit - 0.3, limit + 0.5, 26):
        h, nrm = artefacts.tilted_plane((8, 384), p, angle=math.radians(deg))
        m = measure_frames(psi_frames(h, nrm, pixel=p, microscope=mic), min_modulation=0.0)
        mod = float(np.median(m.modulation[:, 100:284]))
        f = float(np.interp(math.radians(deg), alpha, frac))
        # contrast 2 |X| / (1 + B): the fraction of the illumination cone the tilted
        # mirror reflects into the pupil sets both
        assert_allclose(mod, 2 * f / (1 + f), atol=0.03, err_msg=str(deg))
        mods.append(mod)
    assert np.all(np.diff(mods[:-2]) < 0)
    assert mods[0] > 0.98 and mods[-3] < 0.01 and max(mods[-2:]) < 0.005


def test_newton_rings_of_a_sphere_are_shifted_by_the_na_factor():
    # fringe order n at r_n with 2 sag(r_n) = n lambda_eff: r_n = sqrt(n lambda_eff R),
    # outward of sqrt(n lambda R) by sqrt(lambda_eff / lambda)
    na, lam, radius, p, n = 0.4, 550.0, 0.5, 0.2 * UM, 400
    mic = _mic(na)
    h, nrm = artefacts.sphere((n, n), p, radius=radius)
    fr = psi_frames(h, nrm, pixel=p, microscope=mic, z_ref=0.0, steps=4)
    m = measure_frames(fr)
    # fringe order from the frames alone: the unwrapped phase / 2 pi (no wavelength used)
    order = -(m.height - fr.z_ref) / (fr.effective_wavelength_nm * NM / 2)
    x = p * np.arange(n)
    r = np.hypot(x[None, :] - x.mean(), x[:, None] - x.mean())
    mean_cos = (2 / 3) * (1 - (1 - na * na) ** 1.5) / (na * na)
    lam_eff = lam / mean_cos * NM
    for k in (1, 2, 3, 4, 5):
        ring = np.abs(order - k) < 0.02
        rn = float(np.median(r[ring]))
        # (the effective wavelength grows slightly with the local slope: 0.2 % at 2 deg)
        assert_allclose(rn, math.sqrt(k * lam_eff * radius), rtol=4e-3)
        assert rn > 1.015 * math.sqrt(k * lam * NM * radius)


def test_pixel_integrates_intensity_not_field():
    # a 10 deg tilt, 0.5 um pixels: the camera averages intensity over its pixel, so the
    # interference term falls by the box filter |sinc(f w)| at the fringe frequency while
    # the background does not; a coherent sum of the field would also lower the background
    deg, p, s, n = 10.0, 0.5 * UM, 8, 96

    def centre_modulation(fill):
        mic = _mic(0.4, source=monochromatic(550.0, bandwidth_nm=10.0), fill_factor=fill)
        h, nrm = artefacts.tilted_plane((4, n), p, s, angle=math.radians(deg))
        m = measure_frames(psi_frames(h, nrm, pixel=p, subsamples=s, microscope=mic),
                           min_modulation=0.0)
        return float(np.median(m.modulation[:, n // 2 - 4:n // 2 + 4])), mic

    full, mic = centre_modulation(1.0)
    point, _ = centre_modulation(1e-4)
    fringe = 2 * math.tan(math.radians(deg)) / (mic.effective_wavelength_nm() * NM)
    alpha, frac = acceptance_table(0.4, 0.4)
    f_opt = float(np.interp(math.radians(deg), alpha, frac))
    assert_allclose(point, 2 * f_opt / (1 + f_opt), atol=0.01)
    assert_allclose(full / point, abs(np.sinc(fringe * p)), atol=0.01)


# -------------------------------------------------------------------- camera and noise
def test_noise_on_a_flat_matches_the_camera_inputs():
    mic = _mic(0.4, noise=True)
    h, nrm = artefacts.flat((64, 64), 0.5 * UM)
    heights = []
    for seed in range(8):
        fr = psi_frames(h, nrm, pixel=0.5 * UM, microscope=mic, steps=4, seed=seed)
        heights.append(measure_frames(fr).height)
    heights = np.array(heights)
    sigma = math.sqrt(float(np.mean(np.var(heights, axis=0, ddof=1))))
    cam = mic.camera
    exp = fr.settings["camera_exposure"]
    # balanced beams on a mirror: I = 2 + 2 cos, so a = b = 2 g electrons; 4-step:
    # var(phi) = sigma_I^2 / (2 b^2), sigma_I^2 = shot (a) + read^2 + quantisation
    g = exp["electrons_per_intensity"]
    var_i = 2 * g + cam.read_noise_e ** 2 + exp["electrons_per_adu"] ** 2 / 12
    predicted = math.sqrt(var_i / (2 * (2 * g) ** 2)) / (4 * math.pi / (fr.effective_wavelength_nm * NM))
    assert_allclose(sigma, predicted, rtol=0.1)
    # spatially white: neighbouring pixels uncorrelated
    d = heights[0] - np.nanmean(heights[0])
    assert abs(np.mean(d[:, 1:] * d[:, :-1]) / np.mean(d * d)) < 0.08
    assert abs(np.mean(d[1:] * d[:-1]) / np.mean(d * d)) < 0.08


def test_seeds_repeat_and_fixed_pattern_belongs_to_the_camera():
    h, nrm = artefacts.flat((16, 16), 0.5 * UM)
    mic = _mic(0.4, noise=True, prnu=0.02, dsnu_e=20.0)
    a = psi_frames(h, nrm, pixel=0.5 * UM, microscope=mic, seed=3).frames
    b = psi_frames(h, nrm, pixel=0.5 * UM, microscope=mic, seed=3).frames
    c = psi_frames(h, nrm, pixel=0.5 * UM, microscope=mic, seed=4).frames
    assert np.array_equal(a, b) and not np.array_equal(a, c)
    # the fixed pattern is the same in every measurement: it survives averaging
    many = np.mean([psi_frames(h, nrm, pixel=0.5 * UM, microscope=mic, seed=s).frames[0]
                    for s in range(12)], axis=0)
    clean = psi_frames(h, nrm, pixel=0.5 * UM, microscope=_mic(0.4, noise=False), seed=0).frames[0]
    assert np.std(many / clean) > 0.015


def test_exposure_avoids_saturation_by_default_and_saturated_pixels_are_dropped():
    h, nrm = artefacts.flat((16, 16), 0.5 * UM)
    fr = psi_frames(h, nrm, pixel=0.5 * UM, microscope=_mic(0.4, noise=True))
    assert fr.frames.max() < 1.0 and fr.settings["camera_exposure"]["saturated_fraction"] == 0
    over = psi_frames(h, nrm, pixel=0.5 * UM, microscope=_mic(0.4, noise=True, exposure=1.3))
    assert over.settings["camera_exposure"]["saturated_fraction"] > 0.5
    m = measure_frames(over)
    assert m.meta["saturated_pixels"] > 0 and not m.valid.all()


def test_expose_without_noise_is_the_scaled_model():
    inten = np.linspace(0.5, 2.0, 24, dtype=np.float32).reshape(2, 3, 4)
    frames, info = expose(inten, Camera(noise=False, exposure=0.5))
    assert_allclose(frames, inten / 2.0 * 0.5, rtol=1e-6)
    assert info["saturated_fraction"] == 0.0


# -------------------------------------------------------------------------- disturbances
def test_phase_step_error_biases_4step_more_than_hariharan():
    p, n = 0.5 * UM, 64
    # a periodic surface that spans all phases
    h, nrm = artefacts.sinusoid((8, n), p, period=n * p, amplitude=200 * NM)

    def measured(steps, alg, eps):
        fr = psi_frames(h, nrm, pixel=p, microscope=_mic(0.4), steps=steps,
                        disturbances=Disturbances(step_error=eps))
        return measure_frames(fr, algorithm=alg).height

    def rms_nm(d):
        return float(np.sqrt(np.nanmean((d - np.nanmean(d)) ** 2)) / NM)

    # what the step error adds to each algorithm's result
    e4 = rms_nm(measured(4, "4step", 0.05) - measured(4, "4step", 0.0))
    e5 = rms_nm(measured(5, "5step", 0.05) - measured(5, "5step", 0.0))
    # 4-step: phase error about (pi eps / 4) (1 - cos 2 phi), 1.8 nm peak for eps = 5 %
    assert e4 > 0.8
    assert e5 < 0.1 * e4  # Schwider-Hariharan: insensitive to first order


def test_vibration_and_reference_figure():
    p = 0.5 * UM
    h, nrm = artefacts.flat((32, 32), p)
    base = measure_frames(psi_frames(h, nrm, pixel=p, microscope=_mic(0.4)))
    vib = Disturbances(vibration_amplitude_nm=5.0, vibration_frequency_hz=37.0)
    shaken = measure_frames(psi_frames(h, nrm, pixel=p, microscope=_mic(0.4), disturbances=vib))
    assert np.nanstd(base.height) < 1e-3 * NM
    assert abs(np.nanmean(shaken.height - base.height)) > 0.2 * NM  # a piston/phase error
    ref = Disturbances(reference_figure_rms_nm=3.0, reference_figure_correlation_mm=2 * UM)
    fr = psi_frames(h, nrm, pixel=p, microscope=_mic(0.4), disturbances=ref)
    m = measure_frames(fr)
    figure = ref.reference_figure((32, 32), p)
    assert_allclose(np.sqrt(np.mean(figure ** 2)), 3.0 * NM, rtol=1e-6)
    # the reference mirror's figure appears in the measured height with opposite sign
    got = m.height - np.nanmean(m.height)
    assert_allclose(got, -(figure - figure.mean()), atol=0.15 * NM)


# ------------------------------------------------------------------- frames and measure
def test_frames_carry_settings_but_no_truth():
    h, nrm = artefacts.step((8, 64), 0.5 * UM, height=100 * NM)
    fr = psi_frames(h, nrm, pixel=0.5 * UM, microscope=_mic(0.4))
    assert isinstance(fr, Frames)
    arrays = [k for k, v in vars(fr).items() if isinstance(v, np.ndarray) and v.ndim >= 2]
    assert arrays == ["frames", "valid"]  # images, and where the object returned light
    head = fr.header()
    assert head["effective_wavelength_nm"] > head["wavelength_nm"]
    assert head["instrument"]["microscope"]["objective"]["name"] == "20x"
    import json

    json.dumps(head)  # plain values only


def test_measure_rejects_bad_algorithms():
    h, nrm = artefacts.flat((8, 8), 0.5 * UM)
    fr = psi_frames(h, nrm, pixel=0.5 * UM, microscope=_mic(0.4))
    with pytest.raises(InputError, match="algorithm for PSI frames"):
        measure_frames(fr, algorithm="envelope")
    assert measure_frames(fr, algorithm="hariharan").meta["algorithm"].startswith("5step")


# --------------------------------------------------------------- sources and objectives
def test_sources():
    k, w = led(600.0, bandwidth_nm=120.0).sample(dk=10.0)
    assert_allclose(w.sum(), 1.0)
    lam = 2 * np.pi / k / NM
    assert_allclose(np.sum(w * lam), 600.0, atol=5.0)  # Gaussian in wavelength
    line = monochromatic(633.0)
    assert line.is_line and line.sample(dk=1.0)[0].size == 1
    tab = spectrum_table([500, 550, 600], [0.0, 1.0, 0.0])
    assert_allclose(tab.wavelength_nm, 550.0, atol=3.0)
    assert 30 < tab.bandwidth_nm < 60
    with pytest.raises(InputError, match="bandwidth_nm"):
        led(600.0, bandwidth_nm=0.0)
    with pytest.raises(InputError, match="strictly increasing"):
        spectrum_table([600, 500], [1, 1])


def test_objective_presets_and_overrides():
    assert sorted(OBJECTIVES, key=lambda s: float(s[:-1])) == ["2.5x", "5x", "10x", "20x", "50x", "100x"]
    o = OBJECTIVES["20x"]
    assert o.numerical_aperture == 0.4 and o.camera_pixels == 1024
    assert_allclose(o.pixel * 1024, o.field_of_view)
    o2 = objective("50x", numerical_aperture=0.6, pixel=0.2 * UM)
    assert o2.numerical_aperture == 0.6 and o2.magnification == 50
    with pytest.raises(InputError, match="objective must be one of"):
        objective("40x")
    with pytest.raises(InputError, match="numerical_aperture"):
        objective("20x", numerical_aperture=1.2)
    with pytest.raises(InputError, match="illumination_na"):
        Microscope(objective=o, illumination_na=0.5)


def test_recommended_subsamples_sample_the_pupil_cut_off():
    mic = Microscope()
    s = recommended_subsamples(OBJECTIVES["20x"].pixel, mic, max_slope=0.01)
    # sub-sample spacing below lambda / (2 (NA + NA_ill)) at the short end of the band
    assert OBJECTIVES["20x"].pixel / s < 0.54 * UM / 1.6
    assert recommended_subsamples(0.05 * UM, mic, max_slope=0.01) == 1


def test_bad_input_is_named():
    h, nrm = artefacts.flat((8, 8), 0.5 * UM, )
    with pytest.raises(InputError, match="subsamples"):
        psi_frames(h, nrm, pixel=0.5 * UM, subsamples=3)
    with pytest.raises(InputError, match="normals must have shape"):
        psi_frames(h, nrm[:4], pixel=0.5 * UM)
    with pytest.raises(InputError, match="crop"):
        psi_frames(h, nrm, pixel=0.5 * UM, crop=4)
    with pytest.raises(InputError, match="steps"):
        psi_frames(h, nrm, pixel=0.5 * UM, steps=2)
    with pytest.raises(InputError, match="seed"):
        psi_frames(h, nrm, pixel=0.5 * UM, seed=-1)
    with pytest.raises(InputError, match="all NaN"):
        psi_frames(np.full_like(h, np.nan), nrm, pixel=0.5 * UM)
    with pytest.raises(InputError, match="camera.fill_factor"):
        Camera(fill_factor=0.0)


def test_dark_samples_return_no_light():
    # a hole (no surface reached) is dark: only the reference is seen, nothing is measured
    p = 0.5 * UM
    h, nrm = artefacts.flat((32, 64), p)
    h[:, 16:48] = np.nan  # 16 um wide
    m = measure_frames(psi_frames(h, nrm, pixel=p, microscope=_mic(0.4)))
    # light diffracted into the hole fades with the distance from its edges (Airy tails)
    assert not m.valid[:, 26:38].any()
    assert m.valid[:, :12].all() and m.valid[:, 52:].all()
    assert m.meta["regions"] == 2  # separated regions keep separate offsets
