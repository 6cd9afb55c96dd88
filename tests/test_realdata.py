"""Real instrument files (../shared/realdata, see its SOURCES.md): read as the reference
libraries read them, checked against the values published with the files, and slope
parameters that agree with SurfaceTopography and surfalize."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from conftest import real_file
from numpy.testing import assert_allclose

from render_inspect.io import read_surface
from render_inspect.metrology import analyze_map, areal_parameters, remove_form, slope_parameters


# file: (rows, cols, pixel_x_mm, pixel_y_mm, NaN count, reader)
EXPECTED = {
    "alicona_ski.x3p": (940, 1197, 3.678887926e-3, 3.680270397e-3, 4272, "x3pio"),
    "sensofar_bullet_land.x3p": (256, 918, 2.58e-3, 2.58e-3, 25292, "render_inspect"),
    "mountainsmap_x3p-2.x3p": (650, 650, 1.27656509837346e-4, 3.14582113527746e-4, 0, "x3pio"),
    "sensofar_plu_neox.plu": (576, 768, 1.6600000858306885e-3, 1.6600000858306885e-3, 0,
                              "SurfaceTopography"),
    "wyko_opd-1.opd": (480, 640, 1.9673303177114576e-4, 1.9673303177114576e-4, 116,
                       "SurfaceTopography"),
    "nanofocus_nms-1.nms": (512, 512, 3.125e-4, 3.125e-4, 0, "render_inspect"),
    "zygo_metropro-1.dat": (480, 640, 1.0982520279867458e-3, 1.0982520279867458e-3, 0,
                            "SurfaceTopography"),
    "truemap_tmd-1.tmd": (300, 300, 18.9566 / 300, 18.9566 / 300, 0, "render_inspect"),
    "gelsight_groove.tmd": (514, 616, 0.027458113509339, 0.027458113509339, 0, "render_inspect"),
    "digitalsurf_sur-2.sur": (484, 563, 3.4840002190321684e-3, 3.4840002190321684e-3, 117,
                              "surfalize"),
}


def _path(name):
    return real_file(name)


@pytest.fixture(scope="module")
def maps():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return {name: read_surface(_path(name)) for name in EXPECTED}


def _sq(z):
    v = z[np.isfinite(z)]
    return float(np.sqrt(np.mean((v - v.mean()) ** 2)))


@pytest.mark.parametrize("name", sorted(EXPECTED))
def test_shape_pixel_nan_count_reader_units(maps, name):
    rows, cols, px, py, n_nan, reader = EXPECTED[name]
    m = maps[name]
    assert m.shape == (rows, cols)
    assert_allclose(m.pixel, (px, py), rtol=2e-6)
    assert int(np.isnan(m.z).sum()) == n_nan == m.meta["n_invalid"]
    assert m.meta["reader"].startswith(reader)
    assert m.meta["units"] == {"lateral": "mm", "vertical": "mm"}
    assert set(m.meta["units_in_file"]) == {"lateral", "vertical"}


def test_published_values_surface_topography_test_suite(maps):
    # SurfaceTopography's own tests assert these for the same files (SOURCES.md)
    plu = maps["sensofar_plu_neox.plu"]
    assert_allclose(_sq(plu.z) * 1e3, 2.834391, rtol=1e-6)  # um
    res, _ = remove_form(plu.z, pixel=plu.pixel, method="polynomial", degree=2)
    assert_allclose(_sq(res) * 1e3, 0.01818, rtol=1e-4)  # um, after quadratic detrend
    x3p2 = maps["mountainsmap_x3p-2.x3p"]
    assert_allclose(_sq(x3p2.z), 7.728033273597876e-08 * 1e3, rtol=1e-6)
    assert_allclose(areal_parameters(x3p2.z, pixel=x3p2.pixel)["Sdq"], 0.062070073998443276,
                    rtol=1e-6)
    assert x3p2.pixel[1] / x3p2.pixel[0] == pytest.approx(2.4643, rel=1e-4)  # not squared
    assert_allclose(np.multiply(x3p2.pixel, x3p2.shape[::-1]),
                    (8.29767313942749e-05 * 1e3, 0.0002044783737930349 * 1e3), rtol=1e-6)
    mp = maps["zygo_metropro-1.dat"]
    assert_allclose(_sq(mp.z), 7.528822204734589e-08 * 1e3, rtol=1e-6)
    res, _ = remove_form(mp.z, pixel=mp.pixel, method="polynomial", degree=2)
    assert_allclose(_sq(res), 3.911386124282179e-09 * 1e3, rtol=1e-6)
    opd = maps["wyko_opd-1.opd"]
    assert_allclose(opd.pixel[0] * opd.shape[1], 0.125909140, rtol=1e-6)  # x field, mm
    assert_allclose(opd.pixel[1] * opd.shape[0], 0.094431855, rtol=1e-6)
    tmd = maps["truemap_tmd-1.tmd"]
    assert_allclose(tmd.pixel[0] * tmd.shape[1], 18.9566, rtol=1e-3)  # mm: the format is mm
    assert 0.0 <= np.nanmin(tmd.z) and np.nanmax(tmd.z) == pytest.approx(0.351, abs=1e-3)
    gel = maps["gelsight_groove.tmd"]
    assert_allclose(gel.pixel[0], 0.027458113509339, rtol=1e-7)  # scan.yaml mmperpixel
    assert gel.meta["scan_yaml_mm_per_pixel"] == 0.027458113509339


def test_units_checked_against_file_metadata(maps):
    decl = {n: maps[n].meta["units_in_file"] for n in EXPECTED}
    assert decl["mountainsmap_x3p-2.x3p"] == {"lateral": "m", "vertical": "m"}
    assert decl["sensofar_plu_neox.plu"]["vertical"] in ("µm", "um")
    # Wyko: Pixel_size in mm, heights as counts x Wavelength (nm) / Mult; SurfaceTopography
    # converts them to mm, which is kept apart
    assert decl["wyko_opd-1.opd"] == {"lateral": "mm", "vertical": "nm"}
    assert maps["wyko_opd-1.opd"].meta["library_units"] == {"lateral": "mm", "vertical": "mm"}
    assert decl["zygo_metropro-1.dat"] == {"lateral": "m", "vertical": "m"}
    assert decl["digitalsurf_sur-2.sur"] == {"lateral": "mm", "vertical": "mm"}
    assert decl["truemap_tmd-1.tmd"] == {"lateral": "mm", "vertical": "mm"}
    nms = maps["nanofocus_nms-1.nms"]
    assert decl["nanofocus_nms-1.nms"] == {"lateral": "nm", "vertical": "um"}
    # the heights span exactly the header's z range (um)
    zmin, zmax = nms.meta["z_range_um"]
    assert_allclose([np.nanmin(nms.z) * 1e3, np.nanmax(nms.z) * 1e3], [zmin, zmax], rtol=1e-12)


def test_readers_agree_with_independent_readers(maps):
    """Where two libraries read a file, they agree; where one is wrong, we know how."""
    import surfalize
    from SurfaceTopography import read_topography

    def st(name):
        t = read_topography(str(_path(name)))
        h = t.heights()
        h = h.filled(np.nan) if np.ma.isMaskedArray(h) else h
        scale = {"m": 1e3, "mm": 1.0, "µm": 1e-3}[t.unit]
        return np.asarray(h, float).T * scale

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for name in ("alicona_ski.x3p", "mountainsmap_x3p-2.x3p"):  # x3pio == SurfaceTopography
            assert_allclose(maps[name].z, st(name), rtol=1e-12, equal_nan=True)
        sur = maps["digitalsurf_sur-2.sur"]
        z_st = st("digitalsurf_sur-2.sur")
        ok = np.isfinite(sur.z)
        assert_allclose(sur.z[ok], z_st[ok], rtol=1e-12)
        # SurfaceTopography 1.18.2 turns the 117 non-measured points into heights (one
        # value below the valid range), later versions leave them out as surfalize and we
        # do: NaN are right
        bad = z_st[~ok]
        assert (~ok).sum() == 117
        assert np.isnan(bad).all() or (np.unique(bad).size == 1 and bad[0] < np.nanmin(sur.z))
        # surfalize 0.19.2 on MetroPro ignores phase_res = 1 (32768 counts per fringe): 8 x
        s = surfalize.Surface.load(str(_path("zygo_metropro-1.dat")))
        assert_allclose(_sq(np.asarray(s.data) * 1e-3) / _sq(maps["zygo_metropro-1.dat"].z), 8.0,
                        rtol=1e-9)
        # ... and on TrueMap .tmd takes the mm of the format for um: 1000 x too small
        s = surfalize.Surface.load(str(_path("truemap_tmd-1.tmd")))
        assert_allclose(s.step_x, maps["truemap_tmd-1.tmd"].pixel[0], rtol=1e-9)  # "um" == mm


def _reference_data(m):
    """Our map, and the map with missing points filled by SurfaceTopography (its own test
    suite's practice: ``interpolate_undefined_data``), so all three see the same data."""
    from SurfaceTopography import Topography

    z = m.z
    t = Topography(np.ma.masked_invalid(z.T), (m.pixel[0] * z.shape[1], m.pixel[1] * z.shape[0]),
                   unit="mm")
    if t.has_undefined_data:
        t = t.interpolate_undefined_data()
    return np.asarray(t.heights(), float).T, t


@pytest.mark.parametrize("name", [pytest.param(n, marks=pytest.mark.slow)
                                  if n == "sensofar_bullet_land.x3p" else n
                                  for n in sorted(EXPECTED)])  # filling its holes takes ~10 s
def test_slope_parameters_agree_with_surfacetopography_and_surfalize(maps, name):
    import surfalize

    m = maps[name]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        zf, t = _reference_data(m)
        ours = areal_parameters(zf, pixel=m.pixel)
        st_sdq = t.rms_gradient()
        gx, gy = t.derivative(1)
        st_sdr = 100.0 * np.mean(np.sqrt(1.0 + gx ** 2 + gy ** 2) - 1.0)  # ISO integral
        s = surfalize.Surface(zf * 1e3, m.pixel[0] * 1e3, m.pixel[1] * 1e3)
        sf_sdq, sf_sdr, sf_sq = s.Sdq(), s.Sdr(), s.Sq() * 1e-3
    # same estimator as SurfaceTopography's rms_gradient: identical
    assert_allclose(ours["Sdq"], st_sdq, rtol=1e-9)
    # surfalize averages each direction over its own differences: within 1 % (0.17 % seen)
    assert_allclose(ours["Sdq"], sf_sdq, rtol=0.01)
    # Sdr by ISO 25178-2:2021 D.3 triangulation: identical to surfalize ...
    assert_allclose(ours["Sdr"], sf_sdr, rtol=1e-9)
    # ... and within 1 % of the ISO integral over SurfaceTopography's gradients (0.82 % seen)
    assert_allclose(ours["Sdr"], st_sdr, rtol=0.01)
    assert_allclose(ours["Sq"], sf_sq, rtol=1e-12)
    assert_allclose(ours["Sq"], t.rms_height_from_area(), rtol=1e-12)


def test_raw_maps_with_holes_leave_the_hole_borders_out_as_surfacetopography(maps):
    """On the raw maps with missing points, Sdq leaves out the gradients bordering a hole
    as SurfaceTopography's rms_gradient does (its stencil and one point beyond in +x and
    +y measured); the value with them is reported too, and is what the bare differences
    give.  Equal to SurfaceTopography where there is no hole."""
    from SurfaceTopography import Topography

    for name in ("mountainsmap_x3p-2.x3p", "sensofar_plu_neox.plu", "zygo_metropro-1.dat",
                 "wyko_opd-1.opd", "digitalsurf_sur-2.sur", "alicona_ski.x3p"):
        m = maps[name]
        t = Topography(np.ma.masked_invalid(m.z.T), (m.pixel[0] * m.shape[1],
                                                     m.pixel[1] * m.shape[0]), unit="mm")
        p = areal_parameters(m.z, pixel=m.pixel)
        holes = int(np.isnan(m.z).sum())
        # identical where the holes stay off the map's last two rows and columns (where
        # SurfaceTopography's interpolation wraps around and its positions round)
        assert_allclose(p["Sdq"], t.rms_gradient(), rtol=1e-4 if holes else 1e-12)
        assert (p["n_border"] > 0) == (holes > 0)
        ok = np.isfinite(m.z)
        every = ok[:-1, :-1] & ok[:-1, 1:] & ok[1:, :-1]
        zx = np.diff(m.z, axis=1)[:-1, :] / m.pixel[0]
        zy = np.diff(m.z, axis=0)[:, :-1] / m.pixel[1]
        assert_allclose(p["Sdq_with_border"], np.sqrt(np.mean((zx ** 2 + zy ** 2)[every])),
                        rtol=1e-12)
        sp = slope_parameters(m.z, pixel=m.pixel)
        assert sp["n_slope"] + sp["n_border"] == int(every.sum()) and sp["Sdq"] == p["Sdq"]
    # the bullet land's 25292 missing points come up to the map's edges, where
    # SurfaceTopography's stencil wraps around: within 1 % (0.6 %), against +9.6 % with
    # the border gradients
    m = maps["sensofar_bullet_land.x3p"]
    t = Topography(np.ma.masked_invalid(m.z.T), (m.pixel[0] * m.shape[1], m.pixel[1] * m.shape[0]),
                   unit="mm")
    p = areal_parameters(m.z, pixel=m.pixel)
    assert_allclose(p["Sdq"], t.rms_gradient(), rtol=0.01)
    assert p["Sdq_with_border"] > 1.08 * t.rms_gradient()
    # Digital Surf sur-2: its 117 missing points border 73 gradients that raise Sdq by 6 %
    # and Sdr by 7 %: left out by default, both values reported (analyze warns)
    p = areal_parameters(maps["digitalsurf_sur-2.sur"].z, pixel=maps["digitalsurf_sur-2.sur"].pixel)
    assert p["Sdq_with_border"] / p["Sdq"] > 1.05 and p["Sdr_with_border"] / p["Sdr"] > 1.05
    a = analyze_map(maps["digitalsurf_sur-2.sur"], form="none").metrics
    assert a["holes"]["n_border_gradients"] == p["n_border"]
    assert any("hole" in w and "Sdq" in w for w in a["warnings"])


def test_sal_str_agree_with_surfalize(maps):
    """Sal / Str from our autocorrelation against surfalize's on the same plane-levelled
    maps (both use the unbiased linear ACF and s = 0.2)."""
    import surfalize

    from render_inspect.metrology import spatial_parameters

    for name, str_defined in (("nanofocus_nms-1.nms", True), ("truemap_tmd-1.tmd", True),
                              ("mountainsmap_x3p-2.x3p", False)):
        m = maps[name]
        r, _ = remove_form(m.z, pixel=m.pixel, method="plane")
        ours = spatial_parameters(r, pixel=m.pixel)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            s = surfalize.Surface(r * 1e3, m.pixel[0] * 1e3, m.pixel[1] * 1e3)
            sal, str_ = s.Sal() * 1e-3, s.Str()
        assert_allclose(ours["Sal_mm"], sal, rtol=0.005)
        assert ours["decays_in_all_directions"] is str_defined
        if str_defined:
            assert_allclose(ours["Str"], str_, rtol=0.005)
        else:
            assert np.isnan(ours["Str"]) and np.isnan(str_)


def test_wyko_16_bit_opd_reads_its_invalid_points_as_missing():
    """A Wyko OPD file with 16-bit heights marks points it did not measure with the
    largest 16-bit values.  SurfaceTopography up to 1.18.2 (the last for NumPy 1, which
    this environment keeps) reads them as heights; render_inspect masks them
    (io/_wyko.py).  Published reading (SOURCES.md, SurfaceTopography 1.27.1 and surfalize
    0.19.2): 809 invalid points; with a plane removed over the valid points Sa 1593.8 nm,
    Sq 1926.5 nm, Sz 18844 nm."""
    from render_inspect.core.units import MM_TO_NM
    from render_inspect.io._wyko import invalid_points

    path = _path("wyko_opd-int16.opd")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        m = read_surface(path)
    assert m.z.shape == (480, 736)
    assert_allclose(m.pixel, (1.63424e-3, 1.90661e-3), rtol=1e-5)
    assert int(np.isnan(m.z).sum()) == 809
    assert int(invalid_points(path).sum()) == 809
    z, _ = remove_form(m.z, pixel=m.pixel, method="plane")
    p = areal_parameters(z, pixel=m.pixel)
    assert p["Sq"] * MM_TO_NM == pytest.approx(1926.5, abs=0.1)
    assert p["Sa"] * MM_TO_NM == pytest.approx(1593.8, abs=0.1)
    assert p["Sz"] * MM_TO_NM == pytest.approx(18844, abs=1)
