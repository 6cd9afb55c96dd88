"""What every turning process (STS, FTS/HTS, RCSE) shares: the ``[process]`` keys of a
spiral turning program, the :class:`TurningProcess` base class (plan the compensated
spiral, cut it through the machine and material, the memory estimate, the facts), and
the pair ``compare`` shows by default (compensation on against off)."""

from __future__ import annotations

import logging
import math
import time
from pathlib import Path
from collections.abc import Sequence
from typing import Any, ClassVar, Literal, cast

import numpy as np
from pydantic import Field, model_serializer, model_validator

from ..core.limits import Driver, format_number, memory_budget
from ..core.marks import ToolMarks
from ..core.section import Section
from ..core.toolpath import Links, ToolPath
from ..core.units import MM_TO_NM, MM_TO_UM, NM_TO_MM
from ..machining import FollowedPath, material_burr_facts, mechanics_facts, window_margins

from ..toolpath import (
    BLOCK_RATE_KEY,
    DEFAULT_CLEARANCE,
    DEFAULT_PLUNGE_FEED,
    MIN_CLEARANCE,
    MachineLimits,
    PartModel,
    Tool,
    axes_derivatives,
    block_rate,
    kinematics,
    longest_step,
    limits_from_process,
    plan_feed,
    plan_memory,
    plan_turning,
    region_radii,
    turning_axes,
    turning_point_count,
)
from ._contract import Cut, Envelope, Plan, Process, Traits, Variant, VariantPair
from ._edge_facts import check_edge_and_wear, edge_facts_tiled, edge_figure_tiled
from ._machine import ProcessScene, machine_of, material_of
from ._program import cut_name, feed_per_rev_figure, imported_path, program_checks, program_path
from ._program_part import design_part, machine_limits
from ._mechanics import (TurningInputs, follow, following_error_plots, grooves_of,
                         material_burr_args, texture_of, turn)
from ._registry import check_budget
from ._spindle import spindle_meta, turns_m04
from ._turning_memory import (_TILED_KEPT_BYTES_PER_TICK, _ticks, machine_bytes,
                              turning_memory, turning_points)
from ._wear_facts import worn_h_min

log = logging.getLogger("render_inspect")

__all__ = ["TurningProcessConfig", "TurningProcess", "TurningInputs", "plan_spiral",
           "toolpath_facts", "turning_memory", "turning_points", "machine_bytes",
           "turning_header", "compensation_variants", "turning_precheck", "turning_traits",
           "TiledTurningProcess", "turning_part", "turning_limits"]

#: samples per second the envelope cut runs at on 2 cores (the progress bar's estimate;
#: README speed table)
CUT_RATE = 4e6


