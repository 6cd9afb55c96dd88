"""Benchmark: does ``fit`` capture the truth from anywhere in its bounds, and do its standard
errors cover the truth?

Truths drawn across the bounds (seeded), each measured with its random parts (a new
realisation per truth), each fitted from a start drawn across the bounds:

* ``capture_rate``: the share of fits that end at the truth (feed within 0.5 %, nose radius
  within 5 %) -- the issue's bar: starts anywhere inside the bounds end at the truth;
* ``coverage_2se``: the share of (truth, key) pairs whose error is within 2 reported
  standard errors (a calibrated 2-sigma interval covers about 95 %; the bar is 90 %);
* ``converged_rate``, ``converged_wrong``: how often the status is ``converged``, and how
  often a ``converged`` fit is not at the truth (must be 0);
* ``fit_s_median``: the median wall time per fit.

Two forward models:

* ``analytic`` (default): exact turning cusps of feed f and nose radius R (the parabola's
  Fourier series is what the harmonics read) plus a waviness, measured with white height
  noise and a random low-frequency texture (the random parts), six realisations of which
  give the noise floor as in ``fit``; 0.192 mm field at 1 um.  Cheap: 50 truths in minutes.
* ``simulate``: the real chain (each truth cut by ``simulate`` on the shipped sinusoidal-grid
  scene with the lathe's and material's random parts on, imaged by the 20x virtual
  interferometer with its camera noise, turned into heights by ``measure``, then fitted by
  ``run_fit``, what ``render-inspect fit`` runs); a square field of ``--field-mm`` (default
  0.2 mm) centred 0.35 mm from the spindle axis, ``--pixel-mm`` the fitted scene's
  ``simulation.pixel`` (the evaluations halve it until a feed period holds 18 samples).
  Minutes per fit: ``--stop-after-s`` starts no new truth after that many seconds, and the
  figures then say how many truths they hold.

``--only 12,36`` reruns those truths alone (with the draws of a whole run).
``--rows FILE`` appends each truth's full result (with the standard errors' parts,
``stderr_parts``, and the Birge ratio) as a JSON line as soon as it is done (a
run stopped half-way keeps what it did); ``--summarise FILE`` prints the figures of such a
file again; ``--figure PNG`` draws each (truth, key) pair's error in standard errors and
its relative error (a generated figure: not kept in the repository).

Run: ``nice .venv/bin/python benchmarks/bench_fit_coverage.py [--model simulate] [--truths N]
[--field-mm MM] [--rows FILE] [--figure PNG]``.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from render_inspect.core.errors import InputError

F_BOUNDS = (0.008, 0.013)        # mm per revolution (analytic)
R_BOUNDS = (0.3, 1.0)            # mm
NOISE_MM = 2e-6                  # white height noise of a measurement, rms
TEXTURE_MM = 3e-6                # random low-frequency texture, rms


def _cusps(period, radius, *, n=192, pixel=0.001, centre=(-0.6, 0.05), amp_wave=4e-6):
    x = (np.arange(n) - n / 2) * pixel
    xx, yy = np.meshgrid(x, x)
    r = np.hypot(xx - centre[0], yy - centre[1])
    u = (r / period - np.round(r / period)) * period
    z = radius - np.sqrt(radius ** 2 - u ** 2)
    return z + amp_wave * np.sin(2 * math.pi * xx / 0.1), pixel


def analytic(task):
    v = task["values"]
    return _cusps(v["f"], v["R"])[0], {}


def _random_parts(shape, rng):
    """A realisation of the random parts: white noise plus a smooth texture."""
    from scipy.ndimage import gaussian_filter

    tex = gaussian_filter(rng.normal(size=shape), 6.0)
    tex *= TEXTURE_MM / max(float(np.std(tex)), 1e-30)
    return rng.normal(0.0, NOISE_MM, shape) + tex


def _measured_starts(target):
    """The starts ``fit`` takes from the measurement: the feed from the marks' period, the
    nose radius from the fundamental's amplitude."""
    if target.centroid is None:
        return []
    f = 1.0 / target.centroid
    a1 = float(target.amplitudes[0])
    out = {"f": f}
    if a1 > 0:
        out["R"] = f * f / (2 * math.pi ** 2 * a1)
    return [out, {"f": f}]


