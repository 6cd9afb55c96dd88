"""Progress that progresses and work that stops when asked: the long kernels report their
blocks (the bar moves by the real work, with an ETA from it), and a stop requested by a
signal handler is raised at the next block boundary, in any thread."""

from __future__ import annotations

import io
import signal
import threading
import time

import numpy as np
import pytest

from render_inspect import cli
from render_inspect.core import cancel
from render_inspect.core.progress import report, set_reporter, task
from render_inspect.io import atomic_output_dir
from render_inspect.machining import _envelope
from render_inspect.machining import simulate_turning
from render_inspect.toolpath import ToolPath


class Recorder:
    """A reporter that records what it is told."""

    def __init__(self):
        self.calls = []
        self.lock = threading.Lock()

    def start(self, description, total, timed=False):
        with self.lock:
            self.calls.append(("start", description, total, timed))
            return description

    def advance(self, handle, amount):
        with self.lock:
            self.calls.append(("advance", handle, amount))

    def progress(self, handle, completed):
        with self.lock:
            self.calls.append(("progress", handle, completed))

    def update(self, handle, description):
        self.calls.append(("update", handle, description))

    def finish(self, handle):
        self.calls.append(("finish", handle))


@pytest.fixture(autouse=True)
def _clean():
    cancel.clear()
    yield
    cancel.clear()
    set_reporter(None)


def test_report_moves_the_innermost_step_forward_only():
    rec = Recorder()
    set_reporter(rec)
    with task("outer", total=10) as outer:
        with task("inner", total=4.0, timed=True) as inner:
            report(1, 4)              # a timed step switches to its measured progress
            report(3, 4)
            report(2, 4)              # never back
            assert inner.completed == pytest.approx(3.0) and not inner.timed
        report(5, 10)
        assert outer.completed == pytest.approx(5.0)
    kinds = [c for c in rec.calls if c[1] == "inner" and c[0] in ("progress", "advance")]
    assert kinds[0] == ("progress", "inner", 1.0) and kinds[1] == ("advance", "inner", 2.0)
    assert len(kinds) == 2


def test_a_requested_stop_is_raised_at_the_next_check_in_any_thread():
    cancel.request(signal.SIGTERM)
    with pytest.raises(cancel.Terminated):
        report(1, 2)
    seen = []

    def worker():
        try:
            for _ in cancel.blocks(10, 3):
                pass
        except KeyboardInterrupt as err:
            seen.append(type(err))

    th = threading.Thread(target=worker)
    th.start()
    th.join()
    assert seen == [cancel.Terminated]
    cancel.clear()
    cancel.request(signal.SIGINT)
    with pytest.raises(KeyboardInterrupt) as err:
        cancel.check()
    assert type(err.value) is KeyboardInterrupt
    cancel.clear()
    assert list(cancel.blocks(5, 2)) == [(0, 2), (2, 4), (4, 5)]


def _spiral(n_rev=40, ppr=720, r0=0.6, f=0.01):
    th = np.linspace(0, 2 * np.pi * n_rev, n_rev * ppr + 1)
    rho = r0 - f * th / (2 * np.pi)
    z = 1e-3 * np.sin(3 * th) * rho
    return ToolPath(th, rho, z, th / 10.0)


def test_envelope_in_bands_is_the_whole_grid_and_reports_each_band(monkeypatch):
    path = _spiral()
    region = (-0.2, -0.2, 0.2, 0.2)
    whole = simulate_turning(path, nose_radius=0.5, region=region, pixel=0.002, device="cpu")
    monkeypatch.setattr(_envelope, "BAND_SAMPLES", 201 * 64)  # one block row per band
    rec = Recorder()
    set_reporter(rec)
    with task("cut", total=100.0):
        banded = simulate_turning(path, nose_radius=0.5, region=region, pixel=0.002, device="cpu")
    assert np.array_equal(np.isnan(whole), np.isnan(banded))
    assert np.array_equal(whole[np.isfinite(whole)], banded[np.isfinite(banded)])
    steps = [c[2] for c in rec.calls if c[0] == "advance"]
    assert len(steps) == 4 and sum(steps) == pytest.approx(100.0)  # 201 rows: 4 bands
    # a stop asked while the kernel runs ends it at the next band
    cancel.request(signal.SIGINT)
    with pytest.raises(KeyboardInterrupt):
        simulate_turning(path, nose_radius=0.5, region=region, pixel=0.002, device="cpu")


