"""Measured profiles: the readers (text exports, Dektak .opdx, X3P PRF) on real files and
forward-modelled ones, the ISO 16610-21 Gaussian profile filter checked against its
transmission computed in the frequency domain, and the ISO 21920-2 parameters checked
against closed forms of known profiles and against an independent implementation
(surfalize's Profile)."""

from __future__ import annotations

import csv
import io
import math
from pathlib import Path

# imported at collection, not inside a test: their first import starts a process (uname,
# fc-list), which the quick tier does not allow in a test
import matplotlib.pyplot  # noqa: F401
import numpy as np
import pytest
import SurfaceTopography.IO  # noqa: F401
import surfalize  # noqa: F401
from numpy.testing import assert_allclose, assert_array_equal
from conftest import real_file

from render_inspect.core.errors import InputError
from render_inspect.io import is_profile_file, read_profile
from render_inspect.metrology import (GAUSSIAN_ALPHA, default_cutoffs, dominant_periods,
                                      evaluate_profile, mirror_centre, profile_gaussian_filter,
                                      profile_periods, profile_texture, rmr)


#: (file, rows, measured points, mirror centre (um) the data's SOURCES.md states)
SLICES = [("1021-WLI-2D.csv", 1143, 999, 536.0), ("1022-WLI-2D.csv", 1047, 951, 478.0),
          ("1023-WLI-2D.csv", 1047, 995, 470.0), ("1016-WLI-2D.csv", 962, 962, 415.5)]


def _real(*parts) -> Path:
    return real_file(*parts)


def _csv_numbers(path):
    """The slice read with the csv module alone: positions and heights (um), NaN blanks."""
    xs, zs = [], []
    with open(path, newline="") as fh:
        rows = csv.reader(fh)
        next(rows)
        for row in rows:
            xs.append(float(row[0]))
            zs.append(float(row[1]) if row[1].strip() else math.nan)
    return np.array(xs), np.array(zs)


# -- readers ------------------------------------------------------------------------------

@pytest.mark.parametrize("name,rows,measured,centre_um", SLICES)
def test_real_slices_read_in_micrometres(name, rows, measured, centre_um):
    path = _real("turned", name)
    with pytest.raises(InputError, match=r"--units um\|mm\|nm.*positions 0\.87"):
        read_profile(path)
    m = read_profile(path, units="um")
    x_um, z_um = _csv_numbers(path)
    assert m.meta["n_points"] == rows and m.n_measured == measured
    assert m.spacing == pytest.approx(0.8712e-3, rel=2e-4)  # 0.8712 um pixel
    assert_allclose(m.x, x_um * 1e-3, rtol=1e-12)
    assert_array_equal(np.isnan(m.z), np.isnan(z_um))
    assert m.meta["label"].startswith("Slice")
    # the trace is a diameter through the spindle centre (SOURCES.md: 'centre near x')
    mc = mirror_centre(m.z, spacing=m.spacing, x0=m.x[0])
    assert mc["symmetry"] > 0.85
    assert mc["centre_mm"] * 1e3 == pytest.approx(centre_um, abs=20.0)


def test_ra_of_a_real_slice_equals_an_independent_computation():
    """Ra of the raw heights of a slice (no filter: mean line = the mean) against the same
    numbers read with the csv module and averaged by hand, and against surfalize."""
    import surfalize  # in the lock: a missing one fails
    path = _real("turned", "1016-WLI-2D.csv")
    m = read_profile(path, units="um")
    _, z_um = _csv_numbers(path)
    z_um = z_um[np.isfinite(z_um)]
    by_hand = sum(abs(v - sum(z_um) / len(z_um)) for v in z_um) / len(z_um)
    t = profile_texture(m.z, spacing=m.spacing, n_sections=5)
    assert t["Ra"] * 1e3 == pytest.approx(by_hand, rel=1e-12)
    sp = surfalize.profile.Profile(z_um, m.spacing * 1e3)
    for k in ("Ra", "Rq", "Rp", "Rv", "Rz", "Rt", "Rsk", "Rku"):
        ref = getattr(sp, k)()
        scale = 1e3 if k not in ("Rsk", "Rku") else 1.0
        assert t[k] * scale == pytest.approx(ref, rel=1e-9), k


