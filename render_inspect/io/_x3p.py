"""X3P (ISO 25178-72 / ISO 5436-2) height maps, written and read with ``x3pio``.

X3P stores metres; this module converts at the boundary (mm in, mm out).  The origin
(centre of pixel [0, 0]) goes into the file's placement offset; y grows with the row
index in both X3P and :class:`~render_inspect.machining.HeightMap`.  The metadata date is
fixed by default so the same map gives the same bytes.
"""

from __future__ import annotations

import io
from datetime import datetime, timezone
from collections.abc import Sequence
from pathlib import Path
from typing import cast

import numpy as np
import numpy.typing as npt

from ..core.units import MM_TO_M, M_TO_MM
from .. import __version__
from ..core.errors import InputError, check_positive
from ._atomic import atomic_write_bytes
from ._instrument import x3p_header
from ._limits import check_x3p
from ._vendor import read_x3p_plain

__all__ = ["write_x3p", "read_x3p", "read_x3p_xy"]

_FIXED_DATE = datetime(2000, 1, 1, tzinfo=timezone.utc)


def write_x3p(path: str | Path, z: npt.ArrayLike, *, pixel: float | Sequence[float],
              origin: Sequence[float] = (0.0, 0.0), comment: str | None = None,
              date: datetime | None = None) -> Path:
    """Write a height map (mm) to an X3P file, atomically.

    Parameters
    ----------
    path : str or Path
        Destination (``.x3p``).
    z : (ny, nx) array
        Heights, mm; NaN = not measured (stored as invalid points).  Row 0 is the smallest y.
    pixel : float or (pixel_x, pixel_y)
        Sampling distance, mm: one number for square pixels, or the x (column) and y (row)
        spacings.
    origin : (x, y)
        Centre of pixel [0, 0], mm (the X3P placement offset).
    comment : str, optional
        Free text stored in the metadata record (e.g. the scene as JSON).
    date : datetime, optional
        Creation date in the metadata (default 2000-01-01 UTC, so output is reproducible).
    """
    import x3pio

    z = np.asarray(z, dtype=np.float64)
    if z.ndim != 2 or min(z.shape) < 1:
        raise InputError(f"write_x3p: z must be a 2-D height map, got shape {z.shape}")
    # (one number, or the x and y spacings)
    px, py = ((cast(float, pixel), cast(float, pixel)) if np.ndim(pixel) == 0
              else tuple(cast("Sequence[float]", pixel)))
    check_positive("pixel_x", px)
    check_positive("pixel_y", py)
    if np.isinf(z).any():
        raise InputError("write_x3p: z contains +-inf; use NaN for points that are not measured")
    meta = x3pio.Metadata.for_software("render_inspect", __version__, date=date or _FIXED_DATE)
    if comment:
        import dataclasses

        meta = dataclasses.replace(meta, comment=str(comment))
    place = x3pio.Placement.translation(float(origin[0]) * MM_TO_M, float(origin[1]) * MM_TO_M, 0.0)
    buf = io.BytesIO()
    x3pio.write(buf, z * MM_TO_M, x_scale=float(px) * MM_TO_M, y_scale=float(py) * MM_TO_M,  # mm -> m
                metadata=meta, placement=place, coordinate_system=x3pio.CoordinateSystem.VIEW)
    return atomic_write_bytes(path, buf.getvalue())


def read_x3p(path: str | Path, *, what: str = "X3P file",
             budget: int | tuple[int, str] | None = None
             ) -> tuple[np.ndarray, float, tuple[float, float], dict]:
    """Read an X3P surface with square pixels (:func:`read_x3p_xy` for any pixels).

    The archive and the grid size its ``main.xml`` declares are checked first
    (:func:`~render_inspect.io._limits.check_x3p`: no zip bombs, sizes within ``budget``).

    Returns
    -------
    z : (ny, nx) float64 array
        Heights, mm (NaN where not measured), row 0 = smallest y.
    pixel : float
        mm (x and y sampling agree to 1e-6; otherwise :class:`InputError`).
    origin : (x, y)
        Centre of pixel [0, 0], mm, from the placement offset.
    meta : dict
        ``format`` = "x3p", ``pixel_x_mm``, ``pixel_y_mm``, ``comment``, ``instrument``, ``date``.
    """
    z, (px, py), origin, meta = read_x3p_xy(path, what=what, budget=budget)
    if not np.isclose(px, py, rtol=1e-6, atol=0):
        raise InputError(f"{path}: X3P pixels are not square ({px:.6g} x {py:.6g} mm); read it "
                         f"with read_surface / read_x3p_xy, which keep (pixel_x, pixel_y)")
    return z, px, origin, meta


def read_x3p_xy(path: str | Path, *, what: str = "X3P file",
                budget: int | tuple[int, str] | None = None
                ) -> tuple[np.ndarray, tuple[float, float], tuple[float, float], dict]:
    """Read an X3P surface keeping both sampling distances.

    The archive and the grid size its ``main.xml`` declares are checked first
    (:func:`~render_inspect.io._limits.check_x3p`: no zip bombs, sizes within ``budget``,
    bytes; default the automatic memory budget); ``what`` names the file in messages.

    Returns
    -------
    z : (ny, nx) float64 array
        Heights, mm (NaN where not measured), row 0 = smallest y.
    pixel : (pixel_x, pixel_y)
        mm.
    origin : (x, y)
        Centre of pixel [0, 0], mm, from the placement offset.
    meta : dict
        As :func:`read_x3p`.
    """
    import x3pio

    path = Path(path)
    if not path.is_file():
        raise InputError(f"{what}: X3P file not found: {str(path)!r}")
    check_x3p(path, what=what, budget=budget)
    try:
        f = x3pio.read(str(path))
    except x3pio.X3pError as err:
        # x3pio follows ISO 5436-2 strictly; some exporters write a main.xml without the
        # namespace (or in a sub-folder): read those from their own axes description
        try:
            return read_x3p_plain(path)
        except InputError as err2:
            raise InputError(f"{path}: not a readable X3P file ({err}; {err2})") from None
    except (ValueError, OSError, EOFError) as err:
        raise InputError(f"{path}: not a readable X3P file ({err})") from None
    if not isinstance(f, x3pio.Surface):
        raise InputError(f"{path}: X3P holds a {type(f).__name__}, only surfaces on a regular grid "
                         f"are supported")
    if len(f.layers) != 1:
        raise InputError(f"{path}: X3P has {len(f.layers)} layers, expected 1")
    layer = f.layers[0]
    if not layer.is_regular_grid:
        raise InputError(f"{path}: X3P surface is not on a regular grid")
    px_m, py_m = layer.spacing
    z = np.array(layer.z, dtype=np.float64) * M_TO_MM
    place = f.placement
    if not np.allclose(place.rotation, np.eye(3)):
        raise InputError(f"{path}: X3P placement has a rotation; rotate the data to the view "
                         f"frame first (only translations are supported)")
    off = np.asarray(place.offset) * M_TO_MM
    if off[2]:
        z = z + off[2]
    m = f.metadata
    meta = {"format": "x3p", "pixel_x_mm": px_m * M_TO_MM, "pixel_y_mm": py_m * M_TO_MM,
            "comment": getattr(m, "comment", None) if m else None, **x3p_header(m)}
    meta["reader"] = f"x3pio {getattr(x3pio, '__version__', '')}".strip()
    meta["units_in_file"] = {"lateral": "m", "vertical": "m"}
    meta["units_in_file_from"] = "ISO 25178-72: X3P stores metres"
    return z, (float(px_m * M_TO_MM), float(py_m * M_TO_MM)), (float(off[0]), float(off[1])), meta
