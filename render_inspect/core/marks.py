"""The tool marks a process leaves: what the waviness filters, the diffuse renderer's
surface texture and the report need to know of a process, stated by the process itself
(:meth:`render_inspect.processes.Process.traits`) rather than asked of its kind."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

__all__ = ["ToolMarks"]


@dataclass(frozen=True)
class ToolMarks:
    """Periodic marks left on the machined surface.

    Attributes
    ----------
    pattern : {"circular", "linear"}
        ``"circular"``: concentric about ``center_mm`` (the feed marks of turning, about the
        spindle axis); ``"linear"``: straight lines across ``direction`` (the vibration
        marks of sculpturing, along the cut).
    period_mm : float or None
        Spacing of the marks (turning: the feed per revolution); None when the process
        leaves no periodic marks.
    nose_radius_mm : float
        Radius of the tool edge that cuts them.
    scallop : bool
        The marks are arcs of the nose radius (a feed scallop): their peak-to-valley
        height and kinematic roughness follow from ``period_mm`` and ``nose_radius_mm``.
    pv_mm : float or None
        Peak-to-valley height of marks that are not a scallop (None: not known).
    center_mm : (x, y)
        Centre of circular marks.
    direction : (dx, dy)
        Direction along which linear marks repeat (the cutting direction).
    """

    pattern: Literal["circular", "linear"]
    period_mm: float | None
    nose_radius_mm: float
    scallop: bool = False
    pv_mm: float | None = None
    center_mm: tuple[float, float] = (0.0, 0.0)
    direction: tuple[float, float] = (0.0, 1.0)
