"""Tiled, out-of-core simulation of a turning path on Dask: the height map computed tile by
tile into a chunked Zarr store, its statistics reduced exactly across tiles.

Each tile task (``tile_task``) computes one tile (:func:`render_inspect.machining.compute_tile`),
reduces its residual to (n, mean, M2, min, max), writes design, machined and residual
(float32) into the store's chunks of the tile and the tile's part of every pyramid level
(block sums, exact across tiles), and returns only the small partials.  A second,
read-only pass over the stored residual gives Sa and a histogram once the global mean and
range are known (:func:`render_inspect.machining.tile_abs_dev`).

Tiles run on Dask: the threaded scheduler on this machine by default, or a
``distributed.Client`` (a ``LocalCluster`` started with ``--workers N`` or a cluster
reached with ``--scheduler ADDRESS``).  Workers of a distributed cluster write into the
store themselves, so the store must be on a file system they share with the caller.
"""

from __future__ import annotations

import contextlib
import math
import os
import time
from dataclasses import dataclass, field

import numpy as np

from ..core.errors import InputError
from ..io import block_sums, coarsen, means
from ..machining import (TILE, EnvelopePath, Tile, compute_tile, load_kernels, merge_moments,
                         plan_tiles, tile_abs_dev, tile_moments)

__all__ = ["run_tiles", "tile_client", "TiledStats", "BINS", "CHANNELS"]

#: histogram bins of the residual (pass 2)
BINS = 1024
CHANNELS = ("design", "machined", "residual")


