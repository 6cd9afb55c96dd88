"""Benchmark: the cutting mechanics of the shipped grid scene (Li et al. 2018 sinusoidal
grid on the ``sts_lathe`` machine, Al 6082, 50 nm edge) on the 2 x 2 mm window at 0.5 um
(4001 x 4001 = 16.0 M samples): the fast kernel against the direct model.

Reports
- the fast kernel (``machining.cut_turning``: minimum chip thickness, elastic recovery,
  side flow and the grooves, in row blocks) on all cores and on one, with and without the
  grooves: seconds and M samples/s;
- the direct model (``cut_turning_mechanics`` + ``finish_surface``) on a 1001 x 1001
  part of the window, its seconds per sample scaled to the window, and the largest
  difference between the two there (mm, and relative to the heights);
- the lathe's servo model on the window's program (``follow_turning``: the path the
  kernel cuts), which runs once per part.

``python benchmarks/bench_material.py`` prints and returns the figures (best of
``repeats``).
"""

from __future__ import annotations

import json
import os
import time
from pathlib import Path

import numpy as np

from _timing import best_of

REPO = Path(__file__).resolve().parents[1]


def main(repeats: int = 3) -> dict:
    import numba

    from render_inspect.design import make_surface
    from render_inspect.machining import (Grooves, cut_turning, cut_turning_mechanics, cutting_distance,
                                          finish_surface, follow_turning, prepare_cut)
    from render_inspect.processes import machine_of, material_of, plan_spiral
    from render_inspect.scene import load_scene
    from render_inspect.toolpath import Tool, ToolPath

    region, pixel = (-1.0, -1.0, 1.0, 1.0), 0.0005
    scene = load_scene(REPO / "scenes" / "sts_sinusoidal_grid.toml",
                       [f"simulation.region={list(region)}", f"simulation.pixel={pixel}"])
    path = plan_spiral(scene, make_surface(scene.design), region=region)
    t_follow, fp = best_of(lambda: follow_turning(path.t, path.theta, path.rho, path.z,
                                                machine_of(scene.machine), seed=0), 1)
    cut = ToolPath(fp.theta, fp.rho, fp.z, fp.t)
    tool = Tool.from_config(scene.tool)
    resp = material_of(scene.material)
    t_prep, cp = best_of(lambda: prepare_cut(cut, nose_radius=tool.nose_radius, half_width=tool.half_width,
                                           h_min=resp.h_min, kappa=resp.kappa, side_flow=resp.side_flow), 1)
    grooves = Grooves.of(rms=resp.groove_rms, seed=1)
    small = (0.0, 0.0, 0.01, 0.01)
    cut_turning(cp, grooves, region=small, pixel=pixel)      # compile or load the kernel
    n = 4001 * 4001
    cores = numba.get_num_threads()
    fig = {"samples": n, "followed_path_ticks": int(fp.t.size), "threads": cores,
           "load_average_at_start": os.getloadavg(),
           "follow_turning_s": round(t_follow, 3), "prepare_cut_s": round(t_prep, 3)}
    t, out = best_of(lambda: cut_turning(cp, grooves, region=region, pixel=pixel), repeats)
    fig.update(fast_s=round(t, 3), fast_Msamples_per_s=round(n / t / 1e6, 1))
    del out
    t, _ = best_of(lambda: cut_turning(cp, Grooves.none(), region=region, pixel=pixel), repeats)
    fig.update(fast_no_grooves_s=round(t, 3), fast_no_grooves_Msamples_per_s=round(n / t / 1e6, 1))
    numba.set_num_threads(1)
    try:
        t, _ = best_of(lambda: cut_turning(cp, grooves, region=region, pixel=pixel), max(1, repeats - 1))
    finally:
        numba.set_num_threads(cores)
    fig.update(fast_1thread_s=round(t, 3), fast_1thread_Msamples_per_s=round(n / t / 1e6, 1))
    # the direct model on a quarter of the window's side
    sub = (0.0, 0.0, 0.5, 0.5)
    m = 1001 * 1001
    kw = dict(nose_radius=tool.nose_radius, half_width=tool.half_width, region=sub, pixel=pixel)
    cut_turning_mechanics(cut, **{**kw, "region": small}, h_min=resp.h_min, kappa=resp.kappa)

    def direct():
        c = cut_turning_mechanics(cut, h_min=resp.h_min, kappa=resp.kappa, **kw)
        along = np.interp(np.nan_to_num(c["pass_theta"], nan=cut.theta[0]), cut.theta,
                          cutting_distance(cut.theta, cut.rho))
        return finish_surface(c, resp, along=along, seed=1)[0]

    t, ref = best_of(direct, 1)
    fast = cut_turning(cp, grooves, region=sub, pixel=pixel)["machined"]
    d = float(np.nanmax(np.abs(fast - ref)))
    fig.update(direct_part_samples=m, direct_part_s=round(t, 2),
               direct_Msamples_per_s=round(m / t / 1e6, 3),
               direct_window_s_scaled=round(t * n / m, 1),
               fast_vs_direct_max_abs_diff_mm=d,
               fast_vs_direct_max_rel_diff=d / float(np.nanmax(np.abs(ref))),
               nan_pattern_equal=bool(np.array_equal(np.isnan(fast), np.isnan(ref))),
               load_average_at_end=os.getloadavg())
    print(json.dumps(fig, indent=2))
    return fig


if __name__ == "__main__":
    main()
