"""No scene text can reach a machine program as anything but a comment: every writer
(turning NC, sculpturing NC, turning and sculpturing CSV) is fed hostile scene names
through a scene file and the command, and the program is read back block by block."""

from __future__ import annotations

import re
import string

import numpy as np
import pytest
from numpy.testing import assert_allclose

from render_inspect.io import (
    CSV_COLUMNS,
    PROGRAM_CSV_COLUMNS,
    nc_comment_text,
    read_csv,
    read_nc,
    read_program_nc,
)
from render_inspect.pipeline import run_toolpath
from render_inspect.scene import find_scene, load_scene

HOSTILE_NAMES = [
    "quad\nG00 Z-5",                     # a new block after a line feed
    "quad\rG00 Z-5",                     # a carriage return (a line break for most readers)
    "quad\r\nG00 Z-5\r\nM30",
    "a; G00 Z-5",                        # a second comment / block separator
    "(G00 Z-5) name",                    # a parenthesised comment that closes early
    "name) G00 Z-5 (",
    "%\nM30\n%",                         # tape marks and program end
    "snow\u2603man \u2028G00 Z-5\u2029",  # unicode, line and paragraph separators
    "ctl\x00\x01\x07\x08\x0b\x0c\x1b[31m\x7f\x85\x9b",  # control characters (C0, DEL, C1)
    "tab\tG00\vZ-5\fM30",
    "\u202eevil\u200b",                  # bidi override, zero width space
    "N9999 G00 X0 Z-100",
]


def _toml_string(s: str) -> str:
    """``s`` as a TOML basic string (every control character escaped)."""
    out = []
    for ch in s:
        if ch == '"':
            out.append('\\"')
        elif ch == "\\":
            out.append("\\\\")
        elif ord(ch) < 32 or ord(ch) == 127:
            out.append(f"\\u{ord(ch):04x}")
        else:
            out.append(ch)
    return '"' + "".join(out) + '"'


def _scene_file(tmp_path, shipped: str, name: str, i: int):
    """A copy of a shipped scene file whose ``name`` is ``name`` (TOML-escaped)."""
    text = find_scene(shipped).read_text()
    text = re.sub(r"^name\s*=.*$", lambda m: f"name = {_toml_string(name)}", text, count=1, flags=re.M)
    if not re.search(r"^name\s*=", text, flags=re.M):
        text = f"name = {_toml_string(name)}\n" + text
    p = tmp_path / f"hostile_{i}.toml"
    p.write_text(text, encoding="utf-8")
    return p


_PRINTABLE = set(string.printable) - set("\t\n\r\x0b\x0c")
# cutting blocks, and the links' rapids (G00, the first one Z alone), plunges and retracts
_TURN_BLOCK = re.compile(r"^N\d+ (G01 C-?\d+\.\d+ X-?\d+\.\d+ Z-?\d+\.\d+( F[0-9.e+-]+)?"
                         r"|G00( C-?\d+\.\d+ X-?\d+\.\d+)? Z-?\d+\.\d+)$")
_SCULPT_BLOCK = re.compile(r"^N\d+ (G01 X-?\d+\.\d+ Y-?\d+\.\d+ Z-?\d+\.\d+ F[0-9.e+-]+"
                           r"|G00( X-?\d+\.\d+ Y-?\d+\.\d+)? Z-?\d+\.\d+)$")
_SECTIONS = re.compile(r"^; (approach|cut|link|exit|line \d+)$")


def _check_program_lines(text: str, block: re.Pattern, preamble: tuple[str, ...]) -> int:
    """Every line is a one-line ``;`` comment of printable ASCII without ``(`` ``)`` or a
    second ``;``, a line of the modal preamble, a motion block of the expected form, or M30.
    Returns the number of cutting points (the cutting blocks, and the point each plunge
    leaves the tool on)."""
    assert "\r" not in text
    lines = text.split("\n")
    assert lines[-1] == "" and lines[-2] == "M30"
    n = 0
    section = None
    for line in lines[:-2]:
        assert set(line) <= _PRINTABLE, repr(line)
        if line.startswith(";"):
            assert ";" not in line[1:] and "(" not in line and ")" not in line, repr(line)
        elif line in preamble:
            pass
        else:
            assert block.match(line), repr(line)
            n += section == "cut"
        m = _SECTIONS.match(line)
        if m:
            new = "cut" if m.group(1).startswith("line") else m.group(1)
            n += new == "cut" and section in ("approach", "link")  # the plunge's end point
            section = new
    return n


