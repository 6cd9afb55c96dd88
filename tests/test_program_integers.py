"""Numbers without a decimal point (``process.program_integers``): one program written
with decimals and again in least input increments (IS-B, IS-C, inch IS-B) gives the same
path read with the matching setting; a program that mixes them is said once, naming the
word; a path beyond the part written without points names the increment systems that
bring it in; F without a point under an increment system, and a bad setting, are one
line; the project's own programs are read as written."""

from __future__ import annotations

import json

import numpy as np
import pytest

from render_inspect.cli import main
from render_inspect.core.errors import InputError
from render_inspect.core.toolpath import ToolPath
from render_inspect.io import read_program, scan_program, write_nc

#: a lathe program: facing, an arc by centre (I K) and one by radius (R), in IS-B counts
#: (0.001 mm); each entry a block of (letter, count) words after its G codes
_BLOCKS = [("G00", [("X", 4000), ("Z", 100)]),
           ("G01", [("Z", 0)]),
           ("", [("X", 2000), ("Z", -12)]),
           ("G02", [("X", 1000), ("Z", -1012), ("I", 0), ("K", -1000)]),
           ("G03", [("X", 500), ("Z", -1512), ("R", 1000)]),
           ("G01", [("X", 0), ("W", -25)]),
           ("G00", [("Z", 5000)])]
_HEAD = "G90 G18 G95 G97 S1000\nG01 F0.005\n"


def _program(places: int | None, unit: str = "G21") -> str:
    """The program with its words as decimals (``places=None``: 3 places, as written
    by hand) or as counts of ``10**-places`` (an increment system without points)."""
    out = [f"{unit} {_HEAD}"]
    for g, words in _BLOCKS:
        text = []
        for letter, n in words:
            if places is None:
                text.append(f"{letter}{n / 1000:.3f}")
            else:
                text.append(f"{letter}{n * 10 ** (places - 3)}")
        out.append(" ".join([g] * bool(g) + text) + "\n")
    return "".join(out) + "M30\n"


def _write(tmp_path, name, text):
    p = tmp_path / name
    p.write_text(text)
    return p


def _read(tmp_path, name, text, **kw):
    p = tmp_path / name
    p.write_text(text)
    kw.setdefault("x_mode", "radius")
    kw.setdefault("points_per_rev", 36)
    return read_program(p, **kw)


def _same(a, b):
    for k in ("theta", "rho", "z", "t"):
        assert np.array_equal(getattr(a.program, k), getattr(b.program, k)), k


@pytest.mark.parametrize("system, places", [("IS-B", 3), ("IS-C", 4), ("IS-E", 6)])
def test_increments_read_as_the_decimals(tmp_path, system, places):
    """The program in counts of the increment system, read with it, is the program
    written with decimals, to the last bit: each number is an integer over a power of
    ten either way (X2000 / 10^3 and X2.000 = 2000 / 10^3; X20000 / 10^4 is the same
    rational, correctly rounded alike)."""
    plain = _read(tmp_path, "plain.nc", _program(None))
    counts = _read(tmp_path, "counts.nc", _program(places), integers=system)
    _same(plain, counts)
    assert plain.program.rho.max() == 4.0 and plain.program.z.min() == pytest.approx(-1.537)
    assert "integers" not in plain.inferred and "warnings" not in plain.facts
    assert counts.inferred["integers"].startswith(f"integers as {system} increments")
    assert counts.facts["integers"] == system
    # read whole (the default), the same counts are a path a thousand times and more too
    # large
    whole = scan_program(tmp_path / "counts.nc")
    assert np.nanmax(whole.axes["X"]) == 4.0 * 10 ** places
    assert whole.decimals["without"] == 12 and whole.decimals["with"] == 0


