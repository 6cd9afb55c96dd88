"""Sal / Str from the autocorrelation, sphere form removal, non-square pixels, the one-map
analysis, and the checks a measured map must pass before it is compared with a design.
Known answers come from forward models (random fields of known correlation, sinusoids,
spheres, shifted designs)."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose
from scipy import ndimage

from render_inspect.errors import InputError
from render_inspect.metrology import (analyze_map, areal_parameters, fit_sphere, kinematic_sq_mm,
                                      parse_filter, register_lsq, registered_overlap,
                                      registration_checks, registration_covariance, remove_form,
                                      spatial_parameters)

SAL_FACTOR = 2.0 * np.sqrt(np.log(5.0))  # ACF exp(-t^2 / (4 sigma^2)) falls to 0.2 here / sigma


def _field(shape, sx, sy, seed):
    """Gaussian random field whose ACF is exp(-(tx^2 / (4 sx^2) + ty^2 / (4 sy^2))) (pixels)."""
    w = np.random.default_rng(seed).normal(size=shape)
    return ndimage.gaussian_filter(w, (sy, sx), mode="wrap")


@pytest.mark.parametrize("seed", [0, 1])
def test_sal_str_of_random_fields_with_known_correlation(seed):
    # isotropic: Sal = 2 sigma sqrt(ln 5), Str ~ 1 (sampling scatter ~5 %)
    r = spatial_parameters(_field((512, 512), 4, 4, seed), pixel=0.001)
    assert_allclose(r["Sal_mm"], 0.004 * SAL_FACTOR, rtol=0.08)
    assert r["Str"] > 0.85 and r["decays_in_all_directions"]
    # anisotropic 3 : 9 -> Str = 1/3, fastest decay along x
    r = spatial_parameters(_field((512, 512), 3, 9, seed), pixel=0.001)
    assert_allclose(r["Sal_mm"], 0.003 * SAL_FACTOR, rtol=0.08)
    assert_allclose(r["Str"], 1 / 3, rtol=0.1)
    assert min(r["fastest_direction_rad"], np.pi - r["fastest_direction_rad"]) < np.radians(5)
    # non-square pixels (1 x 2 um) sampling an isotropic field of sigma 6 um
    r = spatial_parameters(_field((256, 512), 6, 3, seed), pixel=(0.001, 0.002))
    assert_allclose(r["Sal_mm"], 0.006 * SAL_FACTOR, rtol=0.08)
    assert r["Str"] > 0.85


def test_sal_of_a_sinusoid_and_undefined_str():
    lam = 0.04
    x = np.arange(1000) * 0.001
    z = np.sin(2 * np.pi * x / lam)[None, :] * np.ones((60, 1))
    r = spatial_parameters(z, pixel=0.001)
    # ACF = cos(2 pi tx / lam) along x: falls to 0.2 at lam acos(0.2) / (2 pi); constant along y
    assert_allclose(r["Sal_mm"], lam * np.arccos(0.2) / (2 * np.pi), rtol=0.01)
    assert r["fastest_direction_rad"] == 0.0
    assert np.isnan(r["Str"]) and not r["decays_in_all_directions"]
    assert r["slowest_direction_rad"] == pytest.approx(np.pi / 2)
    with pytest.raises(InputError, match="s must be in"):
        spatial_parameters(z, pixel=0.001, s=1.0)


def test_fit_sphere_recovers_radius_and_apex_on_non_square_pixels():
    px, py, ny, nx = 0.002, 0.003, 120, 150
    x = 1.0 + px * np.arange(nx)
    y = -0.5 + py * np.arange(ny)
    xx, yy = np.meshgrid(x, y)
    for r_true in (5.0, -8.0):  # concave up (centre above) and convex
        z = 0.02 + r_true - np.sign(r_true) * np.sqrt(r_true ** 2 - (xx - 1.1) ** 2 - (yy + 0.3) ** 2)
        f = fit_sphere(z, pixel=(px, py), origin=(1.0, -0.5))
        assert_allclose(f["radius_mm"], r_true, rtol=1e-8)
        assert_allclose(f["apex_mm"], [1.1, -0.3, 0.02], atol=1e-8)
        assert f["rms_mm"] < 1e-10
        ripple = 1e-5 * np.sin(2 * np.pi * xx / 0.01)
        res, _ = remove_form(z + ripple, pixel=(px, py), origin=(1.0, -0.5), method="sphere")
        assert np.nanstd(res - ripple) < 0.05 * np.std(ripple)
    f = fit_sphere(0.1 * xx - 0.2 * yy, pixel=(px, py), origin=(1.0, -0.5))
    assert f["radius_mm"] == np.inf and f["rms_mm"] < 1e-12


def test_non_square_pixels_in_slopes_and_filters():
    a, b, lx, ly = 2e-4, 1e-4, 0.05, 0.08
    px, py = 0.0005, 0.001  # 100 and 80 px per wavelength
    x = px * np.arange(1001)  # 10 wavelengths in x (1000 cells)
    y = py * np.arange(641)   # 8 wavelengths in y (640 cells)
    xx, yy = np.meshgrid(x, y)
    z = a * np.sin(2 * np.pi * xx / lx) + b * np.sin(2 * np.pi * yy / ly)
    p = areal_parameters(z, pixel=(px, py))
    sdq = np.hypot(a * 2 * np.pi / lx, b * 2 * np.pi / ly) / np.sqrt(2)
    assert_allclose(p["Sdq"], sdq, rtol=1e-3)
    # squaring the pixel to the x one would be far off
    assert abs(areal_parameters(z, pixel=px)["Sdq"] / sdq - 1) > 0.05
    pc = areal_parameters(z, pixel=(px, py), slope="central")
    assert abs(pc["Sdq"] / sdq - 1) < 3e-3
    # near Nyquist (5 pixels per wavelength) forward differences keep sin(pi/5)/(pi/5) of the
    # slope, central ones sin(2 pi/5)/(2 pi/5)
    x = 0.001 * np.arange(2001)
    z5 = np.sin(2 * np.pi * x / 0.005)[None, :] * np.ones((3, 1)) * 1e-4
    true = 1e-4 * 2 * np.pi / 0.005 / np.sqrt(2)
    fw = areal_parameters(z5, pixel=0.001)["Sdq"] / true
    ce = areal_parameters(z5, pixel=0.001, slope="central")["Sdq"] / true
    assert_allclose(fw, np.sin(np.pi / 5) / (np.pi / 5), rtol=2e-3)
    assert_allclose(ce, np.sin(2 * np.pi / 5) / (2 * np.pi / 5), rtol=5e-3)


def test_analyze_map_metrics_form_filters_and_outliers():
    px, py = 0.002, 0.003
    ny, nx = 200, 240
    xx, yy = np.meshgrid(px * np.arange(nx), py * np.arange(ny))
    rough = 5e-5 * np.sin(2 * np.pi * xx / 0.05) * np.sin(2 * np.pi * yy / 0.09)
    z = 1e-3 + 2e-3 * xx - 1e-3 * yy + rough
    a = analyze_map(z, pixel=(px, py), form="plane")
    m = a.metrics
    assert set(m["areal"]) == {"Sa_nm", "Sq_nm", "Sz_nm", "Sp_nm", "Sv_nm", "Ssk", "Sku", "Sdq",
                               "Sdr_percent", "Sal_mm", "Str"}
    assert m["pixel_mm"] == [px, py] and m["shape"] == [ny, nx]
    assert m["valid_fraction"] == 1.0 and m["form"] == {"method": "plane"}
    assert_allclose(m["areal"]["Sq_nm"], np.std(rough) * 1e6, rtol=2e-3)
    assert m["outliers"] == {**m["outliers"], "method": "none", "count": 0, "fraction": 0.0}
    assert m["units"]["lateral"] == "mm" and "nm" in m["units"]["heights"]
    # spikes: off by default (kept and counted), left out with outliers="sigma"
    zs = z.copy()
    spikes = [(20, 30), (100, 100), (150, 40), (60, 200)]
    for r, c in spikes:
        zs[r, c] += 2e-3
    off = analyze_map(zs, pixel=(px, py), form="plane").metrics
    assert off["outliers"]["count"] >= 4 and not off["outliers"]["left_out"]
    assert off["areal"]["Sz_nm"] > 1.5e3 and any("are spikes" in w for w in off["warnings"])
    on = analyze_map(zs, pixel=(px, py), form="plane", outliers="sigma")
    assert on.metrics["outliers"]["left_out"] and on.metrics["outliers"]["count"] >= 4
    assert all(on.outliers[r, c] for r, c in spikes)
    assert_allclose(on.metrics["areal"]["Sq_nm"], np.std(rough) * 1e6, rtol=0.01)
    assert on.metrics["outliers"]["fraction"] == on.metrics["outliers"]["count"] / z.size
    # "none" removes the mean only; poly2 a quadratic; L-filter removes the long waves
    none = analyze_map(z, pixel=(px, py), form="none").metrics
    assert none["areal"]["Sq_nm"] > 10 * m["areal"]["Sq_nm"]
    q = analyze_map(z + 0.01 * xx ** 2, pixel=(px, py), form="poly2").metrics
    assert_allclose(q["areal"]["Sq_nm"], m["areal"]["Sq_nm"], rtol=1e-3)
    lf = analyze_map(z, pixel=(px, py), form="plane", l_filter_mm=0.02).metrics
    assert lf["areal"]["Sq_nm"] < 0.3 * m["areal"]["Sq_nm"] and lf["filter"]["L_mm"] == 0.02
    for bad, match in (({"form": "cubic"}, "form must be one of"),
                       ({"outliers": "mad"}, "outliers must be one of"),
                       ({"slope": "spline"}, "slope must be one of"),
                       ({"s_filter_mm": 0.1, "l_filter_mm": 0.05}, "must be >")):
        with pytest.raises(InputError, match=match):
            analyze_map(z, pixel=(px, py), **bad)


def test_parse_filter():
    assert parse_filter(None) == (None, None) and parse_filter("0.0025,0.8") == (0.0025, 0.8)
    assert parse_filter(",0.8") == (None, 0.8) and parse_filter("0.0025,0") == (0.0025, None)
    for bad in ("0.8", "a,b", "-1,2", "0.8,0.1"):
        with pytest.raises(InputError, match="filter"):
            parse_filter(bad)


class _Grid:
    """A design with lateral structure: A sin(2 pi x / lx) cos(2 pi y / ly)."""

    def __init__(self, a=1e-3, lx=0.15, ly=0.2):
        self.a, self.kx, self.ky = a, 2 * np.pi / lx, 2 * np.pi / ly

    def height(self, x, y):
        return self.a * np.sin(self.kx * np.asarray(x)) * np.cos(self.ky * np.asarray(y))

    def gradient(self, x, y):
        x, y = np.asarray(x), np.asarray(y)
        return (self.a * self.kx * np.cos(self.kx * x) * np.cos(self.ky * y),
                -self.a * self.ky * np.sin(self.kx * x) * np.sin(self.ky * y))


def _measure(design, shift, pixel, shape, noise, seed, corr_px=0.0):
    px, py = pixel
    ny, nx = shape
    xx, yy = np.meshgrid(px * np.arange(nx), py * np.arange(ny))
    z = design.height(xx - shift[0], yy - shift[1]) + shift[2]
    n = np.random.default_rng(seed).normal(size=shape)
    if corr_px:
        n = ndimage.gaussian_filter(n, corr_px) * (2 * np.sqrt(np.pi) * corr_px)
    return z + noise * n


def test_registration_with_non_square_pixels_recovers_the_shift():
    d = _Grid()
    pixel = (0.004, 0.007)
    z = _measure(d, (0.011, -0.006, 2e-4), pixel, (60, 90), 0.0, 0)
    reg = register_lsq(z, d, pixel=pixel, fit=("tx", "ty", "tz"))
    assert_allclose([reg["tx_mm"], reg["ty_mm"], reg["tz_mm"]], [0.011, -0.006, 2e-4], atol=1e-9)


def test_registration_uncertainty_matches_monte_carlo():
    """Formal sigma is right for white noise; for correlated noise only the inflated one."""
    d = _Grid()
    pixel, shape, fit = (0.005, 0.005), (70, 70), ("tx", "ty", "tz", "gamma")
    for corr, lo, hi in ((0.0, 0.6, 1.6), (3.0, 0.55, 1.6)):
        txs, sig, sig_formal = [], [], []
        for seed in range(12):
            z = _measure(d, (0.003, 0.002, 0.0), pixel, shape, 2e-5, seed, corr_px=corr)
            reg = register_lsq(z, d, pixel=pixel, fit=fit)
            xx, yy = np.meshgrid(pixel[0] * np.arange(shape[1]), pixel[1] * np.arange(shape[0]))
            resid = z - d.height(xx - reg["tx_mm"], yy - reg["ty_mm"]) - reg["tz_mm"]
            u = registration_covariance(z, d, reg, pixel=pixel, residual=resid)
            txs.append(reg["tx_mm"])
            sig.append(u["sigma"]["tx_mm"])
            sig_formal.append(u["sigma_formal"]["tx_mm"])
        emp = np.std(txs, ddof=1)
        assert lo < np.mean(sig) / emp < hi, (corr, np.mean(sig), emp)
        if corr:
            assert np.mean(sig_formal) / emp < 0.3  # independent-residual sigma: too optimistic


def test_registered_overlap_and_checks_refuse_a_mismatch():
    d = _Grid()
    pixel = (0.005, 0.005)
    z = _measure(d, (0.003, 0.002, 0.0), pixel, (80, 80), 2e-6, 0)
    reg = register_lsq(z, d, pixel=pixel, fit=("tx", "ty", "tz", "gamma"))
    field = (0.0, 0.0, 0.395, 0.395)
    ov = registered_overlap(z, pixel=pixel, region=field, registration=reg)
    assert ov["fraction"] > 0.97  # shifted by (3, 2) um out of 400 um
    # the map lies inside a region 4 x its area: the smaller area (the map) is all covered
    assert registered_overlap(z, pixel=pixel, region=(0, 0, 0.8, 0.8))["fraction"] == 1.0
    # a region of the map's size shifted by 300 um: 20 x 20 of the 80 x 80 points
    far = registered_overlap(z, pixel=pixel, region=(0.3, 0.3, 0.7, 0.7))
    assert_allclose(far["fraction"], 400 * 0.005 ** 2 / 0.16)
    ok = registration_checks(z, d, reg, pixel=pixel, region=field,
                             expected_sq_mm=kinematic_sq_mm(0.005, 0.5))
    assert ok["ok"] and not ok["refusals"]
    assert ok["uncertainty"]["shift_mm"] < 1e-3 and ok["uncertainty"]["rotation_rad"] < 1e-3
    # a map of something else: a rough random surface 10 um rms registered to the design
    other = _field((80, 80), 3, 3, 1) * 1e-2 / np.std(_field((80, 80), 3, 3, 1))
    reg2 = register_lsq(other, d, pixel=pixel, fit=("tx", "ty", "tz", "gamma"))
    bad = registration_checks(other, d, reg2, pixel=pixel, region=field,
                              expected_sq_mm=kinematic_sq_mm(0.005, 0.5))
    assert not bad["ok"] and "residual RMS" in bad["refusals"][0]
    small = registration_checks(z, d, reg, pixel=pixel, region=(0.3, 0.3, 0.7, 0.7),
                                expected_sq_mm=None)
    assert not small["ok"] and "overlaps" in small["refusals"][0]
    assert any("no expected roughness" in w for w in small["warnings"])


def test_kinematic_sq():
    f, r = 0.01, 0.5
    x = np.linspace(-f / 2, f / 2, 200_001)
    prof = x ** 2 / (2 * r)
    assert_allclose(kinematic_sq_mm(f, r), np.std(prof), rtol=1e-4)


def test_one_spike_is_said_in_the_singular():
    from render_inspect.metrology import analyze_profile

    x = np.arange(2000) * 1e-3
    z = 1e-5 * np.sin(2 * np.pi * x / 0.05)
    z[500] += 5e-3
    one = analyze_profile(x, z, spacing=1e-3)["metrics"]["warnings"]
    assert any(w.startswith("1 point (0.05%) is a spike by the 3-sigma rule; it is kept") for w in one), one
    z[900] += 5e-3
    two = analyze_profile(x, z, spacing=1e-3)["metrics"]["warnings"]
    assert any(w.startswith("2 points (0.10%) are spikes") and "leaves them out" in w for w in two), two
