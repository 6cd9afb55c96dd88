"""A measured cutting edge through the commands: an edge the cut cannot take is refused
before any work by every scene command, in one line; the tiled ``simulate`` says what the
whole-map one says of the edge; ``compare`` sums up the edge of both cuts; an NC program
the project wrote reads back as its own after an editor put a byte order mark before it."""

from __future__ import annotations

import json
import math
import re

import numpy as np
import pytest

from render_inspect.cli import main
from render_inspect.io import write_measurement_exr

NOSE = 0.514  # the shipped sts_sinusoidal_grid's tool.nose_radius, mm
REGION = "simulation.region=[0, 0, 0.06, 0.04]"


def _edge_file(path, deviation_nm, angles_deg):
    """An angle table of the edge: ``deviation_nm(angle_deg)`` at ``angles_deg``."""
    path.write_text("angle_deg, deviation_nm\n"
                    + "".join(f"{a:.6f}, {deviation_nm(a):.6f}\n" for a in angles_deg))
    return path


def _big(tmp_path):
    # 400 nm per degree over +-30 deg: 12000 nm at the ends, beyond 1 % of 0.514 mm (5140 nm)
    return _edge_file(tmp_path / "big.csv", lambda a: 400.0 * a, np.arange(-30.0, 30.5, 3.0))


def _one_line(capsys, command):
    err = [ln for ln in capsys.readouterr().err.strip().splitlines() if ln.strip()]
    assert len(err) == 1 and err[0].startswith(f"render-inspect {command}: error:"), err
    return err[0]


@pytest.mark.parametrize("command", ["simulate", "toolpath", "render", "compare", "fit"])
def test_an_edge_beyond_its_bound_is_refused_before_any_work(tmp_path, capsys, monkeypatch, command):
    """|deviation| <= 1 % of the nose radius: checked before the run (the tool path is never
    planned), in one line naming tool.edge_profile, the largest deviation, the bound and
    the nose radius; exit 1 and no folder."""
    from render_inspect import processes

    edge = _big(tmp_path)

    def no_work(*args, **kwargs):
        raise AssertionError("the run started")

    monkeypatch.setattr(processes.Process, "plan", no_work)
    monkeypatch.setattr(processes.Process, "plan_window", no_work)
    args = [command, "sts_sinusoidal_grid"] if command != "fit" else \
        ["fit", str(tmp_path / "height.exr"), "--scene", "sts_sinusoidal_grid", "--free", "tool.nose_radius"]
    rc = main([*args, "--set", f"tool.edge_profile='{edge.as_posix()}'", "--set", REGION,
               "--out", str(tmp_path / "out"), "-q"])
    msg = _one_line(capsys, command)
    assert rc == 1
    assert f"tool.edge_profile {edge}" in msg
    assert "received 12000 nm" in msg and "<= 5140 nm" in msg and f"tool.nose_radius = {NOSE:g} mm" in msg, msg
    assert not (tmp_path / "out").exists() and not (tmp_path / "out.cache").exists()


def test_each_compared_variant_and_sweep_point_has_its_edge_checked_first(tmp_path, capsys):
    """An edge fine for one nose radius is refused for a smaller one: by ``compare --vary``
    before either variant is simulated, by ``sweep`` before any point runs."""
    edge = _edge_file(tmp_path / "mid.csv", lambda a: 2000.0 * a / 30.0, np.arange(-30.0, 30.5, 3.0))
    sets = ["--set", f"tool.edge_profile='{edge.as_posix()}'", "--set", REGION]
    rc = main(["compare", "sts_sinusoidal_grid", *sets, "--vary", "tool.nose_radius=0.5,0.1",
               "--out", str(tmp_path / "cmp"), "-q"])
    msg = _one_line(capsys, "compare")
    assert rc == 1 and "received 2000 nm" in msg and "tool.nose_radius = 0.1 mm" in msg, msg
    assert not (tmp_path / "cmp").exists()
    sweep = tmp_path / "sweep.toml"
    sweep.write_text(f'name = "edge"\nscene = "sts_sinusoidal_grid"\n[set]\n'
                     f'"simulation.region" = [0, 0, 0.04, 0.04]\n'
                     f'"tool.edge_profile" = "{edge.as_posix()}"\n'
                     f'[grid]\n"tool.nose_radius" = [0.1, 0.5]\n[run]\nrender = "none"\n')
    rc = main(["sweep", str(sweep), "--out", str(tmp_path / "sw"), "-q"])
    err = capsys.readouterr().err
    assert rc == 1 and "1 of 2 points are not valid" in err and "nothing was run" in err
    assert f"tool.edge_profile {edge}: |deviation| must be <= 1000 nm" in err and "[point 0]" in err, err
    assert not (tmp_path / "sw").exists()


