"""Benchmark: the whole ``simulate`` command against its kernel as maps grow, a whole part
through the tiled path, and Dask workers.

1. ``render-inspect simulate`` of the seed-000 grid (Z compensation) at 1, 16 and 64 M
   samples (1 x 1 mm at 1 um, 2 x 2 mm at 0.5 um, 2 x 2 mm at 0.25 um), in memory, each in
   a fresh process: wall time of the command (imports included), the envelope kernel, the
   other simulation steps, the writing of each output file (and its share of the wall
   time), and the process's peak resident memory against the estimate.
2. A whole 10 mm part at 0.5 um (20001 x 20001 = 400 M samples) through the tiled path
   (threads): wall time, tiles, peak resident memory, the store's size on disk.
   It writes about 3 GB into a temporary folder and takes minutes: ``BENCH_WHOLE_PART=0``
   skips it.
3. The tiled path on a 64 M-sample map on a LocalCluster of 1 and of 2 Dask workers.

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

_CHILD = """
import json, resource, sys, time
t0 = time.perf_counter()
from render_inspect.cli import main
rc = main(sys.argv[1:])
print(json.dumps({"rc": rc, "wall_s": time.perf_counter() - t0,
                  "max_rss_MiB": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024}))
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


def simulate(out: Path, region, pixel, *extra) -> dict:
    args = ["simulate", SCENE, "--out", str(out), "--set", f"simulation.region={list(region)}",
            "--set", f"simulation.pixel={pixel}", "--set", "simulation.max_memory_gb=20", *extra]
    r = run_cli(args)
    m = json.loads((out / "metrics.json").read_text())
    ts = m["timing_s"]
    write = ts.get("write", {})
    wsum = sum(write.values())
    fig = {"samples": m["samples"], "shape": m["grid"]["shape"], "path_points": m["toolpath"]["points"],
           "command_wall_s": round(r["process_wall_s"], 2),
           "kernel_s": round(ts.get("envelope", ts.get("tiles_tiles", 0.0)), 3),
           "toolpath_s": round(ts["toolpath"], 3), "simulate_s": round(ts["simulate"], 3),
           "write_s": {k: round(v, 3) for k, v in write.items()}, "write_total_s": round(wsum, 3),
           "write_share_of_wall": round(wsum / r["process_wall_s"], 3),
           "max_rss_MiB": round(r["max_rss_MiB"], 1), "Sq_nm": round(m["residual"]["Sq_nm"], 4),
           "Msamples_per_s_command": round(m["samples"] / r["process_wall_s"] / 1e6, 2)}
    if "tiles" in m:
        fig["tiles"] = m["tiles"]
        fig["store_MB"] = round(_du(out / "heightmap.zarr") / 1e6, 1)
        fig["timing_s"] = {k: v for k, v in ts.items() if k != "write"}
    else:
        from render_inspect.machining import in_memory_bytes

        fig["estimate_MiB"] = round(in_memory_bytes(m["grid"]["shape"], m["toolpath"]["points"]) / 2**20, 1)
        fig["exr_MB"] = round((out / "heightmap.exr").stat().st_size / 1e6, 1)
    return fig


def main() -> dict:
    res = {"load_average_at_start": os.getloadavg()}
    tmp = Path(tempfile.mkdtemp(prefix="bench_scale_"))
    try:
        sizes = {"1M": ((-0.5, -0.5, 0.5, 0.5), 0.001), "16M": ((-1, -1, 1, 1), 0.0005),
                 "64M": ((-1, -1, 1, 1), 0.00025)}
        res["in_memory"] = {}
        for name, (region, pixel) in sizes.items():
            res["in_memory"][name] = simulate(tmp / f"mem_{name}", region, pixel)
            shutil.rmtree(tmp / f"mem_{name}", ignore_errors=True)
            print(name, json.dumps(res["in_memory"][name]), flush=True)
        res["tiled_64M"] = {}
        for label, extra in (("threads", ["--tiled"]), ("workers_1", ["--workers", "1"]),
                             ("workers_2", ["--workers", "2"])):
            res["tiled_64M"][label] = simulate(tmp / f"t_{label}", (-1, -1, 1, 1), 0.00025, *extra)
            shutil.rmtree(tmp / f"t_{label}", ignore_errors=True)
            print("tiled 64M", label, json.dumps(res["tiled_64M"][label]), flush=True)
        if os.environ.get("BENCH_WHOLE_PART", "1") != "0":
            res["whole_part_10mm_0.5um"] = simulate(tmp / "part", (-5, -5, 5, 5), 0.0005, "--tiled")
            print("whole part", json.dumps(res["whole_part_10mm_0.5um"]), flush=True)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    res["load_average_at_end"] = os.getloadavg()
    print(json.dumps(res, indent=2))
    return res


if __name__ == "__main__":
    main()
