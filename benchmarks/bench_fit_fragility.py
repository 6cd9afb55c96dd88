"""Benchmark: how far ``render-inspect fit``'s answer moves under a last-bit change of its
forward model, and how rugged the misfit is at the finest scales of the parameters.

The case is the quiet nose-radius and feed fit of ``tests/test_fit.py``
(``test_tool_nose_radius_and_feed_come_back_within_1_percent``): the sinusoidal-grid scene
cut with a 0.525 mm nose and 0.51 mm/min, its random parts set to 0, imaged and measured
over the tests' field, fitted over a 0.11 mm window from the shipped values (0.514 mm,
0.5 mm/min).

Figures (printed and returned by :func:`main`):

* ``fits``: the fit as it is (``plain``) and with every predicted map changed by one unit
  in the last place of its float32 heights on a fixed pseudo-random half of its pixels
  (``ulp_seed_0``, ``ulp_seed_1``): each key's value, standard error and its parts, the
  status, the evaluations and the CPU seconds;
* ``moved_in_stderr``: each perturbed fit's change of each value over the plain fit's
  standard error (a robust fit moves by a small fraction of one);
* ``ulp_misfit_change``: the misfit's change when the plain fit's best map alone is
  perturbed so (the features barely see it);
* ``scan``: the misfit and its terms at relative steps of 1e-5 to 1e-2 along each key
  through the plain fit's result, and the rms change of the predicted waviness (nm)
  against the result's.

Run: ``.venv/bin/python benchmarks/bench_fit_fragility.py`` (about 200 CPU-s).
"""

from __future__ import annotations

import atexit
import json
import resource
import shutil
import sys
import tempfile
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
RELATIVE_STEPS = (-1e-2, -3e-3, -1e-3, -3e-4, -1e-4, -3e-5, -1e-5,
                  1e-5, 3e-5, 1e-4, 3e-4, 1e-3, 3e-3, 1e-2)


def _ulp(h: np.ndarray, seed: int) -> np.ndarray:
    """``h`` as float32, one unit in the last place up on a fixed half of its pixels."""
    h = np.asarray(h, dtype=np.float32)
    mask = np.random.default_rng(seed).random(h.shape) < 0.5
    return np.where(mask & np.isfinite(h), np.nextafter(h, np.float32(np.inf)), h)


def _cpu() -> float:
    ru = resource.getrusage(resource.RUSAGE_SELF)
    return ru.ru_utime + ru.ru_stime


def main() -> dict:
    sys.path.insert(0, str(REPO / "tests"))
    import test_fit as T  # the tests' truth and settings

    from render_inspect.cli import main as cli
    from render_inspect.fit import _cache, _solve
    from render_inspect.fit._dispatch import features, residuals
    from render_inspect.fit._features import soft_l1, waviness
    from render_inspect.pipeline import _fit as pipeline_fit

    work = Path(tempfile.mkdtemp(prefix="bench_fit_fragility_"))
    atexit.register(shutil.rmtree, work, ignore_errors=True)  # (its fits: tens of MB)
    truth = T._truth(work / "truth", T.TOOL, quiet=True)
    put = _cache.EvaluationCache.put
    solve = pipeline_fit.solve
    caught: dict = {}

    def keep(params, ev, **kw):
        res = solve(params, ev, **kw)
        caught.update(ev=ev, params=params, res=res)
        return res

    fits: dict = {}
    for name, seed in (("plain", None), ("ulp_seed_0", 0), ("ulp_seed_1", 1)):
        if seed is not None:
            _cache.EvaluationCache.put = (  # type: ignore[method-assign]
                lambda self, key, h, meta, _s=seed: put(self, key, _ulp(h, _s), meta))
        pipeline_fit.solve = keep  # type: ignore[attr-defined]
        c0 = _cpu()
        try:
            out = work / name
            assert cli(["fit", str(truth), "--scene", "sts_sinusoidal_grid", "--free",
                        "tool.nose_radius,process.feed_mm_per_min", "--seed", "1",
                        "--profile-points", "0", "--global", "0", "--window",
                        str(T.TOOL_WINDOW), *[f"--set={s}" for s in T.QUIET],
                        "--out", str(out), "-q"]) == 0
        finally:
            _cache.EvaluationCache.put = put  # type: ignore[method-assign]
            pipeline_fit.solve = solve  # type: ignore[attr-defined]
        rec = json.loads((out / "fit.json").read_text())
        fits[name] = {"parameters": {k: {f: p.get(f) for f in (
            "value", "stderr", "stderr_formal", "stderr_steps", "stderr_solver",
            "stderr_random_parts")} for k, p in rec["parameters"].items()},
            "status": rec["status"], "message": rec["message"],
            "evaluations": rec["evaluations"], "cpu_s": _cpu() - c0}
        if name == "plain":
            plain = dict(caught)
    base = fits["plain"]["parameters"]
    moved = {name: {k: (f["parameters"][k]["value"] - base[k]["value"]) / base[k]["stderr"]
                    for k in base} for name, f in fits.items() if name != "plain"}
    # the plain fit's best map: a last-bit change of it alone, and the misfit around it
    ev, params, best = plain["ev"], plain["params"], plain["res"].best
    tgt = ev.target
    d1, a1, _ = residuals(features(_ulp(best.height, 0).astype(np.float64), tgt,
                                   best.values), tgt)
    ulp_change = float(np.sum(a1 * a1 * soft_l1(d1))) - best.cost

    def wavy(h):
        return waviness(h, pixel=tgt.pixel, cutoff=tgt.cutoff, form=tgt.spec.form,
                        origin=tgt.origin)

    w0 = wavy(best.height)
    scan: dict = {}
    for i, p in enumerate(params):
        rows = []
        for rel in RELATIVE_STEPS:
            v = best.values.copy()
            v[i] *= 1 + rel
            e = ev.evaluate([v], budget=False)[0]
            dw = wavy(e.height) - w0
            rows.append({"relative_step": rel, "misfit": e.cost, "terms": e.terms,
                         "waviness_change_rms_nm": float(np.sqrt(np.nanmean(dw ** 2))) * 1e6})
        scan[p.key] = rows
    figures = {"fits": fits, "moved_in_stderr": moved, "ulp_misfit_change": ulp_change,
               "best_misfit": best.cost, "best_terms": best.terms,
               "sigma_map_nm": tgt.sigma_map * 1e6, "map_points": int(len(tgt.points[0])),
               "scan": scan}
    print(json.dumps(figures, indent=1, default=float))
    return figures


if __name__ == "__main__":
    main()