# 50 nm per degree over +-30 deg: the largest deviation 1500 nm, 1 % of a 0.15 mm nose
def _linear(tmp_path):
    return _edge_file(tmp_path / "linear.csv", lambda a: 50.0 * a, np.arange(-30.0, 30.5, 3.0))


@pytest.mark.parametrize("kind", ["map", "profile"])
@pytest.mark.parametrize("free, bounds, expect", [
    # the nose radius down to 0.05 mm: 1500 nm is 1 % of 0.15 mm
    ("tool.nose_radius", ["tool.nose_radius=0.05,1"],
     ("tool.nose_radius = 0.05 mm", "smallest", 0.15, "mm: set the lower bound there or above")),
    # the edge's scale up to 5 on the shipped 0.514 mm nose: 5140 nm / 1500 nm = 3.4267
    ("tool.edge_scale", ["tool.edge_scale=0,5"],
     ("tool.edge_scale = 5 (", "largest", 0.01 * NOSE / 1.5e-3, ": set the upper bound there or below")),
    # both: the scale's bound with the radius at its lower bound, 0.2 mm: 2000 nm / 1500 nm
    ("tool.nose_radius,tool.edge_scale", ["tool.nose_radius=0.2,1", "tool.edge_scale=0,2"],
     ("tool.edge_scale = 2 with tool.nose_radius at its lower bound 0.2 mm", "largest", 4 / 3,
      ": set the upper bound there or below")),
])
def test_fit_bounds_the_edge_refuses_are_refused_before_any_evaluation(
        tmp_path, capsys, monkeypatch, kind, free, bounds, expect):
    """``fit`` with a measured edge and ``--bounds`` reaching where the cut refuses it (its
    deviation above 1 % of the nose radius): refused before any evaluation, in one line
    naming the key, its bound and the value the edge allows (the analytic limit, to six
    digits on the allowed side); exit 1, nothing written."""
    from render_inspect import processes

    def no_work(*args, **kwargs):
        raise AssertionError("an evaluation started")

    monkeypatch.setattr(processes.Process, "plan", no_work)
    monkeypatch.setattr(processes.Process, "plan_window", no_work)
    edge = _linear(tmp_path)
    if kind == "map":
        measured = tmp_path / "height.exr"
        write_measurement_exr(measured, np.zeros((64, 64)), np.ones((64, 64), bool), pixel=0.001,
                              origin=(0.3, 0.0), attrs={"objective": "20x", "mode": "psi"})
    else:
        measured = tmp_path / "profile.csv"
        measured.write_text("x (um), height (um)\n"
                            + "".join(f"{i * 0.87:.3f}, {0.01 * math.sin(i / 7):.5f}\n" for i in range(400)))
    rc = main(["fit", str(measured), "--scene", "sts_sinusoidal_grid", "--free", free,
               "--bounds", *bounds, "--set", f"tool.edge_profile='{edge.as_posix()}'",
               "--out", str(tmp_path / "out"), "-q"])
    msg = _one_line(capsys, "fit")
    at, word, limit, tail = expect
    assert rc == 1 and f"error: --bounds {bounds[-1]}: " in msg, msg
    assert f"the measured cutting edge is refused at {at}" in msg and "|deviation| must be <=" in msg
    shown = float(re.search(rf"the {word} value it allows is ([0-9.e+-]+)", msg).group(1))
    assert shown == pytest.approx(limit, rel=1e-5), msg
    assert (shown >= limit * (1 - 1e-12)) if word == "smallest" else (shown <= limit * (1 + 1e-12))
    assert tail in msg, msg
    assert not (tmp_path / "out").exists() and not (tmp_path / "out.cache").exists()