def fit_analytic(truth, start, seed):
    from render_inspect.fit import (EvaluationCache, Evaluator, FreeParameter, MisfitSpec,
                                    make_target, set_noise_floor, solve)

    rng = np.random.default_rng([seed, 1])
    clean, px = _cusps(truth["f"], truth["R"])
    measured = clean + _random_parts(clean.shape, rng)
    target = make_target(measured, pixel=(px, px), origin=(0.0, 0.0), spec=MisfitSpec())
    params = [FreeParameter("f", start["f"], 0.006, 0.016, 0.1 * start["f"]),
              FreeParameter("R", start["R"], 0.2, 1.5, 0.1 * start["R"])]
    clean0 = analytic({"values": start})[0]
    draws = [clean0 + _random_parts(clean0.shape, rng) for _ in range(6)]
    set_noise_floor(target, draws, clean0)
    ev = Evaluator(params, target, lambda vals: {"values": vals}, analytic,
                   EvaluationCache(None), max_evaluations=400)
    t0 = time.perf_counter()
    res = solve(params, ev, global_points=8, seed=seed, profile_points=0,
                starts=_measured_starts(target))
    return {"values": dict(zip(("f", "R"), map(float, res.values))),
            "stderr": dict(zip(("f", "R"), map(float, res.stderr))),
            "status": res.status, "evaluations": res.evaluations,
            "seconds": time.perf_counter() - t0}


SIM_KEYS = ("tool.nose_radius", "process.feed_mm_per_min")
SIM_BOUNDS = {"tool.nose_radius": (0.35, 0.75), "process.feed_mm_per_min": (0.4, 0.6)}
#: the field's centre (mm): 0.35 mm from the spindle axis, as in tests/test_fit.py
CENTRE = (0.35, 0.0)


def field(side_mm: float = 0.2) -> tuple:
    """The measured field: a square of ``side_mm`` centred at :data:`CENTRE`."""
    h = side_mm / 2
    return (CENTRE[0] - h, CENTRE[1] - h, CENTRE[0] + h, CENTRE[1] + h)


def fit_simulate(truth, start, seed, folder: Path, *, field_mm: float = 0.2,
                 pixel_mm: float | None = None):
    from render_inspect.pipeline import run_fit, run_measure, run_render
    from render_inspect.scene import load_scene

    x0, y0, x1, y1 = field(field_mm)
    m = 0.03
    t_all = time.perf_counter()
    scene = load_scene("sts_sinusoidal_grid", [
        *[f"{k}={v!r}" for k, v in truth.items()], "simulation.pixel=0.0005",
        f"simulation.seed={seed}",  # also the seed of the camera's noise in render
        f"simulation.region=[{x0 - m}, {y0 - m}, {x1 + m}, {y1 + m}]",
        f"render.interferometer.field_of_view=[{x0}, {y0}, {x1}, {y1}]"])
    run_render(scene, folder / "render", kind="interferometer")
    run_measure(folder / "render" / "interferogram.exr", folder / "measure")
    t0 = time.perf_counter()
    fitted = [f"{k}={v!r}" for k, v in start.items()]
    if pixel_mm is not None:
        fitted.append(f"simulation.pixel={pixel_mm!r}")
    rec = run_fit(folder / "measure" / "height.exr",
                  load_scene("sts_sinusoidal_grid", fitted),
                  [",".join(SIM_KEYS)], folder / "fit", seed=seed, profile_points=0,
                  window_mm=field_mm,
                  bounds=[f"{k}={a},{b}" for k, (a, b) in SIM_BOUNDS.items()],
                  max_evaluations=200)
    p = rec["parameters"]
    parts = ("stderr_formal", "stderr_random_parts", "stderr_steps", "stderr_solver")
    return {"values": {k: p[k]["value"] for k in SIM_KEYS},
            "stderr": {k: p[k]["stderr"] for k in SIM_KEYS}, "status": rec["status"],
            "stderr_parts": {k: {part: p[k].get(part) for part in parts} for k in SIM_KEYS},
            "birge_ratio": rec["goodness"].get("birge_ratio"),
            "evaluations": rec["evaluations"], "seconds": time.perf_counter() - t0,
            "seconds_with_measurement": time.perf_counter() - t_all,
            "verdict": rec["model_check"]["after"]["verdict"],
            "misfit_over_noise": rec["model_check"]["after"].get("misfit_over_noise"),
            "evaluation_pixel_mm": rec["simulation"]["pixel_mm"],
            "window_px": rec["placement"]["window_px"][2]}


