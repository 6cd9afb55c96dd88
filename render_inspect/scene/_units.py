"""Unit mistakes a scene can carry although every key is within its range: a region typed
in micrometres, a feed per revolution typed as a feed per minute, a pixel too coarse for
the feed marks.  Each message names the key, the value received, the likely mistake and
the value probably meant.

:func:`unit_errors` returns the mistakes that cannot be meant (a region a thousand times
the part); the scene's validation refuses them.  :func:`unit_warnings` returns the ones
that may be meant (the command line prints them before the run)."""

from __future__ import annotations

from collections.abc import Sequence
import math
from typing import Protocol, cast

from ..core.units import MM_TO_UM, UM_TO_MM
from ..processes import SceneSections

__all__ = ["unit_errors", "unit_warnings", "part_extent", "SMALLEST_FEED_PER_REV_MM",
           "MARK_PIXELS_ALIAS", "MARK_PIXELS_RESOLVE"]

#: the finest feed per revolution diamond turning uses, mm (about 1-50 um/rev; the
#: shipped scenes of Li et al. 2018, the RCSE study and Kong et al. 2020 use 5-10 um)
SMALLEST_FEED_PER_REV_MM = 0.5 * UM_TO_MM
#: pixels per feed-mark period below which the marks alias in the simulated map
MARK_PIXELS_ALIAS = 2.0
#: pixels per period that resolve the marks' shape (the compare report's figure)
MARK_PIXELS_RESOLVE = 4.0
#: a region this many times the part's size, at least :data:`_REGION_MM` across, that lies
#: on the part when read as micrometres, was typed in micrometres
_REGION_FACTOR = 5.0
_REGION_MM = 50.0
#: samples per side of the region when its share off the part is counted
_OFF_PART_SAMPLES = 64
#: the largest part considered when the process does not state one, mm
_LARGEST_PART_MM = 1000.0  # not a unit conversion


def _fmt(v: float) -> str:
    return f"{v:.6g}"


class _Cells(Protocol):
    """A design of cells (a lenslet array): their count and pitch (mm)."""

    rows: int
    cols: int
    pitch_x: float
    pitch_y: float


def part_extent(scene: SceneSections) -> tuple[float, float, float, float] | None:
    """The part's bounding box ``(x0, y0, x1, y1)``, mm: the workpiece disc of a turning
    process (``process.workpiece_radius``), the cells of a lenslet array; None when the
    scene does not say."""
    r = getattr(scene.process, "workpiece_radius", None)
    if r is not None:
        return (-float(r), -float(r), float(r), float(r))
    d = scene.design
    if all(hasattr(d, k) for k in ("rows", "cols", "pitch_x", "pitch_y")):
        cx, cy = float(getattr(d, "center_x", 0.0)), float(getattr(d, "center_y", 0.0))
        cells = cast(_Cells, d)
        hx, hy = cells.cols * cells.pitch_x / 2, cells.rows * cells.pitch_y / 2
        return (cx - hx, cy - hy, cx + hx, cy + hy)
    return None


def _overlaps(a: Sequence[float], b: Sequence[float]) -> bool:
    return a[0] < b[2] and b[0] < a[2] and a[1] < b[3] and b[1] < a[3]


def unit_errors(scene: SceneSections) -> list[str]:
    """Unit mistakes that cannot be meant, as messages naming the key: a
    ``simulation.region`` more than :data:`_REGION_FACTOR` times the part and
    :data:`_REGION_MM` mm across (or than a metre when the part's size is not known) that,
    read as micrometres, lies on the part."""
    out = []
    region = tuple(float(v) for v in scene.simulation.region)
    side = max(region[2] - region[0], region[3] - region[1])
    part = part_extent(scene)
    as_mm = tuple(v * UM_TO_MM for v in region)
    if part is not None:
        size = max(part[2] - part[0], part[3] - part[1])
        too_big = side > max(_REGION_FACTOR * size, _REGION_MM) and _overlaps(as_mm, part)
        what = f"{side / size:.0f} times the part ({_fmt(size)} mm across)"
    else:
        too_big = side > _LARGEST_PART_MM
        what = f"more than the {_LARGEST_PART_MM:g} mm of any part"
    if too_big:
        out.append(f"simulation.region must be in mm: [{', '.join(_fmt(v) for v in region)}] is "
                   f"{_fmt(side)} mm across, {what}, and looks like micrometres; in mm it is "
                   f"[{', '.join(_fmt(v) for v in as_mm)}]")
    return out


