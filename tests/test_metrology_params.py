"""Areal/profile parameters, ISO 16610-61 filters, form removal: forward model -> recover,
and a cross-check against an independent implementation (surfalize) within 1 %."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose

from render_inspect.errors import InputError
from render_inspect.metrology import (
    GAUSSIAN_ALPHA,
    areal_parameters,
    characterise_map,
    extract_section,
    gaussian_filter,
    gaussian_sigma,
    l_filter,
    profile_parameters,
    remove_form,
    s_filter,
    section_parameters,
)


def _grid(n=200, pixel=0.002):
    x = pixel * np.arange(n)
    return np.meshgrid(x, x)


def _smooth_surface(n=256, pixel=0.002):
    xx, yy = _grid(n, pixel)
    # a smooth, asymmetric surface, well sampled (>= 60 points per wavelength)
    z = (5e-3 * np.sin(2 * np.pi * xx / 0.17) * np.cos(2 * np.pi * yy / 0.23)
         + 2e-3 * np.sin(2 * np.pi * (xx + 0.3 * yy) / 0.13) ** 2 + 1e-3 * np.cos(2 * np.pi * yy / 0.31))
    return z, pixel


@pytest.mark.slow
def test_areal_parameters_match_surfalize_within_1_percent():
    import surfalize

    z, pixel = _smooth_surface()
    ours = areal_parameters(z, pixel=pixel)
    s = surfalize.Surface(z * 1e3, pixel * 1e3, pixel * 1e3)  # um
    theirs = {k: getattr(s, k)() for k in ("Sa", "Sq", "Sp", "Sv", "Sz", "Ssk", "Sku", "Sdq", "Sdr")}
    for k in ("Sa", "Sq", "Sp", "Sv", "Sz"):
        assert_allclose(ours[k] * 1e3, theirs[k], rtol=0.01, err_msg=k)
    for k in ("Ssk", "Sku", "Sdq", "Sdr"):
        assert_allclose(ours[k], theirs[k], rtol=0.01, err_msg=k)
    assert ours["Sdr"] > 0.5  # the test surface is steep enough for Sdr to matter


def test_areal_parameters_of_a_sinusoid_analytic():
    a, lam, pixel = 1e-4, 0.1, 0.001
    xx, yy = _grid(400, pixel)  # 4 full wavelengths: 400 points
    z = a * np.sin(2 * np.pi * xx / lam)
    p = areal_parameters(z, pixel=pixel)
    assert_allclose(p["Sq"], a / np.sqrt(2), rtol=1e-3)
    assert_allclose(p["Sa"], 2 * a / np.pi, rtol=2e-3)
    assert_allclose(p["Sku"], 1.5, rtol=2e-3)
    # slopes are taken on the cells: 401 points = 400 cells span the 4 wavelengths exactly
    xx, yy = _grid(401, pixel)
    z = a * np.sin(2 * np.pi * xx / lam)
    p = areal_parameters(z, pixel=pixel)
    # forward differences see the slope attenuated by sinc(pixel / lam) = 1 - 1.6e-4
    assert_allclose(p["Sdq"], a * 2 * np.pi / lam / np.sqrt(2), rtol=5e-4)
    t = np.linspace(0.0, lam, 100_000, endpoint=False)  # the continuous integral, one period
    g2 = (a * 2 * np.pi / lam * np.cos(2 * np.pi * t / lam)) ** 2
    assert_allclose(p["Sdr"], 100 * np.mean(np.sqrt(1 + g2) - 1), rtol=5e-4)


def test_areal_parameters_honour_nan_and_mask():
    z, pixel = _smooth_surface(128)
    zn = z.copy()
    zn[10:20, 30:40] = np.nan
    mask = np.isfinite(zn)
    a = areal_parameters(zn, pixel=pixel)
    b = areal_parameters(z, pixel=pixel, mask=mask)
    assert a["n_valid"] == b["n_valid"] == mask.sum()
    for k in ("Sa", "Sq", "Sz", "Ssk", "Sku"):
        assert_allclose(a[k], b[k], rtol=1e-12)
    with pytest.raises(InputError, match="valid"):
        areal_parameters(np.full((5, 5), np.nan), pixel=pixel)
    with pytest.raises(InputError, match="mask must have the shape"):
        areal_parameters(z, pixel=pixel, mask=np.ones((3, 3), bool))
    with pytest.raises(InputError, match="pixel"):
        areal_parameters(z, pixel=0.0)


def test_gaussian_sigma_is_iso_16610_61():
    assert_allclose(GAUSSIAN_ALPHA, 0.4697, atol=1e-4)
    assert_allclose(gaussian_sigma(0.8), 0.4697 * 0.8 / np.sqrt(2 * np.pi), rtol=1e-4)
    with pytest.raises(InputError, match="cutoff"):
        gaussian_sigma(-1)


@pytest.mark.parametrize("ratio, expected", [(1.0, 0.5), (2.0, np.exp(-np.pi * GAUSSIAN_ALPHA ** 2 / 4))])
def test_gaussian_filter_transmission(ratio, expected):
    # a sinusoid of wavelength ratio * cutoff is passed with exp(-pi (alpha lc / lambda)^2)
    pixel, cutoff = 0.001, 0.05
    lam = ratio * cutoff
    x = pixel * np.arange(600)
    z = np.tile(np.sin(2 * np.pi * x / lam), (40, 1))
    sm = gaussian_filter(z, pixel=pixel, cutoff=cutoff)
    mid = sm[:, 200:400]
    amp = np.sqrt(2) * np.sqrt(np.mean(mid[20] ** 2))
    assert_allclose(amp, expected, rtol=0.01)
    # S and L filters split the surface: S + L = z
    assert_allclose(s_filter(z, pixel=pixel, nesting_index=cutoff)
                    + l_filter(z, pixel=pixel, nesting_index=cutoff), z, atol=1e-12)


@pytest.mark.slow
def test_gaussian_filter_matches_surfalize_in_the_interior():
    import surfalize
    from surfalize.filter import GaussianFilter

    z, pixel = _smooth_surface(200)
    cutoff = 0.08
    ours = gaussian_filter(z, pixel=pixel, cutoff=cutoff)
    s = surfalize.Surface(z * 1e3, pixel * 1e3, pixel * 1e3)
    theirs = GaussianFilter(cutoff * 1e3, "lowpass")(s).data * 1e-3
    m = 40  # away from the edges (4 sigma = 30 pixels), where end effects differ
    err = np.abs(ours[m:-m, m:-m] - theirs[m:-m, m:-m]).max()
    assert err < 0.01 * np.abs(theirs[m:-m, m:-m]).max()


def test_masked_normalised_convolution_keeps_constants_at_edges_and_holes():
    z = np.full((60, 80), 3.0)
    z[20:30, 20:35] = np.nan
    sm = gaussian_filter(z, pixel=0.01, cutoff=0.1)
    assert np.isnan(sm[25, 25])
    assert_allclose(sm[np.isfinite(z)], 3.0, rtol=1e-12)
    with pytest.raises(InputError, match="no valid"):
        gaussian_filter(np.full((5, 5), np.nan), pixel=0.01, cutoff=0.1)


def test_remove_form_plane_polynomial_design():
    pixel = 0.01
    xx, yy = _grid(80, pixel)
    rough = 1e-6 * np.sin(2 * np.pi * xx / 0.05) * np.sin(2 * np.pi * yy / 0.07)
    plane = 1e-3 + 2e-3 * xx - 5e-4 * yy
    res, form = remove_form(plane + rough, pixel=pixel, method="plane")
    assert_allclose(res, rough - rough.mean(), atol=2e-8)
    quad = plane + 0.01 * xx ** 2 - 0.02 * xx * yy + 0.005 * yy ** 2
    res, _ = remove_form(quad + rough, pixel=pixel, method="polynomial", degree=2)
    assert_allclose(res, rough - rough.mean(), atol=2e-8)

    class Design:
        def height(self, x, y):
            return 0.05 * np.sin(x) * np.cos(y)

    des = Design().height(xx, yy)
    res, _ = remove_form(des + rough + 0.3, pixel=pixel, method="design", design=Design())
    assert_allclose(res, rough - rough.mean(), atol=1e-12)
    res2, _ = remove_form(des + rough, pixel=pixel, method="design", design=des)
    assert_allclose(res2, res, atol=1e-12)
    with pytest.raises(InputError, match="method must be one of"):
        remove_form(quad, pixel=pixel, method="cylinder")
    with pytest.raises(InputError, match="needs design"):
        remove_form(quad, pixel=pixel, method="design")
    with pytest.raises(InputError, match="degree"):
        remove_form(quad, pixel=pixel, method="polynomial", degree=11)


def test_profile_parameters_of_a_sinusoid():
    a, lam, dx = 2e-4, 0.1, 0.0005
    x = np.arange(0, 5 * lam, dx)  # 5 wavelengths = 5 sampling lengths of one period each
    p = profile_parameters(a * np.sin(2 * np.pi * x / lam), spacing=dx, n_sampling=5)
    assert_allclose(p["Ra"], 2 * a / np.pi, rtol=2e-3)
    assert_allclose(p["Rq"], a / np.sqrt(2), rtol=2e-3)
    assert_allclose(p["Rz"], 2 * a, rtol=1e-3)
    assert_allclose(p["Rt"], 2 * a, rtol=1e-3)
    with pytest.raises(InputError, match="n_sampling"):
        profile_parameters(np.ones(6), spacing=dx, n_sampling=5)


def test_radial_and_circumferential_sections():
    pixel, a, lam, m = 0.005, 1e-4, 0.2, 6
    x = -1.0 + pixel * np.arange(401)
    xx, yy = np.meshgrid(x, x)
    r, th = np.hypot(xx, yy), np.arctan2(yy, xx)
    radial = a * np.sin(2 * np.pi * r / lam)          # turning marks: a radial sinusoid
    s, v = extract_section(radial, pixel=pixel, origin=(-1.0, -1.0), kind="radial", angle=0.3,
                           r_max=0.8)
    assert_allclose(v, a * np.sin(2 * np.pi * s / lam), atol=2e-3 * a * 10)
    circ = a * np.sin(m * th)                          # m waves around the circumference
    out = section_parameters(circ, pixel=pixel, origin=(-1.0, -1.0), angles=[0.0], radii=[0.5],
                             n_sampling=m)
    c = out["circumferential"][0]
    assert_allclose(c["Rq"], a / np.sqrt(2), rtol=0.01)
    assert_allclose(c["Rz"], 2 * a, rtol=0.01)
    assert out["radial"][0]["Rq"] < 1e-3 * a * 50  # along a ray, sin(m theta) is constant (~0)
    with pytest.raises(InputError, match="radius"):
        extract_section(circ, pixel=pixel, kind="circumferential")


def test_characterise_map_reports_nm_and_settings():
    z, pixel = _smooth_surface(128)
    m = characterise_map(z, pixel=pixel, form_removal="none")
    p = areal_parameters(z, pixel=pixel)
    assert_allclose(m["Sq_nm"], p["Sq"] * 1e6)
    assert m["form_removal"] == "none"
    with pytest.raises(InputError, match="l_filter"):
        characterise_map(z, pixel=pixel, s_filter_mm=0.1, l_filter_mm=0.05)
