"""Progress of long steps, reported to whoever listens.

The pipeline marks its steps with :func:`task`; what is shown is up to the reporter the
caller installs with :func:`set_reporter` (the command line shows rich progress bars with
an ETA; the Blender add-on may show its own).  Without a reporter every step is logged
to the ``render_inspect`` logger at DEBUG level when it ends, with its duration.

>>> with task("simulate", total=3) as t:
...     for part in range(3):
...         t.advance()

Long computations deeper down (kernels run in blocks) call :func:`report` ``(done,
total)`` between their blocks: the innermost running step's bar moves to that fraction
(never back), its ETA comes from the real progress, and a stop asked by a signal
(:mod:`render_inspect.core.cancel`) is raised there.
"""

from __future__ import annotations

from typing import Any
from collections.abc import Iterator
import contextlib
import logging
import threading
import time

from . import cancel

__all__ = ["task", "set_reporter", "get_reporter", "Task", "report"]

log = logging.getLogger("render_inspect")

_STATE: dict = {"reporter": None, "running": []}
_LOCK = threading.Lock()


class Task:
    """A running step: :meth:`advance` it, or :meth:`update` its description."""

    def __init__(self, description: str, total: float | None, reporter: Any, timed: bool = False):
        self.description = description
        self.total = total
        self.timed = timed
        self.completed = 0.0
        self.t0 = time.perf_counter()
        cancel.check()  # a new step does not start once a signal asked to stop
        self._reporter = reporter
        self._handle = reporter.start(description, total, timed) if reporter is not None else None

    def advance(self, amount: float = 1.0) -> None:
        self.completed += amount
        if self._reporter is not None:
            self._reporter.advance(self._handle, amount)
        cancel.check()

    def update(self, description: str) -> None:
        self.description = description
        if self._reporter is not None:
            self._reporter.update(self._handle, description)
        cancel.check()

    def report(self, done: float, total: float) -> None:
        """The step is ``done`` of ``total`` through (any units): the bar moves to that
        fraction of :attr:`total` (never back); a step estimated by time
        (``timed``) is shown by its real progress from then on."""
        if not total or total <= 0 or self.total is None:
            return
        frac = min(max(float(done) / float(total), 0.0), 1.0)
        target = frac * float(self.total)
        if target <= self.completed:
            return
        if self.timed:
            self.timed = False
            show = getattr(self._reporter, "progress", None)
            if show is not None:  # reporters that tell a timed bar from a measured one
                self.completed = target
                show(self._handle, target)
                return
        self.advance(target - self.completed)

    @property
    def elapsed(self) -> float:
        return time.perf_counter() - self.t0

    def _finish(self) -> None:
        if self._reporter is not None:
            self._reporter.finish(self._handle)
        log.debug("%s: %.2f s", self.description, self.elapsed)


@contextlib.contextmanager
def task(description: str, total: float | None = None, *, timed: bool = False) -> Iterator[Task]:
    """Mark a step of the work (a context manager yielding a :class:`Task`).

    Parameters
    ----------
    description : str
        What the step does, for people ("simulate compensated").
    total : float, optional
        Units of work (``Task.advance`` adds to them); None for a step that is not
        subdivided (shown with its elapsed time only).
    timed : bool
        ``total`` is the step's expected duration in seconds (a model's estimate): the
        reporter fills the bar with the elapsed time (never past 99 % before the step
        ends), which gives an ETA for a step that cannot report its own progress.
    """
    t = Task(description, total, _STATE["reporter"], timed)
    with _LOCK:
        _STATE["running"].append(t)
    try:
        yield t
    finally:
        with _LOCK:
            if t in _STATE["running"]:
                _STATE["running"].remove(t)
        t._finish()


def report(done: float, total: float) -> None:
    """Called by long computations between their blocks (in any thread): the innermost
    running step (:func:`task`) is ``done`` of ``total`` through; then the stop asked by a
    signal, if any, is raised (:func:`render_inspect.core.cancel.check`)."""
    with _LOCK:
        t = _STATE["running"][-1] if _STATE["running"] else None
    if t is not None:
        t.report(done, total)
    cancel.check()


def set_reporter(reporter: Any) -> Any:
    """Install ``reporter`` (an object with ``start(description, total, timed) -> handle``,
    ``advance(handle, amount)``, ``update(handle, description)`` and
    ``finish(handle)``; optionally ``progress(handle, completed)``, which shows a step
    started as ``timed`` by its measured progress from then on), or None; return the
    previous one."""
    old = _STATE["reporter"]
    _STATE["reporter"] = reporter
    return old


def get_reporter() -> Any:
    """The installed reporter, or None."""
    return _STATE["reporter"]
