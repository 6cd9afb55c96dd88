"""Machine programs written by others (``--program``, ``[process] program``): each
dialect read against a known answer, malformed programs refused with one line, the
project's own programs read back exactly, the published programs of
../shared/realdata/turned (their feed per revolution against their own X steps)."""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from render_inspect.core.errors import InputError
from render_inspect.io import read_nc, read_program, scan_program, write_nc
from render_inspect.processes import feed_per_rev, fit_paraboloid, program_checks

ROOT = Path(__file__).resolve().parents[1]
#: the published programs (the environment variable points elsewhere for a checkout that
#: does not sit beside shared/)
REAL = Path(os.environ.get("RENDER_INSPECT_REALDATA",
                           ROOT / ".." / "shared" / "realdata")) / "turned"
EXAMPLE = ROOT / "docs" / "examples" / "turned" / "scene.toml"


def _write(tmp_path, name, text):
    p = tmp_path / name
    p.write_text(text)
    return p


def _spiral(r0=1.0, feed=0.02, revs=10, step_deg=0.5, radius=-10.0):
    """A bare point list: C wrapping every revolution, X falling by ``feed`` per rev."""
    n = int(round(revs * 360 / step_deg)) + 1
    c_cum = np.arange(n) * step_deg
    x = r0 - feed * c_cum / 360.0
    z = -x ** 2 / (2 * radius)
    c = np.where((c_cum % 360 == 0) & (c_cum > 0), 360.0, c_cum % 360)
    return c_cum, x, z, c


# ---------------------------------------------------------------------------- point lists
@pytest.mark.parametrize("order", ["CXZ", "XZC"])
def test_point_list_spiral(tmp_path, order):
    c_cum, x, z, c = _spiral()
    words = {"C": c, "X": x, "Z": z}
    text = "".join(" ".join(f"{a}{words[a][i]:.6f}" for a in order) + "\n" for i in range(c.size))
    p = _write(tmp_path, "spiral.nc", text)
    imp = read_program(p, spindle_rpm=60.0, part_radius=1.2)
    path = imp.program
    assert imp.dialect == "point list"
    assert np.allclose(np.degrees(path.theta), c_cum, atol=1e-9)
    assert np.allclose(path.rho, np.round(x, 6), atol=1e-12)
    assert np.allclose(path.z, np.round(z, 6), atol=1e-12)
    # no F, no S: C turns at the scene's 60 rpm, one revolution a second
    assert path.t[-1] == pytest.approx(10.0, rel=1e-12)
    assert path.revolutions == pytest.approx(10.0)
    r, f = feed_per_rev(path)
    assert np.allclose(f, 0.02, atol=2e-6)
    assert "process.spindle_rpm" in imp.inferred["spindle"]
    assert imp.inferred["x"].startswith("X is the radius")


def test_point_list_diameter_inferred_and_set(tmp_path):
    c_cum, x, z, c = _spiral(r0=2.0, feed=0.05, revs=4)
    text = "".join(f"C{c[i]:.4f} X{2 * x[i]:.6f} Z{z[i]:.6f}\n" for i in range(c.size))
    p = _write(tmp_path, "dia.nc", text)
    imp = read_program(p, part_radius=2.1)
    assert imp.inferred["x"].startswith("X is the diameter")
    assert np.allclose(imp.program.rho, x, atol=1e-6)
    forced = read_program(p, part_radius=2.1, x_mode="radius")
    assert np.allclose(forced.program.rho, 2 * x, atol=1e-6)
    with pytest.raises(InputError, match="beyond the part"):
        read_program(p, part_radius=0.5)


# ---------------------------------------------------------------------------- lathe G-code
#: a finishing program in the form ultra-precision lathe controllers take (header blocks
#: as in the published examples docs/programs.md cites): diameter X, mm/rev feed
_LATHE = """%
O1234 (FACE A 10 MM DISC)
(TOOL: 0.5 MM NOSE RADIUS)
N10 G71 G90 G18 G40 ; metric, absolute, Z-X plane
N20 G97 S1000 M03
N30 G95 F0.005
N40 G54
N50 G00 X10.2 Z1.0
N60 G01 Z0.0
N70 X0.0 ; face to the centre
N80 G04 P500
N90 G00 Z5.0
N100 G28 U0 W0
N110 M05
N120 M30
%
"""


