"""Benchmark: the shipped grid scene against the open simulator PySurfSim, side by side in
one run, at the same number of samples.

PySurfSim (L. Schoenemann, LGPL-2.1-or-later) simulates the surface a fly-cutter leaves:
its ``apply_mesh_tool_to_workpiece`` visits every tool position of a raster and lowers the
surface to the tool's shape there (numpy).  It is not part of this repository and is never
downloaded by it: give the folder of a copy you have (the folder that holds its
``PySurfSim`` package) as the first argument or as ``RENDER_INSPECT_PEER``::

    RENDER_INSPECT_PEER=/path/to/PySurfSim .venv/bin/python benchmarks/bench_peer.py
    make bench ONLY=peer RENDER_INSPECT_PEER=/path/to/PySurfSim

Without it the benchmark says where to get one (one line) and measures only this
project's side.  The peer runs in a
subprocess of this Python with its folder on ``sys.path``; it needs only numpy (its
package metadata also lists pandas, joblib and mayavi, which the surface generation does
not import).

What is compared, at 1.0 M samples (1001 x 1001, 1 x 1 mm at 1 um, the scene as shipped)
and 16.0 M samples (4001 x 4001, 2 x 2 mm at 0.5 um):

* ours, ``render-inspect simulate sts_sinusoidal_grid`` on its defaults, each run a fresh
  process (:func:`bench_command.run_simulate`): toolpath + simulate (``timing_s`` of
  metrics.json: planning, the machine's following, the cut, burrs, texture) and the whole
  command (start-up and writing included), wall and CPU time;
* ours, the envelope kernel alone (:func:`render_inspect.machining.simulate_turning` on
  the planned, ideal path; all threads and one thread), in this process;
* the peer on the *matched* problem: the same field and sample grid, the same tool nose
  radius (0.514 mm) and the same step between neighbouring cuts (0.01 mm, the scene's feed
  per revolution, as the fly-cutter's raster step), the peer's own fly-cut radius (60 mm)
  and feed per fly-cut revolution (70 um), and its initial stock of 100 nm (the less stock,
  the smaller the tool's footprint and the faster it runs);
* the peer on its own example's field (0.3348 x 0.3346 mm, 8 um raster, 0.762 mm nose) at
  the same sample count: what its defaults cost.

The two simulators do different work, said with the figures: ours is turning (a spiral
or a slow-tool-servo path of 3600 points per revolution, a lathe's following errors,
minimum chip thickness, burrs and texture); the peer is fly-cutting on a raster of tool
positions, geometry only.  The peer's time grows with (tool positions) x (samples): each
position takes the whole map's maximum and a mask of the whole map.  Where that product
is large (the matched problem at 16 M samples: 6030 positions) the peer runs a block of
rows of its raster from the middle of the field (``PEER_MAX_WORK``, default 5e9
position-samples) and its time is scaled to all rows, said in the figures
(``extrapolated``); at 1 M samples it runs in full, and the full run and the scaled block
are both given there to check the scaling.

Each figure comes with the load average (runnable processes on the machine's cores);
on a shared machine the wall times measure the load, the CPU times (``*_per_cpu_s``) much
less so.  ``BENCH_REPEATS`` (default 2) runs of our command at each size, the best kept.
"""

from __future__ import annotations

import json
import math
import os
import resource
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
REPO = HERE.parent
PEER_ENV = "RENDER_INSPECT_PEER"
#: where the peer is published (cloned by the user, outside this repository)
PEER_URL = "https://github.com/larsschoenemann/PySurfSim"
#: samples per side and field of each size (mm): the grid scene as shipped, and 2 x 2 mm
SIZES = {"1M": (1001, 1.0), "16M": (4001, 2.0)}
#: the grid scene's tool and feed (scenes/sts_sinusoidal_grid.toml)
NOSE_RADIUS_MM = 0.514
FEED_PER_REV_MM = 0.01
#: the peer's own defaults (its ``default_parameters``), nm
PEER_R_FLY_NM = 60e6
PEER_FEED_X_NM = 70e3
PEER_STOCK_NM = 100.0
#: the target: toolpath + simulate at least this many times the peer's samples/s
TARGET_RATIO = 30.0
PEER_EXAMPLE = {"width_nm": 0.334833e6, "height_nm": 0.334618e6, "r_eps_nm": 0.762e6,
                "raster_nm": 8e3}