class TurningProcessConfig(Section):
    """Keys of a spiral turning program (STS, FTS/HTS, RCSE)."""
    spindle_rpm: float = Field(50.0, ge=1e-3, le=20000)
    feed_mm_per_min: float = Field(0.5, ge=1e-6, le=1000)
    workpiece_radius: float = Field(5.0, gt=0, le=500, description="mm, outer radius Rw of the spiral")
    inner_radius: float = Field(0.0, ge=0, description="mm, the spiral stops here")
    compensation: Literal["none", "normal", "z", "edge"] = Field(
        "z", description="tool-radius compensation: none, normal, z (the circular nose) or, for "
                         "kind = \"sts\" only, edge (z against the measured edge of "
                         "tool.edge_profile / tool.waviness)")
    sampling: Literal["constant_angle", "constant_arc", "hybrid"] = "constant_angle"
    points_per_rev: int = Field(3600, ge=8, le=10_000_000, description="N, constant-angle sampling")
    arc_length: float = Field(0.005, gt=0, description="mm, constant-arc sampling step")
    switch_radius: float = Field(1.0, ge=0, description="mm, hybrid sampling: angle inside, arc outside")
    chordal_tolerance: float | None = Field(None, gt=0, description="mm; bound on the linearisation error")
    depth_of_cut: float = Field(0.003, ge=0, description="mm (recorded; the envelope does not depend on it)")
    scallop_bound_nm: float | None = Field(
        None, gt=0, le=1e5, description="plan the largest feed per revolution whose scallop "
                                        "stays within this bound (the residual-height bound of "
                                        "the compound sinusoidal grid study); replaces "
                                        "feed_mm_per_min")
    allow_gouge: bool = Field(False, description="simulate even if the tool cannot reach everywhere")
    clearance: float = Field(DEFAULT_CLEARANCE, ge=MIN_CLEARANCE, le=100,
                             description="mm above the part's highest point (stock included): "
                                         "the clearance plane the program's rapid moves run in")
    plunge_feed_mm_per_min: float = Field(DEFAULT_PLUNGE_FEED, gt=0, le=1000,
                                          description="feed of the vertical plunge onto the "
                                                      "cut and of the retract from it")
    # machine limits used by the kinematics checks (optional)
    x_velocity_limit_mm_s: float | None = Field(None, gt=0)
    x_acceleration_limit_mm_s2: float | None = Field(None, gt=0)
    z_velocity_limit_mm_s: float | None = Field(None, gt=0)
    z_acceleration_limit_mm_s2: float | None = Field(None, gt=0)
    block_rate_limit_per_s: float | None = Field(
        None, gt=0, le=10_000_000, description="blocks per second the machine's control processes; "
                                        "unset: 1000 (toolpath.block_rate)")
    # the user's own program in place of the planned spiral (docs/programs.md)
    program: str | None = Field(None, min_length=1, max_length=4096,
                                description="a machine program file (path relative to the "
                                            "scene file) simulated in place of the planned "
                                            "spiral; docs/programs.md")
    program_x: Literal["auto", "radius", "diameter"] = Field(
        "auto", description="how the program's X is read: auto infers radius or diameter "
                            "from process.workpiece_radius")
    program_integers: Literal["whole", "IS-A", "IS-B", "IS-C", "IS-D", "IS-E"] = Field(
        "whole", description="how the program's numbers without a decimal point are read: "
                             "whole mm / in / deg, or least input increments of the "
                             "control's increment system (IS-B: X2000 is 2 mm)")

    @model_serializer(mode="wrap")
    def _without_program_defaults(self, handler):
        """The program keys and the block rate limit are written only when set, how a
        program's integers are read only when not the default (scenes dump as before)."""
        data = handler(self)
        if isinstance(data, dict) and data.get("block_rate_limit_per_s", 0) is None:
            data.pop("block_rate_limit_per_s")
        if isinstance(data, dict) and data.get("program") is None:
            data.pop("program", None)
            if data.get("program_x") == "auto":
                data.pop("program_x", None)
        if isinstance(data, dict) and data.get("program_integers") == "whole":
            data.pop("program_integers")
        return data

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

    def check_with(self, scene: ProcessScene) -> None:
        """Cross-checks with the rest of the scene (called by the scene's validator)."""
        rc = scene.tool.nose_radius
        check_edge_and_wear(getattr(self, "kind", None), self.compensation, scene)
        # (kind: declared by each kind's subclass)
        if self.program is not None and self.kind == "rcse":  # type: ignore[attr-defined]
            raise ValueError("process.program: process.kind = 'rcse' plans its own path and "
                             "cannot take a program file; use process.kind = 'sts' (or 'fts', "
                             "'hts') to simulate a turning program")
        if self.feed_per_rev >= rc and self.program is None:
            raise ValueError(
                f"process.feed_mm_per_min / process.spindle_rpm (feed per revolution) must be < "
                f"tool.nose_radius ({rc} mm), received {self.feed_per_rev:g} mm/rev "
                f"(feed {self.feed_mm_per_min} mm/min at {self.spindle_rpm} rpm)")