def test_lathe_gcode_facing(tmp_path):
    p = _write(tmp_path, "face.nc", _LATHE)
    imp = read_program(p, part_radius=5.1, points_per_rev=90)
    path = imp.program
    assert imp.dialect == "lathe G-code"
    assert imp.inferred["x"].startswith("X is the diameter")
    cut = imp.motion == 1
    # X 5.1 -> 0 mm radius at 0.005 mm/rev: 1020 revolutions; the plunge 1 mm: 200 more
    face = cut & (np.abs(path.z) < 1e-12)
    revs = (path.theta[face][-1] - path.theta[face][0]) / (2 * math.pi)
    assert revs == pytest.approx(5.1 / 0.005, rel=1e-3)
    dt = path.t[face][-1] - path.t[face][0]
    assert dt == pytest.approx(1020 / 1000 * 60, rel=1e-3)  # at S = 1000 rpm
    r, f = feed_per_rev(path)
    on_face = (r > 0.1) & (r < 5.0)
    assert np.allclose(f[on_face], 0.005, rtol=1e-3)
    assert any("G04" in n for n in imp.facts["notes"])
    assert imp.inferred["spindle"] == "spindle speed from the program's S words: 1000 rpm (G97)"


def test_lathe_gcode_inch_and_incremental_agree(tmp_path):
    metric = """G71 G90 G18 G94 G97 S600 F2.0
G00 X8.0 Z0.5
G01 Z0.0
X4.0 Z-0.1
X0.0 Z-0.2
"""
    inch = f"""G70 G91 G18 G94 G97 S600 F{2.0 / 25.4!r}
G90 G00 X{8 / 25.4!r} Z{0.5 / 25.4!r}
G91 G01 W{-0.5 / 25.4!r}
U{-4 / 25.4!r} W{-0.1 / 25.4!r}
G90 X0.0 Z{-0.2 / 25.4!r}
"""
    a = read_program(_write(tmp_path, "mm.nc", metric), x_mode="diameter", points_per_rev=36)
    b = read_program(_write(tmp_path, "inch.nc", inch), x_mode="diameter", points_per_rev=36)
    assert a.program.points == b.program.points
    for k in ("theta", "rho", "z", "t"):
        assert np.allclose(getattr(a.program, k), getattr(b.program, k), atol=1e-9)
    assert a.program.rho.max() == pytest.approx(4.0)


@pytest.mark.parametrize("words, centre", [
    ("G03 X4.0 Z-2.0 R2.0", (2.0, -2.0)), ("G03 X4.0 Z-2.0 I0.0 K-2.0", (2.0, -2.0)),
    ("G02 X4.0 Z-2.0 R2.0", (4.0, 0.0)), ("G02 X4.0 Z-2.0 I2.0 K0.0", (4.0, 0.0))])
def test_lathe_gcode_arc(tmp_path, words, centre):
    """A quarter circle of radius 2 mm from (X 2, Z 0) to (X 4, Z -2): counter-clockwise
    (G03) about (X 2, Z -2), clockwise (G02) about (X 4, Z 0), seen with Z to the right
    and X up (ISO, plane G18)."""
    text = f"G90 G18 G94 G97 S100 F1.0\nG00 X2.0 Z0.0\nG01 X2.0 Z0.0\n{words}\n"
    imp = read_program(_write(tmp_path, "arc.nc", text), x_mode="radius", points_per_rev=36)
    path = imp.program
    arc = imp.motion == int(words[2])
    assert arc.sum() > 10
    d = np.hypot(path.rho[arc] - centre[0], path.z[arc] - centre[1])
    assert np.allclose(d, 2.0, atol=1e-6)
    assert path.rho[arc].max() == pytest.approx(4.0, abs=1e-9)
    assert np.all((path.z[arc] <= 1e-12) & (path.z[arc] >= -2 - 1e-12))


def test_cxz_gcode_inverse_time(tmp_path):
    rows = ["G90 G93"] + [f"G01 C{c:.3f} X{1 - c / 3600:.6f} Z0.0 F{600.0:g}" for c in
                          np.arange(0.0, 720.001, 1.0)]
    imp = read_program(_write(tmp_path, "g93.nc", "\n".join(rows) + "\n"), part_radius=1.0)
    assert imp.dialect == "C-X-Z G-code"
    # every block takes 1/600 min = 0.1 s
    assert np.allclose(np.diff(imp.program.t), 0.1)
    assert imp.program.revolutions == pytest.approx(2.0)


