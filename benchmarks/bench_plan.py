"""Benchmark: planning the turning programs (the process's ``plan``: spiral, tool-radius
compensation, chordal error, accessibility, and the axis kinematics of the facts).

For the shipped grid scene (Li et al. 2018) over its 1 x 1 mm window, over the 2 x 2 mm
window of the simulation benchmarks and over the whole part, and for every shipped turning
scene over its own window: points, seconds (best of ``repeats``, after one warm-up run)
and M points/s.

``python benchmarks/bench_plan.py`` prints and returns the figures.
"""

from __future__ import annotations

import json
import os
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
TURNING = ("sts_sinusoidal_grid", "sts_fig16_overcut", "sts_mla_2x2", "compound_sinusoid",
           "hts_toric_msa", "rcse_circular_array")


def _plan(scene, repeats: int) -> dict:
    from render_inspect.design import make_surface
    from render_inspect.processes import process_of

    process = process_of(scene)
    cfg = process.inputs_of(scene)
    surface = make_surface(scene.design)
    region = tuple(scene.simulation.region)
    plan = process.plan(cfg, surface, region=region)
    best = None
    for _ in range(repeats):
        t0 = time.perf_counter()
        plan = process.plan(cfg, surface, region=region)
        dt = time.perf_counter() - t0
        best = dt if best is None or dt < best else best
    n = int(plan.program.points)
    return {"points": n, "plan_s": round(best, 3), "Mpoints_per_s": round(n / best / 1e6, 2),
            "steps_s": {k: round(v, 3) for k, v in plan.timing.items()}}


def main(repeats: int = 3) -> dict:
    from render_inspect.scene import load_scene

    res = {"load_average_at_start": os.getloadavg()}
    grid = REPO / "scenes" / "sts_sinusoidal_grid.toml"
    for name, region in (("grid_1x1mm", None), ("grid_2x2mm", [-1, -1, 1, 1]),
                         ("grid_whole_part", [-5, -5, 5, 5])):
        over = [] if region is None else [f"simulation.region={region}"]
        res[name] = _plan(load_scene(grid, over), repeats)
        print(name, json.dumps(res[name]), flush=True)
    res["scenes"] = {}
    for name in TURNING[1:]:
        res["scenes"][name] = _plan(load_scene(REPO / "scenes" / f"{name}.toml"), repeats)
        print(name, json.dumps(res["scenes"][name]), flush=True)
    res["load_average_at_end"] = os.getloadavg()
    print(json.dumps(res, indent=2))
    return res


if __name__ == "__main__":
    main()
