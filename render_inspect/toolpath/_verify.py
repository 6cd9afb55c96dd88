"""The links of a machine program and its verification against the part.

:func:`plan_links` sets the clearance plane (the part's highest point, stock included,
plus the scene's ``process.clearance``) and the plunge feed every written program moves
through between its cuts (:class:`~render_inspect.core.toolpath.Links`).

:func:`verify_blocks` checks every block of a program as it was written (read back
from the file, :func:`render_inspect.io.read_nc_blocks`, in either dialect) against the
part, the design and the machine:

* the program starts with a rapid that raises Z alone to the clearance plane (where the
  machine starts is not known);
* rapids (``G00``) start and end in the clearance plane, which lies at least
  :data:`MIN_CLEARANCE` above the part's highest point: no rapid can pass through the
  part;
* plunges and retracts (``G01`` outside the cut) are vertical, run between the
  clearance plane and a point of the cut, and at the plunge feed;
* cutting blocks end on or above the design surface (within ``cut_tolerance``, the
  chordal and rounding error), inside the part's outline (plus the tool's half width),
  and are no longer than the planned program's longest step;
* every feed is positive and within the machine's limits: the programmed feed, each
  axis's velocity, the spindle speed, the axes' travel.

A failure is an :class:`InputError` naming the block number (``N`` word; in a program
written without block numbers the block's place among the motion blocks and its file
line), what the block does and the limit it breaks.  The same checks run on the blocks a program would have
(:func:`render_inspect.io.program_blocks`) when ``simulate`` plans it: the links are
part of the simulated program and never touch the part.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, cast

import numpy as np

from ..core import trig
from ..core.errors import InputError
from ..core.toolpath import ROLE_CUT, ROLE_NAMES, ROLE_RAPID, Blocks, Links
from ..core.units import MIN_TO_S, MM_TO_NM
from ._verify_scan import scan_blocks

__all__ = ["PartModel", "MachineLimits", "plan_links", "part_top", "verify_blocks", "longest_step",
           "compare_with_plan",
           "MIN_CLEARANCE", "DEFAULT_CLEARANCE", "DEFAULT_PLUNGE_FEED", "CUT_TOLERANCE", "DECIMALS"]

#: the least height of the clearance plane above the part's highest point, mm
MIN_CLEARANCE = 0.01
#: ``process.clearance`` when the scene does not set it, mm
DEFAULT_CLEARANCE = 0.1
#: ``process.plunge_feed_mm_per_min`` when the scene does not set it
DEFAULT_PLUNGE_FEED = 10.0
#: how far a cutting block may end below the design surface, mm: the chordal error of
#: the linear moves, the curvature under a compensated tip and the written places
CUT_TOLERANCE = 1e-4
#: places the programs are written with (mm, deg) and the step they round to
DECIMALS = 6
_ROUND = 10.0 ** -DECIMALS
#: samples across the part's outline when its highest point is sought
_TOP_SAMPLES = 257
#: cutting blocks whose design height is evaluated at a time
_CHUNK = 1 << 18


@dataclass(frozen=True)
class PartModel:
    """The part a program cuts, as the verifier sees it.

    Attributes
    ----------
    height : callable
        ``height(x, y) -> z`` of the design surface, mm (numpy arrays in and out).
    outline : tuple
        Where the part is: ``("disc", cx, cy, radius)`` or ``("box", x0, y0, x1, y1)``, mm.
    stock : float
        Material above the design (the depth of cut), mm.
    half_width : float
        Half the width of the tool's cutting edge, mm (a cut may reach this far beyond
        the outline).
    max_step : float or None
        The longest cutting move of the planned program, mm: a longer one is not part of
        the cut (a move between cuts that does not go through the clearance plane).
    top : float or None
        An upper bound on the design's heights over the outline, mm (the design's true
        highest point, :func:`render_inspect.design.max_height`); None: the highest of
        the heights on a :data:`_TOP_SAMPLES` grid (a narrow peak between the samples is
        missed).
    bound : callable or None
        ``bound(x0, y0, x1, y1) -> high``: an upper bound on the design's heights over
        each box (arrays, mm; :func:`render_inspect.design.height_interval`), or None
        when the design has none (a rapid is then checked against the design's heights
        sampled densely along it).
    """

    height: Callable[..., Any]
    outline: tuple
    stock: float = 0.0
    half_width: float = 0.0
    max_step: float | None = None
    top: float | None = None
    bound: Callable[..., Any] | None = None


@dataclass(frozen=True)
class MachineLimits:
    """What the machine allows (None: no limit).

    Attributes
    ----------
    source : str
        Where the limits come from, for messages (``"machine.preset 'sts_lathe'"``).
    feed_mm_per_min : float or None
        The largest programmed feed of a linear (``G94``) program.
    velocity_mm_s : dict
        Axis (``"X"``, ``"Y"``, ``"Z"``) -> largest velocity, mm/s.
    spindle_rpm : float or None
        The largest speed of the C axis, rev/min.
    travel : dict
        Axis -> (lowest, highest) position, mm (C has none).
    plunge_feed_mm_per_min : float or None
        The largest feed of a plunge or retract the scene's physics allows (a plunge
        enters the stock with the cutting edge: it cuts, no faster than the cutting
        speed), whatever feed the program was written with.
    plunge_source : str
        Where ``plunge_feed_mm_per_min`` comes from, for messages.
    """

    source: str = "the machine"
    feed_mm_per_min: float | None = None
    velocity_mm_s: dict = field(default_factory=dict)
    spindle_rpm: float | None = None
    travel: dict = field(default_factory=dict)
    plunge_feed_mm_per_min: float | None = None
    plunge_source: str = "the cutting speed"


def _grid(outline, n: int):
    kind = outline[0]
    if kind == "disc":
        _, cx, cy, r = outline
        u = np.linspace(-r, r, n)
        x, y = np.meshgrid(cx + u, cy + u)
        inside = (x - cx) ** 2 + (y - cy) ** 2 <= r * r
        return x[inside], y[inside]
    if kind == "box":
        _, x0, y0, x1, y1 = outline
        x, y = np.meshgrid(np.linspace(x0, x1, n), np.linspace(y0, y1, n))
        return x.ravel(), y.ravel()
    raise InputError(f"part outline must be ('disc', cx, cy, r) or ('box', x0, y0, x1, y1), "
                     f"received {outline!r}")


def longest_step(x: np.ndarray, y: np.ndarray, z: np.ndarray,
                 line: np.ndarray | None = None) -> float:
    """The longest straight move between consecutive points of a planned program (within
    each line when ``line`` is given), mm."""
    x, y, z = (np.asarray(a, dtype=np.float64) for a in (x, y, z))
    if x.size < 2:
        return 0.0
    step = np.sqrt(np.diff(x) ** 2 + np.diff(y) ** 2 + np.diff(z) ** 2)
    if line is not None:
        step = step[np.diff(np.asarray(line)) == 0]
    return float(step.max()) if step.size else 0.0


def part_top(part: PartModel, *, program_z: np.ndarray | None = None) -> float:
    """The part's highest point, mm: the design's highest height over the outline
    (``part.top``, its true highest point, or else sampled on a :data:`_TOP_SAMPLES`
    grid) or the highest programmed cutting point, whichever is higher, plus the stock."""
    if part.top is not None and math.isfinite(part.top):
        top = float(part.top)
    else:
        x, y = _grid(part.outline, _TOP_SAMPLES)
        with np.errstate(invalid="ignore"):
            z = np.asarray(part.height(x, y), dtype=np.float64)
        top = float(np.nanmax(z)) if np.isfinite(z).any() else -math.inf
    if program_z is not None and np.size(program_z):
        top = max(top, float(np.nanmax(program_z)))
    if not math.isfinite(top):
        raise InputError("the part's highest point cannot be found: the design has no finite "
                         "height over the part")
    return top + float(part.stock)


def plan_links(part: PartModel, *, clearance: float = DEFAULT_CLEARANCE,
               plunge_feed: float = DEFAULT_PLUNGE_FEED, program_z: np.ndarray | None = None,
               keys: tuple[str, str] = ("process.clearance", "process.plunge_feed_mm_per_min")
               ) -> Links:
    """The :class:`Links` of a program: the clearance plane ``clearance`` mm above the
    part's highest point (:func:`part_top`), the plunge feed.  ``keys`` name the scene
    keys in messages."""
    if not (isinstance(clearance, (int, float)) and math.isfinite(clearance)
            and clearance >= MIN_CLEARANCE):
        raise InputError(f"{keys[0]} must be a number >= {MIN_CLEARANCE} mm (the clearance "
                         f"plane's height above the part), received {clearance!r}")
    if not (isinstance(plunge_feed, (int, float)) and math.isfinite(plunge_feed)
            and plunge_feed > 0):
        raise InputError(f"{keys[1]} must be a number > 0 mm/min, received {plunge_feed!r}")
    top = part_top(part, program_z=program_z)
    # the plane rounded up to the written places, so that it stays above the part
    zc = math.ceil((top + clearance) / _ROUND) * _ROUND
    return Links(clearance_z=round(zc, 6), plunge_feed=float(plunge_feed), part_top=top)


# ---------------------------------------------------------------------------- checks
def _fail(what: str, blocks: Blocks, i: int, text: str):
    n = int(blocks.number[i])
    role = ROLE_NAMES[int(blocks.role[i])]
    move = "G00" if blocks.motion[i] == 0 else "G01"
    if n >= 0:
        where = f"block N{n}"
    else:  # a program without block numbers: the motion block's place (and its file line)
        lines = blocks.meta.get("_file_line")
        where = f"block {i + 1}" + (f" (file line {int(lines[i])})"
                                    if lines is not None and i < len(lines) else "")
    raise InputError(f"{what} {where} ({move}, {role}): {text}")


def _tip(blocks: Blocks):
    """(x, y, z) of the tool tip at the end of each block, mm."""
    ax = blocks.axes
    if blocks.dialect == "turning":
        c = np.radians(ax["C"])
        cs, sn = trig.cos_sin(c)
        return ax["X"] * cs, ax["X"] * sn, ax["Z"]
    return ax["X"], ax["Y"], ax["Z"]


def _inside(outline, x, y, margin: float) -> np.ndarray:
    if outline[0] == "disc":
        _, cx, cy, r = outline
        return np.hypot(x - cx, y - cy) <= r + margin + _ROUND
    _, x0, y0, x1, y1 = outline
    return (x >= x0 - margin - _ROUND) & (x <= x1 + margin + _ROUND) & \
        (y >= y0 - margin - _ROUND) & (y <= y1 + margin + _ROUND)


def _first(mask) -> int | None:
    idx = np.flatnonzero(mask)
    return int(idx[0]) if idx.size else None


def verify_blocks(blocks: Blocks, part: PartModel, limits: MachineLimits, links: Links, *,
                  cut_tolerance: float = CUT_TOLERANCE, what: str = "toolpath.nc",
                  check_cuts: bool = True) -> dict:
    """Check every block of a program (see the module docstring); raise
    :class:`InputError` naming the first block that fails.

    Parameters
    ----------
    blocks : Blocks
        The program as written (:func:`render_inspect.io.read_nc_blocks`).
    part : PartModel
    limits : MachineLimits
    links : Links
        The clearance plane and plunge feed the program was written with.
    cut_tolerance : float
        mm a cutting block may end below the design.
    what : str
        The program's name in messages.
    check_cuts : bool
        Also check the cutting blocks against the design (False: the links, feeds and
        limits only, e.g. when the cut is simulated anyway).

    Returns
    -------
    dict
        Facts: ``blocks``, ``rapids``, ``plunges``, ``retracts``, ``cuts``,
        ``clearance_z_mm``, ``part_top_mm``, ``clearance_above_part_mm``,
        ``rapids_above_part_min_mm`` (the lowest point of any rapid above the part's
        highest point), ``cut_below_design_max_nm``, ``max_feed_mm_per_min``,
        ``plunge_feed_mm_per_min``.
    """
    n = blocks.count
    if n == 0:
        raise InputError(f"{what}: no motion blocks")
    num = blocks.number
    # (a program may have no block numbers at all: a control that needs none)
    if not np.all(num == -1) and (np.any(num < 1) or np.any(np.diff(num) <= 0)):
        i = _first((num < 1) | np.r_[False, np.diff(num) <= 0])
        _fail(what, blocks, cast(int, i), "block numbers must be positive and increase from block to block")
    x, y, z = _tip(blocks)
    zc = float(links.clearance_z)
    top = part_top(part, program_z=z[blocks.role == ROLE_CUT])
    if zc - top < MIN_CLEARANCE - _ROUND:
        raise InputError(f"{what}: the clearance plane Z {zc:.6f} mm lies {zc - top:.6g} mm above "
                         f"the part's highest point ({top:.6f} mm, stock included); it must be at "
                         f"least {MIN_CLEARANCE} mm above (process.clearance)")
    rapid = blocks.motion == 0
    role = blocks.role
    # 1. the start: Z alone up to the clearance plane
    others = [a for a in blocks.axes if a != "Z"]
    if not rapid[0] or any(np.isfinite(blocks.axes[a][0]) for a in others) \
            or not z[0] >= zc - _ROUND:
        _fail(what, blocks, 0, f"the program must start with a rapid that raises Z alone to the "
                               f"clearance plane Z {zc:.6f} mm (where the machine starts is not "
                               f"known)")
    known = np.ones(n, dtype=bool)
    for a in blocks.axes:
        known &= np.isfinite(blocks.axes[a])
    i = _first(~known[1:])
    if i is not None:
        _fail(what, blocks, i + 1, f"the block moves before every axis has a position "
                                   f"({', '.join(blocks.axes)})")
    # the checks of the moves (and a turning program's speeds), in one pass over the blocks
    scan = scan_blocks(blocks, x, y, z, zc, _ROUND, part.max_step, to_s=MIN_TO_S,
                       rpm_max=None if limits.spindle_rpm is None else
                       limits.spindle_rpm * (1 + 1e-6),
                       v_max={a: v * (1 + 1e-6) for a, v in limits.velocity_mm_s.items()
                              if v is not None})

    def zs(i):  # where block i starts (its Z)
        return z[i - 1] if i > 0 else z[0]

    # every check notes the first block it refuses; the earliest block is reported
    problems: list[tuple[int, int, str]] = []

    def note(i, text):  # (block, order of the check, message)
        problems.append((int(i), len(problems), text))

    # 2. rapids stay in the clearance plane
    i = scan["low"]
    if i is not None:
        note(i, f"a rapid from Z {zs(i):.6f} to Z {z[i]:.6f} mm leaves the "
                               f"clearance plane Z {zc:.6f} mm (the part's top is at {top:.6f} mm)")
    # 3. plunges and retracts: vertical, between the plane and the cut
    feedmove = ~rapid & (role != ROLE_CUT)
    i = scan["sideways"]
    if i is not None:
        note(i, "a plunge or retract must be vertical (only Z moves): a feed move "
                               "outside the cut that also moves sideways could cut through the part")
    i = scan["short"]
    if i is not None:
        note(i, f"a plunge or retract must reach the clearance plane Z {zc:.6f} mm, "
                               f"its top is at Z {np.maximum(z[i], zs(i)):.6f} mm")
    i = scan["direction"]
    if i is not None:
        note(i, "a plunge must move down and a retract up")
    # the lower ends of plunges and retracts are points of the cut: checked with the cut
    cutpt = scan["cutpt"]
    # 4. cutting blocks: inside the outline, on or above the design
    i = _first(cutpt & ~_inside(part.outline, x, y, part.half_width))
    if i is not None:
        note(i, f"the cut at x {x[i]:.6f}, y {y[i]:.6f} mm lies outside the part "
                               f"({part.outline[0]} {', '.join(f'{v:g}' for v in part.outline[1:])} mm)")
    below_max = 0.0
    if check_cuts:
        idx = np.flatnonzero(cutpt)
        for a in range(0, idx.size, _CHUNK):
            sel = idx[a:a + _CHUNK]
            try:
                with np.errstate(invalid="ignore"):
                    d = np.asarray(part.height(x[sel], y[sel]), dtype=np.float64) - z[sel]
            except InputError as err:  # the design is not defined where the program cuts
                note(int(sel[0]), f"the design cannot be evaluated where the program cuts ({err})")
                break
            d = np.where(np.isfinite(d), d, -np.inf)
            bad = np.flatnonzero(d > cut_tolerance)
            if bad.size:
                j = int(sel[bad[0]])
                note(j, f"the tool tip ends {d[bad[0]] * MM_TO_NM:.0f} nm below "
                                       f"the design surface at x {x[j]:.6f}, y {y[j]:.6f} mm (at "
                                       f"most {cut_tolerance * MM_TO_NM:.0f} nm allowed)")
            if sel.size:
                below_max = max(below_max, float(np.max(d)))
    i = scan["step"]
    if i is not None:
        step = np.sqrt((x[i] - x[i - 1]) ** 2 + (y[i] - y[i - 1]) ** 2 + (z[i] - z[i - 1]) ** 2)
        note(i, f"a cutting move of {step:.6g} mm, longer than the program's longest planned "
                f"step ({part.max_step:.6g} mm): a move between cuts must retract to the "
                f"clearance plane")
    # 5. feeds and limits
    feed_mm_min = _feeds(blocks, x, y, z, what)
    f = blocks.feed
    fm = ~rapid
    if limits.feed_mm_per_min is not None and blocks.dialect == "linear":
        i = _first(fm & (feed_mm_min > limits.feed_mm_per_min * (1 + 1e-9)))
        if i is not None:
            note(i, f"feed {feed_mm_min[i]:g} mm/min over the {limits.feed_mm_per_min:g} "
                                   f"mm/min {limits.source} allows")
    i = _first(feedmove & (feed_mm_min > links.plunge_feed * (1 + 1e-6) + 1e-9))
    if i is not None:
        note(i, f"plunges and retracts run at the plunge feed "
                               f"({links.plunge_feed:g} mm/min), this one at {feed_mm_min[i]:g} mm/min")
    pf = limits.plunge_feed_mm_per_min
    if pf is not None:
        i = _first(feedmove & (feed_mm_min > pf * (1 + 1e-6) + 1e-9))
        if i is not None:
            note(i, f"a plunge or retract at {feed_mm_min[i]:g} mm/min, over the {pf:g} mm/min "
                    f"of {limits.plunge_source} (it enters the stock with the cutting edge; "
                    f"process.plunge_feed_mm_per_min)")
    for a, (lo, hi_) in limits.travel.items():
        if a in blocks.axes:
            v = blocks.axes[a]
            i = _first((v < lo - _ROUND) | (v > hi_ + _ROUND))
            if i is not None:
                note(i, f"{a} {v[i]:.6f} mm outside the travel [{lo:g}, {hi_:g}] mm "
                                       f"of {limits.source}")
    if blocks.dialect == "turning":
        _turning_velocities(blocks, limits, scan["speeds"], note)
    else:
        _velocities(blocks, x, y, z, feed_mm_min, limits, what, note)
    # 6. every rapid against the design itself, along the move
    gap = _rapids_above_design(blocks, part, rapid, note)
    if problems:
        i, _, text = min(problems)
        _fail(what, blocks, i, text)
    rz = scan["rapid_lowest"]
    return {"blocks": int(n), "rapids": scan["rapids"], "plunges": scan["plunges"],
            "retracts": scan["retracts"], "cuts": scan["cuts"],
            "clearance_z_mm": zc, "part_top_mm": top, "clearance_above_part_mm": zc - top,
            "rapids_above_part_min_mm": float(rz - top) if rz is not None else None,
            "rapids_above_design_min_mm": gap,
            "cut_below_design_max_nm": max(below_max, 0.0) * MM_TO_NM if check_cuts else None,
            "max_feed_mm_per_min": float(np.nanmax(feed_mm_min[fm])) if fm.any() else 0.0,
            "plunge_feed_mm_per_min": float(links.plunge_feed)}


def compare_with_plan(blocks: Blocks, points: np.ndarray, planned: dict, *,
                      what: str = "toolpath.nc",
                      tolerance: float = _ROUND) -> dict:
    """Check that the cutting points of a written program (the blocks ``points``, in
    order) are the planned program's (``planned``: axis -> array, C in deg), each axis to
    ``tolerance`` plus the written places' rounding; returns ``{"points", "max_deviation"}``
    (largest difference of any axis, mm or deg).  A failure names the block."""
    points = np.asarray(points, dtype=np.int64)
    n = len(next(iter(planned.values())))
    if points.size != n:
        raise InputError(f"{what}: the program has {points.size} cutting points, the plan "
                         f"{n}: the written program is not the planned one")
    worst = 0.0
    for a, v in planned.items():
        d = np.abs(blocks.axes[a][points] - np.asarray(v, dtype=np.float64))
        bad = np.flatnonzero(~(d <= 0.501 * tolerance))  # half a place, and float error
        if bad.size:
            i = int(points[bad[0]])
            _fail(what, blocks, i, f"{a} {blocks.axes[a][i]:.6f} differs from the planned "
                                   f"{float(v[bad[0]]):.6f} (point {int(bad[0])} of the plan): "
                                   f"the written program is not the planned one")
        worst = max(worst, float(d.max()) if d.size else 0.0)
    return {"points": int(n), "max_deviation": worst}


def _feeds(blocks: Blocks, x, y, z, what: str) -> np.ndarray:
    """Feed of each ``G01`` block along the tool tip's straight move, mm/min (NaN for
    rapids); refuses a feed block without a positive ``F``."""
    n = blocks.count
    fm = blocks.motion == 1
    if blocks.dialect == "linear":
        f = blocks.feed.copy()
        feed = np.full(n, np.nan)
        last = np.nan
        for i in np.flatnonzero(~np.isnan(f) | fm):  # F is modal in G94
            if np.isnan(f[i]):
                f[i] = last
            last = f[i]
        bad = fm & ~(f > 0)
        i = _first(bad)
        if i is not None:
            _fail(what, blocks, i, f"a feed move needs F > 0 mm/min, received {f[i]!r}")
        feed[fm] = f[fm]
        return feed
    f = blocks.feed
    bad = fm & ~(f > 0)
    i = _first(bad[1:])
    if i is not None:
        _fail(what, blocks, i + 1, f"a feed move needs an inverse-time F > 0 (G93), received "
                                   f"{f[i + 1]!r}")
    # length of the axes' move (X, Z; C is a rotation) over its duration 1/F min
    ax = blocks.axes
    dist = np.empty(n)
    dist[:1] = 0.0
    np.hypot(np.diff(ax["X"]), np.diff(ax["Z"]), out=dist[1:])
    dist *= f
    return np.where(fm, dist, np.nan)


def _velocities(blocks: Blocks, x, y, z, feed_mm_min, limits: MachineLimits, what: str, note):
    n = blocks.count
    fm = np.r_[False, blocks.motion[1:] == 1]
    length = np.r_[0.0, np.sqrt(np.diff(x) ** 2 + np.diff(y) ** 2 + np.diff(z) ** 2)]
    dt = np.full(n, np.nan)
    ok = fm & (length > 0)
    dt[ok] = length[ok] / (feed_mm_min[ok] / MIN_TO_S)
    moves = {a: np.maximum(np.abs(np.r_[0.0, np.diff(blocks.axes[a])]) - 2 * _ROUND, 0.0)
             for a in ("X", "Y", "Z")}
    for a, vmax in limits.velocity_mm_s.items():
        if vmax is None or a not in moves:
            continue
        with np.errstate(invalid="ignore", divide="ignore"):
            v = np.where(fm & (dt > 0), moves[a] / dt, 0.0)
        i = _first(v > vmax * (1 + 1e-6))
        if i is not None:
            note(i, f"the {a} axis moves at {v[i]:.6g} mm/s, over the {vmax:g} mm/s "
                                   f"of {limits.source}")


def _turning_velocities(blocks: Blocks, limits: MachineLimits, first: dict, note):
    """The spindle speed and the X and Z velocities of a turning program (inverse-time
    feeds: a block lasts 1/F min) against ``limits``: ``first``, where each first
    exceeds its limit (:func:`~render_inspect.toolpath._verify_scan.scan_blocks`); each
    axis's move is less the rounding of the written places at either end."""
    ax = blocks.axes

    def move(a, i):
        return np.maximum(np.abs(ax[a][i] - ax[a][i - 1]) - 2 * _ROUND, 0.0)

    i = first["C"]
    if i is not None:
        rpm = np.radians(move("C", i)) / (2 * math.pi) / (MIN_TO_S / blocks.feed[i]) * MIN_TO_S
        note(i, f"the C axis turns at {rpm:.6g} rev/min, over the "
                f"{limits.spindle_rpm:g} rev/min of {limits.source}")
    for a, vmax in limits.velocity_mm_s.items():
        i = first.get(a) if vmax is not None else None
        if i is not None:
            v = move(a, i) / (MIN_TO_S / blocks.feed[i])
            note(i, f"the {a} axis moves at {v:.6g} mm/s, over the {vmax:g} mm/s "
                    f"of {limits.source}")


