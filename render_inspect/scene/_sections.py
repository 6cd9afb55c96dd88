"""``[tool]`` and ``[simulation]``."""

from __future__ import annotations

from pydantic import Field, model_serializer, model_validator

from ..core.grid import grid_shape
from ..core.section import Region, Section

__all__ = ["ToolConfig", "SimulationConfig"]


class ToolConfig(Section):
    """Round-nosed diamond tool."""
    nose_radius: float = Field(0.5, gt=0, le=50, description="mm, Rc")
    included_angle_deg: float = Field(60.0, gt=0, le=180)
    rake_angle_deg: float = Field(0.0, ge=-45, le=45)
    clearance_angle_deg: float = Field(10.0, ge=0, le=45)
    edge_profile: str | None = Field(
        None, description="text file of the measured cutting edge, relative to the scene: a "
                          "header 'angle_deg, deviation_nm' (angle along the edge against the "
                          "deviation of the nose radius; angle_rad, _um, _mm, or 'radius_um' for "
                          "the radius itself) or 'x_um, z_um' (points of the edge); "
                          "None = a circular nose")
    waviness: list[tuple[float, float, float]] | None = Field(
        None, description="edge waviness as harmonics [amplitude nm, period deg, phase deg] "
                          "of the nose radius along the edge angle (added to edge_profile); "
                          "amplitude 0-10000 nm, period 0.5-360 deg")
    edge_scale: float = Field(1.0, ge=0, le=100, description="factor on the edge's deviation "
                                                             "(edge_profile and waviness)")
    wear: bool = Field(False, description="wear the edge along the cut (flank wear and edge radius "
                                          "against the cutting distance, rates of material.preset)")
    wear_scale: float = Field(1.0, ge=0, le=1e4, description="factor on the material's wear rates")
    contact_duty_cycle: float = Field(1.0, gt=0, le=1, description="fraction of the time the edge is "
                                                                   "in contact (vibration cutting < 1): "
                                                                   "scales the chemical wear")

    @model_validator(mode="after")
    def _edge(self) -> ToolConfig:
        for k, (a, p, _) in enumerate(self.waviness or ()):
            if not (0 <= a <= 1e4):
                raise ValueError(f"waviness[{k}] amplitude must be in [0, 10000] nm, received {a}")
            # (the shortest period the cut resolves, toolpath's MIN_WAVINESS_PERIOD_DEG: the
            # scene package does not import the tool path's)
            if not (0.5 <= p <= 360):
                raise ValueError(f"waviness[{k}] period must be in [0.5, 360] deg, received {p}")
        if self.edge_profile is not None and ("\x00" in self.edge_profile or not self.edge_profile.strip()):
            raise ValueError(f"edge_profile must be a file name, received {self.edge_profile!r}")
        return self

    @model_serializer(mode="wrap")
    def _dump(self, handler):
        # a circular nose writes the tool as it always has (outputs that echo the scene
        # stay the same): the edge keys appear once they are set
        d = handler(self)
        if isinstance(d, dict):
            for k, default in _EDGE_DEFAULTS.items():
                if k in d and d[k] == default:
                    del d[k]
        return d


#: the edge and wear keys' defaults (left out of the written scene while they hold them)
_EDGE_DEFAULTS = {"edge_profile": None, "waviness": None, "edge_scale": 1.0, "wear": False,
                  "wear_scale": 1.0, "contact_duty_cycle": 1.0}


class SimulationConfig(Section):
    """The grid on which the machined surface is computed."""
    region: Region = Field((-1.0, -1.0, 1.0, 1.0), description="mm, [x0, y0, x1, y1]")
    pixel: float = Field(0.002, ge=1e-6, le=10, description="mm, grid spacing")
    seed: int = Field(0, ge=0, le=2**63 - 1, description="seed of every random draw")
    max_memory_gb: float | None = Field(
        None, gt=0, le=65536, description="GiB; refuse requests estimated above this; None = "
                                          "80 % of the memory available when the command starts")

    @model_validator(mode="after")
    def _region(self) -> SimulationConfig:
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
