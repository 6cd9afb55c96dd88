"""Compile the numba kernels of turning simulations once per environment.

``make setup`` runs ``python -m render_inspect.pipeline._warmup``: every kernel is
called once with the argument types the commands use, and numba stores the machine code
in its cache (``cache=True``: the ``__pycache__`` folders beside the sources, or numba's
user cache folder where those are read-only).  Later processes, Dask workers included,
load the code instead of compiling it.
"""

from __future__ import annotations

import math
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from ..batch import run_tiles
from ..core.toolpath import ToolPath
from ..io import (block_sums, create_heightmap_zarr, grid_attrs, heightmap_channels,
                  heightmap_overview, preview)
from ..machining import (prepare_envelope, residual_metrics, simulate_turning, tile_abs_dev,
                         tile_moments)


class _Flat:
    def height(self, x, y):
        return np.zeros(np.broadcast(x, y).shape)


def _spiral(uniform: bool) -> ToolPath:
    n_rev, per_rev = 12, 64
    u = np.linspace(0.0, 1.0, n_rev * per_rev + 1)
    theta = 2 * math.pi * n_rev * (u if uniform else u ** 1.1)
    rho = 0.12 - 0.01 * theta / (2 * math.pi)
    return ToolPath(theta, rho, np.zeros_like(theta), theta)


def warm_up() -> float:
    """Compile (or load) every turning kernel; return the seconds it took."""
    t0 = time.perf_counter()
    region = (-0.02, -0.02, 0.02, 0.02)
    for uniform in (True, False):
        path = _spiral(uniform)
        m = simulate_turning(path, nose_radius=0.1, half_width=0.05, region=region, pixel=0.002)
        simulate_turning(path, nose_radius=0.1, half_width=0.05, region=region, pixel=0.002, reference=True)
    d = np.zeros_like(m)
    residual_metrics(m, d)
    tile_moments(m, d)
    for arr in (m, m.astype(np.float32)):
        tile_abs_dev(arr, 0.0, -1.0, 1.0, 8)
        block_sums(arr, 2)
    preview(m, 4, minus=d)
    heightmap_channels(d, m)
    heightmap_overview(d, m, 4)
    ep = prepare_envelope(_spiral(True), nose_radius=0.1, half_width=0.05)
    with tempfile.TemporaryDirectory() as tmp:
        store = str(Path(tmp) / "w.zarr")
        shape = m.shape
        create_heightmap_zarr(store, shape, chunk=64, attrs=grid_attrs(0.002, region[:2], None, None),
                              levels=1)
        run_tiles(ep, _Flat(), origin=region[:2], pixel=0.002, shape=shape, store=store, levels=1, tile=64,
                  workers=1)
    return time.perf_counter() - t0


if __name__ == "__main__":
    dt = warm_up()
    print(f"numba kernels compiled or loaded from the cache in {dt:.1f} s", file=sys.stderr)