def plan_spiral(cfg: TurningInputs, surface: Any, *, region: Sequence[float] | None = None,
                sectors: bool = False) -> ToolPath:
    """The compensated spiral program of a turning process (:func:`plan_turning` with the
    ``[process]`` keys of ``cfg``).  With ``process.scallop_bound_nm`` the feed per
    revolution is the largest whose scallop stays within the bound on every radial section
    the path cuts (:func:`~render_inspect.toolpath.plan_feed`, the residual-height
    formulas of the compound sinusoidal grid study, eqs. 9-13), recorded in
    ``path.meta["scallop_plan"]``.  ``sectors`` (with ``region``): plan each revolution in
    full only over the sector that reaches the region, with the settle lead the ``[machine]``
    needs before it (:func:`~render_inspect.machining.window_margins`): what a simulation
    of the region cuts, at the cost of the region (not a program to write out)."""
    p = cfg.process
    tool = Tool.from_config(cfg.tool)
    margins = window_margins(machine_of(cfg.machine)) if sectors and region is not None else None
    feed, scallop = p.feed_per_rev, None
    if p.scallop_bound_nm is not None:
        r_in, r_out = (p.inner_radius, p.workpiece_radius) if region is None else \
            region_radii(region, tool.half_width)
        scallop = plan_feed(surface, nose_radius=tool.nose_radius,
                            scallop_bound=p.scallop_bound_nm * NM_TO_MM,
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
                        memory_budget=memory_budget(cfg.simulation.max_memory_gb),
                        sectors=margins)
    if scallop is not None:
        path.meta["scallop_plan"] = scallop
    return path


def imported_facts(cfg: TurningInputs, surface: Any, path: ToolPath) -> dict:
    """``metrics["program"]`` of a program read from a file: where it came from, what was
    inferred, and :func:`~render_inspect.processes._program.program_checks` (feed per
    revolution by radius, chordal error, C rate, findings)."""
    info = dict(path.meta.get("program", {}))
    info.update(program_checks(cfg, surface, path))
    return info


def toolpath_facts(path: ToolPath, process: Any, *, derivatives: dict | None = None) -> dict:
    """``metrics["toolpath"]``: points, revolutions, sampling, chordal error, gouge depth,
    accessibility, cut time, and the axis kinematics against the limits of the
    ``[process]`` section ``process`` (``derivatives``: the X and Z axes' where the caller
    has them, :func:`~render_inspect.toolpath.kinematics`)."""
    m = path.meta
    d = {"points": int(path.points), "revolutions": path.revolutions,
         "feed_per_rev_mm": m.get("feed_per_rev_mm"), "sampling": m.get("sampling"),
         "points_per_rev": m.get("points_per_rev"), "compensation": m.get("compensation"),
         "chordal_error_max_nm": m.get("chordal_error_max_mm", 0.0) * MM_TO_NM,
         "gouge_max_nm": m.get("gouge_max_mm", 0.0) * MM_TO_NM,
         "max_slope": m.get("max_slope"), "cut_time_s": m.get("time_s")}
    if "chordal_tolerance_mm" in m:
        d["chordal_tolerance_nm"] = m["chordal_tolerance_mm"] * MM_TO_NM
        d["chordal_within_tolerance"] = m["chordal_within_tolerance"]
    if "scallop_plan" in m:
        d["scallop_plan"] = m["scallop_plan"]
    if "sectors" in m:  # a window planned in sectors (plan_turning's ``sectors``)
        d["sectors"] = m["sectors"]
    if "accessibility" in m:
        d["accessible"] = m["accessibility"]["ok"]
        d["accessibility"] = m["accessibility"]
    if path.points >= 3:
        valid = None
        if "sectors" in m:  # the sectors' own points, not the joins between them
            a0, span = m["sectors"]["full_rad"]
            valid = np.mod(np.asarray(path.theta) - a0, 2 * np.pi) <= span
        d.update(kinematics(path, limits=limits_from_process(process), valid=valid,
                            derivatives=derivatives))
    # (the blocks of a program read from a file: its file lines, set by imported_path)
    d["block_rate"] = block_rate(path.t, lines=getattr(path, "program_lines", None),
                                 limit=getattr(process, BLOCK_RATE_KEY, None), radius=path.rho)
    return d


