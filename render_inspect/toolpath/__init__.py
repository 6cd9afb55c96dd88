"""Tools and tool paths: spirals, compensation, accessibility, kinematics, export."""

from ._path import ToolPath

__all__ = ["ToolPath"]