def test_dektak_opdx_profile():
    """The Dektak file: 3001 points over the 50 um scan (the file's ScanLength); its
    spacing and first heights as the instrument's own text export of the same file
    (SurfaceTopography test/file_format_examples/opdx-3.txt: x 1.6655563e-08 m per point,
    heights 1.3718306e-09, 1.3122408e-09 m)."""
    path = _real("more", "st_opdx-3.opdx")
    assert is_profile_file(path)
    m = read_profile(path)
    assert m.meta["n_points"] == 3001 and m.n_measured == 3001
    assert m.spacing == pytest.approx(1.6655563e-05, rel=1e-7)
    assert m.length == pytest.approx(0.0499667, rel=1e-6)
    assert_allclose(m.z[:2], [1.3718306e-06, 1.3122408e-06], rtol=1e-6)
    assert m.meta["units_in_file"] == {"position": "um", "height": "um"}
    with pytest.raises(InputError, match="states its own units"):
        read_profile(path, units="um")


def test_x3p_profile_round_trip(tmp_path):
    import x3pio  # in the lock: a missing one fails
    z_m = 1e-7 * np.sin(np.arange(400) * 0.1)
    buf = io.BytesIO()
    x3pio.write(buf, z_m, x_scale=5e-7)
    path = tmp_path / "trace.x3p"
    path.write_bytes(buf.getvalue())
    assert is_profile_file(path)
    m = read_profile(path)
    assert m.meta["n_points"] == 400
    assert m.spacing == pytest.approx(5e-4)
    assert_allclose(m.z, z_m * 1e3, rtol=1e-12, atol=1e-15)
    areal = _real("more", "alicona_kautschuk.x3p")
    assert not is_profile_file(areal)
    with pytest.raises(InputError, match="not a profile"):
        read_profile(areal)


@pytest.mark.parametrize("text,units,n_meas,label", [
    ("x (um); height [nm]\n0,0;1,5\n0,5;2\n1,0;\n1,5;-3\n", None, 3, None),
    ("0.0\t1e-3\n0.001\tnan\n0.002\t2e-3\n0.003\t-1e-3\n", "mm", 3, None),
    ("0 1 a\n1 2 a\n2 n/a a\n3 4 a\n", "um,nm", 3, "a"),
    ("Position/mm,Height/um,Name\n0,1,S\n0.5,2,S\n1,,S\n1.5,4,S\n", None, 3, "S"),
])
def test_text_variants(tmp_path, text, units, n_meas, label):
    p = tmp_path / "trace.txt"
    p.write_text(text)
    m = read_profile(p, units=units)
    assert m.meta["n_points"] == 4 and m.n_measured == n_meas
    assert m.meta.get("label") == label
    assert np.isnan(m.z).sum() == 4 - n_meas


def test_text_units_scale(tmp_path):
    p = tmp_path / "t.csv"
    p.write_text("X (um), Height (nm)\n0, 10\n2, 20\n4, 30\n")
    m = read_profile(p)
    assert m.spacing == pytest.approx(2e-3)
    assert_allclose(m.z, [1e-5, 2e-5, 3e-5])
    with pytest.raises(InputError, match="contradicts"):
        read_profile(p, units="mm")


@pytest.mark.parametrize("text,match", [
    ("0,1\n1,2\n3,3\n4,4\n", "evenly spaced"),
    ("0,1\n2,2\n1,3\n", "must increase"),
    ("0,1,2,3\n1,2,3,4\n", "2 or 3 columns"),
    ("0,\n1,\n", "no measured"),
])
def test_text_refusals(tmp_path, text, match):
    p = tmp_path / "t.csv"
    p.write_text(text)
    with pytest.raises(InputError, match=match):
        read_profile(p, units="um")


def test_units_option_is_checked(tmp_path):
    p = tmp_path / "t.csv"
    p.write_text("0,1\n1,2\n2,3\n")
    with pytest.raises(InputError, match="--units must be one of um, mm, nm.*'furlong'"):
        read_profile(p, units="furlong")


# -- ISO 16610-21 filter ----------------------------------------------------------------

