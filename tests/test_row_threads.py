"""Where a compiled row loop may start threads: a process's main thread, the threads the
package starts from it, a Dask worker's task thread; not a pool's threads that run tiles
side by side, nor the row threads themselves."""

from __future__ import annotations

import threading
from concurrent.futures import ThreadPoolExecutor

import numba
import pytest

from render_inspect.core.threads import over_rows


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
