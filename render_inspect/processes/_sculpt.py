"""Vibration-assisted diamond sculpturing (HFUVAS; Zhang, Cheung, Liang and Bulla, Applied
Sciences) of a quadrilateral lenslet array.

Linear X-Y-Z cutting, not turning: the tool moves along target lines x = x_k (the
lenslets' symmetry lines, one per column of cells) in the cutting direction y, with an
ultrasonic vibration along the cut (``[artifacts.vibration]``, defined here); the kernels
and their geometry are described in :mod:`render_inspect.machining._sculpt`.
"""

from __future__ import annotations

from collections.abc import Sequence
import logging
import math
import time
from dataclasses import dataclass
from typing import Any, Literal, cast

import numpy as np
from pydantic import Field, model_serializer, model_validator

from ..design import LensletArrayConfig, Surface
from ..core.deprecation import warn_deprecated
from ..core.errors import AccessibilityError, InputError, SceneError
from ..core.grid import grid_shape
from ..core.limits import Driver, format_number
from ..core.marks import ToolMarks
from ..core.section import Section
from ..core.toolpath import LinearProgram, Links
from ..core.units import HZ_TO_KHZ, MIN_TO_S, MM_TO_UM, UM_TO_MM
from ._program import imported_sculpt_plan
from ..machining import (
    WEAR_RATES,
    apply_burrs,
    contact_ratio,
    cut_lines_mechanics,
    finish_surface,
    material_burrs,
    sculpt_line_profile,
    sculpt_surface,
    target_line,
    vibration_phases,
)
from ..toolpath import (DEFAULT_CLEARANCE, DEFAULT_PLUNGE_FEED, MIN_CLEARANCE, MachineLimits,
                        PartModel, linear_block_rate, longest_step)
from ._contract import Cut, Inputs, Plan, Process, Traits, Variant, VariantPair, section
from ._machine import MaterialConfig, ProcessScene, material_of
from ._program_part import design_part, machine_limits
from ._mechanics import BurrConfig, add_texture, burrs_of
from ._registry import check_budget, register_process, register_retired_key, register_section
from ._wear_facts import sculpt_wear

log = logging.getLogger("render_inspect")

__all__ = ["SculptProcessConfig", "SculptProcess", "SculptInputs", "VibrationConfig",
           "lattice_lines"]


class VibrationConfig(Section):
    """``[artifacts.vibration]``: the ultrasonic vibration along the cut of sculpturing."""
    frequency_hz: float = Field(0.0, ge=0, le=1e7)
    amplitude: float = Field(0.0, ge=0, le=0.1, description="mm")
    samples_per_period: int = Field(16, ge=4, le=1000, description="time samples per vibration period")


register_section("artifacts.vibration", VibrationConfig)
register_retired_key("process.compensation", None,
                     "process.kind 'sculpt': sculpturing has no nose-radius compensation")


