"""The periods ``analyze`` reports are periods the surface has: never negative, never the
end of the range searched, and a trace is called through the spindle axis only when both
arms show the same feed marks.  Each case is a forward model with a known answer."""

from __future__ import annotations

import json

# imported at collection, not inside a test: their first import starts a process
import matplotlib.pyplot  # noqa: F401
import numpy as np
import pytest
from conftest import real_file

from render_inspect.metrology import dominant_periods, map_periods, profile_periods
from render_inspect.pipeline._analyze import run_analyze
from render_inspect.report import analysis_summary

#: tool nose radius of the cusp models, mm
R_TOOL = 0.2


def _cusps(u, feed):
    """Circular-arc cusps of a tool of radius R_TOOL at ``feed`` (mm): a turned profile."""
    ph = (u % feed) - feed / 2
    return -(R_TOOL - np.sqrt(R_TOOL * R_TOOL - ph * ph))


def _write_profile(path, x_mm, z_mm):
    """A two-column text profile, positions in um and heights in nm (stated in the header)."""
    rows = "\n".join(f"{a * 1e3:.6f},{b * 1e6:.6f}" for a, b in zip(x_mm, z_mm))
    path.write_text("X (um),Height (nm)\n" + rows + "\n")
    return path


# -- the sign of a period ------------------------------------------------------------------

@pytest.mark.parametrize("centre", [0.3, 0.5, 0.62])
@pytest.mark.parametrize("sigma", [0.02, 0.05, 0.08])
def test_a_bump_on_feed_marks_gives_the_feed_not_a_negative_period(sigma, centre):
    """A Gaussian bump (a dome, a particle) of width sigma on 10 um feed marks over a 1 mm
    trace: its spectrum falls from the longest period searched like a Gaussian, whose log
    is a parabola with its vertex at zero frequency; the period is the feed, never
    negative, never the end of the range."""
    dx = 1e-3
    x = np.arange(1000) * dx
    z = 1e-4 * np.exp(-0.5 * ((x - centre) / sigma) ** 2) + 1e-7 * np.sin(2 * np.pi * x / 0.01)
    p = dominant_periods(z, spacing=dx)
    assert p["period_mm"] == pytest.approx(0.01, rel=1e-3)
    assert p["rises_to"] == "longest" and "longest period searched" in p["note"]


def test_a_map_with_a_dome_gives_a_positive_period():
    """The same on a map: a Gaussian dome on concentric 20 um turning marks."""
    px = 1e-3
    yy, xx = np.mgrid[0:256, 0:256] * px
    r = np.hypot(xx + 0.2, yy - 0.05)
    z = 2e-4 * np.exp(-0.5 * ((xx - 0.128) ** 2 + (yy - 0.128) ** 2) / 0.02 ** 2) \
        + _cusps(r, 0.02)
    p = map_periods(z, pixel=px)
    assert p["period_mm"] == pytest.approx(0.02, rel=0.03)


def test_no_peak_in_the_range_is_no_period():
    """A bump alone (no marks) holds no period between 4 samples and a quarter of the
    trace: none, with why, rather than a number."""
    dx = 1e-3
    x = np.arange(1000) * dx
    z = np.exp(-0.5 * ((x - 0.5) / 0.3) ** 2)
    p = dominant_periods(z, spacing=dx)
    if p["period_mm"] is not None:  # a side lobe of the window may make a tiny peak
        assert p["period_mm"] > 0 and p["fraction"] < 1e-3
    assert "longest period searched" in p["note"]


# -- the end of the range searched ------------------------------------------------------------

def _bowl_with_marks(tmp_path, radius_mm):
    """A 0.2 mm map: a spherical bowl of ``radius_mm`` (form a plane does not remove) and
    sinusoidal feed marks of 10 um, 10 nm amplitude, saved as .npy."""
    px = 1e-3
    yy, xx = np.mgrid[0:200, 0:200] * px
    z = ((xx - 0.1) ** 2 + (yy - 0.1) ** 2) / (2 * radius_mm) \
        + 1e-5 * np.sin(2 * np.pi * xx / 0.01)
    np.save(tmp_path / "bowl.npy", z)
    (tmp_path / "bowl.json").write_text(json.dumps({"pixel_mm": px, "units": "mm"}))
    return tmp_path / "bowl.npy"


