"""Machine programs: :class:`ToolPath` (turning, C-X-Z) and :class:`LinearProgram`
(sculpturing, X-Y-Z).  Files: see :mod:`render_inspect.io`."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .errors import InputError

__all__ = ["ToolPath", "LinearProgram"]


@dataclass
class ToolPath:
    """Programmed tool-tip points of a turning (C-X-Z) path.

    Attributes
    ----------
    theta : (n,) float64, rad
        Spindle angle C, *cumulative* (monotone non-decreasing over the whole spiral).
    rho : (n,) float64, mm
        Radial position X of the tool tip.
    z : (n,) float64, mm
        Axial position Z of the tool tip (lowest point of the nose arc).
    t : (n,) float64, s
        Time at which each point is reached.
    meta : dict
        Provenance and path facts (sampling, compensation, feed per rev, ...).

    Between points the machine axes interpolate linearly in (C, X, Z), which is what the
    surface-generation simulation assumes.
    """

    theta: np.ndarray
    rho: np.ndarray
    z: np.ndarray
    t: np.ndarray
    meta: dict = field(default_factory=dict)
    #: the cutting-contact points the path was made from (radius, design height), if known
    ccp_rho: np.ndarray | None = field(default=None, repr=False)
    ccp_z: np.ndarray | None = field(default=None, repr=False)

    def __post_init__(self):
        n = len(self.theta)
        for name in ("rho", "z", "t"):
            if len(getattr(self, name)) != n:
                raise InputError(f"ToolPath.{name} has {len(getattr(self, name))} points, theta has {n}")
        if n >= 2 and np.any(np.diff(self.theta) < 0):
            raise InputError("ToolPath.theta must be cumulative and non-decreasing")

    @property
    def x(self) -> np.ndarray:
        return self.rho * np.cos(self.theta)

    @property
    def y(self) -> np.ndarray:
        return self.rho * np.sin(self.theta)

    @property
    def points(self) -> int:
        return len(self.theta)

    @property
    def revolutions(self) -> float:
        return float((self.theta[-1] - self.theta[0]) / (2 * np.pi)) if self.points else 0.0


@dataclass
class LinearProgram:
    """Programmed tool-tip points of a linear X-Y-Z (sculpturing) program.

    Attributes
    ----------
    x, y, z : (n,) float64, mm
        Tool-tip position.
    t : (n,) float64, s
        Nominal time at which each point is reached (lines end to end, without the moves
        between them).
    line : (n,) int64
        Index of the target line each point belongs to.
    meta : dict
        Provenance and program facts (cutting speed, vibration, ...).
    """

    x: np.ndarray
    y: np.ndarray
    z: np.ndarray
    t: np.ndarray
    line: np.ndarray
    meta: dict = field(default_factory=dict)

    def __post_init__(self):
        n = len(self.x)
        for name in ("y", "z", "t", "line"):
            if len(getattr(self, name)) != n:
                raise InputError(f"LinearProgram.{name} has {len(getattr(self, name))} points, x has {n}")

    @property
    def points(self) -> int:
        return len(self.x)

    @property
    def lines(self) -> int:
        return int(self.line.max()) + 1 if self.points else 0

    @property
    def duration_s(self) -> float:
        return float(self.t[-1] - self.t[0]) if self.points else 0.0