def turning_precheck(cfg: TurningInputs, region: Sequence[float] | None = None) -> None:
    """Check the points of the spiral program (``region``: the part of it that reaches
    that window; None: the whole part) against the memory budget before planning; the
    error names ``process.points_per_rev`` / ``arc_length`` / the feed.  (The planner
    checks again with the sampling ``process.chordal_tolerance`` sets.)"""
    p = cfg.process
    f = p.feed_per_rev
    r_in, r_out = (region_radii(region, cfg.tool.nose_radius + 2 * f) if region is not None
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
                          limit=(None, p.spindle_rpm * cfg.tool.nose_radius)))
    check_budget(cfg.simulation, plan_memory(n, sampling=p.sampling, compensation=p.compensation),
                 what=f"the tool path ({format_number(sum(n))} points)", drivers=drivers,
                 hint="or shrink simulation.region / process.workpiece_radius")


def turning_header(cfg: TurningInputs) -> dict:
    """NC header lines of a turning program (of a program read from a file: its name, not
    the scene's feed and compensation, which it does not follow)."""
    p = cfg.process
    head = {"scene": cfg.name, "process": p.kind, "spindle_rpm": p.spindle_rpm}
    if program_path(cfg):
        head["program"] = Path(str(p.program)).name
    else:
        head.update({"feed_per_rev_mm": p.feed_per_rev, "compensation": p.compensation})
    return {**head, "nose_radius_mm": cfg.tool.nose_radius}


def turning_part(cfg: TurningInputs, surface: Any, path: ToolPath | None = None) -> PartModel:
    """The turned part a program is checked against: the design over the disc of
    ``process.workpiece_radius``, the depth of cut as stock, the planned ``path``'s
    longest step."""
    p = cfg.process
    step = None if path is None else longest_step(path.x, path.y, path.z)
    return design_part(surface, ("disc", 0.0, 0.0, float(p.workpiece_radius)),
                       stock=float(p.depth_of_cut),
                       half_width=Tool.from_config(cfg.tool).half_width, max_step=step)


def turning_limits(cfg: TurningInputs) -> MachineLimits:
    """What the lathe allows a turning program: the slides' velocity limits (the
    ``[machine]`` preset's, or ``process.x_velocity_limit_mm_s`` /
    ``z_velocity_limit_mm_s`` when lower) and the spindle speed ``process.spindle_rpm``
    (the program's C axis never turns faster)."""
    p = cfg.process
    machine = machine_of(cfg.machine)
    vel = {}
    # on a machine with a fast tool servo the programmed Z is the slide's and the servo's
    # stroke together: the servo's limit bounds it, not the slide's
    z_axis = machine.fts if not machine.fts.ideal else machine.z
    for axis, key, ax in (("X", "x_velocity_limit_mm_s", machine.x),
                          ("Z", "z_velocity_limit_mm_s", z_axis)):
        lims = [v for v in (ax.velocity_limit, getattr(p, key)) if v is not None]
        vel[axis] = min(lims) if lims else None
    return machine_limits(cfg.machine.preset,
                          also=f" with process.spindle_rpm {p.spindle_rpm:g} and the "
                               f"[process] velocity limits",
                          velocity_mm_s=vel, spindle_rpm=float(p.spindle_rpm))