def test_form_left_over_is_not_reported_as_a_period(tmp_path):
    """A bowl of 1 mm radius under 10 um marks, a plane removed: the spectrum rises to the
    longest period searched (50 um, a quarter of the field); the period reported is the
    marks' and the summary says the form is left over; with a parabola removed the note
    goes."""
    src = _bowl_with_marks(tmp_path, 1.0)
    m = run_analyze(src, tmp_path / "plane")
    dom = m["periods"]["dominant"]
    assert dom["period_mm"] == pytest.approx(0.01, rel=0.01)
    assert "longest period searched (50 um" in dom["note"] and "--form poly2" in dom["note"]
    assert m["periods"]["search_mm"]["longest_mm"] == pytest.approx(0.05)
    row = dict(analysis_summary(m))["dominant period"]
    assert row.startswith("10") and "left over" in row and "--form poly2" in row
    m2 = run_analyze(src, tmp_path / "poly2", form="poly2")
    dom2 = m2["periods"]["dominant"]
    assert dom2["period_mm"] == pytest.approx(0.01, rel=0.01) and "note" not in dom2


def test_a_flat_map_of_marks_has_no_note(tmp_path):
    """A bowl too shallow to matter: the marks, and nothing said about the range."""
    m = run_analyze(_bowl_with_marks(tmp_path, 1e4), tmp_path / "a")
    dom = m["periods"]["dominant"]
    assert dom["period_mm"] == pytest.approx(0.01, rel=0.01) and "note" not in dom


# -- through the spindle axis ---------------------------------------------------------------------

def _through_axis(x, c, feed_axis, feed_edge, reach):
    """A trace through the axis at ``c`` of a part turned with a feed growing linearly with
    the radius (``feed_axis`` at the axis, ``feed_edge`` at ``reach``): mirror-symmetric."""
    r = np.abs(x - c)
    k = (feed_edge - feed_axis) / reach
    feed = feed_axis + k * r
    revs = np.log(feed / feed_axis) / k  # the integral of dr / feed(r)
    return -(R_TOOL - np.sqrt(R_TOOL * R_TOOL - (((revs % 1.0) - 0.5) * feed) ** 2))


def _unmirrored(x, c, feed_left, feed_right, bow):
    """An even bow about ``c`` (mirror-symmetric, and much larger than the marks) with
    different feed marks on each side: not a trace through any axis."""
    marks = np.where(x < c, _cusps(x, feed_left), _cusps(x, feed_right))
    return bow * ((x - c) / (x[-1] - x[0])) ** 4 + marks


def test_a_mirrored_turned_trace_is_through_the_axis():
    dx = 0.5e-3
    x = np.arange(2000) * dx
    c = 0.537
    out = profile_periods(x, _through_axis(x, c, 0.02, 0.024, 0.6), spacing=dx)
    ta = out["through_axis"]
    assert ta["centre_mm"] == pytest.approx(c, abs=2 * dx)
    assert ta["left"]["period_mm"] == pytest.approx(ta["right"]["period_mm"], rel=0.1)
    assert 0.02 < ta["left"]["period_mm"] < 0.024


