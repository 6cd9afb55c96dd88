"""Benchmark: vibration-assisted sculpturing (seed 003) of ``scenes/sculpt_quad_mla.toml``.

The paper's 10 x 10 array at p / 80 = 2.5 um (801 x 801 samples), 104 kHz vibration with
16 time samples per period (about 2 million time samples per target line), burrs on.
Prints and returns the timings and the theoretical overcuts.

    .venv/bin/python benchmarks/bench_sculpt.py
"""

from __future__ import annotations

import json
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def main() -> dict:
    from render_inspect.pipeline import simulate as simulate_scene
    from render_inspect.scene import load_scene

    scene = load_scene(REPO / "scenes" / "sculpt_quad_mla.toml")
    simulate_scene(scene.with_overrides(["design.rows=1", "design.cols=1",
                                         "simulation.region=[-0.09, -0.09, 0.09, 0.09]"]))  # compile
    t0 = time.perf_counter()
    res = simulate_scene(scene)
    wall = time.perf_counter() - t0
    m = res.metrics["sculpt"]
    fig = {"shape": list(res.heightmap.shape), "samples": int(res.heightmap.design.size),
           "lines": m["lines"], "time_samples": m["time_samples"],
           "wall_s": round(wall, 2), "timing_s": {k: round(v, 3) for k, v in res.timing_s.items()},
           "Mtime_samples_per_s": round(m["time_samples"] / res.timing_s["simulate"] / 1e6, 1),
           "vibration_overcut_um": round(m["vibration_overcut_um"], 4),
           "tool_edge_overcut_um": round(m["tool_edge_overcut_um"], 4),
           "Sq_nm": round(res.metrics["residual"]["Sq_nm"], 2) if "residual" in res.metrics else None}
    print(json.dumps(fig, indent=2))
    return fig


if __name__ == "__main__":
    main()
