"""``simulate``: scene -> plan -> cut -> height map and metrics, and its output folder."""

from __future__ import annotations

import json
import logging
import os
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..core.errors import InputError
from ..core.grid import grid_shape
from ..core.heightmap import HeightMap
from ..core.limits import Driver, format_number, memory_budget
from ..core.toolpath import ToolPath
from ..design import make_surface
from ..io import (
    atomic_output_dir,
    atomic_write_text,
    write_heightmap_exr,
    write_json,
    write_toolpath_npz,
)
from ..io._heightmap import grid_attrs
from ..io._exr import heightmap_overview
from ..io._pyramid import coarsen, level_count, means
from ..io._pyramid import preview as area_preview
from ..io._quickplot import map_png
from ..io._zarr import ZarrHeightMap, create_heightmap_zarr, set_store_attrs
from ..machining import design_grid
from ..core.progress import task
from ..machining._envelope import prepare_envelope
from ..machining._memory import tiled_bytes
from ..machining._metrics import metrics_from_moments
from ..machining._tiled import TILE, plan_tiles
from ..processes import Cut, Plan, check_budget, process_kinds, process_of
from ..processes._turning import machine_bytes, tool_of, turning_points
from ..report import kinematics_png, plot_following_error, plot_following_error_map, plot_kinematics
from ._metrics import lenslet_metrics, msa_metrics, simulation_metrics, tiled_metrics
from ._tiled import dask_client, run_tiles

__all__ = ["Simulation", "simulate", "design_heightmap", "write_simulation", "run_simulate",
           "run_simulate_tiled", "wants_tiles"]

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
        The ``lenslets`` table of a lenslet design (after registration for a lenslet
        array on a base).
    msa : dict or None
        Seed 002's characterisation facts of a lenslet array on a base (registration,
        base form error, outliers, summary).
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
    msa: dict | None = None

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
    checked against the memory budget (``simulation.max_memory_gb``, or a share of the
    memory available) before and after planning, and the
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
    with task(f"{scene.process.kind}: plan the tool path"):
        plan = kind.plan(scene, surface, region=tuple(sim.region))
    timing = dict(plan.timing)
    timing["toolpath"] = time.perf_counter() - t0
    check_budget(scene, kind.estimate_memory(scene, plan))
    t0 = time.perf_counter()
    ny, nx = sim.shape
    with task(f"{scene.process.kind}: cut {ny * nx:,} samples",
              total=_expected_cut_seconds(scene, plan), timed=True):
        cut = kind.cut(scene, surface, plan)
    timing.update(cut.timing)
    timing["simulate"] = time.perf_counter() - t0
    hm = HeightMap(cut.design, cut.machined, sim.pixel, (float(sim.region[0]), float(sim.region[1])),
                   scene.to_dict(), dict(cut.meta))
    t0 = time.perf_counter()
    msa = msa_metrics(surface, hm, scene.metrology) if scene.metrology.registration != "none" \
        else None
    if msa is not None:
        lenslets, msa = msa
    else:
        lenslets = lenslet_metrics(surface, hm)
    if lenslets is not None:
        timing["lenslets"] = time.perf_counter() - t0
    result = Simulation(scene, surface, hm, plan, cut, timing, lenslets, msa=msa)
    t0 = time.perf_counter()
    result.metrics = simulation_metrics(scene, result)
    timing["metrics"] = time.perf_counter() - t0
    timing["total"] = time.perf_counter() - t_all
    result.metrics["timing_s"] = dict(timing)
    return result


#: samples per second the cut runs at, for the progress bar's ETA (README speed table:
#: 12 M samples/s for STS on 2 cores; the other kernels are slower)
_CUT_RATE = {"sts": 4e6, "fts": 2e6, "hts": 2e6, "rcse": 1e6, "sculpt": 5e5}


