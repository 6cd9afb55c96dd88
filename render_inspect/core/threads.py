"""A compiled loop over rows run on threads: the serial, GIL-free kernel given a run of
rows at a time.

numba's ``parallel=True`` builds, besides the kernel, a threaded wrapper of the loop's
body, and optimises and emits the body's machine code several times over: 0.5 to 3 CPU-s
more per kernel at its first compilation than the same loop compiled serially (measured on
the imaging model's and the burr model's passes).  A kernel whose loop is over independent
rows (each row writes only its own results) is therefore compiled serially with
``nogil=True`` and a first and an end row, and :func:`over_rows` runs it on runs of rows on
threads, as many as numba's parallel kernels would use (``numba.get_num_threads()`` of the
calling thread).  Each row's numbers are those of the same loop run in one piece.  The
threads run compiled code only, without the interpreter's lock and without numba's own
threading layer.  They are started where numba's parallel loops would have used the cores
(:func:`_may_start_threads`); elsewhere the rows run in the calling thread.

Only the standard library is imported here (numba when :func:`over_rows` first runs).
"""

from __future__ import annotations

import os
import threading
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from typing import Any

from . import cancel

__all__ = ["over_rows"]

#: runs of rows per thread: later runs go to whichever thread is free first
_RUNS_PER_THREAD = 4

#: the name of the row threads
_ROWS = "render_inspect-rows"

_LOCK = threading.Lock()
# the threads that help the calling one, made on first use (again in a forked child)
_POOL: ThreadPoolExecutor | None = None
_POOL_PID = -1
_POOL_SIZE = 0


def _threads() -> int:
    import numba

    return int(numba.get_num_threads())


def _pool(helpers: int) -> ThreadPoolExecutor:
    global _POOL, _POOL_PID, _POOL_SIZE
    with _LOCK:
        if _POOL is None or _POOL_PID != os.getpid() or _POOL_SIZE < helpers:
            _POOL = ThreadPoolExecutor(helpers, thread_name_prefix=_ROWS)
            _POOL_PID, _POOL_SIZE = os.getpid(), helpers
        return _POOL


def _may_start_threads() -> bool:
    """In a process's main thread, in a thread the package started from one (named
    ``render_inspect-...``, such as the interferometer's truth beside its frames; not the
    row threads themselves), and in a Dask worker's task thread (the task has set numba's
    thread count to its share of the cores, as numba's parallel loops used it).  Not in
    other threads: the threads of a pool that runs tiles side by side already keep the
    cores busy, and row threads of their own only add temporaries held at once."""
    current = threading.current_thread()
    if current is threading.main_thread() or "Dask-Default-Threads" in current.name:
        return True
    return current.name.startswith("render_inspect-") and not current.name.startswith(_ROWS)


def over_rows(kernel: Callable[..., Any], n: int, *args: Any) -> None:
    """``kernel(*args, first, end)`` for runs ``first .. end - 1`` that together cover rows
    ``0 .. n - 1``, on threads (the calling one among them), each run once; returns when
    all are done, raising the first error a run raised.  The kernel must release the GIL
    (``nogil=True``) and each row must write only its own results."""
    n = int(n)
    threads = min(_threads(), n) if _may_start_threads() else 1
    if threads <= 1:
        if n > 0:
            kernel(*args, 0, n)
        return
    runs = min(n, _RUNS_PER_THREAD * threads)
    ends = [n * k // runs for k in range(runs + 1)]
    lock = threading.Lock()
    done = threading.Event()
    taken = [0]           # runs handed out
    left = [runs]         # runs not finished
    errors: list[BaseException] = []

    def work() -> None:
        while True:
            with lock:
                k = taken[0]
                if k >= runs:
                    return
                taken[0] = k + 1
            try:
                if not errors:
                    kernel(*args, ends[k], ends[k + 1])
            except BaseException as exc:  # (raised again in the calling thread)
                with lock:
                    errors.append(exc)
            finally:
                with lock:
                    left[0] -= 1
                    if left[0] == 0:
                        done.set()

    pool = _pool(threads - 1)
    # (a stop is raised after the runs are handed out, not inside ``submit``: there it
    # could come while the pool starts a thread, before the pool has recorded it, and the
    # program's exit, which tells the pools' recorded threads to end and then waits for
    # every thread, would wait for that one for ever)
    with cancel.deferred():
        for _ in range(threads - 1):
            pool.submit(work)
    # (the calling thread takes runs too, so that it waits only on runs already started:
    # never on a helper still queued behind other work)
    work()
    done.wait()
    if errors:
        raise errors[0]
