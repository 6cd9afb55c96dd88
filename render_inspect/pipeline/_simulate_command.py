"""``render-inspect simulate``: the in-memory simulation (:func:`~render_inspect.pipeline.simulate`)
written into its folder, or, for a map too large for memory, the tiled, out-of-core
chain: the process's program and the path its nose envelope follows, tiles on Dask into a
Zarr store (:func:`render_inspect.batch.run_tiles`), the metrics reduced across tiles."""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import functools
import json
import logging
import time
from pathlib import Path

import numpy as np

from ..core.errors import InputError
from ..core.grid import grid_shape
from ..core.limits import TILED_SAMPLES, format_number, memory_budget, usable_cpus
from ..core.progress import task
from ..design import make_surface
from ..io import (ZarrHeightMap, atomic_output_dir, atomic_write_text, create_heightmap_zarr,
                  export_program, grid_attrs, level_count, set_store_attrs, chunk_files)
from ..machining import (TILE, CutPath, EnvelopePath, burr_halo, metrics_from_moments, plan_tiles,
                         prepare_cut, prepare_envelope, tiled_bytes)
from ..processes import MirroredSurface, check_budget, cut_name, map_figure_stride, mirrored_region, process_of
from ..toolpath import region_radii
from ..report import draw_figure, residual_png
from ._figure_process import FigureProcess
from ._metrics import tiled_metrics, write_metrics
from ._simulate import residual_title, simulate, timed, write_simulation
from ._toolpath import check_links, log_program_summary

if TYPE_CHECKING:
    from ..scene import Scene

__all__ = ["run_simulate", "run_simulate_tiled", "wants_tiles", "TILED_SAMPLES"]

log = logging.getLogger("render_inspect")

def wants_tiles(scene: Scene, *, tiled: bool | None = None, workers: int | None = None,
                scheduler: str | None = None) -> bool:
    """Whether ``simulate`` takes the tiled path: when asked (``tiled``, ``workers`` or
    ``scheduler``), or when the process can be simulated tile by tile and the map has more
    than :data:`TILED_SAMPLES` samples or its in-memory estimate (the process's
    ``estimate_memory``) exceeds the memory budget (``simulation.max_memory_gb``, or the
    automatic share of the memory available:
    :func:`~render_inspect.core.limits.memory_budget`)."""
    if tiled is not None:
        return bool(tiled)
    if workers is not None or scheduler:
        return True
    process = process_of(scene)
    cfg = process.inputs_of(scene)
    if process.tile_refusal(cfg) is not None:
        return False
    ny, nx = grid_shape(scene.simulation.region, scene.simulation.pixel)
    return ny * nx > TILED_SAMPLES or \
        process.estimate_memory(cfg) > memory_budget(scene.simulation.max_memory_gb)[0]


def _check_tile(tile: Any) -> None:
    # a power of two: the store's pyramid halves the tiles level by level; at most 16384:
    # a float32 chunk of a larger tile is over the 1 GiB a zarr chunk may hold, and the
    # store could not be read back
    if not (isinstance(tile, int) and not isinstance(tile, bool) and tile in _TILES):
        raise InputError(f"--tile must be a power of two from 64 to 16384 pixels (the "
                         f"store's pyramid halves the tiles; a larger tile makes zarr chunks "
                         f"over 1 GiB), received {tile!r}")


#: the tile sides --tile accepts
_TILES = tuple(64 << k for k in range(9))


def run_simulate(scene: Scene, out: str | Path, *, tiled: bool | None = None,
                 workers: int | None = None,
                 scheduler: str | None = None, tile: int = TILE, overwrite: bool = False,
                 figure_process: bool = False) -> dict:
    """``render-inspect simulate``: heightmap.exr (or heightmap.zarr for maps simulated
    tile by tile), metrics.json, toolpath.npz, residual.png, kinematics.png.

    The tiled path is taken when the map does not fit the memory budget (or when
    ``tiled`` is True, or ``workers`` / ``scheduler`` are given): tiles of ``tile``
    pixels run on Dask (threads of this process; a LocalCluster of ``workers`` processes;
    or the cluster at ``scheduler``).

    ``out`` is checked and locked before the simulation starts and replaced as a whole
    when it is complete (:func:`~render_inspect.io.atomic_output_dir`; ``overwrite``
    allows replacing a folder render_inspect did not write).

    ``figure_process``: draw the figures in a second process forked when the command
    starts, beside the computation (Linux; for the ``render-inspect`` program, whose
    process is its own: docs/performance.md, "Writing outputs"); else in a thread of this
    process."""
    # (checked whichever path the map takes: a bad value is never passed over in silence)
    _check_tile(tile)
    if wants_tiles(scene, tiled=tiled, workers=workers, scheduler=scheduler):
        return run_simulate_tiled(scene, out, workers=workers, scheduler=scheduler, tile=tile,
                                  overwrite=overwrite)
    # (forked before the output folder is locked, and before any thread of numba's starts)
    drawer = FigureProcess.start() if figure_process else None
    try:
        with atomic_output_dir(out, overwrite=overwrite, command="simulate", scene=scene) as tmp:
            try:
                metrics, t_write = _simulate_into(scene, Path(tmp), drawer)
            finally:  # (before the folder is swapped in or removed)
                if drawer is not None:
                    drawer.close()
    finally:
        if drawer is not None:
            drawer.close()
    if "program" in metrics:  # a program read from a file: what was inferred, the findings
        log_program_summary(metrics["program"], "metrics.json")
    for text in metrics.get("tool_edge", {}).get("warnings", []):  # the cut beyond the measured edge
        log.warning("warning: %s", text)
    r = metrics["residual"]
    log.info("wrote the outputs in %.2f s; residual Sq %.3f nm, Sz %.2f nm, min %.2f nm -> %s",
             t_write, r["Sq_nm"], r["Sz_nm"], r["min_nm"], out)
    return metrics