def test_fit_bounds_from_the_schema_are_narrowed_to_what_the_edge_allows(tmp_path, caplog):
    """Bounds the user did not give (the schema's: nose radius down to 5e-8 mm, the edge's
    scale up to 100, a waviness amplitude over +-1e9 nm) are narrowed to the values the
    measured edge allows (the analytic limits), with a warning each and a record; bounds
    inside them, and a scene without an edge, are kept."""
    from render_inspect.fit import free_parameters
    from render_inspect.pipeline._fit_edge import edge_bounds
    from render_inspect.scene import load_scene

    edge = _linear(tmp_path)
    scene = load_scene("sts_sinusoidal_grid", [f"tool.edge_profile='{edge.as_posix()}'"])
    for key, want in (("tool.nose_radius", (0.15, 50.0)), ("tool.edge_scale", (0.0, 0.01 * NOSE / 1.5e-3))):
        caplog.clear()
        params = free_parameters(scene, [key], {})
        (p,), narrowed = edge_bounds(scene, params, {})
        assert (p.lower, p.upper) == pytest.approx(want, rel=1e-5)
        assert p.start == params[0].start and 0 < p.scale <= 0.5 * (p.upper - p.lower)
        assert len(narrowed) == 1 and narrowed[0]["key"] == key and narrowed[0]["to"] in (p.lower, p.upper)
        said = [r.getMessage() for r in caplog.records if r.levelname == "WARNING"]
        assert len(said) == 1 and f"bound of {key}" in said[0] and "(the schema's), narrowed to" in said[0], said
    # inside what the edge allows: kept as given
    params = free_parameters(scene, ["tool.nose_radius"], {"tool.nose_radius": (0.2, 1.0)})
    assert edge_bounds(scene, params, {"tool.nose_radius": (0.2, 1.0)}) == (params, [])
    # a waviness amplitude (nm): at least 0 (the scene's rule), at most 1 % of the nose
    wavy = load_scene("sts_sinusoidal_grid", ["tool.waviness=[[1000.0, 10.0, 0.0]]"])
    (p,), narrowed = edge_bounds(wavy, free_parameters(wavy, ["tool.waviness.0.0"], {}), {})
    assert (p.lower, p.upper) == pytest.approx((0.0, 0.01 * NOSE * 1e6), rel=1e-5)
    assert [n["bound"] for n in narrowed] == ["lower", "upper"]
    # no measured edge: nothing to check
    plain = load_scene("sts_sinusoidal_grid")
    params = free_parameters(plain, ["tool.nose_radius"], {})
    assert edge_bounds(plain, params, {}) == (params, [])


def test_an_edge_that_folds_back_is_refused_before_the_run(tmp_path, capsys):
    """A step of the deviation steeper than the nose turns (4 um over 0.001 deg at 10 deg):
    the edge folds back over the radial offset; refused by the scene's check, naming where."""
    edge = _edge_file(tmp_path / "step.csv", lambda a: -4000.0 if a > 10.0 else 0.0,
                      [-20.0, -10.0, 0.0, 5.0, 10.0, 10.001, 15.0, 20.0, 25.0])
    rc = main(["toolpath", "sts_sinusoidal_grid", "--set", f"tool.edge_profile='{edge.as_posix()}'",
               "--out", str(tmp_path / "out"), "-q"])
    msg = _one_line(capsys, "toolpath")
    assert rc == 1 and f"tool.edge_profile {edge}: the edge folds back" in msg, msg
    assert re.search(r"offset at (9\.99\d|10) deg", msg), msg  # the step, to the check's sampling
    assert not (tmp_path / "out").exists()


