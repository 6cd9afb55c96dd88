"""Machine programs: :class:`ToolPath` (turning, C-X-Z) and :class:`LinearProgram`
(sculpturing, X-Y-Z).  Files: see :mod:`render_inspect.io`."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from . import trig
from .errors import InputError

__all__ = ["ToolPath", "LinearProgram", "Links", "Blocks", "ROLE_CUT", "ROLE_RAPID",
           "ROLE_PLUNGE", "ROLE_RETRACT", "ROLE_NAMES", "SPINDLE_KEY", "turns_m04",
           "part_angle", "path_from_part"]

#: ``ToolPath.meta`` key whose value ``"M04"`` says the spindle turned counter-clockwise
#: (absent: M03, the way every planned path turns).  ``theta`` is then the angle the
#: spindle turned through (non-decreasing, as the cutting kernels need it) and the part's
#: own angle of each point is ``-theta`` (:func:`part_angle`): the part is the mirror
#: image (y -> -y) of the one the same path cuts turning M03.
SPINDLE_KEY = "spindle_direction"


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

    def __post_init__(self) -> None:
        n = len(self.theta)
        for name in ("rho", "z", "t"):
            if len(getattr(self, name)) != n:
                raise InputError(f"ToolPath.{name} has {len(getattr(self, name))} points, theta has {n}")
        if n >= 2 and np.any(np.diff(self.theta) < 0):
            raise InputError("ToolPath.theta must be cumulative and non-decreasing")

    @property
    def x(self) -> np.ndarray:
        return self.rho * trig.cos(self.theta)

    @property
    def y(self) -> np.ndarray:
        return self.rho * trig.sin(self.theta)

    @property
    def points(self) -> int:
        return len(self.theta)

    @property
    def revolutions(self) -> float:
        return float((self.theta[-1] - self.theta[0]) / (2 * np.pi)) if self.points else 0.0


def turns_m04(path: object) -> bool:
    """Whether the turning path ``path`` was cut with the spindle turning counter-clockwise
    (M04, :data:`SPINDLE_KEY`)."""
    meta = getattr(path, "meta", None)
    return isinstance(meta, dict) and meta.get(SPINDLE_KEY) == "M04"


def part_angle(path: ToolPath) -> np.ndarray:
    """The part's own angle (rad) of each point of ``path``: ``theta``, or ``-theta`` where
    the spindle turned M04 (:data:`SPINDLE_KEY`)."""
    theta = np.asarray(path.theta, dtype=np.float64)
    if not turns_m04(path):
        return theta
    out = np.negative(theta)
    out += 0.0  # (-0.0 + 0.0 = +0.0: a start at angle 0 stays 0, not -0)
    return out


def path_from_part(angle: np.ndarray, rho: np.ndarray, z: np.ndarray, t: np.ndarray,
                   meta: dict | None = None) -> ToolPath:
    """The :class:`ToolPath` of points at the part's own angles ``angle`` (rad, as a file
    writes them, :func:`part_angle`): angles that decrease (none increasing) are the
    spindle turning M04 (:data:`SPINDLE_KEY`), read as ``theta = -angle``."""
    a = np.asarray(angle, dtype=np.float64)
    meta = dict(meta or {})
    if a.size >= 2 and a[-1] < a[0] and not np.any(np.diff(a) > 0):
        meta[SPINDLE_KEY] = "M04"
        return ToolPath(-a, rho, z, t, meta)
    meta.pop(SPINDLE_KEY, None)
    return ToolPath(a, rho, z, t, meta)


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

    def __post_init__(self) -> None:
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


@dataclass(frozen=True)
class Links:
    """The moves of a machine program that do not cut: how the tool reaches the first
    cut, goes from one cut to the next, and leaves the part.

    Every program written with links starts with a rapid (``G00``) up to the clearance
    plane, then rapids within that plane above the start of the cut and plunges
    vertically onto it at ``plunge_feed``; between the lines of a sculpturing program it
    retracts vertically at ``plunge_feed`` to the clearance plane, rapids within the plane
    above the next line's start and plunges again; at the end it retracts and rapids
    back above the start.  Rapids never leave the clearance plane, plunges and retracts
    never move sideways.

    Attributes
    ----------
    clearance_z : float
        Z of the clearance plane, mm (the part's highest point plus the scene's
        ``process.clearance``).
    plunge_feed : float
        Feed of the plunges and retracts, mm/min.
    part_top : float
        The part's highest point the plane was set from (stock included), mm.
    """

    clearance_z: float
    plunge_feed: float
    part_top: float

    def __post_init__(self) -> None:
        for name in ("clearance_z", "plunge_feed", "part_top"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, float, np.floating)) \
                    or not np.isfinite(v):
                raise InputError(f"Links.{name} must be a finite number, received {v!r}")
        if not self.plunge_feed > 0:
            raise InputError(f"Links.plunge_feed must be > 0 mm/min, received {self.plunge_feed!r}")
        if not self.clearance_z > self.part_top:
            raise InputError(f"Links.clearance_z ({self.clearance_z!r} mm) must lie above the "
                             f"part's highest point ({self.part_top!r} mm)")


#: what a block of a machine program does (:class:`Blocks` ``role``)
ROLE_CUT, ROLE_RAPID, ROLE_PLUNGE, ROLE_RETRACT = 0, 1, 2, 3
ROLE_NAMES = ("cut", "rapid", "plunge", "retract")


@dataclass
class Blocks:
    """The motion blocks of an NC program as written (or read back): what the verifier
    checks and the simulation of the links walks.

    Attributes
    ----------
    dialect : str
        ``"turning"`` (C-X-Z, inverse-time feed ``G93``) or ``"linear"`` (X-Y-Z, ``G94``
        feed in mm/min).
    number : (n,) int64
        The block number (``N`` word).
    motion : (n,) int8
        0 for ``G00`` (rapid), 1 for ``G01`` (feed).
    role : (n,) int8
        :data:`ROLE_CUT`, :data:`ROLE_RAPID`, :data:`ROLE_PLUNGE` or :data:`ROLE_RETRACT`,
        from the section the block stands in (``; cut`` / ``; line k``, ``; approach``,
        ``; link``, ``; exit``): the writer's statement of what the block is for.
    axes : dict of (n,) float64
        The position at the end of each block (``C`` deg, ``X``, ``Z`` or ``X``, ``Y``,
        ``Z`` mm; modal words filled in; NaN where not yet known).
    feed : (n,) float64
        ``F`` of the block (NaN where absent): 1/min (inverse time) or mm/min.
    line : (n,) int64
        The sculpturing line a cutting block belongs to (-1 otherwise).
    meta : dict
        ``; key: value`` header lines.
    """

    dialect: str
    number: np.ndarray
    motion: np.ndarray
    role: np.ndarray
    axes: dict
    feed: np.ndarray
    line: np.ndarray
    meta: dict = field(default_factory=dict)

    @property
    def count(self) -> int:
        return len(self.number)
