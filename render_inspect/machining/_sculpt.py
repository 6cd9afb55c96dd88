"""Vibration-assisted diamond sculpturing (HFUVAS, seed 003) of a quadrilateral lenslet array.

Linear X-Y-Z cutting, not turning.  The tool moves along target lines x = x_k (the
lenslets' symmetry lines, one per column of cells) in the cutting direction y.  Its round
edge (radius R, in the x-z plane, rake 0) is swept along the line; the machined surface is
the lower envelope of every position the edge passes through.

Kinematics (seed 003 eq. 2-9)::

    u(t) = y_start + v_c t                      nominal position along the line
    y(t) = u(t) + A cos(2 pi f t)               ultrasonic vibration along the cut
    z(t) = z_cmd(u(t))                          Z follows the *nominal* position

``z_cmd`` is the target line sampled every ``step`` (the paper's 2.5 um) with a sample at
every sharp edge (segment cutting), linearly interpolated between samples.  The edge at
time t removes material below ``z(t) + R - sqrt(R^2 - (x - x_k)^2)`` in the plane y = y(t).

Two theoretical form errors come out of this geometry, without being put in:

* vibration overcut: a point y is passed by the edge carrying the Z commands of every
  nominal position in [y - A, y + A]; the cut keeps the lowest, so the overcut is about
  A |dz/dy| (largest at the sharp edges between lenslets; < 0.1 um for the paper's data);
* tool-edge overcut: the section of a lenslet across the cut has radius
  sqrt(r^2 - (y - y_c)^2) <= r = R, so a round edge of radius R cuts below it away from
  the line (largest at the four-lenslet cusp, 0.025 um for the paper's data).
"""

from __future__ import annotations

import math
import time

import numpy as np
from numba import njit

from ..errors import AccessibilityError, InputError, MemoryBudgetError, SceneError, check_range
from ._heightmap import HeightMap
from ._metrics import residual_metrics
from ._result import SimulationResult

__all__ = ["simulate_sculpt", "sculpt_line_profile", "sculpt_surface", "target_line",
           "lattice_lines", "vibration_phases", "sculpt_program"]


@njit(cache=True)
def _sweep_segment(ya, za, yb, zb, y0, dy, out):  # pragma: no cover - numba
    """Lower the rows between ya and yb to the straight edge-tip segment (ya, za)-(yb, zb)."""
    ny = out.shape[0]
    if yb < ya:
        ya, yb, za, zb = yb, ya, zb, za
    ja = int(math.ceil((ya - y0) / dy - 1e-9))
    jb = int(math.floor((yb - y0) / dy + 1e-9))
    if ja < 0:
        ja = 0
    if jb > ny - 1:
        jb = ny - 1
    for j in range(ja, jb + 1):
        f = 0.0
        if yb > ya:
            f = (y0 + j * dy - ya) / (yb - ya)
            if f < 0.0:
                f = 0.0
            elif f > 1.0:
                f = 1.0
        zj = za + f * (zb - za)
        if zj < out[j]:
            out[j] = zj


@njit(cache=True)
def _sweep_line(ys, zs, t_start, vc, amp, freq, phases, y0, dy, out):  # pragma: no cover - numba
    """Lower envelope along one target line of the swept edge's lowest point.

    The tool tip is followed through a merged sequence of events: the command's
    breakpoints ``ys`` (at their own times) and, with vibration, the sample ``phases``
    (rad, sorted in [0, 2 pi)) of every vibration period counted from t = 0 (so a part of a
    line gives the same samples as the whole line).  Between consecutive events the tip
    moves on a straight segment; ``out[j]`` (row j at y0 + j dy) keeps the lowest z
    passing it.  The tool is at ``ys[0]`` at time ``t_start``."""
    m = ys.shape[0]
    y_start = ys[0]
    two_pi = 2.0 * math.pi
    vib = amp > 0.0 and freq > 0.0
    npha = phases.shape[0]
    # first vibration sample after t_start
    p = 0
    jph = 0
    t_vib = 1e300
    if vib:
        p = int(math.floor(t_start * freq))
        jph = 0
        t_vib = (p + phases[0] / two_pi) / freq
        while t_vib <= t_start:
            jph += 1
            if jph == npha:
                jph = 0
                p += 1
            t_vib = (p + phases[jph] / two_pi) / freq
    kb = 1                                   # next breakpoint
    y_prev = y_start + amp * math.cos(two_pi * freq * t_start)
    z_prev = zs[0]
    while True:
        t_bp = t_start + (ys[kb] - y_start) / vc
        if t_bp <= t_vib:
            t = t_bp
            z = zs[kb]
            is_bp = True
        else:
            t = t_vib
            u = y_start + vc * (t - t_start)
            w = (u - ys[kb - 1]) / (ys[kb] - ys[kb - 1])
            z = zs[kb - 1] + w * (zs[kb] - zs[kb - 1])
            is_bp = False
        y = (ys[kb] if is_bp else u) + amp * math.cos(two_pi * freq * t)
        _sweep_segment(y_prev, z_prev, y, z, y0, dy, out)
        y_prev = y
        z_prev = z
        if is_bp:
            if kb == m - 1:
                break
            kb += 1
        else:
            jph += 1
            if jph == npha:
                jph = 0
                p += 1
            t_vib = (p + phases[jph] / two_pi) / freq