#: longest piece of a rapid checked against the design at a time, mm
_RAPID_PIECE = 0.005
#: pieces of all rapids checked at most (longer rapids are cut into fewer, longer pieces)
_RAPID_PIECES = 1 << 21


def _rapids_above_design(blocks: Blocks, part: PartModel, rapid, note) -> float | None:
    """The least height of any rapid above the design (stock included) along its whole
    move, mm; notes the first rapid that comes within :data:`MIN_CLEARANCE` of it.

    Each rapid is cut into pieces no longer than :data:`_RAPID_PIECE`; the design under a
    piece (its box widened by the tool's half width) is bounded by ``part.bound`` where
    the design has one, else sampled at the piece's ends and middle.  A turning rapid
    moves C and X together: its pieces follow the arc."""
    idx = np.flatnonzero(rapid)
    idx = idx[idx > 0]
    if not idx.size:
        return None
    ax = blocks.axes
    turning = blocks.dialect == "turning"
    moves: list[float] = []
    for i in idx:
        if turning:
            r = max(abs(ax["X"][i - 1]), abs(ax["X"][i]))
            arc = abs(math.radians(ax["C"][i] - ax["C"][i - 1])) * r
            moves.append(abs(ax["X"][i] - ax["X"][i - 1]) + arc)
        else:
            moves.append(math.hypot(ax["X"][i] - ax["X"][i - 1], ax["Y"][i] - ax["Y"][i - 1]))
    lengths = np.nan_to_num(np.asarray(moves, dtype=np.float64), nan=0.0)
    piece = max(_RAPID_PIECE, float(lengths.sum()) / _RAPID_PIECES)
    worst, worst_i = math.inf, None
    hw = float(part.half_width)
    for i, length in zip(idx, lengths):
        n = int(math.ceil(length / piece)) if length > 0 else 0
        t = np.linspace(0.0, 1.0, 2 * n + 1) if n else np.zeros(1)

        def at(name, tt, i=i):
            return ax[name][i - 1] + (ax[name][i] - ax[name][i - 1]) * tt
        z = at("Z", t)
        if turning:
            c = np.radians(at("C", t))
            xs, ys = at("X", t) * np.cos(c), at("X", t) * np.sin(c)
        else:
            xs, ys = at("X", t), at("Y", t)
        lowest = np.minimum(z[:-1:2], z[2::2]) if n else z
        if part.bound is not None and n:
            # each piece: its ends and middle; its box widened by the tool's half width
            # and by the piece's sagitta (a turning piece is an arc)
            pad = hw + piece
            px = np.stack([xs[:-1:2], xs[1::2], xs[2::2]])
            py = np.stack([ys[:-1:2], ys[1::2], ys[2::2]])
            inside = _inside(part.outline, px, py, hw + piece).any(axis=0)
            if not inside.any():
                continue
            hi = np.asarray(part.bound(px.min(0)[inside] - pad, py.min(0)[inside] - pad,
                                       px.max(0)[inside] + pad, py.max(0)[inside] + pad),
                            dtype=np.float64)
            g = lowest[inside] - (hi + part.stock)
        else:
            inside = _inside(part.outline, xs, ys, hw)
            if not inside.any():
                continue
            try:
                with np.errstate(invalid="ignore"):
                    h = np.asarray(part.height(xs[inside], ys[inside]), dtype=np.float64)
            except InputError:
                continue
            g = z[inside] - (np.where(np.isfinite(h), h, -np.inf) + part.stock)
        if g.size and float(g.min()) < worst:
            worst, worst_i = float(g.min()), int(i)
    if worst_i is not None and worst < MIN_CLEARANCE - _ROUND:
        note(worst_i, f"the rapid passes {worst:.6g} mm above the design (stock included) at its "
                      f"lowest, within the {MIN_CLEARANCE} mm the clearance plane keeps: it could "
                      f"go through the part")
    return worst if math.isfinite(worst) else None