def test_gaussian_filter_matches_its_frequency_domain_transmission():
    """The spatial convolution against the analytic transmission of the ISO 16610-21
    weighting function, ``exp(-pi (alpha lambda_c f)^2)``, applied by FFT to the same
    profile (away from the ends, where both see the whole support)."""
    rng = np.random.default_rng(7)
    dx, lc = 0.5e-3, 0.08
    n = 4000
    z = np.cumsum(rng.normal(size=n)) * 1e-5 + 1e-4 * np.sin(np.arange(n) * dx * 2 * np.pi / 0.03)
    w = profile_gaussian_filter(z, spacing=dx, cutoff=lc)
    pad = 2 * n
    f = np.fft.rfftfreq(pad, d=dx)
    spec = np.fft.rfft(np.r_[z, np.zeros(pad - n)]) * np.exp(-np.pi * (GAUSSIAN_ALPHA * lc * f) ** 2)
    ref = np.fft.irfft(spec, n=pad)[:n]
    m = int(lc / dx) + 1
    assert_allclose(w[m:-m], ref[m:-m], atol=1e-9 * np.ptp(z))


@pytest.mark.parametrize("ratio", [0.5, 1.0, 2.0])
def test_gaussian_filter_keeps_half_the_amplitude_at_the_cutoff(ratio):
    dx, lc = 0.25e-3, 0.25
    lam = lc * ratio
    x = np.arange(int(8 * lc / dx)) * dx
    w = profile_gaussian_filter(np.sin(2 * np.pi * x / lam), spacing=dx, cutoff=lc)
    mid = slice(int(2 * lc / dx), int(6 * lc / dx))
    amp = np.sqrt(2 * np.mean(w[mid] ** 2))
    assert amp == pytest.approx(math.exp(-math.pi * (GAUSSIAN_ALPHA * lc / lam) ** 2), abs=2e-3)


# -- ISO 21920-2 parameters, closed forms ---------------------------------------------

def test_sinusoid_parameters_closed_form():
    """A sinusoid of amplitude A and wavelength L: Ra = 2A/pi, Rq = A/sqrt 2, Rp = Rv = A,
    Rz = Rt = 2A, Rsk = 0, Rku = 3/2, RSm = L, Rdq = 2 pi A / (L sqrt 2), and
    Rmr(c) = arccos(1 - c / A) / pi for c below the peak."""
    A, L, dx = 0.5e-3, 0.05, 0.1e-3
    x = np.arange(int(2.0 / dx)) * dx
    t = profile_texture(A * np.sin(2 * np.pi * x / L), spacing=dx)
    assert t["Ra"] == pytest.approx(2 * A / np.pi, rel=1e-3)
    assert t["Rq"] == pytest.approx(A / np.sqrt(2), rel=1e-3)
    assert t["Rz"] == pytest.approx(2 * A, rel=1e-3) and t["Rt"] == pytest.approx(2 * A, rel=1e-3)
    assert t["Rsk"] == pytest.approx(0.0, abs=1e-3) and t["Rku"] == pytest.approx(1.5, rel=1e-3)
    assert t["RSm"] == pytest.approx(L, rel=1e-3)
    assert t["Rdq"] == pytest.approx(2 * np.pi * A / (L * np.sqrt(2)), rel=1e-3)
    for c in (0.25 * A, A, 1.5 * A):
        assert rmr(A * np.sin(2 * np.pi * x / L), c) == pytest.approx(np.arccos(1 - c / A) / np.pi,
                                                                        abs=2e-3)


def test_triangle_wave_closed_form():
    """A symmetric triangle wave of amplitude A: Ra = A/2, Rq = A/sqrt 3, Rku = 9/5."""
    A, L, dx = 1e-3, 0.04, 0.05e-3
    x = np.arange(int(1.6 / dx)) * dx
    z = A * (2 * np.abs(2 * ((x / L) % 1.0) - 1) - 1)
    t = profile_texture(z, spacing=dx)
    assert t["Ra"] == pytest.approx(A / 2, rel=2e-3)
    assert t["Rq"] == pytest.approx(A / np.sqrt(3), rel=2e-3)
    assert t["Rku"] == pytest.approx(1.8, rel=3e-3)
    assert t["RSm"] == pytest.approx(L, rel=1e-3)