def compensation_variants(cfg: TurningInputs) -> VariantPair:
    """The pair ``compare`` puts side by side for turning: the tool-radius compensation
    (``"z"`` when the scene says ``"none"``) against none.  Without compensation the nose
    overcuts the slopes by about ``Rc slope^2 / 2`` (Li et al. 2018, Fig. 16)."""
    c = cfg.process.compensation
    if c == "edge":
        # the measured edge: the path planned against it against the circular nose's
        return VariantPair(
            Variant("compensated", "Z compensation against the measured edge", {"process.compensation": "edge"}),
            Variant("uncompensated", "Z compensation for the circular nose", {"process.compensation": "z"}),
            key="process.compensation",
            about=("Tool-edge waviness compensation against none: a path planned for the circular "
                   "nose leaves the edge's radius deviation at the contact angle, -delta(theta) along "
                   "the normal, on the part; planned against the measured edge the contact point moves "
                   "along the real edge and the imprint cancels."))
    comp = c if c != "none" else "z"
    name = {"z": "Z-direction", "normal": "normal-direction"}[comp]
    return VariantPair(
        Variant("compensated", f"{name} compensation", {"process.compensation": comp}),
        Variant("uncompensated", "no compensation", {"process.compensation": "none"}),
        key="process.compensation",
        about=(f"Tool-nose radius compensation ({name}) against none: without it the nose "
               f"(Rc = {cfg.tool.nose_radius * MM_TO_UM:.4g} um) cuts below the design on the "
               f"slopes (overcut, about Rc slope^2 / 2), in a pattern that changes with the "
               f"section angle (Li et al. 2018, Fig. 16)."))


def _cleared(section, prefix: str) -> dict:
    """The keys of ``section`` (and its tables) that are set, cleared (dotted -> None)."""
    values = {}
    for key, fld in type(section).model_fields.items():
        value = getattr(section, key)
        if isinstance(value, Section):
            values.update(_cleared(value, f"{prefix}.{key}"))
        elif fld.default is None and value is not None:
            values[f"{prefix}.{key}"] = None
    return values


def _ideal_values(section, name: str) -> dict:
    """Scene values that make ``[name]`` (machine, material) ideal: its preset, and every
    key that would change the preset, cleared."""
    return {f"{name}.preset": "ideal", **_cleared(section, name)}


def turning_contributions(cfg: TurningInputs) -> dict:
    """The lathe and the material, when not ideal, and the scene values that turn each off
    (:attr:`Traits.contributions`)."""
    out = {}
    if cfg.machine.preset != "ideal":
        out["lathe"] = {"label": f"the lathe ({cfg.machine.preset})",
                        "off": _ideal_values(cfg.machine, "machine")}
    if cfg.material.preset != "ideal":
        out["material"] = {"label": f"the material ({cfg.material.preset})",
                           "off": _ideal_values(cfg.material, "material")}
    return out


def turning_traits(cfg: TurningInputs, *, cut_rate: float = CUT_RATE) -> Traits:
    """A turned part: circular feed marks of the nose radius about the spindle axis, the
    disc of the workpiece, the program saved as ``toolpath.npz``, the lathe and the
    material as contributions beyond the commanded geometry."""
    p = cfg.process
    return Traits(name=p.kind, compensation=p.compensation,
                  marks=ToolMarks("circular", float(p.feed_per_rev), float(cfg.tool.nose_radius),
                                  scallop=True),
                  axis=(0.0, 0.0),
                  part={"shape": "disc", "center": [0.0, 0.0], "radius": float(p.workpiece_radius)},
                  saves_program=True, cut_rate=cut_rate,
                  contributions=turning_contributions(cfg))


def _meta(cfg, **extra) -> dict:
    """Provenance of a turned height map."""
    return {"process": cfg.process.kind, "compensation": cfg.process.compensation,
            "seed": cfg.simulation.seed, "machine": cfg.machine.preset,
            "material": cfg.material.preset, **extra}


