"""NC programs for the control they are loaded into: the comment lines as ``; text``
(RS274NGC / LinuxCNC, Siemens 840D) or ``(text)`` (Fanuc-type controls, where ``;`` ends a
block), the block numbers with any increment or none.  The default program is the same
bytes as before; every variant holds the same text otherwise, never a parenthesis inside a
parenthesis comment, and the project's own readers take it as the project's dialect and
read the same program from it, bit for bit."""

from __future__ import annotations

import hashlib
import re
from pathlib import Path

import numpy as np
import pytest

from conftest import run_main
from render_inspect.core.toolpath import LinearProgram, Links, ToolPath
from render_inspect.errors import InputError
from render_inspect.io import (program_dialect, read_nc, read_nc_blocks, read_program,
                               read_program_nc, write_nc, write_program_nc)
from render_inspect.io import _nc_parse
from render_inspect.io._nc_format import format_linear_rows, format_turning_rows

#: 1,000,000,000 s after 1970-01-01 UTC
EPOCH = "1000000000"
#: scene text with every comment delimiter in it
HEADER = {"software_version": "X", "scene": "a (b); c)"}
LINKS = Links(clearance_z=0.1, plunge_feed=10.0, part_top=0.0)
#: the SHA-256 of the two programs below as the writers wrote them before the options
#: (checked against the writers of that time)
BEFORE = {"turning": "e82535387a1013b590ddea578049904a4a11b095cb82b3a3a9e93d947467274c",
          "linear": "a2b36bdbd005f2bab82935c46cadd0a5b11738634a7c02a1f272843a93fbfaa7"}
STYLES = [(c, n) for c in ("semicolon", "parenthesis") for n in (1, 10, 0)]


def _spiral(n_rev=3, ppr=97, rpm=37.0, r0=0.8, seed=3) -> ToolPath:
    """A spiral whose heights are random (seeded) to the last bit."""
    k = np.arange(n_rev * ppr + 1)
    theta = 2 * np.pi * k / ppr
    rho = r0 * (1 - k / k[-1])
    z = np.random.default_rng(seed).uniform(-0.002, 0.0, k.size)
    return ToolPath(theta, rho, z, theta / (2 * np.pi * rpm / 60.0), {"spindle_rpm": rpm})


def _lines(n_lines=4, n=50, seed=4) -> LinearProgram:
    rng = np.random.default_rng(seed)
    x = np.repeat(np.linspace(-0.3, 0.3, n_lines), n)
    y = np.tile(np.linspace(-0.5, 0.5, n), n_lines)
    z = rng.uniform(-0.003, 0.0, x.size)
    return LinearProgram(x, y, z, np.arange(x.size) * 0.01, np.repeat(np.arange(n_lines), n),
                         {"feed_mm_per_min": 120.0})


def _write(kind: str, path: Path, **style) -> Path:
    if kind == "turning":
        return write_nc(path, _spiral(), header=HEADER, links=LINKS, **style)
    return write_program_nc(path, _lines(), header=HEADER, links=LINKS, **style)


def _as_default(text: str, comments: str, step: int) -> str:
    """A variant's text turned back into the default form, line by line: ``(text)`` ->
    ``; text``, the block numbers back to 1, 2, ..."""
    out, k = [], 0
    for line in text.split("\n"):
        if comments == "parenthesis" and line.startswith("("):
            assert line.endswith(")") and line.count("(") == 1 and line.count(")") == 1, line
            line = "; " + line[1:-1]
        elif re.match(r"N\d+ G0|G0[01] ", line):
            k += 1
            if step:
                num, rest = line.split(" ", 1)
                assert num == f"N{k * step}", (num, k)
                line = rest
            else:
                assert not line.startswith("N")
            line = f"N{k} {line}"
        out.append(line)
    return "\n".join(out)


@pytest.fixture(autouse=True)
def _epoch(monkeypatch):
    monkeypatch.setenv("SOURCE_DATE_EPOCH", EPOCH)


@pytest.mark.parametrize("kind", ["turning", "linear"])
def test_the_default_is_the_same_bytes_as_before(kind, tmp_path):
    a = _write(kind, tmp_path / "a.nc")
    b = _write(kind, tmp_path / "b.nc", comments="semicolon", block_numbers=1)
    assert hashlib.sha256(a.read_bytes()).hexdigest() == BEFORE[kind]
    assert a.read_bytes() == b.read_bytes()