def target_line(surface, x_line: float, edges, *, step: float):
    """Target line (seed 003 eq. 2): the design along x = ``x_line``, sampled every
    ``step`` mm inside each segment between consecutive ``edges`` (mm, increasing), with a
    sample on every edge (segment cutting keeps the sharp edges).

    Returns
    -------
    ys, zs : (m,) float64, mm
    """
    edges = np.asarray(edges, dtype=np.float64)
    if edges.ndim != 1 or edges.size < 2 or np.any(np.diff(edges) <= 0):
        raise InputError(f"edges must be >= 2 increasing positions (mm), received {edges!r}")
    check_range("step", step, 0.0, None, lo_open=True)
    parts = []
    for a, b in zip(edges[:-1], edges[1:]):
        n = max(1, int(math.ceil((b - a) / step - 1e-9)))
        parts.append(np.linspace(a, b, n + 1)[:-1])
    parts.append(edges[-1:])
    ys = np.concatenate(parts)
    zs = np.asarray(surface.height(np.full_like(ys, x_line), ys), dtype=np.float64)
    return ys, zs


def vibration_phases(cutting_speed: float, amplitude: float, frequency_hz: float,
                     samples_per_period: int = 16) -> np.ndarray:
    """Phases (rad, sorted in [0, 2 pi)) at which each vibration period is sampled:
    ``samples_per_period`` uniform phases plus the front- and back-cut limits, where the
    tool stops along the cut, y'(t) = v_c - 2 pi f A sin(2 pi f t) = 0 (seed 003 eq. 6), so
    the envelope's extreme points are exact.  Without reversal (v_c >= 2 pi f A) only the
    uniform phases."""
    ph = list(2 * math.pi * np.arange(samples_per_period) / samples_per_period)
    eps = cutting_speed / (2 * math.pi * frequency_hz * amplitude)
    if eps < 1:
        a = math.asin(eps)
        ph += [a, math.pi - a]
    return np.unique(np.mod(np.array(ph), 2 * math.pi))


def sculpt_line_profile(ys, zs, y_grid, *, cutting_speed: float, amplitude: float = 0.0,
                        frequency_hz: float = 0.0, samples_per_period: int = 16,
                        t_start: float = 0.0) -> np.ndarray:
    """Lowest tool-tip height reached above each y of ``y_grid`` along one target line.

    Parameters
    ----------
    ys, zs : (m,) arrays, mm
        Commanded target line (increasing ``ys``); Z follows it at the nominal position.
    y_grid : (ny,) array, mm
        Uniformly spaced row positions.
    cutting_speed : float
        v_c, mm/s (> 0).
    amplitude : float
        A, mm (>= 0): vibration along the cutting direction, y = v_c t + A cos(2 pi f t).
    frequency_hz : float
        f, Hz (>= 0); 0 or ``amplitude`` 0 means no vibration.
    samples_per_period : int
        Uniform time samples per vibration period (>= 4), plus the front- and back-cut
        limits (:func:`vibration_phases`).  Without vibration the tip moves straight
        between the command's breakpoints, which are the only samples needed.
    t_start : float
        Time (s) at which the tool is at ``ys[0]``: sets the vibration's phase, so a line
        cut in part gives the same result as the whole line.

    Returns
    -------
    (ny,) float64, mm; NaN where the tool never passes.
    """
    ys = np.ascontiguousarray(ys, dtype=np.float64)
    zs = np.ascontiguousarray(zs, dtype=np.float64)
    y_grid = np.asarray(y_grid, dtype=np.float64)
    if ys.size < 2 or ys.shape != zs.shape or np.any(np.diff(ys) <= 0):
        raise InputError("ys must hold >= 2 increasing positions and zs the same number of heights")
    check_range("cutting_speed", cutting_speed, 0.0, None, lo_open=True)
    check_range("amplitude", amplitude, 0.0, None)
    check_range("frequency_hz", frequency_hz, 0.0, None)
    check_range("samples_per_period", samples_per_period, 4, 10_000)
    dy = float(y_grid[1] - y_grid[0]) if y_grid.size > 1 else 1.0
    vib = amplitude > 0 and frequency_hz > 0
    phases = vibration_phases(cutting_speed, amplitude, frequency_hz, samples_per_period) if vib \
        else np.zeros(1)
    out = np.full(y_grid.size, np.inf)
    _sweep_line(ys, zs, float(t_start), float(cutting_speed), float(amplitude if vib else 0.0),
                float(frequency_hz if vib else 0.0), phases, float(y_grid[0]), dy, out)
    out[~np.isfinite(out)] = np.nan
    return out


