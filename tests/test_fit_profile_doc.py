"""docs/fit.md and docs/validation.md show the table of ``fit`` on the real turned slices
that docs/fit_profiles.json holds (``python tools/profile_fit_numbers.py`` makes both); the
json's claims hold (the fitted feed within 2 % of the programmed one where the marks are
one family, no standard error where they are not); and the numbers the json takes from the
real files without a simulation (the programs' feed per revolution over each window, the
measured marks' period and family) are what the files give."""

from __future__ import annotations

import importlib.util
import json
import sys
from pathlib import Path

import pytest

from conftest import real_file

REPO = Path(__file__).resolve().parents[1]


def _tool():
    spec = importlib.util.spec_from_file_location("profile_fit_numbers",
                                                  REPO / "tools" / "profile_fit_numbers.py")
    mod = importlib.util.module_from_spec(spec)
    sys.modules.setdefault("profile_fit_numbers", mod)
    spec.loader.exec_module(mod)
    return mod


def _data():
    return json.loads((REPO / "docs" / "fit_profiles.json").read_text())


def test_pages_show_the_json_table():
    tool = _tool()
    table = tool.table(_data())
    for page in ("fit.md", "validation.md"):
        text = (REPO / "docs" / page).read_text()
        i, j = text.index(tool.BEGIN), text.index(tool.END)
        assert text[i + len(tool.BEGIN):j].strip() == table.strip(), (
            f"docs/{page}: the table differs from docs/fit_profiles.json (python "
            f"tools/profile_fit_numbers.py --docs rewrites it)")


def test_fitted_feed_within_two_percent_where_one_family_and_no_number_where_not():
    """What the pages say of the json: the fitted feed within 2 % of the program's in the
    windows the sentence under the table lists (at least three, each with a standard
    error), none of them beyond 3 %; the windows across the axis without a number."""
    cases = _data()["cases"]
    feeds = [c for c in cases if c["free"] == "process.feed_mm_per_min"]
    one = [c for c in feeds if c["one_family"] and c.get("feed_difference") is not None]
    within = [c for c in one if abs(c["feed_difference"]) <= 0.02]
    assert len(within) >= 3, one
    for c in one:
        assert c["fitted_feed_stderr_um"] is not None, c
        assert abs(c["feed_difference"]) <= 0.03, c
    axis = [c for c in feeds if c["through_axis"]]
    assert axis and all(not c["one_family"] and c["stderr"] is None for c in axis)


def test_json_numbers_from_the_real_files():
    """The programmed feed per revolution and the measured window's period and family, as
    the tool takes them (no simulation)."""
    real_file("turned", "1021-WLI-2D.csv")
    tool = _tool()
    from render_inspect.fit._profile import ProfileSpec, make_profile_target, profile_family
    from render_inspect.io import read_profile
    from render_inspect.pipeline._fit_profile import _axis_in_window, profile_window

    for c in _data()["cases"]:
        prof = read_profile(real_file("turned", f"{c['part']}-WLI-2D.csv"), units="um")
        scene = tool._scene(c["part"], c["program"], c["free"])
        win = profile_window(prof, scene, at=(c["centre_mm"], 0.0), window_mm=c["window_mm"])
        t = make_profile_target(prof.z[win["i0"]:win["i1"]], spacing=prof.spacing, lag=0,
                                spec=ProfileSpec())
        assert 1e3 / t.peak == pytest.approx(c["measured_period_um"], rel=1e-9)
        fam = profile_family(t.z, prof.spacing,
                             axis_at_mm=_axis_in_window(scene, win, 1.0 / t.peak))
        assert fam["one_family"] == c["one_family"], (c["part"], fam)
        if c["programmed_feed_um"] is not None:
            # the radii the window's measured samples cover, the mirror centre on the axis
            r0, r1 = c["radii_mm"]
            assert tool.window_radii(prof, scene, win) == pytest.approx([r0, r1], abs=1e-12)
            assert tool.program_feed(c["part"], r0, r1) * 1e3 == pytest.approx(
                c["programmed_feed_um"], rel=1e-9)
            if c.get("fitted_feed_um"):
                assert c["feed_difference"] == pytest.approx(
                    c["fitted_feed_um"] / c["programmed_feed_um"] - 1, rel=1e-9)


def test_fit_page_shows_the_checks_of_the_json():
    """The checks under the table (the programmed step weighted as the fit reads the window,
    the marks' period on the line's other arm) are the json's."""
    tool = _tool()
    data = _data()
    assert data.get("checks"), "docs/fit_profiles.json has no checks (tool --checks)"
    text = (REPO / "docs" / "fit.md").read_text()
    i, j = text.index(tool.CHECKS_BEGIN), text.index(tool.CHECKS_END)
    assert text[i + len(tool.CHECKS_BEGIN):j].strip() == tool.checks_table(data["checks"]).strip()


