"""Surface-generation kernels on explicit numbers and arrays: the envelope of the tool
nose along a turning path (whole or tile by tile), the sculpturing sweep, machine axis
dynamics (the one servo model), error motions, the material's response to the cut and the
part's texture, burrs and residual statistics.  Scene-level processes are in :mod:`render_inspect.processes`."""

from ..core.heightmap import HeightMap
from ._axes import (Axis, Coupling, follow_axis, force_noise_rms, loop_lag, loop_response,
                    second_order_sos, settle_time)
from ._machine import Machine
from ._follow import (FollowedPath, follow_turning, following_error_stats, mask_outside_sector,
                      window_margins)
from ._interpolate import linear_command, pvt_command
from ._burrs import (BURR_WIDTH_PER_CHIP, apply_burrs, burr_halo, burr_height_law, burr_map, edge_turns,
                     machined_sharp_edges, material_burr_block, material_burr_facts, material_burrs,
                     sharp_edges)
from ._cutting import (
    cut_lines_mechanics,
    cut_turning_mechanics,
    finish_surface,
    groove_texture,
    machined_edge_count,
    machined_edges,
    mechanics_facts,
)
from ._cut_kernel import (CutPath, Grooves, cut_fill, cut_turning, cutting_distance, load_cut_kernels,
                          prepare_cut)
from ._design_grid import design_grid
from ._envelope import EnvelopePath, load_kernels, path_radial_slope, prepare_envelope, simulate_turning
from ._errmotion import ErrorMotions, apply_error_motions
from ._texture import TextureJob, add_texture_field, texture_field
from ._material import (
    MATERIAL_PRESETS,
    Material,
    MaterialResponse,
    contact_ratio,
    material_preset,
    material_response,
    min_chip_thickness,
    uncut_chip_thickness,
)
from ._machines import MACHINE_PRESET_NAMES, MACHINE_PRESETS, machine_preset
from ._program_limits import PROGRAM_LIMITS, ProgramLimits, program_limits_of
from ._memory import BURR_BLOCK_BYTES, in_memory_bytes, tiled_bytes
from ._part_map import part_heightmap
from ._metrics import (merge_moments, metrics_from_moments, residual_metrics, tile_abs_dev,
                       tile_moments)
from ._sculpt import sculpt_line_profile, sculpt_surface, target_line, vibration_phases
from ._servo import split_commands
from ._tiled import TILE, Tile, compute_tile, plan_tiles
from ._wear import (MM_PER_KM, SPEED_LAW, WEAR_RATES, WearRate, chemical_distance_km,
                    spiral_distance_km, wear_rate, wear_state, worn_path)

__all__ = ["HeightMap", "PROGRAM_LIMITS", "ProgramLimits", "program_limits_of", "simulate_turning", "path_radial_slope", "residual_metrics",
           "design_grid", "apply_burrs", "burr_map", "sharp_edges", "sculpt_line_profile",
           "sculpt_surface", "target_line", "vibration_phases", "split_commands",
           "machined_sharp_edges", "Axis", "Coupling", "Machine", "FollowedPath",
           "MACHINE_PRESETS", "MACHINE_PRESET_NAMES", "machine_preset", "follow_axis",
           "follow_turning", "following_error_stats", "window_margins", "mask_outside_sector",
           "settle_time", "pvt_command", "linear_command",
           "second_order_sos", "EnvelopePath", "prepare_envelope", "load_kernels",
           "in_memory_bytes", "tiled_bytes", "BURR_BLOCK_BYTES", "merge_moments", "metrics_from_moments",
           "tile_abs_dev", "tile_moments", "TILE", "Tile", "compute_tile", "plan_tiles",
           "MATERIAL_PRESET_NAMES", "part_heightmap",
           "ErrorMotions", "apply_error_motions",
           "Material", "MaterialResponse", "MATERIAL_PRESETS", "material_preset",
           "material_response", "contact_ratio", "min_chip_thickness",
           "cut_turning_mechanics", "cut_lines_mechanics", "finish_surface", "groove_texture",
           "machined_edges", "machined_edge_count", "mechanics_facts", "CutPath", "Grooves", "cut_fill", "cut_turning",
           "cutting_distance", "load_cut_kernels", "prepare_cut",
           "material_burrs", "edge_turns", "burr_height_law", "burr_halo", "material_burr_block", "material_burr_facts",
           "BURR_WIDTH_PER_CHIP", "texture_field", "add_texture_field", "TextureJob", "uncut_chip_thickness", "loop_lag",
           "loop_response", "force_noise_rms", "MM_PER_KM", "WEAR_RATES", "WearRate", "spiral_distance_km",
           "wear_rate", "wear_state", "worn_path", "SPEED_LAW", "chemical_distance_km"]

#: the names ``material.preset`` takes ("ideal": no material response)
MATERIAL_PRESET_NAMES = ("ideal", *MATERIAL_PRESETS)
