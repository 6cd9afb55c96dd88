"""Image regression benchmark: ``render-inspect regress`` over every shipped case
(wall-clock seconds of the command, start-up included) and the seconds of each case."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

EXE = Path(sys.executable).parent / "render-inspect"


def main() -> dict:
    tmp = Path(tempfile.mkdtemp(prefix="bench_regress_"))
    try:
        t0 = time.perf_counter()
        res = subprocess.run([str(EXE), "regress", "--out", str(tmp / "out")], capture_output=True,
                             text=True)
        wall = time.perf_counter() - t0
        summary = json.loads((tmp / "out" / "summary.json").read_text())
        per_case = {}
        for line in res.stderr.splitlines():
            if line.startswith("regress ") and " in " in line and line.endswith(" s"):
                name = line.split()[1].rstrip(":")
                per_case[name] = float(line.rsplit(" in ", 1)[1][:-2])
        fig = {"wall_s": round(wall, 1), "images": summary["images"], "failed": summary["failed"],
               "cases": len(summary["cases"]), "per_case_s": per_case,
               "mitsuba_variant": summary["mitsuba_variant"]}
        print(json.dumps(fig))
        return fig
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


if __name__ == "__main__":
    main()
