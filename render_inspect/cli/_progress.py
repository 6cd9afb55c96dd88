"""Progress on stderr: bars with an ETA on a terminal (rich), else one log line per step
that ran longer than :data:`SHOW_AFTER_S`; log records printed above the bars."""

from __future__ import annotations

import logging
import math
import sys
import threading
import time
from typing import Any

from ._args import log

#: steps shorter than this are not shown
SHOW_AFTER_S = 1.0


class RichReporter:
    """Progress bars (rich) on stderr: one row per running step, shown once the step has
    run for :data:`SHOW_AFTER_S`, with its bar, elapsed time and ETA."""

    def __init__(self, console):
        from rich.progress import (
            BarColumn,
            Progress,
            SpinnerColumn,
            TaskProgressColumn,
            TextColumn,
            TimeElapsedColumn,
            TimeRemainingColumn,
        )

        self._progress = Progress(SpinnerColumn(), TextColumn("{task.description}"), BarColumn(),
                                  TaskProgressColumn(), TimeElapsedColumn(), TextColumn("ETA"),
                                  TimeRemainingColumn(), console=console, transient=True)
        self._lock = threading.Lock()
        self._tasks = {}  # id -> dict(start, total, timed, shown)
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._tick, daemon=True)

    def __enter__(self):
        self._progress.start()
        self._thread.start()
        return self

    def __exit__(self, *exc):
        self._stop.set()
        self._thread.join(timeout=1.0)
        self._progress.stop()
        return False

    def start(self, description: str, total: float | None, timed: bool = False) -> Any:
        with self._lock:
            tid = self._progress.add_task(description, total=total, visible=False)
            self._tasks[tid] = {"start": time.monotonic(), "total": total, "timed": timed}
        return tid

    def advance(self, handle: Any, amount: float) -> None:
        with self._lock:
            if handle in self._tasks and not self._tasks[handle]["timed"]:
                self._progress.advance(handle, amount)

    def update(self, handle: Any, description: str) -> None:
        with self._lock:
            if handle in self._tasks:
                self._progress.update(handle, description=description)

    def progress(self, handle: Any, completed: float) -> None:
        """A step estimated by time reports its measured progress: shown from now on by
        it (the bar and the ETA start again from this point)."""
        with self._lock:
            info = self._tasks.get(handle)
            if info is not None and info["timed"]:
                info["timed"] = False
                self._progress.reset(handle, total=info["total"], completed=completed,
                                     visible=time.monotonic() - info["start"] >= SHOW_AFTER_S)
            elif info is not None:
                self._progress.update(handle, completed=completed)

    def finish(self, handle: Any) -> None:
        with self._lock:
            info = self._tasks.pop(handle, None)
            if info is not None:
                self._progress.remove_task(handle)

    def _tick(self):
        while not self._stop.wait(0.2):
            now = time.monotonic()
            with self._lock:
                for tid, info in self._tasks.items():
                    el = now - info["start"]
                    if el >= SHOW_AFTER_S:
                        upd = {"visible": True}
                        if info["timed"] and info["total"]:
                            upd["completed"] = timed_fill(el, info["total"])
                        self._progress.update(tid, **upd)


def timed_fill(elapsed: float, expected: float) -> float:
    """How far to fill the bar of a step known only by its expected duration: the elapsed
    time up to 80 % of the expectation, then ever more slowly towards (never reaching) the
    end, so that a step that takes longer than expected keeps moving instead of sitting
    at 99 %.  A step that reports its real progress leaves this estimate."""
    x = elapsed / expected
    frac = x if x < 0.8 else 1.0 - 0.2 * math.exp(-(x - 0.8) / 0.2)
    return frac * expected


class LogReporter:
    """Without a terminal: one log line per step that took longer than
    :data:`SHOW_AFTER_S` (its duration)."""

    def __init__(self):
        self._t = {}

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        return False

    def start(self, description: str, total: float | None, timed: bool = False) -> Any:
        h = object()
        self._t[h] = (description, time.monotonic())
        return h

    def advance(self, handle: Any, amount: float) -> None:
        pass

    def update(self, handle: Any, description: str) -> None:
        # a step of a multi-step task ended: log it, time the next one
        if handle in self._t:
            self._log(*self._t[handle])
            self._t[handle] = (description, time.monotonic())

    def finish(self, handle: Any) -> None:
        if handle in self._t:
            self._log(*self._t.pop(handle))

    @staticmethod
    def _log(desc, t0):
        dt = time.monotonic() - t0
        if dt >= SHOW_AFTER_S:
            log.info("%s: %.1f s", desc, dt)


class _NullContext:
    def __enter__(self):
        return None

    def __exit__(self, *exc):
        return False


def _reporter(args):
    if getattr(args, "quiet", False):
        return _NullContext()
    if sys.stderr.isatty():
        from rich.console import Console

        return RichReporter(Console(file=sys.stderr))
    return LogReporter()


class _RichLogHandler(logging.Handler):
    """Log records printed through the progress display's console (above the bars,
    which would otherwise be torn by direct writes to stderr)."""

    def __init__(self, console):
        super().__init__()
        self.console = console

    def emit(self, record):
        try:
            self.console.print(self.format(record), markup=False, highlight=False,
                               soft_wrap=True)
        except Exception:  # logging must never raise into the run
            self.handleError(record)
