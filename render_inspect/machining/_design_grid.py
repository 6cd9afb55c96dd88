"""The design sampled on a simulation grid, in row chunks on a thread per core."""

from __future__ import annotations

from typing import Any
from collections.abc import Sequence
import os
from concurrent.futures import ThreadPoolExecutor

import numpy as np

from ..core.grid import grid_shape
from ..core.progress import report

__all__ = ["design_grid"]


def design_grid(surface: Any, region: Sequence[float], pixel: float, *, rows_per_chunk: int = 128,
                out: np.ndarray | None = None) -> np.ndarray:
    """Design heights (mm) on the grid of ``region`` = (x0, y0, x1, y1) at ``pixel`` (mm),
    row 0 = smallest y, evaluated in row chunks (bounded temporaries) on a thread per
    core (numpy releases the GIL).  ``out`` (ny, nx) float64 is written in place."""
    x0, y0, _, _ = region
    ny, nx = grid_shape(region, pixel)
    x = x0 + pixel * np.arange(nx)
    if out is None:
        out = np.empty((ny, nx), dtype=np.float64)

    def rows(a):
        y = y0 + pixel * np.arange(a, min(a + rows_per_chunk, ny))
        out[a:a + len(y)] = surface.height(x[None, :], y[:, None])
        report(a + len(y), ny)  # (and stop here when a signal asked to)

    starts = range(0, ny, rows_per_chunk)
    if ny * nx < 1_000_000:
        for a in starts:
            rows(a)
    else:
        with ThreadPoolExecutor(max_workers=os.cpu_count() or 1) as ex:
            list(ex.map(rows, starts))
    return out
