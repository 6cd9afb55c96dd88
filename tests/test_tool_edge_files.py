"""Measured cutting edges as tool makers and microscopes write them: every layout the
reader takes gives back the known edge it was written from, the cut prints it, and a
file that cannot be read right is refused in one line; what the cut takes from beyond the
measurement is said."""

from __future__ import annotations

import math

import numpy as np
import pytest

from render_inspect.core.errors import InputError, SceneError
from render_inspect.toolpath import EdgeProfile, edge_notes, edge_of, read_edge_file

from test_tool_edge import _Bowl, _cut  # noqa: E402  (the imprint's forward model)

NM = 1e-6  # mm per nm
AMP_NM, PERIOD_DEG, PHASE_DEG = 300.0, 12.0, 40.0


def _known(theta_rad):
    """The edge the files are written from: delta(theta), nm."""
    return AMP_NM * np.cos(2 * np.pi * np.degrees(theta_rad) / PERIOD_DEG + math.radians(PHASE_DEG))


ANG = np.linspace(-40.0, 40.0, 321)
DEV = _known(np.radians(ANG))


def _rows(fmt, ang=ANG, dev=DEV, sep="\n"):
    return sep.join(fmt(a, d) for a, d in zip(ang, dev)) + sep


LAYOUTS = {
    "plain": "angle_deg, deviation_nm\n" + _rows(lambda a, d: f"{a:.4f}, {d:.6f}"),
    "radians": "angle_rad, deviation_nm\n" + _rows(lambda a, d: f"{math.radians(a):.10f}, {d:.6f}"),
    "micrometres_micro_sign": "angle [deg], deviation [\u00b5m]\n" + _rows(lambda a, d: f"{a:.4f}, {d / 1e3:.9f}"),
    "micrometres_greek_mu": "angle (deg)\tdeviation (\u03bcm)\n" + _rows(lambda a, d: f"{a:.4f}\t{d / 1e3:.9f}"),
    "columns_swapped": "deviation_nm, angle_deg\n" + _rows(lambda a, d: f"{d:.6f}, {a:.4f}"),
    "decreasing_angles": "angle_deg, deviation_nm\n" + _rows(lambda a, d: f"{a:.4f}, {d:.6f}",
                                                             ANG[::-1], DEV[::-1]),
    "semicolons_decimal_commas": "angle_deg;deviation_nm\n" + _rows(
        lambda a, d: f"{a:.4f};{d:.6f}".replace(".", ",")),
    "names_with_spaces": "angle deg, deviation nm\n" + _rows(lambda a, d: f"{a:.4f}, {d:.6f}"),
    "bom_crlf_comments": "\ufeff# certificate 4711\r\n# nose 0.5 mm\r\nangle_deg, deviation_nm  # header\r\n"
                         + _rows(lambda a, d: f"{a:.4f}, {d:.6f}", sep="\r\n"),
    "radius_itself": "angle_deg, radius_mm\n" + _rows(lambda a, d: f"{a:.4f}, {0.5 + d * 1e-6:.12f}"),
}


@pytest.mark.parametrize("layout", sorted(LAYOUTS))
def test_every_layout_reads_the_edge_it_was_written_from(tmp_path, layout):
    p = tmp_path / "edge.csv"
    p.write_bytes(LAYOUTS[layout].encode("utf-8"))
    e = read_edge_file(p, nose_radius=0.5)
    th = np.radians(np.linspace(-39.9, 39.9, 797))
    # linear between the 0.25 deg samples of a 12 deg period: within 0.7 % of the amplitude
    assert np.max(np.abs(e.deviation(th) / NM - _known(th))) < 0.007 * AMP_NM
    assert np.max(np.abs(e.deviation(np.radians(ANG)) / NM - DEV)) < 1e-3  # the samples themselves
    assert e.covers == pytest.approx((math.radians(-40.0), math.radians(40.0)), abs=1e-9)


@pytest.mark.slow
def test_an_edge_file_in_radians_and_micrometres_prints_on_the_part_as_the_geometry_says(tmp_path):
    """A known harmonic written in another layout (radians, micrometres, decreasing rows,
    semicolons with decimal commas) moves the cut surface by -delta(theta) along its
    normal at the contact angle theta = atan(slope): the part the harmonics cut."""
    p = tmp_path / "edge.csv"
    p.write_text("deviation_um;angle_rad\n" + _rows(
        lambda a, d: f"{d / 1e3:.9f};{math.radians(a):.10f}".replace(".", ","), ANG[::-1], DEV[::-1]))
    edge = read_edge_file(p, nose_radius=0.5)
    surf = _Bowl(1.0, 1)
    x, m0 = _cut(surf, None, None)
    _, m1 = _cut(surf, None, edge)
    _, m2 = _cut(surf, None, EdgeProfile.from_harmonics([(AMP_NM, PERIOD_DEG, PHASE_DEG)]))
    theta = np.arctan(x / 1.0)  # the contact angles: 11 .. 24 deg, two periods
    predicted = -_known(theta) * NM
    measured = (m1 - m0) * np.cos(theta)
    assert np.ptp(predicted) > 500 * NM
    # first order in the edge's slope (12 deg periods: the contact slides along the edge,
    # lowering the surface by up to 50 nm here); the sign, the side and the period count
    assert np.max(np.abs(measured - predicted)) < 0.2 * AMP_NM * NM
    assert np.corrcoef(measured, predicted)[0, 1] > 0.99
    # and the part is the harmonics' own, to the 0.25 deg sampling of the file (< 1 nm)
    assert np.max(np.abs(m1 - m2)) < 2 * NM


