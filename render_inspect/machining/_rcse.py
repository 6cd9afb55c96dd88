"""Turning along a rotary-coordinate shuttling-element (RCSE) spiral path (seed 004),
compared with the conventional path interpolated from a rectangular point cloud."""

from __future__ import annotations

import functools
import time
from pathlib import Path

import numpy as np

from ._heightmap import HeightMap
from ._metrics import residual_metrics
from ._result import SimulationResult

__all__ = ["simulate_rcse", "rcse_comparison", "plot_rcse_comparison"]


def rcse_comparison(scene, path, surface, *, heightmap: HeightMap | None = None) -> tuple[dict, object]:
    """Compare the RCSE path with the conventional one over the same spiral samples.

    Parameters
    ----------
    scene : Scene
    path : ToolPath
        The RCSE path (with ``ccp_rho`` / ``ccp_z``).
    surface : Surface
        The design.
    heightmap : HeightMap, optional
        The RCSE simulation (design and machined on ``scene.simulation``'s grid).  If given
        and ``rcse.simulate_conventional``, the conventional path is Z-compensated on its
        own point-cloud model and machined over the same grid, and both residuals are
        reported (``residual``: Sa, Sq, Sz, min in nm).

    Returns
    -------
    (metrics, (rcse CCP path, conventional CCP path))
        ``metrics``: ``rcse`` and ``conventional`` X velocity / acceleration / jerk
        maxima, mean |vX|, X reversals, profile errors (nm: max |error|, RMS), the
        conventional modelling and interpolation times.  The paths carry the CCP heights
        (no tool compensation): their X motion is what each method programs.
    """
    from ..toolpath import ToolPath
    from ..toolpath._kinematics import kinematics
    from ..toolpath._rcse import conventional_ccps, rcse_settings

    st = rcse_settings(scene)
    theta = np.asarray(path.theta)
    rho = np.asarray(path.ccp_rho if path.ccp_rho is not None else path.rho)
    z = np.asarray(path.ccp_z if path.ccp_z is not None else path.z)
    t = np.asarray(path.t)
    conv = conventional_ccps(surface, theta, rho, grid_spacing=st["grid_spacing"],
                             interpolation=st["interpolation"], snap_to_rows=st["snap_to_rows"])
    conv_path = ToolPath(theta.copy(), conv["rho"], conv["z"], t.copy(),
                         {"method": "conventional", "grid_spacing_mm": st["grid_spacing"],
                          "interpolation": st["interpolation"], "snap_to_rows": st["snap_to_rows"]})
    ccp_path = ToolPath(theta.copy(), rho.copy(), z.copy(), t.copy(), {"method": "rcse"})
    err_rcse = z - surface.height(rho * np.cos(theta), rho * np.sin(theta))
    keys = ("x_velocity_max_mm_s", "x_acceleration_max_mm_s2", "x_jerk_max_mm_s3",
            "x_velocity_mean_mm_s", "x_reversals", "z_velocity_max_mm_s", "z_acceleration_max_mm_s2")
    kr = kinematics(ccp_path)
    kc = kinematics(conv_path)
    e = conv["profile_error"]
    out = {
        "rcse": {**{k: kr[k] for k in keys},
                 "profile_error_max_nm": float(np.max(np.abs(err_rcse)) * 1e6),
                 "profile_error_rms_nm": float(np.sqrt(np.mean(err_rcse ** 2)) * 1e6)},
        "conventional": {**{k: kc[k] for k in keys},
                         "profile_error_max_nm": float(np.max(np.abs(e)) * 1e6),
                         "profile_error_rms_nm": float(np.sqrt(np.mean(e ** 2)) * 1e6),
                         "x_deviation_max_um": float(np.max(np.abs(conv["rho"] - rho)) * 1e3),
                         "modelling_s": conv["modelling_s"], "toolpath_s": conv["toolpath_s"],
                         "grid_shape": conv["grid_shape"], "grid_spacing_mm": st["grid_spacing"],
                         "interpolation": st["interpolation"], "snap_to_rows": st["snap_to_rows"]},
        "points_compared": int(theta.size),
    }
    if heightmap is not None and st["simulate_conventional"]:
        out["rcse"]["residual"] = _short(residual_metrics(heightmap))
        out["conventional"]["residual"] = _short(residual_metrics(
            _machine_conventional(scene, conv_path, conv["model"], heightmap), heightmap.design))
    return out, (ccp_path, conv_path)


def _short(r: dict) -> dict:
    return {k: r[k] for k in ("Sa_nm", "Sq_nm", "Sz_nm", "min_nm") if k in r}


def _machine_conventional(scene, conv_path, model, heightmap) -> np.ndarray:
    """The surface the conventional path machines: its CCP heights lifted by the Z
    compensation computed on its own point-cloud model at the machine position (C, X)."""
    from ..toolpath import Tool, ToolPath, z_compensation
    from ..toolpath._rcse import RingLayout
    from ._envelope import simulate_turning

    tool = Tool.from_config(scene.tool)
    slope = RingLayout.from_config(scene.design).max_slope * 1.05
    th, rc = conv_path.theta, conv_path.rho
    m_here = model.height(rc * np.cos(th), rc * np.sin(th))
    lift = z_compensation(model, th, rc, tool.nose_radius, max_slope=slope,
                          half_width=tool.half_width) - m_here
    tip = ToolPath(th, rc, conv_path.z + lift, conv_path.t, dict(conv_path.meta))
    sim = scene.simulation
    return simulate_turning(tip, nose_radius=tool.nose_radius, region=sim.region, pixel=sim.pixel,
                            half_width=tool.half_width)