def test_inch_increments_and_metric(tmp_path):
    """Inch IS-B counts 0.0001 in: the inch program without points is the inch program
    with points to the last bit, and the metric program of the same path (each number
    times 25.4) to the rounding of the conversion."""
    def inch(places):
        return _program(places, "G20").replace("F0.005", "F0.0002")
    with_points = _read(tmp_path, "in.nc", inch(None))
    counts = _read(tmp_path, "in_counts.nc", inch(4), integers="IS-B")
    _same(with_points, counts)
    assert "0.0001 in" in counts.inferred["integers"]
    metric = f"G21 {_HEAD}".replace("F0.005", f"F{0.0002 * 25.4!r}") + "".join(
        " ".join([g] * bool(g) + [f"{k}{n / 1000 * 25.4!r}" for k, n in words]) + "\n"
        for g, words in _BLOCKS)
    mm = _read(tmp_path, "mm.nc", metric)
    for k in ("theta", "rho", "z", "t"):
        assert np.allclose(getattr(counts.program, k), getattr(mm.program, k), rtol=1e-12,
                           atol=1e-12), k
    assert counts.program.rho.max() == pytest.approx(4 * 25.4, rel=1e-15)


def test_angles_count_increments_too(tmp_path):
    """C on IS-C counts 0.0001 deg (C5000 is 0.5 deg), X 0.0001 mm: a point list in
    counts is the point list in degrees and mm, to the last bit."""
    deg = "".join(f"C{k * 0.5:.3f} X{1 - k * 1e-4:.4f} Z0.\n" for k in range(1, 720))
    cnt = "".join(f"C{k * 5000} X{10000 - k} Z0\n" for k in range(1, 720))
    a = _read(tmp_path, "deg.nc", deg, part_radius=1.0)
    b = _read(tmp_path, "cnt.nc", cnt, part_radius=1.0, integers="IS-C")
    _same(a, b)
    assert b.program.theta[-1] == pytest.approx(np.radians(359.5), rel=1e-12)
    assert b.dialect == "point list"


def test_raster_program_in_increments(tmp_path):
    """An X-Y-Z raster program (sculpturing) in IS-A counts (0.01 mm), with an arc in
    G17: the program written with decimals, to the last bit."""
    words = [("G00", "X0 Y0 Z100"), ("G01 F60.", "Z0"), ("", "Y200"), ("G02", "X50 Y250 I50 J0"),
             ("G00", "Z100"), ("", "X50 Y0"), ("G01", "Z-10"), ("", "Y200")]

    def text(dec):
        out = []
        for g, w in words:
            w = " ".join(f"{x[0]}{int(x[1:]) / 100:.2f}" if dec else x for x in w.split())
            out.append(f"{g} {w}\n".lstrip())
        return "G90 G94 G21 G17\n" + "".join(out)
    a = read_program(_write(tmp_path, "dec.nc", text(True)), kind="linear")
    b = read_program(_write(tmp_path, "cnt.nc", text(False)), kind="linear", integers="IS-A")
    for k in ("x", "y", "z", "t"):
        assert np.array_equal(getattr(a.program, k), getattr(b.program, k)), k
    assert b.program.y.max() == 2.5 and "integers as IS-A" in b.inferred["integers"]


def test_mixed_program_warns_naming_the_word(tmp_path):
    text = _program(None).replace("Z5.000", "Z5")   # line 9: the retract has lost its point
    mixed = _read(tmp_path, "mixed.nc", text)
    (warning,) = mixed.facts["warnings"]
    assert warning.startswith("mixed.nc:9: Z5 has no decimal point: read as 5 mm; a "
                              "control that counts least input increments reads it as "
                              "0.005 mm (IS-B): set process.program_integers")
    assert "1 of the 12 nonzero position and angle words" in warning
    assert "whole" in mixed.inferred["integers"]
    # zeros (X0, Z0, I0) are the same either way: no warning
    zeros = _read(tmp_path, "zeros.nc", _program(None).replace("X0.000", "X0")
                  .replace("Z0.000", "Z0").replace("I0.000", "I0"))
    assert "warnings" not in zeros.facts and "integers" not in zeros.inferred
    # a dwell's X (seconds) is no position
    dwell = _read(tmp_path, "dwell.nc", _program(None).replace("M30", "G04 X2\nM30"))
    assert "warnings" not in dwell.facts


