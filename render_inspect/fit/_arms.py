"""Both arms of a diameter slice fitted together.

A slice through a turned part's spindle axis measures the same radii twice, once on each
side of the axis (the line's two *arms*).  A profile fit of a window on one arm may take in
the same radii on the other arm: each evaluation predicts both stretches (each simulated at
its own place on the part), each arm is registered and compared with its own measured
stretch (:mod:`._profile`), and the misfit is the sum of the two arms' misfits.

After the fit, each arm's own estimate is the minimum of that arm's misfit scanned along
each free key about the joint solution (:func:`arm_estimates`), and the arms' disagreement
enters the standard errors as a measurement term (:func:`combine_arms`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from ._budget import BudgetExhausted
from ._features import robust_weights, soft_l1
from ._profile import (ProfilePrediction, ProfileSpec, ProfileTarget, predict_profile_features,
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
#: the least step of an arm's scan, as a fraction of the key's scale (a key at 0)
MIN_STEP_OF_SCALE = 1e-6  # not a unit conversion


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
    def spec(self) -> ProfileSpec:
        return self.first.spec

    @property
    def draws(self) -> list:
        return self.first.draws

    @property
    def peak(self) -> float | None:
        return self.first.peak

    @property
    def centroid(self) -> float | None:
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
    def height(self) -> np.ndarray:
        return self.first.height

    @property
    def centroid(self) -> float | None:
        return self.first.centroid

    @property
    def params(self) -> np.ndarray:
        return self.first.params

    @property
    def shift(self) -> float:
        return self.first.shift


def _rows(z, target: ArmsTarget) -> np.ndarray:
    z = np.asarray(z, dtype=np.float64)
    return z.reshape(len(target.arms), -1)


def arms_features(z: np.ndarray, target: ArmsTarget, values: Any = None, *,
                  measured: bool = False) -> ArmsPrediction:
    """Each arm's features of a predicted (arms, points) array ``z``."""
    return ArmsPrediction([predict_profile_features(row, t, values, measured=measured)
                           for row, t in zip(_rows(z, target), target.arms)])


def arms_residuals(pred: ArmsPrediction,
                   target: ArmsTarget) -> tuple[np.ndarray, np.ndarray, dict]:
    """The arms' residual vectors one after the other; each term's share summed over the
    arms (the joint misfit is the sum of the arms' misfits)."""
    ds, As = [], []
    terms: dict[str, float] = {}
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


def set_arms_noise_floor(target: ArmsTarget, noisy: list, clean: np.ndarray) -> None:
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


def _arm_costs(height, target: ArmsTarget, x) -> list:
    """Each arm's misfit (its share of the joint soft-L1 misfit) at a predicted array."""
    pred = arms_features(height, target, x)
    out = []
    for p, t in zip(pred.arms, target.arms):
        d, a, _ = profile_residual_vector(p, t)
        out.append(float(np.sum(a * a * soft_l1(d))))
    return out


def _parabola_min(xs, ys) -> float:
    """The minimum of the parabola through the lowest sampled point and its neighbours
    (the lowest point itself where the three do not bend upwards)."""
    k = int(np.argmin(ys))
    k = min(max(k, 1), len(xs) - 2)
    x3, y3 = np.asarray(xs[k - 1:k + 2]), np.asarray(ys[k - 1:k + 2])
    c = np.polyfit(x3 - x3[1], y3, 2)
    if c[0] <= 0:
        return float(xs[int(np.argmin(ys))])
    return float(np.clip(x3[1] - c[1] / (2 * c[0]), x3[0], x3[2]))


#: :func:`arm_estimates`' scan: steps either side of the solution, and rounds of one step
#: more outwards on either side while an arm's lowest point is at the scan's end
ARM_REACH, ARM_EXTEND = 2, 3


def arm_evaluations(n_keys: int, *, reach: int = ARM_REACH, extend: int = ARM_EXTEND) -> int:
    """The most evaluations :func:`arm_estimates` makes for ``n_keys`` free keys:
    ``2 (reach + extend)`` each (the scan either side, and each round's step either
    side)."""
    return 2 * (int(reach) + int(extend)) * int(n_keys)


