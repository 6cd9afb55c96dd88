"""Timing helpers shared by the benchmark scripts (run as scripts or by run_all.py, which
both put this folder on ``sys.path``)."""

from __future__ import annotations

import time


def best_of(fn, repeats: int):
    """(the shortest wall time of ``repeats`` calls of ``fn``, s; what the last call
    returned)."""
    best, out = None, None
    for _ in range(max(1, int(repeats))):
        t0 = time.perf_counter()
        out = fn()
        dt = time.perf_counter() - t0
        best = dt if best is None or dt < best else best
    return best, out
