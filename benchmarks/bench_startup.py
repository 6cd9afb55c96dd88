"""Benchmark: how soon a mistake is answered.  ``render-inspect simulate`` in a fresh
process with a misspelt key (``--set tool.nose_radiuz=1``), a value out of range
(``--set tool.nose_radius=-1``) and a scene file that does not exist, and
``render-inspect --help``: the time from the start of the process to its error line
(the process ends right after it), as wall time and as the child's CPU time (user +
system), the best of ``BENCH_REPEATS`` (default 5) runs.  The heavy libraries the process
imported are listed with each case (none is expected).

Also how soon a command starts computing: ``simulate sts_sinusoidal_grid -v`` (the shipped
grid, 1 M samples), the time from the start of the process to the start of its planning
(the planning step's message arrives when it ends and names its duration), and to the
process's end; with whether numba's compiler set-up (its library of numpy functions,
``numba.np.arraymath``) was loaded, which the program leaves to a compilation (the median
of the runs, and each run).

``python benchmarks/bench_startup.py [PACKAGE_ROOT ...]``: each root (a checkout holding
``render_inspect/``; default this repository) is measured in turn, the runs of the roots
interleaved, so that an earlier version can be measured beside this one under the same
load.
"""

from __future__ import annotations

import json
import os
import re
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
HEAVY = ("numba", "scipy", "matplotlib", "mitsuba", "drjit", "dask", "zarr", "OpenEXR", "trimesh")
CASES = {
    "misspelt key": ["simulate", "sts_fig16_overcut", "--set", "tool.nose_radiuz=1"],
    "value out of range": ["simulate", "sts_fig16_overcut", "--set", "tool.nose_radius=-1"],
    "missing scene file": ["simulate", "no_such_scene.toml"],
    "--help": ["--help"],
}
#: runs the command line as ``python -m render_inspect.cli`` does; at exit, the heavy
#: modules imported are written to the file argv[1]
_DRIVER = """
import atexit, json, runpy, sys
where = sys.argv[1]
def _report():
    with open(where, "w") as f:
        json.dump(sorted(m for m in %r if m in sys.modules), f)
atexit.register(_report)
sys.argv = ["render-inspect", *sys.argv[2:]]
runpy.run_module("render_inspect.cli", run_name="__main__", alter_sys=True)
""" % (HEAVY,)


#: the command whose start is timed (the shipped grid as shipped, its steps' messages on)
START_CASE = ["simulate", "sts_sinusoidal_grid", "-v"]
#: a module of numba's compiler set-up (present when numba set itself up for compiling)
NUMBA_SET_UP = "numba.np.arraymath"


def _child_cpu() -> float:
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def run_case(root: Path, argv: list, tmp: Path) -> dict:
    out = tmp / "out"
    report = tmp / "heavy.json"
    args = [sys.executable, "-c", _DRIVER, str(report), *argv]
    if argv[0] != "--help":
        args += ["--out", str(out)]
    env = {**os.environ, "PYTHONPATH": str(root), "MPLBACKEND": "Agg"}
    c0, t0 = _child_cpu(), time.perf_counter()
    p = subprocess.run(args, capture_output=True, text=True, cwd=tmp, env=env)
    wall, cpu = time.perf_counter() - t0, _child_cpu() - c0
    line = (p.stderr.strip().splitlines() or [""])[-1]
    return {"rc": p.returncode, "wall_s": round(wall, 3), "cpu_s": round(cpu, 3),
            "heavy_imported": json.loads(report.read_text()) if report.exists() else None,
            "line": line[:160]}


def run_start(root: Path, tmp: Path) -> dict:
    """:data:`START_CASE` in a fresh process: seconds to the start of planning and to the
    end, and whether numba's compiler set-up was loaded by the end."""
    report = tmp / "heavy.json"
    driver = _DRIVER.replace(repr(HEAVY), repr(HEAVY + (NUMBA_SET_UP,)))
    args = [sys.executable, "-c", driver, str(report), *START_CASE, "--out", str(tmp / "start"),
            "--overwrite"]
    env = {**os.environ, "PYTHONPATH": str(root), "MPLBACKEND": "Agg"}
    t0 = time.perf_counter()
    p = subprocess.Popen(args, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                         cwd=tmp, env=env)
    plan = None
    assert p.stdout is not None
    for line in p.stdout:
        m = re.search(r"plan the tool path: ([0-9.]+) s", line)
        if m and plan is None:
            plan = time.perf_counter() - t0 - float(m.group(1))
    rc = p.wait()
    end = time.perf_counter() - t0
    heavy = json.loads(report.read_text()) if report.exists() else []
    return {"rc": rc, "planning_starts_s": None if plan is None else round(plan, 3),
            "ends_s": round(end, 3), "numba_set_up_loaded": NUMBA_SET_UP in heavy}


def main(roots=None) -> dict:
    roots = [Path(r).resolve() for r in (roots or [REPO])]
    repeats = int(os.environ.get("BENCH_REPEATS", "5"))
    res = {"load_average_at_start": os.getloadavg(), "cpus": os.cpu_count()}
    runs = {(str(r), c): [] for r in roots for c in CASES}
    with tempfile.TemporaryDirectory(prefix="bench_startup_") as tmp:
        for _ in range(repeats):
            for case, argv in CASES.items():
                for root in roots:
                    runs[(str(root), case)].append(run_case(root, argv, Path(tmp)))
        starts = {str(r): [] for r in roots}
        for _ in range(repeats):
            for root in roots:
                starts[str(root)].append(run_start(root, Path(tmp)))
    for root, rs in starts.items():
        ok = [r for r in rs if r["rc"] == 0 and r["planning_starts_s"] is not None]
        if not ok:
            raise RuntimeError(f"{root}: {START_CASE} failed: {rs}")
        summary = {"planning_starts_s": statistics.median(r["planning_starts_s"] for r in ok),
                   "ends_s": statistics.median(r["ends_s"] for r in ok),
                   "numba_set_up_loaded": sorted({r["numba_set_up_loaded"] for r in ok}), "runs": rs}
        res.setdefault(root, {})["simulate starts computing"] = summary
        print(f"{root} | simulate starts computing: planning from {summary['planning_starts_s']:.2f} s, "
              f"ends {summary['ends_s']:.2f} s (medians), numba's set-up loaded "
              f"{summary['numba_set_up_loaded']}", flush=True)
    for (root, case), rs in runs.items():
        best = min(rs, key=lambda r: r["cpu_s"])
        best["runs_wall_s"] = [r["wall_s"] for r in rs]
        best["runs_cpu_s"] = [r["cpu_s"] for r in rs]
        res.setdefault(root, {})[case] = best
        print(f"{root} | {case}: wall {min(best['runs_wall_s']):.2f} s, cpu {best['cpu_s']:.2f} s, "
              f"rc {best['rc']}, heavy {best['heavy_imported']}", flush=True)
    res["load_average_at_end"] = os.getloadavg()
    print(json.dumps(res, indent=2))
    return res


if __name__ == "__main__":
    main(sys.argv[1:])
