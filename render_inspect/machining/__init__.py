"""Surface-generation simulation: the machined height as the envelope of the tool."""

from ._dispatch import simulate_scene
from ._envelope import path_radial_slope, simulate_turning
from ._heightmap import HeightMap
from ._metrics import residual_metrics
from ._result import SimulationResult
from ._sts import design_grid, estimate_memory, simulate_sts

__all__ = ["HeightMap", "SimulationResult", "simulate_scene", "simulate_sts", "simulate_turning",
           "residual_metrics", "design_grid", "estimate_memory", "path_radial_slope"]