# ---------------------------------------------------------------------------- linear
def test_linear_raster(tmp_path):
    text = """G90 G94 G21 G17
G00 X0 Y0 Z1
G01 Z0 F60
Y2.0
G00 Z1
X0.5 Y0
G01 Z-0.1
Y2.0
"""
    imp = read_program(_write(tmp_path, "raster.nc", text), kind="linear")
    prog = imp.program
    assert imp.dialect == "linear G-code"
    assert prog.lines == 3  # the start, and one line after each rapid run
    cut = imp.motion == 1
    assert np.allclose(prog.y[cut], [0.0, 2.0, 0.0, 2.0])
    # 2 mm at 60 mm/min: 2 s per line
    i = np.flatnonzero(cut)
    assert prog.t[i[1]] - prog.t[i[0]] == pytest.approx(2.0)
    with pytest.raises(InputError, match="linear X-Y-Z program, and the scene"):
        read_program(_write(tmp_path, "r2.nc", text), kind="turning")


# ---------------------------------------------------------------------------- malformed
@pytest.mark.parametrize("text, line, word", [
    ("C0.0 X1.0 Z0.0\nC0.5 X1.0.1 Z0.0\n", 2, "the word 'X' has no valid number"),  # point list
    ("C0.0 X1.0 Z0.0\nC0.5 X Z0.0\n", 2, "the word 'X' has no number"),
    ("G90 G18\nG01 X1 Z0 F1\nG32 X0 Z-1 F0.1\n", 3, "G32 is not a G code"),          # lathe
    ("G90\nG01 X1 X2 Z0\n", 2, "the word 'X' appears twice"),
    ("G90\nG01 X1 Z0 (unclosed\n", 2, "without its ')'"),
    ("G90\nG41 X1 Z0\n", 2, "G41 is refused"),
    ("G90 G17\nG00 X0 Y0 Z1\nG95 G01 X1 Y0 Z0 F0.1\n", 3, "G95"),                    # linear
    ("G90 G17\nG00 X0 Y0 Z1\nG01 X1 Y0 Q Z0\n", 3, "the word 'Q' has no number"),
])
def test_malformed_one_line(tmp_path, text, line, word):
    p = _write(tmp_path, "bad.nc", text)
    with pytest.raises(InputError) as err:
        read_program(p, part_radius=2.0)
    msg = str(err.value)
    assert "\n" not in msg
    assert msg.startswith(f"{p}:{line}: ")
    assert word in msg
    assert "in block '" in msg or "G95" in msg


@pytest.mark.parametrize("text", [
    "G71 G90 G94\nG01 X1.0 Z0.0 F0\nG01 X0.5 Z0.0\n",          # a feed of 0 mm/min
    "G71 G90 G93\nG01 X1.0 Z0.0 F0\nG01 X0.5 Z0.0\n",          # inverse time 0
    "G71 G90 G95 S0\nG01 X1.0 Z0.0 F0.01\nG01 X0.5 Z0.0\n",    # per revolution, S0
])
def test_a_feed_of_zero_is_one_line(tmp_path, text):
    """A move at a feed of 0 never ends: one line naming the file and the block's line,
    not an error from the sampling of an endless move."""
    p = _write(tmp_path, "f0.nc", text)
    with pytest.raises(InputError) as err:
        read_program(p, part_radius=2.0)
    msg = str(err.value)
    assert "\n" not in msg and msg.startswith(f"{p}:3: ") and "the feed in force is 0" in msg


def test_malformed_own_dialect(tmp_path):
    from render_inspect.core.toolpath import ToolPath
    n = 50
    path = ToolPath(np.linspace(0, 2 * np.pi, n), np.linspace(1, 0.9, n), np.zeros(n),
                    np.linspace(0, 1, n))
    p = write_nc(tmp_path / "own.nc", path)
    text = p.read_text().replace(" F", " F-", 1).replace("F-", "F", 0)
    lines = text.splitlines()
    k = next(i for i, s in enumerate(lines) if s.startswith("N3 "))
    lines[k] = lines[k].replace("X", "X1.2.3 X", 1)
    p.write_text("\n".join(lines) + "\n")
    with pytest.raises(InputError) as err:
        read_program(p)
    assert f":{k + 1}:" in str(err.value) and "\n" not in str(err.value)


