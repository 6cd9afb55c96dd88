"""Evaluations in this process: one after the other, or a batch of them at once in
threads (:func:`run_local`)."""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator, Sequence
from typing import Any

from ..core.errors import RenderInspectError

__all__ = ["run_local"]


def run_local(compute: Callable[[Any], Any], tasks: Sequence[Any], threads: int = 1, *,
              catch: bool = True) -> Iterator[tuple]:
    """``(height, meta, seconds, error text or None)`` of each task in order, computed in
    this process: one after the other, or ``threads`` at once (a thread pool; each result
    is handed on, in the tasks' order, as soon as it and those before it are done).
    ``catch``: a :class:`~render_inspect.core.errors.RenderInspectError` becomes the error
    text (else it is raised, as every other exception is).

    Running two evaluations at once keeps both cores of a small machine busy through the
    forward model's single-threaded stages (the ray tracer's acceleration structure, the
    machine's following, NumPy); each evaluation's result is the one it gives alone.  The
    fit's forward model runs one at a time
    (:data:`~render_inspect.pipeline._fit_model.LOCAL_THREADS`)."""
    run = _timed_compute if catch else _timed_raise
    threads = min(max(1, int(threads)), len(tasks))
    if threads <= 1:
        for t in tasks:
            yield run(compute, t)
        return
    from concurrent.futures import ThreadPoolExecutor

    with ThreadPoolExecutor(max_workers=threads, thread_name_prefix="fit-evaluation") as pool:
        futures = [pool.submit(run, compute, t) for t in tasks]
        try:
            for fut in futures:
                yield fut.result()
        finally:
            for fut in futures:  # (an error or a stop: the tasks not started are dropped)
                fut.cancel()


def _timed_raise(compute, task):
    t0 = time.perf_counter()
    h, meta = compute(task)
    return h, meta, time.perf_counter() - t0, None


def _timed_compute(compute, task):
    """Run on a worker: (height, meta, seconds, error text or None)."""
    t0 = time.perf_counter()
    try:
        h, meta = compute(task)
        return h, meta, time.perf_counter() - t0, None
    except RenderInspectError as e:
        return None, {}, time.perf_counter() - t0, str(e)
