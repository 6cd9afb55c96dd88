"""Tools and tool paths: spirals, compensation, accessibility, kinematics, export."""

from ._access import check_accessibility, describe_accessibility
from ._build import build_toolpath, region_radii
from ._compensation import contact_window, gouge_depth, normal_compensation, z_compensation
from ._path import ToolPath
from ._spiral import chordal_error, chordal_step_for, spiral_ccps
from ._tool import Tool

__all__ = ["ToolPath", "Tool", "spiral_ccps", "chordal_error", "chordal_step_for",
           "z_compensation", "normal_compensation", "gouge_depth", "contact_window",
           "check_accessibility", "describe_accessibility", "build_toolpath", "region_radii"]