# ---------------------------------------------------------------------------- own dialect
def test_own_dialect_exact(tmp_path):
    from render_inspect.core.toolpath import ToolPath
    n = 2000
    th = np.linspace(0, 20 * np.pi, n)
    path = ToolPath(th, 1 - th / (20 * np.pi), 0.01 * np.sin(th), th / 3.0)
    p = write_nc(tmp_path / "own.nc", path)
    imp = read_program(p, part_radius=1.0)
    ref = read_nc(p)
    assert imp.dialect == "render_inspect turning"
    for k in ("theta", "rho", "z", "t"):
        assert np.array_equal(getattr(imp.program, k), getattr(ref, k))
    assert np.abs(imp.program.rho - path.rho).max() <= 5e-7


def test_scanner_pieces_agree(tmp_path):
    """Pieces of any size give the same blocks (the modal state carries over)."""
    p = _write(tmp_path, "pieces.nc", _LATHE * 1)
    whole = scan_program(p)
    small = scan_program(p, piece_bytes=7)
    for a in "XZ":
        assert np.array_equal(np.nan_to_num(whole.axes[a], nan=-9), np.nan_to_num(small.axes[a], nan=-9))
    assert np.array_equal(whole.line, small.line)
    assert np.array_equal(whole.feed_mode, small.feed_mode)


def test_scanner_fast_cleaning_matches_general_way():
    """The compiled pass that cleans a piece (upper case, spaces dropped, comments
    removed) gives the bytes the general way (regular expressions) gives wherever it takes
    the piece; what it hands on (``%``, ``:``, ``/``, unpaired parentheses, bytes that are
    not ASCII) the general way reads, or names what is wrong."""
    from render_inspect.io._program_kernel import clean_piece
    from render_inspect.io._program_scan import _Scanner

    def fail(line, text):
        raise InputError(text)

    rng = np.random.default_rng(7)
    common = np.frombuffer(b"GXZCFNxz0123456789.-+  \t\r;()\n", np.uint8)
    rare = np.frombuffer(b"%:/)\xc3", np.uint8)
    sc = _Scanner(Path("random.nc"))
    taken = handed = 0
    for k in range(4000):
        text = common[rng.integers(0, common.size, rng.integers(1, 60))]
        if k % 2:  # one byte of the kind handed on, somewhere
            byte = rare[rng.integers(0, rare.size)]
            text = np.insert(text, rng.integers(0, text.size + 1), byte)
        raw = text.tobytes() + b"\n"
        out = np.empty(len(raw), np.uint8)
        m, ok = clean_piece(np.frombuffer(raw, np.uint8), out)
        try:
            general = sc._text(raw, 1, fail)
        except InputError:
            general = None
        if ok:
            taken += 1
            assert general is not None and out[:m].tobytes() == general, raw
        else:
            handed += 1
    assert taken > 400 and handed > 2000, (taken, handed)


# ---------------------------------------------------------------------------- scene
def test_scene_key_relative_and_dump(tmp_path):
    from render_inspect.scene import load_scene
    c_cum, x, z, c = _spiral()
    (tmp_path / "progs").mkdir()
    _write(tmp_path / "progs", "p.nc", "".join(f"C{c[i]:.4f} X{x[i]:.6f} Z{z[i]:.6f}\n"
                                               for i in range(c.size)))
    scene = tmp_path / "s.toml"
    scene.write_text('[design]\ntype = "paraboloid"\nradius_x = -10.0\nradius_y = -10.0\n'
                     '[process]\nprogram = "progs/p.nc"\nworkpiece_radius = 1.2\n')
    sc = load_scene(scene)
    assert Path(sc.process.program) == (tmp_path / "progs" / "p.nc").resolve()
    assert sc.to_dict()["process"]["program"] == sc.process.program
    plain = load_scene("sts_fig16_overcut")
    assert "program" not in plain.to_dict()["process"]
    assert "program_x" not in plain.to_dict()["process"]


