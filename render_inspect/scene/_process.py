"""``[tool]``, ``[process]`` and ``[simulation]``."""

from __future__ import annotations

from typing import Literal

from pydantic import Field, model_validator

from ._base import Section


class ToolConfig(Section):
    """Round-nosed diamond tool."""
    nose_radius: float = Field(0.5, gt=0, le=50, description="mm, Rc")
    included_angle_deg: float = Field(60.0, gt=0, le=180)
    rake_angle_deg: float = Field(0.0, ge=-45, le=45)
    clearance_angle_deg: float = Field(10.0, ge=0, le=45)


class ProcessConfig(Section):
    """How the part is cut."""
    kind: Literal["sts", "fts", "hts", "sculpt", "rcse"] = "sts"
    spindle_rpm: float = Field(50.0, gt=0, le=20000)
    feed_mm_per_min: float = Field(0.5, gt=0, le=1000)
    workpiece_radius: float = Field(5.0, gt=0, le=500, description="mm, outer radius Rw of the spiral")
    inner_radius: float = Field(0.0, ge=0, description="mm, the spiral stops here")
    compensation: Literal["none", "normal", "z"] = "z"
    sampling: Literal["constant_angle", "constant_arc", "hybrid"] = "constant_angle"
    points_per_rev: int = Field(3600, ge=8, le=10_000_000, description="N, constant-angle sampling")
    arc_length: float = Field(0.005, gt=0, description="mm, constant-arc sampling step")
    switch_radius: float = Field(1.0, ge=0, description="mm, hybrid sampling: angle inside, arc outside")
    chordal_tolerance: float | None = Field(None, gt=0, description="mm; bound on the linearisation error")
    depth_of_cut: float = Field(0.003, ge=0, description="mm (recorded; the envelope does not depend on it)")
    allow_gouge: bool = Field(False, description="simulate even if the tool cannot reach everywhere")
    # machine limits used by the kinematics checks (optional)
    x_velocity_limit_mm_s: float | None = Field(None, gt=0)
    x_acceleration_limit_mm_s2: float | None = Field(None, gt=0)
    z_velocity_limit_mm_s: float | None = Field(None, gt=0)
    z_acceleration_limit_mm_s2: float | None = Field(None, gt=0)

    @model_validator(mode="after")
    def _radii(self):
        if self.inner_radius >= self.workpiece_radius:
            raise ValueError(f"inner_radius must be < workpiece_radius ({self.workpiece_radius}), "
                             f"received {self.inner_radius}")
        return self

    @property
    def feed_per_rev(self) -> float:
        """mm per revolution, f / S."""
        return self.feed_mm_per_min / self.spindle_rpm


class SimulationConfig(Section):
    """The grid on which the machined surface is computed."""
    region: tuple[float, float, float, float] = Field((-1.0, -1.0, 1.0, 1.0),
                                                      description="mm, [x0, y0, x1, y1]")
    pixel: float = Field(0.002, gt=0, le=10, description="mm, grid spacing")
    seed: int = Field(0, ge=0, le=2**63 - 1, description="seed of every random draw")
    max_memory_gb: float = Field(8.0, gt=0, le=1024, description="refuse requests estimated above this")

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
        x0, y0, x1, y1 = self.region
        nx = int(round((x1 - x0) / self.pixel)) + 1
        ny = int(round((y1 - y0) / self.pixel)) + 1
        return ny, nx