def test_rich_bars_show_the_measured_progress_with_an_eta():
    from rich.console import Console

    rep = cli.RichReporter(Console(file=io.StringIO(), force_terminal=True, width=120))
    with rep:
        set_reporter(rep)
        with task("cut", total=5.0, timed=True) as t:
            tid = t._handle
            for k in range(1, 5):
                time.sleep(0.05)
                report(k, 10)
            state = rep._progress.tasks[[x.id for x in rep._progress.tasks].index(tid)]
            assert state.completed == pytest.approx(2.0)  # 4 of 10 of the 5-s estimate
            assert state.time_remaining is not None and state.time_remaining > 0
            assert not rep._tasks[tid]["timed"]  # no longer filled by the clock


@pytest.mark.slow
def test_cli_stops_at_the_next_block_when_asked(tmp_path, capsys):
    """In process: a stop requested while ``simulate`` works (as the signal handler does;
    here once its temporary folder has existed for a second) ends it with 143, the
    earlier folder untouched."""
    out = tmp_path / "out"
    with atomic_output_dir(out, command="simulate") as tmp:
        (tmp / "earlier.txt").write_text("earlier")
    asked = threading.Event()
    done = threading.Event()

    def busy() -> bool:
        return any(".partial-" in p.name for p in tmp_path.iterdir())

    def stop_once_busy():
        while not done.is_set() and not busy():
            time.sleep(0.02)
        if not done.wait(1.0) and busy():
            asked.set()
            cancel.request(signal.SIGTERM)

    watcher = threading.Thread(target=stop_once_busy, daemon=True)
    watcher.start()
    try:
        t0 = time.monotonic()
        rc = cli.main(["simulate", "sts_sinusoidal_grid", "--set", "simulation.region=[-2,-2,2,2]",
                       "--set", "material.preset='ideal'", "--out", str(out), "-q"])
    finally:
        done.set()
        watcher.join()
    err = capsys.readouterr().err
    assert asked.is_set(), f"simulate finished (rc {rc}) before it was asked to stop: {err}"
    assert rc == 143, err
    assert "terminated" in err and time.monotonic() - t0 < 60
    assert sorted(p.name for p in out.iterdir()) == [".render_inspect.json", "earlier.txt"]
    assert cancel.requested() is None  # cleared for the next run


def test_a_step_known_by_its_expected_time_keeps_moving():
    """Without measured progress the bar follows the clock to 80 % of the expected time,
    then slows without stopping or reaching the end (no bar sitting at 99 %)."""
    f = [cli.timed_fill(e, 10.0) for e in np.linspace(0, 60, 601)]
    assert f[40] == pytest.approx(4.0) and all(b > a for a, b in zip(f, f[1:]) if b < 9.999)
    assert max(f) < 10.0 and f[150] > 9.9


def test_a_stop_inside_a_deferred_block_is_raised_when_it_ends():
    """Inside :func:`cancel.deferred` the handlers only record a stop; it is raised as the
    block ends (nested blocks: as the outermost ends), not before."""
    cancel.clear()
    steps = []
    with pytest.raises(cancel.Terminated):
        with cancel.deferred():
            with cancel.deferred():
                cancel.request(signal.SIGTERM)
                assert cancel.deferring()
                steps.append("inner")
            steps.append("outer")
    assert steps == ["inner", "outer"] and not cancel.deferring()
    cancel.clear()
    with cancel.deferred():
        pass  # nothing asked: nothing raised