def test_findings_below_design(tmp_path):
    """A point programmed 2 um below the design is a finding with its file line; the rest
    of the program on the design is not."""
    from render_inspect.scene import load_scene
    from render_inspect.design import make_surface
    from render_inspect.processes import process_of
    c_cum, x, z, c = _spiral(r0=0.5, feed=0.01, revs=5, radius=-10.0)
    z = z.copy()
    z[1000] -= 0.002
    p = _write(tmp_path, "dig.nc", "".join(f"C{c[i]:.4f} X{x[i]:.6f} Z{z[i]:.6f}\n"
                                          for i in range(c.size)))
    sc = load_scene("sts_fig16_overcut", [
        "design={type='paraboloid', radius_x=-10.0, radius_y=-10.0}",
        f"process.program={json.dumps(str(p))}", "process.workpiece_radius=0.6"])
    proc = process_of(sc)
    cfg = proc.inputs_of(sc)
    surface = make_surface(sc.design)
    path = proc.program(cfg, surface)
    checks = program_checks(cfg, surface, path)
    (f,) = checks["findings"]
    assert f["kind"] == "below_design" and f["points"] == 1
    assert f["worst_line"] == 1001
    assert f["worst_nm"] == pytest.approx(2000, abs=1)


def test_fit_paraboloid_known():
    from render_inspect.core.toolpath import ToolPath
    r = np.linspace(0, 1, 500)
    z = 0.003 + r ** 2 / (2 * 12.5)
    fit = fit_paraboloid([ToolPath(np.linspace(0, 10, 500), r, z, np.arange(500.0))])
    assert fit["radius_mm"] == pytest.approx(-12.5, rel=1e-10)
    assert fit["offset_mm"] == pytest.approx(0.003, abs=1e-12)
    assert fit["max_nm"] < 1e-6


# ---------------------------------------------------------------------------- real programs
def _real_files():
    if not REAL.is_dir():
        pytest.skip(f"published programs absent: {REAL} (../shared/realdata absent)")
    files = sorted(REAL.glob("*.nc"))
    if len(files) != 3:
        pytest.fail(f"expected the three published programs in {REAL}, found {len(files)}")
    return files


def _x_steps(path):
    """The program's own X step per revolution, from its text: X where C reads 0 (or
    360), one revolution to the next."""
    c, x = [], []
    for row in path.read_text().split():
        if row[0] == "C":
            c.append(float(row[1:]))
        elif row[0] == "X":
            x.append(float(row[1:]))
    c, x = np.asarray(c), np.asarray(x)
    at = np.flatnonzero(c % 360.0 == 0.0)
    # C reads 360 and then 0.5 at some wraps, 359.5 and then 0 at others: one point a turn
    at = at[np.r_[True, np.diff(at) > 1]]
    return at[:-1], x[at[:-1]] - x[at[1:]]


def test_real_programs_feed_per_rev_matches_x_step():
    for f in _real_files():
        imp = read_program(f, part_radius=1.1, spindle_rpm=100.0)
        assert imp.dialect == "point list"
        r, fpr = feed_per_rev(imp.program)
        at, step = _x_steps(f)
        # the reader's feed per revolution at the points where the program's C reads 0
        got = fpr[at]
        assert np.max(np.abs(got - step)) < 1e-12, f.name
        assert step.size >= 26


def test_example_scene_design_is_the_fit():
    files = _real_files()
    from render_inspect.scene import load_scene
    sc = load_scene(EXAMPLE, [f"process.program={json.dumps(str(files[0]))}"])
    fit = fit_paraboloid([read_program(f, part_radius=1.1).program for f in files])
    assert sc.design.radius_x == pytest.approx(fit["radius_mm"], abs=1e-6)
    assert sc.design.offset == pytest.approx(fit["offset_mm"], abs=1e-9)
    assert sc.tool.nose_radius == 0.2


