"""Run every benchmarks/bench_*.py (their ``main()``), print the figures and write them to
docs/benchmarks.json.  ``make bench`` runs this; ``make bench ONLY=sts`` runs one.

``bench_peer.py`` compares against the open simulator PySurfSim, which is not part of this
repository: it runs only when ``RENDER_INSPECT_PEER`` names a folder holding a copy
(``make bench ONLY=peer RENDER_INSPECT_PEER=/path/to/copy``); otherwise it says in one
line where to get one, measures this project's side only and records ``skipped_peer``."""

from __future__ import annotations

import importlib.util
import json
import os
import platform
import sys
import time
import traceback
from pathlib import Path

HERE = Path(__file__).resolve().parent
DOCS = HERE.parent / "docs"


def main(only: str | None = None) -> int:
    results, failed = {}, []
    for path in sorted(HERE.glob("bench_*.py")):
        name = path.stem[len("bench_"):]
        if only and name not in only.split(","):
            continue
        print(f"== {name}", flush=True)
        spec = importlib.util.spec_from_file_location(path.stem, path)
        mod = importlib.util.module_from_spec(spec)
        t0 = time.perf_counter()
        try:
            spec.loader.exec_module(mod)
            results[name] = mod.main()
        except Exception:  # report every benchmark, then fail at the end
            traceback.print_exc()
            failed.append(name)
        print(f"== {name}: {time.perf_counter() - t0:.1f} s", flush=True)
    record = {"machine": {"cpus": os.cpu_count(), "python": platform.python_version(),
                          "platform": platform.platform()},
              "date": time.strftime("%Y-%m-%d"), "results": results, "failed": failed}
    DOCS.mkdir(exist_ok=True)
    out = DOCS / "benchmarks.json"
    old = json.loads(out.read_text()) if out.exists() else {}
    if only and old.get("results"):
        old["results"].update(results)
        record["results"] = old["results"]
    out.write_text(json.dumps(record, indent=2, sort_keys=True, default=str) + "\n")
    print(f"wrote {out}")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main(os.environ.get("ONLY") or (sys.argv[1] if len(sys.argv) > 1 else None)))