def plot_rcse_comparison(paths, png_path) -> Path:
    """X vs C, X velocity and acceleration vs time, RCSE beside conventional (seed 004
    Figs. 8-9), from the pair returned by :func:`rcse_comparison`."""
    from ..toolpath._kinematics import plot_kinematics

    rcse_path, conv_path = paths
    return plot_kinematics(rcse_path, png_path, reference=conv_path,
                           labels=("RCSE (CCPs on the spiral)", "conventional (grid-interpolated)"),
                           title="X-axis motion: RCSE vs conventional (seed 004 Figs. 8-9)")


def simulate_rcse(scene, surface=None, *, plot_dir=None) -> SimulationResult:
    """Simulate turning of ``scene`` along its RCSE path over ``scene.simulation.region``.

    Parameters
    ----------
    scene : Scene
        ``design.type = "lenslet_rings"``, ``process.kind = "rcse"``; the optional
        ``[rcse]`` section sets the conventional comparison.
    surface : Surface, optional
        The design (built from ``scene.design`` if None).
    plot_dir : str or Path, optional
        If given, ``rcse_kinematics.png`` (RCSE vs conventional X motion) is written there.
        Without it, the result's ``plots`` attribute maps ``"rcse_kinematics.png"`` to a
        function ``fn(png_path)`` that draws it (for the output writer).

    Returns
    -------
    SimulationResult
        ``metrics``: ``residual``, ``toolpath`` (points, revolutions, feed per rev and the
        kinematics maxima/warnings against the ``[process]`` limits), ``rcse`` (layout,
        CCPs, sub-paths, generation time, comparison with the conventional path).
    """
    from ..design import make_surface
    from ..toolpath import Tool
    from ..toolpath._kinematics import kinematics
    from ..toolpath._rcse import RingLayout, build_rcse_toolpath, rcse_ccps, rcse_settings
    from ..toolpath._build import region_radii
    from ._sts import check_memory, toolpath_metrics, turned_grid

    timing: dict = {}
    check_memory(scene)
    surface = surface if surface is not None else make_surface(scene.design)
    sim, proc = scene.simulation, scene.process
    tool = Tool.from_config(scene.tool)
    layout = RingLayout.from_config(scene.design)
    t0 = time.perf_counter()
    r_range = region_radii(sim.region, tool.half_width + 2 * proc.feed_per_rev)
    ccps = rcse_ccps(layout, r_outer=proc.workpiece_radius, pitch=proc.feed_per_rev,
                     points_per_rev=proc.points_per_rev, r_inner=proc.inner_radius, r_range=r_range)
    timing["ccps"] = time.perf_counter() - t0
    path = build_rcse_toolpath(scene, surface, ccps=ccps)
    timing["toolpath"] = time.perf_counter() - t0
    check_memory(scene, path.points)
    machined, design = turned_grid(scene, surface, path, timing)
    t0 = time.perf_counter()
    hm = HeightMap(design, machined, sim.pixel, (sim.region[0], sim.region[1]), scene.to_dict(),
                   {"process": "rcse", "compensation": proc.compensation, "seed": sim.seed})
    tp = toolpath_metrics(path)
    tp.update(kinematics(path, limits=proc))
    subs = ccps.sub_paths()
    rcse = {"layout": layout.to_dict(), "ccps": int(ccps.k.size),
            "ccps_on_elements": int(np.count_nonzero(ccps.ring >= 0)),
            "sub_paths": int(subs.shape[0]), "pitch_mm": proc.feed_per_rev,
            "polar_step_deg": 360.0 / proc.points_per_rev,
            "ccp_generation_s": timing["ccps"],
            "layout_overlaps": layout.overlaps()}
    st = rcse_settings(scene)
    if st["compare_conventional"]:
        t1 = time.perf_counter()
        comp, pair = rcse_comparison(scene, path, surface, heightmap=hm)
        rcse["comparison"] = comp
        timing["comparison"] = time.perf_counter() - t1
        if plot_dir is not None:
            plot_rcse_comparison(pair, Path(plot_dir) / "rcse_kinematics.png")
    metrics = {"residual": residual_metrics(hm), "toolpath": tp, "rcse": rcse}
    timing["metrics"] = time.perf_counter() - t0 - timing.get("comparison", 0.0)
    timing["simulate"] = timing["envelope"] + timing["design"] + timing["metrics"]
    res = SimulationResult(hm, path, metrics, timing)
    # figures the writer may draw into the output folder: file name -> fn(png_path)
    res.plots = dict(res.plots)
    if st["compare_conventional"]:
        res.plots["rcse_kinematics.png"] = functools.partial(plot_rcse_comparison, pair)
    return res