def unit_warnings(scene: SceneSections, *, sampling: bool = True) -> list[str]:
    """Values that are probably unit mistakes, or that undo the simulation, as messages:

    * a turning feed per revolution (``process.feed_mm_per_min / process.spindle_rpm``)
      below :data:`SMALLEST_FEED_PER_REV_MM`: probably a feed per revolution typed as the
      feed per minute (the message gives the feed per minute it would mean);
    * (``sampling``) a ``simulation.pixel`` coarser than half the feed marks' period
      (the marks alias into a false pattern; the pixel that resolves them is named), with
      a hint when the pixel itself looks like micrometres.
    """
    out = []
    p = scene.process
    rpm = getattr(p, "spindle_rpm", None)
    feed = getattr(p, "feed_mm_per_min", None)
    if rpm and feed and getattr(p, "scallop_bound_nm", None) is None:
        per_rev = feed / rpm
        if per_rev < SMALLEST_FEED_PER_REV_MM:
            out.append(
                f"process.feed_mm_per_min = {_fmt(feed)} at process.spindle_rpm = {_fmt(rpm)} "
                f"is {_fmt(per_rev * MM_TO_UM)} um per revolution, finer than diamond "
                f"turning's usual 1-50 um: if {_fmt(feed)} is the feed per revolution (mm/rev), "
                f"set process.feed_mm_per_min = {_fmt(feed * rpm)} ({_fmt(feed)} mm/rev x "
                f"{_fmt(rpm)} rev/min)")
    if sampling and not out:  # (a feed in the wrong unit makes the marks wrong too)
        period = _mark_period(scene)
        px = float(scene.simulation.pixel)
        if period is not None and period > 0 and period / px < MARK_PIXELS_ALIAS:
            hint = ""
            if px >= 0.1 and px * UM_TO_MM <= period / MARK_PIXELS_RESOLVE:
                hint = (f"; if {_fmt(px)} is in micrometres, simulation.pixel = "
                        f"{_fmt(px * UM_TO_MM)}")
            out.append(
                f"simulation.pixel = {_fmt(px)} mm samples the {_fmt(period * MM_TO_UM)} um "
                f"feed marks with {period / px:.2g} pixels per period: below "
                f"{MARK_PIXELS_ALIAS:g} they alias into a false, coarser pattern; set "
                f"simulation.pixel <= {_fmt(period / MARK_PIXELS_RESOLVE)} mm "
                f"({MARK_PIXELS_RESOLVE:g} per period) to resolve them{hint}")
    if sampling:
        off = _off_the_part(scene)
        if off:
            out.append(off)
    return out


def _off_the_part(scene: SceneSections) -> str:
    """The message for a ``simulation.region`` that reaches beyond a turned part's radius
    (``process.workpiece_radius``): there the map holds the tool's flank or nothing, and
    the residual's statistics count it.  "" where the region lies on the part."""
    radius = getattr(scene.process, "workpiece_radius", None)
    region = getattr(scene.simulation, "region", None)
    if radius is None or region is None or len(region) != 4:
        return ""
    x0, y0, x1, y1 = (float(v) for v in region)
    reach = max(math.hypot(x, y) for x in (x0, x1) for y in (y0, y1))
    if reach <= radius:
        return ""
    n = _OFF_PART_SAMPLES
    xs = [x0 + (x1 - x0) * (i + 0.5) / n for i in range(n)]
    ys = [y0 + (y1 - y0) * (j + 0.5) / n for j in range(n)]
    off = sum(1 for x in xs for y in ys if math.hypot(x, y) > radius) / (n * n)
    if off == 0:
        return ""
    return (f"simulation.region reaches {_fmt(reach)} mm from the spindle axis, beyond "
            f"process.workpiece_radius = {_fmt(radius)} mm: {off:.1%} of the region lies off "
            f"the part, where the map holds the tool's flank or nothing, and the residual's "
            f"statistics count what is there; keep the region within the part's radius")


def _mark_period(scene: SceneSections) -> float | None:
    """The period of the feed marks a turning process leaves (its feed per revolution),
    mm, or None (no turning feed, or one the scallop bound plans)."""
    p = scene.process
    rpm = getattr(p, "spindle_rpm", None)
    feed = getattr(p, "feed_mm_per_min", None)
    if rpm and feed and getattr(p, "scallop_bound_nm", None) is None:
        return feed / rpm
    return None
