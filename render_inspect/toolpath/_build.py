"""The turning path: spiral CCPs -> compensation -> :class:`ToolPath`."""

from __future__ import annotations

import math
import time

import numpy as np

from ..core.errors import AccessibilityError, InputError
from ..core.toolpath import ToolPath
from ._access import check_accessibility, describe_accessibility
from ._compensation import gouge_depth, normal_compensation, z_compensation
from ._spiral import TWO_PI, chordal_error, chordal_step_for, spiral_ccps
from ._tool import Tool

__all__ = ["plan_turning", "region_radii", "max_curvature"]


def region_radii(region, margin: float) -> tuple[float, float]:
    """Smallest and largest distance (mm) from the spindle axis to ``region``, widened by
    ``margin`` (clamped at 0)."""
    x0, y0, x1, y1 = region
    rmax = max(math.hypot(x, y) for x in (x0, x1) for y in (y0, y1))
    cx = min(max(0.0, x0), x1)
    cy = min(max(0.0, y0), y1)
    rmin = math.hypot(cx, cy)
    return max(rmin - margin, 0.0), rmax + margin


def max_curvature(surface, region, n: int = 129) -> float:
    """Largest |principal curvature| (1/mm) sampled over ``region``."""
    x0, y0, x1, y1 = region
    X, Y = np.meshgrid(np.linspace(x0, x1, n), np.linspace(y0, y1, n))
    hxx, hxy, hyy = surface.hessian(X, Y)
    tr = 0.5 * (hxx + hyy)
    disc = np.sqrt(np.maximum(0.25 * (hxx - hyy) ** 2 + hxy ** 2, 0.0))
    return float(np.nanmax(np.maximum(np.abs(tr + disc), np.abs(tr - disc))))


def plan_turning(surface, tool: Tool, *, workpiece_radius: float, feed_per_rev: float,
                 spindle_rpm: float, compensation: str = "z", sampling: str = "constant_angle",
                 points_per_rev: int = 3600, arc_length: float = 0.005,
                 switch_radius: float = 1.0, inner_radius: float = 0.0,
                 chordal_tolerance: float | None = None, region=None,
                 check_access: bool = True, allow_gouge: bool = False) -> ToolPath:
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
        mm; bound on the linearisation error (seed 001): the CCP spacing is shortened to
        L = sqrt(8 R' h - 4 h^2) for the smallest radius of curvature R' of the region.
    region : (x0, y0, x1, y1), optional
        Only the revolutions whose tool arcs can reach ``region`` are generated (the spiral
        keeps the phase of the full path from ``workpiece_radius``).
    check_access : bool
        Run the accessibility check over ``region`` (or the whole blank) and raise
        :class:`AccessibilityError` unless ``allow_gouge``.

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
    # passes farther than 2 Rc m + f from a pixel never form the envelope there
    # (machining/_envelope.py); keep two more revolutions as margin
    margin = min(tool.half_width, 2.2 * tool.nose_radius * slope + f) + 2 * f
    r_in, r_out = region_radii(area, margin) if region is not None else (0.0, Rw)
    r_in = max(r_in, inner_radius)
    r_out = min(r_out, Rw)
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

    x, y = rho * np.cos(theta), rho * np.sin(theta)
    z_ccp = surface.height(x, y)
    meta["max_slope"] = slope
    comp = compensation
    if comp == "none":
        rho_tip, z_tip = rho, z_ccp.copy()
    elif comp == "z":
        rho_tip = rho
        z_tip = z_compensation(surface, theta, rho, tool.nose_radius, max_slope=slope,
                               half_width=tool.half_width)
    elif comp == "normal":
        rho_tip, z_tip = normal_compensation(surface, theta, rho, tool.nose_radius)
    else:
        raise InputError(f"compensation must be 'none', 'normal' or 'z', received {comp!r}")

    ce = chordal_error(surface, theta, rho, z_ccp)
    meta["chordal_error_max_mm"] = float(ce.max()) if ce.size else 0.0
    if chordal_tolerance is not None:
        meta["chordal_tolerance_mm"] = chordal_tolerance
        meta["chordal_within_tolerance"] = bool(meta["chordal_error_max_mm"] <= chordal_tolerance * 1.0001)

    # gouge check: how far each programmed position would cut below the design section
    if comp == "z":
        meta["gouge_max_mm"] = 0.0
    else:
        g = gouge_depth(surface, theta, rho_tip, z_tip, tool.nose_radius, max_slope=slope,
                        half_width=tool.half_width)
        k = int(np.argmax(g))
        meta["gouge_max_mm"] = float(g[k])
        meta["gouge_worst_at_mm"] = [float(rho_tip[k] * np.cos(theta[k])), float(rho_tip[k] * np.sin(theta[k]))]
    omega = TWO_PI * spindle_rpm / 60.0
    t = theta / omega
    meta["time_s"] = float(t[-1] - t[0]) if t.size else 0.0
    meta["build_s"] = time.perf_counter() - t0
    return ToolPath(theta, np.asarray(rho_tip, dtype=np.float64), np.asarray(z_tip, dtype=np.float64),
                    t, meta, ccp_rho=rho, ccp_z=z_ccp)