def sculpt_surface(profiles, x_lines, x_grid, *, tool_radius: float,
                   half_width: float | None = None) -> np.ndarray:
    """Machined heights from the per-line profiles: the envelope over lines of the round
    edge, min_k [profile_k(y) + R - sqrt(R^2 - (x - x_k)^2)], |x - x_k| <= half_width.

    Parameters
    ----------
    profiles : (n_lines, ny) array, mm (from :func:`sculpt_line_profile`)
    x_lines : (n_lines,) array, mm
    x_grid : (nx,) array, mm
    tool_radius : float, mm
    half_width : float, optional
        Half-width of the edge arc in x (mm), R sin(included / 2); default R.

    Returns
    -------
    (ny, nx) float64, mm; NaN where no edge reaches.
    """
    R = float(check_range("tool_radius", tool_radius, 0.0, None, lo_open=True))
    hw = R if half_width is None else min(float(half_width), R)
    x_grid = np.asarray(x_grid, dtype=np.float64)
    profiles = np.asarray(profiles, dtype=np.float64)
    out = np.full((profiles.shape[1], x_grid.size), np.inf)
    for prof, xk in zip(profiles, np.asarray(x_lines, dtype=np.float64)):
        dx = x_grid - xk
        reach = np.abs(dx) <= hw + 1e-12
        if not reach.any():
            continue
        arc = R - np.sqrt(R * R - np.minimum(dx[reach] ** 2, R * R))
        cand = np.where(np.isnan(prof), np.inf, prof)[:, None] + arc[None, :]
        sub = out[:, reach]
        np.minimum(sub, cand, out=sub)
        out[:, reach] = sub
    out[~np.isfinite(out)] = np.nan
    return out


def lattice_lines(surface, design_cfg) -> tuple[np.ndarray, np.ndarray]:
    """Target-line positions x_k (the columns' symmetry lines) and the cell edges along y
    of a quadrilateral lenslet array: (x_lines, y_edges), mm."""
    if getattr(design_cfg, "type", None) != "lenslet_array":
        raise SceneError("process.kind = 'sculpt' needs design.type = 'lenslet_array' "
                         f"(cells = 'quad'), received design.type = {getattr(design_cfg, 'type', None)!r}")
    if getattr(design_cfg, "cells", "quad") != "quad":
        raise SceneError("process.kind = 'sculpt' needs design.cells = 'quad' (sharp-edged cells "
                         f"along the symmetry lines), received {design_cfg.cells!r}")
    centers = np.asarray([c[-2:] for c in surface.centers()], dtype=np.float64).reshape(-1, 2)
    xs = np.unique(np.round(centers[:, 0], 12))
    yc = np.unique(np.round(centers[:, 1], 12))
    py = float(design_cfg.pitch_y)
    edges = np.concatenate([[yc[0] - py / 2], 0.5 * (yc[1:] + yc[:-1]), [yc[-1] + py / 2]])
    return xs, edges


