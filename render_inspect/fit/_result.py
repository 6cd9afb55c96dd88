"""``fit.json``: the fitted values, their standard errors and correlations, the misfit, and
where everything came from."""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import SupportsFloat

import numpy as np

from .. import __version__
from ..core.units import MM_TO_NM
from ._features import MisfitSpec, Target
from ._profile import ProfileSpec, ProfileTarget
from ._propagate import prediction_lines
from ._solve import FitResult

__all__ = ["fit_record", "misfit_maps", "summary_lines"]


def _num(v: SupportsFloat | None) -> float | None:
    if v is None:
        return None
    v = float(v)
    return v if math.isfinite(v) else None


def misfit_maps(measured: np.ndarray, predicted: np.ndarray) -> dict:
    """rms (nm) of predicted - measured where both are valid, and the share of valid points."""
    d = np.asarray(predicted, dtype=np.float64) - np.asarray(measured, dtype=np.float64)
    ok = np.isfinite(d)
    rms = float(np.sqrt(np.mean(d[ok] ** 2))) * MM_TO_NM if ok.any() else None
    return {"rms_nm": rms, "points": int(ok.sum()), "valid_fraction": float(ok.mean())}


def fit_record(result: FitResult, *, target: Target | ProfileTarget,
               spec: MisfitSpec | ProfileSpec, provenance: dict, maps: dict, waviness: dict,
               extra: dict | None = None) -> dict:
    """The content of ``fit.json``.

    Parameters
    ----------
    result : FitResult
    target : Target
    spec : MisfitSpec
    provenance : dict
        ``seed``, ``scene_hash``, ``objective``, ``measured`` and what else names the inputs.
    maps, waviness : dict
        :func:`misfit_maps` of the form-removed maps and of their waviness, at the solution.
    """
    keys = [p.key for p in result.params]
    params = {}
    ident = result.identifiability or {}
    hidden = set(ident.get("hidden", ()))
    for i, p in enumerate(result.params):
        real = result.stderr_realisations
        solver = result.stderr_solver
        # a key that only a combination determines gets no standard error of its own
        se = None if p.key in hidden else _num(result.stderr[i])
        params[p.key] = {"value": float(result.values[i]), "stderr": se,
                         "determined": p.key not in hidden,
                         "stderr_solver": _num(None if solver is None else solver[i]),
                         "stderr_formal": _num(None if result.stderr_formal is None
                                               else result.stderr_formal[i]),
                         "stderr_random_parts": _num(None if real is None else real[i]),
                         "stderr_steps": _num(None if result.stderr_steps is None
                                              else result.stderr_steps[i]),
                         "start": float(p.start), "bounds": [float(p.lower), float(p.upper)],
                         "schema_range": [_num(p.schema[0]), _num(p.schema[1])],
                         "change_from_start": float(result.values[i] - p.start),
                         "relative_stderr": _num(result.stderr[i] / abs(result.values[i]))
                         if result.values[i] != 0 and se is not None else None}
    corr = {a: {b: float(result.correlation[i, j]) for j, b in enumerate(keys)}
            for i, a in enumerate(keys)}
    rec = {
        "parameters": params,
        "correlation": corr,
        "unresolved_pairs": [{"keys": [a, b], "correlation": r} for a, b, r in result.unresolved],
        "misfit_rms_nm": maps["rms_nm"],
        "misfit": {"value": result.best.cost, "start": result.start.cost,
                   "terms": result.best.terms, "start_terms": result.start.terms,
                   "waviness_rms_nm": waviness["rms_nm"], "map": maps,
                   "definition": spec.to_dict()},
        "identifiability": ident,
        "goodness": dict(result.goodness, birge_ratio=result.birge),
        "checks": result.checks,
        "uncertainty": {"stderr": "sqrt(stderr_formal^2 + birge_ratio x stderr_random_parts^2 "
                                  "+ stderr_steps^2 + stderr_solver^2)",
                        "stderr_steps": "the distance from the result to the minimum of the "
                                        "misfit smoothed over the difference steps (the "
                                        "misfit's fine-scale steps)",
                        "birge_ratio": "the misfit over the misfit the random parts alone "
                                       "leave (at least 1): the model's error",
                        "stderr_solver": "half the distance between the two starts' results "
                                         "when both reach the same misfit",
                        "stderr_formal": "s^2 (J^T J)^-1 of the weighted residuals at the "
                                         "solution (residuals taken as independent; J by "
                                         "central differences)",
                        "stderr_random_parts": "the spread of the solution over the "
                                               "realisations of the random parts and the "
                                               "camera's noise, each taken as the measured "
                                               "map (linearised)",
                        "realisations": int(result.realisations)},
        "evaluations": int(result.evaluations),
        "evaluations_budget": dict(
            result.budget, counted=("every evaluation of the scene at trial values: the "
                                    "search's, the standard errors' differences, the misfit "
                                    "profiles' and (a profile on both arms) each arm's own "
                                    "estimate's; not the realisations of the camera's noise "
                                    "and the random parts at the scene's values that set the "
                                    "noise floor before the fit (random_parts.realisations)")),
        "cache_hits": int(result.cache_hits),
        "status": result.status,
        "message": result.message,
        "global_search": result.global_search,
        "profiles": result.profiles,
        "measured_features": target.summary(),
        "timing_s": {"fit": result.seconds, "forward_model": result.model_seconds,
                     "per_evaluation": (result.model_seconds /
                                        max(1, sum(1 for e in result.history if not e.cached)))},
        "software_version": __version__,
    }
    rec.update(provenance)
    if extra:
        rec.update(extra)
    return rec


