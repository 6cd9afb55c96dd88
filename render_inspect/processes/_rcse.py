"""Turning along a rotary-coordinate shuttling-element (RCSE) spiral path (the RCSE study,
Optica Publishing Group 2024), compared with the conventional path interpolated from a
rectangular point cloud.

The RCSE program itself needs no keys beyond the turning ones: its spiral pitch is the
feed per revolution, its polar step ``360 / process.points_per_rev`` degrees, its elements
the ``lenslet_rings`` design.  The ``[rcse]`` section (defined here) sets how the
conventional path is built for the comparison and which path cuts the simulated surface.
"""

from __future__ import annotations

from collections.abc import Sequence
import math
import time
from dataclasses import dataclass
from typing import Any, Literal, cast

import numpy as np
from pydantic import Field

from ..core.errors import InputError
from ..core.section import Section
from ..core.toolpath import ToolPath
from ..core.units import MM_TO_NM, MM_TO_UM
from ..machining import residual_metrics
from ..toolpath import (
    RingLayout,
    Tool,
    conventional_ccps,
    kinematics,
    rcse_ccps,
    rcse_toolpath,
    region_radii,
    z_compensation,
)
from ..design import Surface
from ._contract import Cut, Envelope, Plan, Process, Traits, Variant, VariantPair
from ._mechanics import Turned, TurningInputs, follow, turn
from ._machine import ProcessScene
from ._program import cut_name
from ._registry import register_process, register_section
from ._turning import TiledTurningProcess, TurningProcessConfig, toolpath_facts, turning_traits

#: samples per second the cut runs at on 2 cores (the progress bar's estimate)
CUT_RATE = 1e6  # not a unit conversion

__all__ = ["RcseProcessConfig", "RcseConfig", "RcseInputs", "RcseProcess", "rcse_comparison"]

_KIN_KEYS = ("x_velocity_max_mm_s", "x_acceleration_max_mm_s2", "x_jerk_max_mm_s3",
             "x_velocity_mean_mm_s", "x_reversals", "z_velocity_max_mm_s",
             "z_acceleration_max_mm_s2")


class RcseConfig(Section):
    """How the conventional (grid-interpolated) path is built for the comparison (the RCSE study, Optica 2024),
    and which of the two paths cuts the simulated surface."""
    path: Literal["rcse", "conventional"] = Field(
        "rcse", description="the path that cuts the simulated surface: the RCSE path, or the "
                            "conventional grid-interpolated one (Z-compensated on its own point "
                            "cloud); compare shows both")
    compare_conventional: bool = Field(True, description="also build the conventional path and compare")
    grid_spacing: float = Field(0.005, gt=0, le=1.0,
                                description="mm, spacing of the rectangular point cloud (modelling grid)")
    interpolation: Literal["linear", "cubic"] = Field("linear", description="interpolation in the point cloud")
    simulate_conventional: bool = Field(True, description="also simulate the surface the conventional "
                                                          "path machines over simulation.region")
    snap_to_rows: bool = Field(True, description="CCPs on the nearest point-cloud row (X reciprocates); "
                                                 "false: interpolated at the exact spiral point")
    spread_elements: int = Field(0, ge=0, le=1000,
                                 description="elements (spread over the rings) on which both paths are "
                                             "cut to compare Sa and its spread; 0 = none")
    spread_window: float = Field(0.214, gt=0, le=10.0,
                                 description="mm, side of the square field measured on each element "
                                             "(the RCSE study: 0.214 mm)")


register_section("rcse", RcseConfig)


class RcseProcessConfig(TurningProcessConfig):
    """``[process]`` of turning along an RCSE path (needs a ``lenslet_rings`` design)."""
    kind: Literal["rcse"]

    def check_with(self, scene: ProcessScene) -> None:
        super().check_with(scene)
        if scene.design.type != "lenslet_rings":
            raise ValueError("process.kind = 'rcse' needs design.type = 'lenslet_rings' (elements on "
                             f"rings), received design.type = {scene.design.type!r}")


@dataclass(frozen=True)
class RcseInputs(TurningInputs):
    """A turning process's sections and ``[rcse]``."""

    process: RcseProcessConfig
    # (burrs above has no default either: section() is a field without one, which mypy
    # takes for a default)
    rcse: RcseConfig  # type: ignore[misc]


