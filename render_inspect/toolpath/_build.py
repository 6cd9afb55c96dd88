"""The turning path: spiral CCPs -> compensation -> :class:`ToolPath`."""

from __future__ import annotations

from typing import Any, Literal, overload
from collections.abc import Sequence
import math
import time

import numpy as np

from ..core import trig
from ..core.errors import AccessibilityError, InputError
from ..core.limits import Driver, check_memory, format_number
from ..core.toolpath import ToolPath
from ..core.units import MIB_TO_BYTES, MIN_TO_S
from ._access import check_accessibility, describe_accessibility
from ._compensation import gouge_depth, normal_compensation, z_compensation
from ._spiral import TWO_PI, chordal_error, chordal_step_for, heights_along, spiral_ccps
from ._tool import Tool, pass_margin

__all__ = ["plan_turning", "region_radii", "max_curvature", "turning_point_count",
           "plan_memory", "PLAN_BYTES_PER_POINT", "PLAN_FIXED_BYTES", "sector_angles",
           "sector_plan", "SECTOR_FILL_PER_REV"]

#: Bytes per tool-path point at the peak of planning (the path arrays, compensation and
#: chordal-error temporaries, the kinematics), by compensation, measured with tracemalloc
#: on paths of 0.35 to 1.1 million points of every sampling (tests/test_limits.py: 66-97
#: with Z or no compensation, 170-193 with normal compensation).
PLAN_BYTES_PER_POINT = {"z": 104, "none": 104, "normal": 200, "edge": 104}
#: Bytes planning holds whatever the path's length (curvature and accessibility grids).
PLAN_FIXED_BYTES = 16 * MIB_TO_BYTES


@overload
def turning_point_count(*, sampling: str, feed_per_rev: float, workpiece_radius: float,
                        r_in: float, r_out: float, inner_radius: float = 0.0,
                        points_per_rev: int = 3600, arc_length: float = 0.005,
                        switch_radius: float = 1.0, parts: Literal[False] = False) -> float: ...


@overload
def turning_point_count(*, sampling: str, feed_per_rev: float, workpiece_radius: float,
                        r_in: float, r_out: float, inner_radius: float = 0.0,
                        points_per_rev: int = 3600, arc_length: float = 0.005,
                        switch_radius: float = 1.0, parts: Literal[True]) -> tuple[float, float]: ...


def turning_point_count(*, sampling: str, feed_per_rev: float, workpiece_radius: float,
                        r_in: float, r_out: float, inner_radius: float = 0.0,
                        points_per_rev: int = 3600, arc_length: float = 0.005,
                        switch_radius: float = 1.0, parts: bool = False
                        ) -> float | tuple[float, float]:
    """Number of spiral points :func:`plan_turning` allocates (a float: it may be far
    beyond any array), computed from the parameters alone.

    Constant angle: the revolutions between ``r_in`` and ``r_out`` times
    ``points_per_rev``.  Arc-length and hybrid sampling build the spiral from
    ``workpiece_radius`` to ``inner_radius`` first: its arc length over ``arc_length``
    (plus at most 8 points per revolution near the axis), and the inner constant-angle
    part of a hybrid spiral.  ``parts``: return (arc-length points, constant-angle
    points) instead of their sum.
    """
    f = float(feed_per_rev)
    c = f / TWO_PI
    N = float(points_per_rev)
    if sampling == "constant_angle":
        n = max(r_out - r_in, 0.0) / f * N + 2.0
        return (0.0, n) if parts else n
    Rw, r_inner = float(workpiece_radius), float(inner_radius)
    r_sw = r_inner if sampling == "constant_arc" else min(max(switch_radius, r_inner), Rw)
    theta_sw = (Rw - r_sw) / c
    s_total = Rw * theta_sw - c * theta_sw ** 2 / 2  # arc length of the outer part
    n = s_total / float(arc_length) + 2.0
    n += 8.0 * min((Rw - r_sw) / f, 8.0 * float(arc_length) / TWO_PI / f + 1.0)
    n_angle = max(r_sw - r_inner, 0.0) / f * N if sampling != "constant_arc" else 0.0
    return (n, n_angle) if parts else n + n_angle


