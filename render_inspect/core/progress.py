"""Progress of long steps, reported to whoever listens.

The pipeline marks its steps with :func:`task`; what is shown is up to the reporter the
caller installs with :func:`set_reporter` (the command line shows rich progress bars with
an ETA; the Blender add-on may show its own).  Without a reporter every step is logged
to the ``render_inspect`` logger at DEBUG level when it ends, with its duration.

>>> with task("simulate", total=3) as t:
...     for part in range(3):
...         t.advance()
"""

from __future__ import annotations

import contextlib
import logging
import time

__all__ = ["task", "set_reporter", "get_reporter", "Task"]

log = logging.getLogger("render_inspect")

_STATE: dict = {"reporter": None}


class Task:
    """A running step: :meth:`advance` it, or :meth:`update` its description."""

    def __init__(self, description: str, total: float | None, reporter, timed: bool = False):
        self.description = description
        self.total = total
        self.timed = timed
        self.completed = 0.0
        self.t0 = time.perf_counter()
        self._reporter = reporter
        self._handle = reporter.start(description, total, timed) if reporter is not None else None

    def advance(self, amount: float = 1.0) -> None:
        self.completed += amount
        if self._reporter is not None:
            self._reporter.advance(self._handle, amount)

    def update(self, description: str) -> None:
        self.description = description
        if self._reporter is not None:
            self._reporter.update(self._handle, description)

    @property
    def elapsed(self) -> float:
        return time.perf_counter() - self.t0

    def _finish(self) -> None:
        if self._reporter is not None:
            self._reporter.finish(self._handle)
        log.debug("%s: %.2f s", self.description, self.elapsed)


@contextlib.contextmanager
def task(description: str, total: float | None = None, *, timed: bool = False):
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
    try:
        yield t
    finally:
        t._finish()


def set_reporter(reporter):
    """Install ``reporter`` (an object with ``start(description, total, timed) -> handle``,
    ``advance(handle, amount)``, ``update(handle, description)`` and
    ``finish(handle)``), or None; return the previous one."""
    old = _STATE["reporter"]
    _STATE["reporter"] = reporter
    return old


def get_reporter():
    """The installed reporter, or None."""
    return _STATE["reporter"]
