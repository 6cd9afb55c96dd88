"""Machine programs a machine can run: every process kind's NC program is written with its
links (approach, moves between cuts, exit through the clearance plane), read back,
verified block by block, and simulated again from the file; the links are checked
against the part with the tool's real footprint, independently of the verifier; unsafe
programs (the gouging straight link of the old sculpturing program, rapids below the
plane, sideways plunges, feeds over the limits, cuts below the design) are refused with
the block number."""

from __future__ import annotations

import math
import re

import numpy as np
import pytest

from render_inspect.core.toolpath import ROLE_CUT, ROLE_PLUNGE, ROLE_RAPID, ROLE_RETRACT, Blocks
from render_inspect.design import make_surface
from render_inspect.errors import InputError, SceneError
from render_inspect.io import (cut_points, program_axes, read_nc, read_nc_blocks,
                               read_program_nc, write_program_nc)
from render_inspect.pipeline import plan_program, run_toolpath, simulate
from render_inspect.processes import process_of
from render_inspect.scene import load_scene
from render_inspect.toolpath import MachineLimits, verify_blocks

#: one small scene per process kind (the shipped scenes, shrunk)
KINDS = {
    "sts": ("sts_sinusoidal_grid", ["process.workpiece_radius=0.35", "process.points_per_rev=720",
                                    "simulation.region=[-0.12,-0.12,0.12,0.12]",
                                    "simulation.pixel=0.003", "material.preset='ideal'"]),
    "fts": ("sts_fig16_overcut", ["process.kind='fts'", "machine.preset='fts'",
                                  "process.workpiece_radius=0.35", "process.points_per_rev=720",
                                  "simulation.region=[-0.12,-0.12,0.12,0.12]",
                                  "simulation.pixel=0.003", "material.preset='ideal'"]),
    "hts": ("hts_toric_msa", ["process.workpiece_radius=0.8", "process.points_per_rev=720",
                              "simulation.region=[-0.3,-0.3,0.3,0.3]", "simulation.pixel=0.005",
                              "material.preset='ideal'"]),
    "rcse": ("rcse_circular_array", ["process.workpiece_radius=1.2", "process.points_per_rev=720",
                                     "simulation.region=[0.6,-0.25,1.1,0.25]",
                                     "simulation.pixel=0.004", "rcse.compare_conventional=false",
                                     "material.preset='ideal'"]),
    "sculpt": ("sculpt_quad_mla", ["design.rows=3", "design.cols=3", "process.arc_length=0.005",
                                   "simulation.region=[-0.3,-0.3,0.3,0.3]",
                                   "simulation.pixel=0.004", "material.preset='ideal'"]),
}


def _scene(kind):
    name, sets = KINDS[kind]
    return load_scene(name, sets)


@pytest.fixture(scope="module")
def written(tmp_path_factory):
    """kind -> (scene, folder, blocks) of each kind's toolpath --format nc."""
    out = {}
    for kind in KINDS:
        scene = _scene(kind)
        folder = tmp_path_factory.mktemp(kind) / "nc"
        run_toolpath(scene, folder, fmt="nc")
        out[kind] = (scene, folder, read_nc_blocks(folder / "toolpath.nc"))
    return out


@pytest.mark.parametrize("kind", list(KINDS))
def test_written_program_has_links_and_is_the_plan(kind, written):
    import json

    scene, folder, b = written[kind]
    facts = json.loads((folder / "toolpath.json").read_text())["program_check"]
    assert facts["as_planned"]["max_deviation"] <= 5.0001e-7
    # the program starts with Z alone up to the plane, and every rapid stays in it
    zc = facts["clearance_z_mm"]
    assert b.motion[0] == 0 and all(np.isnan(b.axes[a][0]) for a in b.axes if a != "Z")
    assert b.axes["Z"][0] == pytest.approx(zc, abs=1e-9)
    rapids = np.flatnonzero(b.role == ROLE_RAPID)
    assert np.all(b.axes["Z"][rapids] >= zc - 1e-9)
    assert facts["clearance_above_part_mm"] >= scene.process.clearance - 2e-6
    # one approach and one exit; a sculpturing program one link per line after the first
    lines = len(np.unique(b.line[b.role == ROLE_CUT]))
    n_links = lines if kind == "sculpt" else 1
    assert facts["plunges"] == n_links and facts["retracts"] == n_links
    assert facts["rapids"] == n_links + 2
    # plunges and retracts run at the plunge feed
    assert facts["plunge_feed_mm_per_min"] == scene.process.plunge_feed_mm_per_min
    # the written cutting points are the plan's
    plan = plan_program(scene)
    idx = cut_points(b)
    for a, v in program_axes(plan.program).items():
        assert np.max(np.abs(b.axes[a][idx] - v)) <= 5.0001e-7, a


