"""Machine programs as controllers and CAM systems write them (Fanuc, Siemens 840D,
Precitech / Moore style): file encodings and line ends, units of the surface speed, the
spindle speed kept after G97, Fanuc lathe feed modes, C that steps backwards, the facts
the reader states.  Each program is checked against the same program written the plain
way (or against the time and angle worked out by hand), or refused with one line."""

from __future__ import annotations

import math

import numpy as np
import pytest

from render_inspect.core.errors import InputError
from render_inspect.io import read_program

#: a facing cut: 1000 rpm, 0.005 mm/rev, diameter 4 mm to the centre
_PLAIN = ("G21 G90 G18 G95 G97 S1000\nG00 X4.0 Z0.1\nG01 Z0.0 F0.005\nX0.0\nG00 Z5.0\n"
          "M30\n")


def _read(tmp_path, name, data, **kw):
    p = tmp_path / name
    p.write_bytes(data if isinstance(data, bytes) else data.encode("ascii"))
    kw.setdefault("x_mode", "diameter")
    kw.setdefault("points_per_rev", 36)
    return read_program(p, **kw)


def _same(a, b):
    for k in ("theta", "rho", "z", "t"):
        assert np.array_equal(getattr(a.program, k), getattr(b.program, k)), k


# ---------------------------------------------------------------------------- the file
@pytest.mark.parametrize("name, data", [
    ("bom.nc", b"\xef\xbb\xbf" + _PLAIN.encode()),
    ("crlf.nc", _PLAIN.replace("\n", "\r\n").encode()),
    ("cr.nc", _PLAIN.replace("\n", "\r").encode()),
    ("utf8_comment.nc", "(\u00d8 4 mm, 20 \u00b0C)\n".encode("utf-8") + _PLAIN.encode()),
    ("latin1_comment.nc", "; \u00d8 4 mm\n".encode("latin-1") + _PLAIN.encode()),
    ("lower_tabs.nc", _PLAIN.lower().replace(" ", "\t").encode()),
    ("no_last_break.nc", _PLAIN.rstrip("\n").encode()),
])
def test_encodings_and_line_ends_read_as_plain(tmp_path, name, data):
    """A byte order mark, CR LF or CR line ends, text in comments that is not ASCII (the
    degree and diameter signs of a Windows editor), lower case and tabs: the same path."""
    plain = _read(tmp_path, "plain.nc", _PLAIN)
    other = _read(tmp_path, name, data)
    _same(plain, other)
    # 2 mm radius at 0.005 mm/rev: 400 revolutions, 20 for the 0.1 mm plunge: 25.2 s at
    # 1000 rpm
    assert plain.program.rho.max() == 2.0
    assert plain.program.t[np.flatnonzero(plain.motion == 1)[-1]] == pytest.approx(25.2, rel=1e-12)


def test_text_outside_comments_still_ascii(tmp_path):
    with pytest.raises(InputError, match=r"bad.nc:2: a byte that is not ASCII text outside a "
                                         r"comment"):
        _read(tmp_path, "bad.nc", "G21\nG01 X\u00b04 Z0\n".encode("utf-8"))


# ---------------------------------------------------------------------------- spindle
def test_constant_surface_speed_in_inches_is_feet_per_minute(tmp_path):
    """G20 G96 S100: 100 ft/min = 30.48 m/min, the same program as G21 G96 S30.48."""
    inch = ("G20 G90 G18 G95 G96 S100\nG50 S3000\nG00 X0.2 Z0.004\nG01 Z0.0 F0.001\nX0.0\n")
    metric = (f"G21 G90 G18 G95 G96 S{100 * 12 * 25.4 / 1000!r}\nG50 S3000\n"
              f"G00 X{0.2 * 25.4!r} Z{0.004 * 25.4!r}\nG01 Z0.0 F{0.001 * 25.4!r}\nX0.0\n")
    a = _read(tmp_path, "inch.nc", inch, x_mode="radius")
    b = _read(tmp_path, "mm.nc", metric, x_mode="radius")
    for k in ("theta", "rho", "z", "t"):
        assert np.allclose(getattr(a.program, k), getattr(b.program, k), rtol=1e-12, atol=1e-12)
    # by hand: 30.48 m/min reaches the 3000 rpm clamp at r = 30480 / (2 pi 3000) mm; the
    # feed per revolution holds, so the time is the integral of dr / (f rpm(r))
    f, v, clamp, r0 = 0.0254, 30480.0, 3000.0, 5.08
    rc = v / (2 * math.pi * clamp)
    t_face = (math.pi * (r0 ** 2 - rc ** 2) / (f * v) + rc / (f * clamp)) * 60
    t_plunge = 0.1016 / f / (v / (2 * math.pi * r0)) * 60
    assert a.program.t[-1] == pytest.approx(t_face + t_plunge, rel=1e-3)
    assert "S 30.48 m/min" in a.inferred["spindle"]


def test_g97_without_s_keeps_the_speed_of_the_switch(tmp_path):
    """G96 S100 (m/min) at diameter 4 mm is 7958 rpm, clamped to 3000: G97 without S keeps
    3000 rpm (as the controller does), not 100 rpm."""
    held = ("G21 G90 G18 G94 F10\nG96 S100\nG50 S3000\nG00 X4.0 Z0.1\nG01 Z0.0\nG97\nX2.0\n")
    told = ("G21 G90 G18 G94 F10\nG96 S100\nG50 S3000\nG00 X4.0 Z0.1\nG01 Z0.0\nG97 S3000\n"
            "X2.0\n")
    a, b = _read(tmp_path, "held.nc", held), _read(tmp_path, "told.nc", told)
    _same(a, b)
    assert "keeps the speed it had under G96 at the switch (3000 rpm)" in a.inferred["spindle"]
    # the last move: 1 mm of radius at 10 mm/min, 6 s at 3000 rpm = 300 revolutions
    last = a.motion == 1
    revs = (a.program.theta[-1] - a.program.theta[np.flatnonzero(a.program.rho == 2.0)[-1]])
    assert revs / (2 * math.pi) == pytest.approx(300.0, rel=1e-9)
    assert last.any()