def _program(cfg, surface, *, region, ccps=None) -> ToolPath:
    p = cfg.process
    layout = RingLayout.from_config(cfg.design)
    return rcse_toolpath(layout, Tool.from_config(cfg.tool), workpiece_radius=p.workpiece_radius,
                         pitch=p.feed_per_rev, points_per_rev=p.points_per_rev,
                         spindle_rpm=p.spindle_rpm, inner_radius=p.inner_radius,
                         compensation=p.compensation, region=region, ccps=ccps,
                         surface=surface)


def _plan(cfg, surface, *, region=None) -> Plan:
    p = cfg.process
    tool = Tool.from_config(cfg.tool)
    layout = RingLayout.from_config(cfg.design)
    t0 = time.perf_counter()
    r_range = None if region is None else region_radii(region, tool.half_width + 2 * p.feed_per_rev)
    if r_range is not None and (r_range[0] > p.workpiece_radius or r_range[1] < p.inner_radius):
        raise InputError(
            f"simulation.region {list(region)} mm lies outside the turned part: the tool reaches "
            f"it only between {r_range[0]:.6g} and {r_range[1]:.6g} mm from the spindle axis, "
            f"but the spiral runs from process.workpiece_radius = {p.workpiece_radius:g} mm in to "
            f"process.inner_radius = {p.inner_radius:g} mm; move the region or change those radii")
    ccps = rcse_ccps(layout, r_outer=p.workpiece_radius, pitch=p.feed_per_rev,
                     points_per_rev=p.points_per_rev, r_inner=p.inner_radius, r_range=r_range)
    t_ccps = time.perf_counter() - t0
    path = _program(cfg, surface, region=region, ccps=ccps)
    timing = {"ccps": t_ccps, "toolpath": time.perf_counter() - t0}
    subs = ccps.sub_paths()
    rcse = {"layout": layout.to_dict(), "ccps": int(ccps.k.size),
            "ccps_on_elements": int(np.count_nonzero(ccps.ring >= 0)),
            "sub_paths": int(subs.shape[0]), "pitch_mm": p.feed_per_rev,
            "polar_step_deg": 360.0 / p.points_per_rev,
            "ccp_generation_s": t_ccps, "layout_overlaps": layout.overlaps()}
    return Plan(path, {"toolpath": toolpath_facts(path, p), "rcse": rcse}, timing)


def rcse_comparison(cfg: Any, path: Any, surface: Any, *,
                    machined: np.ndarray | None = None, design: np.ndarray | None = None,
                    conventional_machined: bool = False,
                    conventional_program: bool = False) -> tuple:
    """Compare the RCSE path with the conventional one over the same spiral samples.

    Parameters
    ----------
    cfg : RcseInputs
    path : ToolPath
        The RCSE path (with ``ccp_rho`` / ``ccp_z``).
    surface : Surface
        The design.
    machined, design : (ny, nx) arrays, optional
        The RCSE simulation on the simulation grid.  If given and ``rcse.simulate_conventional``,
        the conventional path is Z-compensated on its own point-cloud model and machined
        over the same grid, and both residuals are reported (``residual``: Sa, Sq, Sz, min
        in nm).

    conventional_machined : bool
        Also machine the conventional path over the simulation grid (whatever
        ``rcse.simulate_conventional`` says) and return its cut (``Turned``: machined map,
        facts, following-error figures) as a third element.
    conventional_program : bool
        Return the conventional program at the tool tip (Z-compensated on its own point
        cloud, not machined) as a third element instead.

    Returns
    -------
    (metrics, (rcse CCP path, conventional CCP path)[, conventional cut])
        ``metrics``: ``rcse`` and ``conventional`` X velocity / acceleration / jerk
        maxima, mean |vX|, X reversals, profile errors (nm: max |error|, RMS), the
        conventional modelling and interpolation times.  The paths carry the CCP heights
        (no tool compensation): their X motion is what each method programs.
    """
    st = cfg.rcse
    theta = np.asarray(path.theta)
    rho = np.asarray(path.ccp_rho if path.ccp_rho is not None else path.rho)
    z = np.asarray(path.ccp_z if path.ccp_z is not None else path.z)
    t = np.asarray(path.t)
    conv = conventional_ccps(surface, theta, rho, grid_spacing=st.grid_spacing,
                             interpolation=st.interpolation, snap_to_rows=st.snap_to_rows)
    conv_path = ToolPath(theta.copy(), conv["rho"], conv["z"], t.copy(),
                         {"method": "conventional", "grid_spacing_mm": st.grid_spacing,
                          "interpolation": st.interpolation, "snap_to_rows": st.snap_to_rows})
    ccp_path = ToolPath(theta.copy(), rho.copy(), z.copy(), t.copy(), {"method": "rcse"})
    err_rcse = z - surface.height(rho * np.cos(theta), rho * np.sin(theta))
    kr = kinematics(ccp_path)
    kc = kinematics(conv_path)
    e = conv["profile_error"]
    out: dict[str, Any] = {
        "rcse": {**{k: kr[k] for k in _KIN_KEYS},
                 "profile_error_max_nm": float(np.max(np.abs(err_rcse)) * MM_TO_NM),
                 "profile_error_rms_nm": float(np.sqrt(np.mean(err_rcse ** 2)) * MM_TO_NM)},
        "conventional": {**{k: kc[k] for k in _KIN_KEYS},
                         "profile_error_max_nm": float(np.max(np.abs(e)) * MM_TO_NM),
                         "profile_error_rms_nm": float(np.sqrt(np.mean(e ** 2)) * MM_TO_NM),
                         "x_deviation_max_um": float(np.max(np.abs(conv["rho"] - rho)) * MM_TO_UM),
                         "modelling_s": conv["modelling_s"], "toolpath_s": conv["toolpath_s"],
                         "grid_shape": conv["grid_shape"], "grid_spacing_mm": st.grid_spacing,
                         "interpolation": st.interpolation, "snap_to_rows": st.snap_to_rows},
        "points_compared": int(theta.size),
    }
    if conventional_program:
        return out, (ccp_path, conv_path), _conventional_tip(cfg, conv_path, conv["model"])
    conv_cut = None
    if conventional_machined or (machined is not None and st.simulate_conventional):
        conv_cut = _machine_conventional(cfg, surface, conv_path, conv["model"], design=design,
                                         plots=conventional_machined)
    if machined is not None and st.simulate_conventional:
        out["rcse"]["residual"] = _short(residual_metrics(machined, design))
        # (cut above under the same condition)
        out["conventional"]["residual"] = _short(
            residual_metrics(cast(Turned, conv_cut)["machined"], design))
        fe = cast(Turned, conv_cut)["facts"].get("following_error")
        if fe is not None:
            out["conventional"]["following_error"] = fe
    if conventional_machined:
        return out, (ccp_path, conv_path), conv_cut
    return out, (ccp_path, conv_path)


