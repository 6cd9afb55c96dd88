"""The section of ``report.html`` on a machine program read from a file (``--program``,
``[process] program``): what was read and inferred, every finding (moves through the part
or below the design, with their file lines), what a CAM user checks (feed per revolution
against the radius as a table and a figure, chordal error against the design, the axes'
velocities and accelerations, the spindle's C rate) and the machine limits it exceeds.

The numbers come from the variant's ``metrics.json`` (``program`` and ``toolpath``), the
figure from the variant's ``feed_per_rev.png``; a planned program has no such section.
"""

from __future__ import annotations

from collections.abc import Iterable

from ._format import fmt_number, fmt_quantity
from ._html import HtmlReport

__all__ = ["program_section", "program_figure_name", "has_program"]

#: (label, key of metrics["toolpath"], unit) of the axis rows
_AXIS_ROWS = (("X velocity, largest", "x_velocity_max_mm_s", "mm/s"),
              ("X acceleration, largest", "x_acceleration_max_mm_s2", "mm/s^2"),
              ("Z velocity, largest", "z_velocity_max_mm_s", "mm/s"),
              ("Z acceleration, largest", "z_acceleration_max_mm_s2", "mm/s^2"),
              ("cut time", "cut_time_s", "s"))


def program_figure_name(variant: str) -> str:
    """The key of the variant's feed-per-revolution figure among the page's figures."""
    return f"feed_per_rev_{variant}"


def has_program(metrics: dict, names: Iterable[str]) -> bool:
    """Whether any of the variants ``names`` cut a program read from a file."""
    return any(isinstance((metrics.get(n) or {}).get("program"), dict) for n in names)


def _finding_rows(findings: Iterable[dict]) -> list[list]:
    rows = []
    for f in findings:
        rows.append([f.get("what", f.get("kind", "")), fmt_number(f.get("points")),
                     fmt_quantity(f.get("worst_nm"), "nm"), str(f.get("worst_line")),
                     fmt_quantity(f.get("worst_radius_mm"), "mm"),
                     fmt_quantity(f.get("worst_c_deg"), "deg"),
                     ", ".join(str(k) for k in f.get("first_lines", []))])
    return rows


def _check_rows(prog: dict, tp: dict) -> list[list]:
    fpr = prog.get("feed_per_rev") or {}
    rows = [["feed per revolution, median", fmt_quantity(fpr.get("median_um"), "um")],
            ["feed per revolution, least .. largest",
             f"{fmt_quantity(fpr.get('min_um'), 'um')} .. {fmt_quantity(fpr.get('max_um'), 'um')}"],
            ["chordal error against the design, largest",
             fmt_quantity(prog.get("chordal_error_max_nm"), "nm")],
            ["spindle C rate, least .. largest",
             f"{fmt_number(prog.get('c_rate_min_rpm'))} .. {fmt_number(prog.get('c_rate_max_rpm'))} rpm"]]
    for label, key, unit in _AXIS_ROWS:
        if key in tp:
            rows.append([label, fmt_quantity(tp.get(key), unit)])
    for key, n in (tp.get("limits_exceeded") or {}).items():
        rows.append([f"points over process.{key} = {fmt_number((tp.get('limits') or {}).get(key))}",
                     fmt_number(n)])
    read = [("blocks read", "blocks"), ("motion blocks", "motion_blocks"),
            ("points kept for the simulated region", "points_kept_for_region")]
    rows += [[label, fmt_number(prog.get(k))] for label, k in read if k in prog]
    return rows


def _band_rows(prog: dict) -> list[list]:
    return [[f"{fmt_number(b.get('r_from_mm'), sig=4)} .. {fmt_number(b.get('r_to_mm'), sig=4)}",
             fmt_number(b.get("points")), fmt_quantity(b.get("mean_um"), "um"),
             fmt_quantity(b.get("min_um"), "um"), fmt_quantity(b.get("max_um"), "um")]
            for b in (prog.get("feed_per_rev") or {}).get("by_radius", [])]


def program_section(rep: HtmlReport, metrics: dict, names: Iterable[str], figs: dict) -> bool:
    """Add the section "Machine program read from a file" to the page ``rep``
    (:class:`~render_inspect.report.HtmlReport`) for each variant of ``names`` whose
    metrics hold ``program``; ``figs`` maps :func:`program_figure_name` to its PNG bytes.
    Returns whether a section was added."""
    if not has_program(metrics, names):
        return False
    rep.section("Machine program read from a file")
    rep.text("The program replaces the planned path: the machine follows its commands and the "
             "design stays the reference of the residual. Moves that end below the design or "
             "inside the part are findings of the program, reported here rather than refused: "
             "the simulation shows what they cut.")
    for name in names:
        m = metrics.get(name) or {}
        prog = m.get("program")
        if not isinstance(prog, dict):
            continue
        tp = m.get("toolpath") or {}
        rep.heading(f"{name}: {prog.get('file', '')} ({prog.get('dialect', 'unknown dialect')})")
        inferred = prog.get("inferred") or {}
        if inferred:
            rep.list(f"{k}: {v}" for k, v in inferred.items())
        findings = prog.get("findings") or []
        if findings:
            count = prog.get("findings_count")
            rep.text(f"Findings: {fmt_number(count)} point{'' if count == 1 else 's'} of the "
                     f"program (each kind with its deepest point and its first file lines).",
                     cls="note")
            rep.table(_finding_rows(findings),
                      header=["finding", "points", "deepest", "at file line", "radius",
                              "C", "first file lines"])
        else:
            rep.text("Findings: none; no move of the program ends below the design or inside "
                     "the part.")
        rep.table(_check_rows(prog, tp), header=["what a CAM user checks", "value"])
        for w in [*(prog.get("warnings") or []), *(tp.get("warnings") or [])]:
            rep.text(w, cls="note")
        png = figs.get(program_figure_name(name))
        if png is not None:
            rep.figure(png, f"{name}: the feed per revolution (how far the radius moves over "
                            f"the revolution that starts at each point) against the radius, one "
                            f"dot per program point.")
        bands = _band_rows(prog)
        if bands:
            rep.table(bands, header=["radius (mm)", "points", "feed per rev, mean", "least",
                                     "largest"])
    return True