def _expected_cut_seconds(scene, plan) -> float:
    ny, nx = scene.simulation.shape
    return max(0.5, ny * nx / _CUT_RATE.get(scene.process.kind, 2e6))


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
    elif spec.get("kind") == "following_error":
        plot_following_error(spec["t"], spec["errors"], png, title=spec.get("title"),
                             stats=spec.get("stats"))
    elif spec.get("kind") == "following_error_map":
        plot_following_error_map(spec["x_nm"], spec["z_nm"], spec["extent"], png,
                                 title=spec.get("title"))
    else:
        raise ValueError(f"unknown figure kind {spec.get('kind')!r}")


def residual_preview_png(png, machined, design, *, extent, mean_nm: float, title: str,
                         overview: dict | None = None, side: int = 512) -> Path:
    """residual.png: machined - design less its mean (nm) as area averages of at most
    ``side`` pixels a side (no aliasing of the feed marks; ``render_inspect.io._pyramid``),
    from the EXR overview's block sums when given (no second pass over the map)."""
    if overview is not None and overview["residual"] is not None:
        factor, (s, c) = overview["factor"], overview["residual"]
        while max(s.shape) > side:
            s, c = coarsen(s, c, 2)
            factor *= 2
        img = means(s, c)
    else:
        img, factor = area_preview(machined, side, minus=design)
    return residual_png(png, img, factor, extent=extent, mean_nm=mean_nm, title=title)


def residual_png(png, img, factor: int, *, extent, mean_nm: float, title: str) -> Path:
    """residual.png from an area-averaged residual image (mm) of ``factor`` x ``factor``
    pixel means."""
    img = (np.asarray(img, dtype=np.float32) - np.float32(mean_nm * 1e-6)) * np.float32(1e6)
    avg = f", {factor} x {factor}-pixel means" if factor > 1 else ""
    return map_png(png, img, extent=extent, cmap="RdBu_r", symmetric=True,
                   label=f"machined - design (nm{avg})", title=title)


def _residual_title(scene, r) -> str:
    return (f"{scene.name}: residual, compensation {scene.process.compensation}\n"
            f"Sq {r['Sq_nm']:.2f} nm, Sz {r['Sz_nm']:.1f} nm, min {r['min_nm']:.1f} nm")


def _timed(timing: dict, key: str, fn, *args, **kw):
    t0 = time.perf_counter()
    out = fn(*args, **kw)
    timing[key] = round(time.perf_counter() - t0, 4)
    return out


def _kinematics_png(scene, plan, png, *, rcse=None) -> Path:
    """kinematics.png: the axes that move (:func:`~render_inspect.report.kinematics_png`)
    of the commanded program (the slow slide and FTS shares of a tool-servo program), or,
    for RCSE, X of the RCSE path against the conventional one (seed 004 Figs. 8-9)."""
    if rcse is not None:
        return kinematics_png([(rcse["labels"][0], rcse["path"], {}),
                               (rcse["labels"][1], rcse["reference"], {})], png, axes=("X",),
                              title=f"{scene.name}: X motion, RCSE vs conventional")
    return kinematics_png([(f"{scene.process.kind.upper()} program", plan.program, plan.data)],
                          png, title=f"{scene.name}: the axes that move")

