"""``[tool]`` and ``[simulation]``."""

from __future__ import annotations

from pydantic import Field, model_validator

from ..core.grid import grid_shape
from ..core.section import Region, Section

__all__ = ["ToolConfig", "SimulationConfig"]


class ToolConfig(Section):
    """Round-nosed diamond tool."""
    nose_radius: float = Field(0.5, gt=0, le=50, description="mm, Rc")
    included_angle_deg: float = Field(60.0, gt=0, le=180)
    rake_angle_deg: float = Field(0.0, ge=-45, le=45)
    clearance_angle_deg: float = Field(10.0, ge=0, le=45)


class SimulationConfig(Section):
    """The grid on which the machined surface is computed."""
    region: Region = Field((-1.0, -1.0, 1.0, 1.0), description="mm, [x0, y0, x1, y1]")
    pixel: float = Field(0.002, ge=1e-6, le=10, description="mm, grid spacing")
    seed: int = Field(0, ge=0, le=2**63 - 1, description="seed of every random draw")
    max_memory_gb: float | None = Field(
        None, gt=0, le=65536, description="GiB; refuse requests estimated above this; None = "
                                          "80 % of the memory available when the command starts")

    @model_validator(mode="after")
    def _region(self):
        x0, y0, x1, y1 = self.region
        if not (x1 > x0 and y1 > y0):
            raise ValueError(f"region must be [x0, y0, x1, y1] with x1 > x0 and y1 > y0, received {list(self.region)}")
        if self.pixel > min(x1 - x0, y1 - y0):
            raise ValueError(f"pixel must be <= the region's smaller side ({min(x1 - x0, y1 - y0)}), "
                             f"received {self.pixel}")
        return self

    @property
    def shape(self) -> tuple[int, int]:
        """(ny, nx) of the grid; pixel centres from x0 (y0) in steps of ``pixel``."""
        return grid_shape(self.region, self.pixel)
