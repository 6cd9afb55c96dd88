"""Image regression benchmark: the suite's running time, and the false-alarm rate of its
Monte-Carlo test measured over new seeds.

* ``suite``: ``render-inspect regress`` over every shipped case (wall-clock seconds of
  the command, start-up included) and the seconds of each case;
* ``false_alarms``: the cases with Monte-Carlo images run again with ``simulation.seed``
  = 1 .. ``seeds`` (new camera noise and new path-tracing samples; the deterministic
  images are unchanged): per Monte-Carlo image, how many of those runs failed (the test
  is built for at most alpha = 1e-3 per image) and the smallest p-value over its
  threshold (above 1 passes).

``--quick`` runs 3 seeds instead of 20.
"""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

EXE = Path(sys.executable).parent / "render-inspect"
#: Cases with Monte-Carlo images whose surface does not depend on the seed (in
#: sculpt_quad_mla the seed also draws the burrs, so another seed is another surface).
MC_CASES = "sts_grid_z,sts_grid_uncompensated,sts_grid_psi_noise,mla_2x2_z"


def _suite(tmp: Path) -> dict:
    t0 = time.perf_counter()
    res = subprocess.run([str(EXE), "regress", "--out", str(tmp / "suite")], capture_output=True,
                         text=True)
    wall = time.perf_counter() - t0
    summary = json.loads((tmp / "suite" / "summary.json").read_text())
    per_case = {}
    for line in res.stderr.splitlines():
        if line.startswith("regress ") and " in " in line and line.endswith(" s"):
            per_case[line.split()[1].rstrip(":")] = float(line.rsplit(" in ", 1)[1][:-2])
    return {"wall_s": round(wall, 1), "images": summary["images"], "failed": summary["failed"],
            "cases": len(summary["cases"]), "per_case_s": per_case,
            "mitsuba_variant": summary["mitsuba_variant"]}


def _false_alarms(tmp: Path, seeds: int) -> dict:
    from render_inspect.batch import RegressionFailed
    from render_inspect.pipeline import run_regress

    stats: dict = {}
    for seed in range(1, seeds + 1):
        out = tmp / f"seed{seed}"
        try:
            run_regress(only=MC_CASES, out=out, overrides=[f"simulation.seed={seed}"])
        except RegressionFailed:
            pass
        summary = json.loads((out / "summary.json").read_text())
        for r in summary["results"]:
            if r["kind"] != "monte_carlo":
                continue
            s = stats.setdefault(f"{r['case']}/{r['image']}", {"runs": 0, "failed": 0,
                                                              "min_p_over_threshold": None})
            s["runs"] += 1
            s["failed"] += not r["passed"]
            ratio = r["min_p"] / r["threshold"]
            m = s["min_p_over_threshold"]
            s["min_p_over_threshold"] = round(ratio if m is None else min(m, ratio), 3)
        shutil.rmtree(out, ignore_errors=True)
    total = sum(s["runs"] for s in stats.values())
    failed = sum(s["failed"] for s in stats.values())
    return {"seeds": seeds, "image_runs": total, "image_failures": failed, "per_image": stats}


def main(quick: bool = False) -> dict:
    tmp = Path(tempfile.mkdtemp(prefix="bench_regress_"))
    try:
        fig = {"suite": _suite(tmp), "false_alarms": _false_alarms(tmp, 3 if quick else 20)}
        print(json.dumps(fig, indent=1))
        return fig
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


if __name__ == "__main__":
    main(quick="--quick" in sys.argv)
