"""HeightMap: design / machined / residual on a regular grid (mm), and its EXR form."""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .. import __version__
from .._grid import GridCoordinates
from ..errors import InputError


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

    def __post_init__(self):
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
    def shape(self):
        return self.design.shape

    def to_exr(self, path: str | Path) -> Path:
        from ..io import write_exr

        attrs = {"pixel_size_mm": float(self.pixel),
                 "origin_mm": [float(self.origin[0]), float(self.origin[1])],
                 "units": "mm",
                 "scene": json.dumps(self.scene or {}, sort_keys=True),
                 "software_version": __version__,
                 "meta": json.dumps(self.meta, sort_keys=True, default=str)}
        return write_exr(path, {"design": self.design, "machined": self.machined,
                                "residual": self.residual}, attrs)

    @classmethod
    def from_exr(cls, path: str | Path) -> "HeightMap":
        from ..io import read_exr

        ch, attrs = read_exr(path)
        for name in ("design", "machined"):
            if name not in ch:
                raise InputError(f"{path}: EXR has no channel {name!r} (channels: {sorted(ch)})")
        if "pixel_size_mm" not in attrs or "origin_mm" not in attrs:
            raise InputError(f"{path}: EXR lacks pixel_size_mm / origin_mm header attributes")
        scene = attrs.get("scene")
        meta = attrs.get("meta", {})
        return cls(ch["design"].astype(np.float64), ch["machined"].astype(np.float64),
                   float(attrs["pixel_size_mm"]), tuple(attrs["origin_mm"]),
                   scene if isinstance(scene, dict) else None,
                   meta if isinstance(meta, dict) else {})
