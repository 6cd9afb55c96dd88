"""Memory a turning simulation needs, counted from the arrays it allocates (bytes).

An in-memory simulation (the whole map as arrays) goes through four phases; its peak is
the largest of them:

- planning the path: ``PLAN_BYTES`` per path point (spiral, compensation and
  accessibility temporaries; measured 152-157 B);
- cutting: design and machined heights, float64 (16 B per sample), the design
  evaluation's row chunks (``DESIGN_ROWS`` rows x columns x ``DESIGN_TEMPS`` temporaries
  of 8 B per thread), the path (``PATH_BYTES`` per point) and the envelope's segment
  table and slope temporaries (``ENVELOPE_BYTES`` per point);
- writing heightmap.exr: the float32 design, machined and residual channels (12 B per
  sample) beside the float64 heights and the path, and the overview (block means of the
  three channels and the residual's block sums and counts: 24 B per block of F x F
  samples; while it is computed, 36 B per block);
- writing toolpath.npz and the previews: the heights, the path and its npz buffers
  (``NPZ_BYTES`` per point), the overview's residual sums and the preview's coarsening
  (the previews are area averages of at most 512 pixels a side).

Tiled, the peak is bounded by the tiles in flight: each holds float64 design and
machined, float32 design / machined / residual, its share of the block sums and the
encoded chunks (``TILE_BYTES`` per sample), plus the run of the path the tile needs and
the whole prepared path.  With the material's burrs a tile is cut on a block wider by the
burr model's reach (``BURR_BLOCK_BYTES`` per sample of the block).

The test suite checks the in-memory estimate against the measured peak (tracemalloc and
resident memory) of ``simulate`` on three map sizes: within a factor 1.5.
"""

from __future__ import annotations

import os

from ..core.units import MIB_TO_BYTES

#: bytes per path point while the path is planned
PLAN_BYTES = 160
#: bytes per path point of the planned path (theta, rho, z, t, contact points)
PATH_BYTES = 40
#: bytes per path point of the envelope's segment table and slope temporaries
ENVELOPE_BYTES = 80
#: bytes per path point while toolpath.npz is written (x, y and the file buffer)
NPZ_BYTES = 100
#: bytes per sample of a tile in flight
TILE_BYTES = 48
#: further bytes per sample of a tile cut with the material's mechanics (the pass-angle and
#: displaced-material maps, the machined-edge masks)
CUT_TILE_BYTES = 24
#: bytes per sample of the halo'd block of a tile whose material burrs are added tile by
#: tile (the burr model's compiled passes smooth in place and keep the edge masks, turns
#: and ridge: the whole simulate's traced peak fell by about 100 B a sample when they
#: replaced the array passes (109 B measured then), so 32 B with the block's machined
#: copy and texture)
BURR_BLOCK_BYTES = 32
#: bytes per sample of the block a tile task keeps for the next tile of its column (the
#: cut's machined and pass-angle maps, reused where the blocks overlap)
CARRY_BYTES = 16
#: further bytes per path point of the cutting mechanics' prepared path (its lookup table
#: and cutting distance)
CUT_PATH_BYTES = 16
#: rows per chunk of the design evaluation, and temporaries per evaluated sample (8 B each)
DESIGN_ROWS = 128
DESIGN_TEMPS = 6
#: previews: fixed bytes, plus 16 B per overview block (coarsening copies of the residual's
#: block sums and counts) or 4 B per sample without an overview (2 x 2 block sums)
PREVIEW_BYTES = 4 * MIB_TO_BYTES
#: largest side of the heightmap.exr overview (pixels; see render_inspect.io._exr)
OVERVIEW_SIDE = 1024


