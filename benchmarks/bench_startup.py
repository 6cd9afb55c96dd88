"""Benchmark: how soon a mistake is answered.  ``render-inspect simulate`` in a fresh
process with a misspelt key (``--set tool.nose_radiuz=1``), a value out of range
(``--set tool.nose_radius=-1``) and a scene file that does not exist, and
``render-inspect --help``: the time from the start of the process to its error line
(the process ends right after it), as wall time and as the child's CPU time (user +
system), the best of ``BENCH_REPEATS`` (default 5) runs.  The heavy libraries the process
imported are listed with each case (none is expected).

``python benchmarks/bench_startup.py [PACKAGE_ROOT ...]``: each root (a checkout holding
``render_inspect/``; default this repository) is measured in turn, the runs of the roots
interleaved, so that an earlier version can be measured beside this one under the same
load.
"""

from __future__ import annotations

import json
import os
import resource
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
