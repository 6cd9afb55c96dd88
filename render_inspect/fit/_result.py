"""``fit.json``: the fitted values, their standard errors and correlations, the misfit, and
where everything came from."""

from __future__ import annotations

import math

import numpy as np

from .. import __version__
from ..core.units import MM_TO_NM

__all__ = ["fit_record", "misfit_maps"]


def _num(v):
    if v is None:
        return None
    v = float(v)
    return v if math.isfinite(v) else None


def misfit_maps(measured, predicted) -> dict:
    """rms (nm) of predicted - measured where both are valid, and the share of valid points."""
    d = np.asarray(predicted, dtype=np.float64) - np.asarray(measured, dtype=np.float64)
    ok = np.isfinite(d)
    rms = float(np.sqrt(np.mean(d[ok] ** 2))) * MM_TO_NM if ok.any() else None
    return {"rms_nm": rms, "points": int(ok.sum()), "valid_fraction": float(ok.mean())}


def fit_record(result, *, target, spec, provenance: dict, maps: dict, waviness: dict,
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
    for i, p in enumerate(result.params):
        real = result.stderr_realisations
        params[p.key] = {"value": float(result.values[i]), "stderr": _num(result.stderr[i]),
                         "stderr_formal": _num(None if result.stderr_formal is None
                                               else result.stderr_formal[i]),
                         "stderr_random_parts": _num(None if real is None else real[i]),
                         "start": float(p.start), "bounds": [float(p.lower), float(p.upper)],
                         "schema_range": [_num(p.schema[0]), _num(p.schema[1])],
                         "change_from_start": float(result.values[i] - p.start),
                         "relative_stderr": _num(result.stderr[i] / abs(result.values[i]))
                         if result.values[i] != 0 else None}
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
        "uncertainty": {"stderr": "sqrt(stderr_formal^2 + stderr_random_parts^2)",
                        "stderr_formal": "s^2 (J^T J)^-1 of the weighted residuals at the "
                                         "solution (residuals taken as independent)",
                        "stderr_random_parts": "the spread of the solution over the "
                                               "realisations of the random parts and the "
                                               "camera's noise, each taken as the measured "
                                               "map (linearised)",
                        "realisations": int(result.realisations)},
        "evaluations": int(result.evaluations),
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