@pytest.mark.slow
def test_real_programs_simulate_and_toolpath(tmp_path):
    """``toolpath --program`` reports the feed per revolution (table, figure) and the
    findings of each published program; ``simulate`` cuts it (a small window)."""
    files = _real_files()
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    for f in files:
        out = tmp_path / f.stem
        cmd = [sys.executable, "-m", "render_inspect.cli", "toolpath", str(EXAMPLE),
               "--program", str(f), "--out", str(out)]
        run = subprocess.run(cmd, capture_output=True, text=True, env=env, timeout=600)
        assert run.returncode == 0, run.stderr
        facts = json.loads((out / "toolpath.json").read_text())
        assert (out / "feed_per_rev.png").is_file() and (out / "feed_per_rev.csv").is_file()
        prog = facts["program"]
        assert prog["dialect"] == "point list"
        _, step = _x_steps(f)
        table = prog["feed_per_rev"]["by_radius"]
        lo = min(t["min_um"] for t in table)
        hi = max(t["max_um"] for t in table)
        assert lo <= step.min() * 1e3 + 1e-6 and hi >= step.max() * 1e3 - 1e-6
        assert "program findings" in run.stderr
    sim = tmp_path / "sim"
    cmd = [sys.executable, "-m", "render_inspect.cli", "simulate", str(EXAMPLE), "--program",
           str(files[0]), "--out", str(sim), "--set", "simulation.region=[-0.1,-0.02,0.1,0.02]",
           "--set", "simulation.pixel=0.002"]
    run = subprocess.run(cmd, capture_output=True, text=True, env=env, timeout=900)
    assert run.returncode == 0, run.stderr
    m = json.loads((sim / "metrics.json").read_text())
    assert m["program"]["file"] == files[0].name
    # 39 um per revolution under a 0.2 mm nose: scallops near f^2 / (8 Rc) = 0.95 um deep
    assert 300 < m["residual"]["Sz_nm"] < 2500


@pytest.mark.slow
def test_cli_program_errors_one_line(tmp_path):
    bad = _write(tmp_path, "bad.nc", "G90\nG01 X1 Z0\nG33 X0\n")
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    cmd = [sys.executable, "-m", "render_inspect.cli", "toolpath", "sts_fig16_overcut",
           "--program", str(bad), "--out", str(tmp_path / "o")]
    run = subprocess.run(cmd, capture_output=True, text=True, env=env, timeout=300)
    assert run.returncode == 1
    lines = [s for s in run.stderr.splitlines() if s.strip()]
    assert len(lines) == 1 and f"{bad}:3:" in lines[0] and "G33" in lines[0]
    assert not (tmp_path / "o").exists()


@pytest.mark.slow
def test_round_trip_same_surface(tmp_path):
    """A planned program exported and read back cuts the same surface, to the written
    places (6 decimals: 0.5 nm), through the same machine and material."""
    from render_inspect.pipeline import simulate
    from render_inspect.scene import load_scene
    sc = load_scene("sts_fig16_overcut", ["simulation.region=[0.2,0.2,0.26,0.26]",
                                          "simulation.pixel=0.002"])
    a = simulate(sc)
    p = write_nc(tmp_path / "plan.nc", a.plan.program)
    b = simulate(sc.with_overrides([f"process.program={json.dumps(str(p))}"]))
    d = np.abs(b.heightmap.machined - a.heightmap.machined)
    assert np.nanmax(d) < 1e-6
    assert b.metrics["program"]["dialect"] == "render_inspect turning"


def test_refused_programs_one_line(tmp_path):
    # C turning round: up, then back by less than a revolution's wrap
    back = _write(tmp_path, "back.nc", "".join(f"C{c:.1f} X1.0 Z0\n" for c in (0, 10, 20, 15)))
    with pytest.raises(InputError, match=r"back.nc:4: C decreases by 5 deg .* whose C increases"):
        read_program(back, part_radius=1.0)
    both = _write(tmp_path, "both.nc", "G01 X1 Y0 Z0 F10\nC10 X1 Y1 Z0\n")
    with pytest.raises(InputError, match=r"both.nc:2: a program with both Y and C"):
        read_program(both)
    g50 = _write(tmp_path, "g50.nc", "G90\nG50 X10 Z5\n")
    with pytest.raises(InputError, match=r"g50.nc:2: G50 with axis words"):
        read_program(g50)
    xu = _write(tmp_path, "xu.nc", "G90\nG01 X1 U1 Z0 F1\n")
    with pytest.raises(InputError, match=r"xu.nc:2: both X and U"):
        read_program(xu)


