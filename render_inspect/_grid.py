"""Pixel-centre coordinates shared by every regular-grid result (height maps, camera images)."""

from __future__ import annotations

import numpy as np


class GridCoordinates:
    """Mixin for objects with ``shape`` (ny, nx), ``pixel`` (mm) and ``origin`` (x, y of the
    centre of pixel [0, 0], mm).  Row 0 is the smallest y, column 0 the smallest x."""

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