def in_memory_bytes(shape: tuple[int, ...], path_points: int, *, threads: int | None = None,
                    cut_sample_bytes: int = 0,
                    cut_bytes: int = 0) -> int:
    """Peak bytes of an in-memory simulation of a (ny, nx) map from a path of
    ``path_points`` points, including writing its outputs (see the module notes).
    ``cut_sample_bytes`` per sample and ``cut_bytes`` more are held while cutting only
    (a process's own maps and the followed path)."""
    ny, nx = int(shape[0]), int(shape[1])
    px, n = ny * nx, int(path_points)
    threads = threads or os.cpu_count() or 1
    design_tmp = min(ny, DESIGN_ROWS) * nx * 8 * DESIGN_TEMPS * threads
    f = 1
    while max(ny, nx) > OVERVIEW_SIDE * f:
        f *= 2
    blocks = 0 if f == 1 else -(-ny // f) * -(-nx // f)
    phases = (n * PLAN_BYTES,
              px * (16 + cut_sample_bytes) + design_tmp + n * (PATH_BYTES + ENVELOPE_BYTES) + cut_bytes,
              px * 16 + blocks * 36 + n * PATH_BYTES,
              px * 28 + blocks * 24 + n * PATH_BYTES,
              px * 16 + blocks * 12 + n * (PATH_BYTES + NPZ_BYTES) + PREVIEW_BYTES
              + (blocks * 16 if blocks else px * 4))
    return int(max(phases))


def tiled_bytes(tile: int, path_points: int, *, in_flight: int, slice_points: int | None = None,
                material: bool = False, burr_halo: int = 0,
                shape: tuple[int, ...] | None = None) -> int:
    """Peak bytes of a tiled simulation with ``in_flight`` tiles of side ``tile`` computed
    at once in this process (the caller's share when the tiles run on other machines):
    the largest of planning the path, running the tiles (the path, its prepared segments
    and per tile its samples and its run of the path) and writing toolpath.npz.
    ``material``: the tiles are cut with the material's mechanics; ``burr_halo`` > 0: with
    the material's burrs, each tile cut on a block ``burr_halo`` pixels wider on every
    side (the cut's maps and the burr model's temporaries on the block), but never wider
    than the grid of ``shape`` (ny, nx) when given: the block is cut inside the grid.

    Measured (tests/test_memory_estimate.py): ``simulate --tiled`` of the shipped
    sinusoidal grid (a lathe, aluminium 6082 with its burrs), 1001^2 and 2001^2 samples
    in tiles of 256 pixels, one in flight (the process bound to one CPU): peak resident
    set 111 and 178 MB above the warmed-up process, against estimates of 109 and 163 MB
    (with the machine model's share,
    :meth:`~render_inspect.processes.TiledTurningProcess.tiled_memory`).  With two in
    flight the peak depends on whether the tiles overlap in time: 90-122 MB measured at
    1001^2 samples against the 166 MB of two at once.  The estimate
    had been 353 and 451 MB (2.2-3.0 x): the burr block counted wider than the grid and
    with the halo of uncut pixels the region did not have, the machine model's
    following counted as held beside the tiles."""
    per_sample = TILE_BYTES + (CUT_TILE_BYTES if material else 0)
    per_point = 40 + (CUT_PATH_BYTES if material else 0)
    per_tile = tile * tile * per_sample + min(tile, DESIGN_ROWS) * tile * 8 * DESIGN_TEMPS
    if burr_halo > 0:
        side = tile + 2 * int(burr_halo)
        block = side * side if shape is None else min(side, int(shape[0])) * min(side, int(shape[1]))
        block = max(block, tile * tile)
        per_tile += (block - tile * tile) * (CUT_TILE_BYTES + 8) + block * (BURR_BLOCK_BYTES + CARRY_BYTES)
    n = int(path_points)
    sl = n if slice_points is None else int(slice_points)
    phases = (n * PLAN_BYTES,
              n * (PATH_BYTES + per_point) + in_flight * (per_tile + sl * per_point),
              n * (PATH_BYTES + NPZ_BYTES))
    return int(max(phases) + PREVIEW_BYTES)
