"""docs/validation.md says what docs/validation.json holds: every marked span
(``<!-- n:KEY -->TEXT<!-- /n -->``) is the json's text (fast).  ``python
tools/validation_numbers.py`` makes both from the published programs and measured slices.
The band parameters the script takes are checked on a profile with a known answer."""

from __future__ import annotations

import importlib.util
import math
import sys
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]


def _tool():
    spec = importlib.util.spec_from_file_location("validation_numbers",
                                                  REPO / "tools" / "validation_numbers.py")
    mod = importlib.util.module_from_spec(spec)
    sys.modules.setdefault("validation_numbers", mod)
    spec.loader.exec_module(mod)
    return mod


def test_every_marked_number_is_the_runs():
    tool = _tool()
    data = tool.load()
    assert data["numbers"], "docs/validation.json holds no number: run tools/validation_numbers.py"
    quoted = tool._docs_numbers().spans(tool.VALIDATION_MD.read_text())
    assert len(quoted) >= 20, "docs/validation.md marks (almost) no number"
    bad = tool.check(data)
    assert not bad, "\n".join(bad) + "\n(python tools/validation_numbers.py --docs rewrites them)"


def test_validation_doc_is_not_docs_numbers():
    """docs/validation.md's spans are the validation script's, not docs/numbers.json's."""
    tool = _tool()
    dn = tool._docs_numbers()
    assert tool.VALIDATION_MD not in dn.doc_files()
    assert not set(tool.load()["numbers"]) & set(dn.load_numbers()["numbers"])


def test_band_parameters_of_a_sine():
    """A sine of amplitude A and period L on both sides of an axis: Ra = 2A/pi,
    Rq = A/sqrt(2), Rt = 2A, Rsk = 0, Rku = 1.5, RSm = L, in any band of whole periods."""
    tool = _tool()
    spacing, amp, period = 0.0005, 200e-6, 0.04   # mm: 0.5 um steps, 200 nm, 40 um
    axis = 0.5
    s = np.arange(0, 1.0 + spacing / 2, spacing)
    r = amp * np.sin(2 * np.pi * (s - axis) / period)
    got = tool.band_parameters(s, r, np.ones(s.size, bool), axis_mm=axis, band_um=(20.0, 420.0),
                               spacing=spacing)
    assert math.isclose(got["Ra_nm"], 2 * 200 / math.pi, rel_tol=2e-3)
    assert math.isclose(got["Rq_nm"], 200 / math.sqrt(2), rel_tol=2e-3)
    assert math.isclose(got["Rt_nm"], 400, rel_tol=1e-3)
    assert abs(got["Rsk"]) < 1e-2
    assert math.isclose(got["Rku"], 1.5, rel_tol=5e-3)
    assert math.isclose(got["RSm_um"], 40.0, rel_tol=1e-3)
    # outside the evaluation length nothing is counted
    ev = np.abs(s - axis) < 0.1
    few = tool.band_parameters(s, r, ev, axis_mm=axis, band_um=(150.0, 420.0), spacing=spacing)
    assert few["n"] == 0 and few["Ra_nm"] is None


def test_the_registration_stays_within_a_feed_period():
    """compare's registration of each real slice along the line through the spindle axis
    moves it by less than one measured feed period wherever it matches the slice at all
    (correlation over 0.5: every case, the CSI images and, where the PSI image failed its
    check, the cut as the instrument sees it): a match whole periods away is not taken."""
    data = _tool().load()
    checked = 0
    for part, rows in data["table"].items():
        for r in rows:
            if r["correlation"] <= 0.5:
                continue
            period_um = r["bands"]["measured"]["outer"]["RSm_um"]
            assert abs(r["shift_um"]) <= 1.05 * period_um, (part, r["objective"], r["mode"],
                                                             r["shift_um"], period_um)
            checked += 1
    # every case of the three parts: 8 cuts, 2 objectives, 2 modes
    assert checked == sum(len(rows) for rows in data["table"].values()) == 3 * 8 * 2 * 2, checked


def test_the_headings_give_what_the_programs_command():
    """Each part's heading quotes its program's feed per revolution over the two bands'
    radii and its least and largest step point by point, as marked numbers that are what
    the program files give today (``feed_over_radii`` and ``feed_per_rev`` of the program
    as ``read_program`` reads it), not a summary copied from elsewhere."""
    from conftest import real_file

    tool = _tool()
    data = tool.load()["numbers"]
    doc = tool.VALIDATION_MD.read_text()
    for part, (program, _slice) in tool.PARTS.items():
        real_file("turned", program)
        got = tool.program_numbers(part)
        assert len(got) == 4
        fmt = tool._docs_numbers().fmt
        for key, (value, spec) in got.items():
            assert key in data, f"{key} is not in docs/validation.json"
            assert data[key]["text"] == fmt(value, spec), (key, data[key]["text"], value)
        heading = next(line for line in doc.splitlines() if line.startswith(f"### Part {part} "))
        for key in got:
            assert f"<!-- n:{key} -->" in heading, (part, key, heading)


def test_registration_is_compares():
    """Each row records the registration ``compare`` makes: against the virtual
    measurement where that follows the cut, against the cut as the instrument sees it
    where it failed its check (then the shift against the failed image is kept beside
    it); a registration is reliable exactly when it beats the surrogates' level."""
    data = _tool().load()
    assert data["table"]
    for part, rows in data["table"].items():
        for r in rows:
            failed = r["virtual_measurement"] == "failed"
            assert r["against"] == ("cut_as_seen" if failed else "virtual_measurement"), (part, r)
            if not failed:
                assert r["image_shift_um"] == r["shift_um"]
                assert r["image_correlation"] == r["correlation"]
            null = r["null_correlation"]
            assert r["reliable"] == (null is None or r["correlation"] > null), (part, r)


def test_the_numbers_are_the_tables():
    """Every number in docs/validation.json is what the runs' table there and the program
    files give (``--renumber``): none edited by hand, none left from an older summing-up."""
    from conftest import real_file

    tool = _tool()
    for program, _slice in tool.PARTS.values():
        real_file("turned", program)
    data = tool.load()
    assert tool._formatted(tool.numbers_of(data["table"])) == data["numbers"]
