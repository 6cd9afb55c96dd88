"""One tile's float32 maps and pyramid levels for the store, compiled: the same numbers,
to the last bit, as the numpy and :mod:`render_inspect.io` operations they replace.

* :func:`tile_float32` rounds design, machined and residual (machined - design, formed in
  float64) to float32 and takes the level-1 block sums and counts of the three in the same
  pass (:func:`render_inspect.io.block_sums` of each float32 map: the finite samples of
  each 2 x 2 block added in row order, from 0);
* :func:`coarsen2` is :func:`render_inspect.io.coarsen` with a factor 2 (the 2 x 2 entries
  of a block added as numpy adds them: each row's pair, then the two pairs; the missing
  ones of the last row or column as 0);
* :func:`block_means` is :func:`render_inspect.io.means` (each mean taken in float64 and
  rounded to float32; NaN where a block has no sample);
* :func:`write_tile` writes a tile's float32 maps and their levels into the store.

One tile runs on one core (the tiles run side by side), so the loops are serial and
release the GIL.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from ..core.lazy import njit  # numba, imported on first use
from ..io import block_sums, coarsen
from ..machining import Tile

__all__ = ["CHANNELS", "tile_float32", "coarsen2", "block_means", "write_tile"]

#: the maps of a height-map store, in the order they are written
CHANNELS = ("design", "machined", "residual")


@njit(cache=True, nogil=True)
def _float32_level1(design, machined, d32, m32, r32, sums, counts):
    ny, nx = design.shape
    for i in range(ny):
        bi = i // 2
        for j in range(nx):
            d = design[i, j]
            m = machined[i, j]
            a = np.float32(d)
            b = np.float32(m)
            c = np.float32(m - d)
            d32[i, j] = a
            m32[i, j] = b
            r32[i, j] = c
            bj = j // 2
            v = np.float64(a)
            if math.isfinite(v):
                sums[0, bi, bj] += v
                counts[0, bi, bj] += 1
            v = np.float64(b)
            if math.isfinite(v):
                sums[1, bi, bj] += v
                counts[1, bi, bj] += 1
            v = np.float64(c)
            if math.isfinite(v):
                sums[2, bi, bj] += v
                counts[2, bi, bj] += 1


def tile_float32(design: np.ndarray, machined: np.ndarray
                 ) -> tuple[dict[str, np.ndarray], dict[str, tuple[np.ndarray, np.ndarray]]]:
    """({"design", "machined", "residual"}: float32 maps, the same keys: their level-1
    (sums, counts)) of a tile's float64 ``design`` and ``machined`` maps."""
    d = np.ascontiguousarray(design, dtype=np.float64)
    m = np.ascontiguousarray(machined, dtype=np.float64)
    if d.shape != m.shape or d.ndim != 2:
        raise ValueError(f"tile_float32: design {d.shape} and machined {m.shape} must be one 2-D shape")
    ny, nx = d.shape
    maps = {k: np.empty((ny, nx), dtype=np.float32) for k in CHANNELS}
    shape = (3, -(-ny // 2), -(-nx // 2))
    sums = np.zeros(shape)
    counts = np.zeros(shape, dtype=np.int64)
    _float32_level1(d, m, maps["design"], maps["machined"], maps["residual"], sums, counts)
    return maps, {k: (sums[i], counts[i]) for i, k in enumerate(maps)}


#: the smallest side of a coarser level that :func:`coarsen2` computes compiled
_COMPILED_SIDE = 4


@njit(inline="always")
def _at(s, i, j):
    """s[i, j], 0 beyond the map (numpy's padding)."""
    return s[i, j] if i < s.shape[0] and j < s.shape[1] else 0.0


@njit(cache=True, nogil=True)
def _coarsen2(s, c, s2, c2):
    """numpy's sum over the 2 x 2 entries of each block (``reshape(...).sum(axis=(1, 3))``):
    each row's pair first, then the two rows."""
    ny, nx = s.shape
    for bi in range(s2.shape[0]):
        i = 2 * bi
        for bj in range(s2.shape[1]):
            j = 2 * bj
            s2[bi, bj] = (_at(s, i, j) + _at(s, i, j + 1)) + (_at(s, i + 1, j) + _at(s, i + 1, j + 1))
            n = 0
            for a in range(i, min(i + 2, ny)):
                for b in range(j, min(j + 2, nx)):
                    n += c[a, b]
            c2[bi, bj] = n


def coarsen2(sums: np.ndarray, counts: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """:func:`render_inspect.io.coarsen` (factor 2) of float64 ``sums`` and int64 ``counts``.
    Compiled where the coarser level has at least :data:`_COMPILED_SIDE` entries a side
    (numpy adds a block's entries in another order where a side has one: it joins the
    block's rows into one run; there it is numpy's own, a few entries)."""
    s = np.ascontiguousarray(sums, dtype=np.float64)
    c = np.ascontiguousarray(counts, dtype=np.int64)
    shape = (-(-s.shape[0] // 2), -(-s.shape[1] // 2))
    if min(shape) < _COMPILED_SIDE:
        return coarsen(s, c, 2)
    s2 = np.empty(shape)
    c2 = np.empty(shape, dtype=np.int64)
    _coarsen2(s, c, s2, c2)
    return s2, c2


@njit(cache=True, nogil=True)
def _means(s, c, out):
    ny, nx = s.shape
    for i in range(ny):
        for j in range(nx):
            out[i, j] = np.float32(s[i, j] / c[i, j]) if c[i, j] > 0 else np.float32(np.nan)


def block_means(sums: np.ndarray, counts: np.ndarray) -> np.ndarray:
    """:func:`render_inspect.io.means` (float32) of float64 ``sums`` and int64 ``counts``."""
    s = np.ascontiguousarray(sums, dtype=np.float64)
    c = np.ascontiguousarray(counts, dtype=np.int64)
    out = np.empty(s.shape, dtype=np.float32)
    _means(s, c, out)
    return out


def write_tile(group: Any, tile: Tile, arrays: dict, levels: int, tile_levels: int,
               level1: dict | None = None) -> dict:
    """Write the tile into the store (full resolution and pyramid levels <= tile_levels);
    return the block sums and counts at level ``tile_levels`` if coarser levels follow.
    ``level1``: the arrays' level-1 (sums, counts) when already taken
    (:func:`tile_float32`)."""
    r0, c0 = tile.row, tile.col
    coarse = {}
    for name, a in arrays.items():
        group[name][r0:r0 + tile.rows, c0:c0 + tile.cols] = a
        if levels == 0:
            continue
        s, c = level1[name] if level1 is not None else block_sums(a, 2)
        for k in range(1, tile_levels + 1):
            if k > 1:
                s, c = coarsen2(s, c)
            f = 1 << k
            group[f"levels/{k}/{name}"][r0 // f:r0 // f + s.shape[0], c0 // f:c0 // f + s.shape[1]] = block_means(s, c)
        if levels > tile_levels:
            coarse[name] = (s, c)
    return coarse
