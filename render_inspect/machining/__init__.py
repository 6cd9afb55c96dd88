"""Surface-generation kernels on explicit numbers and arrays: the envelope of the tool
nose along a turning path, the sculpturing sweep, servo responses and machine axis
dynamics, error motions, the material's response to the cut, burrs and residual
statistics.  Scene-level processes are in :mod:`render_inspect.processes`."""

from ..core.heightmap import HeightMap
from ._axes import (
    MACHINE_PRESETS,
    Axis,
    Coupling,
    FollowedPath,
    Machine,
    follow_axis,
    follow_turning,
    following_error_stats,
    machine_preset,
    pvt_command,
)
from ._burrs import apply_burrs, burr_map, machined_sharp_edges, sharp_edges
from ._cutting import (
    cut_lines_mechanics,
    cut_turning_mechanics,
    finish_surface,
    groove_texture,
    machined_edges,
)
from ._design_grid import design_grid
from ._envelope import path_radial_slope, simulate_turning
from ._errmotion import ErrorMotions, apply_error_motions
from ._material import (
    MATERIAL_PRESETS,
    Material,
    MaterialResponse,
    contact_ratio,
    material_preset,
    material_response,
    min_chip_thickness,
)
from ._metrics import residual_metrics
from ._sculpt import sculpt_line_profile, sculpt_surface, target_line, vibration_phases
from ._servo import followed_path, servo_response, split_commands

__all__ = ["HeightMap", "simulate_turning", "path_radial_slope", "residual_metrics",
           "design_grid", "apply_burrs", "burr_map", "sharp_edges", "sculpt_line_profile",
           "sculpt_surface", "target_line", "vibration_phases", "servo_response",
           "split_commands", "followed_path", "machined_sharp_edges",
           "Axis", "Coupling", "Machine", "FollowedPath", "MACHINE_PRESETS", "machine_preset",
           "follow_axis", "follow_turning", "following_error_stats", "pvt_command",
           "ErrorMotions", "apply_error_motions",
           "Material", "MaterialResponse", "MATERIAL_PRESETS", "material_preset",
           "material_response", "contact_ratio", "min_chip_thickness",
           "cut_turning_mechanics", "cut_lines_mechanics", "finish_surface", "groove_texture",
           "machined_edges"]
