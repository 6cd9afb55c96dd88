"""Benchmark: ``render-inspect simulate`` of the shipped grid scene on its defaults (the
``sts_lathe`` machine, Al6082 with its burrs and texture), each run a fresh process:

* 1 M samples (the scene as shipped: 1 x 1 mm at 1 um): the whole command;
* 16 M samples (2 x 2 mm at 0.5 um): toolpath + simulate (``timing_s.toolpath`` +
  ``timing_s.simulate`` of metrics.json) and the whole command (start-up and writing
  included).

Each figure is given as wall time and as the CPU time of the child process (user +
system, all its threads): on a machine shared with other jobs the wall time measures the
load as much as the code, the CPU time much less so.  The load average is recorded with
each run.  ``BENCH_REPEATS`` (default 2) runs are made of each size; the best is kept.
Also the burr model alone on a 16 M-sample map (:func:`material_burr_block`, in process).
"""

from __future__ import annotations

import json
import os
import resource
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
SCENE = "sts_sinusoidal_grid"
SIZES = {"1M": None, "16M": ("[-1, -1, 1, 1]", 0.0005)}


def _child_cpu() -> float:
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def run_simulate(out: Path, size) -> dict:
    args = [sys.executable, "-m", "render_inspect.cli", "simulate", SCENE, "--out", str(out),
            "--overwrite"]
    if size is not None:
        args += ["--set", f"simulation.region={size[0]}", "--set", f"simulation.pixel={size[1]}"]
    load0 = os.getloadavg()[0]
    c0, t0 = _child_cpu(), time.perf_counter()
    # run outside the repository: the package comes from PYTHONPATH or the environment
    p = subprocess.run(args, capture_output=True, text=True, cwd=out.parent,
                       env={**os.environ, "PYTHONPATH": os.environ.get("PYTHONPATH", str(REPO))})
    wall, cpu = time.perf_counter() - t0, _child_cpu() - c0
    if p.returncode != 0:
        raise RuntimeError(f"simulate failed:\n{p.stderr[-3000:]}")
    m = json.loads((out / "metrics.json").read_text())
    ts = m["timing_s"]
    n = m["samples"]
    ts_sim = ts["toolpath"] + ts["simulate"]
    return {"samples": n, "command_wall_s": round(wall, 3), "command_cpu_s": round(cpu, 3),
            "command_Msamples_per_s": round(n / wall / 1e6, 3),
            "command_Msamples_per_cpu_s": round(n / cpu / 1e6, 3),
            "toolpath_simulate_s": round(ts_sim, 3),
            "toolpath_simulate_Msamples_per_s": round(n / ts_sim / 1e6, 3),
            "steps_s": {k: round(v, 3) for k, v in ts.items() if k != "write"},
            "write_s": {k: round(v, 3) for k, v in ts.get("write", {}).items()},
            "load_average": [round(load0, 2), round(os.getloadavg()[0], 2)],
            "Sq_nm": m["residual"]["Sq_nm"]}


def burr_model(n: int = 4001) -> dict:
    import numpy as np

    from render_inspect.machining import material_burr_block

    y, x = np.mgrid[0:n, 0:n] * 0.0005
    z = (0.002 * np.sin(2 * np.pi * x / 2.5) * np.cos(2 * np.pi * y / 2.5)
         + np.minimum(0.0, 0.05 * (np.abs(x - x.mean()) - x.mean() / 3)))  # a groove
    kw = dict(pixel=0.0005, chip_thickness=1e-3, coefficient=1.0, smoothing=0.01,
              width=3e-3, edge_angle_deg=1.0)
    material_burr_block(z[:64, :64], **kw)                     # compile / load the kernels
    c0, t0 = time.process_time(), time.perf_counter()
    r = material_burr_block(z, **kw)
    return {"samples": z.size, "wall_s": round(time.perf_counter() - t0, 3),
            "cpu_s": round(time.process_time() - c0, 3),
            "edge_pixels": int(r[1].sum()) if r is not None else 0,
            "load_average": round(os.getloadavg()[0], 2)}


def main() -> dict:
    repeats = int(os.environ.get("BENCH_REPEATS", "2"))
    res = {"load_average_at_start": os.getloadavg(), "cpus": os.cpu_count()}
    tmp = Path(tempfile.mkdtemp(prefix="bench_command_"))
    try:
        for name, size in SIZES.items():
            runs = []
            for _ in range(repeats):
                runs.append(run_simulate(tmp / name, size))
                shutil.rmtree(tmp / name, ignore_errors=True)
                print(name, json.dumps(runs[-1]), flush=True)
            best = min(runs, key=lambda r: r["command_cpu_s"])
            best["runs_wall_s"] = [r["command_wall_s"] for r in runs]
            res[name] = best
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    res["burr_model_16M"] = burr_model()
    res["load_average_at_end"] = os.getloadavg()
    print(json.dumps(res, indent=2))
    return res


if __name__ == "__main__":
    main()
