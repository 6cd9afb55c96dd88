"""``simulate``: scene -> plan -> cut -> height map and metrics, and its output folder."""

from __future__ import annotations

import json
import logging
import time
from dataclasses import dataclass, field
from pathlib import Path

from ..core.heightmap import HeightMap
from ..core.toolpath import ToolPath
from ..design import make_surface
from ..io import (
    atomic_output_dir,
    atomic_write_text,
    save_map_png,
    write_heightmap_exr,
    write_json,
    write_toolpath_npz,
)
from ..machining import design_grid
from ..processes import Cut, Plan, check_budget, process_of
from ..report import plot_kinematics
from ._metrics import lenslet_metrics, simulation_metrics

__all__ = ["Simulation", "simulate", "design_heightmap", "write_simulation", "run_simulate"]

log = logging.getLogger("render_inspect")


@dataclass
class Simulation:
    """A simulated part.

    Attributes
    ----------
    scene : Scene
    surface : Surface
        The design.
    heightmap : HeightMap
        Design and machined heights on the simulation grid, mm.
    plan : Plan
        The commanded program (``plan.program``: ToolPath or LinearProgram) and its facts.
    cut : Cut
        The process's cut (facts, the followed path when servo dynamics act).
    timing_s : dict
        Seconds per stage: ``toolpath`` (planning), ``simulate`` (cutting), ``metrics``,
        ``total`` and the processes' own steps.
    lenslets : list or None
        The ``lenslets`` table of a lenslet design.
    metrics : dict
        The ``metrics.json`` content (:func:`~render_inspect.pipeline.simulation_metrics`).
    """

    scene: object
    surface: object
    heightmap: HeightMap
    plan: Plan
    cut: Cut
    timing_s: dict = field(default_factory=dict)
    lenslets: list | None = None
    metrics: dict = field(default_factory=dict)

    @property
    def program(self):
        """The commanded machine program (ToolPath or LinearProgram)."""
        return self.plan.program

    @property
    def toolpath(self) -> ToolPath | None:
        """The turning tool path, or None for a linear (sculpturing) program."""
        return self.plan.program if isinstance(self.plan.program, ToolPath) else None


def simulate(scene, *, surface=None) -> Simulation:
    """Simulate the machined surface of ``scene`` over ``scene.simulation.region``.

    The scene's process kind plans its program for the region, the memory needed is
    checked against ``simulation.max_memory_gb`` before and after planning, and the
    process cuts the surface; the metrics are built once
    (:func:`~render_inspect.pipeline.simulation_metrics`).
    """
    t_all = time.perf_counter()
    kind = process_of(scene)
    surface = surface if surface is not None else make_surface(scene.design)
    kind.precheck(scene, tuple(scene.simulation.region))
    check_budget(scene, kind.estimate_memory(scene))
    sim = scene.simulation
    t0 = time.perf_counter()
    plan = kind.plan(scene, surface, region=tuple(sim.region))
    timing = dict(plan.timing)
    timing["toolpath"] = time.perf_counter() - t0
    check_budget(scene, kind.estimate_memory(scene, plan))
    t0 = time.perf_counter()
    cut = kind.cut(scene, surface, plan)
    timing.update(cut.timing)
    timing["simulate"] = time.perf_counter() - t0
    hm = HeightMap(cut.design, cut.machined, sim.pixel, (float(sim.region[0]), float(sim.region[1])),
                   scene.to_dict(), dict(cut.meta))
    t0 = time.perf_counter()
    lenslets = lenslet_metrics(surface, hm)
    if lenslets is not None:
        timing["lenslets"] = time.perf_counter() - t0
    result = Simulation(scene, surface, hm, plan, cut, timing, lenslets)
    t0 = time.perf_counter()
    result.metrics = simulation_metrics(scene, result)
    timing["metrics"] = time.perf_counter() - t0
    timing["total"] = time.perf_counter() - t_all
    result.metrics["timing_s"] = dict(timing)
    return result


def design_heightmap(scene) -> HeightMap:
    """The design sampled on the simulation grid (no machining): ``machined`` = ``design``."""
    sim = scene.simulation
    region = tuple(sim.region)
    z = design_grid(make_surface(scene.design), region, float(sim.pixel))
    return HeightMap(z, z.copy(), float(sim.pixel), (float(region[0]), float(region[1])),
                     scene=scene.to_dict(), meta={"surface": "design", "seed": int(sim.seed)})


def _draw(spec: dict, png: Path) -> None:
    if spec.get("kind") == "kinematics":
        plot_kinematics(spec["path"], png, reference=spec.get("reference"),
                        labels=spec.get("labels", ("", "")), title=spec.get("title"))
    else:
        raise ValueError(f"unknown figure kind {spec.get('kind')!r}")


def write_simulation(sim: Simulation, out_dir, *, preview: bool = True) -> dict:
    """Write heightmap.exr, metrics.json, scene.json, toolpath.npz (turning) and the
    previews (residual.png, kinematics.png or the process's own figures) into
    ``out_dir``; return the metrics."""
    out_dir = Path(out_dir)
    scene, hm, metrics = sim.scene, sim.heightmap, sim.metrics
    write_heightmap_exr(out_dir / "heightmap.exr", hm)
    if sim.toolpath is not None:
        write_toolpath_npz(out_dir / "toolpath.npz", sim.toolpath)
    if preview:
        r = metrics["residual"]
        save_map_png(out_dir / "residual.png", (hm.residual - r["mean_nm"] * 1e-6) * 1e6,
                     extent=hm.extent, cmap="RdBu_r", symmetric=True, label="machined - design (nm)",
                     title=f"{scene.name}: residual, compensation {scene.process.compensation}\n"
                           f"Sq {r['Sq_nm']:.2f} nm, Sz {r['Sz_nm']:.1f} nm, min {r['min_nm']:.1f} nm")
        for name, spec in sim.cut.plots.items():
            _draw(spec, out_dir / name)
        if sim.toolpath is not None and "rcse_kinematics.png" not in sim.cut.plots:
            plot_kinematics(sim.toolpath, out_dir / "kinematics.png",
                            labels=(f"{scene.process.kind.upper()} path", ""),
                            title=f"{scene.name}: axis motion")
    write_json(out_dir / "metrics.json", metrics)
    atomic_write_text(out_dir / "scene.json", json.dumps(scene.to_dict(), indent=2, sort_keys=True))
    return metrics


def run_simulate(scene, out, *, overwrite: bool = False) -> dict:
    """``render-inspect simulate``: heightmap.exr, metrics.json, toolpath.npz, residual.png.

    ``out`` is checked and locked before the simulation starts and replaced as a whole
    when it is complete (:func:`~render_inspect.io.atomic_output_dir`; ``overwrite``
    allows replacing a folder render_inspect did not write)."""
    with atomic_output_dir(out, overwrite=overwrite, command="simulate", scene=scene) as tmp:
        t0 = time.perf_counter()
        sim = simulate(scene)
        log.info("simulated %s samples in %.2f s", f"{sim.heightmap.design.size:,}",
                 time.perf_counter() - t0)
        metrics = write_simulation(sim, Path(tmp))
    r = metrics["residual"]
    log.info("residual Sq %.3f nm, Sz %.2f nm, min %.2f nm -> %s", r["Sq_nm"], r["Sz_nm"],
             r["min_nm"], out)
    return metrics