def test_compare_names_program_variants():
    from render_inspect.scene import compare_pair, load_scene
    pair = compare_pair(load_scene("sts_fig16_overcut"),
                        "process.program=../progs/cam_a.nc,/abs/cam_b.nc")
    assert (pair.a.name, pair.b.name) == ("program_cam_a", "program_cam_b")
    assert pair.a.values == {"process.program": "../progs/cam_a.nc"}


def test_program_pair_is_program_against_plan(tmp_path):
    from render_inspect.processes import process_of
    from render_inspect.scene import load_scene
    c_cum, x, z, c = _spiral(r0=0.5, feed=0.01, revs=3)
    p = _write(tmp_path, "s.nc", "".join(f"C{c[i]:.4f} X{x[i]:.6f} Z{z[i]:.6f}\n"
                                        for i in range(c.size)))
    sc = load_scene("sts_fig16_overcut", [f"process.program={json.dumps(str(p))}"])
    pair = process_of(sc).variants(process_of(sc).inputs_of(sc))
    assert (pair.a.name, pair.b.name) == ("program", "planned")
    assert pair.b.values == {"process.program": None}


def test_sculpt_takes_a_raster_program(tmp_path):
    """An X-Y-Z raster program (lines along Y at constant X, linked by rapids) read for
    the sculpturing cut: one target line per run of feed moves."""
    from render_inspect.design import make_surface
    from render_inspect.processes import process_of
    from render_inspect.scene import load_scene
    rows = ["G90 G94 G21 G17 F100"]
    for k, xk in enumerate((-0.099875, 0.099875)):
        rows += [f"G00 X{xk} Y-0.2 Z0.05", "G01 Z0.0"]
        rows += [f"G01 Y{y:.4f} Z0.0" for y in np.linspace(-0.19, 0.2, 40)]
        rows += ["G01 Z0.05"]
    p = _write(tmp_path, "raster.nc", "\n".join(rows) + "\n")
    sc = load_scene("sculpt_quad_mla", ["design.rows=2", "design.cols=2",
                                        "simulation.region=[-0.19975,-0.19975,0.19975,0.19975]",
                                        f"process.program={json.dumps(str(p))}"])
    proc = process_of(sc)
    cfg = proc.inputs_of(sc)
    plan = proc.plan(cfg, make_surface(sc.design))
    assert plan.facts["toolpath"]["lines"] == 2
    assert plan.facts["program"]["dialect"] == "linear G-code"
    assert np.allclose(plan.data["x_lines"], [-0.099875, 0.099875])


def test_findings_rapid_through_part(tmp_path):
    """A rapid across the part below its top is a finding; the rapid that rises straight
    up from the cut is not."""
    from render_inspect.design import make_surface
    from render_inspect.processes import process_of
    from render_inspect.scene import load_scene
    text = """G90 G18 G95 G97 S600 F0.01
G00 X1.0 Z0.1
G01 Z0.0
X0.5
G00 Z0.05
G00 X0.8 Z0.0005
"""
    p = _write(tmp_path, "rapid.nc", text)
    sc = load_scene("sts_fig16_overcut", [
        "design={type='plane'}", f"process.program={json.dumps(str(p))}",
        "process.workpiece_radius=1.0", "process.points_per_rev=36", "process.program_x='radius'"])
    proc = process_of(sc)
    cfg = proc.inputs_of(sc)
    surface = make_surface(sc.design)
    checks = program_checks(cfg, surface, proc.program(cfg, surface))
    kinds = {f["kind"]: f for f in checks["findings"]}
    assert "below_design" not in kinds
    assert kinds["rapid_through_part"]["worst_line"] == 6
    assert set(kinds["rapid_through_part"]["first_lines"]) == {6}


def test_compare_summary_names_program_findings():
    from render_inspect.report import comparison_summary
    side = {"variant": {"label": "x"}, "residual": {"Sq_nm": 1.0, "min_nm": -1.0},
            "filtered": {}, "measured": {}}
    m = {"variants": [{"name": "program"}, {"name": "planned"}],
         "program": {**side, "program": {"findings_count": 12, "file": "a.nc"}},
         "planned": dict(side), "difference": {}}
    rows, _ = comparison_summary(m)
    assert rows[-1] == ("program findings (below the design, rapids in the part)",
                        "12 points (a.nc)", "(planned)")


