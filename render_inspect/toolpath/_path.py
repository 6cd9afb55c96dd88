"""ToolPath: the programmed tool-tip positions of a turning path, in machine axes."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import InputError


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

    def save_npz(self, path: str | Path) -> Path:
        """Write ``toolpath.npz`` with arrays theta, rho, x, y, z, t (atomic)."""
        import io

        from ..io import atomic_write_bytes

        buf = io.BytesIO()
        np.savez(buf, theta=self.theta, rho=self.rho, x=self.x, y=self.y, z=self.z, t=self.t)
        return atomic_write_bytes(path, buf.getvalue())

    @classmethod
    def load_npz(cls, path: str | Path) -> "ToolPath":
        with np.load(path) as d:
            return cls(d["theta"].copy(), d["rho"].copy(), d["z"].copy(), d["t"].copy())