def test_checks_from_the_real_files():
    """The checks recomputed from the slices and programs equal the json's; the weighted
    step equals the plain one where the program's step is constant, and stays within 1 %
    of it in these windows."""
    real_file("turned", "1023-WLI-2D.csv")
    tool = _tool()
    data = _data()
    again = tool.arm_checks(data)
    assert len(again) == len(data["checks"])
    for new, old in zip(again, data["checks"]):
        for k, v in old.items():
            if isinstance(v, float):
                assert new[k] == pytest.approx(v, rel=1e-9), (old["part"], k)
            else:
                assert new[k] == v, (old["part"], k)
        assert abs(new["programmed_feed_weighted_um"] / new["programmed_feed_um"] - 1) < 0.01
    assert tool.program_feed("1016", 0.2, 0.4, "hann") == tool.FEED_1016


def test_fit_page_shows_the_scan_and_it_is_what_the_files_give():
    """The windows moved along both arms of the scanned slice: the page's table is the
    json's, and the json's numbers are what the slice and its program give."""
    tool = _tool()
    data = _data()
    scan = data["scan"]
    text = (REPO / "docs" / "fit.md").read_text()
    i, j = text.index(tool.SCAN_BEGIN), text.index(tool.SCAN_END)
    assert text[i + len(tool.SCAN_BEGIN):j].strip() == tool.scan_table(scan["part"],
                                                                       scan["rows"]).strip()
    real_file("turned", f"{scan['part']}-WLI-2D.csv")
    again = tool.period_scan(scan["part"], scan["window_mm"])
    assert [r["radii_mm"] for r in again] == [r["radii_mm"] for r in scan["rows"]]
    for new, old in zip(again, scan["rows"]):
        for arm in ("minus", "plus"):
            if old[arm] is None:
                assert new[arm] is None, (new["radii_mm"], arm)
            else:
                assert new[arm] == pytest.approx(old[arm], abs=1e-9), (new["radii_mm"], arm)


def test_fit_page_shows_the_arms_of_the_json_and_their_uncertainty():
    """The windows fitted on both arms of the slice: the page's table is the json's; each
    keeps its one-arm fit beside it; the standard error is the fit's and the arms' term in
    quadrature, the arms' term the excess of their difference over its standard error."""
    import math

    tool = _tool()
    data = _data()
    text = (REPO / "docs" / "fit.md").read_text()
    i, j = text.index(tool.ARMS_BEGIN), text.index(tool.ARMS_END)
    assert text[i + len(tool.ARMS_BEGIN):j].strip() == tool.arms_table(data).strip()
    both = [c for c in data["cases"] if c.get("arms") == "both"]
    assert both, "no window of the json is fitted on both arms"
    for c in both:
        a = c["arms_detail"]
        assert c["one_arm"]["fitted_feed_um"] is not None, c["part"]
        if a.get("window_arm") is None or a["stderr"] is None:
            continue
        d = a["window_arm"] - a["other_arm"]
        u_d = math.hypot(a["window_arm_stderr"], a["other_arm_stderr"])
        assert a["u_arms"] == pytest.approx(math.sqrt(max(0.0, d * d - u_d * u_d)) / 2,
                                            rel=1e-6, abs=1e-12)
        assert a["stderr"] == pytest.approx(math.hypot(a["stderr_fit"], a["u_arms"]), rel=1e-6)
        assert c["fitted_feed_stderr_um"] == pytest.approx(a["stderr"], rel=1e-6)
        assert a["disagree"] == (abs(d) > 2 * u_d)


def _same_numbers(new, old, where="slices"):
    """``new`` has the structure, texts and integers of ``old`` and its floats to 1e-9
    (the last bits of the periods' least squares differ between processors)."""
    if isinstance(old, dict):
        assert isinstance(new, dict) and new.keys() == old.keys(), where
        for k in old:
            _same_numbers(new[k], old[k], f"{where}.{k}")
    elif isinstance(old, list):
        assert isinstance(new, list) and len(new) == len(old), where
        for i, (a, b) in enumerate(zip(new, old)):
            _same_numbers(a, b, f"{where}[{i}]")
    elif isinstance(old, float):
        assert new == pytest.approx(old, rel=1e-9, abs=1e-12), where
    else:
        assert new == old, where


def test_fit_page_shows_the_slices_and_they_are_what_the_files_give():
    """The table of the real slices (each side of the mirror in two halves: the radii, the
    program's feed over them, the marks' period there) is the json's, and the json's
    numbers are what the slices and programs give; the program's feed over a half lies
    within its pointwise steps there."""
    tool = _tool()
    data = _data()
    text = (REPO / "docs" / "fit.md").read_text()
    i, j = text.index(tool.SLICES_BEGIN), text.index(tool.SLICES_END)
    assert text[i + len(tool.SLICES_BEGIN):j].strip() == tool.slices_table(data["slices"]).strip()
    real_file("turned", "1022-WLI-2D.csv")
    _same_numbers(tool.slices(), data["slices"])
    from render_inspect.io import read_program
    from render_inspect.processes import feed_per_rev

    for row in data["slices"]:
        if row["part"] not in tool.PROGRAMS:
            continue
        r, f = feed_per_rev(read_program(real_file("turned", tool.PROGRAMS[row["part"]]),
                                         part_radius=1.1).program)
        for side in row["sides"]:
            for h in side["halves"]:
                r0, r1 = h["radii_mm"]
                sel = (r >= r0) & (r <= r1)
                assert f[sel].min() * 1e3 <= h["programmed_feed_um"] <= f[sel].max() * 1e3