@pytest.mark.parametrize("kind", [pytest.param(k, marks=pytest.mark.slow) if k == "rcse" else k
                                  for k in KINDS])  # (RCSE's two cuts take seconds)
def test_program_read_back_simulates_as_planned(kind, written):
    """Parse the written program and cut it again: the surface equals the planned
    program's to the written places (1 nm in X and Z, 1e-6 deg in C)."""
    scene, folder, b = written[kind]
    process = process_of(scene)
    cfg = process.inputs_of(scene)
    surface = make_surface(scene.design)
    plan = plan_program(scene, surface=surface)
    read = read_program_nc if b.dialect == "linear" else read_nc
    program = read(folder / "toolpath.nc")
    assert program.points == plan.program.points
    planned = process.cut(cfg, surface, plan).machined
    again = process.cut(cfg, surface, process.program_plan(cfg, surface, program)).machined
    ok = np.isfinite(planned)
    assert ok.mean() > 0.5 and np.array_equal(ok, np.isfinite(again))
    assert np.max(np.abs(again[ok] - planned[ok])) < 2e-6, kind


def test_program_read_back_simulates_as_planned_with_a_material(tmp_path):
    """With a material the cut responds to the chip thickness, which a rounding of 0.5 nm
    moves across its threshold at a few pixels: the surface is the same but for those."""
    scene = load_scene(KINDS["sts"][0], KINDS["sts"][1] + ["material.preset='al6082'"])
    process = process_of(scene)
    cfg = process.inputs_of(scene)
    surface = make_surface(scene.design)
    plan = plan_program(scene, surface=surface)
    run_toolpath(scene, tmp_path / "o", fmt="nc")
    program = read_nc(tmp_path / "o" / "toolpath.nc")
    planned = process.cut(cfg, surface, plan).machined
    again = process.cut(cfg, surface, process.program_plan(cfg, surface, program)).machined
    ok = np.isfinite(planned)
    d = np.abs(again - planned)[ok]
    assert np.percentile(d, 99) < 2e-6 and np.mean(d > 2e-6) < 0.005
    sq = [np.std(m[ok]) for m in (planned, again)]
    assert sq[1] == pytest.approx(sq[0], rel=1e-3)


def _nose_clearance(part, x, y, z, u, R, hw, n=41):
    """The least height of the tool nose (a circle of radius R, half width hw, across the
    direction ``u``) above the design at the points (x, y, z): negative where it cuts."""
    s = np.linspace(-hw, hw, n)
    nose = R - np.sqrt(np.maximum(R * R - s * s, 0.0))
    px = x[:, None] + s[None, :] * u[:, 0:1]
    py = y[:, None] + s[None, :] * u[:, 1:2]
    return np.min(z[:, None] + nose[None, :] - part.height(px, py), axis=1)


