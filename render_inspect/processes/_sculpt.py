"""Vibration-assisted diamond sculpturing (HFUVAS, seed 003) of a quadrilateral lenslet array.

Linear X-Y-Z cutting, not turning: the tool moves along target lines x = x_k (the
lenslets' symmetry lines, one per column of cells) in the cutting direction y, with an
ultrasonic vibration along the cut; the kernels and their geometry are described in
:mod:`render_inspect.machining._sculpt`.
"""

from __future__ import annotations

import math
import time
from typing import Literal

import numpy as np
from pydantic import Field

from ..core.errors import AccessibilityError, InputError, SceneError
from ..core.grid import grid_shape
from ..core.limits import Driver, format_number
from ..core.section import Section
from ..core.toolpath import LinearProgram
from ..machining import (
    apply_burrs,
    cut_lines_mechanics,
    finish_surface,
    sculpt_line_profile,
    sculpt_surface,
    target_line,
    vibration_phases,
)
from ._mechanics import material_of, vibration_contact
from ._registry import Cut, Plan, Variant, VariantPair, check_budget, register_process
from ._turning import burrs_of

__all__ = ["SculptProcessConfig", "lattice_lines"]


class SculptProcessConfig(Section):
    """``[process]`` of sculpturing: the tool edge is swept along straight target lines."""
    kind: Literal["sculpt"]
    feed_mm_per_min: float = Field(100.0, gt=0, le=100000,
                                   description="nominal cutting speed v_c along the lines, mm/min")
    arc_length: float = Field(0.0025, gt=0, description="mm, target-line sampling step")
    depth_of_cut: float = Field(0.003, ge=0, description="mm (recorded only)")
    allow_gouge: bool = Field(False, description="simulate even if the clearance angle is too small")
    compensation: Literal["none", "normal", "z"] = Field(
        "none", description="not used: the edge follows the target line (no nose compensation)")

    def check_with(self, scene) -> None:
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


def lattice_lines(surface, *, pitch_y: float) -> tuple[np.ndarray, np.ndarray]:
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


def _half_width(scene) -> float:
    R = scene.tool.nose_radius
    return R * math.sin(min(math.radians(scene.tool.included_angle_deg) / 2, math.pi / 2))


def plan(scene, surface, *, region=None) -> Plan:
    """The commanded program: every target line (or, with ``region``, the lines and cells
    whose cut can reach it), without the vibration (the NC program the machine gets)."""
    t0 = time.perf_counter()
    x_lines, y_edges = lattice_lines(surface, pitch_y=scene.design.pitch_y)
    vc = scene.process.feed_mm_per_min / 60.0
    y_line_start = float(y_edges[0])
    used = list(range(len(x_lines)))
    if region is not None:
        x0, y0, x1, y1 = region
        hw = _half_width(scene)
        used = [k for k, xk in enumerate(x_lines) if xk + hw >= x0 and xk - hw <= x1]
        # only the cells along y whose cut can reach the region (the vibration reaches A
        # beyond the nominal position; one whole cell of run-in is kept on either side)
        reach = 2 * scene.artifacts.vibration.amplitude + scene.simulation.pixel
        ia = max(int(np.searchsorted(y_edges, y0 - reach, side="right")) - 2, 0)
        ib = min(int(np.searchsorted(y_edges, y1 + reach, side="left")) + 1, len(y_edges) - 1)
        y_edges = y_edges[ia:ib + 1]
    if not used or y_edges.size < 2:
        d = scene.design
        raise InputError(
            f"simulation.region {list(region)} mm lies outside the lenslet array: its "
            f"{len(x_lines)} target lines run at x = {float(x_lines[0]):.6g} .. "
            f"{float(x_lines[-1]):.6g} mm (design.center_x = {d.center_x:g}, pitch_x = "
            f"{d.pitch_x:g}) over y = {float(y_line_start):.6g} .. "
            f"{float(y_line_start) + d.rows * d.pitch_y:.6g} mm; move the region onto the array")
    lines = [target_line(surface, x_lines[k], y_edges, step=scene.process.arc_length)
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
                         {"kind": "sculpt", "feed_mm_per_min": scene.process.feed_mm_per_min})
    cut_time = float(sum((ys[-1] - ys[0]) / vc for ys, _ in lines))
    facts = {"toolpath": {"points": int(prog.points), "revolutions": 0.0, "feed_per_rev_mm": None,
                          "kind": "sculpt", "lines": len(used),
                          "line_spacing_mm": float(np.median(np.diff(x_lines))) if len(x_lines) > 1 else None,
                          "cut_time_s": cut_time}}
    data = {"lines": lines, "x_lines": x_lines[used], "y_line_start": y_line_start,
            "cut_time_s": cut_time}
    return Plan(prog, facts, {"toolpath": time.perf_counter() - t0}, data)


