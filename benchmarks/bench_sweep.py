"""Sweep benchmark: the shipped fig15_small sweep (9 points) and the full Fig. 15 sweep (106
points), each on a LocalCluster of 1 and of 2 process workers.

Each run is the ``render-inspect sweep`` command in a fresh folder, wall-clock seconds
from the start of the command to its end (cluster start-up, worker imports and the plots
included), plus the sum of the points' own seconds (``seconds`` in results.jsonl) and the
Sq range found.  ``--quick`` skips the full sweep.
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


def _run(sweep: str, workers: int) -> dict:
    tmp = Path(tempfile.mkdtemp(prefix="bench_sweep_"))
    try:
        t0 = time.perf_counter()
        res = subprocess.run([str(EXE), "sweep", sweep, "--out", str(tmp / "out"), "--workers",
                              str(workers)], capture_output=True, text=True)
        wall = time.perf_counter() - t0
        if res.returncode != 0:
            raise RuntimeError(res.stderr[-2000:])
        recs = [json.loads(x) for x in (tmp / "out" / "results.jsonl").read_text().splitlines()]
        sq = [r["metrics"]["residual"]["Sq_nm"] for r in recs if r["status"] == "done"]
        return {"sweep": sweep, "workers": workers, "points": len(recs), "wall_s": round(wall, 1),
                "points_sum_s": round(sum(r["seconds"] for r in recs), 1),
                "Sq_nm_range": [round(min(sq), 4), round(max(sq), 2)]}
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


def main(quick: bool = False) -> dict:
    out = {"fig15_small_1_worker": _run("fig15_small", 1),
           "fig15_small_2_workers": _run("fig15_small", 2)}
    if not quick:
        out["fig15_1_worker"] = _run("fig15", 1)
        out["fig15_2_workers"] = _run("fig15", 2)
    for k, v in out.items():
        print(k, json.dumps(v))
    return out


if __name__ == "__main__":
    main(quick="--quick" in sys.argv)
