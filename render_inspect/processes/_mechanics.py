"""The machine and the material of a scene (``[machine]``, ``[material]``) and the cut of a
turning program through them: the program is followed by the machine's axes (servo
dynamics, error motions), the followed path is cut with the material's mechanics
(minimum chip thickness, side flow, grooves), and the burrs given as an input are put on
the machined edges.  ``preset = "ideal"`` for both gives the geometric cut exactly.
"""

from __future__ import annotations

import math
import time

import numpy as np

from ..core.errors import InputError, SceneError
from ..core.toolpath import ToolPath
from ..machining import (
    apply_burrs,
    contact_ratio,
    cut_turning_mechanics,
    design_grid,
    finish_surface,
    follow_turning,
    following_error_stats,
    machine_preset,
    material_preset,
    material_response,
    simulate_turning,
)
from ..toolpath import Tool

__all__ = ["machine_of", "material_of", "turn", "pass_angle_map", "following_error_plots",
           "Turned"]

TWO_PI = 2 * math.pi


# ---------------------------------------------------------------------------------------
# scene sections -> machining objects (scene units -> mm, rad)
# ---------------------------------------------------------------------------------------
def _linear_axis(cfg) -> dict:
    d = {}
    for k, v in cfg.model_dump(exclude_none=True).items():
        if k == "bandwidth_hz":
            d[k] = None if math.isinf(v) else v
        elif k == "noise_nm":
            d["noise_rms"] = v * 1e-6
        elif k == "velocity_limit_mm_s":
            d["velocity_limit"] = v
        elif k == "acceleration_limit_mm_s2":
            d["acceleration_limit"] = v
        else:
            d[k] = v
    return d


def _spindle_axis(cfg) -> dict:
    d = {}
    for k, v in cfg.model_dump(exclude_none=True).items():
        if k == "bandwidth_hz":
            d[k] = None if math.isinf(v) else v
        elif k == "noise_urad":
            d["noise_rms"] = v * 1e-6
        else:
            d[k] = v
    return d


def _errors(cfg) -> dict:
    d = {}
    for k, v in cfg.model_dump(exclude_none=True).items():
        if k in ("radial_sync", "axial_sync", "tilt_sync"):   # nm (urad for tilt), deg
            d[k] = tuple((int(n), a * 1e-6, math.radians(p)) for n, a, p in v)
        elif k in ("radial_async_nm", "axial_async_nm"):
            d[k.replace("_nm", "_rms")] = v * 1e-6
        elif k == "x_straightness_nm":
            d["x_straightness_rms"] = v * 1e-6
        elif k == "vibration":
            d[k] = tuple((f, a * 1e-6, direction, math.radians(p)) for f, a, direction, p in v)
        else:
            d[k] = v
    return d


def machine_of(scene):
    """The :class:`~render_inspect.machining.Machine` of the scene's ``[machine]``."""
    cfg = scene.machine
    ov = {k: getattr(cfg, k) for k in ("servo_rate_hz", "interpolation", "fts_sync")
          if getattr(cfg, k) is not None}
    for k in ("x", "z", "fts"):
        d = _linear_axis(getattr(cfg, k))
        if d:
            ov[k] = d
    d = _spindle_axis(cfg.c)
    if d:
        ov["c"] = d
    d = _errors(cfg.errors)
    if d:
        ov["errors"] = d
    d = cfg.coupling.model_dump(exclude_none=True)
    if d:
        ov["coupling"] = d
    try:
        return machine_preset(cfg.preset, ov)
    except InputError as err:
        raise SceneError(f"machine (preset {cfg.preset!r}): {err}") from None


def material_of(scene, *, contact=1.0):
    """The :class:`~render_inspect.machining.MaterialResponse` of ``[material]`` at the
    contact ratio ``contact`` (1 = continuous cutting), or None for ``preset = "ideal"``."""
    cfg = scene.material
    if cfg.preset == "ideal":
        return None
    try:
        mat = material_preset(cfg.preset, cfg.overrides())
        return material_response(mat, edge_radius=cfg.edge_radius_nm * 1e-6,
                                 contact_ratio=contact, side_flow=cfg.side_flow)
    except InputError as err:
        raise SceneError(f"material (preset {cfg.preset!r}): {err}") from None


def vibration_contact(scene, cutting_speed: float) -> float:
    """Contact ratio of the scene's ``[artifacts.vibration]`` at ``cutting_speed`` (mm/s)."""
    v = scene.artifacts.vibration
    return contact_ratio(cutting_speed, v.amplitude, v.frequency_hz)