def plan_memory(n_points: float | tuple[float, float], *, sampling: str = "constant_angle",
                compensation: str = "z") -> float:
    """Bytes :func:`plan_turning` (and the kinematics after it) holds at its peak for a
    path of ``n_points`` points, or of (arc-length points, constant-angle points)
    (:func:`turning_point_count` with ``parts=True``)."""
    n = sum(n_points) if isinstance(n_points, tuple) else float(n_points)
    return PLAN_FIXED_BYTES + n * PLAN_BYTES_PER_POINT.get(compensation, PLAN_BYTES_PER_POINT["normal"])


def region_radii(region: Sequence[float], margin: float) -> tuple[float, float]:
    """Smallest and largest distance (mm) from the spindle axis to ``region``, widened by
    ``margin`` (clamped at 0)."""
    x0, y0, x1, y1 = region
    rmax = max(math.hypot(x, y) for x in (x0, x1) for y in (y0, y1))
    cx = min(max(0.0, x0), x1)
    cy = min(max(0.0, y0), y1)
    rmin = math.hypot(cx, cy)
    return max(rmin - margin, 0.0), rmax + margin


#: points per revolution kept outside the sectors of a windowed plan (:func:`sector_plan`)
SECTOR_FILL_PER_REV = 64


def sector_angles(region: Sequence[float], margin: float) -> tuple[float, float] | None:
    """The polar angles (rad, a0 <= a1 < a0 + pi) that ``region`` widened by ``margin`` (mm)
    spans seen from the spindle axis; None when the widened region holds the axis (every
    angle reaches it)."""
    x0, y0, x1, y1 = region
    x0, y0, x1, y1 = x0 - margin, y0 - margin, x1 + margin, y1 + margin
    if x0 <= 0 <= x1 and y0 <= 0 <= y1:
        return None
    c = math.atan2(0.5 * (y0 + y1), 0.5 * (x0 + x1))
    d = [math.remainder(math.atan2(y, x) - c, TWO_PI) for x in (x0, x1) for y in (y0, y1)]
    return c + min(d), c + max(d)


def sector_plan(theta: np.ndarray, region: Sequence[float], margin: float, *, lead_rad: float,
                lag_rad: float, fill_per_rev: int = SECTOR_FILL_PER_REV
                ) -> tuple[np.ndarray | None, dict]:
    """Which points of a whole-revolution spiral (cumulative angles ``theta``) a plan of
    ``region`` keeps: every point whose angle lies in the sector the region (widened by
    ``margin``) spans, from ``lead_rad`` before it to ``lag_rad`` after it and four of the
    largest angular steps more on each side; elsewhere the first point at or after each
    multiple of 2 pi / ``fill_per_rev``; the first and the last point.  Returns (mask,
    facts), or (None, facts) when the sectors would keep more than 3/4 of the points (or
    the region holds the axis): then whole revolutions are planned."""
    ang = sector_angles(region, margin)
    if ang is None or theta.size < 8:
        return None, {}
    step = float(np.max(np.diff(theta)))
    a0 = ang[0] - lead_rad - 4 * step
    span = (ang[1] - ang[0]) + lead_rad + lag_rad + 8 * step
    if span >= 0.75 * TWO_PI:
        return None, {}
    keep = np.mod(theta - a0, TWO_PI) <= span
    grid = np.arange(math.ceil(theta[0] * fill_per_rev / TWO_PI),
                     math.floor(theta[-1] * fill_per_rev / TWO_PI) + 1) * (TWO_PI / fill_per_rev)
    keep[np.minimum(np.searchsorted(theta, grid), theta.size - 1)] = True
    keep[0] = keep[-1] = True
    if keep.sum() > 0.75 * keep.size:
        return None, {}
    return keep, {"sector_rad": [float(ang[0]), float(ang[1])], "full_rad": [a0, span],
                  "points_kept": int(keep.sum())}


