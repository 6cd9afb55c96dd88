"""``[rcse]``: settings of the RCSE tool path's comparison with the conventional method.

The RCSE path itself needs no keys of its own: its spiral pitch is the feed per
revolution (``process.feed_mm_per_min / process.spindle_rpm``), its polar step
``360 / process.points_per_rev`` degrees, its elements the ``lenslet_rings`` design.
"""

from __future__ import annotations

from typing import Literal

from pydantic import Field

from ..core.section import Section


class RcseConfig(Section):
    """How the conventional (grid-interpolated) path is built for the comparison (seed 004)."""
    compare_conventional: bool = Field(True, description="also build the conventional path and compare")
    grid_spacing: float = Field(0.005, gt=0, le=1.0,
                                description="mm, spacing of the rectangular point cloud (modelling grid)")
    interpolation: Literal["linear", "cubic"] = Field("linear", description="interpolation in the point cloud")
    simulate_conventional: bool = Field(True, description="also simulate the surface the conventional "
                                                          "path machines over simulation.region")
    snap_to_rows: bool = Field(True, description="CCPs on the nearest point-cloud row (X reciprocates); "
                                                 "false: interpolated at the exact spiral point")
    spread_elements: int = Field(0, ge=0, le=1000,
                                 description="elements (spread over the rings) on which both paths are "
                                             "cut to compare Sa and its spread; 0 = none")
    spread_window: float = Field(0.214, gt=0, le=10.0,
                                 description="mm, side of the square field measured on each element "
                                             "(seed 004: 0.214 mm)")
