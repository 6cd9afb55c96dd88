"""Where a compiled row loop may start threads: a process's main thread, the threads the
package starts from it, a Dask worker's task thread; not a pool's threads that run tiles
side by side, nor the row threads themselves.  A stop that comes while the threads start
lets the program end."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import threading
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numba
import pytest

from render_inspect.core.threads import over_rows

REPO = Path(__file__).resolve().parents[1]


def _runs(n: int) -> tuple[list[tuple[int, int]], set[str]]:
    runs: list[tuple[int, int]] = []
    names: set[str] = set()
    lock = threading.Lock()

    def kernel(first: int, end: int) -> None:
        with lock:
            runs.append((first, end))
            names.add(threading.current_thread().name)

    over_rows(kernel, n)
    return sorted(runs), names


def _in_thread(name: str, n: int):
    with ThreadPoolExecutor(1, thread_name_prefix=name) as pool:
        return pool.submit(_runs, n).result()


@pytest.mark.skipif(numba.config.NUMBA_NUM_THREADS < 2, reason="numba has one thread here")
def test_rows_cover_each_row_once_on_threads_where_allowed():
    runs, _ = _runs(37)
    assert runs[0][0] == 0 and runs[-1][1] == 37
    assert all(a[1] == b[0] for a, b in zip(runs, runs[1:]))  # each row once, in runs
    assert len(runs) > 1
    for name in ("render_inspect-truth", "Dask-Default-Threads"):
        runs, _ = _in_thread(name, 37)
        assert len(runs) > 1, name
    for name in ("render_inspect-rows", "ThreadPoolExecutor"):  # row threads, tile pools
        runs, names = _in_thread(name, 37)
        assert runs == [(0, 37)] and len(names) == 1, name


def test_a_failing_run_raises_in_the_calling_thread():
    def kernel(first: int, end: int) -> None:
        if first <= 5 < end:
            raise ValueError("row 5")

    with pytest.raises(ValueError, match="row 5"):
        over_rows(kernel, 20)


#: a stop (the command line's SIGTERM handler) that comes while a pool starts its first
#: thread: right after the thread has started, before the pool has recorded it (a signal
#: during the start's wait for the new thread); then the program's end after a stop
_STOP_IN_THREAD_START = """
import os, signal, sys, threading
from concurrent.futures import ThreadPoolExecutor
from render_inspect.cli import _main
from render_inspect.core.cancel import Terminated

start = threading.Thread.start
def starting(self):
    start(self)
    threading.Thread.start = start
    _main._on_terminate(signal.SIGTERM, None)  # (what the handler does when it runs here)
threading.Thread.start = starting
try:
    if sys.argv[1] == "over_rows":
        from render_inspect.core.threads import over_rows
        over_rows(lambda first, end: None, 64)
    else:
        from render_inspect.instruments._imaging import _by_rows, _row_blocks
        _by_rows(ThreadPoolExecutor(2), _row_blocks(64, 2), lambda rows: None)
except Terminated:
    print("stopped", flush=True)
    _main._end_stopped(143)
print("not stopped", flush=True)
sys.exit(3)
"""


@pytest.mark.parametrize("where", ["over_rows", "_by_rows"])
@pytest.mark.slow
def test_a_stop_while_a_pool_starts_its_thread_lets_the_program_end(where):
    """A stop that comes while the row threads' pool (or the imaging model's) starts a
    thread is raised once the work is handed out: the program then ends (exit 143) instead
    of waiting for ever for a thread that the pool never told to end."""
    env = dict(os.environ, PYTHONPATH=str(REPO) + os.pathsep + os.environ.get("PYTHONPATH", ""),
               NUMBA_NUM_THREADS="2", PYTHONFAULTHANDLER="1")
    p = subprocess.Popen([sys.executable, "-c", _STOP_IN_THREAD_START, where], env=env,
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        out, err = p.communicate(timeout=60)
    except subprocess.TimeoutExpired:
        p.send_signal(signal.SIGABRT)  # (its threads' stacks into the failure)
        out, err = p.communicate()
        pytest.fail(f"the program did not end after the stop: {out}\n{err[-3000:]}")
    assert p.returncode == 143 and out.split() == ["stopped"], (p.returncode, out, err[-2000:])