def _simulate_into(scene: Scene, tmp: Path, drawer: FigureProcess | None) -> tuple[dict, float]:
    """The in-memory simulation written into ``tmp``; the figures by ``drawer`` when given
    (each sent as soon as it is made), else in a thread.  Returns the metrics and the
    seconds the writing took."""
    t0 = time.perf_counter()
    if drawer is None:
        # (the figures' library is imported in a thread while the part is cut)
        sim = simulate(scene, preload_figures=True)
    else:
        def send(plots: dict) -> None:
            for name, spec in plots.items():
                drawer.draw(name, spec, tmp / name)

        sim = simulate(scene, figures=send)
    log.info("simulated %s samples in %.2f s", f"{sim.heightmap.design.size:,}",
             time.perf_counter() - t0)
    t0 = time.perf_counter()
    # (its progress: the files written)
    metrics = write_simulation(sim, tmp, drawer=drawer)
    return metrics, time.perf_counter() - t0


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
            log.info("%s %d/%d (%.0f %%), %.1f s, about %.0f s left", label, done, total,
                     100 * done / total, elapsed, left)
    return report


def _tiled_check(simulation, bytes_at: Callable[[int, int], int], *, tile: int, in_flight: int,
                 points: int, workers, scheduler, halo: int = 0) -> int:
    """The memory of a tiled simulation (``bytes_at(tile, in_flight)``: its bytes with tiles
    of that side, that many at once) against the budget.  The message names the largest
    ``--tile`` (a power of two) that fits, worked out with ``bytes_at`` itself; where none
    does, what holds the memory (the burr model's ``halo`` of pixels around each tile,
    which grows as 1 / pixel where the feed sets the smoothing); and the region."""
    where = ("on the cluster's workers" if scheduler else
             f"{in_flight} at once" + ("" if workers else " (one per core)"))
    nbytes = bytes_at(tile, in_flight)
    budget = memory_budget(simulation.max_memory_gb)[0]
    what = (f"the tiled simulation (tiles of {tile} x {tile} pixels, {where}; "
            f"{format_number(points)} path points")
    if halo:
        what += f"; the burr model reads {halo} pixels around each tile"
    what += ")"
    hints = []
    if nbytes > budget:
        fits = next((t for t in reversed(_TILES) if t < tile and bytes_at(t, in_flight) <= budget),
                    None)
        if fits is not None:
            hints.append(f"to fit, set --tile {fits} (now {tile})")
        elif halo > tile // 2:
            hints.append(f"the burrs are smoothed over max(feed, 2 pixels), {halo} pixels at "
                         f"simulation.pixel {simulation.pixel:g} mm: a coarser simulation.pixel, "
                         f"or material.burrs = false")
        if in_flight > 1 and not scheduler and bytes_at(tile, 1) <= budget:
            hints.append("run one tile at a time (--workers 1)")
        # (the path planned and followed is that of the passes that reach the region)
        hints.append("or shrink simulation.region")
    hint = "; ".join(hints) if hints else None
    return check_budget(simulation, nbytes, what=what, drivers=[], hint=hint)


def _may_leave_uncut(region, path, env) -> bool:
    """Whether the path may leave pixels of ``region`` uncut (NaN: a tile's burrs are then
    computed on a wider block, :func:`~render_inspect.machining.burr_halo` with ``nan``):
    the region reaches radii the nose does not sweep."""
    rho = np.abs(np.asarray(path.rho))
    if rho.size == 0:
        return True
    r_in, r_out = region_radii(tuple(region), 0.0)
    hw = float(env.half_width)
    return bool(r_out > float(rho.max()) + hw or r_in < float(rho.min()) - hw)