def _short(r: dict) -> dict:
    return {k: r[k] for k in ("Sa_nm", "Sq_nm", "Sz_nm", "min_nm") if k in r}


def _conventional_tip(cfg, conv_path, model) -> ToolPath:
    """The conventional program at the tool tip: its CCP heights lifted by the Z
    compensation computed on its own point-cloud model at the machine position (C, X)."""
    tool = Tool.from_config(cfg.tool)
    slope = RingLayout.from_config(cfg.design).max_slope * 1.05
    th, rc = conv_path.theta, conv_path.rho
    m_here = model.height(rc * np.cos(th), rc * np.sin(th))
    lift = z_compensation(model, th, rc, tool.nose_radius, max_slope=slope,
                          half_width=tool.half_width) - m_here
    return ToolPath(th, rc, conv_path.z + lift, conv_path.t, dict(conv_path.meta))


def _machine_conventional(cfg, surface, conv_path, model, *, region=None, design=None,
                          plots: bool = False):
    """The surface the conventional program machines on the machine and material
    (:func:`~render_inspect.processes._mechanics.turn`; ``plots``: with its
    following-error figures)."""
    return turn(cfg, surface, _conventional_tip(cfg, conv_path, model), region=region,
                plots=plots, design=design)


def element_windows(layout: Any, n: int, side: float) -> list:
    """``n`` square fields of side ``side`` (mm) centred on elements spread over the rings
    (ring after ring; the k-th field's angle steps by the golden ratio of a turn):
    [(ring, element, (x0, y0, x1, y1)), ...]."""
    out = []
    rings = len(layout.ring_radii)
    golden = (math.sqrt(5.0) - 1.0) / 2.0
    for k in range(n):
        i = k % rings
        N = layout.counts[i]
        # angles spread by the golden ratio: no two fields alike, every quadrant visited
        e = int(round(((k * golden) % 1.0) * N)) % N
        a = layout.phase + 2 * np.pi * e / N
        R = layout.ring_radii[i]
        cx, cy = R * np.cos(a), R * np.sin(a)
        out.append((i, int(e), (cx - side / 2, cy - side / 2, cx + side / 2, cy + side / 2)))
    return out


