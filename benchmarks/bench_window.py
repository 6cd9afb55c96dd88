"""Benchmark: what a window of a turned part costs to plan and to follow, planned in the
sectors that reach it (what ``simulate`` does) against whole revolutions (as before).

Cases: a 0.5 x 0.5 mm window of ``sts_fig16_overcut`` at 0.5 um (1 M samples) on the
``sts_lathe`` machine, a 0.4 x 0.4 mm window of ``hts_toric_msa`` (its FTS at 20 kHz) and
``sts_mla_2x2`` on its own window.  For each: the points planned, the servo ticks (all,
and those the Z slide and the FTS are followed over), the CPU seconds of planning and of
following (best of ``repeats`` after a warm-up) and the largest difference of the followed
tool-tip Z inside the window's sector between the two (mm).

``python benchmarks/bench_window.py`` prints and returns the figures.
"""

from __future__ import annotations

import json
import os
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
CASES = {
    "fig16_0.5mm_1M": ("sts_fig16_overcut", ["simulation.region=[1.0,1.0,1.5,1.5]",
                                             "simulation.pixel=0.0005"]),
    "hts_0.4mm": ("hts_toric_msa", ["simulation.region=[0.55,0.55,0.95,0.95]",
                                    "simulation.pixel=0.001"]),
    "mla_2x2_shipped": ("sts_mla_2x2", []),
}


def _cpu(fn, repeats: int):
    best, out = None, None
    for _ in range(max(1, repeats)):
        c0 = time.process_time()
        out = fn()
        dt = time.process_time() - c0
        best = dt if best is None or dt < best else best
    return best, out


def _case(name: str, over: list, repeats: int) -> dict:
    from render_inspect.design import make_surface
    from render_inspect.processes import process_of
    from render_inspect.processes._mechanics import follow
    from render_inspect.scene import load_scene

    scene = load_scene(REPO / "scenes" / f"{name}.toml", over)
    process = process_of(scene)
    cfg = process.inputs_of(scene)
    surface = make_surface(scene.design)
    region = tuple(scene.simulation.region)
    out, paths = {"samples": int(np.prod(scene.simulation.shape))}, {}
    for key, sectors in (("whole_revolutions", False), ("sectors", True)):
        def plan():
            return process.plan(cfg, surface, region=region, sectors=sectors)
        plan()
        plan_s, p = _cpu(plan, repeats)
        z_fts = (p.data or {}).get("z_fts")

        def run():
            return follow(cfg, p.program, z_fts=z_fts)
        run()
        follow_s, (cut_path, fp, facts) = _cpu(run, repeats)
        m = facts["machine"]
        out[key] = {"points": int(p.program.points), "ticks": m["ticks"],
                    "ticks_z_fts": m.get("ticks_in_sectors", m["ticks"]),
                    "plan_cpu_s": round(plan_s, 3), "follow_cpu_s": round(follow_s, 3)}
        paths[key] = (cut_path, p.program.meta.get("sectors"))
    sec = paths["sectors"][1]
    if sec is not None:
        a0, a1 = sec["sector_rad"]
        (wp, _), (sp, _) = paths["whole_revolutions"], paths["sectors"]
        inside = np.mod(sp.theta - a0, 2 * np.pi) <= a1 - a0
        # the same servo ticks: tick by tick
        out["max_dz_in_sector_mm"] = float(np.max(np.abs(wp.z[inside] - sp.z[inside])))
    return out


def main(repeats: int = 2) -> dict:
    res = {"load_average_at_start": os.getloadavg()}
    for case, (name, over) in CASES.items():
        res[case] = _case(name, over, repeats)
        print(case, json.dumps(res[case]), flush=True)
    res["load_average_at_end"] = os.getloadavg()
    print(json.dumps(res, indent=2))
    return res


if __name__ == "__main__":
    main()