def test_beyond_the_part_names_the_increment_systems(tmp_path):
    """Every nonzero position word without a point, the path beyond the part read whole:
    the refusal says which increment systems bring it within the part."""
    with pytest.raises(InputError) as e:
        _read(tmp_path, "counts.nc", _program(3), x_mode="auto", part_radius=5.0)
    text = str(e.value)
    assert "the cutting moves reach X = 4000 mm, beyond the part" in text
    assert text.endswith("; no position word of the program has a decimal point: read in "
                         "least input increments the moves reach X = 4 mm as IS-B, X = 0.4 "
                         "mm as IS-C, within the part (set process.program_integers)")
    assert "\n" not in text
    ok = _read(tmp_path, "counts.nc", _program(3), x_mode="auto", part_radius=5.0,
               integers="IS-B")
    assert ok.program.rho.max() == 4.0
    # one word with its point: no hint (the program is not written in increments)
    mixed = _program(3).replace("Z5000", "Z5.")
    with pytest.raises(InputError) as e:
        _read(tmp_path, "mixed.nc", mixed, x_mode="auto", part_radius=5.0)
    assert "decimal point" not in str(e.value)


#: a facing program without decimal points: its head, then (unit, X of the first rapid) for
#: each section; the furthest X is that of the last section
_SECTIONS_HEAD = "G90 G18 G95 G97 S1000\nG01 F5\n"


def _sections(*sections) -> str:
    out = [_SECTIONS_HEAD]
    for unit, x in sections:
        out.append(f"{unit}\nG00 X{x} Z100\nG01 Z0\nX{x // 2} Z-12\n")
    return "".join(out) + "M30\n"


def _hint(tmp_path, name, text):
    with pytest.raises(InputError) as e:
        _read(tmp_path, name, text, x_mode="auto", part_radius=5.0)
    text = str(e.value)
    assert "\n" not in text
    return text.split("no position word of the program has a decimal point", 1)[1]


@pytest.mark.parametrize("sections, reach", [
    # metric throughout: 4000 IS-B counts of 0.001 mm
    ([("G21", 4000)], ": read in least input increments the moves reach X = 4 mm as IS-B, "
                      "X = 0.4 mm as IS-C, within the part"),
    # inch throughout: 1000 IS-B counts of 0.0001 in = 2.54 mm
    ([("G20", 1000)], ": read in least input increments the moves reach X = 2.54 mm as IS-B, "
                      "X = 0.254 mm as IS-C, within the part"),
    # inch, then the furthest move in mm: counted in mm increments
    ([("G20", 100), ("G21", 4000)], ": read in least input increments the moves reach X = 4 mm "
                                    "as IS-B, X = 0.4 mm as IS-C (the furthest move's X is "
                                    "written in mm, G21 / G71; the program switches units), "
                                    "within the part"),
    # mm, then the furthest move in inches (G70: the same as G20)
    ([("G71", 100), ("G70", 1000)], ": read in least input increments the moves reach X = "
                                    "2.54 mm as IS-B, X = 0.254 mm as IS-C (the furthest "
                                    "move's X is written in inches, G20 / G70; the program "
                                    "switches units), within the part"),
])
def test_beyond_the_part_hint_counts_in_the_furthest_moves_unit(tmp_path, sections, reach):
    """The increments the hint counts are those of the unit the furthest move's X was
    written in, not the program's other unit: a program that switches from G20 to G21 is
    not taken as inches throughout."""
    assert _hint(tmp_path, "units.nc", _sections(*sections)) == (
        reach + " (set process.program_integers)")


def test_beyond_the_part_hint_of_an_x_in_both_units(tmp_path):
    """The furthest X adds an incremental word in inches to an X written in mm: no one
    increment system's reading is the whole move; the hint says so, without numbers."""
    text = _SECTIONS_HEAD + "G21\nG00 X1000 Z100\nG01 Z0\nG20\nU1000\nX0 Z-12\nM30\n"
    assert _hint(tmp_path, "both.nc", text) == (
        ", and the furthest move's X adds incremental words written in inches and in mm: "
        "read in least input increments it may lie within the part (set "
        "process.program_integers)")
    sp = scan_program(tmp_path / "both.nc")
    assert sp.x_unit.tolist() == [0, 0, 2, 1]  # (X0: written again, in inches)


@pytest.mark.parametrize("mode, f, unit", [("G95", "5", r"mm/rev \(G95\)"),
                                           ("G94", "500", r"mm/min \(G94\)")])
