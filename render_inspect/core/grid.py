"""Regular grids: pixel-centre coordinates shared by every gridded result (height maps,
camera images) and the grid a region and a pixel size define."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

__all__ = ["GridCoordinates", "Grid", "grid_shape", "flip_rows"]


def grid_shape(region: Sequence[float], pixel: float) -> tuple[int, int]:
    """(ny, nx) of the grid with pixel centres at x0 + i pixel, y0 + j pixel over
    ``region`` = (x0, y0, x1, y1), mm."""
    x0, y0, x1, y1 = region
    nx = int(round((x1 - x0) / pixel)) + 1
    ny = int(round((y1 - y0) / pixel)) + 1
    return ny, nx


def flip_rows(a: np.ndarray) -> np.ndarray:
    """``a`` with its rows in the opposite order, in place (one row of scratch): the map
    of a grid mirrored about y (row k of the one is row ny - 1 - k of the other)."""
    n = a.shape[0]
    for i in range(n // 2):
        row = a[i].copy()
        a[i] = a[n - 1 - i]
        a[n - 1 - i] = row
    return a


class GridCoordinates:
    """Mixin for objects with ``shape`` (ny, nx), ``pixel`` (mm) and ``origin`` (x, y of the
    centre of pixel [0, 0], mm).  Row 0 is the smallest y, column 0 the smallest x."""

    if TYPE_CHECKING:  # what the class using the mixin provides (fields or properties)
        @property
        def shape(self) -> tuple[int, ...]: ...

        @property
        def pixel(self) -> float: ...

        @property
        def origin(self) -> tuple[float, float]: ...

    @property
    def x(self) -> np.ndarray:
        return self.origin[0] + self.pixel * np.arange(self.shape[1])

    @property
    def y(self) -> np.ndarray:
        return self.origin[1] + self.pixel * np.arange(self.shape[0])

    @property
    def extent(self) -> tuple[float, float, float, float]:
        """(x0, x1, y0, y1) of the pixel edges, for matplotlib ``imshow(origin='lower')``."""
        h = self.pixel / 2
        x, y = self.x, self.y
        return (x[0] - h, x[-1] + h, y[0] - h, y[-1] + h)


@dataclass(frozen=True)
class Grid(GridCoordinates):
    """A regular grid of square pixels.

    Attributes
    ----------
    origin : (x, y), mm, centre of pixel [0, 0]
    pixel : float, mm
    shape : (ny, nx)
    """

    origin: tuple[float, float]
    pixel: float
    shape: tuple[int, int]

    @classmethod
    def from_region(cls, region: Sequence[float], pixel: float) -> "Grid":
        """The grid of ``region`` = (x0, y0, x1, y1) (mm) at ``pixel`` (mm), pixel centres
        from (x0, y0)."""
        return cls((float(region[0]), float(region[1])), float(pixel), grid_shape(region, pixel))

    @property
    def region(self) -> tuple[float, float, float, float]:
        """(x0, y0, x1, y1) of the first and last pixel centres, mm."""
        ny, nx = self.shape
        x0, y0 = self.origin
        return (x0, y0, x0 + self.pixel * (nx - 1), y0 + self.pixel * (ny - 1))

    @property
    def size(self) -> int:
        return int(self.shape[0]) * int(self.shape[1])
