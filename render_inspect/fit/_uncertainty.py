"""The uncertainty of a fit and which combinations of its parameters the measurement
determines: the formal covariance, the random parts' covariance and the misfit's noise
floor, the eigen-directions of the covariance in relative units; the global phase's search
box; the probes either side of a result and the misfit profiles through it."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace
from typing import Any

import numpy as np

from ..core.progress import task as progress_task
from ._dispatch import features as predict_features
from ._params import FreeParameter
from ._features import Prediction, Target, residual_vector
from ._profile import ProfileTarget, profile_realisation_shifts
from ._arms import ArmsTarget, arms_realisation_shifts

__all__ = ["identifiability", "search_box", "realisation_shifts", "UNDETERMINED_RELATIVE",
           "SINGULAR"]


def search_box(params: Sequence[FreeParameter],
               search: dict | None = None) -> tuple[np.ndarray, np.ndarray]:
    """(lower, upper) in physical units of the global phase: ``search[key]`` where given,
    else the fit's bounds narrowed to the start value / 2 .. x 2 (a schema's range, such as
    a nose radius of (0, 50] mm, is no place to search: most of it cannot be cut), or to
    start +- 10 scales for a start at 0."""
    search = dict(search or {})
    lo, hi = [], []
    for p in params:
        if p.key in search:
            a, b = search[p.key]
        elif p.start > 0:
            a, b = p.start / 2.0, p.start * 2.0
        elif p.start < 0:
            a, b = p.start * 2.0, p.start / 2.0
        else:
            a, b = -10 * p.scale, 10 * p.scale
        lo.append(max(p.lower, a))
        hi.append(min(p.upper, b))
    return np.array(lo), np.array(hi)


def _covariance(j_units, residual, scales):
    """Formal covariance (physical units) from the Jacobian in scaled units; ``residual``:
    the weighted residual vector at the solution."""
    m, n = j_units.shape
    jp = j_units / scales[None, :]
    jtj = jp.T @ jp
    dof = max(m - n, 1)
    s2 = float(residual @ residual) / dof
    w, v = np.linalg.eigh(jtj)
    floor = max(float(w.max()), 1e-300) * 1e-12  # not a unit conversion
    inv = (v / np.maximum(w, floor)) @ v.T
    cov = s2 * inv
    d = np.sqrt(np.maximum(np.diag(cov), 0.0))
    return cov, d, _correlation(cov, d)


def _correlation(cov, d):
    with np.errstate(divide="ignore", invalid="ignore"):
        corr = cov / np.outer(d, d)
    corr = np.where(np.isfinite(corr), corr, 0.0)
    np.fill_diagonal(corr, 1.0)
    return np.clip(corr, -1.0, 1.0)


def _realisation_covariance(j_units, weights, best, target, scales):
    """The covariance (physical units) of the fitted values over the realisations of the
    random parts: each realisation, taken as the measured map, moves the weighted residual
    vector by ``weights * shift`` (:func:`realisation_shifts`) and the solution by the
    linearised least-squares step ``-pinv(J) weights shift``.  Also the mean sum of squares
    of those weighted shifts: the misfit the random parts alone leave at the true values
    (the noise floor of the misfit).  (None, None) without realisations."""
    pred = predict_features(best.height, target, best.values)
    shifts = realisation_shifts(pred, target)
    if shifts.shape[0] < 2 or shifts.shape[1] != j_units.shape[0]:
        return None, None
    ws = weights[None, :] * shifts
    du = -(np.linalg.pinv(j_units) @ ws.T).T
    dx = du * scales[None, :]
    floor_ss = float(np.mean(np.sum(ws * ws, axis=1)))
    return np.atleast_2d(np.cov(dx, rowvar=False, ddof=1)), floor_ss


#: a combination of parameters whose relative standard error exceeds this is "not
#: determined" by the measurement
UNDETERMINED_RELATIVE = 0.1
#: the information matrix's eigenvalues below this fraction of its largest are singular
SINGULAR = 1e-10


def identifiability(params: Sequence[FreeParameter], values: Sequence[float] | np.ndarray,
                    cov: np.ndarray, info: Any = None) -> dict:
    """Which combinations of the parameters the measurement determines: the eigenvectors
    of the covariance in relative units (each parameter divided by its value, or by its
    scale where the value is 0) and the standard error along each.  A direction whose
    relative standard error exceeds :data:`UNDETERMINED_RELATIVE` (or whose eigenvalue of
    the information matrix ``info`` is singular) is not determined; the parameters that
    carry it (weight above 0.3) get no standard error of their own, since any number
    printed alone would hide that only a combination is known.

    Returns ``{"directions": [...], "undetermined": [...], "hidden": [keys]}``; each
    direction is ``{"weights": {key: w}, "relative_stderr": s, "determined": bool,
    "text": "..."}`` (w: the relative change of each key along it, unit length)."""
    n = len(params)
    ref = np.array([abs(v) if v != 0 else p.scale for p, v in zip(params, values)])
    rel = cov / np.outer(ref, ref)
    w, v = np.linalg.eigh(0.5 * (rel + rel.T))
    singular = np.zeros(n, dtype=bool)
    if info is not None:
        wi, vi = np.linalg.eigh(info)
        top = max(float(wi.max()), 1e-300)
        for k in range(n):
            if wi[k] < SINGULAR * top:
                # the information matrix's null direction, in relative units
                d = vi[:, k] * ref
                d = d / max(np.linalg.norm(d), 1e-300)
                best = int(np.argmax(np.abs(v.T @ d)))
                singular[best] = True
    directions, undetermined, hidden = [], [], set()
    for k in np.argsort(w)[::-1]:
        vec = v[:, k] / (np.sign(v[np.argmax(np.abs(v[:, k])), k]) or 1.0)
        s = float(np.sqrt(max(w[k], 0.0)))
        det = s <= UNDETERMINED_RELATIVE and not singular[k]
        weights = {p.key: float(c) for p, c in zip(params, vec) if abs(c) > 0.05}
        text = _combination_text(weights)
        item = {"weights": weights, "relative_stderr": s, "determined": bool(det),
                "text": text}
        directions.append(item)
        if not det:
            undetermined.append(item)
            carriers = [key for key, c in weights.items() if abs(c) > 0.3]
            if len(carriers) > 1:
                hidden.update(carriers)
    return {"directions": directions, "undetermined": undetermined,
            "hidden": sorted(hidden), "threshold_relative": UNDETERMINED_RELATIVE}


def _combination_text(weights: dict) -> str:
    parts = []
    for key, c in weights.items():
        sign = "-" if c < 0 else "+"
        parts.append(f"{sign} {abs(c):.2f} d{key}/{key}")
    text = " ".join(parts)
    return text[2:] if text.startswith("+ ") else text


def realisation_shifts(pred: Prediction, target: Target) -> np.ndarray:
    """(R, m): how the normalised residuals of ``pred`` change when the measured map's
    features are replaced by those of each realisation of the random parts
    (``target.draws``), less their mean: the spread of the residual vector that the random
    parts alone cause (an empty array without at least two realisations)."""
    if isinstance(target, ArmsTarget):
        return arms_realisation_shifts(pred, target)
    if isinstance(target, ProfileTarget):
        return profile_realisation_shifts(pred, target)
    feats = target.draws
    if len(feats) < 2:
        return np.zeros((0, 0))

    def with_features(wavy, psd, centroid, amplitudes):
        return replace(target, wavy=wavy, psd=psd, centroid=centroid, amplitudes=amplitudes)

    def mean(values):
        return np.mean(np.asarray(values, dtype=np.float64), axis=0)

    centroids = [f.centroid for f in feats]
    has_peak = target.peak is not None and all(c is not None and np.isfinite(c) for c in centroids)
    mean_target = with_features(mean([f.wavy for f in feats]), mean([f.psd for f in feats]),
                                float(np.mean(centroids)) if has_peak else target.centroid,
                                mean([f.amplitudes for f in feats]))
    base = residual_vector(pred, mean_target)[0]
    return np.array([residual_vector(pred, with_features(
        f.wavy, f.psd, f.centroid if has_peak else target.centroid, f.amplitudes))[0] - base
        for f in feats])




def probe(params: Sequence[FreeParameter], evaluator: Any, best: Any, sigma_units: np.ndarray,
          lo: np.ndarray, hi: np.ndarray, fd_step: float) -> tuple[list, int]:
    """The misfit either side of ``best`` along each parameter (2 standard errors, between
    half a difference step and five): (lower evaluations found, probes made)."""
    u = np.array([p.to_unit(v) for p, v in zip(params, best.values)])
    pts = []
    for i in range(len(params)):
        d = float(np.clip(2 * sigma_units[i] if np.isfinite(sigma_units[i]) else fd_step,
                          fd_step / 2, 5 * fd_step))
        for s in (-d, d):
            v = u.copy()
            v[i] = np.clip(u[i] + s, lo[i], hi[i])
            if v[i] != u[i]:
                pts.append(v)
    evs = evaluator.evaluate_units(pts) if pts else []
    tol = 1e-3 * best.cost + 1e-12  # not a unit conversion
    lower = [e for e in evs if e.error is None and e.cost < best.cost - tol]
    return lower, len(pts)


def profiles(params: Sequence[FreeParameter], evaluator: Any, best: Any, stderr: np.ndarray,
             k: int) -> dict:
    """The misfit along each parameter through the solution (the others held)."""
    pts, where = [], []
    for i, p in enumerate(params):
        x = best.values[i]
        span = max(3 * stderr[i] if np.isfinite(stderr[i]) else 0.0, 0.02 * abs(x),
                   0.2 * p.scale)
        vals = x + span * np.linspace(-1, 1, 2 * k + 1)
        vals = np.unique(np.clip(vals, p.lower, p.upper))
        for v in vals:
            xx = best.values.copy()
            xx[i] = v
            pts.append(xx)
            where.append((p.key, float(v)))
    out: dict[str, dict[str, list]] = {p.key: {"values": [], "misfit": [], "terms": []}
                                       for p in params}
    with progress_task(f"fit: misfit along each parameter ({len(pts)} points)",
                       total=len(pts)) as st:
        evaluator.step = st
        try:
            evs = evaluator.evaluate(pts, budget=False)
        finally:
            evaluator.step = None
    for (key, v), ev in zip(where, evs):
        out[key]["values"].append(v)
        out[key]["misfit"].append(ev.cost if ev.error is None else None)
        out[key]["terms"].append(ev.terms)
    return out