class SculptProcessConfig(Section):
    """``[process]`` of sculpturing: the tool edge is swept along straight target lines."""
    kind: Literal["sculpt"]
    feed_mm_per_min: float = Field(100.0, gt=0, le=100000,
                                   description="nominal cutting speed v_c along the lines, mm/min")
    arc_length: float = Field(0.0025, gt=0, description="mm, target-line sampling step")
    depth_of_cut: float = Field(0.003, ge=0, le=1.0,
                                description="mm, depth of the finishing (last) layer: the "
                                            "uncut chip thickness of the material's burrs")
    allow_gouge: bool = Field(False, description="simulate even if the clearance angle is too small")
    clearance: float = Field(DEFAULT_CLEARANCE, ge=MIN_CLEARANCE, le=100,
                             description="mm above the part's highest point (stock included): "
                                         "the clearance plane the program's rapid moves between "
                                         "the lines run in")
    plunge_feed_mm_per_min: float = Field(DEFAULT_PLUNGE_FEED, gt=0, le=100000,
                                          description="feed of the vertical plunge onto each "
                                                      "line and of the retract from it")
    program: str | None = Field(None, min_length=1, max_length=4096,
                                description="an X-Y-Z machine program file (path relative to "
                                            "the scene file) simulated in place of the planned "
                                            "lines; docs/programs.md")
    block_rate_limit_per_s: float | None = Field(
        None, gt=0, le=10_000_000, description="blocks per second the machine's control processes; "
                                        "unset: 1000 (toolpath.block_rate)")
    program_integers: Literal["whole", "IS-A", "IS-B", "IS-C", "IS-D", "IS-E"] = Field(
        "whole", description="how the program's numbers without a decimal point are read: "
                             "whole mm / in / deg, or least input increments of the "
                             "control's increment system (IS-B: X2000 is 2 mm)")

    @model_serializer(mode="wrap")
    def _without_program(self, handler):
        """``program`` and the block rate limit are written only when set, how the
        program's integers are read only when not the default (scenes dump as before)."""
        data = handler(self)
        if isinstance(data, dict) and data.get("program") is None:
            data.pop("program", None)
        if isinstance(data, dict) and data.get("block_rate_limit_per_s", 0) is None:
            data.pop("block_rate_limit_per_s")
        if isinstance(data, dict) and data.get("program_integers") == "whole":
            data.pop("program_integers")
        return data

    @model_validator(mode="before")
    @classmethod
    def _retired_compensation(cls, data):
        """``process.compensation`` meant nothing for sculpturing (the edge follows the
        target line): accepted with a warning and dropped."""
        if isinstance(data, dict) and "compensation" in data:
            warn_deprecated("process.compensation", None,
                            "sculpturing has no nose-radius compensation")
            data = {k: v for k, v in data.items() if k != "compensation"}
        return data

    def check_with(self, scene: ProcessScene) -> None:
        if scene.machine.preset != "ideal":
            raise ValueError(
                "machine.preset must be 'ideal' for process.kind = 'sculpt' (the machine model "
                f"is a turning lathe's C-X-Z axes), received {scene.machine.preset!r}")
        d = scene.design
        if getattr(d, "type", None) != "lenslet_array" or getattr(d, "cells", None) != "quad":
            raise ValueError(
                "process.kind = 'sculpt' needs design.type = 'lenslet_array' with cells = 'quad' "
                f"(sharp-edged cells along the symmetry lines), received design.type = "
                f"{getattr(d, 'type', None)!r}" + (f", cells = {d.cells!r}" if hasattr(d, "cells") else ""))
        if scene.tool.edge_profile or scene.tool.waviness:
            raise ValueError("tool.edge_profile and tool.waviness describe a measured edge the turning "
                             "processes cut with (sts, fts, hts, rcse); sculpturing sweeps a circular "
                             "edge of tool.nose_radius: remove them, received "
                             + ", ".join(f"{k} = {getattr(scene.tool, k)!r}" for k in ("edge_profile", "waviness")
                                         if getattr(scene.tool, k)))
        if getattr(scene.tool, "wear", False):
            if scene.material.preset not in WEAR_RATES:
                raise ValueError(f"tool.wear wears the edge at the rates of material.preset, one of "
                                 f"{', '.join(sorted(WEAR_RATES))}; received material.preset "
                                 f"{scene.material.preset!r}")


def lattice_lines(surface: Surface, *, pitch_y: float) -> tuple[np.ndarray, np.ndarray]:
    """Target-line positions x_k (the columns' symmetry lines) and the cell edges along y
    of a quadrilateral lenslet array: (x_lines, y_edges), mm."""
    if not hasattr(surface, "centers"):
        raise SceneError("process.kind = 'sculpt' needs design.type = 'lenslet_array'")
    centers = np.asarray([c[-2:] for c in surface.centers()], dtype=np.float64).reshape(-1, 2)
    xs = np.unique(np.round(centers[:, 0], 12))
    yc = np.unique(np.round(centers[:, 1], 12))
    py = float(pitch_y)
    edges = np.concatenate([[yc[0] - py / 2], 0.5 * (yc[1:] + yc[:-1]), [yc[-1] + py / 2]])
    return xs, edges


@dataclass(frozen=True)
class SculptInputs(Inputs):
    """What sculpturing reads: ``[process]``, ``[tool]``, ``[simulation]``, the lenslet
    array of ``[design]``, ``[material]``, ``[artifacts.vibration]`` and
    ``[artifacts.burrs]``."""

    process: SculptProcessConfig
    # (a quad lenslet array: the scene is refused otherwise, SculptProcessConfig.check_with)
    design: LensletArrayConfig
    material: MaterialConfig
    vibration: VibrationConfig = section("artifacts.vibration")
    burrs: BurrConfig = section("artifacts.burrs")


def _half_width(tool) -> float:
    R = tool.nose_radius
    return R * math.sin(min(math.radians(tool.included_angle_deg) / 2, math.pi / 2))


