"""``simulate``: scene -> plan -> cut -> height map and metrics, and its output folder.

The stages are the scene's process (:class:`~render_inspect.processes.Process`: its
typed inputs, ``plan``, ``cut`` and ``traits``), the metrology of lenslet designs, the one
metrics builder, and the writers and figures of the outputs."""

from __future__ import annotations

from collections.abc import Callable
import json
import logging
import threading
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from ..core.handoff import receiving
from ..core.heightmap import HeightMap
from ..core.progress import task
from ..core.units import BYTES_TO_MIB
from ..design import Surface, make_surface
from ..io import atomic_write_text, export_program, heightmap_overview, writer
from ..machining import design_grid
from ..metrology import lenslet_facts
from ..processes import Cut, Plan, Traits, check_budget, cut_name, process_of
from ..report import draw_figure, preload_drawing, residual_preview_image, residual_preview_png, uses_matplotlib
from ._figure_process import FigureProcess
from ._metrics import simulation_metrics, write_metrics
from ._toolpath import check_links

if TYPE_CHECKING:
    from ..scene import Scene

__all__ = ["Simulation", "simulate", "design_heightmap", "write_simulation", "residual_title",
           "timed"]

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
    traits : Traits
        What the process says of itself (marks, part, compensation, ...).
    timing_s : dict
        Seconds per stage: ``toolpath`` (planning), ``simulate`` (cutting), ``metrics``,
        ``total`` and the processes' own steps.
    lenslets : list or None
        The ``lenslets`` table of a lenslet design (after registration for a lenslet
        array on a base).
    msa : dict or None
        Kong et al. 2020's characterisation facts of a lenslet array on a base
        (registration, base form error, outliers, summary).
    metrics : dict
        The ``metrics.json`` content (:func:`~render_inspect.pipeline.simulation_metrics`).
    """

    scene: Scene
    surface: object
    heightmap: HeightMap
    plan: Plan
    cut: Cut
    traits: Traits
    timing_s: dict = field(default_factory=dict)
    lenslets: list | None = None
    metrics: dict = field(default_factory=dict)
    msa: dict | None = None

    @property
    def program(self) -> Any:
        """The commanded machine program (ToolPath or LinearProgram)."""
        return self.plan.program

    @property
    def toolpath(self) -> Any:
        """The program ``simulate`` saves as ``toolpath.npz`` (the turning tool path), or
        None for a process that saves none (sculpturing)."""
        return self.plan.program if self.traits.saves_program else None

    @property
    def figures(self) -> dict:
        """The figures of the plan and the cut (file name -> figure spec)."""
        return {**self.plan.plots, **self.cut.plots}


def simulate(scene: Scene, *, surface: Surface | None = None,
             preload_figures: bool = False,
             figures: Callable[[dict], None] | None = None) -> Simulation:
    """Simulate the machined surface of ``scene`` over ``scene.simulation.region``.

    The scene's process plans its program for the region, the memory needed is checked
    against the memory budget (``simulation.max_memory_gb``, or a share of the memory
    available) before and after planning, and the process cuts the surface; the metrics
    are built once (:func:`~render_inspect.pipeline.simulation_metrics`).
    ``preload_figures``: once the program is planned (its inputs read and checked),
    import matplotlib in a thread while the surface is cut
    (:func:`~render_inspect.report.preload_drawing`) when a figure of the plan is drawn
    with it, for a caller that draws them next.
    ``figures``: called with the plan's figures (file name -> spec) once the program is
    planned, with each of the cut's as soon as the cut has made it (the following error
    once the machine has followed the program: :mod:`~render_inspect.core.handoff`) and
    with the rest once the surface is cut, each figure once, for a caller that draws them
    while the rest is computed (the command's figure process).
    """
    t_all = time.perf_counter()
    if figures is not None:
        figures = _each_once(figures)
    process = process_of(scene)
    cfg = process.inputs_of(scene)
    traits = process.traits(cfg)
    surface = surface if surface is not None else make_surface(scene.design)
    sim = scene.simulation
    region = tuple(sim.region)
    process.precheck(cfg, region)
    check_budget(sim, process.estimate_memory(cfg))
    t0 = time.perf_counter()
    with task(f"{traits.name}: plan the tool path"):
        plan = process.plan_window(cfg, surface, region)
    timing = dict(plan.timing)
    timing["toolpath"] = time.perf_counter() - t0
    if preload_figures and any(uses_matplotlib(spec) for spec in plan.plots.values()):
        _preload_figures()
    if figures is not None and plan.plots:
        figures(dict(plan.plots))
    # the program's moves between its cuts are simulated too: they never touch
    # the part (metrics toolpath.links; an error naming the block otherwise)
    links = check_links(process, cfg, surface, plan)
    if links is not None:
        plan.facts.setdefault("toolpath", {})["links"] = links
    check_budget(sim, process.estimate_memory(cfg, plan))
    t0 = time.perf_counter()
    ny, nx = sim.shape
    with task(f"{traits.name}: cut {ny * nx:,} samples",
              total=max(0.5, ny * nx / traits.cut_rate), timed=True), receiving(figures):
        # (a figure ready before the cut ends is passed to ``figures`` at once)
        cut = process.cut(cfg, surface, plan)
    timing.update(cut.timing)
    timing["simulate"] = time.perf_counter() - t0
    if figures is not None and cut.plots:
        figures(dict(cut.plots))
    hm = HeightMap(cut.design, cut.machined, sim.pixel, (float(region[0]), float(region[1])),
                   scene.to_dict(), dict(cut.meta))
    t0 = time.perf_counter()
    lenslets, msa = lenslet_facts(surface, hm, scene.metrology)
    if lenslets is not None:
        timing["lenslets"] = time.perf_counter() - t0
    result = Simulation(scene, surface, hm, plan, cut, traits, timing, lenslets, msa=msa)
    t0 = time.perf_counter()
    result.metrics = simulation_metrics(scene, result)
    timing["metrics"] = time.perf_counter() - t0
    timing["total"] = time.perf_counter() - t_all
    result.metrics["timing_s"] = dict(timing)
    return result


def _each_once(figures: Callable[[dict], None]) -> Callable[[dict], None]:
    """``figures``, called with each file name once (a figure handed over during the cut
    is among the cut's plots again at its end)."""
    given: set[str] = set()

    def once(plots: dict) -> None:
        new = {name: spec for name, spec in plots.items() if name not in given}
        given.update(new)
        if new:
            figures(new)

    return once


def design_heightmap(scene: Scene) -> HeightMap:
    """The design sampled on the simulation grid (no machining): ``machined`` = ``design``."""
    sim = scene.simulation
    region = tuple(sim.region)
    z = design_grid(make_surface(scene.design), region, float(sim.pixel))
    return HeightMap(z, z.copy(), float(sim.pixel), (float(region[0]), float(region[1])),
                     scene=scene.to_dict(), meta={"surface": "design", "seed": int(sim.seed)})


def residual_title(name: str, traits: Traits, r: dict) -> str:
    """The title of ``residual.png``."""
    return (f"{name}: residual, compensation {traits.compensation}\n"
            f"Sq {r['Sq_nm']:.2f} nm, Sz {r['Sz_nm']:.1f} nm, min {r['min_nm']:.1f} nm")


def timed(timing: dict, key: str, fn: Callable[..., Any], *args: Any, **kw: Any) -> Any:
    """``fn(*args, **kw)``, its seconds recorded as ``timing[key]``."""
    t0 = time.perf_counter()
    out = fn(*args, **kw)
    timing[key] = round(time.perf_counter() - t0, 4)
    return out


def _preload_figures() -> threading.Thread:
    """Start a thread that imports what the figures are drawn with
    (:func:`~render_inspect.report.preload_drawing`), so that the import overlaps the
    computation instead of delaying the figures at the end.  A failure there is left to
    the drawing, which imports the same and reports it."""

    def run() -> None:
        try:
            preload_drawing()
        except Exception:  # (the figures' own import raises it again, where it is reported)
            pass

    t = threading.Thread(target=run, name="render_inspect-figures-preload", daemon=True)
    t.start()
    return t


def write_simulation(sim: Simulation, out_dir: str | Path, *, preview: bool = True,
                     drawer: FigureProcess | None = None) -> dict:
    """Write heightmap.exr, metrics.json, scene.json, toolpath.npz (the processes that save
    their program) and the figures (residual.png and the plan's and cut's own:
    kinematics.png, following_error.png, ...) into ``out_dir``; return the metrics
    (``timing_s.write`` holds the seconds per file).  ``drawer``: the figure process
    that was sent the plan's and the cut's figures (:func:`simulate`'s ``figures``); it
    draws residual.png too, and is waited for here."""
    out_dir = Path(out_dir)
    scene, hm, metrics = sim.scene, sim.heightmap, sim.metrics
    tw: dict[str, float] = {}
    log.info("writing heightmap.exr (%d x %d, %.0f MiB) ...", hm.shape[1], hm.shape[0],
             hm.design.size * 12 * BYTES_TO_MIB)
    # the progress moves by the files written (the overview, heightmap.exr, toolpath.npz,
    # the figures, metrics.json and scene.json), from both threads
    n_files = 4 + (sim.toolpath is not None) + ((1 + len(sim.figures)) if preview else 0)
    lock = threading.Lock()
    with task(f"write the {hm.design.size:,}-sample height map and previews "
              f"({n_files - 1} files)", total=n_files) as step:

        def written(key, fn, *args, **kwargs):
            value = timed(tw, key, fn, *args, **kwargs)
            with lock:
                step.advance()
            return value

        # one pass for the EXR overview and the preview (area averages)
        overview = written("overview", heightmap_overview, hm.design, hm.machined)

        def figures():
            r = metrics["residual"]
            written("residual.png", residual_preview_png, out_dir / "residual.png", hm.machined,
                    hm.design, extent=hm.extent, mean_nm=r["mean_nm"],
                    title=residual_title(cut_name(scene), sim.traits, r), overview=overview)
            for name, spec in sim.figures.items():
                written(name, draw_figure, spec, out_dir / name)

        def files():
            # the program (uncompressed: its file writes leave the interpreter free) beside
            # the height map
            with ThreadPoolExecutor(1) as pool:
                npz = None if sim.toolpath is None else pool.submit(
                    written, "toolpath.npz", export_program, sim.toolpath, out_dir, fmt="npz")
                written("heightmap.exr", writer("heightmap", ".exr"), out_dir / "heightmap.exr",
                        hm, overview=overview)
                if npz is not None:
                    npz.result()

        if drawer is not None and preview:
            # residual.png by the figure process too (the other figures were sent to it as
            # they were made), while the height map and the program are written here
            r = metrics["residual"]
            img, factor = residual_preview_image(hm.machined, hm.design, overview=overview)
            drawer.residual("residual.png", out_dir / "residual.png", img, factor,
                            extent=hm.extent, mean_nm=r["mean_nm"],
                            title=residual_title(cut_name(scene), sim.traits, r))
            files()

            def done(name: str) -> None:
                with lock:
                    step.advance()

            tw.update(drawer.results(done))
        else:
            # the figures (one thread: matplotlib's state is shared) are drawn while the
            # height map and the program are compressed and written
            with ThreadPoolExecutor(1) as pool:
                drawn = pool.submit(figures) if preview else None
                files()
                if drawn is not None:
                    drawn.result()
        metrics.setdefault("timing_s", {})["write"] = tw
        write_metrics(out_dir, metrics)
        step.advance()
        atomic_write_text(out_dir / "scene.json", json.dumps(scene.to_dict(), indent=2, sort_keys=True))
        step.advance()
    return metrics
