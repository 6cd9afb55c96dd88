"""Benchmark: the machine and the material.

- ``follow_turning`` of the whole seed-004 RCSE program (1,368,001 points, 950
  revolutions, 1,357 s of cutting at 42 rpm) on the ``sts_lathe`` preset: 6.8 M servo
  ticks, four axes, error motions and the reaction coupling;
- the envelope with the cutting mechanics of Al 6061 (the direct model,
  ``cut_turning_mechanics``, and the fast kernel, ``cut_turning``, with the grooves)
  against the geometric envelope (``simulate_turning``) on a 1001 x 1001 grid of the
  Li et al. (2018) sinusoidal grid.

``python benchmarks/bench_machine.py`` prints and returns the figures (best of
``repeats``).
"""

from __future__ import annotations

import json
import time
from pathlib import Path

from _timing import best_of

REPO = Path(__file__).resolve().parents[1]


def main(repeats: int = 2) -> dict:
    from render_inspect.design import make_surface
    from render_inspect.machining import (
        Grooves,
        cut_turning,
        cut_turning_mechanics,
        prepare_cut,
        follow_turning,
        machine_preset,
        material_preset,
        material_response,
        simulate_turning,
    )
    from render_inspect.processes import plan_spiral, process_of
    from render_inspect.scene import load_scene

    scene = load_scene(REPO / "scenes" / "rcse_circular_array.toml")
    surface = make_surface(scene.design)
    rcse = process_of(scene)
    path = rcse.plan(rcse.inputs_of(scene), surface).program
    machine = machine_preset("sts_lathe")
    t_follow, fp = best_of(lambda: follow_turning(path.t, path.theta, path.rho, path.z, machine,
                                                seed=0), repeats)
    grid = load_scene(REPO / "scenes" / "sts_sinusoidal_grid.toml",
                      ["simulation.region=[-0.5,-0.5,0.5,0.5]", "simulation.pixel=0.001"])
    gsurf = make_surface(grid.design)
    gpath = plan_spiral(grid, gsurf, region=tuple(grid.simulation.region))
    resp = material_response(material_preset("al6061"), edge_radius=50e-6)
    kw = {"nose_radius": grid.tool.nose_radius, "region": tuple(grid.simulation.region),
          "pixel": grid.simulation.pixel}
    t_geo, _ = best_of(lambda: simulate_turning(gpath, **kw), repeats)
    t_mech, _ = best_of(lambda: cut_turning_mechanics(gpath, h_min=resp.h_min, kappa=resp.kappa,
                                                    **kw), repeats)
    cp = prepare_cut(gpath, nose_radius=grid.tool.nose_radius, h_min=resp.h_min, kappa=resp.kappa)
    gr = Grooves.of(rms=resp.groove_rms, seed=1)
    cut_turning(cp, gr, region=(0.0, 0.0, 0.01, 0.01), pixel=kw["pixel"])
    t_fast, _ = best_of(lambda: cut_turning(cp, gr, region=kw["region"], pixel=kw["pixel"]), repeats)
    out = {"rcse_program_points": int(path.points), "servo_ticks": int(fp.t.size),
           "follow_turning_s": t_follow, "ticks_per_s": fp.t.size / t_follow,
           "following_error": fp.following_error(),
           "grid_pixels": 1001 * 1001, "grid_path_points": int(gpath.points),
           "envelope_geometric_s": t_geo, "envelope_mechanics_s": t_mech,
           "mechanics_fast_kernel_with_grooves_s": t_fast}
    print(json.dumps(out, indent=1))
    return out


if __name__ == "__main__":
    main()