def _plan(cfg: SculptInputs, surface, *, region=None) -> Plan:
    """The commanded program: every target line (or, with ``region``, the lines and cells
    whose cut can reach it), without the vibration (the NC program the machine gets)."""
    t0 = time.perf_counter()
    x_lines, y_edges = lattice_lines(surface, pitch_y=cfg.design.pitch_y)
    vc = cfg.process.feed_mm_per_min / MIN_TO_S
    y_line_start = float(y_edges[0])
    used = list(range(len(x_lines)))
    if region is not None:
        x0, y0, x1, y1 = region
        hw = _half_width(cfg.tool)
        used = [k for k, xk in enumerate(x_lines) if xk + hw >= x0 and xk - hw <= x1]
        # only the cells along y whose cut can reach the region (the vibration reaches A
        # beyond the nominal position; one whole cell of run-in is kept on either side)
        reach = 2 * cfg.vibration.amplitude + cfg.simulation.pixel
        ia = max(int(np.searchsorted(y_edges, y0 - reach, side="right")) - 2, 0)
        ib = min(int(np.searchsorted(y_edges, y1 + reach, side="left")) + 1, len(y_edges) - 1)
        y_edges = y_edges[ia:ib + 1]
    if not used or y_edges.size < 2:
        d = cfg.design
        raise InputError(
            f"simulation.region {list(region)} mm lies outside the lenslet array: its "
            f"{len(x_lines)} target lines run at x = {float(x_lines[0]):.6g} .. "
            f"{float(x_lines[-1]):.6g} mm (design.center_x = {d.center_x:g}, pitch_x = "
            f"{d.pitch_x:g}) over y = {float(y_line_start):.6g} .. "
            f"{float(y_line_start) + d.rows * d.pitch_y:.6g} mm; move the region onto the array")
    lines = [target_line(surface, x_lines[k], y_edges, step=cfg.process.arc_length)
             for k in used]
    xs, ys_all, zs_all, ts, ks = [], [], [], [], []
    t = 0.0
    for k, (ys, zs) in zip(used, lines):
        xs.append(np.full(ys.size, x_lines[k]))
        ys_all.append(ys)
        zs_all.append(zs)
        ts.append(t + (ys - ys[0]) / vc)
        ks.append(np.full(ys.size, k, dtype=np.int64))
        t = ts[-1][-1]
    prog = LinearProgram(np.concatenate(xs), np.concatenate(ys_all), np.concatenate(zs_all),
                         np.concatenate(ts), np.concatenate(ks),
                         {"kind": "sculpt", "feed_mm_per_min": cfg.process.feed_mm_per_min})
    cut_time = float(sum((ys[-1] - ys[0]) / vc for ys, _ in lines))
    facts = {"toolpath": {"points": int(prog.points), "revolutions": 0.0, "feed_per_rev_mm": None,
                          "kind": "sculpt", "lines": len(used),
                          "line_spacing_mm": float(np.median(np.diff(x_lines))) if len(x_lines) > 1 else None,
                          "cut_time_s": cut_time,
                          # (the blocks the control reads: each move along a line at the
                          # programmed feed)
                          "block_rate": linear_block_rate(
                              prog.x, prog.y, prog.z, prog.line, cfg.process.feed_mm_per_min,
                              limit=cfg.process.block_rate_limit_per_s)}}
    data = {"lines": lines, "x_lines": x_lines[used], "y_line_start": y_line_start,
            "cut_time_s": cut_time}
    return Plan(prog, facts, {"toolpath": time.perf_counter() - t0}, data)


