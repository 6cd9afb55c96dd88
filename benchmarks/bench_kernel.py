"""Benchmark: the envelope kernel alone on the seed-000 benchmark grid (2 x 2 mm at 0.5 um,
16.0 M samples, Z-compensated path), against the memory bandwidth of the same machine.

Reports
- the fast kernel's samples/s on all cores and on one, and the reference kernel's;
- a streaming triad a = b + s c over float64 arrays of the map's size (numba, all
  cores): bytes moved per second, counting the write-allocate read of ``a`` (32 B per
  element), and the kernel's time over the time it would take if it were bound by that
  bandwidth (it writes 8 B per sample, 16 B with the write-allocate read; the path is
  read from cache);
- the numba compile cost: a first run with an empty cache folder against a warm run (each
  in a fresh process: import + compile or load + one small simulation).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from _timing import best_of

REPO = Path(__file__).resolve().parents[1]

_COLD = ("import time; t0 = time.perf_counter(); from render_inspect.pipeline._warmup import warm_up; "
         "warm_up(); print(time.perf_counter() - t0)")


def main(repeats: int = 3) -> dict:
    import numba
    from numba import njit, prange

    from render_inspect.design import make_surface
    from render_inspect.machining import simulate_turning
    from render_inspect.processes import plan_spiral
    from render_inspect.toolpath import Tool
    from render_inspect.scene import load_scene

    region, pixel = (-1.0, -1.0, 1.0, 1.0), 0.0005
    scene = load_scene(REPO / "scenes" / "sts_sinusoidal_grid.toml",
                       [f"simulation.region={list(region)}", f"simulation.pixel={pixel}"])
    path = plan_spiral(scene, make_surface(scene.design), region=region)
    tool = Tool.from_config(scene.tool)
    kw = dict(nose_radius=tool.nose_radius, half_width=tool.half_width, region=region, pixel=pixel)
    out = np.empty((4001, 4001))
    simulate_turning(path, **{**kw, "region": (0, 0, 0.01, 0.01)})
    simulate_turning(path, reference=True, **{**kw, "region": (0, 0, 0.01, 0.01)})
    n = out.size
    cores = numba.get_num_threads()
    fast = best_of(lambda: simulate_turning(path, out=out, **kw), repeats)[0]
    numba.set_num_threads(1)
    fast1 = best_of(lambda: simulate_turning(path, out=out, **kw), repeats)[0]
    numba.set_num_threads(cores)
    ref = best_of(lambda: simulate_turning(path, out=out, reference=True, **kw), max(1, repeats - 1))[0]
    a = simulate_turning(path, **kw)
    b = simulate_turning(path, reference=True, **kw)
    max_diff = float(np.nanmax(np.abs(a - b)))
    del a, b

    @njit(parallel=True)
    def triad(x, y, z, s):
        for i in prange(x.size):
            x[i] = y[i] + s * z[i]

    x, y, z = np.empty(n), np.ones(n), np.ones(n)
    triad(x, y, z, 2.0)
    t_triad = best_of(lambda: triad(x, y, z, 2.0), 5)[0]
    bw = 32 * n / t_triad
    bound = 16 * n / bw

    def fresh(cache):
        env = dict(os.environ, NUMBA_CACHE_DIR=cache)
        t0 = time.perf_counter()
        p = subprocess.run([sys.executable, "-c", _COLD], env=env, capture_output=True, text=True, check=True)
        return time.perf_counter() - t0, float(p.stdout.strip().splitlines()[-1])

    with tempfile.TemporaryDirectory() as cache:
        cold_proc, cold = fresh(cache)
        warm_proc, warm = fresh(cache)
    fig = {
        "samples": n, "path_points": path.points, "threads": cores,
        "kernel_s": round(fast, 3), "kernel_Msamples_per_s": round(n / fast / 1e6, 1),
        "kernel_1thread_s": round(fast1, 3), "kernel_1thread_Msamples_per_s": round(n / fast1 / 1e6, 1),
        "reference_kernel_s": round(ref, 3), "reference_Msamples_per_s": round(n / ref / 1e6, 1),
        "fast_vs_reference_max_abs_diff_mm": max_diff,
        "triad_s": round(t_triad, 4), "triad_GB_per_s": round(bw / 1e9, 1),
        "kernel_if_bandwidth_bound_s": round(bound, 4), "kernel_over_bandwidth_bound": round(fast / bound, 1),
        "numba_first_run_s": round(cold, 2), "numba_warm_run_s": round(warm, 2),
        "numba_first_process_s": round(cold_proc, 2), "numba_warm_process_s": round(warm_proc, 2),
    }
    print(json.dumps(fig, indent=2))
    return fig


if __name__ == "__main__":
    main()
