"""Benchmark: the whole ``simulate`` command against its kernel as maps grow, whole parts
through the tiled path, and Dask workers; the shipped scenes as they are (the lathe's
servo model and the material's cutting mechanics) and the ideal ones.

1. ``render-inspect simulate`` of the Li et al. (2018) grid (Z compensation) at 1 and
   16 M samples (1 x 1 mm at 1 um, 2 x 2 mm at 0.5 um), in memory, each in a fresh
   process, as shipped and on the ideal machine and material: wall time of the command
   (imports included), the cut, the other simulation steps, the writing of each output
   file (and its share of the wall time), and the process's peak resident memory against
   the estimate.
2. The tiled path on a 64 M-sample map (2 x 2 mm at 0.25 um) as shipped: on the threads of
   the process, and on a LocalCluster of 1 and of 2 Dask workers.
3. Whole parts, as ``simulate`` runs them on the defaults (the tiled path, chosen by the
   map's size): the grid's 10 mm part at 0.5 um (20001 x 20001 = 400 M samples) as shipped
   and ideal, and every other shipped turning scene over its whole part at its own pixel.
   They write several GB into a temporary folder and take minutes: ``BENCH_WHOLE_PART=0``
   skips them.

Every command runs in a child process whose peak resident set (``ru_maxrss``) is
reported.  Outputs go to a temporary folder that is removed afterwards.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
SCENE = "sts_sinusoidal_grid"
#: the ideal machine and material (the geometric envelope)
IDEAL = ("--set", "machine.preset='ideal'", "--set", "material.preset='ideal'")
#: the other shipped turning scenes, simulated over their whole part at their own pixel
WHOLE_PART_SCENES = ("sts_fig16_overcut", "sts_mla_2x2", "compound_sinusoid", "hts_toric_msa",
                     "rcse_circular_array")

# the peak resident set of the child's own memory (VmHWM): ru_maxrss would also count the
# parent's pages at the fork when the parent is large (run_all.py after other benchmarks)
_CHILD = """
import json, sys, time
t0 = time.perf_counter()
from render_inspect.cli import main
rc = main(sys.argv[1:])
hwm = [int(x.split()[1]) for x in open("/proc/self/status") if x.startswith("VmHWM")][0]
print(json.dumps({"rc": rc, "wall_s": time.perf_counter() - t0, "max_rss_MiB": hwm / 1024}))
"""


def _du(path: Path) -> int:
    return sum(f.stat().st_size for f in path.rglob("*") if f.is_file())


def run_cli(args: list[str]) -> dict:
    """Run ``render-inspect ARGS`` in a fresh process; its wall time and peak RSS."""
    t0 = time.perf_counter()
    p = subprocess.run([sys.executable, "-c", _CHILD, *args], capture_output=True, text=True)
    if p.returncode != 0:
        raise RuntimeError(f"render-inspect {' '.join(args)} failed:\n{p.stderr[-3000:]}")
    r = json.loads(p.stdout.strip().splitlines()[-1])
    r["process_wall_s"] = time.perf_counter() - t0
    r["log_tail"] = p.stderr.strip().splitlines()[-4:]
    return r


def simulate(out: Path, region, pixel, *extra, scene: str = SCENE, budget: bool = True) -> dict:
    args = ["simulate", scene, "--out", str(out), "--set", f"simulation.region={list(region)}",
            *(("--set", f"simulation.pixel={pixel}") if pixel else ()),
            *(("--set", "simulation.max_memory_gb=20") if budget else ()), *extra]
    r = run_cli(args)
    m = json.loads((out / "metrics.json").read_text())
    ts = m["timing_s"]
    write = ts.get("write", {})
    wsum = sum(write.values())
    fig = {"samples": m["samples"], "shape": m["grid"]["shape"], "path_points": m["toolpath"]["points"],
           "command_wall_s": round(r["process_wall_s"], 2),
           "kernel_s": round(ts.get("envelope", ts.get("tiles_tiles", 0.0)), 3),
           "machine_s": round(ts.get("machine", 0.0), 3),
           "toolpath_s": round(ts["toolpath"], 3), "simulate_s": round(ts["simulate"], 3),
           "write_s": {k: round(v, 3) for k, v in write.items()}, "write_total_s": round(wsum, 3),
           "write_share_of_wall": round(wsum / r["process_wall_s"], 3),
           "max_rss_MiB": round(r["max_rss_MiB"], 1), "Sq_nm": round(m["residual"]["Sq_nm"], 4),
           "Msamples_per_s_command": round(m["samples"] / r["process_wall_s"] / 1e6, 2),
           "load_average": os.getloadavg()}
    if "tiles" in m:
        fig["tiles"] = m["tiles"]
        fig["store_MB"] = round(_du(out / "heightmap.zarr") / 1e6, 1)
        fig["timing_s"] = {k: v for k, v in ts.items() if k != "write"}
    else:
        from render_inspect.processes import process_of
        from render_inspect.scene import load_scene

        sc = load_scene(scene, [args[i + 1] for i, a in enumerate(args[:-1]) if a == "--set"])
        process = process_of(sc)
        fig["estimate_MiB"] = round(process.estimate_memory(process.inputs_of(sc)) / 2**20, 1)
        fig["exr_MB"] = round((out / "heightmap.exr").stat().st_size / 1e6, 1)
    return fig


def main() -> dict:
    res = {"load_average_at_start": os.getloadavg()}
    tmp = Path(tempfile.mkdtemp(prefix="bench_scale_"))

    def run(key, name, *a, **kw):
        res.setdefault(key, {})[name] = simulate(tmp / "o", *a, **kw)
        shutil.rmtree(tmp / "o", ignore_errors=True)
        print(key, name, json.dumps(res[key][name]), flush=True)

    try:
        sizes = {"1M": ((-0.5, -0.5, 0.5, 0.5), 0.001), "16M": ((-1, -1, 1, 1), 0.0005)}
        for name, (region, pixel) in sizes.items():
            run("in_memory", name, region, pixel)
            run("in_memory_ideal", name, region, pixel, *IDEAL)
        for label, extra in (("threads", ["--tiled"]), ("workers_1", ["--workers", "1"]),
                             ("workers_2", ["--workers", "2"])):
            run("tiled_64M", label, (-1, -1, 1, 1), 0.00025, *extra)
        if os.environ.get("BENCH_WHOLE_PART", "1") != "0":
            # as simulate runs them on the defaults: the automatic memory budget
            run("whole_part", "grid_10mm_0.5um", (-5, -5, 5, 5), 0.0005, budget=False)
            run("whole_part", "grid_10mm_0.5um_ideal", (-5, -5, 5, 5), 0.0005, *IDEAL, budget=False)
            from render_inspect.scene import load_scene

            for name in WHOLE_PART_SCENES:
                r = load_scene(REPO / "scenes" / f"{name}.toml").process.workpiece_radius
                run("whole_part", name, (-r, -r, r, r), None, scene=name, budget=False)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    res["load_average_at_end"] = os.getloadavg()
    print(json.dumps(res, indent=2))
    return res


if __name__ == "__main__":
    main()
