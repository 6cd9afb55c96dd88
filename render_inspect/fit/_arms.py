"""Both arms of a diameter slice fitted together.

A slice through a turned part's spindle axis measures the same radii twice, once on each
side of the axis (the line's two *arms*).  A profile fit of a window on one arm may take in
the same radii on the other arm: each evaluation predicts both stretches (each simulated at
its own place on the part), each arm is registered and compared with its own measured
stretch (:mod:`._profile`), and the misfit is the sum of the two arms' misfits.

After the fit, each arm's own estimate follows from the joint fit's Jacobian split by arm
(:func:`arm_estimates`), and their disagreement enters the standard errors as a measurement
term (:func:`combine_arms`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from ._features import robust_weights
from ._profile import (ProfilePrediction, ProfileTarget, predict_profile_features,
                       profile_realisation_shifts, profile_residual_vector,
                       set_profile_noise_floor)

__all__ = ["ArmsTarget", "ArmsPrediction", "arms_features", "arms_residuals",
           "arms_realisation_shifts", "set_arms_noise_floor", "arm_estimates", "combine_arms",
           "ARMS_CHOICES", "ARMS_DISAGREE", "arms_text"]

#: ``--arms``: one arm (the window's), or both where the line crosses the axis
ARMS_CHOICES = ("one", "both")
#: the arms "disagree" when their estimates differ by more than this many of the
#: difference's standard uncertainty (from the arms' own standard errors)
ARMS_DISAGREE = 2.0


@dataclass
class ArmsTarget:
    """The measured stretches of the arms (the window's arm first), each a
    :class:`~._profile.ProfileTarget` of the same number of points."""

    arms: list
    kind: str = "profile"

    @property
    def first(self) -> ProfileTarget:
        return self.arms[0]

    @property
    def z(self) -> np.ndarray:
        return self.first.z

    @property
    def height(self) -> np.ndarray:
        return self.first.z

    @property
    def spacing(self) -> float:
        return self.first.spacing

    @property
    def spec(self):
        return self.first.spec

    @property
    def draws(self) -> list:
        return self.first.draws

    @property
    def peak(self):
        return self.first.peak

    @property
    def centroid(self):
        """The marks' mean frequency over the arms (cycles/mm; what the measurement proposes
        as the start of the feed), None where an arm has no marks."""
        ks = [a.centroid for a in self.arms]
        if any(k is None for k in ks):
            return None
        return float(np.mean(ks))

    @property
    def amplitudes(self) -> np.ndarray:
        return np.mean([a.amplitudes for a in self.arms], axis=0)

    @property
    def params(self) -> np.ndarray:
        return self.first.params

    def summary(self) -> dict:
        out = self.first.summary()
        out["arms"] = [a.summary() for a in self.arms]
        return out


@dataclass
class ArmsPrediction:
    """The arms' predictions (:class:`~._profile.ProfilePrediction` each)."""

    arms: list

    @property
    def first(self) -> ProfilePrediction:
        return self.arms[0]

    @property
    def height(self):
        return self.first.height

    @property
    def centroid(self):
        return self.first.centroid

    @property
    def params(self):
        return self.first.params

    @property
    def shift(self):
        return self.first.shift


def _rows(z, target: ArmsTarget) -> np.ndarray:
    z = np.asarray(z, dtype=np.float64)
    return z.reshape(len(target.arms), -1)


def arms_features(z, target: ArmsTarget, values=None, *, measured: bool = False) -> ArmsPrediction:
    """Each arm's features of a predicted (arms, points) array ``z``."""
    return ArmsPrediction([predict_profile_features(row, t, values, measured=measured)
                           for row, t in zip(_rows(z, target), target.arms)])


def arms_residuals(pred: ArmsPrediction, target: ArmsTarget):
    """The arms' residual vectors one after the other; each term's share summed over the
    arms (the joint misfit is the sum of the arms' misfits)."""
    ds, As, terms = [], [], {}
    for p, t in zip(pred.arms, target.arms):
        d, a, tm = profile_residual_vector(p, t)
        ds.append(d)
        As.append(a)
        for k, v in tm.items():
            terms[k] = terms.get(k, 0.0) + v
    return np.concatenate(ds), np.concatenate(As), terms


def arms_realisation_shifts(pred: ArmsPrediction, target: ArmsTarget) -> np.ndarray:
    """:func:`~._profile.profile_realisation_shifts` of each arm, side by side."""
    parts = [profile_realisation_shifts(p, t) for p, t in zip(pred.arms, target.arms)]
    if any(p.size == 0 for p in parts):
        return np.zeros((0, 0))
    return np.concatenate(parts, axis=1)


def set_arms_noise_floor(target: ArmsTarget, noisy, clean) -> None:
    """:func:`~._profile.set_profile_noise_floor` of each arm (its rows of the
    realisations)."""
    rows = [_rows(z, target) for z in noisy]
    c = _rows(clean, target)
    for i, t in enumerate(target.arms):
        set_profile_noise_floor(t, [r[i] for r in rows], c[i])


def _arm_vectors(height, target: ArmsTarget, x) -> list:
    """Each arm's (weighted residuals a * d, robust weights) at a predicted array."""
    pred = arms_features(height, target, x)
    out = []
    for p, t in zip(pred.arms, target.arms):
        d, a, _ = profile_residual_vector(p, t)
        out.append((a * d, robust_weights(d)))
    return out


