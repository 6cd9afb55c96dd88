"""Benchmark: hybrid tool servo (seed 002) simulation of ``scenes/hts_toric_msa.toml``.

Runs the scene's default window (2 x 2 lenslets at 5 um) and, with ``--full``, the whole
7 x 7 array (13.8 mm square) at ``pixel`` (default 0.01 mm).  Prints and returns the
stage timings, the path size and the largest lenslet dislocation.

    .venv/bin/python benchmarks/bench_hts.py [--full] [pixel_mm]
"""

from __future__ import annotations

import json
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def _run(overrides):
    from render_inspect.pipeline import simulate as simulate_scene
    from render_inspect.scene import load_scene

    scene = load_scene(REPO / "scenes" / "hts_toric_msa.toml", overrides=overrides)
    t0 = time.perf_counter()
    res = simulate_scene(scene)
    wall = time.perf_counter() - t0
    lens = res.metrics.get("lenslets", [])
    dmax = max(((e["dx_um"] ** 2 + e["dy_um"] ** 2) ** 0.5 for e in lens), default=0.0)
    return {"overrides": overrides, "shape": list(res.heightmap.shape),
            "samples": int(res.heightmap.design.size), "path_points": res.toolpath.points,
            "wall_s": round(wall, 2), "timing_s": {k: round(v, 2) for k, v in res.timing_s.items()},
            "Msamples_per_s": round(res.heightmap.design.size / wall / 1e6, 3),
            "lenslets": len(lens), "max_dislocation_um": round(dmax, 2),
            "effective_lag_angle_mrad": round(res.metrics["servo"]["effective_lag_angle_rad"] * 1e3, 3)}


def main(*, full: bool = False, pixel: float = 0.01) -> dict:
    from render_inspect.pipeline import simulate as simulate_scene  # noqa: F401  (numba warm-up below)

    _run(["simulation.region=[-0.1, -0.1, 0.1, 0.1]"])       # compile the kernels once
    figs = {"default_window": _run([])}
    if full:
        figs["full_array"] = _run(["simulation.region=[-6.9, -6.9, 6.9, 6.9]",
                                   f"simulation.pixel={pixel}"])
    print(json.dumps(figs, indent=2))
    return figs


if __name__ == "__main__":
    args = [a for a in sys.argv[1:] if a != "--full"]
    main(full="--full" in sys.argv[1:], **({"pixel": float(args[0])} if args else {}))