@pytest.mark.parametrize("comments,step", STYLES)
@pytest.mark.parametrize("kind", ["turning", "linear"])
def test_every_style_holds_the_same_program(kind, comments, step, tmp_path, monkeypatch):
    """The text is the default's but for the comment delimiters and the block numbers;
    the readers (the fast one, and the line-by-line one) read the same program, blocks,
    header and file lines from it, the dialect recognised from its first line."""
    base = _write(kind, tmp_path / "base.nc")
    nc = _write(kind, tmp_path / "v.nc", comments=comments, block_numbers=step)
    text = nc.read_text()
    assert _as_default(text, comments, step) == base.read_text()
    if comments == "parenthesis":
        # a Fanuc-type control: no ';' anywhere, every comment one (...) with nothing
        # of the kind inside; the scene's own parentheses and semicolons replaced
        assert ";" not in text
        comments_ = [ln for ln in text.split("\n") if ln.startswith("(")]
        assert comments_ and all(re.fullmatch(r"\([^()]*\)", ln) for ln in comments_)
        assert "(scene: a [b], c])" in comments_
        assert all(ln.startswith(("(", "N", "G", "M")) for ln in text.split("\n") if ln)
    if step == 0:
        assert not re.search(r"^N", text, re.M)
    want = "render_inspect turning" if kind == "turning" else "render_inspect linear"
    assert program_dialect(nc) == want
    read = read_nc if kind == "turning" else read_program_nc
    a, b = read(base), read(nc)
    for name in ("x", "y", "z", "t", "theta", "rho", "line"):
        if hasattr(a, name):
            assert np.asarray(getattr(a, name)).tobytes() == np.asarray(getattr(b, name)).tobytes()
    assert a.meta == b.meta and a.meta["scene"] == "a [b], c]"
    imported = read_program(nc)
    assert imported.dialect == want and imported.file_line.tolist() == read_program(base).file_line.tolist()
    ba = read_nc_blocks(base)
    slow = _nc_parse._blocks_line_by_line(nc)
    # the fast reader takes every style (the line-by-line one made to fail)
    monkeypatch.setattr(_nc_parse, "_blocks_line_by_line",
                        lambda path: pytest.fail(f"{path} was read line by line"))
    bb = read_nc_blocks(nc)
    for got in (bb, slow):
        assert got.dialect == ba.dialect
        for name in ("motion", "role", "feed", "line"):
            assert getattr(got, name).tobytes() == getattr(ba, name).tobytes(), name
        for a_ in ba.axes:
            assert got.axes[a_].tobytes() == ba.axes[a_].tobytes()
        assert got.meta["_file_line"].tolist() == ba.meta["_file_line"].tolist()
        assert {k: v for k, v in got.meta.items() if k != "_file_line"} == \
            {k: v for k, v in ba.meta.items() if k != "_file_line"}
        want_num = ba.number * step if step else np.full(ba.count, -1)
        assert got.number.tolist() == want_num.tolist()


def test_programs_longer_than_a_piece_are_read_the_same(tmp_path, monkeypatch):
    """The fast reader takes a program in pieces: sections, header lines and blocks cut
    at any place read the same in every style."""
    monkeypatch.setattr(_nc_parse, "_PIECE_BYTES", 997)
    for kind in ("turning", "linear"):
        base = read_nc_blocks(_write(kind, tmp_path / "base.nc"))
        for comments, step in STYLES:
            got = read_nc_blocks(_write(kind, tmp_path / "v.nc", comments=comments,
                                        block_numbers=step))
            assert got.role.tobytes() == base.role.tobytes()
            assert got.line.tobytes() == base.line.tobytes()
            assert all(got.axes[a].tobytes() == base.axes[a].tobytes() for a in base.axes)
            assert got.meta["_file_line"].tolist() == base.meta["_file_line"].tolist()


@pytest.mark.parametrize("step", [0, 1, 7])
def test_compiled_blocks_are_pythons_with_any_numbers(step):
    """The compiled writer's blocks with block numbers k * step (none for 0), against
    Python's formatting, the values it leaves to Python included."""
    rng = np.random.default_rng(step)
    n = 3000
    c = rng.normal(0, 1, n) * np.where(rng.random(n) < 0.05, 1e10, 1.0)
    x, z = rng.normal(0, 1, n), rng.normal(0, 1e-3, n)
    feed = rng.random(n) * 10.0 ** rng.integers(-2, 11, n)
    lead = (lambda k: f"N{k * step} ") if step else (lambda k: "")
    want = "".join(f"{lead(5 + j)}G01 C{c[j]:.6f} X{x[j]:.6f} Z{z[j]:.6f}"
                   + (" F%.10g" % feed[j] if j >= 1 else "") + "\n" for j in range(n))
    assert format_turning_rows(5, c, x, z, feed, 1, 6, step) == want.encode("ascii")
    want = "".join(f"{lead(9 + j)}G01 X{c[j]:.6f} Y{x[j]:.6f} Z{z[j]:.6f} F120\n"
                   for j in range(n))
    assert format_linear_rows(9, c, x, z, "120", step) == want.encode("ascii")


