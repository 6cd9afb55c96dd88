"""Statistics of a stored map read as a ``dask.array`` (its chunks are the tiles it was
computed in): the second, read-only pass of the tiled simulation."""

from __future__ import annotations

import functools
import math

from typing import Any

import numpy as np
import numpy.typing as npt

from ..machining import tile_abs_dev
from ._cluster import call_with_threads, cluster_info

__all__ = ["stored_abs_dev"]


def _block_abs_dev(block: np.ndarray, mean: float, lo: float, hi: float, bins: int) -> np.ndarray:
    """(n, sum |r - mean|, counts...) of one chunk, as a (1, 1, bins + 2) array."""
    n, s, counts = tile_abs_dev(block, mean, lo, hi, bins)
    out = np.empty((1, 1, bins + 2))
    out[0, 0, 0] = n
    out[0, 0, 1] = s
    out[0, 0, 2:] = counts
    return out


def stored_abs_dev(store: str, mean: float, lo: float, hi: float, bins: int, *,
                   client: Any = None, workers: int | None = None, channel: str = "residual"
                   ) -> tuple[int, float, npt.NDArray[np.int64]]:
    """(n, sum |r - mean|, histogram counts over [lo, hi] in ``bins`` bins) of the stored
    ``channel``, chunk by chunk through ``dask.array`` (``map_blocks`` of
    :func:`render_inspect.machining.tile_abs_dev`), on ``client`` or on threads; the
    chunks' sums are added exactly on the caller's side (``math.fsum``).  (``client``: a
    ``distributed.Client``, an optional dependency imported where it is used.)"""
    import dask
    import dask.array as da
    import zarr

    arr = da.from_zarr(zarr.open_array(f"{store}/{channel}", mode="r"))
    threads = cluster_info(client)["threads"] if client is not None else None
    fn = functools.partial(call_with_threads, threads, _block_abs_dev)
    parts = arr.map_blocks(fn, mean, lo, hi, bins, new_axis=2, chunks=(1, 1, bins + 2),
                           dtype=np.float64, meta=np.empty((0, 0, 0)))
    if client is not None:
        per_chunk = client.compute(parts).result()
    else:
        (per_chunk,) = dask.compute(parts, scheduler="threads",
                                    num_workers=workers or None)
    flat = per_chunk.reshape(-1, bins + 2)
    n = int(flat[:, 0].sum())
    s = math.fsum(flat[:, 1])
    counts = flat[:, 2:].sum(axis=0).round().astype(np.int64)
    return n, s, counts