def _stored_row(store: str, row: int) -> np.ndarray:
    """Row ``row`` of the residual (machined - design, mm) the tiles stored in ``store``
    (float32 there; only the chunks that hold the row are read)."""
    return np.asarray(ZarrHeightMap(store).read("residual", rows=slice(row, row + 1))[0],
                      dtype=np.float64)


def run_simulate_tiled(scene: Scene, out: str | Path, *, workers: int | None = None,
                       scheduler: str | None = None,
                       tile: int = TILE, overwrite: bool = False) -> dict:
    """The tiled, out-of-core ``simulate`` (see :func:`run_simulate`): heightmap.zarr (with
    an area-averaged pyramid), metrics.json, scene.json, toolpath.npz, residual.png and
    the program's figures.  Memory is bounded by the tiles in flight, not by the map.

    ``out`` is checked and locked before the simulation starts, built beside it (the
    store too: Dask workers on other machines need a file system they share with this
    one) and swapped in whole when complete (``overwrite``: see
    :func:`~render_inspect.io.atomic_output_dir`)."""
    # (the tiles' machinery, imported here: an in-memory simulation does not need it)
    from ..batch import cluster_info, run_tiles, tile_client

    t_all = time.perf_counter()
    process = process_of(scene)
    cfg = process.inputs_of(scene)
    refusal = process.tile_refusal(cfg)
    if refusal is not None:
        raise InputError(refusal)
    traits = process.traits(cfg)
    sim = scene.simulation
    _check_tile(tile)
    shape = grid_shape(sim.region, sim.pixel)
    origin = (float(sim.region[0]), float(sim.region[1]))
    surface = make_surface(scene.design)
    # a LocalCluster has at most one worker per core (batch.plan_workers); threads: one
    # per CPU this process may use
    cpus = usable_cpus()
    in_flight = 1 if scheduler else min(workers or cpus, cpus)
    # the whole program is planned in memory: its points against the budget first
    process.precheck(cfg, tuple(sim.region))
    extra, n_est = process.tiled_memory(cfg)
    # two phases: the machine model following the whole path, then the tiles
    following = process.following_memory(cfg)
    _tiled_check(sim, lambda t, k: max(tiled_bytes(t, n_est, in_flight=k) + extra, following),
                 tile=tile, in_flight=in_flight, points=n_est, workers=workers, scheduler=scheduler)
    timing = {}
    # the folder is checked and locked first; the Dask workers start while the path is
    # planned, and are shut down before the folder is swapped in
    with atomic_output_dir(out, overwrite=overwrite, command="simulate", scene=scene) as tmp, \
            tile_client(workers=workers, scheduler=scheduler) as client:
        t0 = time.perf_counter()
        plan = process.plan_window(cfg, surface, tuple(sim.region))
        timing.update(plan.timing)
        timing["toolpath"] = time.perf_counter() - t0
        # the moves between the cuts never touch the part (metrics toolpath.links)
        links = check_links(process, cfg, surface, plan)
        if links is not None:
            plan.facts.setdefault("toolpath", {})["links"] = links
        env = process.envelope(cfg, surface, plan)
        path = env.path
        if path.points < 2:
            raise InputError(f"the tool path over simulation.region {list(sim.region)} has "
                             f"{path.points} point(s), at least 2 are needed: the region lies off "
                             f"the turned part (process.workpiece_radius, process.inner_radius)")
        mat = env.mechanics
        ep: EnvelopePath | CutPath
        if mat is None:
            ep = prepare_envelope(path, nose_radius=env.nose_radius, half_width=env.half_width,
                                  edge=env.edge)
        else:  # the material's cutting mechanics, pixel by pixel
            ep = prepare_cut(path, nose_radius=env.nose_radius, half_width=env.half_width,
                             h_min=mat.h_min, kappa=mat.kappa, side_flow=mat.side_flow, edge=env.edge,
                             h_min_points=getattr(env, "h_min_points", None))
        # the following-error map of the pass that cut each point, on a coarse grid
        stride = map_figure_stride(shape) if env.followed is not None else 0
        extra, _ = process.tiled_memory(cfg, plan)
        # with the material's burrs each tile is cut with the burr model's halo (the wider
        # one of a block with NaN pixels: the bound)
        halo = 0 if env.burrs is None else burr_halo(sim.pixel, env.burrs["smoothing"],
                                                     env.burrs["width"],
                                                     nan=_may_leave_uncut(sim.region, path, env))
        following = process.following_memory(cfg, plan)
        est = _tiled_check(sim, lambda t, k: max(tiled_bytes(t, path.points, in_flight=k,
                                                             material=mat is not None, burr_halo=halo,
                                                             shape=shape) + extra, following),
                           tile=tile, in_flight=in_flight, points=path.points, workers=workers,
                           scheduler=scheduler, halo=halo)
        levels = level_count(shape)
        n_tiles = len(plan_tiles(shape, tile))
        log.info("simulating %s samples in %d tiles of %d x %d pixels (%s) ...",
                 f"{shape[0] * shape[1]:,}", n_tiles, tile, tile,
                 f"scheduler {scheduler}" if scheduler else
                 f"{cluster_info(client)['workers']} Dask workers" if client else "threads")
        tmp = Path(tmp)
        store = str(tmp / "heightmap.zarr")
        create_heightmap_zarr(store, shape, chunk=tile, levels=levels,
                              attrs=grid_attrs(sim.pixel, origin, scene.to_dict(), env.meta))
        # a program turning M04: the tiles cut the M03 run of the mirror image (the design
        # mirrored, over the mirrored grid), and the store's rows are turned over after them
        cut_surface, cut_origin = surface, origin
        if env.mirror:
            cut_surface = MirroredSurface(surface)
            cut_origin = mirrored_region(sim.region, sim.pixel)[:2]
        t0 = time.perf_counter()
        with task(f"{traits.name}: cut {n_tiles} tiles", total=n_tiles) as step:
            stats = run_tiles(ep, cut_surface, origin=cut_origin, pixel=sim.pixel, shape=shape,
                              store=store, levels=levels, tile=tile, client=client,
                              workers=None if client else workers,
                              progress=_progress("tiles", step), grooves=env.grooves, stride=stride,
                              texture=env.texture, burrs=env.burrs, flip=env.mirror)
        timing["simulate"] = time.perf_counter() - t0
        timing.update({f"tiles_{k}": v for k, v in stats.timing_s.items()})
        residual = metrics_from_moments(stats.moments, stats.abs_dev, shape[0] * shape[1])
        # (with the residual's metrics: what facts of the whole map need of them)
        facts, cut_plots = process.tiled_facts(cfg, env, {**stats.cut, "residual": residual,
                                                          "residual_row": functools.partial(
                                                              _stored_row, store)},
                                               stride=stride)
        metrics = tiled_metrics(scene, plan, traits, residual, shape, origin, timing, facts=facts)
        metrics["tiles"] = {"count": stats.tiles, "tile_px": tile, "pyramid_levels": levels,
                            "scheduler": scheduler or ("LocalCluster" if workers else
                                                       "client" if client else "threads"),
                            "workers": (cluster_info(client)["workers"] if client else
                                        cpus),
                            "memory_estimate_bytes": est}
        lo, hi, counts = stats.histogram
        set_store_attrs(store, residual_histogram={"lo_mm": lo, "hi_mm": hi,
                                                   "counts": counts.tolist()},
                        chunk_files=chunk_files(store))
        z = ZarrHeightMap(store)
        tw: dict[str, float] = {}
        if traits.saves_program:
            timed(tw, "toolpath.npz", export_program, plan.program, tmp, fmt="npz")
        k = z.level_for(512)
        img = z.read("residual", level=k)
        gx, gy = (np.arange(shape[1]) * sim.pixel, np.arange(shape[0]) * sim.pixel)
        extent = (origin[0] + gx[0] - sim.pixel / 2, origin[0] + gx[-1] + sim.pixel / 2,
                  origin[1] + gy[0] - sim.pixel / 2, origin[1] + gy[-1] + sim.pixel / 2)
        timed(tw, "residual.png", residual_png, tmp / "residual.png", img, 2 ** k, extent=extent,
              mean_nm=residual["mean_nm"], title=residual_title(cut_name(scene), traits, residual))
        for name, spec in {**plan.plots, **cut_plots}.items():
            timed(tw, name, draw_figure, spec, tmp / name)
        timing["write"] = tw
        timing["total"] = time.perf_counter() - t_all
        metrics["timing_s"] = dict(timing)
        write_metrics(tmp, metrics)
        atomic_write_text(tmp / "scene.json", json.dumps(scene.to_dict(), indent=2, sort_keys=True))
    for text in metrics.get("tool_edge", {}).get("warnings", []):  # the cut beyond the measured edge
        log.warning("warning: %s", text)
    log.info("residual Sq %.3f nm, Sz %.2f nm, min %.2f nm -> %s", residual["Sq_nm"],
             residual["Sz_nm"], residual["min_nm"], out)
    return metrics