@pytest.mark.parametrize("kind", list(KINDS))
def test_links_never_touch_the_part(kind, written):
    """Every rapid, plunge and retract sampled every micrometre with the nose's footprint
    (an independent check of what the verifier assumes): the nose never goes below the
    design (below its height at the cut's own point, where a plunge ends and a retract
    starts), and once higher than the stock above that point it clears the stock."""
    scene, folder, b = written[kind]
    process = process_of(scene)
    cfg = process.inputs_of(scene)
    surface = make_surface(scene.design)
    plan = plan_program(scene, surface=surface)
    part = process.program_part(cfg, surface, plan)
    R = scene.tool.nose_radius
    hw = part.half_width
    if b.dialect == "turning":
        c = np.radians(b.axes["C"])
        x, y = b.axes["X"] * np.cos(c), b.axes["X"] * np.sin(c)
    else:
        x, y = b.axes["X"], b.axes["Y"]
    z = b.axes["Z"]
    worst_far, checked = math.inf, 0
    known = np.isfinite(x) & np.isfinite(y)
    for i in np.flatnonzero(b.role != ROLE_CUT)[1:]:
        if not known[i - 1]:  # the first block's start (where the machine is) is unknown
            continue
        n = int(min(max(abs(z[i] - z[i - 1]), math.hypot(x[i] - x[i - 1], y[i] - y[i - 1]))
                    / 1e-3, 4000)) + 2
        f = np.linspace(0, 1, n)
        px, py, pz = (a[i - 1] + f * (a[i] - a[i - 1]) for a in (x, y, z))
        if b.dialect == "turning":
            r = np.maximum(np.hypot(px, py), 1e-12)
            u = np.c_[px / r, py / r]
        else:
            u = np.tile([1.0, 0.0], (n, 1))
        clear = _nose_clearance(part, px, py, pz, u, R, hw)
        low = min(z[i], z[i - 1])
        at_cut = clear[np.argmin(pz)]  # the nose at the cut's point, as the cut leaves it
        assert np.all(clear >= min(at_cut, 0.0) - 1e-9), (kind, int(b.number[i]))
        far = pz > low + part.stock + 1e-3  # above the stock over the cut's point
        assert np.all(clear[far] > part.stock), (kind, int(b.number[i]), float(clear[far].min()))
        worst_far = min(worst_far, float(clear[far].min()) if far.any() else math.inf)
        checked += n
    assert checked > 100
    # the rapids clear the part's top by the clearance
    r = np.flatnonzero(b.role == ROLE_RAPID)[1:]
    assert np.min(z[r]) - part.stock - np.nanmax(part.height(x[b.role == ROLE_CUT],
                                                             y[b.role == ROLE_CUT])) > 0.09


def test_simulate_checks_the_links():
    sim = simulate(_scene("sculpt"))
    links = sim.metrics["toolpath"]["links"]
    assert links["plunges"] == links["retracts"] == sim.metrics["sculpt"]["lines"]
    assert links["rapids_above_part_min_mm"] >= 0.1 - 2e-6
    sim = simulate(_scene("sts"))
    assert sim.metrics["toolpath"]["links"]["clearance_above_part_mm"] >= 0.1 - 2e-6


def test_a_process_stating_its_own_links_has_them_checked():
    """A process kind that overrides ``program_links`` alone (a plug-in's own clearance)
    has those links checked by ``simulate``, against its ``program_part``."""
    from dataclasses import replace

    from render_inspect.pipeline._toolpath import check_links, links_and_part

    scene = _scene("sts")
    process = process_of(scene)
    cfg = process.inputs_of(scene)
    surface = make_surface(scene.design)
    plan = plan_program(scene, surface=surface)
    base_links, part = process.program_links_part(cfg, surface, plan)
    higher = replace(base_links, clearance_z=base_links.clearance_z + 0.4)

    class OwnLinks(type(process)):
        def program_links(self, cfg, surface, plan):
            return higher

    own = OwnLinks()
    links, own_part = links_and_part(own, cfg, surface, plan)
    assert links is higher and own_part.stock == part.stock
    assert links_and_part(process, cfg, surface, plan)[0] == base_links
    checked = check_links(own, cfg, surface, plan)
    assert checked["clearance_above_part_mm"] == pytest.approx(
        simulate(scene).metrics["toolpath"]["links"]["clearance_above_part_mm"] + 0.4, abs=1e-6)


def test_clearance_key_is_validated_and_used(tmp_path):
    with pytest.raises(SceneError, match=r"process\.clearance.*0\.01"):
        load_scene("sts_sinusoidal_grid", ["process.clearance=0.001"])
    with pytest.raises(SceneError, match=r"process\.plunge_feed_mm_per_min"):
        load_scene("sculpt_quad_mla", ["process.plunge_feed_mm_per_min=0"])
    name, sets = KINDS["sculpt"]
    scene = load_scene(name, sets + ["process.clearance=2.5", "process.plunge_feed_mm_per_min=7"])
    run_toolpath(scene, tmp_path / "o", fmt="nc")
    b = read_nc_blocks(tmp_path / "o" / "toolpath.nc")
    top = float(b.meta["part_top_mm"])
    assert float(b.meta["clearance_z_mm"]) == pytest.approx(top + 2.5, abs=1e-6)
    assert np.all(b.feed[(b.role == ROLE_PLUNGE) | (b.role == ROLE_RETRACT)] == 7)


# --------------------------------------------------------------- unsafe programs refused
def _part_and_limits(kind, written):
    scene, folder, b = written[kind]
    process = process_of(scene)
    cfg = process.inputs_of(scene)
    surface = make_surface(scene.design)
    plan = plan_program(scene, surface=surface)
    links = process.program_links(cfg, surface, plan)
    return process.program_part(cfg, surface, plan), process.program_limits(cfg), links


