"""Tiles of a turning simulation: the height map of one square tile of the grid at a
time, from the run of the tool path whose nose arcs reach it.

A whole part at the instrument's pixel (10 mm at 0.5 um: 400 M samples, 3.2 GB per
float64 array) does not fit in memory next to its design, residual and previews.  Here
the grid is cut into square tiles (``tile`` pixels, a multiple of the envelope kernel's
block, aligned to the grid origin).  Each tile task

1. takes the run of the tool path whose nose arcs reach the tile
   (``EnvelopePath.slice_for``) and computes the envelope (one core, no GIL) and the
   design heights of the tile in float64;
2. reduces the residual to (n, mean, M2, min, max) (``tile_moments``);
3. writes design, machined and residual (float32) into the store's chunks of the tile
   and the tile's part of every pyramid level (block sums, exact across tiles);
4. returns only the small partials.

Peak memory is bounded by (tiles in flight) x (tile size), not by the part.  The
scheduling on Dask, the store and the reductions are in ``render_inspect.batch``; this
module holds the pure per-tile computation.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..core.errors import InputError
from ._envelope import BLOCK, EnvelopePath, envelope_fill

#: default tile side (pixels): a power of two (pyramid levels stay inside a tile) and a
#: multiple of the kernel's block (tiles equal the whole-grid run bit for bit)
TILE = 1024


@dataclass(frozen=True)
class Tile:
    """Rows ``row .. row + rows - 1`` and columns ``col .. col + cols - 1`` of the grid."""

    row: int
    col: int
    rows: int
    cols: int

    def region(self, origin, pixel) -> tuple[float, float, float, float]:
        """(x0, y0, x1, y1) of the tile's pixel centres, mm."""
        x0 = origin[0] + self.col * pixel
        y0 = origin[1] + self.row * pixel
        return (x0, y0, x0 + (self.cols - 1) * pixel, y0 + (self.rows - 1) * pixel)


def plan_tiles(shape, tile: int = TILE) -> list[Tile]:
    """Square tiles of side ``tile`` (a multiple of 64) covering a (ny, nx) grid."""
    if tile <= 0 or tile % BLOCK:
        raise InputError(f"tile must be a positive multiple of {BLOCK} pixels, got {tile}")
    ny, nx = shape
    return [Tile(r, c, min(tile, ny - r), min(tile, nx - c))
            for r in range(0, ny, tile) for c in range(0, nx, tile)]


def design_tile(surface, origin, pixel: float, tile: Tile, *, rows_per_chunk: int = 128) -> np.ndarray:
    """Design heights (mm, float64) of the tile's pixels, in row chunks (bounded temporaries)."""
    x = origin[0] + pixel * (tile.col + np.arange(tile.cols))
    out = np.empty((tile.rows, tile.cols))
    for a in range(0, tile.rows, rows_per_chunk):
        b = min(a + rows_per_chunk, tile.rows)
        y = origin[1] + pixel * (tile.row + np.arange(a, b))
        out[a:b] = surface.height(x[None, :], y[:, None])
    return out


def compute_tile(ep: EnvelopePath, surface, origin, pixel: float, tile: Tile) -> tuple[np.ndarray, np.ndarray]:
    """(design, machined) of one tile, float64 (mm): machined equals the same pixels of
    ``simulate_turning`` over the whole grid bit for bit."""
    sl = ep.slice_for(tile.region(origin, pixel))
    machined = np.empty((tile.rows, tile.cols))
    envelope_fill(sl, origin, pixel, machined, start=(tile.row, tile.col), parallel=False)
    return design_tile(surface, origin, pixel, tile), machined