def test_default_cutoffs_follow_rsm_and_ra():
    """ISO 21920-3 (as ISO 4288): RSm 0.1 mm -> lambda_c 0.25 mm; RSm 0.3 mm -> 0.8 mm;
    a non-periodic profile with Ra 0.05 um -> 0.25 mm, with Ra 0.5 um -> 0.8 mm."""
    dx = 0.5e-3
    x = np.arange(int(12.0 / dx)) * dx
    for period, lc in ((0.1, 0.25), (0.3, 0.8)):
        d = default_cutoffs(x, 1e-3 * np.sin(2 * np.pi * x / period), spacing=dx)
        assert d["by"] == "RSm" and d["lambda_c"] == lc and d["lambda_s"] == 0.0025
    rng = np.random.default_rng(3)
    noise = rng.normal(size=x.size)
    for ra_mm, lc in ((0.05e-3, 0.25), (0.5e-3, 0.8)):
        z = noise * ra_mm * np.sqrt(np.pi / 2)  # Ra of white Gaussian noise = sigma sqrt(2/pi)
        d = default_cutoffs(x, z, spacing=dx)
        assert d["by"] == "Ra" and d["lambda_c"] == lc


def test_filtered_parameters_of_a_known_profile():
    """A feed-mark sinusoid on a long waviness: lambda_c removes the waviness and keeps the
    marks at the filter's transmission, so Ra is 2A/pi times that transmission."""
    dx, lc = 0.5e-3, 0.25
    A, L = 0.2e-3, 0.05
    x = np.arange(int(3.0 / dx)) * dx
    z = A * np.sin(2 * np.pi * x / L) + 5e-3 * np.sin(2 * np.pi * x / 2.5)
    e = evaluate_profile(x, z, spacing=dx, lambda_s=0.0025, lambda_c=lc)
    keep = (1 - math.exp(-math.pi * (GAUSSIAN_ALPHA * lc / L) ** 2)) \
        * math.exp(-math.pi * (GAUSSIAN_ALPHA * 0.0025 / L) ** 2)
    assert e["parameters"]["Ra"] == pytest.approx(2 * A / np.pi * keep, rel=0.02)
    assert e["filter"]["chosen_by"] == "--filter"


# -- periods ---------------------------------------------------------------------------

def test_periods_of_a_forward_modelled_cusp_profile():
    """Circular-arc cusps of a tool of radius R at feed f (the turned profile) have the
    feed as fundamental and harmonics; a trace through the axis with feed f1 left and f2
    right gives each side's feed and the centre."""
    R, dx = 0.2, 0.5e-3
    x = np.arange(int(1.2 / dx)) * dx

    def cusps(u, f):
        ph = (u % f) - f / 2
        return -(R - np.sqrt(R * R - ph * ph))

    p = dominant_periods(cusps(x, 0.02), spacing=dx)
    assert p["period_mm"] == pytest.approx(0.02, rel=5e-3)
    assert [h["order"] for h in p["harmonics"]][:2] == [2, 3]
    # through the axis: the feed grows with the radius (0.02 mm at the axis, 0.03 mm at
    # 0.6 mm), so the trace is mirror-symmetric about the axis only
    c = 0.61
    r = np.abs(x - c)
    feed = 0.02 + 0.01 * r / 0.6
    revs = np.log(feed / 0.02) * 0.6 / 0.01  # the integral of dr / feed(r)
    z = -(R - np.sqrt(R * R - (((revs % 1.0) - 0.5) * feed) ** 2))
    out = profile_periods(x, z, spacing=dx)
    assert out["through_axis"]["centre_mm"] == pytest.approx(c, abs=2 * dx)
    for side in ("left", "right"):
        assert 0.02 < out["through_axis"][side]["period_mm"] < 0.03


