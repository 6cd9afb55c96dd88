"""The figures of a ``simulate`` command drawn by a second process beside the computation.

Drawing a figure is Python work that holds the interpreter (a few tens of milliseconds
for the figures drawn with Pillow: the axes' motion, the following error and its map,
``residual.png``; matplotlib's, such as the tool-wear figure, about 0.35 CPU-s to import
and 0.1-0.3 CPU-s a figure), so a thread of the same process draws it only when the
computation leaves the interpreter free.  A child process, forked when the command starts
(a copy of the process as it is then: the package already imported, no thread of numba's
yet), draws each figure as soon as its data is sent, on the other core, while the parent
plans, follows, cuts and writes.  The figures are the same files, byte for byte: the same
functions draw them from the same data.

The child is forked before numba starts (about 0.3 CPU-s: its import and its compiler's
set-up, which the parent needs next to plan), and imports matplotlib only when the first
figure that needs it arrives: a scene whose figures are all drawn with Pillow leaves the
second core to the parent's threads.  The figures need no compiled kernel of their own:
the axis-motion figure is drawn from the derivatives the plan took (a figure that needs a
kernel all the same starts numba in the child when it is drawn).

Figures that arrive together (the cut's, then ``residual.png`` while the parent writes its
files) are drawn at once, each by a copy of the child forked for it (the copy costs
milliseconds, and shares matplotlib once the child has it), up to :data:`DRAWERS` at a
time and one per usable core; on one usable core the child draws them one after the other.

The child only draws: it ignores Ctrl-C and hang-ups (the parent decides), ends when the
parent closes its end of the pipe or ends itself, and never runs the parent's clean-up
(it leaves with ``os._exit``); its copies end with it.  A figure that fails in the child
raises its error in the parent; a child that ended unexpectedly leaves its figures to the
parent, which draws them itself.  Linux only (``fork``); elsewhere, or when the fork
fails, the figures are drawn in a thread of the command's process.
"""

from __future__ import annotations

import gc
import logging
import os
import pickle
import queue
import select
import signal
import sys
import threading
import time
import warnings
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from ..core.lazy import collector_paused, freeze_lasting
from ..core.limits import usable_cpus
from ..core.units import MIB_TO_BYTES
from ..report import draw_figure, drawn_data, preload_drawing, residual_png, uses_matplotlib
from ..toolpath import axis_derivatives

__all__ = ["FigureProcess"]

#: seconds without a finished figure after which the child is taken for stuck: it is
#: ended and its figures are drawn by the parent
STALL_S = 300.0
#: figures drawn at once at most (by copies of the child, one per figure; at most one per
#: usable core)
DRAWERS = 2


def _run_job(kind: str, args: tuple, kwargs: dict) -> None:
    if kind == "figure":
        draw_figure(*args, **kwargs)
    elif kind == "residual":
        residual_png(*args, **kwargs)
    else:  # (never: the parent sends only these)
        raise ValueError(f"unknown figure job {kind!r}")


def _warm_kernels() -> None:
    """Start numba in the command's process (its import and its compiler's set-up, about
    0.3 CPU-s in a fresh process) and load the kernels of the axes' derivatives, which
    the plan takes first, on three points."""
    t = np.arange(3, dtype=np.float64)
    axis_derivatives(t, t * t)


#: the largest report written in one piece (POSIX: writes of at most PIPE_BUF bytes into
#: a pipe are not interleaved with others')
_REPORT_MAX = getattr(select, "PIPE_BUF", 512)


def _result(key: int, seconds: float, error: BaseException | None) -> bytes:
    """A job's report as the parent reads it: its length (8 bytes), then (key, seconds,
    error) pickled; at most ``select.PIPE_BUF`` bytes, so that the reports of drawers
    writing into the one pipe at once are never interleaved (a long error is cut)."""
    try:
        blob = pickle.dumps((key, seconds, error))
    except Exception:  # an error that does not pickle: its type and text
        blob = b""
    if not blob or len(blob) + 8 > _REPORT_MAX:
        text = f"{type(error).__name__}: {error}"[:1000]
        blob = pickle.dumps((key, seconds, RuntimeError(text)))
    return len(blob).to_bytes(8, "little") + blob


def _uses_matplotlib(job: tuple) -> bool:
    """Whether drawing ``job`` imports matplotlib (``residual.png`` and the figures
    :func:`~render_inspect.report.uses_matplotlib` names are drawn with Pillow)."""
    _, kind, args, _ = job
    return kind == "figure" and uses_matplotlib(args[0])


