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
of the tile's border pixels.  With the material's burrs the halo is the burr model's reach
(:func:`~._burrs.burr_halo`: the smoothing, the edge's turn, the ridge's half width): the
texture is added on the halo'd block, which is smoothed where the edge search reads it,
and the edges and ridges are found only on the tile and the ridge's half width around it
(``material_burr_block(..., inner=)``: the same numbers as on the whole block); on a block
inside the grid with every pixel cut, the design on the block lets the model show first
that no pixel of the tile's window can be an edge, without smoothing the block
(:func:`~._burr_bound.no_edge_possible`: no burrs, as the search would find).  The tile
also returns the partial sums of the material's facts (the grooves' squares, the largest
displaced material, the edge pixels, the burrs' edge pixels and maxima) and, for the
following-error map, its pixels on a stride of the whole grid.  The burr model's halo is
wide (268 pixels at 0.5 um on the shipped lathe and aluminium: a 1024-pixel tile's block
has 2.3 times its pixels), so the tiles of a column are computed top to bottom in one
task that keeps the last block (``carry``): the rows two blocks share are cut once, as
are the pixels a tile with uncut pixels shares with its block before the wider halo.

Peak memory is bounded by (tiles in flight) x (tile size), not by the part.  The
scheduling on Dask, the store and the reductions are in ``render_inspect.batch``; this
module holds the pure per-tile computation.
"""

from __future__ import annotations

from collections.abc import Sequence
import functools
from dataclasses import dataclass
from typing import Any

import numpy as np

import math

from ..core.errors import InputError
from ._burrs import BURR_WIDTH_PER_CHIP, burr_halo, material_burr_block
from ._cut_kernel import CutPath, Grooves, cut_fill
from ._cutting import machined_edges
from ._envelope import BLOCK, EnvelopePath, envelope_fill
from ._texture import textured

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

    def region(self, origin: Sequence[float], pixel: float) -> tuple[float, float, float, float]:
        """(x0, y0, x1, y1) of the tile's pixel centres, mm."""
        x0 = origin[0] + self.col * pixel
        y0 = origin[1] + self.row * pixel
        return (x0, y0, x0 + (self.cols - 1) * pixel, y0 + (self.rows - 1) * pixel)


def plan_tiles(shape: Sequence[int], tile: int = TILE) -> list[Tile]:
    """Square tiles of side ``tile`` (a multiple of 64) covering a (ny, nx) grid."""
    if tile <= 0 or tile % BLOCK:
        raise InputError(f"tile must be a positive multiple of {BLOCK} pixels, got {tile}")
    ny, nx = shape
    return [Tile(r, c, min(tile, ny - r), min(tile, nx - c))
            for r in range(0, ny, tile) for c in range(0, nx, tile)]


def design_tile(surface: Any, origin: Sequence[float], pixel: float, tile: Tile, *,
                rows_per_chunk: int = 128) -> np.ndarray:
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