def _cut(cfg: SculptInputs, surface, plan: Plan) -> Cut:
    sim = cfg.simulation
    x0, y0, x1, y1 = sim.region
    ny, nx = grid_shape(sim.region, sim.pixel)
    px = sim.pixel
    xg = x0 + px * np.arange(nx)
    yg = y0 + px * np.arange(ny)
    R = cfg.tool.nose_radius
    half_width = _half_width(cfg.tool)
    vc = cfg.process.feed_mm_per_min / MIN_TO_S
    vib = cfg.vibration
    spp = vib.samples_per_period
    design = surface.sample(sim.region, px)[2]
    # accessibility: clearance angle vs the largest slope along the cut (rake 0)
    gy = np.abs(surface.gradient(xg[None, ::4], yg[::4, None])[1])
    max_slope_deg = float(np.degrees(np.arctan(np.nanmax(gy)))) if gy.size else 0.0
    clearance = cfg.tool.clearance_angle_deg
    if max_slope_deg >= clearance and not cfg.process.allow_gouge:
        raise AccessibilityError(
            f"tool.clearance_angle_deg must exceed the largest slope along the cutting direction "
            f"({max_slope_deg:.2f} deg), received {clearance}; use a larger clearance angle or "
            "set process.allow_gouge = true")
    lines, xl = plan.data["lines"], plan.data["x_lines"]
    y_line_start = plan.data["y_line_start"]
    t_sim = time.perf_counter()
    prof_vib = np.array([sculpt_line_profile(ys, zs, yg, cutting_speed=vc, amplitude=vib.amplitude,
                                             frequency_hz=vib.frequency_hz, samples_per_period=spp,
                                             t_start=(ys[0] - y_line_start) / vc)
                         for ys, zs in lines]).reshape(len(lines), ny)
    prof_0 = np.array([sculpt_line_profile(ys, zs, yg, cutting_speed=vc)
                       for ys, zs in lines]).reshape(len(lines), ny)
    machined_0 = sculpt_surface(prof_0, xl, xg, tool_radius=R, half_width=half_width)
    machined = sculpt_surface(prof_vib, xl, xg, tool_radius=R, half_width=half_width)
    with np.errstate(invalid="ignore"):
        vib_over = np.nanmax(machined_0 - machined) if np.isfinite(machined).any() else 0.0
        edge_over = np.nanmax(design - machined_0) if np.isfinite(machined_0).any() else 0.0
    # the material's response (the vibration's contact ratio is reported: no source relates
    # it to the surface left; continuous cutting of steel is outside the model)
    eta = contact_ratio(vc, vib.amplitude, vib.frequency_hz)
    wear_facts = None
    if getattr(cfg.tool, "wear", False):  # the edge worn over the cut, at the vibration's duty cycle
        mat_cfg, wear_facts = sculpt_wear(cfg, lines, eta)
        resp = material_of(mat_cfg, contact=eta)
    else:
        resp = material_of(cfg.material, contact=eta)
    material_facts = None
    if resp is not None:
        c = cut_lines_mechanics(prof_vib, xl, xg, tool_radius=R, half_width=half_width,
                                h_min=resp.h_min, kappa=resp.kappa, side_flow=resp.side_flow)
        # cutting distance: along the line, lines cut one after another
        line_len = float(np.max([ys[-1] - ys[0] for ys, _ in lines])) if lines else 0.0
        along = np.broadcast_to(yg[:, None] + line_len * np.nan_to_num(c["pass_line"]),
                                c["machined"].shape)
        machined, info = finish_surface(c, resp, along=along, seed=int(sim.seed) + 1,
                                        across_length=cfg.material.groove_across_um * UM_TO_MM,
                                        along_length=cfg.material.groove_along_mm)
        machined, info["texture_measured_rms_nm"] = add_texture(machined, resp, sim.region, px,
                                                                int(sim.seed) + 2)
        material_facts = {**resp.to_dict(), **info}
        if resp.validity:
            log.warning("%s", resp.validity)
    t_sim = time.perf_counter() - t_sim
    b = burrs_of(cfg.burrs, sim.seed)
    if cfg.burrs.height == 0 and resp is not None and cfg.material.burrs:
        machined, burr_info = material_burrs(
            machined, design, pixel=px, origin=(x0, y0), chip_thickness=cfg.process.depth_of_cut,
            coefficient=resp.burr_coefficient, variation=b["variation"], seed=b["seed"],
            edge_angle_deg=b["edge_angle_deg"], smoothing=2 * px)
    else:
        machined, burr_info = apply_burrs(machined, design, pixel=px, origin=(x0, y0),
                                          edges_from="machined", smoothing=2 * px, **b)
    per_period = (len(vibration_phases(vc, vib.amplitude, vib.frequency_hz, spp))
                  if vib.amplitude > 0 and vib.frequency_hz > 0 else 0)
    n_time = sum(int(math.ceil((ys[-1] - ys[0]) / vc * vib.frequency_hz * per_period)) + ys.size
                 for ys, _ in lines)
    facts = {
        "sculpt": {"lines": len(lines), "line_x_mm": [float(v) for v in xl],
                   "cutting_speed_mm_s": vc, "target_step_mm": cfg.process.arc_length,
                   "target_points": int(sum(ys.size for ys, _ in lines)),
                   "time_samples": n_time,
                   "tool_radius_mm": R, "max_slope_deg": max_slope_deg,
                   "vibration_overcut_um": float(max(vib_over, 0.0) * MM_TO_UM),
                   "tool_edge_overcut_um": float(max(edge_over, 0.0) * MM_TO_UM),
                   "cutting_time_s": plan.data["cut_time_s"]},
        "vibration": {"frequency_hz": vib.frequency_hz, "amplitude_mm": vib.amplitude,
                      "samples_per_period": spp,
                      "peak_velocity_mm_s": 2 * math.pi * vib.frequency_hz * vib.amplitude},
        "burrs": burr_info,
    }
    if material_facts is not None:
        facts["material"] = material_facts
    if wear_facts is not None:
        facts["tool_wear"] = wear_facts
    meta = {"process": "sculpt", "seed": int(sim.seed), "compensation": "none",
            "vibration": facts["vibration"], "burrs": burr_info,
            "material": cfg.material.preset}
    return Cut(machined, design, facts, {"sweep": t_sim}, meta)


