"""A store's rows turned over, out of core: the map the tiles wrote on a mirrored grid
(a program turning the spindle M04 is cut as the M03 run of the mirror image) made the
part's, in its own coordinates (row k becomes row ny - 1 - k).

One task turns one column of chunks over and writes every chunk of it whole, with its
pyramid levels made from it as a tile makes them
(:func:`~render_inspect.batch._tile_pyramid.write_tile`): the levels are those of the
flipped map (the 2 x 2 blocks start at its row 0), not the stored levels flipped.  Chunk k
of the flipped map (rows kT .. kT + T - 1, T the chunk's side) is rows ny - kT - T ..
ny - kT - 1 of the stored map in the other order, which lie in at most two of its chunks.
The chunks are written from both ends of the column inward; a chunk that a write replaces
while a later chunk still reads it is read first and held.  A column holds at most a few
chunks at a time (:func:`column_sources`): the memory is bounded by the chunk's side, not
by the map's.
"""

from __future__ import annotations

from collections import Counter
from typing import Any

import numpy as np

from ..core import cancel
from ..machining import Tile
from ._tile_pyramid import CHANNELS, write_tile

__all__ = ["flip_column", "flip_order", "column_sources"]

def flip_order(n: int) -> list[int]:
    """The chunks 0 .. n - 1 of a column from both ends inward: 0, n - 1, 1, n - 2, ..."""
    out = []
    lo, hi = 0, n - 1
    while lo <= hi:
        out.append(lo)
        if hi != lo:
            out.append(hi)
        lo, hi = lo + 1, hi - 1
    return out


def column_sources(k: int, ny: int, chunk: int) -> range:
    """The chunks of the stored column that chunk ``k`` of the flipped one reads (one or two)."""
    r0, r1 = k * chunk, min((k + 1) * chunk, ny)
    m0, m1 = ny - r1, ny - r0
    return range(m0 // chunk, (m1 - 1) // chunk + 1)


def flip_column(store: str, shape: tuple[int, int], chunk: int, levels: int, tile_levels: int,
                col: int, *, stats: dict | None = None) -> list[dict[str, Any]]:
    """Turn over the rows of the column of chunks that starts at column ``col`` of
    ``store`` (its maps of ``shape``, chunks of side ``chunk``), with their pyramid levels
    up to ``tile_levels`` of ``levels``; return, for each chunk (a Tile), the block sums
    and counts at level ``tile_levels`` of each map where coarser levels follow
    (``{"tile": Tile, "coarse": {name: (sums, counts)}}``).  ``stats``: given a dict, the
    most chunks the column held at once is put in it (``"held"``)."""
    import zarr

    group: Any = zarr.open_group(store, mode="r+")  # (its members are the store's arrays)
    ny, nx = (int(v) for v in shape)
    c0, c1 = col, min(col + chunk, nx)
    n = -(-ny // chunk)
    tiles = [Tile(k * chunk, col, min(chunk, ny - k * chunk), c1 - c0) for k in range(n)]
    coarse: list[dict] = [{} for _ in range(n)]
    held_most = 0
    for name in CHANNELS:
        arr = group[name]

        def read(j: int, arr: Any = arr) -> np.ndarray:
            return np.asarray(arr[j * chunk:min((j + 1) * chunk, ny), c0:c1])

        need = Counter(j for k in range(n) for j in column_sources(k, ny, chunk))
        held: dict[int, np.ndarray] = {}
        for k in flip_order(n):
            cancel.check()  # a stop ends the column at its next chunk
            r0, r1 = k * chunk, min((k + 1) * chunk, ny)
            block = np.empty((r1 - r0, c1 - c0), dtype=np.float32)
            for j in column_sources(k, ny, chunk):
                src = held[j] if j in held else read(j)
                a, b = max(ny - r1, j * chunk), min(ny - r0, (j + 1) * chunk)
                block[ny - b - r0:ny - a - r0] = src[a - j * chunk:b - j * chunk][::-1]
                need[j] -= 1
                if need[j] > 0:
                    held[j] = src
                else:
                    held.pop(j, None)
            if need[k] > 0 and k not in held:  # still to be read: held before it is replaced
                held[k] = read(k)
            held_most = max(held_most, len(held))
            coarse[k].update(write_tile(group, tiles[k], {name: block}, levels, tile_levels))
            del block
        if held:
            raise RuntimeError(f"flip_column: chunks {sorted(held)} held after the column")
    if stats is not None:
        stats["held"] = held_most
    return [{"tile": t, "coarse": c} for t, c in zip(tiles, coarse)]
