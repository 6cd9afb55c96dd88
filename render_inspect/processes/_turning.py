"""What every turning process (STS, FTS/HTS, RCSE) shares: the ``[process]`` keys of a
spiral turning program, the tool, the envelope cut on the simulation grid, and the memory
estimate."""

from __future__ import annotations

from typing import Literal

from pydantic import Field, model_validator

from ..core.grid import grid_shape
from ..core.limits import Driver, format_number, memory_budget
from ..core.section import Section
from ..design import make_surface
from ..machining._memory import in_memory_bytes
from ..toolpath import (
    Tool,
    kinematics,
    limits_from_process,
    plan_feed,
    plan_memory,
    plan_turning,
    region_radii,
    turning_point_count,
)
from ._mechanics import machine_of, turn
from ._registry import Variant, VariantPair, check_budget

__all__ = ["TurningProcessConfig", "tool_of", "plan_spiral", "cut_turning", "toolpath_facts",
           "turning_memory", "turning_points", "machine_bytes", "burrs_of", "turning_header",
           "compensation_variants", "turning_precheck"]


class TurningProcessConfig(Section):
    """Keys of a spiral turning program (STS, FTS/HTS, RCSE)."""
    spindle_rpm: float = Field(50.0, ge=1e-3, le=20000)
    feed_mm_per_min: float = Field(0.5, ge=1e-6, le=1000)
    workpiece_radius: float = Field(5.0, gt=0, le=500, description="mm, outer radius Rw of the spiral")
    inner_radius: float = Field(0.0, ge=0, description="mm, the spiral stops here")
    compensation: Literal["none", "normal", "z"] = "z"
    sampling: Literal["constant_angle", "constant_arc", "hybrid"] = "constant_angle"
    points_per_rev: int = Field(3600, ge=8, le=10_000_000, description="N, constant-angle sampling")
    arc_length: float = Field(0.005, gt=0, description="mm, constant-arc sampling step")
    switch_radius: float = Field(1.0, ge=0, description="mm, hybrid sampling: angle inside, arc outside")
    chordal_tolerance: float | None = Field(None, gt=0, description="mm; bound on the linearisation error")
    depth_of_cut: float = Field(0.003, ge=0, description="mm (recorded; the envelope does not depend on it)")
    scallop_bound_nm: float | None = Field(
        None, gt=0, le=1e5, description="plan the largest feed per revolution whose scallop "
                                        "stays within this bound (seed 001); replaces feed_mm_per_min")
    allow_gouge: bool = Field(False, description="simulate even if the tool cannot reach everywhere")
    # machine limits used by the kinematics checks (optional)
    x_velocity_limit_mm_s: float | None = Field(None, gt=0)
    x_acceleration_limit_mm_s2: float | None = Field(None, gt=0)
    z_velocity_limit_mm_s: float | None = Field(None, gt=0)
    z_acceleration_limit_mm_s2: float | None = Field(None, gt=0)

    @model_validator(mode="after")
    def _radii(self):
        if self.inner_radius >= self.workpiece_radius:
            raise ValueError(f"inner_radius must be < workpiece_radius ({self.workpiece_radius}), "
                             f"received {self.inner_radius}")
        return self

    @property
    def feed_per_rev(self) -> float:
        """mm per revolution, f / S."""
        return self.feed_mm_per_min / self.spindle_rpm

    def check_with(self, scene) -> None:
        """Cross-checks with the rest of the scene (called by the scene's validator)."""
        rc = scene.tool.nose_radius
        if self.feed_per_rev >= rc:
            raise ValueError(
                f"process.feed_mm_per_min / process.spindle_rpm (feed per revolution) must be < "
                f"tool.nose_radius ({rc} mm), received {self.feed_per_rev:g} mm/rev "
                f"(feed {self.feed_mm_per_min} mm/min at {self.spindle_rpm} rpm)")


def tool_of(scene) -> Tool:
    """The :class:`~render_inspect.toolpath.Tool` of the scene's ``[tool]``."""
    return Tool.from_config(scene.tool)