def element_spread(cfg: Any, surface: Any) -> dict:
    """Sa of both paths on ``rcse.spread_elements`` element fields, their mean and
    standard deviation, and how much lower RCSE's are (the RCSE study's Table 2: 60.6 %
    and 91.7 %)."""
    st = cfg.rcse
    layout = RingLayout.from_config(cfg.design)
    rows = []
    fe: dict[str, list[dict]] = {"rcse": [], "conventional": []}
    for ring, elem, win in element_windows(layout, st.spread_elements, st.spread_window):
        sub = cfg.replace(simulation=cfg.simulation.model_copy(update={"region": tuple(win)}))
        plan_w = _plan(sub, surface, region=win)
        rc = turn(sub, surface, plan_w.program, plots=False)
        path = cast(ToolPath, plan_w.program)  # (the RCSE path, with its CCP radii)
        conv = conventional_ccps(surface, path.theta, cast(np.ndarray, path.ccp_rho),
                                 grid_spacing=st.grid_spacing,
                                 interpolation=st.interpolation, snap_to_rows=st.snap_to_rows)
        conv_path = ToolPath(path.theta, conv["rho"], conv["z"], path.t, {})
        cc = _machine_conventional(sub, surface, conv_path, conv["model"], design=rc["design"])
        sa_r = residual_metrics(rc["machined"], rc["design"])["Sa_nm"]
        sa_c = residual_metrics(cc["machined"], rc["design"])["Sa_nm"]
        rows.append({"ring": ring, "element": elem, "region_mm": list(win),
                     "rcse_Sa_nm": sa_r, "conventional_Sa_nm": sa_c})
        for key, c in (("rcse", rc), ("conventional", cc)):
            if "following_error" in c["facts"]:
                fe[key].append(c["facts"]["following_error"])
    r = np.array([x["rcse_Sa_nm"] for x in rows])
    c = np.array([x["conventional_Sa_nm"] for x in rows])
    sd = (lambda a: float(np.std(a, ddof=1)) if a.size > 1 else 0.0)
    out = {"elements": rows, "window_mm": st.spread_window,
           "rcse": {"Sa_mean_nm": float(r.mean()), "Sa_sd_nm": sd(r)},
           "conventional": {"Sa_mean_nm": float(c.mean()), "Sa_sd_nm": sd(c)}}
    out["Sa_mean_reduction_percent"] = float(100 * (1 - r.mean() / c.mean()))
    if sd(c) > 0:
        out["Sa_sd_reduction_percent"] = float(100 * (1 - sd(r) / sd(c)))
    for key, lst in fe.items():
        if lst:
            out[key]["following_error"] = {
                k: (max(d[k] for d in lst) if "max" in k else float(np.sqrt(np.mean([d[k] ** 2 for d in lst]))))
                for k in lst[0]}
    return out


def _comparison_plots(cfg, rcse_path, conv_path) -> dict:
    """``rcse_kinematics.png`` and the pair of X motions in ``kinematics.png``."""
    labels = ("RCSE (CCPs on the spiral)", "conventional (grid-interpolated)")
    return {"rcse_kinematics.png": {
                "kind": "kinematics", "path": rcse_path, "reference": conv_path, "labels": labels,
                "title": "X-axis motion: RCSE vs conventional (the RCSE study, Figs. 8-9)"},
            "kinematics.png": {
                "kind": "axes", "columns": [(labels[0], rcse_path, {}), (labels[1], conv_path, {})],
                "axes": ("X",), "title": f"{cut_name(cfg)}: X motion, RCSE vs conventional",
                "pair": True,
                "pair_title": "X motion: RCSE vs conventional (the RCSE study, Figs. 8-9)"}}


def _tiled_envelope(process, cfg, surface, plan: Plan):
    """The RCSE cut tile by tile: the path that cuts (RCSE or conventional) followed by the
    machine, with the comparison's kinematics and profile errors (the residuals of both
    paths over the grid, ``residual``, need the map in memory and are left out)."""
    conventional = cfg.rcse.path == "conventional"
    program, facts, plots = plan.program, {}, {}
    if cfg.rcse.compare_conventional or conventional:
        comp, (rcse_path, conv_path), conv_tip = rcse_comparison(cfg, plan.program, surface,
                                                                 conventional_program=True)
        if conventional:
            program = conv_tip
        facts["rcse"] = {**plan.facts["rcse"], "comparison": comp, "path": cfg.rcse.path}
        if cfg.rcse.spread_elements:
            facts["rcse"]["comparison"]["spread"] = element_spread(cfg, surface)
        plots = _comparison_plots(cfg, rcse_path, conv_path)
    cut_path, fp, mfacts = follow(cfg, program)
    if "following_error" in mfacts and "comparison" in facts.get("rcse", {}):
        facts["rcse"]["comparison"]["conventional" if conventional else "rcse"]["following_error"] = \
            mfacts["following_error"]
    return process.envelope_of(cfg, cut_path, fp, {**mfacts, **facts}, plots=plots,
                               meta={"process": "rcse", "path": cfg.rcse.path})


