"""Slow-tool-servo (STS) turning: scene -> tool path -> machined height map."""

from __future__ import annotations

import time

import numpy as np

from ..errors import MemoryBudgetError
from ._heightmap import HeightMap
from ._metrics import residual_metrics
from ._result import SimulationResult


def grid_of(region, pixel):
    x0, y0, x1, y1 = region
    nx = int(round((x1 - x0) / pixel)) + 1
    ny = int(round((y1 - y0) / pixel)) + 1
    return ny, nx


def estimate_memory(scene, n_path_points: int | None = None) -> int:
    """Bytes the simulation will hold at its peak: design + machined (float64) plus one
    chunk of temporaries, plus the path (theta, rho, z, t, CCPs and lookup table)."""
    ny, nx = grid_of(scene.simulation.region, scene.simulation.pixel)
    if n_path_points is None:
        from ..toolpath import region_radii

        r_in, r_out = region_radii(scene.simulation.region, scene.tool.nose_radius)
        revs = (min(r_out, scene.process.workpiece_radius) - r_in) / scene.process.feed_per_rev
        n_path_points = int(revs * scene.process.points_per_rev) + 1
    return int(ny * nx * 8 * 2 + min(ny, 512) * nx * 8 * 4 + n_path_points * 8 * 10)


def check_memory(scene, n_path_points=None):
    est = estimate_memory(scene, n_path_points)
    budget = scene.simulation.max_memory_gb * 2 ** 30
    if est > budget:
        ny, nx = grid_of(scene.simulation.region, scene.simulation.pixel)
        raise MemoryBudgetError(
            f"the simulation would need about {est / 2**30:.2f} GiB ({ny} x {nx} samples) but "
            f"simulation.max_memory_gb is {scene.simulation.max_memory_gb}; shrink "
            f"simulation.region, increase simulation.pixel (each doubling quarters the memory) "
            f"or raise simulation.max_memory_gb")
    return est


def design_grid(surface, region, pixel, *, rows_per_chunk: int = 128, out=None) -> np.ndarray:
    """Design heights on the grid, evaluated in row chunks (bounded temporaries) on a
    thread per core (numpy releases the GIL)."""
    import os
    from concurrent.futures import ThreadPoolExecutor

    x0, y0, _, _ = region
    ny, nx = grid_of(region, pixel)
    x = x0 + pixel * np.arange(nx)
    if out is None:
        out = np.empty((ny, nx), dtype=np.float64)

    def rows(a):
        y = y0 + pixel * np.arange(a, min(a + rows_per_chunk, ny))
        out[a:a + len(y)] = surface.height(x[None, :], y[:, None])

    starts = range(0, ny, rows_per_chunk)
    if ny * nx < 1_000_000:
        for a in starts:
            rows(a)
    else:
        with ThreadPoolExecutor(max_workers=os.cpu_count() or 1) as ex:
            list(ex.map(rows, starts))
    return out


def toolpath_metrics(path) -> dict:
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
    if "accessibility" in m:
        d["accessible"] = m["accessibility"]["ok"]
        d["accessibility"] = m["accessibility"]
    return d


def turned_grid(scene, surface, path, timing: dict) -> tuple[np.ndarray, np.ndarray]:
    """(machined, design) on the simulation grid for a turning ``path``: the envelope of
    the tool nose plus the design heights; records ``envelope`` / ``design`` seconds."""
    from ..toolpath import Tool
    from ._envelope import simulate_turning

    sim = scene.simulation
    tool = Tool.from_config(scene.tool)
    t0 = time.perf_counter()
    machined = simulate_turning(path, nose_radius=tool.nose_radius, region=sim.region, pixel=sim.pixel,
                                half_width=tool.half_width)
    timing["envelope"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    design = design_grid(surface, sim.region, sim.pixel)
    timing["design"] = time.perf_counter() - t0
    return machined, design


def simulate_sts(scene, surface=None) -> SimulationResult:
    """Simulate STS turning of ``scene`` over ``scene.simulation.region``."""
    from ..design import make_surface
    from ..toolpath import build_toolpath

    timing = {}
    check_memory(scene)
    surface = surface if surface is not None else make_surface(scene.design)
    sim = scene.simulation
    t0 = time.perf_counter()
    path = build_toolpath(scene, surface, region=sim.region)
    timing["toolpath"] = time.perf_counter() - t0
    check_memory(scene, path.points)
    machined, design = turned_grid(scene, surface, path, timing)
    t0 = time.perf_counter()
    origin = (sim.region[0], sim.region[1])
    metrics = {}
    if scene.artifacts.burrs.height > 0:
        from ._burrs import apply_burrs

        machined, metrics["burrs"] = apply_burrs(machined, design, pixel=sim.pixel, origin=origin,
                                                 cfg=scene.artifacts.burrs, seed=sim.seed)
    hm = HeightMap(design, machined, sim.pixel, origin, scene.to_dict(),
                   {"process": "sts", "compensation": scene.process.compensation, "seed": sim.seed})
    metrics.update(residual=residual_metrics(hm), toolpath=toolpath_metrics(path))
    timing["metrics"] = time.perf_counter() - t0
    timing["simulate"] = timing["envelope"] + timing["design"] + timing["metrics"]
    return SimulationResult(hm, path, metrics, timing)