def _write_tile(group, tile: Tile, arrays: dict, levels: int, tile_levels: int) -> dict:
    """Write the tile into the store (full resolution and pyramid levels <= tile_levels);
    return the block sums and counts at level ``tile_levels`` if coarser levels follow."""
    r0, c0 = tile.row, tile.col
    coarse = {}
    for name, a in arrays.items():
        group[name][r0:r0 + tile.rows, c0:c0 + tile.cols] = a
        if levels == 0:
            continue
        s, c = block_sums(a, 2)
        for k in range(1, tile_levels + 1):
            if k > 1:
                s, c = coarsen(s, c, 2)
            f = 1 << k
            group[f"levels/{k}/{name}"][r0 // f:r0 // f + s.shape[0], c0 // f:c0 // f + s.shape[1]] = means(s, c)
        if levels > tile_levels:
            coarse[name] = (s, c)
    return coarse


def tile_task(ep: EnvelopePath, surface, origin, pixel: float, tile: Tile, store: str, levels: int,
              tile_levels: int) -> dict:
    """Compute one tile and write it into ``store``; return its partial statistics."""
    import zarr

    design, machined = compute_tile(ep, surface, origin, pixel, tile)
    moments = tile_moments(machined, design)
    residual = np.subtract(machined, design).astype(np.float32)
    machined32 = machined.astype(np.float32)
    del machined
    design32 = design.astype(np.float32)
    del design
    group = zarr.open_group(store, mode="r+")
    coarse = _write_tile(group, tile, {"design": design32, "machined": machined32, "residual": residual},
                         levels, tile_levels)
    return {"tile": tile, "moments": moments, "coarse": coarse}


def abs_dev_task(store: str, tile: Tile, mean: float, lo: float, hi: float, bins: int) -> tuple:
    """Pass 2 of one tile: (n, sum |r - mean|, histogram counts) of its stored residual."""
    import zarr

    r = zarr.open_array(f"{store}/residual", mode="r")[tile.row:tile.row + tile.rows, tile.col:tile.col + tile.cols]
    return tile_abs_dev(r, mean, lo, hi, bins)


@dataclass
class TiledStats:
    """What the tiled run returns (the maps themselves are in the store).

    moments : (n, mean, M2, min, max) of the residual (mm), merged over tiles
    abs_dev : (n, sum |r - mean|) (mm) from the stored residual
    histogram : (lo_mm, hi_mm, counts) of the stored residual
    tiles : number of tiles
    timing_s : seconds of ``tiles`` (pass 1), ``pass2``, ``levels``
    """

    moments: tuple
    abs_dev: tuple
    histogram: tuple
    tiles: int
    timing_s: dict = field(default_factory=dict)


class _Counter:
    """Calls ``progress(done, total, elapsed_s)`` as tasks finish."""

    def __init__(self, total: int, progress, t0: float):
        self.total, self.progress, self.t0, self.done = total, progress, t0, 0

    def step(self):
        self.done += 1
        if self.progress is not None:
            self.progress(self.done, self.total, time.perf_counter() - self.t0)


def _run(fn, arg_lists: list[tuple], shared: tuple, *, client=None, workers: int | None = None,
         progress=None) -> list:
    """fn(*shared, *args) for each args in ``arg_lists`` on Dask; results in order."""
    t0 = time.perf_counter()
    counter = _Counter(len(arg_lists), progress, t0)
    if client is not None:
        from distributed import as_completed

        n = getattr(client, "expected_workers", 0)
        if n:
            client.wait_for_workers(n)
        client.run(_load_kernels)
        big = [client.scatter(v, broadcast=True) if isinstance(v, EnvelopePath) else v for v in shared]
        futures = [client.submit(fn, *big, *args, pure=False) for args in arg_lists]
        index = {f.key: i for i, f in enumerate(futures)}
        out = [None] * len(futures)
        for fut in as_completed(futures):
            out[index[fut.key]] = fut.result()
            counter.step()
            fut.release()
        return out
    import dask
    from dask.diagnostics import Callback

    shared_d = [dask.delayed(v, traverse=False) if isinstance(v, EnvelopePath) else v for v in shared]
    tasks = [dask.delayed(fn, pure=False)(*shared_d, *args) for args in arg_lists]
    keys = {t.key for t in tasks}

    def posttask(key, result, dsk, state, worker_id):
        if key in keys:
            counter.step()

    with Callback(posttask=posttask):
        return list(dask.compute(*tasks, scheduler="threads", num_workers=workers or os.cpu_count() or 1))


def run_tiles(ep: EnvelopePath, surface, *, origin, pixel: float, shape, store: str, levels: int,
              tile: int = TILE, client=None, workers: int | None = None, progress=None,
              bins: int = BINS) -> TiledStats:
    """Compute the machined surface of ``ep`` over the grid tile by tile into ``store``.

    Parameters
    ----------
    ep : EnvelopePath
        The whole path (``prepare_envelope``).
    surface : Surface
        The design (``height(x, y)``).
    origin : (x, y)
        Centre of pixel [0, 0], mm.
    pixel : float
        mm.
    shape : (ny, nx)
    store : str
        A store made by ``create_heightmap_zarr`` with ``chunk == tile`` and ``levels``.
    levels : int
        Pyramid levels of the store.
    tile : int
        Tile side, pixels (multiple of 64; a power of two keeps pyramid levels inside).
    client : distributed.Client, optional
        Run on this cluster; the threaded scheduler with ``workers`` threads otherwise.
    progress : callable(done, total, elapsed_s), optional
        Called as tiles finish (pass 1).
    bins : int
        Residual histogram bins.
    """
    tiles = plan_tiles(shape, tile)
    tile_levels = min(levels, int(math.log2(tile))) if tile & (tile - 1) == 0 else 0
    if levels > tile_levels and tile & (tile - 1):
        raise InputError(f"tile must be a power of two for a pyramid, got {tile}")
    timing = {}
    t0 = time.perf_counter()
    parts = _run(tile_task, [(t, store, levels, tile_levels) for t in tiles], (ep, surface, origin, pixel),
                 client=client, workers=workers, progress=progress)
    timing["tiles"] = time.perf_counter() - t0
    moments = (0, 0.0, 0.0, math.inf, -math.inf)
    for p in parts:
        moments = merge_moments(moments, p["moments"])
    if moments[0] == 0:
        raise ValueError("the path does not cover the region: no finite residual")
    t0 = time.perf_counter()
    _, mean, _, lo, hi = moments
    # the histogram spans the float32 values actually stored
    lo32, hi32 = float(np.float32(lo)), float(np.float32(hi))
    p2 = _run(abs_dev_task, [(t, mean, lo32, hi32, bins) for t in tiles], (store,), client=client,
              workers=workers)
    n2 = sum(p[0] for p in p2)
    sa = math.fsum(p[1] for p in p2)
    counts = np.sum([p[2] for p in p2], axis=0) if p2 else np.zeros(bins, dtype=np.int64)
    timing["pass2"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    if levels > tile_levels:
        import zarr

        group = zarr.open_group(store, mode="r+")
        f0 = 1 << tile_levels
        for name in CHANNELS:
            shp = (-(-shape[0] // f0), -(-shape[1] // f0))
            s = np.zeros(shp)
            c = np.zeros(shp, dtype=np.int64)
            for p in parts:
                ts, tc = p["coarse"][name]
                t = p["tile"]
                s[t.row // f0:t.row // f0 + ts.shape[0], t.col // f0:t.col // f0 + ts.shape[1]] = ts
                c[t.row // f0:t.row // f0 + tc.shape[0], t.col // f0:t.col // f0 + tc.shape[1]] = tc
            for k in range(tile_levels + 1, levels + 1):
                s, c = coarsen(s, c, 2)
                group[f"levels/{k}/{name}"][...] = means(s, c)
    timing["levels"] = time.perf_counter() - t0
    return TiledStats(moments, (n2, sa), (lo32, hi32, counts), len(tiles), timing)


def _load_kernels() -> bool:
    """Load the tile code's compiled kernels (in a worker process)."""
    load_kernels()
    z = np.zeros((1, 1))
    tile_moments(z, z)
    return True


@contextlib.contextmanager
def tile_client(*, workers: int | None = None, scheduler: str | None = None):
    """The Dask client tiles run on: None (the threaded scheduler of this process) when
    neither is given; a ``LocalCluster`` of ``workers`` single-threaded processes; or the
    cluster whose scheduler listens at ``scheduler`` (``tcp://host:8786``).

    The workers of a LocalCluster start in the background: the caller can plan the path
    meanwhile, and :func:`run_tiles` waits for them.  Scripts that start a cluster need
    the ``if __name__ == "__main__":`` guard (worker processes re-import the main module)."""
    if scheduler:
        from distributed import Client

        try:
            client = Client(scheduler, timeout="20s")
        except (OSError, TimeoutError) as err:
            raise InputError(f"--scheduler: no Dask scheduler answers at {scheduler!r} ({err})") from None
        with client:
            yield client
        return
    if workers is None:
        yield None
        return
    if not 1 <= int(workers) <= 1024:
        raise InputError(f"--workers must be in [1, 1024], got {workers}")
    from distributed import Client, LocalCluster

    with LocalCluster(n_workers=0, threads_per_worker=1, processes=True, dashboard_address=None,
                      memory_limit=0) as cluster, Client(cluster) as client:
        cluster.scale(int(workers))
        client.expected_workers = int(workers)
        yield client