@pytest.mark.parametrize("text, needle", [
    # an angle column without its unit: radians would be read as degrees
    ("angle, deviation_nm\n" + "".join(f"{a / 100}, 0\n" for a in range(-5, 6)),
     "angle column must name its unit, 'angle_deg' or 'angle_rad', received 'angle'"),
    # a radius column that holds the deviation
    ("angle_deg, radius_nm\n" + "".join(f"{a}, 120\n" for a in range(-5, 6)),
     "median must lie within 5 % of tool.nose_radius = 0.5 mm, received 0.00012 mm"),
    # metadata lines that are not comments before the header
    ("Tool S/N 4711\nangle_deg, deviation_nm\n" + "".join(f"{a}, 0\n" for a in range(-5, 6)),
     "line 2: line 1 ('Tool S/N 4711') and this line"),
    # a table measured from one end of the edge (0 .. 120 deg)
    ("angle_deg, deviation_nm\n" + "".join(f"{a}, 0\n" for a in range(0, 121, 10)),
     "line 12: angle must be in [-90, 90] deg"),
    ("angle_rad, deviation_nm\n" + "".join(f"{a / 10}, 0\n" for a in range(0, 20)),
     "angle must be in [-1.5708, 1.5708] rad"),
    ("angle_deg, deviation_nm\n" + "".join(f"{a}, 0\n" for a in (0, 1, 2, 3, 3, 5, 6, 7, 8)),
     "line 6: angles must increase (or all decrease), received 3 deg after 3 deg"),
    ("angle_deg, deviation_nm\n" + "".join(f"{a}, 0\n" for a in range(9)) + "9, nan\n",
     "line 11: values must be finite"),
    ("angle_deg, deviation_nm\n" + "".join(f"{a},5, 0,5\n" for a in range(9)), "decimal commas?"),
])
def test_a_file_that_cannot_be_read_right_is_refused_in_one_line(tmp_path, text, needle):
    p = tmp_path / "cert.csv"
    p.write_text(text)
    with pytest.raises(InputError) as err:
        read_edge_file(p, nose_radius=0.5)
    msg = str(err.value)
    assert needle in msg and "\n" not in msg and "cert.csv" in msg


def _xz_text(zsign):
    Rc = 0.5
    th = np.radians(ANG)
    r = Rc + DEV * NM
    x, z = 3.0 + r * np.sin(th), zsign * (7.0 - r * np.cos(th))
    return "x_um, z_um\n" + "".join(f"{a * 1e3:.6f}, {b * 1e3:.6f}\n" for a, b in zip(x, z))


def test_points_with_z_into_the_tool_are_refused_not_wrapped_round(tmp_path):
    """An (x, z) edge whose z points the other way puts the points above the fitted
    centre, at angles beyond 90 deg: refused (it read as an edge of angles near 180 deg)."""
    p = tmp_path / "xz.csv"
    p.write_text(_xz_text(+1))
    assert read_edge_file(p, nose_radius=0.5).covers[1] < math.radians(41)
    p.write_text(_xz_text(-1))
    with pytest.raises(InputError, match=r"xz.csv, line 2: .* deg from the tool axis .*negate it"):
        read_edge_file(p, nose_radius=0.5)


def test_the_cut_beyond_the_measured_edge_is_said():
    """A table of part of the edge: the angles the cut uses beyond it are named with the
    values held there; within it, nothing is said."""
    edge = EdgeProfile(np.radians(np.linspace(0.0, 15.0, 31)), np.linspace(100, -50, 31) * NM, "part.csv")
    notes = edge_notes(edge, 0.5, (math.radians(11.6), math.radians(26.7)), "the contact angles")
    assert len(notes) == 1 and "measured from 0 to 15 deg" in notes[0]
    assert "-50 nm from 15 deg up" in notes[0] and "from 0 deg down" not in notes[0]
    assert edge_notes(edge, 0.5, (math.radians(1.0), math.radians(14.0)), "the contact angles") == []
    both = edge_notes(edge, 0.5, (-math.radians(30), math.radians(30)), "the nose arc")
    assert "100 nm from 0 deg down" in both[0] and "-50 nm from 15 deg up" in both[0]