def plan_spiral(scene, surface, *, region=None):
    """The compensated spiral program of a turning scene (:func:`plan_turning` with the
    scene's ``[process]`` keys).  With ``process.scallop_bound_nm`` the feed per revolution
    is the largest whose scallop stays within the bound on every radial section the path
    cuts (:func:`~render_inspect.toolpath.plan_feed`, seed 001 eqs. 9-13), recorded in
    ``path.meta["scallop_plan"]``."""
    p = scene.process
    tool = tool_of(scene)
    feed, scallop = p.feed_per_rev, None
    if p.scallop_bound_nm is not None:
        r_in, r_out = (p.inner_radius, p.workpiece_radius) if region is None else \
            region_radii(region, tool.half_width)
        scallop = plan_feed(surface, nose_radius=tool.nose_radius,
                            scallop_bound=p.scallop_bound_nm * 1e-6,
                            r_outer=min(r_out, p.workpiece_radius),
                            r_inner=min(max(r_in, p.inner_radius), 0.999 * min(r_out, p.workpiece_radius)),
                            spindle_rpm=p.spindle_rpm)
        feed = scallop["feed_per_rev_mm"]
    path = plan_turning(surface, tool, workpiece_radius=p.workpiece_radius,
                        feed_per_rev=feed, spindle_rpm=p.spindle_rpm,
                        compensation=p.compensation, sampling=p.sampling,
                        points_per_rev=p.points_per_rev, arc_length=p.arc_length,
                        switch_radius=p.switch_radius, inner_radius=p.inner_radius,
                        chordal_tolerance=p.chordal_tolerance, region=region,
                        allow_gouge=p.allow_gouge,
                        memory_budget=memory_budget(scene.simulation.max_memory_gb))
    if scallop is not None:
        path.meta["scallop_plan"] = scallop
    return path


def toolpath_facts(path, scene) -> dict:
    """``metrics["toolpath"]``: points, revolutions, sampling, chordal error, gouge depth,
    accessibility, cut time, and the axis kinematics against the ``[process]`` limits."""
    m = path.meta
    d = {"points": int(path.points), "revolutions": path.revolutions,
         "feed_per_rev_mm": m.get("feed_per_rev_mm"), "sampling": m.get("sampling"),
         "points_per_rev": m.get("points_per_rev"), "compensation": m.get("compensation"),
         "chordal_error_max_nm": m.get("chordal_error_max_mm", 0.0) * 1e6,
         "gouge_max_nm": m.get("gouge_max_mm", 0.0) * 1e6,
         "max_slope": m.get("max_slope"), "cut_time_s": m.get("time_s")}
    if "chordal_tolerance_mm" in m:
        d["chordal_tolerance_nm"] = m["chordal_tolerance_mm"] * 1e6
        d["chordal_within_tolerance"] = m["chordal_within_tolerance"]
    if "scallop_plan" in m:
        d["scallop_plan"] = m["scallop_plan"]
    if "accessibility" in m:
        d["accessible"] = m["accessibility"]["ok"]
        d["accessibility"] = m["accessibility"]
    if path.points >= 3:
        d.update(kinematics(path, limits=limits_from_process(scene.process)))
    return d


def burrs_of(scene) -> dict:
    """The ``[artifacts.burrs]`` keys as :func:`~render_inspect.machining.apply_burrs`
    arguments."""
    b = scene.artifacts.burrs
    return {"height": b.height, "width": b.width, "variation": b.variation,
            "edge_angle_deg": b.edge_angle_deg, "correlation_length": b.correlation_length,
            "seed": int(scene.simulation.seed)}


def cut_turning(scene, surface, path, *, burrs: bool = True, z_fts=None) -> tuple:
    """(machined, design, timing, facts) on the simulation grid for a turning ``path``
    cut on the scene's ``[machine]`` with its ``[material]``
    (:func:`~render_inspect.processes._mechanics.turn`): the followed path's tool-nose
    envelope with the material's mechanics, the design heights, and the burrs of
    ``[artifacts.burrs]`` on the machined edges when their height is set.  ``facts``
    holds ``machine``, ``following_error`` (a non-ideal machine), ``material`` and
    ``burrs`` as they apply, and ``plots`` the following-error figures."""
    t = turn(scene, surface, path, burrs=burrs, z_fts=z_fts)
    return t["machined"], t["design"], t["timing"], {**t["facts"], "plots": t["plots"]}


def _revolutions(scene) -> float:
    """Revolutions of the scene's spiral over its region, before planning: the radii the
    planner keeps (:func:`~render_inspect.toolpath.plan_turning`: the region widened by
    the passes that can reach it, 2.2 Rc m + f + 2 f for the design's largest slope m)."""
    sim, p = scene.simulation, scene.process
    tool = tool_of(scene)
    slope = make_surface(scene.design).max_slope(tuple(sim.region))
    f = p.feed_per_rev
    margin = min(tool.half_width, 2.2 * tool.nose_radius * slope + f) + 2 * f
    r_in, r_out = region_radii(sim.region, margin)
    r_in = max(r_in, p.inner_radius)
    return max(min(r_out, p.workpiece_radius) - r_in, 0.0) / f


def turning_points(scene, plan=None) -> int:
    """Points of the scene's path over its region (estimated before planning)."""
    if plan is not None:
        return int(plan.program.points)
    return int(_revolutions(scene) * scene.process.points_per_rev) + 1


#: bytes per servo tick the machine model holds (commands, followed positions, errors and
#: the loops' states of every axis; measured with tracemalloc: about 250)
_BYTES_PER_TICK = 8 * 32