@pytest.mark.parametrize("i, name", list(enumerate(HOSTILE_NAMES)))
def test_turning_nc_and_csv_carry_hostile_names_only_as_comments(tmp_path, i, name):
    scene_file = _scene_file(tmp_path, "sts_sinusoidal_grid", name, i)
    scene = load_scene(scene_file, ["process.workpiece_radius=0.2", "process.points_per_rev=64",
                                    "simulation.region=[-0.1,-0.1,0.1,0.1]"])
    assert scene.name == name  # the scene keeps the name as written
    prog = run_toolpath(scene, tmp_path / "nc", fmt="nc")
    nc = tmp_path / "nc" / "toolpath.nc"
    blocks = _check_program_lines(nc.read_text(encoding="ascii"), _TURN_BLOCK, ("G18 G21 G40", "G90 G93"))
    assert blocks == prog.points
    back = read_nc(nc)
    assert back.meta["scene"] == nc_comment_text(name)
    assert back.points == prog.points
    assert_allclose(back.rho, prog.rho, atol=5.0001e-7)
    assert_allclose(back.z, prog.z, atol=5.0001e-7)
    # CSV: no text at all, the fixed header and one row per point
    run_toolpath(scene, tmp_path / "csv", fmt="csv")
    csv = (tmp_path / "csv" / "toolpath.csv").read_text(encoding="ascii")
    assert csv.split("\n", 1)[0] == ",".join(CSV_COLUMNS)
    back = read_csv(tmp_path / "csv" / "toolpath.csv")
    assert back.points == prog.points
    assert_allclose(back.z, prog.z, rtol=0, atol=0)


@pytest.mark.parametrize("i, name", list(enumerate(HOSTILE_NAMES)))
def test_sculpturing_nc_and_csv_carry_hostile_names_only_as_comments(tmp_path, i, name):
    scene_file = _scene_file(tmp_path, "sculpt_quad_mla", name, i)
    scene = load_scene(scene_file, ["design.rows=2", "design.cols=2", "process.arc_length=0.01"])
    prog = run_toolpath(scene, tmp_path / "nc", fmt="nc")
    nc = tmp_path / "nc" / "toolpath.nc"
    text = nc.read_text(encoding="ascii")
    assert _check_program_lines(text, _SCULPT_BLOCK, ("G17 G40", "G90 G94 G21")) == prog.points
    back = read_program_nc(nc)
    assert back.meta["scene"] == nc_comment_text(name)
    assert back.points == prog.points
    assert_allclose(back.x, prog.x, atol=5.0001e-7)
    assert_allclose(back.y, prog.y, atol=5.0001e-7)
    assert_allclose(back.z, prog.z, atol=5.0001e-7)
    np.testing.assert_array_equal(back.line, prog.line)
    run_toolpath(scene, tmp_path / "csv", fmt="csv")
    rows = (tmp_path / "csv" / "toolpath.csv").read_text(encoding="ascii").splitlines()
    assert rows[0] == ",".join(PROGRAM_CSV_COLUMNS) and len(rows) == prog.points + 1
    assert all(len(r.split(",")) == 5 for r in rows[1:])


def test_comment_text_is_a_whitelist():
    """Whatever goes in, the comment text is printable ASCII without ; ( ) and never
    starts or ends with a space; the words survive."""
    rng = np.random.default_rng(16)
    alphabet = [chr(c) for c in range(0, 0x250)] + ["\u2028", "\u2029", "\ufeff", "\U0001f600"]
    for _ in range(2000):
        s = "".join(rng.choice(alphabet, size=int(rng.integers(0, 40))))
        out = nc_comment_text(s)
        assert set(out) <= _PRINTABLE - set(";()"), repr(out)
        assert out == out.strip()
    assert nc_comment_text("quad\nG00 Z-5") == "quad G00 Z-5"
    assert nc_comment_text("a;b(c)") == "a,b[c]"
