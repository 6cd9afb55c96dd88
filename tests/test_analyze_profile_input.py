"""What ``analyze`` says it read from a profile, as it says it of a map: the file (format,
reader, the units it declares or ``--units`` gave), the instrument the file names (or
"not stated in the file") and the profile's points, spacing, length and invalid points;
``metrics.json`` ``input`` under the keys a map's has.  Profiles written here with known
content, and a real white-light slice."""

from __future__ import annotations

import dataclasses
import io
import json
from datetime import datetime, timezone

import numpy as np
import pytest
from conftest import real_file

from render_inspect.cli import main as cli_main
from render_inspect.report import analysis_summary

NOT_STATED = "not stated in the file"


def _text_profile(path, *, n: int, step_um: float, holes: list[int]) -> None:
    """A cusp profile (heights in nm, positions in um, both said in the header) with the
    heights of the rows ``holes`` left empty."""
    x = np.arange(n) * step_um
    z = 40.0 * np.cos(2 * np.pi * x / 25.0)
    lines = ["position (um), height (nm)"]
    lines += [f"{xv:.6f}," + ("" if i in holes else f"{zv:.6f}")
              for i, (xv, zv) in enumerate(zip(x, z))]
    path.write_text("\n".join(lines) + "\n")


def test_a_text_profile_names_file_instrument_and_invalid_points(tmp_path, capsys):
    src = tmp_path / "trace.csv"
    holes = [3, 4, 50, 51, 52, 120, 199]
    _text_profile(src, n=200, step_um=0.5, holes=holes)
    out = tmp_path / "a"
    assert cli_main(["analyze", str(src), "--out", str(out)]) == 0
    shown = " ".join(capsys.readouterr().out.replace("│", " ").split())
    m = json.loads((out / "metrics.json").read_text())
    inp = m["input"]
    assert inp["format"] == "csv" and inp["format_name"] == "text profile export (.csv)"
    assert inp["units_in_file"] == {"position": "um", "height": "nm"}
    assert inp["units_from"] == "file" and inp["units_in_file_from"] == "the header line"
    assert inp["instrument"] == NOT_STATED and inp["instrument_fields"] == {}
    assert inp["date"] is None
    assert inp["n_invalid"] == len(holes) == m["n_points"] - m["n_measured"]
    assert m["valid_fraction"] == pytest.approx(1 - len(holes) / 200, rel=1e-12)
    rows = dict(analysis_summary(m))
    assert rows["file"] == ("text profile export (.csv), read by render_inspect; in the file: "
                            "positions um, heights nm")
    assert rows["instrument"] == NOT_STATED
    # 200 points 0.5 um apart: 99.5 um from the first to the last
    assert rows["profile"] == "200 points, spacing 0.5 um, length 0.0995 mm; 7 invalid (3.5 %)"
    for text in rows.values():
        assert text in shown


def test_units_given_with_the_option_are_said_to_be_so(tmp_path):
    src = tmp_path / "bare.txt"
    src.write_text("".join(f"{i * 2.0:g} {np.sin(i / 3.0):.6f}\n" for i in range(300)))
    out = tmp_path / "a"
    assert cli_main(["analyze", str(src), "--out", str(out), "--units", "um", "-q"]) == 0
    m = json.loads((out / "metrics.json").read_text())
    rows = dict(analysis_summary(m))
    assert rows["file"] == ("text profile export (.txt), read by render_inspect; units from "
                            "--units (the file does not state them): positions um, heights um")
    assert rows["profile"] == "300 points, spacing 2 um, length 0.598 mm; 0 invalid (0.0 %)"


def test_an_x3p_profile_names_the_instrument_of_its_record(tmp_path):
    import x3pio  # in the lock: a missing one fails
    z_m = 5e-8 * np.sin(np.arange(800) * 2 * np.pi * 0.5e-6 / 20e-6)
    meta = x3pio.Metadata.for_software("x", "1", date=datetime(2024, 5, 6, 7, 8, 9,
                                                               tzinfo=timezone.utc))
    meta = dataclasses.replace(
        meta, instrument=x3pio.Instrument(manufacturer="Taylor Hobson", model="Form Talysurf",
                                          serial="T123", version="4.1"),
        probing_system=x3pio.ProbingSystem(type=x3pio.ProbingType.CONTACTING,
                                           identification="2 um stylus"))
    buf = io.BytesIO()
    x3pio.write(buf, z_m, x_scale=0.5e-6, metadata=meta)
    src = tmp_path / "trace.x3p"
    src.write_bytes(buf.getvalue())
    out = tmp_path / "a"
    assert cli_main(["analyze", str(src), "--out", str(out), "-q"]) == 0
    m = json.loads((out / "metrics.json").read_text())
    inp = m["input"]
    assert inp["format_name"] == "ISO 25178-72 .x3p"
    assert inp["units_in_file"] == {"position": "m", "height": "m"}
    f = inp["instrument_fields"]
    assert (f["manufacturer"], f["model"], f["serial"], f["version"]) == (
        "Taylor Hobson", "Form Talysurf", "T123", "4.1")
    assert inp["instrument"].startswith("Taylor Hobson Form Talysurf, serial T123")
    assert "2 um stylus" in inp["instrument"] and inp["date"].startswith("2024-05-06")
    rows = dict(analysis_summary(m))
    assert rows["instrument"] == f"{inp['instrument']}; acquired {inp['date']}"
    assert rows["file"].startswith("ISO 25178-72 .x3p, read by x3pio")
    assert rows["profile"] == "800 points, spacing 0.5 um, length 0.3995 mm; 0 invalid (0.0 %)"


def test_a_real_white_light_slice(tmp_path, capsys):
    """The 1022 slice: 1047 rows, 96 of them without a height (an empty second column)."""
    src = real_file("turned", "1022-WLI-2D.csv")
    rows_in_file = [r.split(",") for r in src.read_text().splitlines()[1:] if r.strip()]
    empty = sum(1 for r in rows_in_file if not r[1].strip())
    out = tmp_path / "a"
    assert cli_main(["analyze", str(src), "--out", str(out), "--units", "um"]) == 0
    shown = " ".join(capsys.readouterr().out.replace("│", " ").split())
    m = json.loads((out / "metrics.json").read_text())
    assert len(rows_in_file) == m["n_points"] == 1047 and empty == m["input"]["n_invalid"] == 96
    assert m["input"]["instrument"] == NOT_STATED
    assert "file text profile export (.csv), read by render_inspect" in shown
    assert "instrument not stated in the file" in shown
    assert "profile 1047 points, spacing 0.8712 um, length 0.9112 mm; 96 invalid (9.2 %)" in shown