def sculpt_program(scene) -> dict:
    """The commanded sculpturing program of ``scene``: every target line of the array, in
    cutting order, without the vibration (the NC program the machine is given).

    Returns
    -------
    dict of (n,) float64 arrays
        ``x, y, z`` (mm, tool tip), ``t`` (s, nominal cutting time, lines end to end
        without the moves between them) and ``line`` (index of the target line).
    """
    from ..design import make_surface

    surface = make_surface(scene.design)
    x_lines, y_edges = lattice_lines(surface, scene.design)
    vc = scene.process.feed_mm_per_min / 60.0
    xs, ys_all, zs_all, ts, ks = [], [], [], [], []
    t0 = 0.0
    for k, xk in enumerate(x_lines):
        ys, zs = target_line(surface, xk, y_edges, step=scene.process.arc_length)
        xs.append(np.full(ys.size, xk))
        ys_all.append(ys)
        zs_all.append(zs)
        ts.append(t0 + (ys - ys[0]) / vc)
        ks.append(np.full(ys.size, k, dtype=np.float64))
        t0 = ts[-1][-1]
    return {"x": np.concatenate(xs), "y": np.concatenate(ys_all), "z": np.concatenate(zs_all),
            "t": np.concatenate(ts), "line": np.concatenate(ks)}