def summarise(rows: list, settings: dict) -> dict:
    """The figures of a list of truths' results (what :func:`main` prints)."""
    keys = list(rows[0]["truth"]) if rows else []
    pairs = [v for r in rows for v in r["z"].values()]
    conv = [r for r in rows if r["status"] == "converged"]
    statuses: dict = {}
    for r in rows:
        statuses[r["status"]] = statuses.get(r["status"], 0) + 1
    out = {**settings, "truths_done": len(rows),
           "capture_rate": sum(r["captured"] for r in rows) / len(rows),
           "coverage_2se": sum(z <= 2.0 for z in pairs) / len(pairs),
           "coverage_1se": sum(z <= 1.0 for z in pairs) / len(pairs),
           "coverage_2se_by_key": {k: sum(r["z"][k] <= 2.0 for r in rows) / len(rows)
                                   for k in keys},
           "coverage_1se_by_key": {k: sum(r["z"][k] <= 1.0 for r in rows) / len(rows)
                                   for k in keys},
           # the rms of error / standard error: 1 for calibrated errors, above 1 where
           # they are too small
           "z_rms_by_key": {k: math.sqrt(statistics.fmean(
               [r["z"][k] ** 2 for r in rows if math.isfinite(r["z"][k])] or [math.nan]))
               for k in keys},
           "relative_error_mean_by_key": {k: statistics.fmean(r["relative_error"][k]
                                                              for r in rows) for k in keys},
           "no_stderr": sum(r["stderr"][k] is None for r in rows for k in keys),
           "statuses": statuses,
           "converged_rate": len(conv) / len(rows),
           "converged_wrong": sum(not r["captured"] for r in conv),
           "fit_s_median": statistics.median(r["seconds"] for r in rows),
           "evaluations_median": statistics.median(r["evaluations"] for r in rows)}
    if any("verdict" in r for r in rows):
        out["verdicts"] = {}
        for r in rows:
            v = str(r.get("verdict"))
            out["verdicts"][v] = out["verdicts"].get(v, 0) + 1
    return out


