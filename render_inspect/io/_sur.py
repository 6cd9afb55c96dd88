"""Digital Surf ``.sur`` files: the z offset and the inversion flag, and a minimal writer
for tests.

A ``.sur`` height is ``count x z step + z offset``, both in the unit of the z step
(``unit_step_z``): Gwyddion's ``surffile.c`` reads and writes the offset so.  surfalize
0.19.2, which reads ``.sur`` here, adds the bare offset to heights it has already turned
into micrometres, so a file whose z step is in mm, m or nm comes out shifted (by 14.7 nm
on ``sf_test_uncompressed.sur``, whose offset is -1.47e-5 mm, and by 3.41 mm on
``st_sur-3.sur``, -0.00341 m); SurfaceTopography 1.18.2 leaves the offset out.
:func:`sur_offset_fix` puts the offset right.  The header's inversion code (``1``: z
inverted, ``2`` / ``3``: also mirrored) is applied by Gwyddion but by neither library:
the heights are read as stored and the code is said in a warning.

Layout written by :func:`sur_bytes` (little-endian, one 512-byte header, the format
surfalize and Gwyddion read): the magic ``DIGITAL SURF``, the grid, the steps and their
units, the z offset, then the rows of int32 counts, row 0 first; ``min - 2`` marks a
point not measured.
"""

from __future__ import annotations

import struct

import numpy as np

from ..core.units import UM_TO_MM

__all__ = ["sur_bytes", "sur_offset_fix"]

_HEADER = ("<12shhhh30s30shhhhhf4xhiiiiifff16s16s16s16s16s16s16s16s16sfffhhh12xhhhhhhhfI6xhh"
           "128sfffff13s13s")


def sur_bytes(counts: np.ndarray, *, pixel: tuple[float, float], z_step: float,
              unit: str = "mm", z_offset: float = 0.0, inverted: int = 0,
              measured: np.ndarray | None = None) -> bytes:
    """A ``.sur`` file (classic, uncompressed) holding ``counts`` (int32 rows, row 0
    first): lateral steps ``pixel`` (x, y) and ``z_step`` and ``z_offset`` all in
    ``unit`` (e.g. "mm", "nm", "m"); ``inverted`` is the header's inversion code;
    ``measured`` (bool, the shape of ``counts``) False marks points not measured."""
    c = np.array(counts, dtype="<i4")
    ny, nx = c.shape
    ok = np.ones(c.shape, bool) if measured is None else np.asarray(measured, bool)
    lo, hi = int(c[ok].min()), int(c[ok].max())
    c[~ok] = lo - 2
    u = unit.encode("latin-1")
    head = struct.pack(
        _HEADER, b"DIGITAL SURF", 0, 1, 1, 2, b"", b"", 0, 0, 0, 1, 0, 0.0, 32, lo, hi, nx, ny,
        nx * ny, float(pixel[0]), float(pixel[1]), float(z_step), b"X", b"Y", b"Z", u, u, u, u,
        u, u, 1.0, 1.0, 1.0, 0, int(inverted), 0, 0, 0, 0, 1, 1, 2024, 0, 0.0, 0, 0, 0, b"",
        0.0, 0.0, float(z_offset), 0.0, 0.0, b"", b"")
    return head + c.tobytes()


def sur_offset_fix(z_mm: np.ndarray, header: dict, unit_to_mm: float) -> tuple[np.ndarray, dict]:
    """Heights read by surfalize (mm) with the header's z offset taken in the unit of the
    z step (``unit_to_mm``: that unit in mm) instead of micrometres; returns the heights
    and what to add to the map's description (``z_offset_in_file``, ``warnings``).  An
    offset of 0 leaves the heights untouched."""
    meta: dict = {}
    off = header.get("offset_z", 0.0)
    if isinstance(off, (int, float)) and np.isfinite(off) and off != 0.0:
        z_mm = z_mm + float(off) * (unit_to_mm - UM_TO_MM)  # surfalize added off as um
        meta["z_offset_in_file"] = {"value": float(off), "unit": header.get("unit_step_z")}
    inverted = header.get("inverted", 0)
    if isinstance(inverted, int) and inverted != 0:
        meta["warnings"] = [f"the file's header marks its heights as inverted (code {inverted}); "
                            f"they are read as stored, not inverted: check the sign against "
                            f"the part"]
    return z_mm, meta