def test_feed_without_point_refused_under_increments(tmp_path, mode, f, unit):
    text = _program(3).replace("G95", mode).replace("F0.005", f"F{f}")
    with pytest.raises(InputError, match=(
            rf"f.nc:2: F{f} has no decimal point: with process.program_integers = 'IS-B' .* "
            rf"write the feed with its decimal point \(F{f}\. for {f} {unit}\) in block")):
        _read(tmp_path, "f.nc", text, integers="IS-B")
    # read whole, F5 is 5 mm/rev (the default reading, as before); F5. under IS-B too
    assert _read(tmp_path, "f.nc", text).program.points > 0
    fine = _read(tmp_path, "f.nc", text.replace(f"F{f}", f"F{f}."), integers="IS-B")
    assert fine.inferred["feed"].endswith(f"{f} {unit}".replace("\\", ""))


def test_bad_setting_is_one_line(tmp_path, capsys):
    with pytest.raises(InputError, match=r"process.program_integers must be one of "
                                         r"\['whole', 'IS-A', .*received 'IS-F'"):
        _read(tmp_path, "plain.nc", _program(None), integers="IS-F")
    prog = tmp_path / "p.nc"
    prog.write_text(_program(None))
    out = tmp_path / "o"
    assert main(["toolpath", "sts_fig16_overcut", "--program", str(prog), "--set",
                 "process.program_integers=IS-F", "--out", str(out)]) == 1
    err = [s for s in capsys.readouterr().err.splitlines() if s.strip()]
    assert len(err) == 1 and "process.program_integers" in err[0] and "'IS-F'" in err[0]
    assert "'IS-B'" in err[0] and not out.exists()
    # the default is not written in a scene's dump (scenes dump, and hash, as before)
    from render_inspect.scene import load_scene
    sc = load_scene("sts_fig16_overcut", [f"process.program={json.dumps(str(prog))}"])
    assert "program_integers" not in sc.to_dict()["process"]
    sc = sc.with_overrides(["process.program_integers='IS-C'"])
    assert sc.to_dict()["process"]["program_integers"] == "IS-C"


def test_toolpath_command_says_the_reading_once(tmp_path, capsys):
    """The mixed program through ``toolpath``: the warning once, the reading in the
    summary line and in toolpath.json."""
    prog = tmp_path / "mixed.nc"
    prog.write_text(_program(None).replace("Z5.000", "Z5").replace("X4.000", "X-4."))
    out = tmp_path / "o"
    assert main(["toolpath", "sts_fig16_overcut", "--program", str(prog), "--set",
                 "process.points_per_rev=36", "--set", "process.workpiece_radius=3",
                 "--set", "process.program_x='radius'", "--out", str(out)]) == 0
    err = capsys.readouterr().err
    assert err.count("Z5 has no decimal point") == 1
    assert "integers as whole mm, inches and degrees" in err
    facts = json.loads((out / "toolpath.json").read_text())["program"]
    assert facts["integers"] == "whole"
    assert facts["warnings"][0].startswith("mixed.nc:9: Z5 has no decimal point")
    # under IS-B the program's Z5 is 0.005 mm, and the summary says so
    out2 = tmp_path / "o2"
    assert main(["toolpath", "sts_fig16_overcut", "--program", str(prog), "--set",
                 "process.points_per_rev=36", "--set", "process.workpiece_radius=3",
                 "--set", "process.program_x='radius'", "--set",
                 "process.program_integers='IS-B'", "--out", str(out2)]) == 0
    err = capsys.readouterr().err
    assert "no decimal point" in err and "warning" not in err
    assert "integers as IS-B increments (0.001 mm, 0.0001 in, 0.001 deg" in err
    assert json.loads((out2 / "toolpath.json").read_text())["program"]["integers"] == "IS-B"


def test_own_dialect_read_as_written(tmp_path):
    """The project's own programs write decimals: any setting reads them as written."""
    n = 400
    theta = np.linspace(0, 4 * np.pi, n)
    path = ToolPath(theta, np.linspace(1.0, 0.9, n), np.linspace(0, -0.001, n),
                    np.linspace(0, 2.4, n), {})
    p = write_nc(tmp_path / "own.nc", path)
    a = read_program(p)
    for system in ("IS-B", "IS-E"):
        b = read_program(p, integers=system)
        _same(a, b)
        assert "integers" not in b.inferred and "integers" not in b.facts