def _draw(job: tuple, results_fd: int) -> None:
    """Draw ``job`` and write its report."""
    key, kind, args, kwargs = job
    t0 = time.perf_counter()
    error: BaseException | None = None
    try:
        _run_job(kind, args, kwargs)
    except Exception as err:  # reported in the parent
        error = err
    os.write(results_fd, _result(key, round(time.perf_counter() - t0, 4), error))


def _fork_drawer(job: tuple, results_fd: int) -> int | None:
    """A copy of the child (matplotlib loaded) that draws ``job``, reports it and ends; its
    pid, or None when the fork fails (the child then draws it itself)."""
    me = os.getpid()
    try:
        pid = os.fork()
    except OSError:
        return None
    if pid == 0:
        code = 0
        try:
            _end_with(me)
            _draw(job, results_fd)
        except BaseException:
            code = 1
        finally:
            os._exit(code)
    return pid


def _end_with(parent: int) -> None:
    """End this process when ``parent`` ends (Linux: the parent-death signal), so that a
    child the command ends at once (:meth:`FigureProcess.close`) leaves no copy writing."""
    try:
        import ctypes

        ctypes.CDLL(None, use_errno=True).prctl(1, signal.SIGKILL)  # PR_SET_PDEATHSIG
    except Exception:  # (then it ends when its figure is drawn)
        return
    if os.getppid() != parent:  # (the parent ended before the signal was asked for)
        os._exit(1)


