"""The command line's output: progress, -q / -v, logging, the compare summary."""

from __future__ import annotations

import io
import subprocess
import sys
import time

import pytest

from render_inspect.core.progress import set_reporter, task


def _cli(*args):
    return subprocess.run([sys.executable, "-m", "render_inspect.cli", *map(str, args)],
                          capture_output=True, text=True)


@pytest.mark.slow
def test_quiet_simulate_says_nothing(tmp_path, tiny_scene):
    p = tiny_scene
    r = _cli("simulate", p, "--out", tmp_path / "q", "-q")
    assert r.returncode == 0, r.stderr
    assert r.stderr == "" and r.stdout == ""
    from render_inspect.cli import build_parser

    args = build_parser().parse_args(["-q", "simulate", str(p), "--out", "x"])  # before too
    assert args.quiet and not args.verbose


@pytest.mark.slow
def test_verbose_lists_every_step(tmp_path, tiny_scene):
    p = tiny_scene
    r = _cli("simulate", p, "--out", tmp_path / "v", "-v")
    assert r.returncode == 0, r.stderr
    assert "sts: plan the tool path:" in r.stderr and "sts: cut" in r.stderr
    assert "done in" in r.stderr


@pytest.mark.slow
def test_quiet_and_verbose_exclude_each_other(tmp_path):
    r = _cli("simulate", "sts_fig16_overcut", "--out", tmp_path / "x", "-q", "-v")
    assert r.returncode == 2 and "not allowed with" in r.stderr


def test_rich_progress_shows_eta_for_long_steps():
    from rich.console import Console

    from render_inspect.cli import RichReporter

    buf = io.StringIO()
    con = Console(file=buf, force_terminal=True, width=100)
    with RichReporter(con) as rep:
        old = set_reporter(rep)
        try:
            with task("short step"):
                pass
            with task("long step", total=4) as t:
                for _ in range(4):
                    time.sleep(0.4)
                    t.advance()
            with task("timed step", total=3.0, timed=True):
                time.sleep(1.5)
        finally:
            set_reporter(old)
    text = buf.getvalue()
    assert "long step" in text and "timed step" in text and "ETA" in text
    assert "short step" not in text  # shorter than a second: never shown


@pytest.mark.mitsuba
@pytest.mark.slow
def test_compare_prints_a_summary_with_the_report_path(tmp_path, tiny_scene):
    p = tiny_scene
    out = tmp_path / "cmp"
    r = _cli("compare", p, "--out", out)
    assert r.returncode == 0, r.stderr
    lines = r.stdout.strip().splitlines()
    assert len(lines) <= 20  # one screen
    text = r.stdout
    assert "compensated" in text and "uncompensated" in text
    assert "residual Sq" in text and "nm" in text
    assert f"report: {(out / 'report.html').resolve()}" in text
    assert "compensated - uncompensated" in text
    # the progress of the steps went to stderr (plain log lines without a terminal)
    assert "compensated: simulate" in r.stderr or "done in" in r.stderr
