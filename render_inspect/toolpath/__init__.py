"""Tool paths: pure planners on explicit numbers and arrays (spirals, tool-radius
compensation, accessibility, RCSE cutting-contact points, axis kinematics).  Scene-level
planning is in :mod:`render_inspect.processes`; files in :mod:`render_inspect.io`."""

from ..core.toolpath import LinearProgram, ToolPath
from ._access import check_accessibility, describe_accessibility
from ._build import (
    PLAN_BYTES_PER_POINT,
    max_curvature,
    plan_memory,
    plan_turning,
    sector_plan,
    region_radii,
    turning_point_count,
)
from ._compensation import (
                    contact_window,
                    gouge_depth,
                    normal_compensation,
                    z_compensation,
)
from ._block_rate import BLOCK_RATE_KEY, DEFAULT_BLOCK_RATE_LIMIT, block_rate, linear_block_rate
from ._kinematics import (LIMIT_KEYS, axes_derivatives, axis_derivatives, kinematics,
                          limits_from_process, turning_axes)
from ._rcse import (
                    PointCloudModel,
                    RcseCcps,
                    RingLayout,
                    conventional_ccps,
                    paper_layout,
                    rcse_ccps,
                    rcse_toolpath,
)
from ._scallop import feed_for_scallop, max_feed_for_scallop, plan_feed, scallop_height
from ._spiral import SAMPLINGS, chordal_error, chordal_step_for, spiral_ccps
from ._edge import EdgeProfile, edge_notes, edge_of, read_edge_file
from ._tool import Tool, pass_margin
from ._verify import (CUT_TOLERANCE, DEFAULT_CLEARANCE, DEFAULT_PLUNGE_FEED, MIN_CLEARANCE,
                      MachineLimits, PartModel, compare_with_plan, longest_step, part_top, plan_links,
                      verify_blocks)

__all__ = ["ToolPath", "LinearProgram", "Tool", "pass_margin", "EdgeProfile", "edge_notes", "edge_of", "read_edge_file", "spiral_ccps", "chordal_error",
           "chordal_step_for", "SAMPLINGS", "z_compensation", "normal_compensation",
           "gouge_depth", "contact_window", "check_accessibility", "describe_accessibility",
           "plan_turning", "sector_plan", "region_radii", "max_curvature", "plan_memory", "turning_point_count",
           "PLAN_BYTES_PER_POINT", "kinematics", "block_rate", "linear_block_rate", "DEFAULT_BLOCK_RATE_LIMIT",
           "BLOCK_RATE_KEY", "axis_derivatives", "axes_derivatives", "turning_axes",
           "limits_from_process", "LIMIT_KEYS", "RingLayout", "RcseCcps", "PointCloudModel",
           "rcse_ccps", "conventional_ccps", "rcse_toolpath", "paper_layout",
           "scallop_height", "feed_for_scallop", "max_feed_for_scallop", "plan_feed",
           "PartModel", "MachineLimits", "plan_links", "part_top", "verify_blocks", "longest_step", "compare_with_plan",
           "MIN_CLEARANCE", "DEFAULT_CLEARANCE", "DEFAULT_PLUNGE_FEED", "CUT_TOLERANCE"]