def _edit(path, tmp_path, fn):
    lines = path.read_text().splitlines()
    out = tmp_path / "edited.nc"
    out.write_text("\n".join(fn(lines)) + "\n")
    return out


def _n_of(line: str) -> str:
    return line.split()[0]


def _check(path, part, limits, links):
    return verify_blocks(read_nc_blocks(path), part, limits, links)


def test_the_old_sculpturing_program_is_refused(tmp_path, written):
    """The program without links (each line fed straight into the next at the ridge
    height) is refused: it does not start from the clearance plane, and its diagonal
    feed moves across the array are no cut of the plan."""
    scene, folder, _ = written["sculpt"]
    part, limits, links = _part_and_limits("sculpt", written)
    plan = plan_program(scene)
    old = write_program_nc(tmp_path / "old.nc", plan.program)
    with pytest.raises(InputError, match=r"block N1 \(G01, cut\).*start with a rapid"):
        _check(old, part, limits, links)

    # the same straight link inside a program that has an approach
    def straight_link(lines):
        out, skip = [], 0
        for line in lines:
            if line == "; link":
                skip = 3
                continue
            if skip:
                skip -= 1
                continue
            out.append(line)
        return out

    bad = _edit(folder / "toolpath.nc", tmp_path, straight_link)
    with pytest.raises(InputError, match=r"\(G01, cut\): a cutting move of 0\.[1-9]\d* mm, longer"):
        _check(bad, part, limits, links)


def _mutate(kind, written, tmp_path, pick, change):
    """Apply ``change`` to the first block line ``pick`` selects; return the file and
    the block's N word."""
    _, folder, _ = written[kind]
    state = {}

    def fn(lines):
        out = []
        for line in lines:
            if "n" not in state and pick(line, out):
                state["n"] = _n_of(line)
                line = change(line)
            out.append(line)
        return out

    return _edit(folder / "toolpath.nc", tmp_path, fn), state["n"]


def _sub(word, value):
    return lambda line: re.sub(rf"{word}-?[0-9.e+]+", f"{word}{value}", line)


CASES = [
    # (kind, what the block is, how it is changed, message)
    ("sculpt", lambda ln, out: ln.startswith("N") and " G00 " in ln and "X" in ln and len(out) > 20,
     _sub("Z", "0.004"), "leaves the clearance plane"),
    ("sculpt", lambda ln, out: out and out[-1] == "; link", _sub("X", "0.5"), "must be vertical"),
    ("sculpt", lambda ln, out: ln.startswith("N") and " G01 " in ln and "F100" in ln and len(out) > 40,
     _sub("F", "200000"), "feed 200000 mm/min over"),
    ("sculpt", lambda ln, out: ln.startswith("N") and "F100" in ln and len(out) > 40,
     lambda ln: re.sub(r"Z(-?[0-9.]+)", lambda m: f"Z{float(m.group(1)) - 0.002:.6f}", ln),
     "below the design"),
    ("sculpt", lambda ln, out: ln.startswith("N1 "), lambda ln: "N1 G00 X0 Y0 Z1.0",
     "raises Z alone"),
    ("sts", lambda ln, out: ln.startswith("N") and " F" in ln and len(out) > 60,
     lambda ln: re.sub(r"F([0-9.e+]+)", lambda m: f"F{float(m.group(1)) * 20:.10g}", ln),
     "the C axis turns at"),
    ("sts", lambda ln, out: ln.startswith("N") and " G00 C" in ln, _sub("Z", "0.001"),
     "leaves the clearance plane"),
    ("sts", lambda ln, out: out and out[-1] == "; exit", _sub("Z", "0.0001"),
     "must reach the clearance plane"),
    ("hts", lambda ln, out: ln.startswith("N") and " G01 " in ln and len(out) > 500,
     _sub("X", "9.0"), "outside the part"),
    ("rcse", lambda ln, out: ln.startswith("N3 "),
     lambda ln: re.sub(r"X([0-9.]+)", lambda m: f"X{float(m.group(1)) - 0.1:.6f}", ln),
     "must be vertical"),
]


@pytest.mark.parametrize("case", CASES, ids=lambda c: f"{c[0]}-{c[3]}")
def test_unsafe_programs_are_refused_naming_the_block(case, tmp_path, written):
    kind, pick, change, message = case
    part, limits, links = _part_and_limits(kind, written)
    path, n = _mutate(kind, written, tmp_path, pick, change)
    with pytest.raises(InputError, match=rf"block {n} \(.*{re.escape(message)}"):
        _check(path, part, limits, links)