_PEER_RUN = r"""
import json, math, resource, sys, time
t_start = time.perf_counter()
folder, cfg = sys.argv[1], json.loads(sys.argv[2])
sys.path.insert(0, folder)
import numpy as np
from PySurfSim import MeshToolFlyCut, apply_mesh_tool_to_workpiece, gen_surface_mesh
t_import = time.perf_counter() - t_start
n, w, h = cfg["points"], cfg["width_nm"], cfg["height_nm"]
t0, c0 = time.perf_counter(), time.process_time()
surf = gen_surface_mesh(w, h, cfg["stock_nm"], n, fixed_num_points=True)
num_x = math.ceil(w / cfg["feed_x_nm"]) + 1
num_y = math.ceil(h / cfg["raster_nm"]) + 1
tool_pos = np.meshgrid(np.arange(num_x) * cfg["feed_x_nm"], np.arange(num_y) * cfg["raster_nm"])
tool_pos.append(np.ones(tool_pos[0].shape) * cfg["r_fly_nm"])
rows = num_y if cfg["rows"] is None else min(num_y, cfg["rows"])
first = (num_y - rows) // 2
tool_pos = [a[first:first + rows] for a in tool_pos]
tool = MeshToolFlyCut(r_fly=cfg["r_fly_nm"], delta_r_fly=0.0, r_eps=cfg["r_eps_nm"])
t_setup = time.perf_counter() - t0
t1, c1 = time.perf_counter(), time.process_time()
out = apply_mesh_tool_to_workpiece(surf, tool_pos, tool)
t_cut, c_cut = time.perf_counter() - t1, time.process_time() - c1
z = out[2]
cut = z < cfg["stock_nm"]
m = n // 8
inner = z[m:-m, m:-m]
print(json.dumps({
    "samples": int(z.size), "positions_total": int(num_x * num_y), "positions_run": int(num_x * rows),
    "import_s": t_import, "setup_s": t_setup, "setup_cpu_s": time.process_time() - c0 - c_cut,
    "cut_s": t_cut, "cut_cpu_s": c_cut,
    "cut_fraction": float(cut.mean()),
    "inner_peak_to_valley_nm": float(inner.max() - inner.min()) if rows == num_y else None,
    "max_rss_MiB": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024}))
"""


def peer_folder(given: str | None = None) -> Path | None:
    """The folder to put on ``sys.path`` for ``import PySurfSim`` (the argument, else
    ``RENDER_INSPECT_PEER``); None when neither is given.  A folder without the package
    raises ValueError."""
    raw = given if given else os.environ.get(PEER_ENV, "")
    if not raw:
        return None
    p = Path(raw).expanduser().resolve()
    if (p / "PySurfSim" / "__init__.py").is_file():
        return p
    if p.name == "PySurfSim" and (p / "__init__.py").is_file():
        return p.parent
    raise ValueError(f"bench_peer: {PEER_ENV} (or the argument) must be a folder holding the "
                     f"PySurfSim package (<folder>/PySurfSim/__init__.py); received {raw!r}")


def _child_cpu() -> float:
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def run_peer(folder: Path, cfg: dict) -> dict:
    """One run of the peer in a fresh process; its figures plus the process's wall and CPU
    time and the load average."""
    load0 = os.getloadavg()[0]
    c0, t0 = _child_cpu(), time.perf_counter()
    p = subprocess.run([sys.executable, "-c", _PEER_RUN, str(folder), json.dumps(cfg)],
                       capture_output=True, text=True, cwd=tempfile.gettempdir(),
                       env={k: v for k, v in os.environ.items() if k != "PYTHONPATH"})
    wall, cpu = time.perf_counter() - t0, _child_cpu() - c0
    if p.returncode != 0:
        raise RuntimeError(f"the peer failed:\n{p.stderr[-3000:]}")
    r = json.loads(p.stdout.strip().splitlines()[-1])
    scale = r["positions_total"] / r["positions_run"]
    gen_s = r["setup_s"] + r["cut_s"] * scale
    gen_cpu = r["setup_cpu_s"] + r["cut_cpu_s"] * scale
    n = r["samples"]
    r.update({"extrapolated": scale > 1.0, "rows_scale": round(scale, 3),
              "surface_s": round(gen_s, 3), "surface_cpu_s": round(gen_cpu, 3),
              "surface_Msamples_per_s": round(n / gen_s / 1e6, 4),
              "surface_Msamples_per_cpu_s": round(n / gen_cpu / 1e6, 4),
              # the process as a command: start-up and import + the whole surface
              "process_s": round(wall + (r["cut_s"] * (scale - 1.0)), 3),
              "process_cpu_s": round(cpu + (r["cut_cpu_s"] * (scale - 1.0)), 3),
              "load_average": [round(load0, 2), round(os.getloadavg()[0], 2)]})
    r["process_Msamples_per_s"] = round(n / r["process_s"] / 1e6, 4)
    r["process_Msamples_per_cpu_s"] = round(n / r["process_cpu_s"] / 1e6, 4)
    for k in ("import_s", "setup_s", "setup_cpu_s", "cut_s", "cut_cpu_s", "cut_fraction",
              "max_rss_MiB"):
        r[k] = round(r[k], 4)
    return r