# ---------------------------------------------------------------------------- feed modes
def test_fanuc_system_a_feed_modes(tmp_path):
    """G98 / G99 (Fanuc lathe G-code system A) are G94 / G95."""
    a = _read(tmp_path, "a.nc", _PLAIN.replace("G95", "G99") + "")
    b = _read(tmp_path, "b.nc", _PLAIN)
    _same(a, b)
    c = _read(tmp_path, "c.nc", "G21 G98 G97 S600 F10\nG00 X4 Z0.1\nG01 Z0\nX0\n")
    d = _read(tmp_path, "d.nc", "G21 G94 G97 S600 F10\nG00 X4 Z0.1\nG01 Z0\nX0\n")
    _same(c, d)


def test_fanuc_system_a_cycle_refused(tmp_path):
    text = "G21 G99 G97 S1000\nG00 X4.0 Z0.1\nG90 X3.0 Z-2.0 F0.01\n"
    with pytest.raises(InputError, match=r"cyc.nc:3: G90 / G94 with axis words in a program "
                                         r"with G98 / G99 .* turning / facing cycle"):
        _read(tmp_path, "cyc.nc", text)
    # without G98 / G99 (system B / C) G90 with axis words is the absolute mode and a move
    b = _read(tmp_path, "b.nc", "G21 G95 G97 S1000\nG00 X4.0 Z0.1\nG90 G01 Z0 F0.01\nX0\n")
    assert b.program.rho[-1] == 0.0


# ---------------------------------------------------------------------------- C
def _point_list(c):
    x = 1.0 - np.arange(c.size) / 36000
    return "".join(f"C{ci:.3f} X{xi:.6f} Z0.0\n" for ci, xi in zip(c, x))


def test_c_stepping_back_a_little_is_refused(tmp_path):
    """A step back of 0.2 deg is the spindle turning backwards, not 359.8 deg forwards
    (which would add a revolution); a step back of 359 deg is a new revolution."""
    c = np.arange(721) * 1.0
    ok = _read(tmp_path, "ok.nc", _point_list(c % 360), spindle_rpm=60.0, x_mode="radius")
    assert ok.program.revolutions == pytest.approx(2.0)
    c[100] = c[99] - 0.2
    with pytest.raises(InputError, match=r"back.nc:101: C decreases by 0.2 deg \(C99 to C98.8\)"):
        _read(tmp_path, "back.nc", _point_list(c % 360), spindle_rpm=60.0, x_mode="radius")


def test_c_in_plus_minus_180_unwraps(tmp_path):
    c = np.arange(721) * 1.0
    a = _read(tmp_path, "a.nc", _point_list((c + 180) % 360 - 180), spindle_rpm=60.0,
              x_mode="radius")
    assert a.program.revolutions == pytest.approx(2.0)
    assert np.allclose(np.diff(np.degrees(a.program.theta)), 1.0)


def test_points_per_revolution_reported(tmp_path):
    c = np.arange(721) * 0.5
    a = _read(tmp_path, "pl.nc", _point_list(c % 360), spindle_rpm=60.0, x_mode="radius")
    assert a.program.meta["points_per_rev"] == 720
    b = _read(tmp_path, "lathe.nc", _PLAIN, points_per_rev=90)
    assert b.program.meta["points_per_rev"] == 90


# ---------------------------------------------------------------------------- words
@pytest.mark.parametrize("text, match", [
    ("G21 G94 F10\nG01 X1.E-3 Z0\n", r":2: a number with an exponent"),
    ("N10 G18 G95\nN20 G96 S200 LIMS=3000\n", r":2: the word 'L' has no number \(a block "
                                              r"holds words.*LIMS="),
    ("N10 DIAMON\n", r":1: the word 'D' has no number .*named words"),
    ("#100=1\n", r":1: cannot read '#' .*macro variables"),
    ("G17 G90 G94 S1000 F10\nG00 X2.0 Z0.1\nG01 Z0.0\nG02 X0.0 Z-1 R1\n",
     r":4: an arc outside the Z-X plane"),
    ("G21 G91 G94 F10\nG00 U2 W0.1\nG01 W-0.1\n",
     r"no block places the tool.*incremental moves"),
])
def test_refused_with_what_is_allowed(tmp_path, text, match):
    with pytest.raises(InputError, match=match):
        _read(tmp_path, "r.nc", text)


def test_decimal_forms(tmp_path):
    a = _read(tmp_path, "a.nc", "G21 G94 G97 S600 F10\nG00 X.5 Z.1\nG01 Z-0.\nX5.\nX+0.25\n",
              x_mode="radius")
    b = _read(tmp_path, "b.nc", "G21 G94 G97 S600 F10\nG00 X0.5 Z0.1\nG01 Z0\nX5\nX0.25\n",
              x_mode="radius")
    _same(a, b)


def test_feed_and_speed_stated(tmp_path):
    text = ("G21 G95 G97 S1000\nG00 X4.0 Z0.1\nG01 Z0 F0.01\nX0 F0.005\nG94 F100\nG00 Z5\n"
            "G01 X4.0\n")
    a = _read(tmp_path, "s.nc", text)
    assert a.inferred["spindle"] == "spindle speed from the program's S words: 1000 rpm (G97)"
    assert a.inferred["feed"] == ("feed from the program's F words: 100 mm/min (G94), "
                                  "0.005 .. 0.01 mm/rev (G95)")