def test_the_tiled_simulation_says_what_the_whole_map_says_of_the_edge(tmp_path, capsys):
    """An edge measured over +-0.02 deg, a design whose contact angles reach -0.05 deg: the
    whole-map and the tiled runs carry the same ``tool_edge`` keys and warnings, the same
    contact angles and predicted imprint, the form error of the same residual, and both
    say the warning after the run."""
    edge = _edge_file(tmp_path / "part.csv", lambda a: 5000.0 * (a + 0.02), np.linspace(-0.02, 0.02, 21))
    sets = ["--set", f"tool.edge_profile='{edge.as_posix()}'", "--set", REGION]
    facts, logs = {}, {}
    for name, extra in (("whole", []), ("tiled", ["--tiled", "--tile", "256"])):
        rc = main(["simulate", "sts_sinusoidal_grid", *sets, *extra, "--out", str(tmp_path / name), "-q"])
        logs[name] = capsys.readouterr().err
        assert rc == 0, logs[name]
        m = json.loads((tmp_path / name / "metrics.json").read_text())
        facts[name] = m["tool_edge"]
        facts[name + "_residual"] = m["residual"]
    w, t = facts["whole"], facts["tiled"]
    assert sorted(w) == sorted(t)
    assert len(w["warnings"]) == 1 and "contact angles" in w["warnings"][0]
    assert t["warnings"] == w["warnings"]
    for text in w["warnings"]:
        assert logs["tiled"].count(text) == logs["whole"].count(text) == 1
    assert t["contact_angle_range_deg"] == w["contact_angle_range_deg"]
    for key in ("imprint_predicted_pv_nm", "imprint_predicted_rms_nm"):
        assert t[key] == pytest.approx(w[key], rel=1e-9)
    assert t["form_error_rms_nm"] == pytest.approx(facts["tiled_residual"]["Sq_nm"], rel=1e-12)
    assert w["form_error_rms_nm"] == pytest.approx(facts["whole_residual"]["Sq_nm"], rel=1e-9)
    assert t["form_error_pv_nm"] == pytest.approx(w["form_error_pv_nm"], rel=1e-6)
    # the tiled run draws the whole map's figure of the edge too
    for name in ("whole", "tiled"):
        assert (tmp_path / name / "tool_edge.png").stat().st_size > 1000, name


