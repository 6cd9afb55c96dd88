"""Benchmark: ``render-inspect analyze`` of a height-map store (``heightmap.zarr``, what
``simulate --tiled`` writes), each run a fresh process, its peak resident memory read
from the operating system (``ru_maxrss`` of the child) with its wall and CPU time.

The store is synthetic, written band by band with the package's own store writer
(:func:`render_inspect.io._zarr.create_heightmap_zarr`, the pyramid from
:mod:`render_inspect.io._pyramid`): a gently curved design with the concentric feed
marks of a turned part (cusps of a round-nosed tool, 5 um feed, 0.5 mm nose radius) and
1 nm of seeded noise, at 0.5 um pixels: 64 M samples (4 x 4 mm) by default;
``BENCH_STORE_SIZES=64M,400M`` adds a whole 10 x 10 mm part (about 1.6 GB of disk per
400 M float32 values and channel).  ``analyze`` runs with the default options (plane)
and with ``--form poly2``.
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

import numpy as np

REPO = Path(__file__).resolve().parents[1]
PIXEL_MM = 0.0005
#: samples -> side (pixels) of the square map
SIZES = {"16M": 4096, "64M": 8192, "400M": 20000}
FEED_MM = 0.005
NOSE_MM = 0.5


def make_store(path: Path, side: int, *, chunk: int = 1024, seed: int = 7) -> Path:
    """A ``side`` x ``side`` turned-marks store at :data:`PIXEL_MM`, written band by band
    (memory: a few bands, whatever the size)."""
    sys.path.insert(0, str(REPO))
    from render_inspect.io import grid_attrs
    from render_inspect.io._pyramid import block_sums, coarsen, level_count, means
    from render_inspect.io._zarr import consolidate, create_heightmap_zarr

    shape = (side, side)
    levels = level_count(shape)
    half = side * PIXEL_MM / 2
    origin = (-half + PIXEL_MM / 2, -half + PIXEL_MM / 2)
    g = create_heightmap_zarr(path, shape, chunk=chunk, levels=levels,
                              attrs=grid_attrs(PIXEL_MM, origin, {"name": "turned marks"},
                                               {"seed": seed}))
    rng = np.random.default_rng(seed)
    band = max(chunk, 1 << levels)
    x = origin[0] + np.arange(side) * PIXEL_MM
    for r0 in range(0, side, band):
        r1 = min(r0 + band, side)
        y = (origin[1] + np.arange(r0, r1) * PIXEL_MM)[:, None]
        r = np.hypot(x[None, :], y)
        design = -0.02 * r * r  # a shallow concave sag, mm
        u = (r % FEED_MM) - FEED_MM / 2
        machined = design + u * u / (2 * NOSE_MM) + rng.normal(0.0, 1e-6, r.shape)
        residual = machined - design
        for name, a in (("design", design), ("machined", machined), ("residual", residual)):
            g[name][r0:r1] = a.astype(np.float32)
            s, c = block_sums(a, 2)
            for k in range(1, levels + 1):
                if k > 1:
                    s, c = coarsen(s, c, 2)
                f = 1 << k
                g[f"levels/{k}/{name}"][r0 // f:-(-r1 // f)] = means(s, c)
    consolidate(path)
    return path


def _child() -> tuple[float, int]:
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime, r.ru_maxrss


def run_analyze(store: Path, out: Path, *options: str) -> dict:
    """One ``analyze`` process; its peak RSS (GiB), wall and CPU time.  ``ru_maxrss`` of
    the children is the largest child so far: each run is its own fresh helper process
    (``_measure``), so the figure is this run's."""
    args = [sys.executable, "-m", "render_inspect.cli", "analyze", str(store), "--out", str(out),
            "--overwrite", *options]
    env = {**os.environ, "PYTHONPATH": os.environ.get("PYTHONPATH", str(REPO))}
    load0 = os.getloadavg()[0]
    c0, _ = _child()
    t0 = time.perf_counter()
    p = subprocess.run(args, capture_output=True, text=True, cwd=out.parent, env=env)
    wall = time.perf_counter() - t0
    cpu, maxrss_kib = _child()
    if p.returncode != 0:
        raise RuntimeError(f"analyze failed:\n{p.stderr[-3000:]}")
    m = json.loads((out / "metrics.json").read_text())
    return {"options": " ".join(options) or "(defaults)", "wall_s": round(wall, 2),
            "cpu_s": round(cpu - c0, 2), "peak_rss_gib": round(maxrss_kib / 2 ** 20, 3),
            "windowed": "windowed" in m, "Sq_nm": m["areal"]["Sq_nm"],
            "load_average_1min": round(load0, 2)}


def _measure(store: str, out: str, *options: str) -> dict:
    """Run :func:`run_analyze` in a fresh process of its own (so ``ru_maxrss`` of the
    children is this run's alone)."""
    code = ("import json, sys; sys.path.insert(0, %r); import bench_analyze_store as b; "
            "from pathlib import Path; print(json.dumps(b.run_analyze(Path(%r), Path(%r), *%r)))"
            % (str(Path(__file__).parent), store, out, list(options)))
    p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    if p.returncode != 0:
        raise RuntimeError(p.stderr[-3000:])
    return json.loads(p.stdout.strip().splitlines()[-1])


def main() -> dict:
    sizes = [s.strip() for s in os.environ.get("BENCH_STORE_SIZES", "64M").split(",") if s.strip()]
    out: dict = {}
    with tempfile.TemporaryDirectory(prefix="bench_analyze_store_") as tmp:
        tmp = Path(tmp)
        for name in sizes:
            side = SIZES[name]
            t0 = time.perf_counter()
            store = make_store(tmp / f"{name}.zarr", side)
            made = time.perf_counter() - t0
            runs = []
            for opts in ((), ("--form", "poly2")):
                r = _measure(str(store), str(tmp / "out"), *opts)
                print(f"{name} ({side} x {side}) {r['options']}: peak RSS {r['peak_rss_gib']:.2f} "
                      f"GiB, {r['wall_s']:.1f} s wall, {r['cpu_s']:.1f} s CPU (load "
                      f"{r['load_average_1min']})", flush=True)
                runs.append(r)
            out[name] = {"samples": side * side, "store_written_s": round(made, 1), "runs": runs}
            shutil.rmtree(store)
    return out


if __name__ == "__main__":
    print(json.dumps(main(), indent=2))
