"""The round-nosed diamond tool."""

from __future__ import annotations

from typing import Any
import math
from dataclasses import dataclass, field

from ..core.errors import check_range
from ._edge import EdgeProfile, edge_of


@dataclass(frozen=True)
class Tool:
    """Round-nosed tool.  Lengths in mm, angles in rad.

    Parameters
    ----------
    nose_radius : float
        Rc, mm (> 0).
    included_angle : float
        Included (wrap) angle of the nose arc, rad in (0, pi]; the arc spans
        +- included_angle / 2 about the tool axis.
    rake_angle, clearance_angle : float
        rad.
    edge : EdgeProfile or None
        The measured cutting edge (nose radius Rc + delta(angle)); None: a circular nose.
    """

    nose_radius: float
    included_angle: float = math.radians(60.0)
    rake_angle: float = 0.0
    clearance_angle: float = math.radians(10.0)
    edge: EdgeProfile | None = field(default=None, compare=False)

    def __post_init__(self) -> None:
        check_range("tool.nose_radius", self.nose_radius, 0.0, None, lo_open=True)
        check_range("tool.included_angle", self.included_angle, 0.0, math.pi, lo_open=True)
        check_range("tool.clearance_angle", self.clearance_angle, 0.0, math.pi / 2)

    @classmethod
    def from_config(cls, cfg: Any) -> "Tool":
        # (a measured edge is checked against the nose arc it cuts with: refused here, before
        # any work, when the cut cannot take it)
        half_width = cfg.nose_radius * math.sin(min(math.radians(cfg.included_angle_deg) / 2, math.pi / 2))
        edge = edge_of(getattr(cfg, "edge_profile", None), getattr(cfg, "waviness", None),
                       nose_radius=cfg.nose_radius, amplitude_scale=getattr(cfg, "edge_scale", 1.0),
                       half_width=half_width)
        return cls(cfg.nose_radius, math.radians(cfg.included_angle_deg),
                   math.radians(cfg.rake_angle_deg), math.radians(cfg.clearance_angle_deg), edge)

    @property
    def half_width(self) -> float:
        """Radial half-width of the cutting arc, Rc sin(included / 2), mm."""
        return self.nose_radius * math.sin(min(self.included_angle / 2, math.pi / 2))

    @property
    def half_angle(self) -> float:
        """Half the angle of the edge that can cut, rad (included / 2, at most pi / 2)."""
        return min(self.included_angle / 2, math.pi / 2)


def pass_margin(tool: Tool, max_slope: float, feed_per_rev: float) -> float:
    """Radial distance (mm) around a region within which a turning pass can still cut it.

    A pass farther than 2 Rc m + f / 2 from a point never forms the envelope there (m the
    largest radial slope, f the feed per revolution: the proven pass window of
    ``machining/_envelope.py``), nor farther than the nose arc's half-width.  The margin
    takes 2.2 Rc m + f, capped by :attr:`Tool.half_width`, plus two more revolutions.  The
    planner keeps the radii of the region widened by it, and the memory estimates count
    the revolutions over them.
    """
    f = float(feed_per_rev)
    return min(tool.half_width, 2.2 * tool.nose_radius * max_slope + f) + 2 * f
