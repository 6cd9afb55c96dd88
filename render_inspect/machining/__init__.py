"""Surface-generation kernels on explicit numbers and arrays: the envelope of the tool
nose along a turning path, the sculpturing sweep, servo responses, burrs and residual
statistics.  Scene-level processes are in :mod:`render_inspect.processes`."""

from ..core.heightmap import HeightMap
from ._burrs import apply_burrs, burr_map, sharp_edges
from ._design_grid import design_grid
from ._envelope import path_radial_slope, simulate_turning
from ._metrics import residual_metrics
from ._sculpt import sculpt_line_profile, sculpt_surface, target_line, vibration_phases
from ._servo import followed_path, servo_response, split_commands

__all__ = ["HeightMap", "simulate_turning", "path_radial_slope", "residual_metrics",
           "design_grid", "apply_burrs", "burr_map", "sharp_edges", "sculpt_line_profile",
           "sculpt_surface", "target_line", "vibration_phases", "servo_response",
           "split_commands", "followed_path"]
