"""The one-screen summaries on stdout: ``compare`` and ``demo`` (the two variants'
headline numbers and the path of ``report.html``), ``measure`` and ``analyze``."""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Any


def _print_compare_summary(metrics: dict, out: str, seconds: float) -> None:
    from rich.console import Console
    from rich.table import Table

    # the pipeline is imported lazily (see _run)
    from ..pipeline import compare_summary

    con = Console(file=sys.stdout, highlight=False)
    rows, diff = compare_summary(metrics)
    va, vb = (v["name"] for v in metrics["variants"])
    # (the scene's name, with the program's file where the cut is a program read from one)
    scene = metrics.get("run_name") or metrics.get("scene", {}).get("name", "")
    t = Table(title=f"render-inspect compare: {scene} ({seconds:.0f} s)", title_justify="left",
              show_edge=False)
    # long names (a program file's) fold onto a second line rather than being cut short
    t.add_column("", overflow="fold")
    t.add_column(va, justify="right", overflow="fold")
    t.add_column(vb, justify="right", overflow="fold")
    for r in rows:
        t.add_row(*r)
    con.print(t)
    # lines are not wrapped: a path must stay one piece to be copied
    if metrics.get("pair", {}).get("identical"):
        con.print(f"The two variants are identical ({metrics['pair']['key']} has no effect here).",
                  soft_wrap=True)
    else:
        for k, v in diff:
            con.print(f"{k}: {v}", soft_wrap=True)
    con.print(f"report: {metrics.get('report') or (out.rstrip('/') + '/report.html')}",
              soft_wrap=True, markup=False)


def _print_profile_compare_summary(metrics: dict, out: str, seconds: float) -> None:
    """``compare --measured PROFILE``: the three profiles' parameters side by side, the
    registration, the warnings and the path of report.html."""
    from rich.console import Console
    from rich.table import Table

    # the pipeline is imported lazily (see _run)
    from ..pipeline import PROFILE_COLUMNS, profile_compare_summary

    con = Console(file=sys.stdout, highlight=False)
    rows, lines = profile_compare_summary(metrics)
    name = Path(str((metrics.get("input") or {}).get("path", ""))).name
    t = Table(title=f"render-inspect compare: {name} against "
                    f"{metrics.get('run_name') or metrics.get('scene', '')} "
                    f"({seconds:.0f} s)", title_justify="left", show_edge=False)
    t.add_column("", overflow="fold")
    for _, head in PROFILE_COLUMNS:
        t.add_column(head, justify="right", overflow="fold")
    for r in rows:
        t.add_row(*r)
    con.print(t)
    for line in lines:
        con.print(line, soft_wrap=True, markup=False)
    con.print(f"report: {str((Path(out) / 'report.html').resolve())}", soft_wrap=True,
              markup=False)


#: commands whose summary rows pipeline.command_summary gives
ROW_SUMMARIES = ("toolpath", "characterise", "render")


def _print_summary(command: str, metrics: dict, out: str, seconds: float) -> None:
    """``measure``, ``analyze`` (and :data:`ROW_SUMMARIES`): their headline numbers and
    where the files are."""
    from rich.console import Console
    from rich.table import Table

    # the pipeline is imported lazily (see _run)
    from ..pipeline import analyze_summary, command_summary, measure_summary

    src: Any  # where the numbers come from: the output folder, or the input file
    if command in ROW_SUMMARIES:
        rows, src = command_summary(command, metrics, out), out
    else:
        rows = measure_summary(metrics) if command == "measure" else analyze_summary(metrics)
        src = metrics.get("source") if command == "measure" else metrics.get("input", {}).get("path")
    con = Console(file=sys.stdout, highlight=False)
    t = Table(title=f"render-inspect {command}: {Path(str(src)).name} ({seconds:.0f} s)",
              title_justify="left",
              show_edge=False, show_header=False)
    t.add_column("")
    t.add_column("")
    for r in rows:
        t.add_row(*r)
    con.print(t)
    con.print(f"output: {str(Path(out).resolve())}", soft_wrap=True, markup=False)
