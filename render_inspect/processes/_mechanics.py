"""The cut of a turning program through the scene's machine and material: the program is
followed by the machine's axes (servo dynamics, error motions:
:func:`~render_inspect.machining.follow_turning`), the followed path is cut with the
material's mechanics (minimum chip thickness, side flow, grooves), and the burrs of
``[artifacts.burrs]`` (an input, this module's section) are put on the machined edges.
``preset = "ideal"`` for both machine and material gives the geometric cut exactly.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np
from pydantic import Field

from ..core.errors import InputError
from ..core.section import Section
from ..core.toolpath import ToolPath
from ..core.units import MM_TO_NM, UM_TO_MM
from ..machining import (
    apply_burrs,
    cut_turning_mechanics,
    design_grid,
    finish_surface,
    follow_turning,
    following_error_stats,
    simulate_turning,
)
from ..toolpath import Tool
from ._contract import Inputs, section
from ._machine import MachineConfig, MaterialConfig, machine_of, material_of
from ._registry import register_section

__all__ = ["BurrConfig", "TurningInputs", "turn", "pass_angle_map", "following_error_plots",
           "followed_program", "burrs_of", "Turned"]

TWO_PI = 2 * math.pi


class BurrConfig(Section):
    """``[artifacts.burrs]``: ridges put on the machined edges (a given input, not a model
    of their formation; the material's side flow models that)."""
    height: float = Field(0.0, ge=0, le=0.1, description="mm")
    width: float = Field(0.0, ge=0, le=1.0, description="mm")
    variation: float = Field(0.3, ge=0, le=1, description="relative seeded variation")
    edge_angle_deg: float = Field(1.0, gt=0, lt=90, description="smallest slope jump that is a sharp edge")
    correlation_length: float | None = Field(None, gt=0, description="mm, of the variation; None = 4 x width")


register_section("artifacts.burrs", BurrConfig)


@dataclass(frozen=True)
class TurningInputs(Inputs):
    """What a turning process reads: ``[process]``, ``[tool]``, ``[simulation]``, the
    ``[design]`` (the planner's reach, the memory estimate), the ``[machine]`` and
    ``[material]`` and ``[artifacts.burrs]``."""

    design: object
    machine: MachineConfig
    material: MaterialConfig
    burrs: BurrConfig = section("artifacts.burrs")


def burrs_of(burrs: BurrConfig, seed: int) -> dict:
    """The ``[artifacts.burrs]`` keys as :func:`~render_inspect.machining.apply_burrs`
    arguments."""
    return {"height": burrs.height, "width": burrs.width, "variation": burrs.variation,
            "edge_angle_deg": burrs.edge_angle_deg,
            "correlation_length": burrs.correlation_length, "seed": int(seed)}


class Turned(dict):
    """``machined``, ``design`` (maps, mm), ``timing``, ``facts`` (metrics entries),
    ``followed`` (ToolPath or None), ``followed_path`` (FollowedPath or None),
    ``pass_theta`` (map of the cutting pass's spindle angle, or None)."""


def pass_angle_map(path, region, pixel) -> np.ndarray:
    """Cumulative spindle angle (rad) of the pass that cuts each pixel, on the nominal
    spiral of ``path`` (the revolution nearest to the pixel's radius at its angle)."""
    theta = np.asarray(path.theta, dtype=np.float64)
    rho = np.asarray(path.rho, dtype=np.float64)
    x0, y0, x1, y1 = region
    nx = int(round((x1 - x0) / pixel)) + 1
    ny = int(round((y1 - y0) / pixel)) + 1
    x = x0 + pixel * np.arange(nx)
    y = y0 + pixel * np.arange(ny)
    xx, yy = np.meshgrid(x, y)
    r = np.hypot(xx, yy)
    phi = np.mod(np.arctan2(yy, xx), TWO_PI)
    span = theta[-1] - theta[0]
    cc = (rho[0] - rho[-1]) / span if span > 0 else 0.0
    if cc <= 0:
        return np.full(r.shape, np.nan)
    s0 = theta[0] + (rho[0] - r) / cc
    s = phi + TWO_PI * np.round((s0 - phi) / TWO_PI)
    return np.where((s >= theta[0]) & (s <= theta[-1]), s, np.nan)


def _cutting_distance(path) -> tuple[np.ndarray, np.ndarray]:
    th = np.asarray(path.theta, dtype=np.float64)
    rho = np.abs(np.asarray(path.rho, dtype=np.float64))
    d = np.concatenate([[0.0], np.cumsum(0.5 * (rho[1:] + rho[:-1]) * np.diff(th))])
    return th, d


def _error_maps(fp, pass_theta, stride: int) -> tuple[np.ndarray, np.ndarray]:
    s = pass_theta[::stride, ::stride]
    ok = np.isfinite(s)
    t = np.interp(np.where(ok, s, fp.theta[0]), fp.theta, fp.t)
    ex = np.where(ok, np.interp(t, fp.t, fp.errors["x"]) * MM_TO_NM, np.nan)
    ez = np.where(ok, np.interp(t, fp.t, fp.errors["z"] + fp.errors["fts"]) * MM_TO_NM, np.nan)
    return ex, ez


def following_error_plots(fp, pass_theta, region, pixel, *, name: str) -> dict:
    """Figure specs (``following_error.png``, ``following_error_map.png``) of a followed
    path: the errors against time, and the X and Z (slide + FTS) errors of the pass that
    cut each point, on at most ~800 x 800 points."""
    x0, y0 = region[0], region[1]
    stride = max(1, int(math.ceil(max(pass_theta.shape) / 800)))
    ex, ez = _error_maps(fp, pass_theta, stride)
    n = fp.t.size
    keep = slice(None, None, max(1, n // 400_000))  # the envelope plot needs no more
    stats = following_error_stats(fp.errors)
    return {"following_error.png": {"kind": "following_error", "t": fp.t[keep],
                                    "errors": {k: v[keep] for k, v in fp.errors.items()},
                                    "stats": stats,
                                    "title": f"{name}: following error (command - followed)"},
            "following_error_map.png": {"kind": "following_error_map", "x_nm": ex, "z_nm": ez,
                                        "extent": (x0, x0 + pixel * stride * (ex.shape[1] - 1),
                                                   y0, y0 + pixel * stride * (ex.shape[0] - 1)),
                                        "title": f"{name}: following error of the pass that cut "
                                                 "each point"}}


def turn(cfg: TurningInputs, surface, path, *, z_fts=None, burrs: bool = True, region=None,
         plots: bool = True, design=None) -> Turned:
    """Cut a turning program through the machine and material of ``cfg``.

    Parameters
    ----------
    cfg : TurningInputs
    surface : Surface
    path : ToolPath
        The commanded program (tool tip).
    z_fts : (n,) array, optional
        The fast tool servo's share of ``path.z`` (mm).
    burrs : bool
        Add the ``[artifacts.burrs]`` ridges (on the machined edges) when their height is set.
    region : (x0, y0, x1, y1), optional
        mm; default ``simulation.region``.
    plots : bool
        Add the following-error figures to the facts' plots.
    design : (ny, nx) array, optional
        The design on the grid (computed if None).

    Returns
    -------
    Turned
    """
    sim = cfg.simulation
    region = tuple(sim.region) if region is None else tuple(region)
    tool = Tool.from_config(cfg.tool)
    timing, facts, figs = {}, {}, {}
    t0 = time.perf_counter()
    machine = machine_of(cfg.machine)
    fp = follow_turning(path.t, path.theta, path.rho, path.z, machine, z_fts=z_fts,
                        seed=int(sim.seed))
    cut_path = path if fp.ideal else ToolPath(fp.theta, fp.rho, fp.z, fp.t,
                                              {**path.meta, "followed": machine.name})
    facts["machine"] = {"preset": cfg.machine.preset, "ideal": fp.ideal,
                        "settings": machine.to_dict(), "ticks": int(fp.t.size)}
    if not fp.ideal:
        facts["following_error"] = following_error_stats(fp.errors)
    timing["machine"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    resp = material_of(cfg.material)
    pass_theta = None
    if resp is None:
        machined = simulate_turning(cut_path, nose_radius=tool.nose_radius, region=region,
                                    pixel=sim.pixel, half_width=tool.half_width)
    else:
        c = cut_turning_mechanics(cut_path, nose_radius=tool.nose_radius, region=region,
                                  pixel=sim.pixel, half_width=tool.half_width, h_min=resp.h_min,
                                  kappa=resp.kappa, side_flow=resp.side_flow)
        th, dist = _cutting_distance(cut_path)
        pass_theta = c["pass_theta"]
        along = np.interp(np.nan_to_num(pass_theta, nan=th[0]), th, dist)
        machined, info = finish_surface(c, resp, along=along, seed=int(sim.seed) + 1,
                                        across_length=cfg.material.groove_across_um * UM_TO_MM,
                                        along_length=cfg.material.groove_along_mm)
        facts["material"] = {**resp.to_dict(), **info}
    timing["envelope"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    if design is None:
        design = design_grid(surface, region, sim.pixel)
    timing["design"] = time.perf_counter() - t0
    if burrs and cfg.burrs.height > 0:
        b = cfg.burrs
        feed = abs(float(cut_path.rho[0] - cut_path.rho[-1])) / max(cut_path.revolutions, 1e-12)
        machined, facts["burrs"] = apply_burrs(
            machined, design, pixel=sim.pixel, origin=(region[0], region[1]), height=b.height,
            width=b.width, variation=b.variation, edge_angle_deg=b.edge_angle_deg,
            correlation_length=b.correlation_length, seed=int(sim.seed), edges_from="machined",
            smoothing=max(feed, 2 * sim.pixel))
    if plots and not fp.ideal:
        if pass_theta is None:
            pass_theta = pass_angle_map(cut_path, region, sim.pixel)
        figs = following_error_plots(fp, pass_theta, region, sim.pixel, name=cfg.name)
    return Turned(machined=machined, design=design, timing=timing, facts=facts,
                  followed=None if fp.ideal else cut_path, followed_path=fp,
                  pass_theta=pass_theta, plots=figs)


def followed_program(cfg: TurningInputs, path) -> ToolPath:
    """The path the tool follows on the ``[machine]`` (the commanded ``path`` on an ideal
    machine): what a tiled simulation cuts, since the machine acts on the whole path while
    the envelope of its nose can be taken tile by tile.  Material models act on the whole
    map, so a tiled simulation needs ``material.preset = "ideal"``."""
    if cfg.material.preset != "ideal":
        raise InputError(
            f"material.preset must be 'ideal' for a simulation computed tile by tile (the "
            f"material's side flow and grooves are modelled on the whole map), received "
            f"{cfg.material.preset!r}; set --set material.preset='ideal', or simulate a "
            f"region that fits simulation.max_memory_gb")
    machine = machine_of(cfg.machine)
    fp = follow_turning(path.t, path.theta, path.rho, path.z, machine,
                        seed=int(cfg.simulation.seed))
    if fp.ideal:
        return path
    return ToolPath(fp.theta, fp.rho, fp.z, fp.t, {**path.meta, "followed": machine.name})
