"""Surface-generation simulation: the machined height as the envelope of the tool."""

from ._heightmap import HeightMap
from ._result import SimulationResult

__all__ = ["HeightMap", "SimulationResult"]