class TurningProcess(Process[TurningInputs]):
    """A turning process: the compensated spiral (:func:`plan_spiral`) cut through the
    machine and material (:func:`~render_inspect.processes._mechanics.turn`).  Subclasses
    set ``config`` and change what differs."""

    inputs: ClassVar[type[TurningInputs]] = TurningInputs

    def program(self, cfg: TurningInputs, surface: Any, *, region: Sequence[float] | None = None,
                sectors: bool = False) -> ToolPath:
        """The commanded turning program: the scene's ``process.program`` read from its
        file (:func:`~render_inspect.processes._program.imported_path`), else the planned
        spiral (:func:`plan_spiral`); a subclass that programs the spiral otherwise
        (another time axis, other sampling) overrides this."""
        if program_path(cfg):
            return imported_path(cfg, surface, region=region)
        return plan_spiral(cfg, surface, region=region, sectors=sectors)

    def plan(self, cfg: TurningInputs, surface: Any, *, region: Sequence[float] | None = None,
             sectors: bool = False) -> Plan:
        t0 = time.perf_counter()
        path = (self.program(cfg, surface, region=region, sectors=True) if sectors
                else self.program(cfg, surface, region=region))
        # the X and Z axes' derivatives, for the kinematics and for their figure
        derivatives = axes_derivatives(path.t, turning_axes(path))
        facts = {"toolpath": toolpath_facts(path, cfg.process, derivatives=derivatives)}
        if program_path(cfg):
            facts["program"] = info = imported_facts(cfg, surface, path)
            tp = facts["toolpath"]
            tp["chordal_error_max_nm"] = info.get("chordal_error_max_nm", 0.0)
            below = [f for f in info["findings"] if f["kind"] == "below_design"]
            tp["gouge_max_nm"] = below[0]["worst_nm"] if below else 0.0
        return Plan(path, facts, {"toolpath": time.perf_counter() - t0},
                    plots=self.program_plots(cfg, path, derivatives=derivatives))

    def program_plots(self, cfg: TurningInputs, path: ToolPath, data: dict | None = None, *,
                      derivatives: dict | None = None) -> dict:
        """``kinematics.png``: the axes of the program that move (and, for a program read
        from a file, ``feed_per_rev.png``).  ``derivatives``: those of the axes
        (:func:`~render_inspect.toolpath.turning_axes` of ``path`` and ``data``) where the
        caller has them."""
        extra = {}
        if program_path(cfg):
            extra["feed_per_rev.png"] = feed_per_rev_figure(path, cut_name(cfg))
        # the axes' derivatives taken here, where the compiled kernels are loaded (the
        # figure is drawn from them by the command's figure process, which need not start
        # numba for it)
        data = dict(data or {})
        data["derivatives"] = (derivatives if derivatives is not None
                               else axes_derivatives(path.t, turning_axes(path, data)))
        return {**extra, "kinematics.png": {"kind": "axes",
                                   "columns": [(f"{cfg.process.kind.upper()} program", path,
                                                data)],
                                   "title": f"{cut_name(cfg)}: the axes that move"}}

    def plan_window(self, cfg: TurningInputs, surface: Any, region: Sequence[float]) -> Plan:
        """The spiral planned in full only over the sectors that reach ``region``
        (:func:`plan_spiral` with ``sectors``).  A subclass that programs the spiral
        otherwise (its own :meth:`program`: another time axis, other sampling) plans
        whole revolutions: the sectors hold only for the spiral as planned here."""
        if type(self).program is not TurningProcess.program:
            return self.plan(cfg, surface, region=region)
        return self.plan(cfg, surface, region=region, sectors=True)

    def cut(self, cfg: TurningInputs, surface: Any, plan: Plan) -> Cut:
        t = turn(cfg, surface, plan.program)
        return Cut(t["machined"], t["design"], t["facts"], t["timing"],
                   _meta(cfg, **spindle_meta(plan.program)),
                   followed=t["followed"], plots=t["plots"])

    def estimate_memory(self, cfg: TurningInputs, plan: Plan | None = None) -> int:
        return turning_memory(cfg, plan)

    def traits(self, cfg: TurningInputs) -> Traits:
        return turning_traits(cfg)

    def precheck(self, cfg: TurningInputs, region: Sequence[float] | None = None) -> None:
        if not program_path(cfg):  # a program file's size is known once it is read
            turning_precheck(cfg, region)

    def program_links_part(self, cfg: TurningInputs, surface: Any,
                           plan: Plan) -> tuple[Links, PartModel] | None:
        """None for a program read from a file: its own moves between the cuts are part
        of it (and checked as findings), no links are added."""
        if program_path(cfg):
            return None
        return super().program_links_part(cfg, surface, plan)

    def program_header(self, cfg: TurningInputs) -> dict:
        return turning_header(cfg)

    def program_part(self, cfg: TurningInputs, surface: Any, plan: Plan) -> PartModel:
        return turning_part(cfg, surface, cast(ToolPath, plan.program))

    def program_limits(self, cfg: TurningInputs) -> MachineLimits:
        return turning_limits(cfg)

    def program_facts(self, cfg: TurningInputs, plan: Plan) -> dict:
        """``toolpath.json``: the plan's facts with the path's own (points, revolutions,
        feed, the planner's records) and its accessibility check."""
        prog = cast(ToolPath, plan.program)  # (a turning program)
        facts = dict(plan.facts)
        tp = facts.setdefault("toolpath", {})
        tp.setdefault("points", prog.points)
        tp.setdefault("revolutions", prog.revolutions)
        # (a program read from a file: its own median feed, in its meta)
        tp.setdefault("feed_per_rev_mm", prog.meta.get("feed_per_rev_mm", cfg.process.feed_per_rev))
        for k, v in prog.meta.items():
            if k not in ("accessibility", "program") and not k.startswith("_"):
                tp.setdefault(k, v)
        if "accessibility" in prog.meta:
            facts["accessibility"] = prog.meta["accessibility"]
        return facts

    def variants(self, cfg: TurningInputs) -> VariantPair:
        if program_path(cfg):
            return program_variants(cfg)
        return compensation_variants(cfg)