def test_a_symmetric_bow_with_unlike_arms_is_not_through_the_axis(tmp_path):
    """The bow makes the trace mirror-symmetric (correlation above 0.5) about its vertex,
    but the arms carry marks of 9 and 2 um: not a trace through the axis, and the report
    says why."""
    dx = 0.5e-4
    x = np.arange(3000) * dx
    c = 0.0711
    z = _unmirrored(x, c, 0.009, 0.002, 2e-4)
    out = profile_periods(x, z, spacing=dx)
    assert out["mirror"]["symmetry"] >= 0.5  # the bow is mirror-symmetric ...
    assert "through_axis" not in out  # ... but the arms are not alike
    assert out["mirror"]["through_axis"] is False
    assert "periods differ" in out["mirror"]["why"]
    m = run_analyze(_write_profile(tmp_path / "bow.csv", x, z), tmp_path / "a")
    assert "through_axis" not in m["periods"]
    assert m["periods"]["mirror"]["through_axis"] is False
    assert dict(analysis_summary(m))["through the axis"].startswith("no: ")


def test_the_same_bow_with_alike_arms_is_through_the_axis():
    """The control: the same bow with 9 um marks mirrored about its vertex."""
    dx = 0.5e-4
    x = np.arange(3000) * dx
    c = 0.0711
    marks = _cusps(np.abs(x - c) + 0.0045, 0.009)
    z = 2e-4 * ((x - c) / (x[-1] - x[0])) ** 4 + marks
    out = profile_periods(x, z, spacing=dx)
    ta = out["through_axis"]
    assert ta["centre_mm"] == pytest.approx(c, abs=2 * dx)
    for side in ("left", "right"):
        assert ta[side]["period_mm"] == pytest.approx(0.009, rel=0.05)


# -- the figure's title -------------------------------------------------------------------------------

def test_the_profile_figure_title_fits(tmp_path, monkeypatch):
    """A real slice's title (file name, points, spacing, Ra, Rq, Rz, the cut-offs and
    what chose them) lies inside the figure."""
    from render_inspect.report import _profile_figs

    figs = []
    real_png = _profile_figs._to_png

    def keep(fig, **kw):
        png = real_png(fig, **kw)
        figs.append(fig)
        return png

    monkeypatch.setattr(_profile_figs, "_to_png", keep)
    dx = 0.8712e-3
    x = np.arange(1143) * dx
    src = _write_profile(tmp_path / "1021-WLI-2D.csv", x, _through_axis(x, 0.536, 0.04, 0.04001,
                                                                        0.6))
    run_analyze(src, tmp_path / "a")
    fig = figs[-1]
    title = fig._suptitle
    bb = title.get_window_extent(fig.canvas.get_renderer())
    assert len(title.get_text()) > 120  # the whole title, not cut short
    assert bb.x0 >= 0 and bb.x1 <= fig.bbox.width and bb.y1 <= fig.bbox.height


# -- the real files the defects were seen on ------------------------------------------------------

def test_real_map_period_is_positive_and_inside_the_range(tmp_path):
    """A 160 um white-light map whose spectrum falls from the longest period searched
    (40 um) almost as a Gaussian: the period reported lies inside the range."""
    m = run_analyze(real_file("more", "st_nms-2.nms"), tmp_path / "a")
    dom, rng = m["periods"]["dominant"], m["periods"]["search_mm"]
    assert dom["period_mm"] is None or rng["shortest_mm"] < dom["period_mm"] < rng["longest_mm"]
    assert "longest period searched" in dom["note"]


def test_real_stylus_trace_with_unlike_arms_is_not_through_the_axis(tmp_path):
    """The 50 um Dektak trace (Ra 0.27 nm) is mirror-symmetric about 35.6 um at long
    wavelengths, but its arms show no common period."""
    m = run_analyze(real_file("more", "st_opdx-3.opdx"), tmp_path / "a")
    assert "through_axis" not in m["periods"]
    assert m["periods"]["mirror"]["symmetry"] > 0.9
    assert m["periods"]["mirror"]["through_axis"] is False
    dom = m["periods"]["dominant"]
    assert dom["period_mm"] is None or dom["period_mm"] < m["periods"]["search_mm"]["longest_mm"]


@pytest.mark.parametrize("name,centre_mm", [("1021-WLI-2D.csv", 0.536), ("1022-WLI-2D.csv", 0.493),
                                            ("1023-WLI-2D.csv", 0.482), ("1016-WLI-2D.csv", 0.421)])