def max_curvature(surface: Any, region: Sequence[float], n: int = 129) -> float:
    """Largest |principal curvature| (1/mm) sampled over ``region``."""
    x0, y0, x1, y1 = region
    X, Y = np.meshgrid(np.linspace(x0, x1, n), np.linspace(y0, y1, n))
    hxx, hxy, hyy = surface.hessian(X, Y)
    tr = 0.5 * (hxx + hyy)
    disc = np.sqrt(np.maximum(0.25 * (hxx - hyy) ** 2 + hxy ** 2, 0.0))
    return float(np.nanmax(np.maximum(np.abs(tr + disc), np.abs(tr - disc))))


def plan_turning(surface: Any, tool: Tool, *, workpiece_radius: float, feed_per_rev: float,
                 spindle_rpm: float, compensation: str = "z", sampling: str = "constant_angle",
                 points_per_rev: int = 3600, arc_length: float = 0.005,
                 switch_radius: float = 1.0, inner_radius: float = 0.0,
                 chordal_tolerance: float | None = None, region: Sequence[float] | None = None,
                 check_access: bool = True, allow_gouge: bool = False,
                 memory_budget: int | tuple[int, str] | None = None,
                 sectors: tuple[float, float] | None = None) -> ToolPath:
    """The inward spiral turning path over ``surface`` with its tool-radius compensation.

    Parameters
    ----------
    surface : Surface
        The design.
    tool : Tool
    workpiece_radius : float
        Rw, mm: the spiral starts there at theta = 0.
    feed_per_rev : float
        mm per revolution (feed / spindle speed).
    spindle_rpm : float
        Sets the time of each point, t = theta / omega.
    compensation : {"none", "normal", "z"}
        See :mod:`render_inspect.toolpath._compensation`.
    sampling, points_per_rev, arc_length, switch_radius :
        See :func:`spiral_ccps`.
    inner_radius : float
        mm; the spiral stops there.
    chordal_tolerance : float, optional
        mm; bound on the linearisation error (the compound sinusoidal grid paper): the CCP
        spacing is shortened to L = sqrt(8 R' h - 4 h^2) for the smallest radius of
        curvature R' of the region.
    region : (x0, y0, x1, y1), optional
        Only the revolutions whose tool arcs can reach ``region`` are generated (the spiral
        keeps the phase of the full path from ``workpiece_radius``).
    check_access : bool
        Run the accessibility check over ``region`` (or the whole blank) and raise
        :class:`AccessibilityError` unless ``allow_gouge``.
    memory_budget : (bytes, source) or int, optional
        The path's size (:func:`turning_point_count`, :func:`plan_memory`) is checked
        against it before any array is allocated, after ``chordal_tolerance`` has set the
        sampling (:func:`~render_inspect.core.limits.check_memory`; default: the automatic
        budget).  The error names the parameter to change and how far.
    sectors : (lead_s, lag_s), optional
        With ``region``: plan each revolution in full only over the angular sector that
        reaches the region (widened by the tool's footprint, ``lead_s`` seconds of spindle
        turn before it and ``lag_s`` after it, and a few points each side for the
        interpolation); elsewhere keep :data:`SECTOR_FILL_PER_REV` points a revolution,
        so that the program stays one continuous spiral in time
        (:func:`sector_plan`).  Every point kept is the whole-revolution plan's point, bit
        for bit.  None: whole revolutions.

    Returns
    -------
    ToolPath
        Tool-tip program; ``meta`` holds the path facts (sampling, chordal error, gouge
        depth, accessibility, cut time).
    """
    t0 = time.perf_counter()
    Rw = float(workpiece_radius)
    f = float(feed_per_rev)
    c = f / TWO_PI
    blank = (-Rw, -Rw, Rw, Rw)
    area = tuple(region) if region is not None else blank
    slope = surface.max_slope(area)
    margin = pass_margin(tool, slope, f)
    r_in, r_out = region_radii(area, margin) if region is not None else (0.0, Rw)
    reach = (r_in, r_out)
    r_in = max(r_in, inner_radius)
    r_out = min(r_out, Rw)
    if r_out - r_in < f:
        x0, y0, x1, y1 = area
        raise InputError(
            f"simulation.region {[x0, y0, x1, y1]} mm lies outside the turned part: the tool "
            f"reaches it only between {reach[0]:.6g} and {reach[1]:.6g} mm from the spindle axis, but "
            f"the spiral runs from process.workpiece_radius = {Rw:g} mm in to "
            f"process.inner_radius = {inner_radius:g} mm; move the region or change those radii")
    meta: dict = {"sampling": sampling, "compensation": compensation,
                  "feed_per_rev_mm": f, "nose_radius_mm": tool.nose_radius,
                  "spindle_rpm": spindle_rpm, "workpiece_radius_mm": Rw,
                  "r_range_mm": [r_in, r_out]}

    if check_access:
        access = check_accessibility(surface, tool, area)
        meta["accessibility"] = access
        if not access["ok"] and not allow_gouge:
            raise AccessibilityError(
                "the tool cannot reach the design: " + describe_accessibility(access)
                + ". Use a smaller tool.nose_radius / larger angles, or set "
                  "process.allow_gouge = true to simulate the gouging anyway.")

    N = int(points_per_rev)
    ds = float(arc_length)
    if chordal_tolerance is not None:
        kmax = max_curvature(surface, area)
        L = chordal_step_for(chordal_tolerance, 1.0 / kmax if kmax > 0 else math.inf)
        meta["chordal_step_bound_mm"] = L
        if math.isfinite(L):
            ds = min(ds, L)
            r_ref = r_out if sampling == "constant_angle" else min(switch_radius, r_out)
            N = max(N, int(math.ceil(TWO_PI * max(r_ref, 1e-9) / L)))
    meta["points_per_rev"] = N
    meta["arc_length_mm"] = ds
    n_parts = turning_point_count(sampling=sampling, feed_per_rev=f, workpiece_radius=Rw,
                                  r_in=r_in, r_out=r_out, inner_radius=inner_radius,
                                  points_per_rev=N, arc_length=ds, switch_radius=switch_radius,
                                  parts=True)
    n_est = sum(n_parts)
    raised = chordal_tolerance is not None and (N > int(points_per_rev) or ds < float(arc_length))
    drivers = []
    if raised:
        drivers.append(Driver("process.chordal_tolerance", chordal_tolerance, -0.5, "mm"))
    else:
        if sampling != "constant_arc":
            drivers.append(Driver("process.points_per_rev", points_per_rev, 1, limit=(8, 1e7)))
        if sampling != "constant_angle":
            drivers.append(Driver("process.arc_length", arc_length, -1, "mm"))
    drivers.append(Driver("the feed per revolution (process.feed_mm_per_min / "
                          "process.spindle_rpm)", f, -1, "mm/rev", limit=(None, tool.nose_radius)))
    why = (f"; process.chordal_tolerance = {format_number(chordal_tolerance)} mm sets "
           f"{format_number(N)} points per revolution" if raised else "")
    check_memory(plan_memory(n_parts, sampling=sampling, compensation=compensation),
                 what=f"the tool path ({format_number(n_est)} points, "
                      f"{format_number((r_out - r_in) / f)} revolutions{why})",
                 budget=memory_budget, drivers=drivers,
                 hint="or plan a smaller part of it (simulation.region, process.workpiece_radius)")

    if sampling == "constant_angle":
        dth = TWO_PI / N
        i0 = int(math.floor((Rw - r_out) / c / dth))
        i1 = int(math.ceil((Rw - r_in) / c / dth))
        theta = np.arange(i0, i1 + 1, dtype=np.float64) * dth
        rho = np.maximum(Rw - c * theta, 0.0)
    else:
        theta, rho = spiral_ccps(feed_per_rev=f, r_outer=Rw, r_inner=inner_radius,
                                 sampling=sampling, points_per_rev=N, arc_length=ds,
                                 switch_radius=switch_radius)
        keep = (rho >= r_in - f) & (rho <= r_out + f)
        idx = np.flatnonzero(keep)
        theta, rho = theta[idx[0]:idx[-1] + 1], rho[idx[0]:idx[-1] + 1]

    full = None
    # the normal compensation moves X off the spiral: the sparse points between the
    # sectors would change the X command, which the machine follows
    if sectors is not None and region is not None and compensation != "normal":
        omega = TWO_PI * spindle_rpm / MIN_TO_S
        kept, info = sector_plan(theta, area, margin, lead_rad=float(sectors[0]) * omega,
                                 lag_rad=float(sectors[1]) * omega)
        if kept is not None:
            idx = np.flatnonzero(kept)
            full = np.zeros(idx.size, dtype=bool)
            full[:-1] = np.diff(idx) == 1
            theta, rho = theta[idx], rho[idx]
            meta["sectors"] = {**info, "lead_s": float(sectors[0]), "lag_s": float(sectors[1]),
                               "points_whole_revolutions": int(kept.size)}

    cs, sn = trig.cos_sin(theta)
    z_ccp = heights_along(surface, rho, cs, sn)
    meta["max_slope"] = slope
    comp = compensation
    if comp == "none":
        rho_tip, z_tip = rho, z_ccp.copy()
    elif comp == "z":
        rho_tip = rho
        z_tip = z_compensation(surface, theta, rho, tool.nose_radius, max_slope=slope,
                               half_width=tool.half_width, ccp_height=z_ccp,
                               cos_sin=(cs, sn))
    elif comp == "normal":
        rho_tip, z_tip = normal_compensation(surface, theta, rho, tool.nose_radius)
    elif comp == "edge":
        if tool.edge is None:
            raise InputError("process.compensation = 'edge' plans the path against the measured "
                             "cutting edge: set tool.edge_profile or tool.waviness")
        rho_tip = rho
        z_tip = z_compensation(surface, theta, rho, tool.nose_radius, max_slope=slope,
                               half_width=tool.half_width, edge=tool.edge, ccp_height=z_ccp,
                               cos_sin=(cs, sn))
    else:
        raise InputError(f"compensation must be 'none', 'normal', 'z' or 'edge', received {comp!r}")

    ce = chordal_error(surface, theta, rho, z_ccp)
    if full is not None:  # the sectors' own segments (not the chords that join them)
        ce = ce[full[:-1]]
    meta["chordal_error_max_mm"] = float(ce.max()) if ce.size else 0.0
    if chordal_tolerance is not None:
        meta["chordal_tolerance_mm"] = chordal_tolerance
        meta["chordal_within_tolerance"] = bool(meta["chordal_error_max_mm"] <= chordal_tolerance * 1.0001)

    # gouge check: how far each programmed position would cut below the design section
    if comp in ("z", "edge"):
        meta["gouge_max_mm"] = 0.0
    else:
        g = gouge_depth(surface, theta, rho_tip, z_tip, tool.nose_radius, max_slope=slope,
                        half_width=tool.half_width)
        k = int(np.argmax(g))
        meta["gouge_max_mm"] = float(g[k])
        meta["gouge_worst_at_mm"] = [float(rho_tip[k] * np.cos(theta[k])), float(rho_tip[k] * np.sin(theta[k]))]
    omega = TWO_PI * spindle_rpm / MIN_TO_S  # rpm -> rad/s
    t = theta / omega
    meta["time_s"] = float(t[-1] - t[0]) if t.size else 0.0
    meta["build_s"] = time.perf_counter() - t0
    return ToolPath(theta, np.asarray(rho_tip, dtype=np.float64), np.asarray(z_tip, dtype=np.float64),
                    t, meta, ccp_rho=rho, ccp_z=z_ccp)