def _cut(cfg, surface, plan: Plan) -> Cut:
    """Cut along the RCSE path, or (``rcse.path = "conventional"``) along the conventional
    grid-interpolated path Z-compensated on its own point cloud, either on the
    machine and material, with the burrs of ``[artifacts.burrs]``."""
    conventional = cfg.rcse.path == "conventional"
    t = turn(cfg, surface, plan.program, plots=not conventional)
    machined, design, timing = t["machined"], t["design"], t["timing"]
    facts = dict(t["facts"])
    plots = dict(t["plots"])
    followed = t["followed"]
    if cfg.rcse.compare_conventional or conventional:
        t1 = time.perf_counter()
        res = rcse_comparison(cfg, plan.program, surface, machined=machined, design=design,
                              conventional_machined=conventional)
        comp, (rcse_path, conv_path) = res[0], res[1]
        timing["comparison"] = time.perf_counter() - t1
        if "following_error" in facts:
            comp["rcse"]["following_error"] = facts["following_error"]
        if conventional:  # the surface is the conventional path's cut
            conv_cut = res[2]
            machined, followed = conv_cut["machined"], conv_cut["followed"]
            facts = dict(conv_cut["facts"])
            plots = dict(conv_cut["plots"])
        facts["rcse"] = {**plan.facts["rcse"], "comparison": comp, "path": cfg.rcse.path}
        if cfg.rcse.spread_elements:
            t1 = time.perf_counter()
            facts["rcse"]["comparison"]["spread"] = element_spread(cfg, surface)
            timing["spread"] = time.perf_counter() - t1
        plots.update(_comparison_plots(cfg, rcse_path, conv_path))
    meta = {"process": "rcse", "compensation": cfg.process.compensation,
            "seed": cfg.simulation.seed, "path": cfg.rcse.path,
            "machine": cfg.machine.preset, "material": cfg.material.preset}
    return Cut(machined, design, facts, timing, meta, followed=followed, plots=plots)


class RcseProcess(TiledTurningProcess):
    """Turning along the RCSE path; ``compare`` puts it against the conventional path.
    Tiled when large (without the residuals of the comparison)."""

    config = RcseProcessConfig
    inputs = RcseInputs

    plan_window = Process.plan_window  # its own path: planned for the region as before

    def plan(self, cfg: TurningInputs, surface: Surface, *,
             region: Sequence[float] | None = None, sectors: bool = False) -> Plan:
        # ``sectors`` is not used: this process plans its region as before (plan_window)
        plan = _plan(cfg, surface, region=region)
        plan.plots = self.program_plots(cfg, cast(ToolPath, plan.program))
        return plan

    def cut(self, cfg: TurningInputs, surface: Surface, plan: Plan) -> Cut:
        return _cut(cfg, surface, plan)

    def envelope(self, cfg: TurningInputs, surface: Surface, plan: Plan) -> Envelope:
        return _tiled_envelope(self, cfg, surface, plan)

    def traits(self, cfg: TurningInputs) -> Traits:
        return turning_traits(cfg, cut_rate=CUT_RATE)

    def variants(self, cfg: Any) -> VariantPair:
        """The surface cut along the RCSE path against the one cut along the conventional
        grid-interpolated path."""
        st = cfg.rcse
        return VariantPair(
            Variant("rcse", "RCSE path (CCPs on the spiral)", {"rcse.path": "rcse"}),
            Variant("conventional", f"conventional path ({st.interpolation} interpolation in a "
                                    f"{st.grid_spacing * MM_TO_UM:.3g} um point cloud)",
                    {"rcse.path": "conventional"}),
            key="rcse.path",
            about=("RCSE against the conventional path: the conventional CCPs come from a "
                   "rectangular point cloud, so X reciprocates and the profile carries the "
                   "interpolation error; the RCSE CCPs lie on the spiral (the RCSE study, "
                   "Optica 2024)."))


register_process(RcseProcess())