def test_a_fitted_radius_the_cut_does_not_use_is_said(tmp_path):
    p = tmp_path / "xz.csv"
    p.write_text(_xz_text(+1))
    e = read_edge_file(p, nose_radius=0.5)
    assert edge_notes(e, 0.5, (0.0, 0.1), "the contact angles") == []  # 0.2 um off, below the waviness
    notes = edge_notes(e, 0.49, (0.0, 0.1), "the contact angles")
    assert len(notes) == 1 and "set tool.nose_radius = 0.50" in notes[0]


def test_simulated_facts_carry_the_notes():
    """``metrics["tool_edge"]["warnings"]`` names the contact angles beyond the table."""
    from render_inspect.processes._edge_facts import edge_facts
    from render_inspect.toolpath import Tool

    edge = EdgeProfile(np.radians(np.linspace(0.0, 15.0, 31)), np.zeros(31), "part.csv")
    tool = Tool(0.5, edge=edge)
    region, px = (0.2, -0.01, 0.45, 0.01), 0.01
    ny, nx = 3, 26
    x = region[0] + px * np.arange(nx)
    design = np.tile(x ** 2 / 2.0, (ny, 1))  # slope x: contact angles 11.3 .. 24.2 deg
    facts, _ = edge_facts(tool, "z", design.copy(), design, region, px)
    assert facts["measured_range_deg"] == pytest.approx([0.0, 15.0])
    assert len(facts["warnings"]) == 1 and "from 15 deg up" in facts["warnings"][0]


def test_waviness_is_sampled_finely_enough_for_its_period():
    """A short period is sampled 64 times per period (0.05 deg steps alias it: a 0.6 deg
    harmonic lost up to 3 % of its amplitude between samples, and one of 0.1 deg at a
    90 deg phase vanished); a period the cut cannot resolve is refused."""
    e = EdgeProfile.from_harmonics([(100.0, 0.6, 90.0)])
    th = np.radians(np.linspace(-30.0, 30.0, 20001))
    exact = 100.0 * np.cos(2 * np.pi * np.degrees(th) / 0.6 + math.pi / 2)
    assert np.max(np.abs(e.deviation(th) / NM - exact)) < 0.2
    # a long period keeps the samples it always had
    assert EdgeProfile.from_harmonics([(100.0, 12.0, 0.0)]).angle.size == 7201
    with pytest.raises(InputError, match=r"tool.waviness\[0\] period must be >= 0.5 deg"):
        EdgeProfile.from_harmonics([(100.0, 0.1, 90.0)])
    from render_inspect.scene import load_scene

    with pytest.raises(SceneError, match=r"period must be in \[0.5, 360\] deg, received 0.1"):
        load_scene("sts_fig16_overcut", ["tool.waviness=[[300, 0.1, 90]]"])


def test_waviness_added_to_a_partial_file_continues_beyond_it(tmp_path):
    """The harmonics hold over the whole edge; only the file's deviation is held beyond
    its ends (it dropped the harmonics there), and within the file nothing changes."""
    p = tmp_path / "part.csv"
    p.write_text("angle_deg, deviation_nm\n" + "".join(f"{a}, {10 * a}\n" for a in range(-10, 11)))
    e = edge_of(str(p), [[50.0, 8.0, 0.0]])
    wav = EdgeProfile.from_harmonics([[50.0, 8.0, 0.0]])
    for deg in (-25.0, -3.3, 0.0, 7.1, 20.0, 29.0):
        th = math.radians(deg)
        file_part = 10 * max(-10.0, min(10.0, deg))
        assert float(e.deviation(th)) / NM == pytest.approx(file_part + float(wav.deviation(th)) / NM,
                                                             abs=0.05)
    assert e.covers == pytest.approx((math.radians(-10), math.radians(10)))


def test_sculpturing_refuses_a_measured_edge_it_would_not_cut():
    from render_inspect.scene import load_scene

    with pytest.raises(SceneError, match="sculpturing sweeps a circular edge"):
        load_scene("sculpt_quad_mla", ["tool.waviness=[[300, 12, 0]]"])


def test_a_note_said_before_the_run_is_not_said_again_after_it(tmp_path, capsys):
    """The fitted radius the cut does not use is a fact of the file and the scene: said
    once by ``simulate``, though both the scene's check and the run's results carry it."""
    from render_inspect.cli import main

    p = tmp_path / "xz.csv"
    p.write_text(_xz_text(+1))
    code = main(["simulate", "sts_sinusoidal_grid", "--set", f"tool.edge_profile='{p.as_posix()}'",
                 "--set", "tool.nose_radius=0.49", "--set", "simulation.region=[0, 0, 0.04, 0.04]",
                 "--out", str(tmp_path / "out"), "-q"])
    err = capsys.readouterr().err
    assert code == 0
    assert err.count("the circle fitted to tool.edge_profile") == 1, err
    facts = __import__("json").loads((tmp_path / "out" / "metrics.json").read_text())["tool_edge"]
    assert any("the circle fitted" in w for w in facts["warnings"])  # kept in the record
