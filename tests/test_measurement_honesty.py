"""Two measurements are two measurements: each pixel's height noise estimated from the
frames, the difference's noise floor and whether it is resolved, and fringe-order
failures found from the measurement itself.  Known answers from the forward model
``I_k = a + b cos(4 pi (h - z_ref) / lambda + delta_k) + noise``."""

from __future__ import annotations

import numpy as np
import pytest

from render_inspect.metrology import (difference_noise, difference_order_check,
                                      fringe_order_check, measured_difference,
                                      measurement_seeds, repeat_statistics, resolution,
                                      retrieve_csi, retrieve_psi)

LAM_NM = 550.0
LAM = LAM_NM * 1e-6  # mm
STEPS = np.arange(4) * np.pi / 2
PIX = 0.002


def _grid(n=96):
    x = (np.arange(n) - n / 2) * PIX
    return np.meshgrid(x, x)


def _frames(h, seed, *, a=0.5, b=0.3, sigma=0.004):
    rng = np.random.default_rng(seed)
    f = np.stack([a + b * np.cos(4 * np.pi * h / LAM + d) for d in STEPS])
    return f + rng.normal(0.0, sigma, f.shape)


def _measure(h, seed, **kw):
    return retrieve_psi(_frames(h, seed, **kw), wavelength_nm=LAM_NM, steps_rad=STEPS)


def test_psi_height_noise_matches_the_scatter_it_predicts():
    x, y = _grid()
    h = 4e-4 * x + 2e-4 * y
    sigma, b = 0.004, 0.3
    r = _measure(h, 1, sigma=sigma, b=b)
    # forward model: the phase noise of the 4-step formula is sigma / (b sqrt(2))
    expect_nm = LAM_NM / (4 * np.pi) * sigma / (b * np.sqrt(2))
    est = r.meta["noise"]["height_noise_rms_nm"]
    assert est == pytest.approx(expect_nm, rel=0.1)
    # two independent realisations: the difference scatters by sqrt(2) x one
    r2 = _measure(h, 2, sigma=sigma, b=b)
    d, _ = measured_difference(r.height, r2.height, pixel=PIX, labels_a=r.labels,
                               labels_b=r2.labels, fringe_order_mm=LAM / 2)
    rms = float(np.sqrt(np.nanmean(d ** 2))) * 1e6
    fl = difference_noise(r.height_noise, r2.height_noise)
    assert fl["floor_nm"] == pytest.approx(np.sqrt(2) * expect_nm, rel=0.1)
    assert rms == pytest.approx(fl["floor_nm"], rel=0.1)
    assert resolution(rms, fl["floor_nm"])["verdict"] == "not resolved"


def test_csi_height_noise_matches_the_scatter_it_predicts():
    x, _ = _grid(48)
    h = 2e-4 + 0.0 * x
    z = np.linspace(h.min() - 0.004, h.max() + 0.004, 129)
    lc = 0.0012
    rng = np.random.default_rng(3)
    opd = 2 * (h[None] - z[:, None, None])
    st = 0.5 + 0.3 * np.exp(-(opd / lc) ** 2) * np.cos(2 * np.pi * opd / LAM)
    st = st + rng.normal(0, 0.003, st.shape)
    r = retrieve_csi(st, z, wavelength_nm=LAM_NM)
    scatter = float(np.nanstd(r.height)) * 1e6
    assert r.meta["noise"]["height_noise_rms_nm"] == pytest.approx(scatter, rel=0.35)


def test_a_difference_above_the_noise_is_resolved_and_one_below_is_not():
    x, y = _grid()
    base = 4e-4 * x
    for amp_nm, verdict in ((0.2, "not resolved"), (5.0, "resolved")):
        bump = amp_nm * 1e-6 * np.sin(2 * np.pi * x / 0.05)
        ra, rb = _measure(base + bump, 11), _measure(base, 12)
        d, _ = measured_difference(ra.height, rb.height, pixel=PIX, terms="piston",
                                   labels_a=ra.labels, labels_b=rb.labels)
        rms = float(np.sqrt(np.nanmean(d ** 2))) * 1e6
        v = resolution(rms, difference_noise(ra.height_noise, rb.height_noise)["floor_nm"])
        assert v["verdict"] == verdict
        if verdict == "resolved":  # the part above the noise is the true rms
            assert v["above_noise_nm"] == pytest.approx(amp_nm / np.sqrt(2), rel=0.1)