@pytest.mark.parametrize("name,feed_um", [("1021-WLI-2D.csv", 39.6), ("1016-WLI-2D.csv", 10.0)])
def test_real_slice_feed_period(name, feed_um):
    """The feed per revolution of the program (1021: 39.6 um for r = 0.2-0.8 mm; 1016: 0.01
    mm/rev by its name) is the slice's dominant period within 5 %."""
    m = read_profile(_real("turned", name), units="um")
    out = profile_periods(m.x, m.z, spacing=m.spacing)
    for side in ("left", "right"):
        assert out["through_axis"][side]["period_mm"] * 1e3 == pytest.approx(feed_um, rel=0.05)


# -- the outlier rule: spikes, not curvature ---------------------------------------------

def _turned(r, feed=0.04, R=0.2):
    ph = (r % feed) - feed / 2
    return -(R - np.sqrt(R * R - ph * ph))


def test_spike_rule_keeps_cusp_tips_and_finds_spikes():
    """A forward-modelled turned profile (0.2 mm tool, 40 um feed, 0.87 um sampling, 2 nm
    noise, the tips rounded by a 1.5 um instrument blur): the spike rule flags no point, the
    curvature rule flags the tips; 20 nm .. 200 nm spikes added at random are all found."""
    from scipy import ndimage

    from render_inspect.metrology import detect_outliers

    dx = 0.87e-3
    x = np.arange(1100) * dx
    rng = np.random.default_rng(11)
    z = ndimage.gaussian_filter1d(_turned(x), 1.5e-3 / dx / 2.355) + rng.normal(0, 2e-6, x.size)
    _, flagged = detect_outliers(z, pixel=dx, replace=False)
    assert flagged.sum() <= 2  # noise tails at most (k = 3)
    _, old = detect_outliers(z, pixel=dx, replace=False, rule="curvature")
    assert old.sum() > 0.05 * x.size  # the tips the old rule took
    idx = rng.choice(np.arange(5, x.size - 5), 12, replace=False)
    zs = z.copy()
    zs[idx] += rng.choice([-1, 1], idx.size) * rng.uniform(2e-5, 2e-4, idx.size)
    cleaned, flagged = detect_outliers(zs, pixel=dx)
    assert flagged[idx].all() and flagged.sum() <= idx.size + 2
    assert_allclose(cleaned[idx], z[idx], atol=2e-5)


def test_spike_rule_on_a_turned_map():
    """Concentric cusps on a map (the turned part seen from above): no point flagged; five
    spikes all found."""
    from render_inspect.metrology import detect_outliers

    px = 1e-3
    yy, xx = np.mgrid[0:200, 0:200] * px
    z = _turned(np.hypot(xx - 0.05, yy - 0.08)) + np.random.default_rng(2).normal(0, 1e-6, xx.shape)
    _, flagged = detect_outliers(z, pixel=px, replace=False)
    assert flagged.sum() <= 0.001 * z.size
    spikes = [(20, 30), (100, 100), (150, 40), (60, 180), (190, 7)]
    for r, c in spikes:
        z[r, c] += 1e-4
    _, flagged = detect_outliers(z, pixel=px, replace=False)
    assert all(flagged[r, c] for r, c in spikes)


@pytest.mark.parametrize("name", [s[0] for s in SLICES])
def test_spike_rule_on_the_real_slices(name):
    """The real slices of clean turned parts: the old curvature rule flagged 2-24 % of
    their points (cusp tips); the spike rule flags under 1 %."""
    from render_inspect.metrology import detect_outliers

    m = read_profile(_real("turned", name), units="um")
    _, flagged = detect_outliers(m.z, pixel=m.spacing, replace=False)
    assert flagged.sum() < 0.01 * m.n_measured


def test_mirror_centre_of_a_long_trace():
    """A 60000-point trace through the axis (searched on block means, then refined): the
    centre within one sample."""
    R, dx = 0.2, 0.05e-3
    x = np.arange(60000) * dx
    c = 1.7231
    r = np.abs(x - c)
    feed = 0.02 + 0.01 * r / 3.0
    revs = np.log(feed / 0.02) * 3.0 / 0.01
    z = -(R - np.sqrt(R * R - (((revs % 1.0) - 0.5) * feed) ** 2))
    mc = mirror_centre(z, spacing=dx)
    assert mc["centre_mm"] == pytest.approx(c, abs=dx) and mc["symmetry"] > 0.99