def peer_config(points: int, field_mm: float, *, example: bool = False,
                max_work: float = 5e9) -> dict:
    """The peer's problem at ``points`` x ``points`` samples: matched to the grid scene over
    ``field_mm`` (``example=False``) or on its own example's field; ``rows`` limits the raster
    rows run so that positions x samples stays under ``max_work`` (None: all)."""
    if example:
        cfg = dict(PEER_EXAMPLE)
    else:
        cfg = {"width_nm": field_mm * 1e6, "height_nm": field_mm * 1e6,
               "r_eps_nm": NOSE_RADIUS_MM * 1e6, "raster_nm": FEED_PER_REV_MM * 1e6}
    cfg.update(points=points, r_fly_nm=PEER_R_FLY_NM, feed_x_nm=PEER_FEED_X_NM,
               stock_nm=PEER_STOCK_NM, rows=None)
    num_x = math.ceil(cfg["width_nm"] / cfg["feed_x_nm"]) + 1
    num_y = math.ceil(cfg["height_nm"] / cfg["raster_nm"]) + 1
    if num_x * num_y * points * points > max_work:
        cfg["rows"] = max(2, int(max_work / (num_x * points * points)))
        if cfg["rows"] >= num_y:
            cfg["rows"] = None
    return cfg


def kernel_alone(field_mm: float, pixel: float, repeats: int = 2) -> dict:
    """Our envelope kernel alone on the grid scene's planned (ideal) path over the field:
    all threads and one thread."""
    import numba
    import numpy as np

    from _timing import best_of
    from render_inspect.design import make_surface
    from render_inspect.machining import simulate_turning
    from render_inspect.processes import plan_spiral
    from render_inspect.scene import load_scene
    from render_inspect.toolpath import Tool

    h = field_mm / 2
    region = (-h, -h, h, h)
    scene = load_scene(REPO / "scenes" / "sts_sinusoidal_grid.toml",
                       [f"simulation.region={list(region)}", f"simulation.pixel={pixel}"])
    path = plan_spiral(scene, make_surface(scene.design), region=region)
    tool = Tool.from_config(scene.tool)
    kw = dict(nose_radius=tool.nose_radius, half_width=tool.half_width, region=region, pixel=pixel)
    n_side = int(round(field_mm / pixel)) + 1
    out = np.empty((n_side, n_side))
    simulate_turning(path, **{**kw, "region": (0, 0, 0.01, 0.01)})   # compile / load
    load0 = os.getloadavg()[0]
    threads = numba.get_num_threads()
    t_all = best_of(lambda: simulate_turning(path, out=out, **kw), repeats)[0]
    numba.set_num_threads(1)
    try:
        c0 = time.process_time()
        t_one = best_of(lambda: simulate_turning(path, out=out, **kw), repeats)[0]
        cpu_one = (time.process_time() - c0) / max(1, repeats)
    finally:
        numba.set_num_threads(threads)
    n = out.size
    return {"samples": n, "path_points": int(path.points), "threads": threads,
            "kernel_s": round(t_all, 4), "kernel_Msamples_per_s": round(n / t_all / 1e6, 2),
            "kernel_1thread_s": round(t_one, 4),
            "kernel_1thread_Msamples_per_s": round(n / t_one / 1e6, 2),
            "kernel_1thread_Msamples_per_cpu_s": round(n / cpu_one / 1e6, 2),
            "load_average": [round(load0, 2), round(os.getloadavg()[0], 2)]}


def _ratio(a: float, b: float) -> float:
    return round(a / b, 2) if b else float("nan")


