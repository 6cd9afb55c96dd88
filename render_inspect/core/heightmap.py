"""HeightMap: design / machined / residual on a regular grid (mm).  Files: see
:mod:`render_inspect.io` (``heightmap.exr``, X3P, Zarr)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .errors import InputError
from .grid import GridCoordinates


@dataclass
class HeightMap(GridCoordinates):
    """Heights on a regular grid.  Row 0 is the smallest y, column 0 the smallest x.

    Attributes
    ----------
    design, machined : (ny, nx) float64 arrays, mm (NaN where not covered)
    pixel : float, mm (square pixels)
    origin : (x, y) of the centre of pixel [0, 0], mm
    scene : dict (the validated scene, JSON-able) or None
    meta : dict of extra provenance (seed, compensation, ...)
    """

    design: np.ndarray
    machined: np.ndarray
    pixel: float
    origin: tuple[float, float]
    scene: dict | None = None
    meta: dict = field(default_factory=dict)

    def __post_init__(self) -> None:
        if self.design.shape != self.machined.shape or self.design.ndim != 2:
            raise InputError(f"design and machined must be 2-D arrays of one shape, got "
                             f"{self.design.shape} and {self.machined.shape}")
        if not self.pixel > 0:
            raise InputError(f"pixel must be > 0 mm, got {self.pixel}")

    @property
    def residual(self) -> np.ndarray:
        """machined - design (mm)."""
        return self.machined - self.design

    @property
    def shape(self) -> tuple[int, ...]:
        return self.design.shape