# ---------------------------------------------------------------------------------------
# the cut
# ---------------------------------------------------------------------------------------
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
    ex = np.where(ok, np.interp(t, fp.t, fp.errors["x"]) * 1e6, np.nan)
    ez = np.where(ok, np.interp(t, fp.t, fp.errors["z"] + fp.errors["fts"]) * 1e6, np.nan)
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


def turn(scene, surface, path, *, z_fts=None, followed: ToolPath | None = None,
         burrs: bool = True, region=None, plots: bool = True, design=None) -> Turned:
    """Cut a turning program through the scene's machine and material.

    Parameters
    ----------
    scene : Scene
    surface : Surface
    path : ToolPath
        The commanded program (tool tip).
    z_fts : (n,) array, optional
        The fast tool servo's share of ``path.z`` (mm).
    followed : ToolPath, optional
        A path already followed by other means (the ``[artifacts.servo]`` model of an
        ideal machine); the machine is then not applied again.
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
    sim = scene.simulation
    region = tuple(sim.region) if region is None else tuple(region)
    tool = Tool.from_config(scene.tool)
    timing, facts, figs = {}, {}, {}
    fp = None
    t0 = time.perf_counter()
    if followed is None:
        machine = machine_of(scene)
        fp = follow_turning(path.t, path.theta, path.rho, path.z, machine, z_fts=z_fts,
                            seed=int(sim.seed))
        cut_path = path if fp.ideal else ToolPath(fp.theta, fp.rho, fp.z, fp.t,
                                                  {**path.meta, "followed": machine.name})
        facts["machine"] = {"preset": scene.machine.preset, "ideal": fp.ideal,
                            "settings": machine.to_dict(), "ticks": int(fp.t.size)}
        if not fp.ideal:
            facts["following_error"] = following_error_stats(fp.errors)
    else:
        cut_path = followed
        facts["machine"] = {"preset": scene.machine.preset, "ideal": True,
                            "followed": "artifacts.servo"}
    timing["machine"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    resp = material_of(scene)
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
                                        across_length=scene.material.groove_across_um * 1e-3,
                                        along_length=scene.material.groove_along_mm)
        facts["material"] = {**resp.to_dict(), **info}
    timing["envelope"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    if design is None:
        design = design_grid(surface, region, sim.pixel)
    timing["design"] = time.perf_counter() - t0
    if burrs and scene.artifacts.burrs.height > 0:
        b = scene.artifacts.burrs
        feed = abs(float(cut_path.rho[0] - cut_path.rho[-1])) / max(cut_path.revolutions, 1e-12)
        machined, facts["burrs"] = apply_burrs(
            machined, design, pixel=sim.pixel, origin=(region[0], region[1]), height=b.height,
            width=b.width, variation=b.variation, edge_angle_deg=b.edge_angle_deg,
            correlation_length=b.correlation_length, seed=int(sim.seed), edges_from="machined",
            smoothing=max(feed, 2 * sim.pixel))
    if plots and fp is not None and not fp.ideal:
        if pass_theta is None:
            pass_theta = pass_angle_map(cut_path, region, sim.pixel)
        figs = following_error_plots(fp, pass_theta, region, sim.pixel, name=scene.name)
    out = Turned(machined=machined, design=design, timing=timing, facts=facts,
                 followed=None if (fp is not None and fp.ideal) else cut_path,
                 followed_path=fp, pass_theta=pass_theta, plots=figs)
    return out


def followed_program(scene, path) -> ToolPath:
    """The path the tool follows on the scene's ``[machine]`` (the commanded ``path`` on an
    ideal machine): what a tiled simulation cuts, since the machine acts on the whole
    path while the envelope of its nose can be taken tile by tile.  Material models act
    on the whole map, so a tiled simulation needs ``material.preset = "ideal"``."""
    if scene.material.preset != "ideal":
        raise InputError(
            f"material.preset must be 'ideal' for a simulation computed tile by tile (the "
            f"material's side flow and grooves are modelled on the whole map), received "
            f"{scene.material.preset!r}; set --set material.preset='ideal', or simulate a "
            f"region that fits simulation.max_memory_gb")
    machine = machine_of(scene)
    fp = follow_turning(path.t, path.theta, path.rho, path.z, machine,
                        seed=int(scene.simulation.seed))
    if fp.ideal:
        return path
    return ToolPath(fp.theta, fp.rho, fp.z, fp.t, {**path.meta, "followed": machine.name})
