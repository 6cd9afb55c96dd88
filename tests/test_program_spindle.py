"""The spindle's direction and stops in a user's program (M03, M04, M05; M00, M01).

A lathe turning the other way cuts the mirror image: the part an X-Z program cuts
turning M04 on a design is the mirror (y -> -y) of the part the same program cuts
turning M03 on the mirrored design.  The tests build that known answer (the M03 run of
the mirrored design, flipped) and the hand of the turning marks' spiral (their phase
2 pi r / f + s phi: s = +1 for M03, -1 for M04), check the stopped spindle's refusal and
its time, and that M03 reads as a program without spindle words does."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from render_inspect.core.errors import InputError
from render_inspect.io import read_csv, read_nc, read_program, read_toolpath_npz, write_csv, \
    write_nc, write_toolpath_npz

#: a facing cut at 1000 rpm, 10 um per revolution, from X 0.62 mm (radius) to the centre,
#: the spindle words put in by ``{m}``
_FACE = ("G71 G90 G18 G94\nG97 S1000 {m}\nG95 F0.01\nG00 X0.62 Z0.01\nG01 Z0.0\nG01 X0.0\n"
         "G00 Z1.0\nM05\nM30\n")
#: a design without mirror symmetry in y, and its mirror
_DESIGN = "0.0003*x*y + 0.0002*y + 0.0001*x"
_MIRRORED = "-0.0003*x*y - 0.0002*y + 0.0001*x"
#: a region whose numbers are exact in binary (the mirrored grid is the grid's mirror
#: to the last bit)
_REGION = "[-0.25,-0.25,0.25,0.25]"
_PIXEL = 1 / 512
_FEED = 0.01


def _write(tmp_path, name, text):
    p = tmp_path / name
    p.write_text(text)
    return p


def _simulate(tmp_path, m, design, machine="sts_lathe", material="al6082"):
    from render_inspect.pipeline import simulate
    from render_inspect.scene import load_scene
    p = _write(tmp_path, f"face_{m}.nc", _FACE.format(m=m))
    sc = load_scene("sts_fig16_overcut", [
        f"design={{type='expression', expr='{design}'}}", f"process.program={json.dumps(str(p))}",
        "process.workpiece_radius=0.7", "process.points_per_rev=720",
        f"simulation.region={_REGION}", f"simulation.pixel={_PIXEL!r}",
        f"machine.preset='{machine}'", f"material.preset='{material}'"])
    return simulate(sc)


def _hand(machined):
    """The slope s of the turning marks' phase 2 pi r / f + s phi (phi the part's polar
    angle) that fits the map best, among -3 .. 3 in steps of 0.1."""
    ny, nx = machined.shape
    x = -0.25 + _PIXEL * np.arange(nx)
    y = -0.25 + _PIXEL * np.arange(ny)
    xx, yy = np.meshgrid(x, y)
    ok = np.isfinite(machined)
    h = machined[ok] - np.mean(machined[ok])
    r, phi = np.hypot(xx, yy)[ok], np.arctan2(yy, xx)[ok]
    slopes = np.round(np.linspace(-3, 3, 61), 6)
    fit = [abs(np.mean(h * np.exp(-1j * (2 * math.pi * r / _FEED + s * phi)))) for s in slopes]
    return float(slopes[int(np.argmax(fit))]), max(fit) / min(fit)


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """The facing program turning M04 on the design, turning M03 on the mirrored design,
    through the shipped lathe and aluminium."""
    tmp = tmp_path_factory.mktemp("spindle")
    return {"M04": _simulate(tmp, "M04", _DESIGN), "M03 mirrored": _simulate(tmp, "M03", _MIRRORED)}


def test_m04_is_the_mirror_of_m03_on_the_mirrored_design(runs):
    """Bit for bit: the machined and design maps, the following error's map; the residual's
    metrics to rounding (sums over the rows in the other order); the outputs say M04."""
    a, b = runs["M03 mirrored"], runs["M04"]
    assert np.array_equal(b.heightmap.machined, a.heightmap.machined[::-1], equal_nan=True)
    assert np.array_equal(b.heightmap.design, a.heightmap.design[::-1])
    # the design map is the design itself on the part's own grid
    from render_inspect.design import make_surface
    from render_inspect.machining import design_grid
    sc = b.scene
    assert np.array_equal(b.heightmap.design,
                          design_grid(make_surface(sc.design), tuple(sc.simulation.region), _PIXEL))
    # (sums over the rows in the other order: to rounding)
    ra, rb = a.metrics["residual"], b.metrics["residual"]
    assert rb.keys() == ra.keys()
    assert all(rb[k] == pytest.approx(ra[k], rel=1e-12, abs=1e-12) for k in ra)
    fa, fb = a.figures["following_error_map.png"], b.figures["following_error_map.png"]
    for k in ("x_nm", "z_nm"):
        assert np.array_equal(np.asarray(fb[k]), np.asarray(fa[k])[::-1], equal_nan=True)
    assert fb["extent"] == pytest.approx(fa["extent"], abs=1e-15)
    assert b.heightmap.meta["spindle_direction"] == "M04"
    assert "spindle_direction" not in a.heightmap.meta
    assert b.metrics["program"]["spindle_direction"] == "M04"
    assert a.metrics["program"]["spindle_direction"] == "M03"
    assert "counter-clockwise (M04, line 2)" in b.metrics["program"]["inferred"]["spindle"]


def test_the_marks_spiral_has_the_spindles_hand(runs, tmp_path):
    """The turning marks' phase turns with the part's angle one way for M03 (s = +1: the
    radius falls as the angle grows) and the other for M04, by a clear margin."""
    m03 = _simulate(tmp_path, "M03", _DESIGN, machine="ideal", material="ideal")
    m04 = _simulate(tmp_path, "M04", _DESIGN, machine="ideal", material="ideal")
    s3, c3 = _hand(m03.heightmap.machined)
    s4, c4 = _hand(m04.heightmap.machined)
    assert (s3, s4) == (1.0, -1.0)
    assert c3 > 100 and c4 > 100
    # through the lathe and the material the hand is the same
    assert _hand(runs["M04"].heightmap.machined)[0] == -1.0


def test_m03_reads_as_a_program_without_spindle_words(tmp_path):
    """M03 (and a program saying nothing) is the project's turning: the same path to the
    last bit, M05 at the end after the last move changes nothing."""
    plain = read_program(_write(tmp_path, "plain.nc", _FACE.format(m="").replace("M05\n", "")),
                         part_radius=0.7, points_per_rev=90)
    m03 = read_program(_write(tmp_path, "m03.nc", _FACE.format(m="M03")), part_radius=0.7,
                       points_per_rev=90)
    for k in ("theta", "rho", "z", "t"):
        assert np.array_equal(getattr(plain.program, k), getattr(m03.program, k)), k
    assert m03.inferred == plain.inferred and "spindle_direction" not in m03.program.meta


def test_m04_path_turns_as_m03(tmp_path):
    """M04's path is M03's (the spindle's angle turned through), marked M04."""
    m03 = read_program(_write(tmp_path, "m03.nc", _FACE.format(m="M03")), part_radius=0.7,
                       points_per_rev=90)
    m04 = read_program(_write(tmp_path, "m04.nc", _FACE.format(m="M04")), part_radius=0.7,
                       points_per_rev=90)
    for k in ("theta", "rho", "z", "t"):
        assert np.array_equal(getattr(m03.program, k), getattr(m04.program, k)), k
    assert m04.program.meta["spindle_direction"] == "M04"
    assert m04.facts["spindle_direction"] == "M04" and m03.facts["spindle_direction"] == "M03"


@pytest.mark.parametrize("body, line, word", [
    ("G01 X0.6\nM05\nG01 X0.3\nM03\nG01 X0.0\n", 8, "G01"),
    ("G01 X0.6\nM05\nG00 Z0.5\nG02 X0.3 Z0.2 R0.3\n", 9, "G02"),
    ("G01 X0.6\nG01 X0.3 M05\n", 7, "G01"),   # M05 acts before the block's move
])
def test_cutting_with_the_spindle_stopped_is_refused(tmp_path, body, line, word):
    head = "G71 G90 G18 G94\nG97 S1000 M03\nG95 F0.01\nG00 X0.62 Z0.01\nG01 Z0.0\n"
    p = _write(tmp_path, "stop.nc", head + body + "M30\n")
    stop_line = 1 + (head + body).splitlines().index(
        next(t for t in (head + body).splitlines() if "M05" in t))
    with pytest.raises(InputError, match=rf"^{p}:{line}: a cutting move \({word}\) with the "
                                         rf"spindle stopped \(M05 at line {stop_line}\)"):
        read_program(p, part_radius=0.7, points_per_rev=36)


def test_stopped_spindle_then_restart(tmp_path):
    """M05, rapids out and back, M03: the rapids take their time at the rapid rate with the
    spindle standing; the moves after the restart are read as usual."""
    text = ("G71 G90 G18 G94\nG97 S1000 M03\nG95 F0.01\nG00 X0.62 Z0.01\nG01 Z0.0\n"
            "G01 X0.6\nM05\nG00 Z1.0\nG00 X0.3\nM03\nG00 Z0.01\nG01 Z0.0\nG01 X0.0\nM30\n")
    imp = read_program(_write(tmp_path, "restart.nc", text), part_radius=0.7, points_per_rev=90)
    p, lines = imp.program, imp.file_line
    stood = np.isin(lines, (8, 9))
    k0, k1 = np.flatnonzero(stood)[[0, -1]]
    # the spindle's angle does not advance over the stopped rapids
    assert np.all(p.theta[k0 - 1:k1 + 1] == p.theta[k0 - 1])
    # their time: 1 mm up and 0.3 mm in at 2000 mm/min
    assert p.t[k1] - p.t[k0 - 1] == pytest.approx((1.0 + 0.3) / 2000 * 60, rel=1e-12)
    # the spindle's revolutions: the turning moves' time at 1000 rpm
    dt = np.diff(p.t)
    turning = ~stood[1:]
    assert p.revolutions == pytest.approx(np.sum(dt[turning]) * 1000 / 60, rel=1e-9)
    assert "stands (M05) in 2 rapid moves (lines 8 .. 9), 0.039 s" in imp.inferred["spindle"]
    # after the restart: the 0.01 mm plunge and the 0.3 mm face at 10 um per revolution
    k = np.flatnonzero(lines == 11)[-1]  # the rapid back to the part: the cut starts there
    revs = (p.theta[-1] - p.theta[k]) / (2 * math.pi)
    assert revs == pytest.approx(31.0, rel=1e-9)


def test_program_stops_are_noted_and_take_no_time(tmp_path):
    plain = read_program(_write(tmp_path, "plain.nc", _FACE.format(m="M03")), part_radius=0.7,
                         points_per_rev=90)
    stops = read_program(_write(tmp_path, "stops.nc", _FACE.format(m="M03").replace(
        "G01 X0.0\n", "M00\nG01 X0.3\nM01\nG01 X0.0\n")), part_radius=0.7, points_per_rev=90)
    assert stops.program.t[-1] == pytest.approx(plain.program.t[-1], rel=1e-12)
    assert np.allclose(stops.program.theta[-1], plain.program.theta[-1], rtol=1e-12)
    (note,) = [n for n in stops.facts["notes"] if "M00" in n]
    assert note.startswith("M00 (program stop) and M01 (optional stop): the program stops there "
                           "for the operator; the stop takes no machining time")
    assert not any("M00" in n for n in plain.facts["notes"])


def test_cutting_both_ways_is_refused(tmp_path):
    text = ("G71 G90 G18 G94\nG97 S1000 M03\nG95 F0.01\nG00 X0.62 Z0.01\nG01 Z0.0\nG01 X0.4\n"
            "M04\nG01 X0.0\nM30\n")
    p = _write(tmp_path, "both.nc", text)
    with pytest.raises(InputError, match=rf"^{p}:8: this cutting move turns the spindle M04, "
                                         rf"the cutting moves before it M03"):
        read_program(p, part_radius=0.7, points_per_rev=36)


# ---------------------------------------------------------------------------- C words
def _c_list(step):
    """A point list: 3 revolutions at 2 deg a point, X falling 0.02 mm a revolution; C
    turning by ``step`` deg a point and wrapping at 360."""
    n = 3 * 180 + 1
    c = np.mod(np.arange(n) * step, 360.0)
    x = 0.5 - 0.02 * np.arange(n) / 180
    return "".join(f"C{c[i]:.3f} X{x[i]:.6f} Z0\n" for i in range(n))


def test_c_decreasing_is_the_other_hand(tmp_path):
    """C decreasing throughout (as M04 in C-axis mode): the path of C increasing, marked
    M04; the part's angle of each point is its C."""
    up = read_program(_write(tmp_path, "up.nc", _c_list(2.0)), part_radius=0.6)
    down = read_program(_write(tmp_path, "down.nc", _c_list(-2.0)), part_radius=0.6)
    from render_inspect.core.toolpath import part_angle
    for k in ("theta", "rho", "z", "t"):
        assert np.allclose(getattr(up.program, k), getattr(down.program, k), rtol=0, atol=1e-12), k
    assert down.program.meta["spindle_direction"] == "M04"
    assert "decreases: the spindle turns the other way (as M04)" in down.inferred["c"]
    assert np.allclose(part_angle(down.program), -up.program.theta, atol=1e-12)


def test_spindle_words_with_c_words_are_noted(tmp_path):
    """With C words the C words set the angle: M04 there is noted, C increasing cuts the
    M03 hand."""
    text = "G97 S100 M04\nG94 F1\n" + _c_list(2.0)
    imp = read_program(_write(tmp_path, "c_m04.nc", text), part_radius=0.6)
    assert "spindle_direction" not in imp.program.meta
    (note,) = [n for n in imp.facts["notes"] if n.startswith("M04 in a program with C words")]
    assert "C is increasing: the spindle turns as with M03" in note


def test_c_turning_round_is_refused(tmp_path):
    p = _write(tmp_path, "round.nc", "C0 X1 Z0\nC-10 X1 Z0\nC-20 X1 Z0\nC-15 X1 Z0\n")
    with pytest.raises(InputError, match=rf"^{p}:4: C increases by 5 deg .* whose C decreases"):
        read_program(p, part_radius=1.0)


# ---------------------------------------------------------------------------- files
def test_program_files_are_in_the_parts_angles(tmp_path):
    """An M04 path written as npz, CSV and the project's NC program: the part's own
    angles (decreasing), read back as the same M04 path."""
    m04 = read_program(_write(tmp_path, "m04.nc", _FACE.format(m="M04")), part_radius=0.7,
                       points_per_rev=90).program
    npz = write_toolpath_npz(tmp_path / "p.npz", m04)
    with np.load(npz) as d:
        assert np.array_equal(d["theta"], -m04.theta + 0.0)
        assert np.array_equal(d["y"], -m04.y) and str(d["spindle_direction"]) == "M04"
    nc = write_nc(tmp_path / "p.nc", m04)
    assert "; spindle_direction: M04" in nc.read_text()
    for back in (read_toolpath_npz(npz), read_csv(write_csv(tmp_path / "p.csv", m04)),
                 read_nc(nc)):
        assert back.meta["spindle_direction"] == "M04"
        assert np.allclose(back.theta, m04.theta, rtol=0, atol=1e-8)
        assert np.array_equal(back.rho, m04.rho) or np.allclose(back.rho, m04.rho, atol=5e-7)


def _tiled_pair(tmp_path, overrides, tile, program=_FACE, figures=None):
    """The M04 ``program`` simulated in memory and tile by tile (tiles of ``tile``): the
    in-memory Simulation, the tiled run's metrics and its store (``figures``: a dict that
    gets the in-memory run's figure specs)."""
    from render_inspect.io._zarr import ZarrHeightMap
    from render_inspect.pipeline import run_simulate, simulate
    from render_inspect.scene import load_scene
    p = _write(tmp_path, "m04.nc", program.format(m="M04"))
    sc = load_scene("sts_fig16_overcut", [f"process.program={json.dumps(str(p))}",
                                          "process.workpiece_radius=0.7", *overrides])
    mem = simulate(sc, figures=None if figures is None else figures.update)
    tiled = run_simulate(sc, tmp_path / "tiled", tiled=True, tile=tile)
    return mem, tiled, ZarrHeightMap(tmp_path / "tiled" / "heightmap.zarr")


def _same_maps(mem, z):
    """The store holds the in-memory maps as heightmap.exr does (float32; the residual
    formed in float64)."""
    hm = mem.heightmap
    want = {"design": hm.design, "machined": hm.machined, "residual": hm.machined - hm.design}
    for name, a in want.items():
        assert np.array_equal(z.read(name), a.astype(np.float32), equal_nan=True), name


def test_tiles_cut_m04_as_in_memory(tmp_path):
    """A program turning M04 tile by tile (the mirror image cut in tiles, the store's rows
    turned over): the in-memory map to the last bit, in the part's own coordinates (a grid
    of 276 rows: tiles of 64 do not divide it, the mirrored tiles straddle the stored
    chunks), its pyramid that of the map, its metadata M04."""
    from render_inspect.io._pyramid import pyramid
    region = [0.1, -0.3, 0.2, 0.25]
    mem, tiled, z = _tiled_pair(tmp_path, [
        "process.points_per_rev=90", f"simulation.region={region}", "machine.preset='ideal'",
        "material.preset='ideal'"], 64)
    assert z.read("machined").shape == (276, 51) and tiled["tiles"]["count"] == 5
    _same_maps(mem, z)
    full = z.read("residual")
    assert z.attrs["levels"] and np.isfinite(full).all()
    for k, want in enumerate(pyramid(full, len(z.attrs["levels"])), start=1):
        assert np.array_equal(z.read("residual", level=k), want, equal_nan=True), k
    assert z.attrs["origin_mm"] == list(mem.heightmap.origin) == region[:2]
    assert json.loads(z.attrs["meta"])["spindle_direction"] == "M04"
    assert tiled["program"]["spindle_direction"] == "M04"
    for k in ("Sq_nm", "Sz_nm", "Sp_nm", "Sv_nm", "min_nm", "mean_nm"):
        assert tiled["residual"][k] == pytest.approx(mem.metrics["residual"][k], rel=1e-12, abs=1e-9), k
    assert tiled["residual"]["Sa_nm"] == pytest.approx(mem.metrics["residual"]["Sa_nm"], rel=1e-6)


#: the facing cut with a V ring (radii 0.2 .. 0.3 mm, 5 um deep): machined edges, burrs
_GROOVED = _FACE.replace("G01 X0.0\n", "G01 X0.3\nG01 X0.25 Z-0.005\nG01 X0.2 Z0.0\nG01 X0.0\n")


@pytest.mark.slow
def test_tiles_cut_m04_through_the_lathe_and_aluminium_as_in_memory(tmp_path, monkeypatch):
    """Through the shipped lathe and aluminium (error motions, texture, grooves, the burrs
    of a V ring's edges; the following error's map): tile by tile as in memory, to the
    last bit."""
    import render_inspect.pipeline._simulate_command as command
    assert _GROOVED != _FACE
    drawn, figures = {}, {}
    monkeypatch.setattr(command, "draw_figure", lambda spec, path: drawn.update({path.name: spec}))
    mem, tiled, z = _tiled_pair(tmp_path, [
        f"design={{type='expression', expr='{_DESIGN}'}}", "process.points_per_rev=720",
        f"simulation.region={_REGION}", f"simulation.pixel={_PIXEL!r}",
        "machine.preset='sts_lathe'", "material.preset='al6082'"], 64, _GROOVED, figures)
    _same_maps(mem, z)
    a, b = figures["following_error_map.png"], drawn["following_error_map.png"]
    assert b["extent"] == pytest.approx(a["extent"], rel=0, abs=1e-12)
    for k in ("x_nm", "z_nm"):
        assert np.array_equal(b[k], a[k], equal_nan=True), k
    mem = mem.metrics
    assert mem["burrs"]["edge_pixels"] > 0 and tiled["burrs"].keys() == mem["burrs"].keys()
    for k, v in mem["burrs"].items():
        assert tiled["burrs"][k] == (pytest.approx(v, rel=1e-12) if isinstance(v, float) else v), k
    assert tiled["material"]["grooves_rms_nm"] == pytest.approx(mem["material"]["grooves_rms_nm"],
                                                                rel=1e-12)
    for k in ("Sq_nm", "Sz_nm", "min_nm", "mean_nm"):
        assert tiled["residual"][k] == pytest.approx(mem["residual"][k], rel=1e-12), k
    assert (tmp_path / "tiled" / "residual.png").is_file()
