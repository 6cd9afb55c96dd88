"""The cut of a turning program through the scene's machine and material: the program is
followed by the machine's axes (servo dynamics, error motions:
:func:`~render_inspect.machining.follow_turning`), the followed path is cut with the
material's mechanics (minimum chip thickness, side flow), the part's texture is added (a
field of the position on the part), and burrs are put on the machined edges: the material's
(:func:`~render_inspect.machining.material_burrs`, from the uncut chip thickness of the
finishing cut, the exit angle and the ductility), or a given height
(``[artifacts.burrs]``, this module's section, an override).  ``preset = "ideal"`` for
both machine and material gives the geometric cut exactly.  The scallop of the feed used
is reported always (``metrics["scallop"]``).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
import logging
import math
import time
from dataclasses import dataclass
from typing import Any

import numpy as np
from pydantic import Field

from ..design import DesignConfig
from ..core.grid import flip_rows, grid_shape
from ..core.handoff import hand_over
from ..core.pages import Prefaulted
from ..core.section import Section
from ..core.toolpath import ToolPath
from ..core.units import MM_TO_NM, UM_TO_MM
from ..machining import (
    BURR_WIDTH_PER_CHIP,
    CutPath,
    FollowedPath,
    Grooves,
    MaterialResponse,
    TextureJob,
    add_texture_field,
    apply_burrs,
    cut_turning,
    design_grid,
    follow_turning,
    following_error_stats,
    machined_edge_count,
    mask_outside_sector,
    material_burrs,
    mechanics_facts,
    prepare_cut,
    simulate_turning,
    uncut_chip_thickness,
)
from ..toolpath import Tool, scallop_height
from ._contract import Inputs, section
from ._edge_facts import edge_facts
from ._machine import MachineConfig, MaterialConfig, machine_of, material_of
from ._program import cut_name
from ._registry import register_section
from ._settings import machine_settings
from ._spindle import MirroredSurface, mirrored_region, part_figure, turns_m04
from ._wear_facts import roughness_against_radius, wear_figure, wear_path, worn_h_min

__all__ = ["BurrConfig", "TurningInputs", "turn", "pass_angle_map", "following_error_plots",
           "follow", "burrs_of", "Turned", "material_cut_path", "grooves_of", "feed_scallop",
           "add_texture", "texture_of", "material_burr_args"]

TWO_PI = 2 * math.pi
log = logging.getLogger("render_inspect")


class BurrConfig(Section):
    """``[artifacts.burrs]``: ridges of a given height put on the machined edges, in place
    of the material's burr model (an override, not a model of their formation)."""
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

    design: DesignConfig
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
    ``followed`` (ToolPath or None), ``followed_path`` (FollowedPath or None), ``plots``
    (figure specs)."""


def pass_angle_map(path: ToolPath, region: Sequence[float], pixel: float, *,
                   stride: int = 1) -> np.ndarray:
    """Cumulative spindle angle (rad) of the pass that cuts each pixel, on the nominal
    spiral of ``path`` (the revolution nearest to the pixel's radius at its angle).
    ``stride``: every ``stride``-th row and column of the grid only (the same numbers as
    the whole map's ``[::stride, ::stride]``)."""
    theta = np.asarray(path.theta, dtype=np.float64)
    rho = np.asarray(path.rho, dtype=np.float64)
    x0, y0, x1, y1 = region
    nx = int(round((x1 - x0) / pixel)) + 1
    ny = int(round((y1 - y0) / pixel)) + 1
    x = x0 + pixel * np.arange(nx)[::stride]
    y = y0 + pixel * np.arange(ny)[::stride]
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


def material_cut_path(path: ToolPath, tool: Tool, resp: MaterialResponse,
                      h_min_points: np.ndarray | None = None) -> CutPath:
    """The followed path prepared for the cutting-mechanics kernel with the material's
    minimum chip thickness (``h_min_points``: at each point, the edge worn along the path),
    elastic recovery and side flow."""
    return prepare_cut(path, nose_radius=tool.nose_radius, half_width=tool.half_width,
                       h_min=resp.h_min, kappa=resp.kappa, side_flow=resp.side_flow, edge=tool.edge,
                       h_min_points=h_min_points)


def grooves_of(cfg: TurningInputs, resp: MaterialResponse) -> Grooves:
    """The grooves of the material's cutting edge (seeded by ``simulation.seed`` + 1)."""
    return Grooves.of(rms=resp.groove_rms, seed=int(cfg.simulation.seed) + 1,
                      across_length=cfg.material.groove_across_um * UM_TO_MM,
                      along_length=cfg.material.groove_along_mm)


#: largest side (points) of the following-error map: about the pixels its panel has in the
#: figure (more are drawn at no gain, and cost time to resample and compress)
MAP_FIGURE_POINTS = 440


def _error_maps(fp, pass_theta, stride: int) -> tuple[np.ndarray, np.ndarray]:
    s = pass_theta[::stride, ::stride]
    ok = np.isfinite(s)
    t = np.interp(np.where(ok, s, fp.theta[0]), fp.theta, fp.t)
    ex = np.where(ok, np.interp(t, fp.t, fp.errors["x"]) * MM_TO_NM, np.nan)
    ez = np.where(ok, np.interp(t, fp.t, fp.errors["z"] + fp.errors["fts"]) * MM_TO_NM, np.nan)
    return ex, ez


def following_error_plots(fp: Any, pass_theta: np.ndarray, region: Sequence[float],
                          pixel: float, *, name: str) -> dict:
    """Figure specs (``following_error.png``, ``following_error_map.png``) of a followed
    path: the errors against time, and the X and Z (slide + FTS) errors of the pass that
    cut each point, on at most ~:data:`MAP_FIGURE_POINTS` points a side."""
    return {**following_error_series_plot(fp, name=name),
            **following_error_map_plot(fp, pass_theta, region, pixel, name=name)}


def following_error_series_plot(fp: Any, *, name: str) -> dict:
    """The spec of ``following_error.png``: each axis' error against time (at most about
    400,000 ticks: the envelope plot needs no more)."""
    n = fp.t.size
    keep = slice(None, None, max(1, n // 400_000))
    stats = following_error_stats(fp.errors)
    return {"following_error.png": {"kind": "following_error", "t": fp.t[keep],
                                    "errors": {k: v[keep] for k, v in fp.errors.items()},
                                    "stats": stats,
                                    "title": f"{name}: following error (command - followed)"}}


def map_figure_stride(shape: Sequence[int]) -> int:
    """The stride of rows and columns ``following_error_map.png`` draws of a map of
    ``shape``: at most ~:data:`MAP_FIGURE_POINTS` points a side."""
    return max(1, int(math.ceil(max(shape) / MAP_FIGURE_POINTS)))


def following_error_map_plot(fp: Any, pass_theta: np.ndarray, region: Sequence[float],
                             pixel: float, *, name: str) -> dict:
    """The spec of ``following_error_map.png``: the X and Z errors of the pass that cut
    each point (``pass_theta``), on at most ~:data:`MAP_FIGURE_POINTS` points a side."""
    x0, y0 = region[0], region[1]
    stride = map_figure_stride(pass_theta.shape)
    ex, ez = _error_maps(fp, pass_theta, stride)
    return {"following_error_map.png": {"kind": "following_error_map", "x_nm": ex, "z_nm": ez,
                                        "extent": (x0, x0 + pixel * stride * (ex.shape[1] - 1),
                                                   y0, y0 + pixel * stride * (ex.shape[0] - 1)),
                                        "title": f"{name}: following error of the pass that cut "
                                                 "each point"}}


def feed_scallop(feed: float, nose_radius: float) -> dict:
    """``metrics["scallop"]``: the scallop the feed per revolution ``feed`` leaves with a
    nose of radius ``nose_radius`` (mm) on a flat section: its height
    H = R - sqrt(R^2 - f^2 / 4) (exact circle) and the Sa = 4 H / (9 sqrt 3) and
    Sq = f^2 / (R sqrt 720) of the parabolic scallop (mean removed): the roughness the feed
    alone leaves across the feed marks."""
    f, r = float(feed), float(nose_radius)
    h = float(scallop_height(f, r))
    return {"feed_per_rev_mm": f, "nose_radius_mm": r, "height_nm": h * MM_TO_NM,
            "Sa_nm": 4 * f * f / (8 * r) / (9 * math.sqrt(3)) * MM_TO_NM,
            "Sq_nm": f * f / (r * math.sqrt(720.0)) * MM_TO_NM}


def texture_of(cfg: TurningInputs, resp: MaterialResponse) -> tuple[float, float, int]:
    """The part's texture of the material response ``resp``: (rms, correlation length,
    seed), mm (seeded by ``simulation.seed`` + 2)."""
    return float(resp.texture_rms), float(resp.texture_length), int(cfg.simulation.seed) + 2


def texture_grid(region: Sequence[float], pixel: float, shape: Sequence[int]) -> tuple[np.ndarray, np.ndarray]:
    """The positions x (nx,) and y (ny,) (mm) of the map of ``shape`` on ``region``'s grid."""
    ny, nx = shape
    return region[0] + pixel * np.arange(nx), region[1] + pixel * np.arange(ny)


def add_texture(machined: np.ndarray, resp: MaterialResponse, region: Sequence[float],
                pixel: float, seed: int, *, overwrite: bool = False,
                buffers: tuple = (), unit: np.ndarray | None = None) -> tuple[np.ndarray, float]:
    """``machined`` with the part's texture (:func:`~render_inspect.machining.texture_field`
    of the grid's positions, from ``seed``) added where it is finite; the texture's
    measured rms (nm).  ``overwrite``, ``buffers``, ``unit``: as
    :func:`~render_inspect.machining.add_texture_field` (added into ``machined``; maps
    whose content is no longer needed, to compute in; the unit field computed already)."""
    x, y = texture_grid(region, pixel, machined.shape)
    out, rms = add_texture_field(machined, x, y, rms=resp.texture_rms, correlation_length=resp.texture_length,
                                 seed=seed, overwrite=overwrite, buffers=buffers, unit=unit)
    return out, rms * MM_TO_NM


def material_burr_args(cfg: TurningInputs, resp: MaterialResponse | None, path: ToolPath,
                       tool: Tool) -> dict | None:
    """The material's burrs of a turning cut (:func:`~render_inspect.machining.material_burrs`'
    keyword arguments but the grid's: the uncut chip thickness of the finishing cut at the
    feed of ``path`` (its ``feed_per_rev_mm``, else ``process.feed_per_rev``), the
    material ``resp``'s burr coefficient, the smoothing max(feed, 2 pixels) that removes
    the feed marks), or None where none are added (no material, ``material.burrs`` off,
    or ``[artifacts.burrs] height`` set in their place)."""
    if resp is None or not cfg.material.burrs or cfg.burrs.height > 0:
        return None
    sim = cfg.simulation
    feed = float(path.meta.get("feed_per_rev_mm") or cfg.process.feed_per_rev)
    h_u = uncut_chip_thickness(feed, cfg.process.depth_of_cut, tool.nose_radius)
    return {"chip_thickness": h_u, "coefficient": resp.burr_coefficient, "seed": int(sim.seed),
            "edge_angle_deg": cfg.burrs.edge_angle_deg, "variation": cfg.burrs.variation,
            "smoothing": max(feed, 2 * sim.pixel), "width": BURR_WIDTH_PER_CHIP * h_u}


def turn(cfg: TurningInputs, surface: Any, path: Any, *, z_fts: np.ndarray | None = None,
         burrs: bool = True, region: Sequence[float] | None = None, plots: bool = True,
         design: np.ndarray | None = None,
         progress: Callable[[int, int], Any] | None = None) -> Turned:
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
    progress : callable(done, total), optional
        Called between the row blocks of the material's cut (rows done, rows in all); it
        may raise to stop the cut.

    Returns
    -------
    Turned
        A path cut turning M04 (:mod:`~render_inspect.processes._spindle`) is cut as the
        same path turning M03 on the mirrored design over the mirrored region; its maps
        and figures are flipped back into the part's own coordinates.
    """
    sim = cfg.simulation
    region = tuple(sim.region) if region is None else tuple(region)
    part_region, mirror = region, turns_m04(path)
    if mirror:  # the M03 run of the mirror image (its design given flipped too)
        region = mirrored_region(region, sim.pixel)
        surface = MirroredSurface(surface)
        design = None if design is None else flip_rows(np.array(design, dtype=np.float64))

    def framed(spec: dict) -> dict:
        """A figure of the maps in the part's own coordinates."""
        return {k: part_figure(v, part_region) for k, v in spec.items()} if mirror else spec
    tool = Tool.from_config(cfg.tool)
    resp = material_of(cfg.material)
    shape = grid_shape(region, sim.pixel)
    # the part's texture is a matrix product that needs nothing of the cut: once the machine
    # has followed the program, it is computed on a thread of its own while the cut's path
    # is prepared and the cut's figures and facts are made (steps that leave a core idle),
    # and waits while the cut takes every core (TextureJob; closed whatever happens)
    textured = resp is not None and resp.texture_rms > 0
    job = None
    try:
        timing, figs = {}, {}
        # the cut's maps get their memory from the system on a spare core while the machine
        # follows the program (core.pages): the machined heights, the passes' angles and the
        # displaced material or, with the part's texture, its unit field in its place
        maps = Prefaulted(shape, 3) if resp is not None else None
        t0 = time.perf_counter()
        cut_path, fp, facts = follow(cfg, path, z_fts=z_fts)
        timing["machine"] = time.perf_counter() - t0
        # the following-error figures are handed over as soon as each can be made (the time
        # series now, the map once the passes' angles are known), to be drawn while the part
        # is cut (core.handoff); they stay in the cut's plots too
        error_figures = plots and not fp.ideal
        if error_figures:
            figs.update(following_error_series_plot(fp, name=cut_name(cfg)))
            hand_over(figs)
        t0 = time.perf_counter()
        design_out = None
        if resp is None:
            machined = simulate_turning(cut_path, nose_radius=tool.nose_radius, region=region,
                                        pixel=sim.pixel, half_width=tool.half_width, edge=tool.edge)
            if error_figures:
                # the passes' angles on the figure's points only (the same numbers as those
                # points of the whole map, which nothing else needs), drawn meanwhile
                stride = map_figure_stride(grid_shape(region, sim.pixel))
                error_map = framed(following_error_map_plot(
                    fp, pass_angle_map(cut_path, region, sim.pixel, stride=stride), region,
                    sim.pixel * stride, name=cut_name(cfg)))
                figs.update(error_map)
                hand_over(error_map)
        else:
            # the fast kernel of the direct model (machining.cut_turning_mechanics +
            # finish_surface), in row blocks; the texture's thread waits meanwhile (the cut
            # takes every core)
            out = maps.take() if maps is not None else None
            if textured and out is not None:
                job = TextureJob(*texture_grid(region, sim.pixel, shape), resp.texture_length,
                                 texture_of(cfg, resp)[2], out=out.pop())
            cp = material_cut_path(cut_path, tool, resp, worn_h_min(cfg, cut_path, resp))
            if job is not None:
                job.pause()
            c = cut_turning(cp, grooves_of(cfg, resp), region=region, pixel=sim.pixel, progress=progress,
                            out=out, keep_added=job is None)
            if job is not None:
                job.resume()
            maps = out = None
            del cp
            pass_theta, machined, added = c.pop("pass_theta"), c.pop("machined"), c.pop("added", None)
            if error_figures:
                error_map = framed(following_error_map_plot(fp, pass_theta, region, sim.pixel,
                                                            name=cut_name(cfg)))
                figs.update(error_map)
                hand_over(error_map)
            info = mechanics_facts(resp, grooves_sumsq=c["grooves_sumsq"], grooves_n=c["grooves_n"],
                                   added_max=c["added_max"],
                                   edge_pixels=machined_edge_count(pass_theta, jump=math.pi))
            # pass_theta (its figure made) and the added material's map (where kept) are not
            # needed further: the texture's squares are computed in the first, its unit field
            # in the second (or taken from its thread), the texture is added into the cut's own
            # map, and the design is sampled into the unit field's map (memory already touched,
            # not three new maps)
            unit = job.result() if job is not None else None
            machined, info["texture_measured_rms_nm"] = add_texture(
                machined, resp, region, sim.pixel, texture_of(cfg, resp)[2], overwrite=True,
                buffers=(pass_theta,) if added is None else (added, pass_theta), unit=unit)
            pass_theta = None
            spare = unit if unit is not None else added
            if spare is not None and spare.shape == shape and spare.dtype == np.float64 \
                    and spare.flags.c_contiguous and not np.may_share_memory(spare, machined):
                design_out = spare
            del c, added, unit, spare
            facts["material"] = {**resp.to_dict(), **info}
            if resp.validity:
                log.warning("%s", resp.validity)
        timing["envelope"] = time.perf_counter() - t0
        t0 = time.perf_counter()
        if design is None:
            design = design_grid(surface, region, sim.pixel, out=design_out)
        del design_out
        timing["design"] = time.perf_counter() - t0
        feed = float(path.meta.get("feed_per_rev_mm") or cfg.process.feed_per_rev)
        facts["scallop"] = feed_scallop(feed, tool.nose_radius)
        if burrs and cfg.burrs.height > 0:
            b = cfg.burrs
            machined, facts["burrs"] = apply_burrs(
                machined, design, pixel=sim.pixel, origin=(region[0], region[1]), height=b.height,
                width=b.width, variation=b.variation, edge_angle_deg=b.edge_angle_deg,
                correlation_length=b.correlation_length, seed=int(sim.seed), edges_from="machined",
                smoothing=max(feed, 2 * sim.pixel))
        elif burrs and (args := material_burr_args(cfg, resp, path, tool)) is not None:
            t0 = time.perf_counter()
            # (machined is this cut's own array: the burrs are added in place)
            machined, facts["burrs"] = material_burrs(machined, design, pixel=sim.pixel,
                                                      origin=(region[0], region[1]),
                                                      overwrite=True, **args)
            timing["burrs"] = time.perf_counter() - t0
        if mirror:  # the part's own coordinates from here on
            machined, design, region = flip_rows(machined), flip_rows(design), part_region
        if "tool_wear" in facts:
            facts["tool_wear"]["roughness_against_radius"] = roughness_against_radius(
                cfg, machined, design, region, sim.pixel)
            if plots:
                figs["tool_wear.png"] = wear_figure(cfg, facts["tool_wear"])
        if tool.edge is not None:
            facts["tool_edge"], edge_figs = edge_facts(tool, str(path.meta.get("compensation", "")), machined,
                                                       design, region, sim.pixel, name=cut_name(cfg))
            if plots:
                figs.update(edge_figs)
        return Turned(machined=machined, design=design, timing=timing, facts=facts,
                      followed=None if fp.ideal else cut_path, followed_path=fp, plots=figs)
    finally:
        if job is not None:
            job.close()


def follow(cfg: TurningInputs, path: Any, *,
           z_fts: np.ndarray | None = None) -> tuple[ToolPath, FollowedPath, dict]:
    """The program ``path`` followed by the ``[machine]`` (its axes, error motions; seeded
    by ``simulation.seed``): (the path the tool follows, the FollowedPath, the facts
    ``machine`` and ``following_error``).  On an ideal machine the path is ``path``
    itself.  A tiled simulation follows the whole program once and cuts each tile from
    the run of the followed path that reaches it."""
    machine = machine_of(cfg.machine)
    sectors = path.meta.get("sectors", {})
    fp = follow_turning(path.t, path.theta, path.rho, path.z, machine, z_fts=z_fts,
                        seed=int(cfg.simulation.seed), sector=sectors.get("full_rad"))
    cut_path = path if fp.ideal else ToolPath(fp.theta, fp.rho, fp.z, fp.t,
                                              {**path.meta, "followed": machine.name})
    sector = sectors.get("sector_rad")
    if sector is not None and not fp.ideal:
        # a windowed plan: the errors of the passes over the window (between the sectors
        # the program is sparse and the loops settle)
        fp.errors = mask_outside_sector(fp.commanded["theta"], fp.errors, sector)
    # (settings: the machining model's units, mm, rad and s; scene_settings: the
    # [machine] keys and units, its preset's values filled in)
    facts = {"machine": {"preset": cfg.machine.preset, "ideal": fp.ideal,
                         "settings": machine.to_dict(), "scene_settings": machine_settings(cfg.machine),
                         "ticks": int(fp.t.size)}}
    if sectors.get("full_rad") is not None and not fp.ideal:
        # the ticks the Z slide and the FTS were followed over (the rest: between sectors)
        facts["machine"]["ticks_in_sectors"] = fp.sector_ticks
    if not fp.ideal:
        facts["following_error"] = following_error_stats(fp.errors)
    if getattr(cfg.tool, "wear", False):  # the worn edge at each point of the path
        cut_path, facts["tool_wear"] = wear_path(cfg, path, cut_path)
    return cut_path, fp, facts