def arm_estimates(params: list, evaluator: Any, values: np.ndarray, stderr: np.ndarray, *,
                  rel_step: float = 0.01, reach: int = ARM_REACH, extend: int = ARM_EXTEND) -> dict:
    """Each arm's own estimate of the free keys, from the joint fit at ``values``.

    The joint misfit is the sum of the arms' misfits.  Along each free key (the others
    held at the joint solution), the misfit is sampled at steps of ``rel_step`` of the
    value, ``reach`` steps either side (and up to ``extend`` more outwards while an arm's
    lowest point is at the end of the scan); one evaluation gives both arms' misfits.  Each
    arm's own estimate is the minimum of the parabola through its lowest sample and their
    neighbours: where a fit of that arm alone ends (for one free key; with several, each
    key's minimum with the others held).

    Each arm's standard error is the joint one scaled by the share of the information that
    arm holds: ``stderr_i * sqrt(inv(F_arm)_ii / inv(F)_ii)`` with ``F = J^T J`` of the
    arm's (``F_arm``) and of both arms' (``F``) residuals, weighted as the joint fit's
    covariance weights them (the soft-L1 loss's re-weighting at the solution), J by central
    differences over one step.  Costs ``2 reach`` evaluations per free key, and more where
    an arm's minimum lies beyond them; all within ``evaluator.max_evaluations`` (an error
    where it is reached first)."""
    target: ArmsTarget = evaluator.target
    x0 = np.asarray(values, dtype=np.float64)
    n = x0.size
    m = len(target.arms)
    hs = np.array([max(rel_step * abs(v), MIN_STEP_OF_SCALE * p.scale) for p, v in zip(params, x0)])
    best = evaluator.evaluate([x0.copy()], budget=False)[0]
    if best.error is not None:
        return {"error": f"the evaluation at the solution failed: {best.error}"}
    base = _arm_vectors(best.height, target, best.values)
    est = np.tile(x0, (m, 1))
    infos = [np.zeros((n, n)) for _ in range(m)]
    js = [np.zeros((base[k][0].size, n)) for k in range(m)]
    scans = []

    def at(i, steps):
        pts = []
        for st in steps:
            x = x0.copy()
            x[i] = min(max(x0[i] + st * hs[i], params[i].lower), params[i].upper)
            pts.append(x)
        return pts, evaluator.evaluate(pts, budget=False)

    cap = getattr(evaluator, "max_evaluations", None)
    over = {"error": f"--max-evaluations {cap} was reached before each arm's own minimum "
                     f"was found", "budget": True}
    for i in range(n):
        steps = [st for st in range(-reach, reach + 1) if st != 0]
        try:
            pts, evs = at(i, steps)
        except BudgetExhausted:
            return over
        bad = [e.error for e in evs if e.error is not None]
        if bad:
            return {"error": f"an evaluation about the solution failed: {bad[0]}"}
        sample = {0: (x0[i], _arm_costs(best.height, target, best.values))}
        for st, x, e in zip(steps, pts, evs):
            sample[st] = (x[i], _arm_costs(e.height, target, e.values))
        # the arms' residuals one step either side: the information each holds
        lo, hi = evs[steps.index(-1)], evs[steps.index(1)]
        v_lo = _arm_vectors(lo.height, target, lo.values)
        v_hi = _arm_vectors(hi.height, target, hi.values)
        dx = pts[steps.index(1)][i] - pts[steps.index(-1)][i]
        for k in range(m):
            js[k][:, i] = base[k][1] * (v_hi[k][0] - v_lo[k][0]) / dx
        # outwards while an arm's lowest sample is at an end of the scan
        for _ in range(extend):
            ends = set()
            for k in range(m):
                low = min(sample, key=lambda st: sample[st][1][k])
                if low == min(sample) or low == max(sample):
                    ends.add(low)
            new = sorted({st + (1 if st > 0 else -1) for st in ends} - set(sample))
            if not new:
                break
            try:
                p2, e2 = at(i, new)
            except BudgetExhausted:
                return over
            for st, x, e in zip(new, p2, e2):
                if e.error is None:
                    sample[st] = (x[i], _arm_costs(e.height, target, e.values))
            if all(e.error is not None for e in e2):
                break
        order = sorted(sample)
        scans.append({"key": params[i].key, "values": [float(sample[st][0]) for st in order],
                      "misfit": [[float(sample[st][1][k]) for st in order]
                                 for k in range(m)]})
        for k in range(m):
            est[k, i] = _parabola_min([sample[st][0] for st in order],
                                      [sample[st][1][k] for st in order])
    for k in range(m):
        infos[k] = js[k].T @ js[k]
    f_all = np.sum(infos, axis=0)
    se = np.asarray(stderr, dtype=np.float64)
    inv_all = np.diag(np.linalg.pinv(f_all))
    out_arms = []
    for k, f in enumerate(infos):
        inv_k = np.diag(np.linalg.pinv(f))
        with np.errstate(divide="ignore", invalid="ignore"):
            ratio = np.sqrt(np.where(inv_all > 0, inv_k / inv_all, np.nan))
        out_arms.append({"values": [float(v) for v in est[k]],
                         "stderr": [float(v) for v in se * ratio],
                         "information_share": [float(f[i, i] / f_all[i, i])
                                               if f_all[i, i] > 0 else None
                                               for i in range(n)]})
    return {"arms": out_arms, "steps": [float(h) for h in hs], "scans": scans}


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
              name: str = "", stderr: bool = True, unit_name: str = "") -> str:
    """The arms' disagreement in words for the summary (``stderr`` False: the fit gives no
    standard error, its values not being a measurement, and none is printed;
    ``unit_name``: the unit written after each number)."""
    rel = comb["difference_relative"]
    what = name or key
    u = f" {unit_name}" if unit_name else ""
    arms = f"{what}: the window's arm {a * unit:.5g}{u}, the other arm {b * unit:.5g}{u}"
    if not stderr:
        return (f"{arms} (they differ by {'n/a' if rel is None else f'{100 * rel:+.2g} %'}; "
                f"no standard error: the values are not a measurement, see the verdict)")
    text = (f"{arms} (they differ by {'n/a' if rel is None else f'{100 * rel:+.2g} %'}, "
            f"{comb['difference_over_stderr']:.2g} times the difference's standard error)")
    if comb["disagree"]:
        text += ("; the arms disagree by more than their standard errors allow: the "
                 "measurement's spread between the arms is in the standard error "
                 f"({comb['stderr_fit'] * unit:.2g}{u} from the fit, "
                 f"{comb['u_arms'] * unit:.2g}{u} from the arms, "
                 f"{comb['stderr'] * unit:.2g}{u} combined)")
    return text