def compute_tile(ep: EnvelopePath | CutPath, surface: Any, origin: Sequence[float], pixel: float,
                 tile: Tile, *, grooves: Grooves | None = None,
                 shape: Sequence[int] | None = None, stride: int = 0,
                 texture: tuple[float, float, int] | None = None,
                 burrs: dict | None = None,
                 carry: dict | None = None) -> tuple[np.ndarray, np.ndarray, dict]:
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
    and ``texture_n``.

    ``burrs`` (a cut only) = the keyword arguments of
    :func:`~render_inspect.machining.material_burrs` but ``origin`` and ``pixel``
    (``chip_thickness``, ``coefficient``, ``variation``, ``seed``, ``edge_angle_deg``,
    ``smoothing``, optional ``width``) adds the material's burrs after the texture, as on
    the whole grid: the tile is cut with a halo of :func:`~._burrs.burr_halo` pixels (the
    burr model's reach; a wider one where the halo'd block has NaN pixels, which are
    filled from their nearest valid pixel), inside the grid, and the burrs of that block
    are cropped to the tile (equal to the whole grid's bit for bit).  Partials
    ``burr_edge_pixels``, ``burr_turn_max`` (rad), ``burr_height_max`` and
    ``burr_added_max`` (mm): summed and maximised over the tiles they give the facts of
    :func:`~render_inspect.machining.material_burrs`.

    ``carry`` (a cut only): a dict kept between the tiles of one column of the grid,
    computed top to bottom: the rows of the halo'd block that a tile shares with the one
    above it are not cut again (the results are the same; the dict holds one block)."""
    design = design_tile(surface, origin, pixel, tile)
    if isinstance(ep, EnvelopePath):
        if burrs is not None:
            raise InputError("compute_tile: burrs need a cut with the material's mechanics (a CutPath)")
        sl = ep.slice_for(tile.region(origin, pixel))
        machined = np.empty((tile.rows, tile.cols))
        envelope_fill(sl, origin, pixel, machined, start=(tile.row, tile.col), parallel=False)
        return design, machined, {}
    if not isinstance(ep, CutPath):
        raise TypeError(f"compute_tile: an EnvelopePath or a CutPath, got {type(ep).__name__}")
    ny, nx = shape if shape is not None else (tile.row + tile.rows, tile.col + tile.cols)
    if burrs is not None:
        burrs = dict(burrs)
        if burrs.get("width") is None:
            burrs["width"] = BURR_WIDTH_PER_CHIP * burrs["chip_thickness"]
        halo = max(HALO, burr_halo(pixel, burrs["smoothing"], burrs["width"]))
    else:
        halo = HALO
    narrow = halo
    maps, st, big = _cut_block(ep, grooves, origin, pixel, tile, halo, (ny, nx), carry)
    if burrs is not None and big.rows * big.cols < ny * nx and not np.isfinite(maps["machined"]).all():
        # NaN pixels are filled from their nearest valid pixel: a wider halo
        halo = max(HALO, burr_halo(pixel, burrs["smoothing"], burrs["width"], nan=True))
        maps, st, big = _cut_block(ep, grooves, origin, pixel, tile, halo, (ny, nx), carry)
    r0, c0 = big.row, big.col
    rows = slice(tile.row - r0, tile.row - r0 + tile.rows)
    cols = slice(tile.col - c0, tile.col - c0 + tile.cols)
    # the machined edges of the tile: its pixels and their neighbours within the block
    e0, e1 = max(rows.start - 1, 0), min(rows.stop + 1, big.rows)
    f0, f1 = max(cols.start - 1, 0), min(cols.stop + 1, big.cols)
    edges = machined_edges(maps["pass_theta"][e0:e1, f0:f1],
                           jump=math.pi)[rows.start - e0:rows.stop - e0, cols.start - f0:cols.stop - f0]
    part: dict[str, Any] = {"grooves_sumsq": float(st[rows, 0].sum()), "grooves_n": int(st[rows, 1].sum()),
            "added_max": float(st[rows, 2].max()) if tile.rows else -math.inf}
    part["edge_pixels"] = int(edges.sum())
    if stride > 0:
        i0 = -(-tile.row // stride)
        j0 = -(-tile.col // stride)
        pr = np.arange(i0 * stride, tile.row + tile.rows, stride) - r0
        pc = np.arange(j0 * stride, tile.col + tile.cols, stride) - c0
        part["pass_theta"] = (i0, j0, maps["pass_theta"][np.ix_(pr, pc)])
    # the texture and the burrs on the block that the burrs need (the tile alone without)
    blk = (slice(None), slice(None)) if burrs is not None else (rows, cols)
    at = (rows, cols) if burrs is not None else (slice(None), slice(None))
    src = maps["machined"][blk]
    if texture is not None and texture[0] > 0 and np.isfinite(src).any():
        r_a, c_a = (r0, c0) if burrs is not None else (tile.row, tile.col)
        src = np.ascontiguousarray(src)
        x = origin[0] + pixel * np.arange(c_a, c_a + src.shape[1])
        y = origin[1] + pixel * np.arange(r_a, r_a + src.shape[0])
        # texture_field added where the map is finite, in one compiled pass (the same
        # numbers as numpy's): the texture's squares left there
        machined, sq = textured(src, x, y, rms=texture[0], correlation_length=texture[1], seed=texture[2],
                                cache=carry)
        ot = np.isfinite(machined[at])
        part["texture_sumsq"], part["texture_n"] = float(np.sum(sq[at][ot])), int(ot.sum())
        del sq, ot
    else:
        if texture is not None and texture[0] > 0:
            # no pixel to add it to (a block beyond the workpiece's rim): the sums are 0
            part["texture_sumsq"], part["texture_n"] = 0.0, 0
        machined = src.copy()
    del maps, src
    if burrs is not None:
        part.update(burr_edge_pixels=0, burr_turn_max=0.0, burr_height_max=0.0, burr_added_max=0.0)
        # the burrs of the tile's pixels only (the block is what they need)
        border = (r0 == 0, big.row + big.rows == ny, c0 == 0, big.col + big.cols == nx)
        # the design on a block inside the grid with every pixel cut: the map with which the
        # burr model shows a tile without edges to be one before smoothing the block (made
        # there, and let go before it smooths)
        r = material_burr_block(machined, pixel=pixel, origin=origin, **burrs, border=border,
                                start=(r0, c0), inner=(rows.start, rows.stop, cols.start, cols.stop),
                                reference=functools.partial(design_tile, surface, origin, pixel, big)
                                if halo == narrow and not any(border) else None)
        machined = machined[at].copy()
        if r is not None:
            b, e, turn, heights = r
            del r
            machined += b
            part["burr_edge_pixels"] = int(e.sum())
            if part["burr_edge_pixels"]:
                part["burr_turn_max"] = float(turn[e].max())
            part["burr_height_max"] = float(heights.max())
            part["burr_added_max"] = float(np.nanmax(b))
    return design, machined, part


def _cut_block(ep: CutPath, grooves, origin, pixel: float, tile: Tile, halo: int, shape,
               carry: dict | None = None):
    """The cut's maps (``machined`` and ``pass_theta``) and row statistics on the tile and
    a halo of ``halo`` pixels inside the grid of ``shape``, and that block (a Tile).

    ``carry`` (a dict the caller keeps between calls: the tiles of a column top to
    bottom, and the wider halo of a tile with NaN pixels): the pixels this block shares
    with the previous one are taken from it instead of being cut again, and this block is
    left in it for the next call.  Each pixel depends only on the path and its position,
    and a row's sums only on the tile's pixels of that row (cut in one call), so the
    block equals one cut whole bit for bit."""
    ny, nx = shape
    r0, c0 = max(tile.row - halo, 0), max(tile.col - halo, 0)
    r1, c1 = min(tile.row + tile.rows + halo, ny), min(tile.col + tile.cols + halo, nx)
    big = Tile(r0, c0, r1 - r0, c1 - c0)
    key = (tile.col, tile.cols)   # the columns a row's sums cover
    maps = {k: np.empty((big.rows, big.cols)) for k in ("machined", "pass_theta")}
    st = np.empty((big.rows, 3))
    gr = grooves if grooves is not None else Grooves.none()

    def cut(a: int, b: int, ca: int, cb: int, into_stats: bool) -> None:
        """Cut rows [a, b) x columns [ca, cb) (grid indices) into the block."""
        if a >= b or ca >= cb:
            return
        part = Tile(a, ca, b - a, cb - ca)
        sl = ep.slice_for(part.region(origin, pixel))
        whole = ca == c0 and cb == c1
        out = ({k: maps[k][a - r0:b - r0] for k in maps} if whole
               else {k: np.empty((part.rows, part.cols)) for k in maps})
        out["added"] = np.empty((part.rows, part.cols))
        sc = (tile.col - ca, tile.col - ca + tile.cols) if into_stats else (0, 0)
        s = cut_fill(sl, gr, origin, pixel, out, start=(a, ca), parallel=False, stat_cols=sc)
        if not whole:
            for k in maps:
                maps[k][a - r0:b - r0, ca - c0:cb - c0] = out[k]
        if into_stats:
            st[a - r0:b - r0] = s

    prev = carry.get("block") if carry is not None else None
    o0 = o1 = r0
    if prev is not None:
        pkey, p0, p1, pc0, pc1, pmaps, pst = prev
        o0, o1 = max(r0, p0), min(r1, p1)
        oc0, oc1 = max(c0, pc0), min(c1, pc1)
        # reused: the rows the two blocks share, where the tile's columns (its row sums)
        # lie inside the shared columns
        if not (pkey == key and o0 < o1 and oc0 <= tile.col and tile.col + tile.cols <= oc1):
            o0 = o1 = r0
    if o0 < o1:
        for k in maps:
            maps[k][o0 - r0:o1 - r0, oc0 - c0:oc1 - c0] = pmaps[k][o0 - p0:o1 - p0, oc0 - pc0:oc1 - pc0]
        st[o0 - r0:o1 - r0] = pst[o0 - p0:o1 - p0]
        cut(r0, o0, c0, c1, True)
        cut(o1, r1, c0, c1, True)
        cut(o0, o1, c0, oc0, False)
        cut(o0, o1, oc1, c1, False)
    else:
        cut(r0, r1, c0, c1, True)
    if carry is not None:
        carry["block"] = (key, r0, r1, c0, c1, maps, st)
    return maps, st, big