#: bytes per target-line point while planning (the line arrays and the program's)
PLAN_BYTES_PER_POINT = 96
#: samples per second of the sculpturing sweep (the progress bar's estimate)
CUT_RATE = 5e5


class SculptProcess(Process[SculptInputs]):
    """Sculpturing: one target line per column of cells, the edge swept along it."""

    config = SculptProcessConfig
    inputs = SculptInputs

    def plan(self, cfg: SculptInputs, surface: Surface, *,
             region: Sequence[float] | None = None) -> Plan:
        """The commanded program: every target line (or, with ``region``, the lines and
        cells whose cut can reach it), without the vibration (the NC program the machine
        gets); or the X-Y-Z program of ``process.program`` read from its file."""
        if cfg.process.program:
            return imported_sculpt_plan(self, cfg, surface)
        return _plan(cfg, surface, region=region)

    def cut(self, cfg: SculptInputs, surface: Surface, plan: Plan) -> Cut:
        return _cut(cfg, surface, plan)

    def estimate_memory(self, cfg: SculptInputs, plan: Plan | None = None) -> int:
        """Bytes at the peak: eight float64 maps of the grid (design, two cuts, profiles
        and temporaries)."""
        ny, nx = grid_shape(cfg.simulation.region, cfg.simulation.pixel)
        return 8 * 8 * ny * nx

    def traits(self, cfg: SculptInputs) -> Traits:
        """Straight marks along the cut, one per vibration cycle (cutting speed / vibration
        frequency; none without vibration); the simulated region is the part."""
        vib = cfg.vibration
        period = pv = None
        if vib.frequency_hz > 0 and vib.amplitude > 0:
            period = (cfg.process.feed_mm_per_min / MIN_TO_S) / vib.frequency_hz
            pv = 2 * vib.amplitude
        return Traits(name=cfg.process.kind,
                      marks=ToolMarks("linear", period, float(cfg.tool.nose_radius), pv_mm=pv,
                                      direction=(0.0, 1.0)),
                      cut_rate=CUT_RATE)

    def precheck(self, cfg: SculptInputs, region: Sequence[float] | None = None) -> None:
        if cfg.process.program:
            return  # a program file's size is known once it is read
        self._precheck(cfg, region)

    def _precheck(self, cfg: SculptInputs, region=None) -> None:
        """Check the points of the target lines (every column's line over every row of
        cells, one point per ``process.arc_length``) against the memory budget."""
        d = cfg.design
        step = cfg.process.arc_length
        n = d.cols * (d.rows * d.pitch_y / step + d.rows + 1)
        check_budget(cfg.simulation, n * PLAN_BYTES_PER_POINT, what=f"the sculpturing program "
                     f"({format_number(n)} points on {d.cols} lines)",
                     drivers=[Driver("process.arc_length", step, -1, "mm")])

    def program_header(self, cfg: SculptInputs) -> dict:
        vib = cfg.vibration
        return {"scene": cfg.name, "process": "sculpt",
                "cutting_speed_mm_per_min": cfg.process.feed_mm_per_min,
                "vibration_not_programmed": f"{vib.frequency_hz} Hz, {vib.amplitude} mm"}

    def program_plan(self, cfg: SculptInputs, surface: Any,
                     program: Any) -> Plan:
        """The plan of a sculpturing program read back from its file: its target lines
        (points grouped by ``line``) as the cut takes them."""
        _, y_edges = lattice_lines(surface, pitch_y=cfg.design.pitch_y)
        vc = cfg.process.feed_mm_per_min / MIN_TO_S
        lines, x_lines = [], []
        for k in np.unique(program.line):
            sel = program.line == k
            lines.append((np.asarray(program.y[sel], np.float64),
                          np.asarray(program.z[sel], np.float64)))
            x_lines.append(float(program.x[sel][0]))
        cut_time = float(sum((ys[-1] - ys[0]) / vc for ys, _ in lines))
        return Plan(program, {}, {}, {"lines": lines, "x_lines": np.asarray(x_lines),
                                      "y_line_start": float(y_edges[0]), "cut_time_s": cut_time})

    def program_links_part(self, cfg: SculptInputs, surface: Surface,
                           plan: Plan) -> tuple[Links, PartModel] | None:
        """None for a program read from a file (its own moves between the lines are part of
        it); else the clearance plane and plunge feed of the written program, and the
        part."""
        if cfg.process.program:
            return None
        return super().program_links_part(cfg, surface, plan)

    def program_part(self, cfg: SculptInputs, surface: Surface, plan: Plan) -> PartModel:
        """The lenslet array the program is checked against: the design over the cells
        (between the outer target lines' cell edges and the first and last row's edges),
        the depth of cut as stock."""
        d = cfg.design
        x_lines, y_edges = lattice_lines(surface, pitch_y=d.pitch_y)
        box = ("box", float(x_lines[0]) - d.pitch_x / 2, float(y_edges[0]),
               float(x_lines[-1]) + d.pitch_x / 2, float(y_edges[-1]))
        prog = cast(LinearProgram, plan.program)  # (an X-Y-Z program)
        return design_part(surface, box, stock=float(cfg.process.depth_of_cut),
                           half_width=_half_width(cfg.tool),
                           max_step=longest_step(prog.x, prog.y, prog.z, prog.line))

    def program_limits(self, cfg: SculptInputs) -> MachineLimits:
        """The machine's largest feed and travel (``machine.preset``); a plunge or
        retract enters the stock with the cutting edge and runs no faster than the
        cutting speed ``process.feed_mm_per_min``."""
        # sculpturing runs on the ideal machine preset only (its check_with)
        return machine_limits("ideal",
                              plunge_feed_mm_per_min=float(cfg.process.feed_mm_per_min),
                              plunge_source="the cutting speed process.feed_mm_per_min")

    def program_facts(self, cfg: SculptInputs, plan: Plan) -> dict:
        prog = cast(LinearProgram, plan.program)  # (an X-Y-Z program)
        facts = dict(plan.facts)
        tp = facts.setdefault("toolpath", {})
        tp.setdefault("points", prog.points)
        tp.setdefault("lines", prog.lines)
        tp.setdefault("kind", "sculpt")
        tp.setdefault("cut_time_s", prog.duration_s)
        return facts

    def variants(self, cfg: SculptInputs) -> VariantPair:
        """The ultrasonic vibration on against off, or, without vibration, the tool edge
        radius as set against half of it (sculpturing has no nose-radius compensation)."""
        vib = cfg.vibration
        if vib.amplitude > 0 and vib.frequency_hz > 0:
            return VariantPair(
                Variant("vibration_on", f"vibration {vib.frequency_hz * HZ_TO_KHZ:.4g} kHz, "
                                        f"{vib.amplitude * MM_TO_UM:.3g} um", {}),
                Variant("vibration_off", "no vibration", {"artifacts.vibration.amplitude": 0.0}),
                key="artifacts.vibration.amplitude",
                about=("Ultrasonic vibration along the cut on against off: the front and back "
                       "cut limits of each vibration cycle leave cut lines off the target, the "
                       "error growing with the slope and peaking at the edges between lenslets "
                       "(Zhang et al., Applied Sciences)."))
        r = cfg.tool.nose_radius
        return VariantPair(
            Variant(f"edge_radius_{r:g}mm", f"tool edge radius {r:g} mm", {}),
            Variant(f"edge_radius_{r / 2:g}mm", f"tool edge radius {r / 2:g} mm",
                    {"tool.nose_radius": r / 2}),
            key="tool.nose_radius",
            about=("Tool edge radius as set against half of it: the swept edge leaves the "
                   "tool-edge overcut at the cusps between lenslets (Zhang et al., Applied "
                   "Sciences)."))


register_process(SculptProcess())