#: what each misfit term measures, for the summary
TERM_WORDS = {
    "map": "the waviness (the marks filtered out), point by point",
    "psd": "the spectrum, bin by bin in decades",
    "harmonics": "the marks' frequency and the amplitudes of their harmonics",
}


def summary_lines(record: dict, unit: Callable[[str], str] | None = None) -> list[str]:
    """The fit's summary in words: each value with its standard error (or why it has
    none), the status and why, each misfit term against its scale, the verdict of the
    model checks.  ``unit``: a key's unit ("" for none), written after its numbers."""
    lines = []
    after = (record.get("model_check") or {}).get("after") or {}
    # a standard error holds only where the model describes the measurement
    caveat = ("" if after.get("describes", True) else
              " (the model does not describe this measurement: see the verdict)")
    for k, p in record["parameters"].items():
        se = p.get("stderr")
        u = f" {unit(k)}" if unit is not None and unit(k) else ""
        if se is None and not p.get("determined", True):
            err = "(not determined alone: see the combinations below)"
        else:
            err = "+- n/a" if se is None else f"+- {se:.3g}{u}"
        lines.append(f"{k} = {p['value']:.6g}{u} {err} (start {p['start']:.6g}{u}){caveat}")
    ident = record.get("identifiability") or {}
    if ident.get("undetermined"):
        for d in ident["undetermined"]:
            lines.append(f"not determined by this measurement: {d['text']} (relative "
                         f"standard error {d['relative_stderr']:.3g})")
        for d in ident.get("directions", []):
            if d["determined"]:
                lines.append(f"determined: {d['text']} (relative standard error "
                             f"{d['relative_stderr']:.3g})")
    for pair in record.get("unresolved_pairs", []):
        lines.append(f"{pair['keys'][0]} and {pair['keys'][1]} cannot be told apart "
                     f"(correlation {pair['correlation']:.3f})")
    lines.append(f"status: {record['status']}: {record['message']}")
    mf = record["misfit"]
    for t, v in (mf.get("terms") or {}).items():
        lines.append(f"misfit term {t} ({TERM_WORDS.get(t, t)}): {v:.3g} (1 = each entry one "
                     f"scale off; start {mf.get('start_terms', {}).get(t, float('nan')):.3g})")
    g = record.get("goodness") or {}
    if g.get("ratio") is not None:
        lines.append(f"the misfit is {g['ratio']:.3g} times what the random parts and the "
                     f"camera's noise alone would leave if the model described the measurement")
    if record.get("misfit_rms_nm") is not None:
        lines.append(f"height difference rms {record['misfit_rms_nm']:.3g} nm: the marks' "
                     f"phase (where the spiral began) is not fitted, so the raw maps differ by "
                     f"about the marks' own rms even at a perfect fit; the waviness differs by "
                     f"{(mf.get('waviness_rms_nm') or float('nan')):.3g} nm rms")
    mc = record.get("model_check") or {}
    if mc.get("after"):
        lines.append(mc["after"]["verdict"])
    lines.append(f"{record['evaluations']} evaluations")
    if record.get("prediction"):
        lines += prediction_lines(record["prediction"])
    return lines
