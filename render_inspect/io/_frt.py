"""FRT MicroProf ``.frt`` files: the row order, and a minimal writer for tests.

An FRT file stores its height raster row by row, the first stored row being the bottom
line of the image.  Gwyddion (``modules/file/microprof.c`` flips every image it reads,
``gwy_data_field_invert(dfield, TRUE, FALSE, FALSE)``) and SurfaceTopography from 1.27
on put the last stored row first; SurfaceTopography 1.18 to 1.22 keep the stored order,
which mirrors the map in y against both.  :func:`reader_keeps_stored_order` finds out
which the installed SurfaceTopography does (by reading a small file written here), so the
measured-file reader can put the rows in Gwyddion's order with either version.

Layout written by :func:`frt_bytes` (little-endian; the blocks SurfaceTopography and
Gwyddion need for one topography image): the magic ``FRTM_GLIDERV1.00``, the number of
blocks (uint16), then blocks of ``id`` (uint16), ``size`` (uint32) and the payload:

- ``0x0066``: columns, rows, bits per value (16 or 32), three uint32;
- ``0x0067``: x range, y range (m), x offset, y offset, y factor (doubles), scan
  direction (uint32);
- ``0x006c``: measuring range (uint32), height scale (m per count, double);
- ``0x000b``: the raster, rows of uint16 (or int32) counts; the count 1 marks a point
  that was not measured.
"""

from __future__ import annotations

import functools
import io
import struct

import numpy as np

__all__ = ["frt_bytes", "reader_keeps_stored_order", "FRT_INVALID"]

#: the count that marks a point that was not measured
FRT_INVALID = 1


def frt_bytes(counts: np.ndarray, *, pixel_m: float = 1e-6, zscale_m: float = 1e-9) -> bytes:
    """An FRT file (version 1.00) holding ``counts`` (rows as stored, uint16 or int32)
    as its topography, ``pixel_m`` the sampling (m) and ``zscale_m`` metres per count."""
    counts = np.asarray(counts)
    if counts.ndim != 2:
        raise ValueError(f"counts must be a 2-D raster, received shape {counts.shape}")
    ny, nx = counts.shape
    bits = 16 if counts.dtype.itemsize <= 2 and counts.dtype.kind == "u" else 32
    raster = counts.astype("<u2" if bits == 16 else "<i4").tobytes()
    blocks = [
        (0x0066, struct.pack("<3I", nx, ny, bits)),
        (0x0067, struct.pack("<5dI", nx * pixel_m, ny * pixel_m, 0.0, 0.0, 1.0, 0)),
        (0x006C, struct.pack("<Id", 0, zscale_m)),
        (0x000B, raster),
    ]
    out = io.BytesIO()
    out.write(b"FRTM_GLIDERV1.00")
    out.write(struct.pack("<H", len(blocks)))
    for block_id, payload in blocks:
        out.write(struct.pack("<HI", block_id, len(payload)))
        out.write(payload)
    return out.getvalue()


@functools.lru_cache(maxsize=1)
def reader_keeps_stored_order() -> bool:
    """Whether the installed SurfaceTopography's FRT reader gives the rows in the order
    they are stored (1.18 .. 1.22: the first stored row at y index 0), found by reading
    a 2 x 3 file whose rows differ.  False when it already flips them (1.27 on)."""
    from SurfaceTopography.IO import FRTReader

    stored = np.array([[2, 3, 4], [5, 6, 7]], dtype=np.uint16)
    t = FRTReader(io.BytesIO(frt_bytes(stored))).topography()
    h = np.asarray(t.heights(), dtype=np.float64)  # [x, y]
    first = h[:, 0] / h[0, 0] * stored[0, 0]
    return bool(np.allclose(first, stored[0]))
