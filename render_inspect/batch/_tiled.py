"""Tiled, out-of-core simulation of a turning path on Dask: the height map computed tile by
tile into a chunked Zarr store, its statistics reduced exactly across tiles.

Each tile task (``tile_task``) computes one tile (:func:`render_inspect.machining.compute_tile`),
or a run of tiles of one column top to bottom that share the rows of their halo'd blocks,
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

from collections.abc import Callable, Iterator, Sequence
import contextlib
import ctypes
import math
import threading
import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..core import cancel
from ..core.errors import InputError
from ..core.units import GIB_TO_BYTES, MIB_TO_BYTES
from ..core.limits import usable_cpus
from ._store_stats import stored_abs_dev
from ._tile_flip import flip_column
from ._tile_pyramid import CHANNELS, tile_float32, write_tile
from ._cluster import call_with_threads, cluster_info, dask_client, open_client, wait_for_workers
from ..io import coarsen, means
from ..machining import (TILE, CutPath, EnvelopePath, Tile, compute_tile, load_cut_kernels, load_kernels,
                         Grooves, merge_moments, plan_tiles, tile_moments)

__all__ = ["run_tiles", "tile_client", "TiledStats", "BINS", "CHANNELS"]

#: histogram bins of the residual (pass 2)
BINS = 1024


# (``surface: Any``: a design's Surface, which this layer does not import; ``client: Any``:
# a ``distributed.Client``, an optional dependency imported where it is used)
def tile_task(ep: EnvelopePath | CutPath, surface: Any, origin: Sequence[float], pixel: float,
              grooves: Grooves | None, shape: Sequence[int], stride: int,
              texture: tuple[float, float, int] | None, burrs: dict[str, Any] | None,
              tiles: Tile | Sequence[Tile], store: str, levels: int,
              tile_levels: int) -> list[dict[str, Any]]:
    """Compute the tiles ``tiles`` (a Tile, or a run of tiles of one column, top to bottom;
    ``ep``: an EnvelopePath or a CutPath) and write them into ``store``; return their
    partial statistics (and the material's, :func:`~render_inspect.machining.compute_tile`),
    one dict per tile.  The tiles of a run share the rows of their halo'd blocks that
    overlap (cut once, not once per tile)."""
    import zarr

    if isinstance(tiles, Tile):
        tiles = [tiles]
    group = zarr.open_group(store, mode="r+")
    carry: dict = {}
    out = []
    for tile in tiles:
        cancel.check()  # a tile not started when the run is stopped is not started
        design, machined, cut = compute_tile(ep, surface, origin, pixel, tile, grooves=grooves, shape=shape,
                                             stride=stride, texture=texture, burrs=burrs,
                                             carry=carry if isinstance(ep, CutPath) else None)
        moments = tile_moments(machined, design)
        # float32 design, machined and residual (formed in float64) and their level-1
        # block sums, in one compiled pass
        maps, level1 = tile_float32(design, machined)
        del machined, design
        coarse = write_tile(group, tile, maps, levels, tile_levels, level1)
        del maps, level1
        out.append({"tile": tile, "moments": moments, "coarse": coarse, "cut": cut})
    return out


def column_runs(tiles: list[Tile], tasks: int) -> list[list[Tile]]:
    """The tiles grouped into runs of consecutive tiles of one column (top to bottom), each
    column split into as few runs as give at least ``tasks`` runs in all (a run shares the
    cut rows of its tiles' halos)."""
    cols: dict[int, list[Tile]] = {}
    for t in tiles:
        cols.setdefault(t.col, []).append(t)
    split = max(1, -(-int(tasks) // max(len(cols), 1)))
    runs: list[list[Tile]] = []
    for col in cols.values():
        col.sort(key=lambda t: t.row)
        n = min(split, len(col))
        size = -(-len(col) // n)
        runs.extend(col[i:i + size] for i in range(0, len(col), size))
    return runs


@dataclass
class TiledStats:
    """What the tiled run returns (the maps themselves are in the store).

    moments : (n, mean, M2, min, max) of the residual (mm), merged over tiles
    abs_dev : (n, sum |r - mean|) (mm) from the stored residual
    histogram : (lo_mm, hi_mm, counts) of the stored residual
    tiles : number of tiles
    timing_s : seconds of ``tiles`` (pass 1), ``flip`` (a flipped store), ``pass2``, ``levels``
    cut : the material's sums over the tiles (a cut with the cutting mechanics):
        ``grooves_sumsq``, ``grooves_n``, ``added_max``, ``edge_pixels``, the texture's
        ``texture_sumsq`` and ``texture_n``, with the material's burrs ``burr_edge_pixels``,
        ``burr_turn_max`` (rad), ``burr_height_max`` and ``burr_added_max`` (mm); and
        ``pass_theta``, the cutting pass's angle on every ``stride``-th row and column
    """

    moments: tuple
    abs_dev: tuple
    histogram: tuple
    tiles: int
    timing_s: dict = field(default_factory=dict)
    cut: dict = field(default_factory=dict)


class _Counter:
    """Calls ``progress(done, total, elapsed_s)`` as tasks finish."""

    def __init__(self, total: int, progress, t0: float):
        self.total, self.progress, self.t0, self.done = total, progress, t0, 0

    def step(self, n: int = 1):
        self.done += n
        if self.progress is not None:
            self.progress(self.done, self.total, time.perf_counter() - self.t0)


def _run(fn, arg_lists: list[tuple], shared: tuple, *, client=None, workers: int | None = None,
         progress=None, total: int | None = None) -> list:
    """fn(*shared, *args) for each args in ``arg_lists`` on Dask; results in order.
    ``progress`` counts ``total`` items (default: the calls; a call that returns a list
    counts its items)."""
    t0 = time.perf_counter()
    counter = _Counter(total if total is not None else len(arg_lists), progress, t0)
    if client is not None:
        from distributed import as_completed

        wait_for_workers(client, label="the tiled simulation",
                         n=getattr(client, "expected_workers", None))
        client.run(_load_kernels)
        threads = cluster_info(client)["threads"]
        big = [client.scatter(v, broadcast=True) if isinstance(v, (EnvelopePath, CutPath)) else v for v in shared]
        futures = [client.submit(call_with_threads, threads, fn, *big, *args, pure=False)
                   for args in arg_lists]
        index = {f.key: i for i, f in enumerate(futures)}
        out = [None] * len(futures)
        try:
            for fut in as_completed(futures, loop=client.loop):
                out[index[fut.key]] = r = fut.result()
                counter.step(len(r) if isinstance(r, list) else 1)
                fut.release()
        except BaseException:
            # stopped: no tile not yet started starts (running ones cannot be stopped)
            with contextlib.suppress(Exception):
                client.cancel(futures)
            raise
        return out
    import dask
    from dask.diagnostics import Callback

    shared_d = [dask.delayed(v, traverse=False) if isinstance(v, (EnvelopePath, CutPath)) else v
                for v in shared]
    running = _Running()
    tasks = [dask.delayed(running.wrap(fn), pure=False)(*shared_d, *args) for args in arg_lists]
    keys = {t.key for t in tasks}

    def posttask(key, result, dsk, state, worker_id):
        if key in keys:
            counter.step(len(result) if isinstance(result, list) else 1)

    with Callback(posttask=posttask):
        try:
            return list(dask.compute(*tasks, scheduler="threads",
                                     num_workers=workers or usable_cpus()))
        except BaseException:
            # a stop (or a failed tile) ends the main thread's wait at once, but the pool's
            # threads finish the tiles they run, writing into the store: wait for them, so
            # that the output folder is removed after its last write, not before
            running.wait_idle(DRAIN_S)
            raise


#: how long a stopped threaded run waits for the tiles its threads are cutting, s
DRAIN_S = 120.0


class _Running:
    """Counts the calls of a function running in the pool's threads."""

    def __init__(self):
        self._n = 0
        self._cond = threading.Condition()

    def wrap(self, fn):
        def tracked(*a):
            with self._cond:
                self._n += 1
            try:
                return fn(*a)
            finally:
                with self._cond:
                    self._n -= 1
                    self._cond.notify_all()
        tracked.__name__ = getattr(fn, "__name__", "tile")
        return tracked

    def wait_idle(self, timeout: float) -> bool:
        """Wait until no call runs (at most ``timeout`` s); returns whether none does."""
        with self._cond:
            return self._cond.wait_for(lambda: self._n == 0, timeout=timeout)


#: glibc's mallopt parameters (malloc.h) and what the tiles' run sets them to: arrays up
#: to 1 GiB from the heap (glibc's dynamic threshold stops at 32 MiB, below the 36 MB
#: arrays of a 1024-pixel tile's block with the wider halo of uncut pixels), freed memory
#: kept instead of given back (every tile allocates its block's arrays afresh: given back,
#: each page faults again when the next tile touches it), the heap grown by 64 MiB at a time
_M_TRIM_THRESHOLD, _M_TOP_PAD, _M_MMAP_THRESHOLD = -1, -2, -3
_KEPT_HEAP = ((_M_MMAP_THRESHOLD, GIB_TO_BYTES), (_M_TRIM_THRESHOLD, 2 * GIB_TO_BYTES - 1),
              (_M_TOP_PAD, 64 * MIB_TO_BYTES))
#: after the run: glibc's defaults for the top pad, and the thresholds its dynamic rule
#: reaches with arrays of 32 MiB (the trim threshold twice the mmap threshold)
_HEAP_AFTER = ((_M_TOP_PAD, MIB_TO_BYTES // 8), (_M_TRIM_THRESHOLD, 64 * MIB_TO_BYTES),
               (_M_MMAP_THRESHOLD, 32 * MIB_TO_BYTES))


@contextlib.contextmanager
def _kept_heap() -> Iterator[bool]:
    """While the tiles of this process run (the threaded scheduler): glibc's allocator
    keeps the memory the tiles free for the next tiles (:data:`_KEPT_HEAP`), then gives it
    back (``malloc_trim``).  The resident set stays at the tiles' high-water mark (measured:
    the peak of a whole part did not rise, docs/benchmarks.md); other C libraries: nothing
    changes.  Yields whether the settings were made."""
    try:
        libc = ctypes.CDLL("libc.so.6")
        mallopt, trim = libc.mallopt, libc.malloc_trim
    except (OSError, AttributeError):
        yield False
        return
    ok = all(mallopt(p, v) == 1 for p, v in _KEPT_HEAP)
    try:
        yield ok
    finally:
        for p, v in _HEAP_AFTER:
            mallopt(p, v)
        trim(0)


def run_tiles(ep: EnvelopePath | CutPath, surface: Any, *, origin: Sequence[float], pixel: float,
              shape: Sequence[int], store: str, levels: int, tile: int = TILE, client: Any = None,
              workers: int | None = None, progress: Callable[[int, int, float], object] | None = None,
              bins: int = BINS, grooves: Grooves | None = None, stride: int = 0,
              texture: tuple[float, float, int] | None = None,
              burrs: dict[str, Any] | None = None, flip: bool = False) -> TiledStats:
    """Compute the machined surface of ``ep`` over the grid tile by tile into ``store``.

    Parameters
    ----------
    ep : EnvelopePath or CutPath
        The whole path (``prepare_envelope``: the geometric envelope; ``prepare_cut``:
        with the cutting mechanics of a material).
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
    grooves : Grooves, optional
        The grooves of a cut with the cutting mechanics.
    stride : int
        Keep the cutting pass's angle on every ``stride``-th row and column (0: none).
    texture : (rms, correlation length, seed), optional
        The part's texture added to a cut with the cutting mechanics (mm).
    burrs : dict, optional
        The material's burrs added to a cut with the cutting mechanics, after the texture
        (the keyword arguments of :func:`~render_inspect.machining.material_burrs` but the
        grid's; each tile is cut with the burr model's halo,
        :func:`~render_inspect.machining.compute_tile`).
    flip : bool
        Store the map with its rows in the other order (row k of the grid cut is row
        ny - 1 - k of the store; the pass angles of ``cut`` too): the grid cut is the
        mirror (y -> -y) of the store's, the M03 run of the mirror image that a program
        turning M04 cuts.  The tiles are cut and written as they are, then the store's
        rows turned over column by column (:func:`~._tile_flip.flip_column`, the pyramid
        made from the turned map), out of core.
    """
    tiles = plan_tiles(shape, tile)
    tile_levels = min(levels, int(math.log2(tile))) if tile & (tile - 1) == 0 else 0
    if levels > tile_levels and tile & (tile - 1):
        raise InputError(f"tile must be a power of two for a pyramid, got {tile}")
    timing = {}
    t0 = time.perf_counter()
    if burrs is not None and isinstance(ep, CutPath):
        # the burr model's halo is wide: the tiles of a column share the cut rows of their
        # blocks, in runs (at least two per worker; per tile where the cluster's size is unknown)
        n_workers = (workers or usable_cpus()) if client is None else cluster_info(client)["workers"]
        runs = column_runs(tiles, 2 * n_workers) if n_workers else [[t] for t in tiles]
    else:
        runs = [[t] for t in tiles]
    with _kept_heap() if client is None else contextlib.nullcontext(False):
        done = {(p["tile"].row, p["tile"].col): p
                # (a store to flip gets its levels from the flipped map, below)
                for r in _run(tile_task, [(r, store, 0 if flip else levels, 0 if flip else tile_levels)
                                          for r in runs],
                              (ep, surface, origin, pixel, grooves, tuple(shape), int(stride), texture, burrs),
                              client=client, workers=workers, progress=progress, total=len(tiles))
                for p in r}
    # in the tiles' order: the moments are merged in it (the same sums whatever the runs)
    parts = [done[(t.row, t.col)] for t in tiles]
    timing["tiles"] = time.perf_counter() - t0
    if flip:
        t0 = time.perf_counter()
        cols = sorted({t.col for t in tiles})
        flipped = {(p["tile"].row, p["tile"].col): p["coarse"]
                   for r in _run(flip_column, [(c,) for c in cols],
                                 (store, tuple(shape), int(tile), levels, tile_levels),
                                 client=client, workers=workers)
                   for p in r}
        for p in parts:
            p["coarse"] = flipped[(p["tile"].row, p["tile"].col)]
        timing["flip"] = time.perf_counter() - t0
    moments = (0, 0.0, 0.0, math.inf, -math.inf)
    for p in parts:
        moments = merge_moments(moments, p["moments"])
    if moments[0] == 0:
        raise ValueError("the path does not cover the region: no finite residual")
    t0 = time.perf_counter()
    _, mean, _, lo, hi = moments
    # the histogram spans the float32 values actually stored
    lo32, hi32 = float(np.float32(lo)), float(np.float32(hi))
    # the stored residual read back as a dask.array whose chunks are the tiles
    n2, sa, counts = stored_abs_dev(store, mean, lo32, hi32, bins, client=client, workers=workers)
    timing["pass2"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    if levels > tile_levels:
        import zarr

        group: Any = zarr.open_group(store, mode="r+")  # (its members are the store's arrays)
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
                with cancel.deferred():  # zarr's I/O thread finishes the write first
                    group[f"levels/{k}/{name}"][...] = means(s, c)
    timing["levels"] = time.perf_counter() - t0
    return TiledStats(moments, (n2, sa), (lo32, hi32, counts), len(tiles), timing,
                      _merge_cut(parts, shape, stride, flip) if isinstance(ep, CutPath) else {})


def _merge_cut(parts: list, shape, stride: int, flip: bool = False) -> dict:
    """The material's sums over the tiles, and the strided pass-angle map (``flip``: its
    rows in the other order)."""
    cuts = [p["cut"] for p in parts]
    out = {"grooves_sumsq": math.fsum(c["grooves_sumsq"] for c in cuts),
           "grooves_n": int(sum(c["grooves_n"] for c in cuts)),
           "added_max": max((c["added_max"] for c in cuts), default=-math.inf),
           "edge_pixels": int(sum(c["edge_pixels"] for c in cuts)),
           "texture_sumsq": math.fsum(c.get("texture_sumsq", 0.0) for c in cuts),
           "texture_n": int(sum(c.get("texture_n", 0) for c in cuts))}
    if any("burr_edge_pixels" in c for c in cuts):
        out["burr_edge_pixels"] = int(sum(c["burr_edge_pixels"] for c in cuts))
        for k in ("burr_turn_max", "burr_height_max", "burr_added_max"):
            out[k] = max(c[k] for c in cuts)
    if stride > 0:
        pt = np.full((-(-shape[0] // stride), -(-shape[1] // stride)), np.nan)
        for c in cuts:
            i0, j0, a = c["pass_theta"]
            pt[i0:i0 + a.shape[0], j0:j0 + a.shape[1]] = a
        out["pass_theta"] = np.ascontiguousarray(pt[::-1]) if flip else pt
    return out


def _load_kernels() -> bool:
    """Load the tile code's compiled kernels (in a worker process)."""
    load_kernels()
    load_cut_kernels()
    z = np.zeros((1, 1))
    tile_moments(z, z)
    return True


@contextlib.contextmanager
def tile_client(*, workers: int | None = None, scheduler: str | None = None,
                client: Any = None) -> Iterator[Any]:
    """The Dask client tiles run on (:func:`render_inspect.batch.dask_client`): ``client``
    when given; the cluster whose scheduler listens at ``scheduler``; a ``LocalCluster`` of
    ``workers`` single-threaded processes; the client open in this process (a notebook's);
    or None (the threaded scheduler of this process) when there is none of these.

    The workers of a LocalCluster start in the background: the caller can plan the path
    meanwhile, and :func:`run_tiles` waits for them.  Scripts that start a cluster need
    the ``if __name__ == "__main__":`` guard (worker processes re-import the main module)."""
    if client is None and scheduler is None and workers is None and open_client() is None:
        yield None
        return
    with dask_client(client=client, scheduler=scheduler, workers=workers, wait=False,
                     label="--scheduler" if scheduler else None) as c:
        yield c
