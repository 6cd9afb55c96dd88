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

With the cutting mechanics of a material (a :class:`~._cut_kernel.CutPath` instead of an
``EnvelopePath``) the tile is computed with a halo of ``HALO`` pixels on every side that
lies inside the grid: each pixel of the kernel depends only on the path and its own
position (the path's reach is in the slice of passes, :meth:`CutPath.slice_for`), and
the machined edges (a pixel whose neighbour was cut by another pass) need the neighbours
of the tile's border pixels.  The tile also returns the partial sums of the material's
facts (the grooves' squares, the largest displaced material, the edge pixels) and, for
the following-error map, its pixels on a stride of the whole grid.

Peak memory is bounded by (tiles in flight) x (tile size), not by the part.  The
scheduling on Dask, the store and the reductions are in ``render_inspect.batch``; this
module holds the pure per-tile computation.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

import math

from ..core.errors import InputError
from ._cut_kernel import OUT_CHANNELS, CutPath, Grooves, cut_fill
from ._cutting import machined_edges
from ._envelope import BLOCK, EnvelopePath, envelope_fill
from ._material import texture_field

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


#: pixels of halo around a tile cut with the material's mechanics (the machined edges
#: compare each pixel with its four neighbours)
HALO = 1


def compute_tile(ep, surface, origin, pixel: float, tile: Tile, *, grooves: Grooves | None = None,
                 shape=None, stride: int = 0, texture=None) -> tuple[np.ndarray, np.ndarray, dict]:
    """(design, machined, partials) of one tile, float64 (mm).

    ``ep`` is an ``EnvelopePath`` (the geometric envelope: machined equals the same pixels
    of ``simulate_turning`` over the whole grid bit for bit; no partials) or a
    :class:`CutPath` (the cutting mechanics with ``grooves``, on the tile and a halo of
    :data:`HALO` pixels inside the grid of ``shape`` (ny, nx): machined equals the same
    pixels of :func:`~render_inspect.machining.cut_turning` over the whole grid bit for
    bit).  The partials of a cut: ``grooves_sumsq``, ``grooves_n``, ``added_max``,
    ``edge_pixels`` (the tile's pixels on a machined edge) and, when ``stride`` > 0,
    ``pass_theta``: (first row, first column, map) of the cutting pass's spindle angle on
    the pixels of the whole grid whose row and column are multiples of ``stride``, the
    first row and column counted on that coarse grid.  ``texture`` = (rms, correlation
    length, seed) (mm) adds the part's texture
    (:func:`~render_inspect.machining.texture_field`, a field of the position: the tile's
    pixels equal the whole grid's) where the tile is cut; its partials ``texture_sumsq``
    and ``texture_n``."""
    design = design_tile(surface, origin, pixel, tile)
    if isinstance(ep, EnvelopePath):
        sl = ep.slice_for(tile.region(origin, pixel))
        machined = np.empty((tile.rows, tile.cols))
        envelope_fill(sl, origin, pixel, machined, start=(tile.row, tile.col), parallel=False)
        return design, machined, {}
    if not isinstance(ep, CutPath):
        raise TypeError(f"compute_tile: an EnvelopePath or a CutPath, got {type(ep).__name__}")
    ny, nx = shape if shape is not None else (tile.row + tile.rows, tile.col + tile.cols)
    r0, c0 = max(tile.row - HALO, 0), max(tile.col - HALO, 0)
    r1, c1 = min(tile.row + tile.rows + HALO, ny), min(tile.col + tile.cols + HALO, nx)
    big = Tile(r0, c0, r1 - r0, c1 - c0)
    sl = ep.slice_for(big.region(origin, pixel))
    maps = {k: np.empty((big.rows, big.cols)) for k in OUT_CHANNELS}
    st = cut_fill(sl, grooves if grooves is not None else Grooves.none(), origin, pixel, maps,
                  start=(r0, c0), parallel=False, stat_cols=(tile.col - c0, tile.col - c0 + tile.cols))
    rows = slice(tile.row - r0, tile.row - r0 + tile.rows)
    cols = slice(tile.col - c0, tile.col - c0 + tile.cols)
    edges = machined_edges(maps["pass_theta"], jump=math.pi)[rows, cols]
    part = {"grooves_sumsq": float(st[rows, 0].sum()), "grooves_n": int(st[rows, 1].sum()),
            "added_max": float(st[rows, 2].max()) if tile.rows else -math.inf}
    part["edge_pixels"] = int(edges.sum())
    if stride > 0:
        i0 = -(-tile.row // stride)
        j0 = -(-tile.col // stride)
        pr = np.arange(i0 * stride, tile.row + tile.rows, stride) - r0
        pc = np.arange(j0 * stride, tile.col + tile.cols, stride) - c0
        part["pass_theta"] = (i0, j0, maps["pass_theta"][np.ix_(pr, pc)])
    machined = maps["machined"][rows, cols].copy()
    if texture is not None and texture[0] > 0:
        x = origin[0] + pixel * np.arange(tile.col, tile.col + tile.cols)
        y = origin[1] + pixel * np.arange(tile.row, tile.row + tile.rows)
        tex = texture_field(x, y, rms=texture[0], correlation_length=texture[1], seed=texture[2])
        ok = np.isfinite(machined)
        machined[ok] += tex[ok]
        part["texture_sumsq"], part["texture_n"] = float(np.sum(tex[ok] ** 2)), int(ok.sum())
    return design, machined, part