def arm_estimates(params, evaluator: Any, values, stderr, *, rel_step: float = 0.005) -> dict:
    """Each arm's own estimate of the free keys, from the joint fit at ``values``.

    The joint misfit is the sum of the arms' misfits; each arm's residuals (weighted by
    their terms and by the soft-L1 loss's re-weighting at the joint solution, as the joint
    fit's covariance is) are linearised about the joint solution by central differences
    (steps of ``rel_step`` of each value, inside the bounds), and a Gauss-Newton step on
    that arm alone, repeated once from where it lands, gives the arm's estimate: where the
    fit of that arm alone would end.  Each arm's standard error is the joint one scaled by
    the share of the information that arm holds: ``stderr_i * sqrt(inv(F_arm)_ii /
    inv(F)_ii)`` with ``F = J^T J`` of the arm's (``F_arm``) and of both arms' (``F``)
    columns.  Costs 2 evaluations per free key and one per arm."""
    target: ArmsTarget = evaluator.target
    x0 = np.asarray(values, dtype=np.float64)
    n = x0.size
    hs = np.array([max(rel_step * abs(v), 1e-6 * p.scale) for p, v in zip(params, x0)])
    pts = [x0.copy()]
    for i, p in enumerate(params):
        for s in (-1.0, 1.0):
            x = x0.copy()
            x[i] = min(max(x0[i] + s * hs[i], p.lower), p.upper)
            pts.append(x)
    evs = evaluator.evaluate(pts, budget=False)
    if any(e.error is not None for e in evs):
        bad = next(e.error for e in evs if e.error is not None)
        return {"error": f"an evaluation about the solution failed: {bad}"}
    vecs = [_arm_vectors(e.height, target, e.values) for e in evs]
    arms = []
    infos = []
    js = []
    for k in range(len(target.arms)):
        sw = vecs[0][k][1]
        r0 = sw * vecs[0][k][0]
        j = np.empty((r0.size, n))
        for i in range(n):
            lo_x, hi_x = pts[1 + 2 * i][i], pts[2 + 2 * i][i]
            j[:, i] = sw * (vecs[2 + 2 * i][k][0] - vecs[1 + 2 * i][k][0]) / (hi_x - lo_x)
        js.append(j)
        infos.append(j.T @ j)
        step = -np.linalg.lstsq(j, r0, rcond=None)[0]
        arms.append(x0 + step)
    # once more from where each arm's step lands (the registered profile is not linear in
    # the feed over a few per cent)
    land = [np.clip(x, [p.lower for p in params], [p.upper for p in params]) for x in arms]
    evs2 = evaluator.evaluate(land, budget=False)
    for k, e in enumerate(evs2):
        if e.error is not None:
            continue
        vec, _ = _arm_vectors(e.height, target, e.values)[k]
        sw = vecs[0][k][1]
        arms[k] = land[k] - np.linalg.lstsq(js[k], sw * vec, rcond=None)[0]
    f_all = sum(infos)
    se = np.asarray(stderr, dtype=np.float64)
    try:
        inv_all = np.diag(np.linalg.pinv(f_all))
        out_arms = []
        for k, f in enumerate(infos):
            inv_k = np.diag(np.linalg.pinv(f))
            ratio = np.sqrt(np.where(inv_all > 0, inv_k / np.where(inv_all > 0, inv_all, 1.0),
                                     np.nan))
            out_arms.append({"values": [float(v) for v in arms[k]],
                             "stderr": [float(v) for v in se * ratio],
                             "information_share": [float(f[i, i] / f_all[i, i])
                                                   if f_all[i, i] > 0 else None
                                                   for i in range(n)]})
    except np.linalg.LinAlgError as err:
        return {"error": f"the arms' information matrix: {err}"}
    return {"arms": out_arms, "steps": [float(h) for h in hs]}


def combine_arms(value: float, stderr: float, a: float, sa: float, b: float,
                 sb: float) -> dict:
    """The arms' disagreement folded into a joint estimate's standard error.

    ``a``, ``b``: the arms' own estimates with standard errors ``sa``, ``sb``; ``value``,
    ``stderr``: the joint fit's.  The difference ``D = a - b`` is expected to scatter by
    ``u_D = sqrt(sa^2 + sb^2)``; what it exceeds that by is the measurement's own spread
    between the arms.  The joint value, in effect the mean of the two arms, takes as a
    systematic standard uncertainty that of a mean of two readings whose scatter is that
    excess: ``u_arms = sqrt(max(0, D^2 - u_D^2)) / 2``, added in quadrature:
    ``u = sqrt(stderr^2 + u_arms^2)``.  The arms *disagree* when ``|D| > 2 u_D``."""
    d = a - b
    u_d = math.hypot(sa, sb)
    u_arms = math.sqrt(max(0.0, d * d - u_d * u_d)) / 2.0
    ratio = abs(d) / u_d if u_d > 0 else math.inf
    return {"difference": d, "difference_relative": d / value if value else None,
            "difference_stderr": u_d, "difference_over_stderr": ratio,
            "u_arms": u_arms, "stderr_fit": stderr, "stderr": math.hypot(stderr, u_arms),
            "disagree": bool(ratio > ARMS_DISAGREE)}


def arms_text(key: str, comb: dict, a: float, b: float, *, unit: float = 1.0,
              name: str = "") -> str:
    """The arms' disagreement in words for the summary."""
    rel = comb["difference_relative"]
    what = name or key
    text = (f"{what}: the window's arm {a * unit:.5g}, the other arm {b * unit:.5g} "
            f"(they differ by {'n/a' if rel is None else f'{100 * rel:+.2g} %'}, "
            f"{comb['difference_over_stderr']:.2g} times the difference's standard error)")
    if comb["disagree"]:
        text += ("; the arms disagree by more than their standard errors allow: the "
                 "measurement's spread between the arms is in the standard error "
                 f"({comb['stderr_fit'] * unit:.2g} from the fit, {comb['u_arms'] * unit:.2g} "
                 f"from the arms, {comb['stderr'] * unit:.2g} combined)")
    return text