def test_bad_styles_are_one_line(tmp_path):
    for bad in ({"comments": "brace"}, {"block_numbers": -1}, {"block_numbers": 1001},
                {"block_numbers": 2.5}, {"block_numbers": True}):
        with pytest.raises(InputError, match=r"NC (comment style|block-number increment) .* received"):
            write_nc(tmp_path / "p.nc", _spiral(), **bad)
        with pytest.raises(InputError, match=r"received"):
            write_program_nc(tmp_path / "l.nc", _lines(), **bad)
    assert not list(tmp_path.iterdir())


SMALL = ["--set", "simulation.region=[-0.05,-0.05,0.05,0.05]", "--set", "simulation.pixel=0.005",
         "--set", "process.workpiece_radius=0.3", "--set", "process.points_per_rev=360"]


def test_toolpath_command_writes_reads_back_and_verifies_each_style(tmp_path, capsys):
    """``toolpath --format nc --nc-comments parenthesis --nc-block-numbers off``: the
    program is written, read back and verified (a program without block numbers passes
    the checks), the same program as the default's; bad options are one line, exit 1,
    nothing written."""
    rc, err = run_main(capsys, "toolpath", "sts_sinusoidal_grid", "--format", "nc", "--out",
                    tmp_path / "a", *SMALL)
    assert rc == 0, err
    rc, err = run_main(capsys, "toolpath", "sts_sinusoidal_grid", "--format", "nc", "--out",
                    tmp_path / "b", "--nc-comments", "parenthesis", "--nc-block-numbers", "off",
                    *SMALL)
    assert rc == 0, err
    text = (tmp_path / "b" / "toolpath.nc").read_text()
    assert text.startswith("(render_inspect generic C-X-Z turning program)\n") and ";" not in text
    a, b = read_nc(tmp_path / "a" / "toolpath.nc"), read_nc(tmp_path / "b" / "toolpath.nc")
    assert a.z.tobytes() == b.z.tobytes() and a.t.tobytes() == b.t.tobytes()
    import json
    facts = json.loads((tmp_path / "b" / "toolpath.json").read_text())["program_check"]
    assert facts["blocks"] == json.loads((tmp_path / "a" / "toolpath.json").read_text())[
        "program_check"]["blocks"]
    for argv, want in (
            (["--format", "nc", "--nc-block-numbers", "5000"],
             "--nc-block-numbers) must be 'off' or a whole number in [1, 1000], received 5000"),
            (["--format", "nc", "--nc-block-numbers", "ten"], "received 'ten'"),
            (["--format", "npz", "--nc-comments", "parenthesis"],
             "--nc-comments set how an NC program is written: they need --format nc, "
             "received --format npz")):
        rc, err = run_main(capsys, "toolpath", "sts_sinusoidal_grid", "--out", tmp_path / "c",
                        *argv, *SMALL)
        assert rc == 1 and want in err and "Traceback" not in err, err
        assert len(err.strip().splitlines()) == 1 and not (tmp_path / "c").exists()
    with pytest.raises(SystemExit) as usage:  # (a usage error: argparse's own)
        run_main(capsys, "toolpath", "sts_sinusoidal_grid", "--out", tmp_path / "c",
              "--format", "nc", "--nc-comments", "brace", *SMALL)
    assert usage.value.code == 2 and "--nc-comments: invalid choice: 'brace'" in capsys.readouterr().err


def test_a_failing_block_without_a_number_is_named_by_place_and_file_line(tmp_path):
    """The verifier names a block of a program without block numbers by its place among
    the motion blocks and its file line."""
    from render_inspect.toolpath import MachineLimits, PartModel, verify_blocks

    nc = _write("linear", tmp_path / "v.nc", block_numbers=0)
    text = nc.read_text().split("\n")
    i = next(k for k, ln in enumerate(text) if ln.startswith("G00 X"))  # the first rapid
    text[i] = text[i].replace("Z0.100000", "Z0.050000")  # below the clearance plane
    nc.write_text("\n".join(text))
    blocks = read_nc_blocks(nc)
    assert np.all(blocks.number == -1)
    part = PartModel(lambda x, y: np.full(np.shape(x), -0.01), ("box", -1.0, -1.0, 1.0, 1.0),
                     top=0.0)
    with pytest.raises(InputError, match=rf"v.nc block 2 \(file line {i + 1}\) \(G00, rapid\)"):
        verify_blocks(blocks, part, MachineLimits(), LINKS, what="v.nc", check_cuts=False)