def main(peer: str | None = None) -> dict:
    folder = peer_folder(peer)
    if str(HERE) not in sys.path:
        sys.path.insert(0, str(HERE))
    from bench_command import SIZES as COMMAND_SIZES
    from bench_command import run_simulate

    repeats = int(os.environ.get("BENCH_REPEATS", "2"))
    max_work = float(os.environ.get("PEER_MAX_WORK", "5e9"))
    only = [s for s in os.environ.get("PEER_SIZES", ",".join(SIZES)).split(",") if s]
    res = {"peer_folder": str(folder) if folder else None, "cpus": os.cpu_count(),
           "load_average_at_start": [round(v, 2) for v in os.getloadavg()]}
    if folder is None:
        msg = (f"bench_peer: no peer given, so only this project's figures are measured. To "
               f"compare, clone the peer outside this repository (it is LGPL; never copy it "
               f"in): git clone {PEER_URL} /some/folder, then set {PEER_ENV}=/some/folder or "
               f"pass the folder")
        print(msg, flush=True)
        res["skipped_peer"] = msg
    tmp = Path(tempfile.mkdtemp(prefix="bench_peer_"))
    try:
        for name in only:
            points, field = SIZES[name]
            pixel = field / (points - 1)
            row = {}
            runs = []
            for _ in range(repeats):
                runs.append(run_simulate(tmp / name, COMMAND_SIZES[name]))
                shutil.rmtree(tmp / name, ignore_errors=True)
            ours = min(runs, key=lambda r: r["command_cpu_s"])
            ours["runs_wall_s"] = [r["command_wall_s"] for r in runs]
            assert ours["samples"] == points * points, (ours["samples"], points)
            row["ours_command"] = ours
            print(name, "ours", json.dumps(ours), flush=True)
            row["ours_kernel"] = kernel_alone(field, pixel)
            print(name, "kernel", json.dumps(row["ours_kernel"]), flush=True)
            if folder is None:
                res[name] = row
                continue
            row["peer_matched"] = run_peer(folder, peer_config(points, field, max_work=max_work))
            print(name, "peer matched", json.dumps(row["peer_matched"]), flush=True)
            if name == "1M" and not row["peer_matched"]["extrapolated"]:
                # the same problem as a block of rows, scaled: checks the scaling used at 16 M
                cfg = peer_config(points, field, max_work=max_work / 10)
                if cfg["rows"] is not None:
                    row["peer_matched_scaled_block"] = run_peer(folder, cfg)
                    print(name, "peer matched (block, scaled)",
                          json.dumps(row["peer_matched_scaled_block"]), flush=True)
            row["peer_example"] = run_peer(folder, peer_config(points, field, example=True,
                                                               max_work=max_work))
            print(name, "peer example", json.dumps(row["peer_example"]), flush=True)
            pm, pe = row["peer_matched"], row["peer_example"]
            ts = ours["toolpath_simulate_Msamples_per_s"]
            row["ratios"] = {
                "toolpath_simulate_vs_peer_matched": _ratio(ts, pm["surface_Msamples_per_s"]),
                "toolpath_simulate_vs_peer_example": _ratio(ts, pe["surface_Msamples_per_s"]),
                "command_vs_peer_matched_process": _ratio(ours["command_Msamples_per_s"],
                                                          pm["process_Msamples_per_s"]),
                "command_cpu_vs_peer_matched_process_cpu": _ratio(
                    ours["command_Msamples_per_cpu_s"], pm["process_Msamples_per_cpu_s"]),
                # CPU seconds, which a loaded machine inflates much less than wall time: our
                # whole command (start-up and writing included) against the peer's surface
                # alone, a lower bound of the toolpath + simulate ratio
                "command_cpu_vs_peer_matched_surface_cpu": _ratio(
                    ours["command_Msamples_per_cpu_s"], pm["surface_Msamples_per_cpu_s"]),
                "command_cpu_vs_peer_example_surface_cpu": _ratio(
                    ours["command_Msamples_per_cpu_s"], pe["surface_Msamples_per_cpu_s"]),
                "kernel_vs_peer_matched": _ratio(row["ours_kernel"]["kernel_Msamples_per_s"],
                                                 pm["surface_Msamples_per_s"]),
                "kernel_1thread_vs_peer_matched": _ratio(
                    row["ours_kernel"]["kernel_1thread_Msamples_per_s"], pm["surface_Msamples_per_s"]),
                "kernel_vs_peer_example": _ratio(row["ours_kernel"]["kernel_Msamples_per_s"],
                                                 pe["surface_Msamples_per_s"]),
            }
            r = row["ratios"]
            r["target_toolpath_simulate"] = TARGET_RATIO
            r["target_met_matched"] = r["toolpath_simulate_vs_peer_matched"] >= TARGET_RATIO
            r["target_met_example"] = r["toolpath_simulate_vs_peer_example"] >= TARGET_RATIO
            print(name, "ratios", json.dumps(r), flush=True)
            res[name] = row
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    res["load_average_at_end"] = [round(v, 2) for v in os.getloadavg()]
    print(json.dumps(res, indent=2))
    return res


if __name__ == "__main__":
    try:
        main(sys.argv[1] if len(sys.argv) > 1 else None)
    except ValueError as e:
        print(e, file=sys.stderr)
        sys.exit(1)