def write_simulation(sim: Simulation, out_dir, *, preview: bool = True) -> dict:
    """Write heightmap.exr, metrics.json, scene.json, toolpath.npz (turning) and the
    previews (residual.png, kinematics.png or the process's own figures) into
    ``out_dir``; return the metrics (``timing_s.write`` holds the seconds per file)."""
    out_dir = Path(out_dir)
    scene, hm, metrics = sim.scene, sim.heightmap, sim.metrics
    tw = {}
    log.info("writing heightmap.exr (%d x %d, %.0f MB) ...", hm.shape[1], hm.shape[0], hm.design.size * 12 / 1e6)
    # one pass for the EXR overview and the preview (area averages)
    overview = _timed(tw, "overview", heightmap_overview, hm.design, hm.machined)
    _timed(tw, "heightmap.exr", write_heightmap_exr, out_dir / "heightmap.exr", hm, overview=overview)
    if sim.toolpath is not None:
        _timed(tw, "toolpath.npz", write_toolpath_npz, out_dir / "toolpath.npz", sim.toolpath)
    if preview:
        r = metrics["residual"]
        _timed(tw, "residual.png", residual_preview_png, out_dir / "residual.png", hm.machined, hm.design,
               extent=hm.extent, mean_nm=r["mean_nm"], title=_residual_title(scene, r), overview=overview)
        for name, spec in sim.cut.plots.items():
            _timed(tw, name, _draw, spec, out_dir / name)
        if sim.toolpath is not None and "kinematics.png" not in sim.cut.plots:
            _timed(tw, "kinematics.png", _kinematics_png, scene, sim.plan, out_dir / "kinematics.png",
                   rcse=sim.cut.plots.get("rcse_kinematics.png"))
    metrics.setdefault("timing_s", {})["write"] = tw
    write_json(out_dir / "metrics.json", metrics)
    atomic_write_text(out_dir / "scene.json", json.dumps(scene.to_dict(), indent=2, sort_keys=True))
    return metrics


def wants_tiles(scene, *, tiled: bool | None = None, workers: int | None = None,
                scheduler: str | None = None) -> bool:
    """Whether ``simulate`` takes the tiled path: when asked (``tiled``, ``workers`` or
    ``scheduler``), or when the in-memory estimate (the process's ``estimate_memory``)
    exceeds the memory budget (``simulation.max_memory_gb``, or the automatic share of
    the memory available: :func:`~render_inspect.core.limits.memory_budget`) and the
    process supports tiles."""
    if tiled is not None:
        return bool(tiled)
    if workers is not None or scheduler:
        return True
    kind = process_of(scene)
    return kind.envelope_path is not None and scene.artifacts.burrs.height == 0 and \
        scene.material.preset == "ideal" and \
        kind.estimate_memory(scene) > memory_budget(scene.simulation.max_memory_gb)[0]


def run_simulate(scene, out, *, tiled: bool | None = None, workers: int | None = None,
                 scheduler: str | None = None, tile: int = TILE, overwrite: bool = False) -> dict:
    """``render-inspect simulate``: heightmap.exr (or heightmap.zarr for maps simulated
    tile by tile), metrics.json, toolpath.npz, residual.png, kinematics.png.

    The tiled path is taken when the map does not fit the memory budget (or when
    ``tiled`` is True, or ``workers`` / ``scheduler`` are given): tiles of ``tile``
    pixels run on Dask (threads of this process; a LocalCluster of ``workers`` processes;
    or the cluster at ``scheduler``).

    ``out`` is checked and locked before the simulation starts and replaced as a whole
    when it is complete (:func:`~render_inspect.io.atomic_output_dir`; ``overwrite``
    allows replacing a folder render_inspect did not write)."""
    if wants_tiles(scene, tiled=tiled, workers=workers, scheduler=scheduler):
        return run_simulate_tiled(scene, out, workers=workers, scheduler=scheduler, tile=tile,
                                  overwrite=overwrite)
    with atomic_output_dir(out, overwrite=overwrite, command="simulate", scene=scene) as tmp:
        t0 = time.perf_counter()
        sim = simulate(scene)
        log.info("simulated %s samples in %.2f s", f"{sim.heightmap.design.size:,}",
                 time.perf_counter() - t0)
        n = sim.heightmap.design.size
        t0 = time.perf_counter()
        # EXR (3 float32 channels, compressed) and the previews: ~1 M samples/s on the CI machine
        with task(f"write the {n:,}-sample height map and previews", total=1.0 + n / 1e6, timed=True):
            metrics = write_simulation(sim, Path(tmp))
    r = metrics["residual"]
    log.info("wrote the outputs in %.2f s; residual Sq %.3f nm, Sz %.2f nm, min %.2f nm -> %s",
             time.perf_counter() - t0, r["Sq_nm"], r["Sz_nm"], r["min_nm"], out)
    return metrics