def figure(rows: list, path: Path) -> None:
    """Each (truth, key) pair's |error| in standard errors against the truth, and its
    relative error (a generated figure)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    keys = list(rows[0]["truth"])
    fig, axes = plt.subplots(2, len(keys), figsize=(4.5 * len(keys), 6.5), squeeze=False)
    for j, k in enumerate(keys):
        t = np.array([r["truth"][k] for r in rows])
        z = np.array([min(r["z"][k], 10.0) for r in rows])
        e = np.array([100 * r["relative_error"][k] for r in rows])
        ok = np.array([r["status"] == "converged" for r in rows])
        ax = axes[0, j]
        ax.scatter(t[ok], z[ok], s=14, label="converged")
        ax.scatter(t[~ok], z[~ok], s=14, marker="x", label="other status")
        for level in (1, 2):
            ax.axhline(level, color="0.5", lw=0.8, ls="--")
        ax.set(xlabel=f"truth {k}", ylabel="|error| / standard error (10 = none)",
               title=f"{k}: {np.mean(z <= 2):.0%} within 2 s.e.")
        ax.legend(fontsize=7)
        ax = axes[1, j]
        ax.scatter(t, e, s=14)
        ax.axhline(0, color="0.5", lw=0.8)
        ax.set(xlabel=f"truth {k}", ylabel="relative error (%)")
    fig.suptitle(f"fit coverage: {len(rows)} truths")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main(truths: int = 50, model: str = "analytic", seed: int = 2026, *,
         field_mm: float = 0.2, pixel_mm: float | None = None, rows_path=None,
         stop_after_s: float | None = None, figure_path=None, first: int = 0,
         only=None) -> dict:
    rng = np.random.default_rng(seed)
    rows = []
    settings = {"model": model, "truths": truths, "seed": seed, "cpus": os.cpu_count(),
                "affinity": len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity")
                else None}
    if model == "simulate":
        settings.update(field_mm=field_mm, field=list(field(field_mm)),
                        scene_pixel_mm=pixel_mm, bounds=SIM_BOUNDS, max_evaluations=200,
                        global_points=8)
    t_start = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        for i in range(truths):
            if i < first or (only is not None and i not in only):
                # a run continued, or a few truths rerun: the draws of the truths before
                rng.uniform(size=4)
                continue
            if stop_after_s is not None and time.perf_counter() - t_start > stop_after_s:
                print(json.dumps({"stopped": f"after {i} truths: --stop-after-s "
                                             f"{stop_after_s:g} reached"}), flush=True)
                break
            if model == "analytic":
                truth = {"f": float(rng.uniform(*F_BOUNDS)), "R": float(rng.uniform(*R_BOUNDS))}
                start = {"f": float(rng.uniform(*F_BOUNDS)), "R": float(rng.uniform(*R_BOUNDS))}
                got = fit_analytic(truth, start, seed + i)
                tol = {"f": 0.005, "R": 0.05}
            else:
                truth = {k: float(rng.uniform(*SIM_BOUNDS[k])) for k in SIM_KEYS}
                start = {k: float(rng.uniform(*SIM_BOUNDS[k])) for k in SIM_KEYS}
                t0 = time.perf_counter()
                try:
                    got = fit_simulate(truth, start, seed + i, Path(tmp) / f"t{i}",
                                       field_mm=field_mm, pixel_mm=pixel_mm)
                except InputError as e:  # refused: counted, with no value
                    got = {"values": {k: math.nan for k in SIM_KEYS},
                           "stderr": {k: None for k in SIM_KEYS}, "status": "refused",
                           "reason": str(e), "evaluations": 0,
                           "seconds": time.perf_counter() - t0}
                tol = {"tool.nose_radius": 0.05, "process.feed_mm_per_min": 0.005}
            err = {k: got["values"][k] / truth[k] - 1.0 for k in truth}
            z = {k: (abs(got["values"][k] - truth[k]) / got["stderr"][k]
                     if got["stderr"][k] else math.inf) for k in truth}
            rows.append({"i": i, "truth": truth, "start": start, **got,
                         "relative_error": err, "z": z,
                         "captured": all(abs(err[k]) <= tol[k] for k in truth)})
            print(json.dumps({"i": i, "captured": rows[-1]["captured"], "status": got["status"],
                              "error": {k: round(v, 5) for k, v in err.items()},
                              "z": {k: round(v, 2) for k, v in z.items()},
                              "s": round(got["seconds"], 1)}), flush=True)
            if rows_path is not None:
                with open(rows_path, "a") as fh:
                    fh.write(json.dumps({**rows[-1], "settings": settings}) + "\n")
    out = summarise(rows, settings)
    print(json.dumps(out, indent=2))
    if figure_path is not None and rows:
        figure(rows, Path(figure_path))
    return out


def _read_rows(path) -> list:
    rows = [json.loads(line) for line in Path(path).read_text().splitlines() if line.strip()]
    for r in rows:
        r["z"] = {k: float(v) for k, v in r["z"].items()}  # Infinity: no standard error
    return rows


if __name__ == "__main__":
    ap = argparse.ArgumentParser()
    ap.add_argument("--model", choices=("analytic", "simulate"), default="analytic")
    ap.add_argument("--truths", type=int, default=50)
    ap.add_argument("--seed", type=int, default=2026)
    ap.add_argument("--field-mm", type=float, default=0.2,
                    help="side of the measured field (simulate), mm")
    ap.add_argument("--pixel-mm", type=float, default=None,
                    help="simulation.pixel of the fitted scene (simulate; default the scene's)")
    ap.add_argument("--rows", default=None, help="append each truth's result to this JSON-lines file")
    ap.add_argument("--stop-after-s", type=float, default=None,
                    help="start no new truth after this many seconds")
    ap.add_argument("--figure", default=None, help="write the coverage figure (PNG)")
    ap.add_argument("--first", type=int, default=0,
                    help="continue a run: start at this truth (the same draws as a whole run)")
    ap.add_argument("--only", default=None,
                    help="rerun only these truths (comma-separated indices; the same draws "
                         "as a whole run)")
    ap.add_argument("--summarise", default=None,
                    help="print the figures of a --rows file (and draw --figure) and stop")
    a = ap.parse_args()
    if a.summarise:
        rows = _read_rows(a.summarise)
        res = summarise(rows, rows[0].get("settings", {}) if rows else {})
        print(json.dumps(res, indent=2))
        if a.figure and rows:
            figure(rows, Path(a.figure))
        sys.exit(0 if rows else 1)
    sys.exit(0 if main(a.truths, a.model, a.seed, field_mm=a.field_mm, pixel_mm=a.pixel_mm,
                       rows_path=a.rows, stop_after_s=a.stop_after_s,
                       figure_path=a.figure, first=a.first,
                       only=None if a.only is None else
                       {int(v) for v in a.only.split(",") if v.strip()}) else 1)