def program_variants(cfg: TurningInputs) -> VariantPair:
    """The pair ``compare`` shows for a program read from a file: the program as written
    against the spiral the process would plan from the scene."""
    name = Path(str(cfg.process.program)).name
    return VariantPair(
        Variant("program", f"the program {name}", {}),
        Variant("planned", "the planned spiral", {"process.program": None}),
        key="process.program",
        about=(f"The program {name} as written against the spiral planned from the scene "
               f"(feed {cfg.process.feed_per_rev * MM_TO_UM:.4g} um/rev, compensation "
               f"{cfg.process.compensation}): what the program cuts differently."))


class TiledTurningProcess(TurningProcess):
    """A turning process whose machined surface is cut along one followed path (the
    machine's axes and error motions act on the whole program, the material's mechanics
    pixel by pixel, the material's burrs within their reach): it can be simulated tile by
    tile.  Burrs of a given height (``[artifacts.burrs] height``) are not added tile by
    tile.  A program turning M04: :attr:`~render_inspect.processes.Envelope.mirror`."""

    def tile_refusal(self, cfg: TurningInputs) -> str | None:
        if cfg.burrs.height > 0:
            return (f"the tiled simulation adds the material's burrs, not ridges of a given "
                    f"height: artifacts.burrs.height must be 0 for maps simulated tile by tile, "
                    f"received {cfg.burrs.height}")
        return None

    def follow_program(self, cfg: TurningInputs,
                       plan: Plan) -> tuple[ToolPath, FollowedPath, dict]:
        """:func:`~render_inspect.processes._mechanics.follow` of the plan's program (a
        process that splits the program between axes passes its share here)."""
        return follow(cfg, plan.program)

    def envelope(self, cfg: TurningInputs, surface: Any, plan: Plan) -> Envelope:
        return self.envelope_of(cfg, *self.follow_program(cfg, plan))

    def envelope_of(self, cfg: TurningInputs, cut_path: ToolPath, fp: FollowedPath, facts: dict, *,
                    plots: dict | None = None, meta: dict | None = None) -> Envelope:
        """The Envelope of a followed path (:func:`~render_inspect.processes._mechanics.follow`)."""
        tool = Tool.from_config(cfg.tool)
        resp = material_of(cfg.material)
        if tool.edge is not None:  # the edge itself (a tiled run adds its facts: tiled_facts)
            facts = {**facts, "tool_edge": {**tool.edge.to_dict(tool.half_angle),
                                            "compensation": cfg.process.compensation}}
        return Envelope(cut_path, tool.nose_radius, tool.half_width,
                        {**_meta(cfg), **(meta or {}), **spindle_meta(cut_path)}, mirror=turns_m04(cut_path),
                        mechanics=resp, grooves=None if resp is None else grooves_of(cfg, resp),
                        texture=None if resp is None else texture_of(cfg, resp),
                        burrs=material_burr_args(cfg, resp, cut_path, tool),
                        facts=facts, followed=None if fp.ideal else fp, plots=dict(plots or {}),
                        edge=tool.edge, h_min_points=worn_h_min(cfg, cut_path, resp))

    def tiled_facts(self, cfg: TurningInputs, env: Envelope, cut: dict, *, stride: int) -> tuple[dict, dict]:
        facts, plots = dict(env.facts), dict(env.plots)
        if env.mechanics is not None:
            info = mechanics_facts(env.mechanics, grooves_sumsq=cut["grooves_sumsq"],
                                   grooves_n=cut["grooves_n"], added_max=cut["added_max"],
                                   edge_pixels=cut["edge_pixels"])
            n = cut.get("texture_n", 0)
            info["texture_measured_rms_nm"] = (math.sqrt(cut["texture_sumsq"] / n) * MM_TO_NM
                                               if n else 0.0)
            facts["material"] = {**env.mechanics.to_dict(), **info}
            if env.burrs is not None and "burr_edge_pixels" in cut:
                facts["burrs"] = material_burr_facts(
                    **env.burrs, edge_pixels=cut["burr_edge_pixels"], turn_max=cut["burr_turn_max"],
                    height_max=cut["burr_height_max"], added_max=cut["burr_added_max"])
        if env.followed is not None and "pass_theta" in cut:
            sim = cfg.simulation
            plots.update(following_error_plots(env.followed, cut["pass_theta"], tuple(sim.region),
                                               sim.pixel * stride, name=cut_name(cfg)))
        tool = Tool.from_config(cfg.tool)
        if tool.edge is not None and "residual" in cut:  # the whole map's tool_edge facts
            sim = cfg.simulation
            facts["tool_edge"] = edge_facts_tiled(tool, str(env.path.meta.get("compensation", "")),
                                                  cfg.design, tuple(sim.region), sim.pixel, cut["residual"])
            if "residual_row" in cut:  # and its figure, from the stored residual's middle row
                plots.update(edge_figure_tiled(tool, cfg.design, tuple(sim.region), sim.pixel,
                                               facts["tool_edge"], cut["residual_row"], name=cut_name(cfg)))
        return facts, plots

    def tiled_memory(self, cfg: TurningInputs, plan: Plan | None = None) -> tuple[int, int]:
        # the machine model's following (machine_bytes) ends before the tiles start; what
        # it leaves is held beside them
        return _ticks(cfg, plan) * _TILED_KEPT_BYTES_PER_TICK, turning_points(cfg, plan)

    def following_memory(self, cfg: TurningInputs, plan: Plan | None = None) -> int:
        # the phase before the tiles: every servo tick of the followed path at once
        return machine_bytes(cfg, plan)