def test_a_failed_verification_writes_nothing(tmp_path, monkeypatch):
    """The toolpath command checks the program before putting the folder in place: a
    program over the machine's limits is refused, the folder is never written."""
    scene = _scene("sculpt")
    process = process_of(scene)
    monkeypatch.setattr(type(process), "program_limits",
                        lambda self, cfg: MachineLimits(source="a slow test machine",
                                                        feed_mm_per_min=50.0))
    with pytest.raises(InputError, match=r"toolpath\.nc block N\d+ .*a slow test machine"):
        run_toolpath(scene, tmp_path / "o", fmt="nc")
    assert not (tmp_path / "o").exists()
    assert not [p for p in tmp_path.iterdir() if ".partial" in p.name]


def _cut_points_walked(b: Blocks) -> np.ndarray:
    """The cutting points found block by block: each run of cutting blocks with one line
    label, from the point the block before it leaves the tool on when that one does not
    cut (a plunge), else from its own first block."""
    idx: list[int] = []
    i, n = 0, b.count
    while i < n:
        if b.role[i] != ROLE_CUT:
            i += 1
            continue
        j = i
        while j < n and b.role[j] == ROLE_CUT and b.line[j] == b.line[i]:
            j += 1
        idx.extend(range(i - 1 if i > 0 and b.role[i - 1] != ROLE_CUT else i, j))
        i = j
    return np.asarray(idx, dtype=np.int64)


@pytest.mark.parametrize("dialect", ["turning", "linear"])
def test_cut_points_are_the_runs_walked_block_by_block(dialect):
    """The cutting points taken from the runs of cutting blocks at once equal those found
    walking the program block by block, on random programs: roles in runs, line labels
    that change inside a run of cutting blocks, a program that starts or ends cutting, one
    that never cuts."""
    rng = np.random.default_rng(3)
    axes = ("C", "X", "Z") if dialect == "turning" else ("X", "Y", "Z")
    roles = np.array([ROLE_CUT, ROLE_RAPID, ROLE_PLUNGE, ROLE_RETRACT], dtype=np.int8)
    for case in range(300):
        n = int(rng.integers(0, 60))
        role = roles[np.repeat(rng.integers(0, 4, size=n), rng.integers(1, 6, size=n))][:n]
        if case % 7 == 0:
            role[:] = ROLE_RAPID
        line = np.where(role == ROLE_CUT, np.cumsum(rng.random(role.size) < 0.1), -1).astype(np.int64)
        m = role.size
        b = Blocks(dialect, np.arange(1, m + 1, dtype=np.int64), np.ones(m, dtype=np.int8), role,
                   {a: rng.random(m) for a in axes}, np.full(m, 10.0), line,
                   {"_file_line": np.arange(1, m + 1, dtype=np.int64)})
        got, want = cut_points(b), _cut_points_walked(b)
        assert got.dtype == np.int64 and np.array_equal(got, want), case
    # a run whose first point lacks a word is named by its file line, the first such run
    b = Blocks(dialect, np.arange(1, 5, dtype=np.int64), np.ones(4, dtype=np.int8),
               np.array([ROLE_RAPID, ROLE_CUT, ROLE_CUT, ROLE_CUT], dtype=np.int8),
               {a: np.array([np.nan, 1.0, 2.0, 3.0]) for a in axes}, np.full(4, 10.0),
               np.array([-1, 0, 0, 0]), {"_file_line": np.array([7, 8, 9, 10])})
    with pytest.raises(InputError, match=rf"^prog:7: first motion block lacks the {axes[0]} word"):
        cut_points(b, "prog")


def test_modal_feed_of_a_linear_program_is_the_last_written():
    """An X-Y-Z program's F is modal: each block without one takes the last written before
    it (none before the first), as a block-by-block walk carries it."""
    rng = np.random.default_rng(5)
    from render_inspect.io._nc_parse import _ffill
    for _ in range(200):
        feed = rng.random(int(rng.integers(0, 40))) * 100
        feed[rng.random(feed.size) < 0.6] = np.nan
        walked, last = feed.copy(), math.nan
        for i in range(feed.size):
            if math.isnan(walked[i]):
                walked[i] = last
            last = walked[i]
        assert np.array_equal(_ffill(feed, math.nan), walked, equal_nan=True)