def test_lathe_constant_surface_speed_with_clamp(tmp_path):
    """G96 (surface speed, m/min) under a G50 S clamp, in the form of the published
    face-and-turn sample (docs/programs.md): the spindle turns at V / (2 pi r) until the
    clamp."""
    text = """%
O4968 (SAMPLE FACE)
N01 M216
N02 G21 G90 G54 D200 G40
N03 G50 S2000
N04 T0300
N05 G96 S100 M03
N06 G00 X20.0 Z0.1
N07 G95 G01 Z0.0 F0.01
N08 X0.0
N09 G00 Z5.0
N10 M30
%
"""
    imp = read_program(_write(tmp_path, "css.nc", text), part_radius=10.0, points_per_rev=20)
    path = imp.program
    assert imp.inferred["x"].startswith("X is the diameter")
    face = imp.file_line == 10  # N08 X0.0
    i = np.flatnonzero(face)
    r = 0.5 * (path.rho[i[1:]] + path.rho[i[:-1]])
    rpm = np.diff(path.theta[i]) / np.diff(path.t[i]) * 60 / (2 * math.pi)
    expect = np.minimum(2000.0, 100_000.0 / (2 * math.pi * r))
    ok = r > 0.05
    assert np.allclose(rpm[ok], expect[ok], rtol=2e-3)
    assert rpm.max() == pytest.approx(2000.0, rel=1e-9)
    # the feed per revolution stays 0.01 mm whatever the speed
    rr, f = feed_per_rev(path)
    sel = (rr > 1.0) & (rr < 9.0)
    assert np.allclose(f[sel], 0.01, rtol=2e-3)


def test_a_cut_from_a_program_names_the_program_in_its_outputs(tmp_path, monkeypatch):
    """``simulate --program`` (the whole map and tiled): ``metrics.json`` ``run_name`` and
    the titles of ``residual.png`` and of the program's figures name the program's file
    beside the scene, ``scene_name`` stays the scene's; a planned cut is named by its
    scene alone."""
    from render_inspect.pipeline import _simulate, _simulate_command, run_simulate
    from render_inspect.processes import cut_name
    from render_inspect.scene import load_scene

    c_cum, x, z, c = _spiral(r0=0.5, feed=0.01, revs=3)
    p = _write(tmp_path, "cam_spiral.nc", "".join(f"C{c[i]:.4f} X{x[i]:.6f} Z{z[i]:.6f}\n"
                                                  for i in range(c.size)))
    region = "simulation.region=[0.46, -0.02, 0.5, 0.02]"
    scene = load_scene("sts_fig16_overcut", [f"process.program={json.dumps(str(p))}", region])
    planned = load_scene("sts_fig16_overcut", [region])
    name = "sts_fig16_overcut, program cam_spiral.nc"
    assert cut_name(scene) == name and cut_name(planned) == "sts_fig16_overcut"
    titles: dict = {}

    def keep(fn, key):
        def draw(*args, **kwargs):
            spec = args[0] if isinstance(args[0], dict) else {}
            titles.setdefault(key, []).append(kwargs.get("title") or spec.get("title"))
            return fn(*args, **kwargs)
        return draw

    monkeypatch.setattr(_simulate, "residual_preview_png", keep(_simulate.residual_preview_png, "whole"))
    for k in ("residual_png", "draw_figure"):
        monkeypatch.setattr(_simulate_command, k, keep(getattr(_simulate_command, k), "tiled"))
    for tiled in (False, True):
        out = tmp_path / ("tiled" if tiled else "whole")
        m = run_simulate(scene, out, tiled=tiled, tile=64)
        assert m["run_name"] == name and m["scene_name"] == "sts_fig16_overcut"
        assert json.loads((out / "metrics.json").read_text())["run_name"] == name
        assert (out / "feed_per_rev.png").is_file()
    sim = _simulate.simulate(scene)
    assert sim.figures["feed_per_rev.png"]["title"].startswith(f"{name}: feed per revolution")
    assert titles["whole"] and all(t.startswith(f"{name}: residual") for t in titles["whole"])
    # residual.png and every figure the tiled run drew
    assert len(titles["tiled"]) >= 2 and all(t.startswith(f"{name}: ") for t in titles["tiled"]), titles
    assert _simulate.simulate(planned).metrics["run_name"] == "sts_fig16_overcut"