def _progress(label: str, step=None):
    """A progress callback that logs at most every 2 s (and at the end) and advances
    ``step`` (a :func:`~render_inspect.core.progress.task`: the command line's bar)."""
    last = [0.0]
    shown = [0]

    def report(done: int, total: int, elapsed: float):
        if step is not None and done > shown[0]:
            step.advance(done - shown[0])
            shown[0] = done
        if done == total or elapsed - last[0] >= 2.0:
            last[0] = elapsed
            left = elapsed / done * (total - done) if done else float("nan")
            log.info("%s %d/%d (%.0f %%), %.1f s, about %.0f s left", label, done, total, 100 * done / total,
                     elapsed, left)
    return report


def _tiled_check(scene, nbytes, *, tile: int, in_flight: int, points: int, workers, scheduler) -> int:
    """The memory of a tiled simulation against the budget; the message names ``--tile``
    (memory grows as its square) and the tiles in flight."""
    where = ("on the cluster's workers" if scheduler else
             f"{in_flight} at once" + ("" if workers else " (one per core)"))
    return check_budget(
        scene, nbytes, what=f"the tiled simulation (tiles of {tile} x {tile} pixels, {where}; "
                            f"{format_number(points)} path points)",
        drivers=[Driver("--tile", tile, 2, "pixels", limit=(64, None))],
        hint="or run fewer tiles at once (--workers) or shrink simulation.region")