def simulate_sculpt(scene) -> SimulationResult:
    """Simulate HFUVAS sculpturing of the scene's quadrilateral lenslet array.

    Scene keys used: ``design`` (``lenslet_array``, ``cells = "quad"``); ``tool.nose_radius``
    (edge radius R), ``tool.included_angle_deg`` (edge half-width R sin(included / 2)),
    ``tool.clearance_angle_deg`` (must exceed the largest slope along the cut unless
    ``process.allow_gouge``); ``process.feed_mm_per_min`` (nominal cutting speed v_c);
    ``process.arc_length`` (target-line sampling, the paper's 2.5 um);
    ``artifacts.vibration.{frequency_hz, amplitude, samples_per_period}``;
    ``artifacts.burrs`` (see :mod:`render_inspect.machining._burrs`); ``simulation.{region,
    pixel, seed}``.

    Returns
    -------
    SimulationResult
        ``metrics["sculpt"]`` holds the line count, cutting speed, time samples and the
        separated overcuts (``vibration_overcut_um``: the largest depth the vibration adds
        to the no-vibration cut; ``tool_edge_overcut_um``: the largest depth the
        no-vibration cut lies below the design); ``metrics["vibration"]`` and
        ``metrics["burrs"]`` echo the settings and the seed.
    """
    from ..design import make_surface
    from ._burrs import apply_burrs

    t0 = time.perf_counter()
    surface = make_surface(scene.design)
    x_lines, y_edges = lattice_lines(surface, scene.design)
    sim = scene.simulation
    x0, y0, x1, y1 = sim.region
    ny, nx = sim.shape
    px = sim.pixel
    xg = x0 + px * np.arange(nx)
    yg = y0 + px * np.arange(ny)
    R = scene.tool.nose_radius
    half_width = R * math.sin(min(math.radians(scene.tool.included_angle_deg) / 2, math.pi / 2))
    vc = scene.process.feed_mm_per_min / 60.0
    step = scene.process.arc_length
    vib = scene.artifacts.vibration
    spp = vib.samples_per_period
    if sim.max_memory_gb * 1e9 < 8 * 8 * ny * nx:
        raise MemoryBudgetError(f"simulation grid {ny} x {nx} needs about {8 * 8 * ny * nx / 1e9:.1f} GB, "
                                f"over simulation.max_memory_gb = {sim.max_memory_gb}; use a larger "
                                "simulation.pixel or a smaller simulation.region")

    design = surface.sample(sim.region, px)[2]
    # accessibility: clearance angle vs the largest slope along the cut (rake 0)
    gy = np.abs(surface.gradient(xg[None, ::4], yg[::4, None])[1])
    max_slope_deg = float(np.degrees(np.arctan(np.nanmax(gy)))) if gy.size else 0.0
    clearance = scene.tool.clearance_angle_deg
    if max_slope_deg >= clearance and not scene.process.allow_gouge:
        raise AccessibilityError(
            f"tool.clearance_angle_deg must exceed the largest slope along the cutting direction "
            f"({max_slope_deg:.2f} deg), received {clearance}; use a larger clearance angle or "
            "set process.allow_gouge = true")

    # lines whose edge reaches the region
    used = [k for k, xk in enumerate(x_lines) if xk + half_width >= x0 and xk - half_width <= x1]
    # only the cells along y whose cut can reach the region (the vibration reaches A
    # beyond the nominal position; one whole cell of run-in is kept on either side)
    reach = 2 * vib.amplitude + px
    ia = max(int(np.searchsorted(y_edges, y0 - reach, side="right")) - 2, 0)
    ib = min(int(np.searchsorted(y_edges, y1 + reach, side="left")) + 1, len(y_edges) - 1)
    y_line_start = float(y_edges[0])
    y_edges = y_edges[ia:ib + 1]
    t_path = time.perf_counter()
    lines = [target_line(surface, x_lines[k], y_edges, step=step) for k in used]
    t_path = time.perf_counter() - t_path

    t_sim = time.perf_counter()
    prof_vib = np.array([sculpt_line_profile(ys, zs, yg, cutting_speed=vc, amplitude=vib.amplitude,
                                             frequency_hz=vib.frequency_hz, samples_per_period=spp,
                                             t_start=(ys[0] - y_line_start) / vc)
                         for ys, zs in lines]).reshape(len(used), ny)
    prof_0 = np.array([sculpt_line_profile(ys, zs, yg, cutting_speed=vc)
                       for ys, zs in lines]).reshape(len(used), ny)
    xl = x_lines[used]
    machined_0 = sculpt_surface(prof_0, xl, xg, tool_radius=R, half_width=half_width)
    machined = sculpt_surface(prof_vib, xl, xg, tool_radius=R, half_width=half_width)
    t_sim = time.perf_counter() - t_sim

    with np.errstate(invalid="ignore"):
        vib_over = np.nanmax(machined_0 - machined) if np.isfinite(machined).any() else 0.0
        edge_over = np.nanmax(design - machined_0) if np.isfinite(machined_0).any() else 0.0
    seed = int(sim.seed)
    machined, burr_info = apply_burrs(machined, design, pixel=px, origin=(x0, y0),
                                      cfg=scene.artifacts.burrs, seed=seed)
    per_period = (len(vibration_phases(vc, vib.amplitude, vib.frequency_hz, spp))
                  if vib.amplitude > 0 and vib.frequency_hz > 0 else 0)
    n_time = sum(int(math.ceil((ys[-1] - ys[0]) / vc * vib.frequency_hz * per_period)) + ys.size
                 for ys, _ in lines)
    metrics = {
        "sculpt": {"lines": len(used), "line_x_mm": [float(v) for v in xl],
                   "cutting_speed_mm_s": vc, "target_step_mm": step,
                   "target_points": int(sum(ys.size for ys, _ in lines)),
                   "time_samples": n_time,
                   "tool_radius_mm": R, "max_slope_deg": max_slope_deg,
                   "vibration_overcut_um": float(max(vib_over, 0.0) * 1e3),
                   "tool_edge_overcut_um": float(max(edge_over, 0.0) * 1e3),
                   "cutting_time_s": float(sum((ys[-1] - ys[0]) / vc for ys, _ in lines))},
        "vibration": {"frequency_hz": vib.frequency_hz, "amplitude_mm": vib.amplitude,
                      "samples_per_period": spp,
                      "peak_velocity_mm_s": 2 * math.pi * vib.frequency_hz * vib.amplitude},
        "burrs": burr_info,
        # linear X-Y-Z cutting: no spiral; points = target-line samples
        "toolpath": {"points": int(sum(ys.size for ys, _ in lines)), "revolutions": 0.0,
                     "feed_per_rev_mm": None, "kind": "sculpt", "lines": len(used),
                     "line_spacing_mm": float(np.median(np.diff(x_lines))) if len(x_lines) > 1 else None,
                     "cut_time_s": float(sum((ys[-1] - ys[0]) / vc for ys, _ in lines))},
    }
    meta = {"process": "sculpt", "seed": seed, "compensation": "none",
            "vibration": metrics["vibration"], "burrs": burr_info}
    hm = HeightMap(design, machined, px, (x0, y0), scene=scene.to_dict(), meta=meta)
    metrics["residual"] = residual_metrics(hm)
    t_l = time.perf_counter()
    metrics["lenslets"] = _lenslet_metrics(hm, surface)
    timing_l = time.perf_counter() - t_l
    total = time.perf_counter() - t0
    return SimulationResult(heightmap=hm, toolpath=None, metrics=metrics,
                            timing_s={"toolpath": t_path, "simulate": t_sim, "lenslets": timing_l,
                                      "total": total})


def _lenslet_metrics(hm, surface) -> list[dict]:
    """``lenslets``: metrology's per-lenslet fit (centre, dislocation, form error inside
    0.95 x half the pitch) of the machined map; lenslets cut by the region are left out."""
    import warnings

    from ..metrology._msa import lenslet_table

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return lenslet_table(hm, surface)