def _child(jobs_fd: int, results_fd: int) -> None:
    """The child's life: draw the jobs as they arrive and report each (name, seconds,
    error or None) until the parent closes the pipe; matplotlib is imported when the
    first figure that needs it arrives.  Up
    to :data:`DRAWERS` jobs are drawn at once, each by a copy of the child forked for it
    (the figures of a cut arrive together while the command writes its files), or one
    after the other by the child itself on a single usable core."""
    for name in ("SIGINT", "SIGHUP"):
        sig = getattr(signal, name, None)
        if sig is not None:
            signal.signal(sig, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    # nothing of the child's reaches the terminal: the parent's handlers (and the locks
    # another of its threads may have held at the fork) are not the child's to use
    logging.disable(logging.CRITICAL)
    warnings.simplefilter("ignore")
    inbox: queue.Queue = queue.Queue()

    def read() -> None:  # jobs are read as they come, so that the parent never waits
        with os.fdopen(jobs_fd, "rb") as jobs:
            while True:
                try:
                    job = pickle.load(jobs)
                except (EOFError, OSError, pickle.UnpicklingError):
                    inbox.put(None)
                    return
                inbox.put(job)

    threading.Thread(target=read, daemon=True).start()
    at_once = min(DRAWERS, usable_cpus())
    drawing: set[int] = set()
    loaded = False
    while True:
        job = inbox.get()
        if job is None:
            break
        if not loaded and _uses_matplotlib(job):
            # matplotlib, imported once here for the figures that need it (the copies
            # forked below share it), with the collector paused: its modules live as
            # long as the child (its own switch, not collector_paused, whose lock was
            # the parent's)
            loaded = True
            was_on = gc.isenabled()
            gc.disable()
            try:
                preload_drawing()
            except Exception:  # (drawing loads the same and reports what fails there)
                pass
            gc.freeze()
            if was_on:
                gc.enable()
        while len(drawing) >= at_once:
            _wait_drawer(drawing)
        pid = _fork_drawer(job, results_fd) if at_once > 1 else None
        if pid is None:
            _draw(job, results_fd)
        else:
            drawing.add(pid)
    while drawing:
        _wait_drawer(drawing)


def _wait_drawer(drawing: set[int]) -> None:
    """Wait for one of the child's drawers (pids ``drawing``) to end and take it out."""
    try:
        drawing.discard(os.wait()[0])
    except ChildProcessError:  # (none is left)
        drawing.clear()


class FigureProcess:
    """A forked child that draws figures (see the module notes).  ``draw`` and
    ``residual`` send a job; ``results`` waits for them all and returns the seconds each
    took (name -> s); ``close`` ends the child."""

    def __init__(self, pid: int, jobs_fd: int, results_fd: int) -> None:
        self.pid: int | None = pid
        self._results_fd: int | None = results_fd
        # job id -> (file name, kind, args, kwargs)
        self._sent: dict[int, tuple[str, str, tuple, dict]] = {}
        self._outbox: queue.Queue = queue.Queue()
        # a writer thread: a large job does not wait for the child to read it
        self._writer = threading.Thread(target=self._write, args=(jobs_fd,), daemon=True,
                                        name="render_inspect-figures-send")
        self._writer.start()

    @classmethod
    def start(cls) -> FigureProcess | None:
        """Fork the child, or None where that is not possible (not Linux, no fork)."""
        if not sys.platform.startswith("linux"):
            return None
        # forked before numba starts (see the module notes); what is made so far is left out
        # of the collector's passes before the fork, so that the child's collections never
        # copy the pages it shares
        freeze_lasting()
        try:
            jobs_r, jobs_w = os.pipe()
            res_r, res_w = os.pipe()
        except OSError:
            return None
        try:
            pid = os.fork()
        except OSError:
            for fd in (jobs_r, jobs_w, res_r, res_w):
                os.close(fd)
            return None
        if pid == 0:  # the child: draw, then leave without the parent's clean-up
            code = 0
            try:
                os.close(jobs_w)
                os.close(res_r)
                _child(jobs_r, res_w)
            except BaseException:
                code = 1
            finally:
                os._exit(code)
        os.close(jobs_r)
        os.close(res_w)
        # numba's start, which the planning needs next, while the child imports matplotlib
        # (with the collector paused: numba's start makes some sixty thousand lasting
        # objects and almost no garbage)
        with collector_paused():
            try:
                _warm_kernels()
            except Exception:  # (the kernels' first use reports what fails there)
                pass
        return cls(pid, jobs_w, res_r)

    def _write(self, fd: int) -> None:
        with os.fdopen(fd, "wb") as pipe:
            while True:
                blob = self._outbox.get()
                if blob is None:
                    return
                try:
                    pipe.write(blob)
                    pipe.flush()
                except OSError:  # the child is gone: its figures are drawn by the parent
                    return

    def _send(self, name: str, kind: str, args: tuple, kwargs: dict) -> None:
        job = len(self._sent)
        self._sent[job] = (name, kind, args, kwargs)
        self._outbox.put(pickle.dumps((job, kind, args, kwargs), protocol=5))

    def draw(self, name: str, spec: dict, png: str | Path) -> None:
        """Draw the figure ``spec`` into ``png`` (:func:`~render_inspect.report.draw_figure`)."""
        # (reduced here to what is drawn: the axes' figure is sent as its panels)
        self._send(name, "figure", (drawn_data(spec), Path(png)), {})

    def residual(self, name: str, png: str | Path, img: Any, factor: int, **kwargs: Any) -> None:
        """residual.png from its area-averaged image (:func:`~render_inspect.report.residual_png`)."""
        self._send(name, "residual", (Path(png), img, factor), kwargs)

    def results(self, done: Callable[[str], None] | None = None) -> dict:
        """Wait for every job sent; return name -> seconds.  ``done(name)`` is called as
        each figure is finished.  A figure that failed raises its error; the figures of a
        child that ended unexpectedly are drawn here."""
        self._outbox.put(None)
        times: dict[str, float] = {}
        finished: set[int] = set()
        error: BaseException | None = None
        fd = self._results_fd
        while fd is not None and len(finished) < len(self._sent):
            if not select.select([fd], [], [], STALL_S)[0]:
                break  # (stuck: ended below, its figures drawn here)
            head = _read_exact(fd, 8)
            if head is None:
                break
            blob = _read_exact(fd, int.from_bytes(head, "little"))
            if blob is None:
                break
            job, seconds, err = pickle.loads(blob)
            finished.add(job)
            name = self._sent[job][0]
            times[name] = seconds
            if err is not None and error is None:
                error = err
            if done is not None:
                done(name)
        if error is not None:
            raise error
        if len(finished) < len(self._sent):
            self.close()
        for job, (name, kind, args, kwargs) in self._sent.items():
            if job not in finished:  # the child ended before drawing it: drawn here
                t0 = time.perf_counter()
                _run_job(kind, args, kwargs)
                times[name] = round(time.perf_counter() - t0, 4)
                if done is not None:
                    done(name)
        return times

    def close(self) -> None:
        """End the child (at once, if it is still drawing) and collect it."""
        if self.pid is None:
            return
        self._outbox.put(None)
        pid, self.pid = self.pid, None
        try:
            done, _ = os.waitpid(pid, os.WNOHANG)
            if done == 0:
                os.kill(pid, signal.SIGKILL)
                os.waitpid(pid, 0)
        except (ChildProcessError, ProcessLookupError):
            pass
        if self._results_fd is not None:
            try:
                os.close(self._results_fd)
            except OSError:
                pass
            self._results_fd = None


def _read_exact(fd: int, n: int) -> bytes | None:
    """``n`` bytes from ``fd``, or None at the end of the stream."""
    parts = []
    while n > 0:
        chunk = os.read(fd, min(n, MIB_TO_BYTES))
        if not chunk:
            return None
        parts.append(chunk)
        n -= len(chunk)
    return b"".join(parts)