def machine_bytes(scene, plan=None) -> int:
    """Bytes the scene's ``[machine]`` model holds while following the path (0 on the
    ideal machine)."""
    machine = machine_of(scene)
    if machine.ideal:
        return 0
    if plan is None:
        duration = _revolutions(scene) * 60.0 / scene.process.spindle_rpm
    else:
        t = plan.program.t
        duration = float(t[-1] - t[0]) if len(t) > 1 else 0.0
    return int(duration * machine.servo_rate_hz) * _BYTES_PER_TICK


def turning_memory(scene, plan=None) -> int:
    """Bytes an in-memory turning simulation and the writing of its outputs hold at their
    peak (:mod:`render_inspect.machining._memory`: the height arrays, the float32 channels
    of heightmap.exr, the design evaluation's temporaries and the tool path); on a
    non-ideal ``[machine]`` also the servo ticks (:func:`machine_bytes`) and the maps of
    where each pass cut and its following error, with a ``[material]`` the cut's mechanics
    maps (measured with tracemalloc: within 1.5 x of the peak in every combination)."""
    shape = grid_shape(scene.simulation.region, scene.simulation.pixel)
    samples = shape[0] * shape[1]
    nbytes = in_memory_bytes(shape, turning_points(scene, plan)) + machine_bytes(scene, plan)
    material = scene.material.preset != "ideal"
    if material:  # the cut's mechanics maps and the finished surface's grooves
        nbytes += samples * 8 * 11
    if not machine_of(scene).ideal:  # pass-angle and following-error maps (shared with the material)
        nbytes += samples * 8 * (1 if material else 2)
    return int(nbytes)


def turning_precheck(scene, region=None) -> None:
    """Check the points of the spiral program (``region``: the part of it that reaches
    that window; None: the whole part) against the memory budget before planning; the
    error names ``process.points_per_rev`` / ``arc_length`` / the feed.  (The planner
    checks again with the sampling ``process.chordal_tolerance`` sets.)"""
    p = scene.process
    f = p.feed_per_rev
    r_in, r_out = (region_radii(region, scene.tool.nose_radius + 2 * f) if region is not None
                   else (0.0, p.workpiece_radius))
    r_in, r_out = max(r_in, p.inner_radius), min(r_out, p.workpiece_radius)
    n = turning_point_count(sampling=p.sampling, feed_per_rev=f, workpiece_radius=p.workpiece_radius,
                            r_in=r_in, r_out=max(r_out, r_in), inner_radius=p.inner_radius,
                            points_per_rev=p.points_per_rev, arc_length=p.arc_length,
                            switch_radius=p.switch_radius, parts=True)
    drivers = []
    if p.sampling != "constant_arc":
        drivers.append(Driver("process.points_per_rev", p.points_per_rev, 1, limit=(8, 1e7)))
    if p.sampling != "constant_angle":
        drivers.append(Driver("process.arc_length", p.arc_length, -1, "mm"))
    drivers.append(Driver("process.feed_mm_per_min", p.feed_mm_per_min, -1, "mm/min",
                          limit=(None, p.spindle_rpm * scene.tool.nose_radius)))
    check_budget(scene, plan_memory(n, sampling=p.sampling, compensation=p.compensation),
                 what=f"the tool path ({format_number(sum(n))} points)", drivers=drivers,
                 hint="or shrink simulation.region / process.workpiece_radius")


def turning_header(scene) -> dict:
    """NC header lines of a turning program."""
    p = scene.process
    return {"scene": scene.name, "process": p.kind, "spindle_rpm": p.spindle_rpm,
            "feed_per_rev_mm": p.feed_per_rev, "compensation": p.compensation,
            "nose_radius": scene.tool.nose_radius}


def compensation_variants(scene) -> VariantPair:
    """The pair ``compare`` puts side by side for turning: the scene's tool-radius
    compensation (``"z"`` when it says ``"none"``) against none.  Without compensation
    the nose overcuts the slopes by about ``Rc slope^2 / 2`` (seed 000 Fig. 16)."""
    c = scene.process.compensation
    comp = c if c != "none" else "z"
    name = {"z": "Z-direction", "normal": "normal-direction"}[comp]
    return VariantPair(
        Variant("compensated", f"{name} compensation", {"process.compensation": comp}),
        Variant("uncompensated", "no compensation", {"process.compensation": "none"}),
        key="process.compensation",
        about=(f"Tool-nose radius compensation ({name}) against none: without it the nose "
               f"(Rc = {scene.tool.nose_radius * 1e3:.4g} um) cuts below the design on the "
               f"slopes (overcut, about Rc slope^2 / 2), in a pattern that changes with the "
               f"section angle (seed 000 Fig. 16)."))