def test_real_turned_slices_stay_through_the_axis(name, centre_mm):
    """The four white-light slices through the spindle axis: found through it, at the
    centres the docs give, with the arms' periods within the tolerance."""
    from render_inspect.io import read_profile

    p = read_profile(real_file("turned", name), units="um")
    out = profile_periods(p.x, p.z, spacing=p.spacing)
    ta = out["through_axis"]
    assert ta["centre_mm"] == pytest.approx(centre_mm, abs=0.002)
    assert ta["left"]["period_mm"] == pytest.approx(ta["right"]["period_mm"], rel=0.05)


@pytest.mark.parametrize("period_mm", [1.0, 0.95, 0.004])
def test_a_trace_of_four_periods_or_of_four_samples_a_period_is_found(period_mm):
    """The range's end bins are peaks when the spectrum falls beyond them: a trace of
    exactly four periods, or marks of four samples, are periods, not the range's end."""
    x = np.arange(4000) * 0.001
    r = dominant_periods(np.sin(2 * np.pi * x / period_mm), spacing=0.001)
    assert r["period_mm"] == pytest.approx(period_mm, rel=0.01) and r["note"] is None


# -- a weak period -------------------------------------------------------------------------

@pytest.mark.parametrize("radius_mm", [10.0, 30.0])
def test_a_period_under_form_beyond_the_range_is_called_weak(tmp_path, radius_mm):
    """A bowl of 10 or 30 mm radius under 10 um marks of 10 nm, a plane removed: the bowl's
    power lies at periods longer than the longest searched (50 um) and the spectrum
    falls towards that end, so nothing said it was left over, while the marks hold 0.1 %
    or 1 % of the variance.  The period is the marks' and the note calls it weak, says
    where the rest lies and asks for --form poly2; with a parabola removed the marks
    hold most of the variance and the note goes."""
    src = _bowl_with_marks(tmp_path, radius_mm)
    m = run_analyze(src, tmp_path / "plane")
    dom = m["periods"]["dominant"]
    assert dom["period_mm"] == pytest.approx(0.01, rel=0.01)
    assert dom["fraction_of_variance"] < 0.05
    assert "weak period" in dom["note"] and "longer than the longest searched (50 um" in dom["note"]
    assert "--form poly2" in dom["note"]
    row = dict(analysis_summary(m))["dominant period"]
    assert "weak period" in row
    m2 = run_analyze(src, tmp_path / "poly2", form="poly2")
    dom2 = m2["periods"]["dominant"]
    assert dom2["fraction_of_variance"] > 0.5 and "note" not in dom2


def test_a_profile_under_a_cubic_is_called_weak_and_marks_alone_are_not():
    """A 1 mm profile: 10 um marks of 10 nm under a cubic of 1 um (form a parabola does not
    remove) hold 0.4 % of the variance: weak, the rest at longer periods; the marks alone
    hold nearly all of it and nothing is said."""
    x = np.arange(1000) * 1e-3
    marks = 1e-5 * np.sin(2 * np.pi * x / 0.01)
    p = dominant_periods(1e-3 * ((x - 0.5) / 0.5) ** 3 + marks, spacing=1e-3)
    assert p["period_mm"] == pytest.approx(0.01, rel=1e-3) and p["weak"]
    assert p["fraction"] < 0.01 and "weak period" in p["note"] and "longer than" in p["note"]
    q = dominant_periods(marks, spacing=1e-3)
    assert not q["weak"] and q["note"] is None


def test_random_roughness_is_weak_without_blaming_form():
    """White noise has no period: its strongest line holds a few per cent, so the note
    calls it weak, and no form is blamed (the long periods hold their share only)."""
    z = np.random.default_rng(5).normal(size=1000)
    p = dominant_periods(z, spacing=1e-3)
    assert p["weak"] and "weak period" in p["note"] and "longer than" not in p["note"]