def test_the_tiled_figure_of_the_edge_is_the_whole_maps():
    """``tool_edge.png`` of a map simulated tile by tile: the same figure data as the whole
    map's (the edge, its contact angles, the section through the middle row against the
    distance from the axis, the predicted imprint there from the design), the form error
    from the stored float32 residual's row: equal to float32's precision."""
    from render_inspect.design import make_surface
    from render_inspect.processes._edge_facts import edge_facts, edge_facts_tiled, edge_figure_tiled
    from render_inspect.toolpath import EdgeProfile, Tool

    edge = EdgeProfile(np.radians(np.linspace(-20.0, 20.0, 81)),
                       40e-6 * np.sin(np.linspace(0.0, 9.0, 81)), "part.csv")
    tool = Tool(0.5, edge=edge)
    # a paraboloid of 1 mm radius: contact angles 11 .. 24 deg over the region
    design_section = {"type": "paraboloid", "radius_x": 1.0, "radius_y": 1.0}
    region, px = (0.2, -0.011, 0.45, 0.013), 0.002
    ny, nx = 13, 126
    x = region[0] + px * np.arange(nx)
    y = region[1] + px * np.arange(ny)
    design = np.array(np.broadcast_to(make_surface(design_section).height(x[None, :], y[:, None]),
                                      (ny, nx)), dtype=np.float64)
    machined = design + 1e-5 * np.sin(40.0 * x)[None, :] + 2e-6 * np.cos(7.0 * y)[:, None]
    machined[ny // 2, 5] = np.nan  # a pixel the cut left
    facts, whole = edge_facts(tool, "z", machined, design, region, px, name="grid")
    residual = {"Sz_nm": facts["form_error_pv_nm"], "Sq_nm": facts["form_error_rms_nm"]}
    tiled_facts = edge_facts_tiled(tool, "z", design_section, region, px, residual)
    stored = (machined - design).astype(np.float32)
    rows = []
    tiled = edge_figure_tiled(tool, design_section, region, px, tiled_facts,
                              lambda r: rows.append(r) or stored[r], name="grid")
    assert rows == [ny // 2]  # one row read from the store: the middle one
    w, t = whole["tool_edge.png"], tiled["tool_edge.png"]
    assert sorted(w) == sorted(t) and t["kind"] == "tool_edge"
    for key in ("angle_deg", "delta_nm", "r_mm"):
        np.testing.assert_array_equal(t[key], w[key])
    assert t["contact_deg"] == pytest.approx(w["contact_deg"], rel=1e-12)
    np.testing.assert_allclose(t["imprint_nm"], w["imprint_nm"], rtol=0, atol=1e-9)
    assert np.ptp(w["imprint_nm"]) > 10.0  # (a section that crosses the edge's waviness)
    np.testing.assert_array_equal(np.isnan(t["error_nm"]), np.isnan(w["error_nm"]))
    # float32 of heights of ~10 nm: 1e-6 nm
    np.testing.assert_allclose(t["error_nm"], w["error_nm"], rtol=0, atol=1e-4)
    assert (t["title"], t["compensation"], t["half_angle_deg"]) == \
        (w["title"], w["compensation"], w["half_angle_deg"])


def test_a_compare_sums_up_the_edge_of_both_cuts():
    """``compare``'s top-level ``tool_edge``: the edge's source and measured range, and each
    variant's compensation, form error, predicted imprint and warnings (from the same
    facts each cut's metrics carry); its summary has a row and a line of them."""
    from render_inspect.pipeline import compare_summary
    from render_inspect.pipeline._metrics import compared_tool_edge
    from render_inspect.processes._edge_facts import edge_facts
    from render_inspect.toolpath import EdgeProfile, Tool

    edge = EdgeProfile(np.radians(np.linspace(0.0, 15.0, 31)), np.linspace(0.0, 100.0, 31) * 1e-6, "part.csv")
    tool = Tool(0.5, edge=edge)
    region, px = (0.2, -0.01, 0.45, 0.01), 0.01
    x = region[0] + px * np.arange(26)
    design = np.tile(x ** 2 / 2.0, (3, 1))  # contact angles 11.3 .. 24.2 deg: beyond 15 deg
    per = {"compensated": edge_facts(tool, "edge", design.copy(), design, region, px)[0],
           "uncompensated": edge_facts(tool, "z", design + 1e-5 * np.sin(x), design, region, px)[0]}
    top = compared_tool_edge(per)
    assert top["source"] == "part.csv" and top["measured_range_deg"] == pytest.approx([0.0, 15.0])
    for name, f in per.items():
        assert top["variants"][name]["warnings"] == f["warnings"] and len(f["warnings"]) == 1
        assert top["variants"][name]["compensation"] == f["compensation"]
        assert top["variants"][name]["form_error_rms_nm"] == f["form_error_rms_nm"]
    assert compared_tool_edge({"a": None, "b": None}) is None
    # an edge on one variant alone (--vary tool.edge_profile): the other is null
    assert compared_tool_edge({"a": per["compensated"], "b": None})["variants"]["b"] is None
    metrics = {"variants": [{"name": n, "label": n, "values": {}} for n in per],
               "difference": {}, "tool_edge": top,
               **{n: {"variant": {"label": n}, "residual": {"Sq_nm": 1.0, "min_nm": 0.0},
                      "filtered": {}, "measured": {}} for n in per}}
    rows, lines = compare_summary(metrics)
    row = [r for r in rows if r[0] == "form error rms (measured edge)"]
    assert len(row) == 1 and row[0][1].endswith("nm") and row[0][2].endswith("nm")
    line = dict(lines)["measured cutting edge"]
    assert "part.csv" in line and "measured 0 .. 15 deg" in line and "2 warning(s)" in line
    assert "imprint predicted on a path planned for the circular nose" in line


def test_an_nc_program_saved_with_a_byte_order_mark_reads_as_the_projects_own(tmp_path):
    """``toolpath --format nc``, saved again by an editor that puts a UTF-8 byte order mark
    first: still the project's own dialect, the same points bit for bit."""
    from render_inspect.io import program_dialect, read_nc_blocks, read_program

    rc = main(["toolpath", "sts_sinusoidal_grid", "--set", REGION, "--set", "process.workpiece_radius=0.1",
               "--format", "nc", "--out", str(tmp_path / "nc"), "-q"])
    assert rc == 0
    plain = tmp_path / "nc" / "toolpath.nc"
    bom = tmp_path / "bom.nc"
    bom.write_bytes(b"\xef\xbb\xbf" + plain.read_bytes())
    assert program_dialect(bom) == program_dialect(plain) == "render_inspect turning"
    a, b = read_program(plain), read_program(bom)
    assert b.dialect == a.dialect and b.inferred == a.inferred
    for k in ("theta", "rho", "z", "t"):
        assert np.array_equal(getattr(a.program, k), getattr(b.program, k)), k
    assert np.array_equal(a.file_line, b.file_line)
    ba, bb = read_nc_blocks(plain), read_nc_blocks(bom)
    assert ba.meta.keys() == bb.meta.keys() and np.array_equal(ba.number, bb.number)
    # a block an editor changed (read line by line): the mark does not matter there either
    text = bom.read_bytes().replace(b"\nN", b"\n N", 1)
    edited = tmp_path / "edited.nc"
    edited.write_bytes(text)
    assert np.array_equal(read_nc_blocks(edited).number, ba.number)
    assert math.isfinite(float(read_program(edited).program.t[-1]))
