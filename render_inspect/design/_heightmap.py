"""A design surface given as a sampled height map (EXR or .npy), interpolated."""

from __future__ import annotations

from collections.abc import Sequence
import math
from pathlib import Path
from typing import Literal

import numpy as np
from pydantic import Field

from ..core.errors import InputError, check_positive
from ..core.section import Length, Section
from ..io import check_npy, exr_placement, read_exr
from ._base import Surface
from ._registry import register_design

__all__ = ["HeightMapSurface"]


class HeightMapSurface(Surface):
    """Heights (mm) on a regular grid, interpolated by a linear or cubic spline.

    Parameters
    ----------
    path : str or Path, or None
        ``.exr`` in the ``heightmap.exr`` contract (header ``pixel_size_mm`` and
        ``origin_mm``; the channel ``channel``), or ``.npy`` holding a 2-D float array
        (row 0 = smallest y, column 0 = smallest x) with ``pixel`` and ``origin`` given.
        None: take the heights from ``data``.
    channel : str
        EXR channel to read (``"design"``, ``"machined"``, ...).
    pixel : float, optional
        Grid spacing (mm); required for ``.npy``; for EXR, if given it must match the header.
    origin : (float, float), optional
        (x, y) of the centre of pixel [0, 0] (mm); as ``pixel``.
    interpolation : {"linear", "cubic"}
        Bilinear (gradient piecewise constant, d2z/dx2 = d2z/dy2 = 0) or bicubic spline
        through the samples (smooth gradient and Hessian).
    data : (ny, nx) array, optional
        Heights given directly (with ``path=None``, ``pixel`` and ``origin``).

    Evaluating outside the map's pixel centres raises :class:`InputError`; so does a map
    with NaN or infinite samples.
    """
    kind = "heightmap"

    def __init__(self, path=None, channel="design", pixel=None, origin=None,
                 interpolation="cubic", *, data=None):
        if interpolation not in ("linear", "cubic"):
            raise InputError(f"design.interpolation must be 'linear' or 'cubic', received "
                             f"{interpolation!r}")
        self.path = None if path is None else str(path)
        self.channel = channel
        if path is None:
            if data is None:
                raise InputError("HeightMapSurface needs design.path or data")
            z = np.asarray(data)
            if np.iscomplexobj(z) or not (np.issubdtype(z.dtype, np.number) or z.dtype == bool):
                raise InputError(f"design height map data must be real numbers, got dtype {z.dtype}")
            z = z.astype(np.float64)
            hdr_pixel, hdr_origin = None, None
        else:
            z, hdr_pixel, hdr_origin = self._load(Path(path), channel)
        pixel = self._reconcile("design.pixel", pixel, hdr_pixel)
        origin = self._reconcile("design.origin", origin, hdr_origin)
        if pixel is None or origin is None:
            raise InputError(f"design.pixel (mm) and design.origin ([x, y] mm of pixel [0, 0]) "
                             f"are required for {self.path or 'array data'}, received "
                             f"pixel={pixel!r}, origin={origin!r}")
        self.pixel = float(check_positive("design.pixel", pixel))
        if len(origin) != 2 or not all(math.isfinite(float(o)) for o in origin):
            raise InputError(f"design.origin must be [x, y] (mm), received {origin!r}")
        self.origin = (float(origin[0]), float(origin[1]))
        if z.ndim != 2:
            raise InputError(f"design height map {self.path or ''} must be 2-D, got shape {z.shape}")
        k = 1 if interpolation == "linear" else 3
        if min(z.shape) < k + 1:
            raise InputError(f"design height map needs at least {k + 1} x {k + 1} samples for "
                             f"{interpolation} interpolation, got shape {z.shape}")
        if not np.all(np.isfinite(z)):
            raise InputError(f"design height map {self.path or ''} (channel {channel!r}) has "
                             f"{int((~np.isfinite(z)).sum())} NaN/infinite samples; a design "
                             "must be defined everywhere")
        self.interpolation = interpolation
        self.data = z
        ny, nx = z.shape
        self.x = self.origin[0] + self.pixel * np.arange(nx)
        self.y = self.origin[1] + self.pixel * np.arange(ny)
        self._k = k
        self._spline = None
        if k == 3:
            from scipy.interpolate import RectBivariateSpline

            # scipy's first axis is our y (rows), its second our x (columns)
            self._spline = RectBivariateSpline(self.y, self.x, z, kx=3, ky=3, s=0)

    @staticmethod
    def _reconcile(name, given, header):
        if header is None:
            return given
        if given is None:
            return header
        g = np.atleast_1d(np.asarray(given, dtype=float))
        h = np.atleast_1d(np.asarray(header, dtype=float))
        if g.shape != h.shape or not np.allclose(g, h, rtol=1e-9, atol=1e-12):
            raise InputError(f"{name} = {given!r} disagrees with the EXR header ({header!r}); "
                             "leave it out for EXR files")
        return header

    @staticmethod
    def _load(path: Path, channel: str):
        suffix = path.suffix.lower()
        if not path.is_file():
            raise InputError(f"design.path: file not found: {str(path)!r}")
        if suffix == ".exr":
            chans, attrs = read_exr(path, what="design.path")
            if channel not in chans:
                raise InputError(f"design.channel {channel!r} is not in {str(path)!r} "
                                 f"(channels: {sorted(chans)})")
            pixel, origin = exr_placement(attrs, what="design.path", path=path)
            return np.asarray(chans[channel], dtype=np.float64), pixel, origin
        if suffix == ".npy":
            check_npy(path, what="design.path")  # header, dtype, size: before loading
            try:
                z = np.load(path, allow_pickle=False)
            except (ValueError, OSError, EOFError) as err:
                raise InputError(f"design.path {str(path)!r} is not a plain .npy array: {err}") from None
            return np.asarray(z, dtype=np.float64), None, None
        raise InputError(f"design.path must end in .exr or .npy, received {str(path)!r}")

    @property
    def bounds(self) -> tuple[float, float, float, float]:
        """(x0, y0, x1, y1): the first and last pixel centres (mm)."""
        return (float(self.x[0]), float(self.y[0]), float(self.x[-1]), float(self.y[-1]))

    def _check(self, x, y):
        x = np.asarray(x, dtype=np.float64)
        y = np.asarray(y, dtype=np.float64)
        x, y = np.broadcast_arrays(x, y)
        x0, y0, x1, y1 = self.bounds
        tol = 1e-9 * self.pixel  # not a unit conversion: a relative tolerance
        out = ~((x >= x0 - tol) & (x <= x1 + tol) & (y >= y0 - tol) & (y <= y1 + tol))
        if np.any(out):
            k = np.flatnonzero(out.ravel())[0]
            raise InputError(f"design height map covers x in [{x0:.6g}, {x1:.6g}], y in "
                             f"[{y0:.6g}, {y1:.6g}] mm; {int(out.sum())} point(s) lie outside, "
                             f"e.g. ({x.ravel()[k]:.6g}, {y.ravel()[k]:.6g}); shrink "
                             "simulation.region / process.workpiece_radius")
        return np.clip(x, x0, x1), np.clip(y, y0, y1)

    def _ev(self, x, y, dx, dy):
        """d^(dx+dy) F / dx^dx dy^dy at (x, y) (inside the map)."""
        if self._spline is None:
            return self._bilinear(x, y, dx, dy)
        # scipy: dx is the order along its first axis (our y)
        out = self._spline.ev(y.ravel(), x.ravel(), dx=dy, dy=dx)
        return out.reshape(x.shape)

    def _bilinear(self, x, y, dx, dy):
        ny, nx = self.data.shape
        fx = (x - self.origin[0]) / self.pixel
        fy = (y - self.origin[1]) / self.pixel
        j = np.clip(np.floor(fx).astype(np.int64), 0, nx - 2)
        i = np.clip(np.floor(fy).astype(np.int64), 0, ny - 2)
        t, u = fx - j, fy - i
        z = self.data
        z00, z01, z10, z11 = z[i, j], z[i, j + 1], z[i + 1, j], z[i + 1, j + 1]
        h = self.pixel
        if (dx, dy) == (0, 0):
            return (z00 * (1 - t) * (1 - u) + z01 * t * (1 - u) + z10 * (1 - t) * u
                    + z11 * t * u)
        if (dx, dy) == (1, 0):
            return ((z01 - z00) * (1 - u) + (z11 - z10) * u) / h
        if (dx, dy) == (0, 1):
            return ((z10 - z00) * (1 - t) + (z11 - z01) * t) / h
        if (dx, dy) == (1, 1):
            return (z11 - z10 - z01 + z00) / (h * h)
        return np.zeros(x.shape)      # d2/dx2 and d2/dy2 of a bilinear patch

    def height(self, x: np.ndarray | float, y: np.ndarray | float) -> np.ndarray:
        x, y = self._check(x, y)
        return self._ev(x, y, 0, 0)

    def gradient(self, x: np.ndarray | float,
                 y: np.ndarray | float) -> tuple[np.ndarray, np.ndarray]:
        x, y = self._check(x, y)
        return self._ev(x, y, 1, 0), self._ev(x, y, 0, 1)

    def hessian(self, x: np.ndarray | float,
                y: np.ndarray | float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        x, y = self._check(x, y)
        return self._ev(x, y, 2, 0), self._ev(x, y, 1, 1), self._ev(x, y, 0, 2)

    def max_slope(self, region: Sequence[float], pixel: float | None = None) -> float:
        """Largest |grad F| over ``region`` clipped to the map."""
        x0, y0, x1, y1 = region
        bx0, by0, bx1, by1 = self.bounds
        clipped = (max(x0, bx0), max(y0, by0), min(x1, bx1), min(y1, by1))
        if clipped[2] <= clipped[0] or clipped[3] <= clipped[1]:
            raise InputError(f"region {tuple(region)} does not overlap the design height map "
                             f"{self.bounds}")
        return super().max_slope(clipped, pixel)

    def __repr__(self):
        return (f"HeightMapSurface({self.path!r}, channel={self.channel!r}, shape="
                f"{self.data.shape}, pixel={self.pixel}, origin={self.origin}, "
                f"interpolation={self.interpolation!r})")


# ------------------------------------------------------------------ scene schema
class HeightMapConfig(Section):
    """A height map loaded from EXR (channel ``channel``) or .npy, interpolated."""
    type: Literal["heightmap"]
    path: str = Field(..., min_length=1, max_length=4096, pattern=r"^[^\x00]*$")
    channel: str = Field("design", min_length=1, max_length=256)
    pixel: float | None = Field(None, gt=0, le=1e3, description="mm; required for .npy")
    origin: tuple[Length, Length] | None = Field(None, description="mm, centre of pixel [0, 0]; .npy")
    interpolation: Literal["linear", "cubic"] = "cubic"


register_design(HeightMapConfig, HeightMapSurface)
