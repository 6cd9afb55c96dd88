"""Multi-resolution pyramids of height maps: area averages over 2^k x 2^k pixel blocks.

Level k (factor F = 2^k) holds, for each block of F x F full-resolution pixels (rows
i F .. i F + F - 1, columns j F .. j F + F - 1; blocks on the last row / column hold
what is left), the mean of the block's finite samples (NaN where the block has none).
An area average is the box filter followed by decimation: detail finer than the block
(feed marks of a few um on a whole-part map) averages out instead of aliasing into false
patterns, as picking every F-th sample would.  Its pixel centres are at
origin + ((F - 1) / 2 + i F) pixel (for full blocks).

Levels are built from block *sums and counts*, which add exactly across tiles and
levels: a level computed tile by tile (tiles aligned to the block size) equals the level
of the whole map, and level k + 1 is the 2 x 2 sum of level k's sums and counts.
"""

from __future__ import annotations

from typing import Any
import math

import numpy as np
from ..core.lazy import njit  # numba, imported on first use
from ..core.threads import over_rows


@njit(cache=True, nogil=True)
def _block_sums(a, b, has_b, f, sums, counts):
    ny, nx = a.shape
    for i in range(ny):
        bi = i // f
        for j in range(nx):
            v = np.float64(a[i, j])
            if has_b:
                v -= np.float64(b[i, j])
            if math.isfinite(v):
                bj = j // f
                sums[bi, bj] += v
                counts[bi, bj] += 1


_ZERO = np.zeros((1, 1))


@njit(cache=True, nogil=True)
def _block_sums3(design, machined, f, sums, counts, b0, b1):
    ny, nx = design.shape
    for bi in range(b0, b1):
        for i in range(bi * f, min(bi * f + f, ny)):
            for j in range(nx):
                bj = j // f
                d = np.float64(design[i, j])
                m = np.float64(machined[i, j])
                r = m - d
                if math.isfinite(d):
                    sums[0, bi, bj] += d
                    counts[0, bi, bj] += 1
                if math.isfinite(m):
                    sums[1, bi, bj] += m
                    counts[1, bi, bj] += 1
                if math.isfinite(r):
                    sums[2, bi, bj] += r
                    counts[2, bi, bj] += 1


def heightmap_block_sums(design: np.ndarray, machined: np.ndarray, factor: int) -> dict:
    """Block sums (float64) and counts (int32) of ``design``, ``machined`` and ``residual``
    (machined - design, formed in float64) in one pass threaded over rows of blocks: {name:
    (sums, counts)}."""
    shape = (-(-design.shape[0] // factor), -(-design.shape[1] // factor))
    sums = np.zeros((3, *shape))
    counts = np.zeros((3, *shape), dtype=np.int32)
    over_rows(_block_sums3, shape[0], np.asarray(design), np.asarray(machined), int(factor), sums, counts)
    return {name: (sums[k], counts[k]) for k, name in enumerate(("design", "machined", "residual"))}


def block_sums(a: np.ndarray, factor: int, *, minus: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """(sums, counts) of the finite samples of ``a`` ((ny, nx), any float dtype; or of
    ``a - minus``, formed in float64 sample by sample) in blocks of ``factor`` x
    ``factor``: float64 and int64 arrays of shape (ceil(ny / factor), ceil(nx / factor))."""
    a = np.asarray(a)
    b = _ZERO if minus is None else np.asarray(minus)
    if minus is not None and b.shape != a.shape:
        raise ValueError(f"block_sums: minus has shape {b.shape}, expected {a.shape}")
    shape = (-(-a.shape[0] // factor), -(-a.shape[1] // factor))
    sums = np.zeros(shape)
    counts = np.zeros(shape, dtype=np.int64)
    _block_sums(a, b, minus is not None, int(factor), sums, counts)
    return sums, counts


def coarsen(sums: np.ndarray, counts: np.ndarray, factor: int = 2) -> tuple[np.ndarray, np.ndarray]:
    """Block sums and counts of the next coarser level(s): blocks of ``factor`` x
    ``factor`` entries added up."""
    return block_sums_of_sums(sums, factor), block_sums_of_sums(counts, factor)


def block_sums_of_sums(s: np.ndarray, factor: int) -> np.ndarray:
    ny, nx = s.shape
    py, px = (-ny) % factor, (-nx) % factor
    if py or px:
        s = np.pad(s, ((0, py), (0, px)))
    return s.reshape(s.shape[0] // factor, factor, s.shape[1] // factor, factor).sum(axis=(1, 3))


def means(sums: np.ndarray, counts: np.ndarray, dtype: Any = np.float32) -> np.ndarray:
    """Block means (NaN where a block has no finite sample), without float64 temporaries."""
    out = np.full(sums.shape, np.nan, dtype=dtype)
    np.divide(sums, counts, out=out, where=counts > 0, casting="unsafe")
    return out


def level_count(shape: tuple[int, ...], *, smallest: int = 256) -> int:
    """Number of levels (factors 2, 4, ...) until the larger side is at most ``smallest``
    pixels (0 if the map is already that small)."""
    n = max(shape)
    return max(0, math.ceil(math.log2(n / smallest))) if n > smallest else 0


def level_shape(shape: tuple[int, ...], k: int) -> tuple[int, int]:
    f = 2 ** k
    return (-(-shape[0] // f), -(-shape[1] // f))


def pyramid(a: np.ndarray, levels: int) -> list[np.ndarray]:
    """Area-averaged levels 1..``levels`` of ``a`` (float32 means, see the module notes)."""
    out: list[np.ndarray] = []
    if levels <= 0:
        return out
    s, c = block_sums(a, 2)
    out.append(means(s, c))
    for _ in range(1, levels):
        s, c = coarsen(s, c, 2)
        out.append(means(s, c))
    return out


def preview(a: np.ndarray, max_side: int = 512, *, minus: np.ndarray | None = None) -> tuple[np.ndarray, int]:
    """Area average of ``a`` (or ``a - minus``) with the smallest power-of-two factor that
    brings its larger side to at most ``max_side`` pixels: (float32 image, factor)."""
    k = level_count(a.shape, smallest=max_side)
    s, c = block_sums(a, 2 ** k, minus=minus)
    return means(s, c), 2 ** k