def cut(scene, surface, plan: Plan) -> Cut:
    sim = scene.simulation
    x0, y0, x1, y1 = sim.region
    ny, nx = grid_shape(sim.region, sim.pixel)
    px = sim.pixel
    xg = x0 + px * np.arange(nx)
    yg = y0 + px * np.arange(ny)
    R = scene.tool.nose_radius
    half_width = _half_width(scene)
    vc = scene.process.feed_mm_per_min / 60.0
    vib = scene.artifacts.vibration
    spp = vib.samples_per_period
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
    # the material's response: intermittent cutting (contact ratio) against adhesion
    resp = material_of(scene, contact=vibration_contact(scene, vc))
    material_facts = None
    if resp is not None:
        c = cut_lines_mechanics(prof_vib, xl, xg, tool_radius=R, half_width=half_width,
                                h_min=resp.h_min, kappa=resp.kappa, side_flow=resp.side_flow)
        # cutting distance: along the line, lines cut one after another
        line_len = float(np.max([ys[-1] - ys[0] for ys, _ in lines])) if lines else 0.0
        along = np.broadcast_to(yg[:, None] + line_len * np.nan_to_num(c["pass_line"]),
                                c["machined"].shape)
        machined, info = finish_surface(c, resp, along=along, seed=int(sim.seed) + 1,
                                        across_length=scene.material.groove_across_um * 1e-3,
                                        along_length=scene.material.groove_along_mm)
        material_facts = {**resp.to_dict(), **info}
    t_sim = time.perf_counter() - t_sim
    b = burrs_of(scene)
    machined, burr_info = apply_burrs(machined, design, pixel=px, origin=(x0, y0),
                                      edges_from="machined", smoothing=2 * px, **b)
    per_period = (len(vibration_phases(vc, vib.amplitude, vib.frequency_hz, spp))
                  if vib.amplitude > 0 and vib.frequency_hz > 0 else 0)
    n_time = sum(int(math.ceil((ys[-1] - ys[0]) / vc * vib.frequency_hz * per_period)) + ys.size
                 for ys, _ in lines)
    facts = {
        "sculpt": {"lines": len(lines), "line_x_mm": [float(v) for v in xl],
                   "cutting_speed_mm_s": vc, "target_step_mm": scene.process.arc_length,
                   "target_points": int(sum(ys.size for ys, _ in lines)),
                   "time_samples": n_time,
                   "tool_radius_mm": R, "max_slope_deg": max_slope_deg,
                   "vibration_overcut_um": float(max(vib_over, 0.0) * 1e3),
                   "tool_edge_overcut_um": float(max(edge_over, 0.0) * 1e3),
                   "cutting_time_s": plan.data["cut_time_s"]},
        "vibration": {"frequency_hz": vib.frequency_hz, "amplitude_mm": vib.amplitude,
                      "samples_per_period": spp,
                      "peak_velocity_mm_s": 2 * math.pi * vib.frequency_hz * vib.amplitude},
        "burrs": burr_info,
    }
    if material_facts is not None:
        facts["material"] = material_facts
    meta = {"process": "sculpt", "seed": int(sim.seed), "compensation": "none",
            "vibration": facts["vibration"], "burrs": burr_info,
            "material": scene.material.preset}
    return Cut(machined, design, facts, {"sweep": t_sim}, meta)


def estimate_memory(scene, plan=None) -> int:
    """Bytes at the peak: eight float64 maps of the grid (design, two cuts, profiles and
    temporaries)."""
    ny, nx = grid_shape(scene.simulation.region, scene.simulation.pixel)
    return 8 * 8 * ny * nx


def sculpt_variants(scene) -> VariantPair:
    """The pair ``compare`` puts side by side for sculpturing (which has no nose-radius
    compensation): the ultrasonic vibration on against off, or, when the scene has no
    vibration, the tool edge radius as set against half of it."""
    vib = scene.artifacts.vibration
    if vib.amplitude > 0 and vib.frequency_hz > 0:
        return VariantPair(
            Variant("vibration_on", f"vibration {vib.frequency_hz / 1e3:.4g} kHz, "
                                    f"{vib.amplitude * 1e3:.3g} um", {}),
            Variant("vibration_off", "no vibration", {"artifacts.vibration.amplitude": 0.0}),
            key="artifacts.vibration.amplitude",
            about=("Ultrasonic vibration along the cut on against off: the front and back "
                   "cut limits of each vibration cycle leave cut lines off the target, the "
                   "error growing with the slope and peaking at the edges between lenslets "
                   "(seed 003)."))
    r = scene.tool.nose_radius
    return VariantPair(
        Variant(f"edge_radius_{r:g}mm", f"tool edge radius {r:g} mm", {}),
        Variant(f"edge_radius_{r / 2:g}mm", f"tool edge radius {r / 2:g} mm",
                {"tool.nose_radius": r / 2}),
        key="tool.nose_radius",
        about=("Tool edge radius as set against half of it: the swept edge leaves the "
               "tool-edge overcut at the cusps between lenslets (seed 003)."))
#: bytes per target-line point while planning (the line arrays and the program's)
PLAN_BYTES_PER_POINT = 96


def precheck(scene, region=None) -> None:
    """Check the points of the target lines (every column's line over every row of cells,
    one point per ``process.arc_length``) against the memory budget before planning."""
    d = scene.design
    step = scene.process.arc_length
    n = d.cols * (d.rows * d.pitch_y / step + d.rows + 1)
    check_budget(scene, n * PLAN_BYTES_PER_POINT, what=f"the sculpturing program "
                 f"({format_number(n)} points on {d.cols} lines)",
                 drivers=[Driver("process.arc_length", step, -1, "mm")])


def program_header(scene) -> dict:
    vib = scene.artifacts.vibration
    return {"scene": scene.name, "process": "sculpt",
            "cutting_speed_mm_per_min": scene.process.feed_mm_per_min,
            "vibration_not_programmed": f"{vib.frequency_hz} Hz, {vib.amplitude} mm"}


register_process(SculptProcessConfig, plan=plan, cut=cut, estimate_memory=estimate_memory,
                 precheck=precheck,
                 program_header=program_header, variants=sculpt_variants)