def run_simulate_tiled(scene, out, *, workers: int | None = None, scheduler: str | None = None,
                       tile: int = TILE, overwrite: bool = False) -> dict:
    """The tiled, out-of-core ``simulate`` (see :func:`run_simulate`): heightmap.zarr (with
    an area-averaged pyramid), metrics.json, scene.json, toolpath.npz, residual.png and
    kinematics.png.  Memory is bounded by the tiles in flight, not by the map.

    ``out`` is checked and locked before the simulation starts, built beside it (the
    store too: Dask workers on other machines need a file system they share with this
    one) and swapped in whole when complete (``overwrite``: see
    :func:`~render_inspect.io.atomic_output_dir`)."""
    t_all = time.perf_counter()
    kind = process_of(scene)
    if kind.envelope_path is None:
        raise InputError(f"the tiled simulation supports process.kind "
                         f"{sorted(k for k, v in process_kinds().items() if v.envelope_path)}; "
                         f"received {scene.process.kind!r} (shrink simulation.region or raise "
                         f"simulation.max_memory_gb to simulate it in memory)")
    if scene.artifacts.burrs.height > 0:
        raise InputError("the tiled simulation does not add burrs: artifacts.burrs.height must be 0 "
                         f"for maps simulated tile by tile, received {scene.artifacts.burrs.height}")
    sim = scene.simulation
    if not (isinstance(tile, int) and not isinstance(tile, bool) and 64 <= tile <= 65536
            and tile % 64 == 0):
        raise InputError(f"--tile must be a multiple of 64 pixels in [64, 65536], received {tile!r}")
    shape = grid_shape(sim.region, sim.pixel)
    origin = (float(sim.region[0]), float(sim.region[1]))
    surface = make_surface(scene.design)
    in_flight = 1 if scheduler else (workers or os.cpu_count() or 1)
    # the whole program is planned in memory: its points against the budget first
    kind.precheck(scene, tuple(sim.region))
    n_est = turning_points(scene)
    _tiled_check(scene, tiled_bytes(tile, n_est, in_flight=in_flight) + machine_bytes(scene),
                 tile=tile, in_flight=in_flight, points=n_est, workers=workers, scheduler=scheduler)
    timing = {}
    # the folder is checked and locked first; the Dask workers start while the path is
    # planned, and are shut down before the folder is swapped in
    with atomic_output_dir(out, overwrite=overwrite, command="simulate", scene=scene) as tmp, \
            dask_client(workers=workers, scheduler=scheduler) as client:
        t0 = time.perf_counter()
        plan = kind.plan(scene, surface, region=tuple(sim.region))
        timing.update(plan.timing)
        timing["toolpath"] = time.perf_counter() - t0
        path, meta = kind.envelope_path(scene, surface, plan)
        if path.points < 2:
            raise InputError(f"the tool path over simulation.region {list(sim.region)} has "
                             f"{path.points} point(s), at least 2 are needed: the region lies off "
                             f"the turned part (process.workpiece_radius, process.inner_radius)")
        tool = tool_of(scene)
        ep = prepare_envelope(path, nose_radius=tool.nose_radius, half_width=tool.half_width)
        est = _tiled_check(scene, tiled_bytes(tile, path.points, in_flight=in_flight)
                           + machine_bytes(scene, plan), tile=tile, in_flight=in_flight,
                           points=path.points, workers=workers, scheduler=scheduler)
        levels = level_count(shape)
        log.info("simulating %s samples in %d tiles of %d x %d pixels (%s) ...", f"{shape[0] * shape[1]:,}",
                 len(plan_tiles(shape, tile)), tile, tile,
                 f"scheduler {scheduler}" if scheduler else f"{workers} Dask workers" if workers else "threads")
        tmp = Path(tmp)
        store = str(tmp / "heightmap.zarr")
        create_heightmap_zarr(store, shape, chunk=tile, levels=levels,
                              attrs=grid_attrs(sim.pixel, origin, scene.to_dict(), meta))
        t0 = time.perf_counter()
        n_tiles = len(plan_tiles(shape, tile))
        with task(f"{scene.process.kind}: cut {n_tiles} tiles", total=n_tiles) as step:
            stats = run_tiles(ep, surface, origin=origin, pixel=sim.pixel, shape=shape, store=store,
                              levels=levels, tile=tile, client=client,
                              workers=None if client else workers,
                              progress=_progress("tiles", step))
        timing["simulate"] = time.perf_counter() - t0
        timing.update({f"tiles_{k}": v for k, v in stats.timing_s.items()})
        residual = metrics_from_moments(stats.moments, stats.abs_dev, shape[0] * shape[1])
        metrics = tiled_metrics(scene, plan, residual, shape, origin, timing)
        metrics["tiles"] = {"count": stats.tiles, "tile_px": tile, "pyramid_levels": levels,
                            "scheduler": scheduler or ("LocalCluster" if workers else "threads"),
                            "workers": workers or (None if scheduler else os.cpu_count()),
                            "memory_estimate_bytes": est}
        lo, hi, counts = stats.histogram
        set_store_attrs(store, residual_histogram={"lo_mm": lo, "hi_mm": hi, "counts": counts.tolist()})
        z = ZarrHeightMap(store)
        tw = {}
        if path is not None:
            _timed(tw, "toolpath.npz", write_toolpath_npz, tmp / "toolpath.npz", plan.program)
        k = z.level_for(512)
        img = z.read("residual", level=k)
        gx, gy = (np.arange(shape[1]) * sim.pixel, np.arange(shape[0]) * sim.pixel)
        extent = (origin[0] + gx[0] - sim.pixel / 2, origin[0] + gx[-1] + sim.pixel / 2,
                  origin[1] + gy[0] - sim.pixel / 2, origin[1] + gy[-1] + sim.pixel / 2)
        _timed(tw, "residual.png", residual_png, tmp / "residual.png", img, 2 ** k, extent=extent,
               mean_nm=residual["mean_nm"], title=_residual_title(scene, residual))
        _timed(tw, "kinematics.png", _kinematics_png, scene, plan, tmp / "kinematics.png")
        timing["write"] = tw
        timing["total"] = time.perf_counter() - t_all
        metrics["timing_s"] = dict(timing)
        write_json(tmp / "metrics.json", metrics)
        atomic_write_text(tmp / "scene.json", json.dumps(scene.to_dict(), indent=2, sort_keys=True))
    log.info("residual Sq %.3f nm, Sz %.2f nm, min %.2f nm -> %s", residual["Sq_nm"], residual["Sz_nm"],
             residual["min_nm"], out)
    return metrics