def test_measurement_seeds_are_independent_and_reproducible():
    s = measurement_seeds(0, 2)
    assert s[0] != s[1] and s == measurement_seeds(0, 2)
    assert measurement_seeds(0, 2, repeat=1) != s


def test_repeat_statistics_measures_the_floor():
    rng = np.random.default_rng(0)
    maps = rng.normal(0, 0.5, (6, 40, 40)) + 0.1
    st = repeat_statistics(maps, [float(np.sqrt(np.mean(m ** 2))) for m in maps])
    assert st["pixel_repeatability_nm"] == pytest.approx(0.5, rel=0.05)
    assert st["mean_map_floor_nm"] == pytest.approx(0.5 / np.sqrt(6), rel=0.05)


def _partial_step(cross):
    """A tilted plane with a step along the middle row whose height grows from 0 at the
    left to 0.5 lambda at the right: beyond column ``cross`` it is higher than lambda / 4
    and the unwrapping cannot follow it (a residue where it crosses)."""
    x, y = _grid()
    n = x.shape[0]
    col = np.arange(n)
    step = np.clip(0.25 * LAM * col / cross, 0.0, 0.5 * LAM)
    h = 1e-4 * x
    h[n // 2:, :] += step[None, :]
    return h


def test_fringe_order_slips_are_found_from_the_measurement():
    good = _measure(_grid()[0] * 1e-4, 0)
    chk = fringe_order_check(good, fringe_order_mm=LAM / 2)
    assert chk["residues"] == 0 and chk["slips"] == 0
    bad = _measure(_partial_step(60), 0)
    chk = fringe_order_check(bad, fringe_order_mm=LAM / 2)
    assert chk["residues"] >= 1 and chk["slips"] > 0


def test_a_slipped_difference_is_failed_not_measured():
    # two surfaces that differ by a small bump; one measurement also slips
    x, y = _grid()
    ra = _measure(_partial_step(60), 0)
    rb = _measure(_partial_step(30), 1)
    fo = LAM / 2
    checks = [fringe_order_check(r, fringe_order_mm=fo) for r in (ra, rb)]
    d, info = measured_difference(ra.height, rb.height, pixel=PIX, labels_a=ra.labels,
                                  labels_b=rb.labels, fringe_order_mm=fo)
    out = difference_order_check(d, fringe_order_mm=fo, checks=checks)
    assert out["status"] == "failed" and out["jumps"] > 0 and out["reasons"]
    # what the summary and the report say of it: failed, no measured number
    from render_inspect.report import comparison_summary
    from render_inspect.report._comparison import resolution_text

    meas = {"status": "failed", "rms_nm": None, "fringe_order": out,
            "resolution": {"verdict": "failed", "resolved": None}}
    text = resolution_text(meas)
    assert text.startswith("failed") and "not a measured difference" in text
    m = {"variants": [{"name": "a"}, {"name": "b"}],
         "a": {"variant": {"label": "A"}, "residual": {"Sq_nm": 1.0, "min_nm": -1.0},
               "filtered": {}, "measured": {}},
         "b": {"variant": {"label": "B"}, "residual": {"Sq_nm": 1.0, "min_nm": -1.0},
               "filtered": {}, "measured": {}},
         "difference": {"window": {"measured": meas, "true": {"rms_nm": 20.6},
                                   "true_same_form_removed": {"rms_nm": 20.0}}}}
    _, lines = comparison_summary(m)
    joined = " ".join(t for _, t in lines)
    assert "FAILED" in joined and "measured rms" not in joined
    # the same pair without the step: nothing to mask
    ra, rb = _measure(1e-4 * x, 0), _measure(1e-4 * x + 1e-6 * np.sin(x / 0.02), 1)
    d, _ = measured_difference(ra.height, rb.height, pixel=PIX, fringe_order_mm=fo)
    assert difference_order_check(d, fringe_order_mm=fo)["status"] == "ok"


def test_separate_regions_between_two_orders_are_ambiguous():
    x, y = _grid()
    fo = LAM / 2
    d = np.zeros_like(x)
    d[:, 40:44] = np.nan  # two regions that do not touch
    d[:, 44:] = 0.5 * fo  # half an order off: either order is as likely
    out = difference_order_check(d, fringe_order_mm=fo)
    assert out["ambiguous_regions"] == 1 and out["status"] == "failed"
    d[:, 44:] = 1.02 * fo  # a whole order off: the nearest order is clear
    assert difference_order_check(d, fringe_order_mm=fo)["status"] == "ok"


@pytest.mark.mitsuba
def test_a_csi_scan_too_short_for_the_heights_is_refused_before_rendering(monkeypatch):
    """A tilted plane spanning 2.4 um in the field, scanned with 40 frames of 40 nm
    (1.56 um): refused, naming the range needed; a scan long enough is rendered."""
    import math

    from render_inspect.errors import InputError
    from render_inspect.instruments import _interferometer, render_interferogram
    from render_inspect.instruments._modes import scan_needed
    from render_inspect.machining import HeightMap
    from render_inspect.scene import InterferometerConfig

    n, pixel = 81, 0.001
    c = np.arange(n) * pixel
    xx, _ = np.meshgrid(c, c)
    tilt = math.radians(2.0)
    z = xx * math.tan(tilt)
    hm = HeightMap(z, z.copy(), pixel, (0.0, 0.0))
    kw = dict(mode="csi", pixel=0.001, field_of_view=(0.0105, 0.0105, 0.0695, 0.0695),
              noise=False, subsamples=1, numerical_aperture=0.3, wavelength_nm=600.0,
              bandwidth_nm=120.0, margin=0, scan_step_nm=40.0)
    traced = []
    monkeypatch.setattr(_interferometer, "trace_heights",
                        lambda *a, **k: traced.append(1) or (_ for _ in ()).throw(AssertionError))
    with pytest.raises(InputError, match=r"frames = 40 .* must cover at least \d+ nm \(frames >= \d+"):
        render_interferogram(hm, InterferometerConfig(**kw, frames=40), surface="design")
    assert not traced  # refused before anything was traced
    monkeypatch.undo()
    cfg = InterferometerConfig(**kw, frames=40)
    from render_inspect.instruments._interferometer import microscope_from_config
    need = scan_needed(0.0, float(z[:, :71].max()) + 2e-6, microscope_from_config(cfg),
                       scan_step_nm=40.0)
    ig = render_interferogram(hm, InterferometerConfig(**kw, frames=need["frames"]), surface="design")
    assert ig.frames.shape[0] == need["frames"]
    from render_inspect.metrology import measure_frames
    assert measure_frames(ig.recorded()).valid.mean() > 0.9


@pytest.mark.slow
def test_characterise_stops_the_transfer_function_at_the_camera_nyquist():
    """At the 20x camera pixel (0.879 um: Nyquist 569 /mm, below the 1455 /mm cut-off)
    the transfer function is a number up to Nyquist only; above it the aliased pattern is
    kept apart and said to be one."""
    from render_inspect.instruments._characterise import _itf
    from render_inspect.instruments._interferometer import (disturbances_from_config,
                                                            microscope_from_config)
    from render_inspect.scene import InterferometerConfig

    cfg = InterferometerConfig(objective="20x")
    mic, dist = microscope_from_config(cfg), disturbances_from_config(cfg)
    pixel = 0.000879
    fine = 550e-6 / (8 * 0.8)
    itf = _itf(mic, dist, mode="psi", pixel=pixel, fine=fine, quick=True)
    nyq = itf["camera_nyquist_per_mm"]
    assert nyq == pytest.approx(0.5 / pixel)
    assert itf["instrument_transfer_up_to_per_mm"] == pytest.approx(nyq)
    assert "Nyquist" in itf["instrument_note"]
    above = [r for r in itf["table"] if r["frequency_per_mm"] > nyq]
    below = [r for r in itf["table"] if r["frequency_per_mm"] <= nyq]
    assert above and below
    for r in above:
        assert r["itf_instrument"] is None and r["aliased_instrument"] is not None
    for r in below:  # the optics' transfer times the camera pixel's box filter
        box = abs(np.sinc(r["frequency_per_mm"] * pixel))
        assert r["itf_instrument"] == pytest.approx(r["itf_optics"] * box, abs=0.06)


@pytest.mark.slow
@pytest.mark.parametrize("obj", ["20x", "50x"])
def test_nothing_beyond_the_slope_limit_is_valid_on_a_sphere(obj):
    """A sphere whose slopes reach 1.25 times the slope limit, imaged by coherence
    scanning (characterise's sphere): no light returns from a facet steeper than
    asin(NA) (geometric optics, filled illumination), so no pixel beyond it may be
    measured; below it the drop-out is gradual (the contrast fades towards the limit)."""
    import math

    from render_inspect.instruments._characterise import _sphere
    from render_inspect.instruments._interferometer import (disturbances_from_config,
                                                            microscope_from_config)
    from render_inspect.instruments._objectives import OBJECTIVES
    from render_inspect.scene import InterferometerConfig

    cfg = InterferometerConfig(objective=obj, mode="csi")
    mic = microscope_from_config(cfg)
    out = _sphere(mic, disturbances_from_config(cfg), pixel=OBJECTIVES[obj].pixel, n=96, seed=0)
    limit = math.degrees(math.asin(mic.na))
    assert out["slope_limit_deg"] == pytest.approx(limit)
    beyond = [r for r in out["table"] if r["slope_deg"] - 0.25 > limit]
    assert len(beyond) >= 5
    for r in beyond:
        assert r["valid_fraction"] == 0.0, r
    assert out["dropout_50_deg"] < limit
    assert out["table"][0]["valid_fraction"] == 1.0


@pytest.mark.mitsuba
def test_the_truth_channel_does_not_alias_texture_finer_than_the_pixel():
    """A 10 nm grating of 0.6 um period on a tilted plane, imaged with 1 um pixels and
    5 x 5 sub-samples (0.2 um apart): point samples at the pixel centres would alias it
    to a full 10 nm pattern of 3 um period; the pixel's mean keeps 1/5 of it (three
    sub-samples per period cancel), and the plane itself is kept exactly."""
    import math

    from render_inspect.instruments import render_interferogram
    from render_inspect.machining import HeightMap
    from render_inspect.scene import InterferometerConfig

    fine = 0.00005  # map pixel, mm
    n = 601
    c = np.arange(n) * fine
    xx, yy = np.meshgrid(c, c)
    amp = 10e-6  # mm
    plane = 2e-3 * xx + 1e-3 * yy
    z = plane + amp * np.cos(2 * math.pi * xx / 0.0006)
    hm = HeightMap(plane.copy(), z, fine, (0.0, 0.0))  # design: the plane; machined: + grating
    cfg = InterferometerConfig(pixel=0.001, field_of_view=(0.005, 0.005, 0.025, 0.025),
                               noise=False, subsamples=5, margin=2)
    ig = render_interferogram(hm, cfg, surface="machined")
    xs, ys = np.meshgrid(ig.x, ig.y)
    ref = 2e-3 * xs + 1e-3 * ys
    err = (ig.height_true - ref) * 1e6  # nm
    err -= np.nanmean(err)
    rms = float(np.sqrt(np.nanmean(err ** 2)))
    # a point sample: |cos| of the grating at the centres, 10 nm at Nyquist (rms ~ 7 nm)
    point = amp * np.cos(2 * math.pi * xs / 0.0006) * 1e6
    assert float(np.sqrt(np.mean((point - point.mean()) ** 2))) > 5.0
    assert rms < 0.25 * 10.0 / math.sqrt(2) + 0.1
    assert ig.meta["height_true_unresolved_rms_nm"] == pytest.approx(10 / math.sqrt(2), rel=0.25)
    # the design channel (the plane): the mean is the centre value
    ig2 = render_interferogram(hm, cfg, surface="design")
    np.testing.assert_allclose(ig2.height_true, ref, atol=2e-8)


def test_the_summary_says_whether_the_difference_is_resolved():
    """The one-screen summary that compare and demo print: the measured rms with its
    noise floor and the verdict, from two forward-model measurements."""
    from render_inspect.report import comparison_summary

    x, _ = _grid()
    ra, rb = _measure(4e-4 * x + 0.2e-6 * np.sin(x / 0.01), 5), _measure(4e-4 * x, 6)
    d, info = measured_difference(ra.height, rb.height, pixel=PIX)
    rms = float(np.sqrt(np.nanmean(d ** 2))) * 1e6
    noise = difference_noise(ra.height_noise, rb.height_noise)
    meas = {"status": "ok", "rms_nm": rms, "noise": noise, "fringe_order": {},
            "resolution": resolution(rms, noise["floor_nm"])}
    side = {"variant": {"label": "A"}, "residual": {"Sq_nm": 1.0, "min_nm": -1.0},
            "filtered": {}, "measured": {}}
    m = {"variants": [{"name": "a"}, {"name": "b"}], "a": side, "b": side,
         "difference": {"window": {"measured": meas, "true": {"rms_nm": 0.2},
                                   "true_same_form_removed": {"rms_nm": 0.14}}}}
    _, lines = comparison_summary(m)
    verdict = dict(lines)["a - b, resolved?"]
    assert verdict.startswith("not resolved") and "noise floor" in verdict
