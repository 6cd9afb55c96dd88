"""The uncertainty of a prediction made with fitted values (``fit --predict``): the fit's
covariance of its free keys carried to the predicted cut's headline numbers.

Numbers in, numbers out: the caller simulates the scene at the points
:func:`plan_propagation` gives and hands the metrics back to :func:`combine_propagation`.

Method: the law of propagation of uncertainty (JCGM 100:2008, the GUM, 5.1.2 and 5.2) with
the fitted keys' covariance C = V diag(s^2) V^T, its derivatives taken by differences along
the covariance's eigen-directions: the prediction is simulated at the fitted values (y0) and
at +-1 standard deviation s_i along each direction v_i (y+, y-; 2 n + 1 simulations for n
keys, the points of an unscented transform, Julier and Uhlmann, Proc. IEEE 92 (2004) 401).
Along each direction d_i = (y+ - y-) / 2 is the change per standard deviation (the first
order) and c_i = (y+ + y- - 2 y0) / 2 the second-order coefficient; then

    u^2 = sum d_i^2 + 2 sum c_i^2

(the GUM's law with the second-order terms of 5.1.2's note along each direction; the mixed
second derivatives between directions are not sampled) and sum c_i is the second-order
shift of the number's mean from its value at the fitted values.  A number whose second-order
part outweighs its first (``smooth`` false) is not linear in the keys over +-1 s: a number
that jumps with small changes of the keys (a window's extreme, Sz, can) reads so, and its u
is then a rough one.  Each point's numbers are the prediction window's, averaged over its
positions across the marks as the prediction's are (:mod:`._predict_window`).  Only the
parameters' uncertainty is carried: the model's own error (what it leaves out) is not in
it.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

__all__ = ["PREDICTED_QUANTITIES", "Propagation", "SigmaPoint", "plan_propagation",
           "combine_propagation", "prediction_lines", "COVERAGE_FACTOR"]

#: the predicted cut's headline numbers whose uncertainty is given: (the path in
#: ``simulate``'s metrics.json, the unit, what it is)
PREDICTED_QUANTITIES: tuple[tuple[str, str, str], ...] = (
    ("residual.Sq_nm", "nm", "residual Sq"),
    ("residual.Sa_nm", "nm", "residual Sa"),
    ("residual.Sz_nm", "nm", "residual Sz (peak to valley)"),
    ("scallop.height_nm", "nm", "feed marks' cusp height"),
    ("toolpath.feed_per_rev_mm", "mm", "feed per revolution (the marks' period)"),
)
#: the coverage factor of the expanded uncertainty reported beside the standard one
COVERAGE_FACTOR = 2.0
#: the share of a bound's distance a point keeps to where +-1 standard deviation would
#: cross the bound
BOUND_SHARE = 0.5
#: the method, as fit.json and metrics.json state it
METHOD = ("law of propagation of uncertainty (GUM, JCGM 100:2008 5.1.2 and 5.2) with the "
          "fitted keys' covariance: u^2 = sum d_i^2 + 2 sum c_i^2, d_i = (y+ - y-) / 2 and "
          "c_i = (y+ + y- - 2 y0) / 2 from predictions at +-1 standard deviation along "
          "the covariance's eigen-directions (2 n + 1 points, each simulated over the same "
          "window positions and pixel and averaged over the positions as the prediction is, "
          "every simulation with the scene's seed of the random parts, so that their "
          "differences are the parameters', not another realisation's); the parameters' "
          "uncertainty only, not the model's own error")


@dataclass
class SigmaPoint:
    """One simulation of the prediction: ``values`` of the keys, ``direction`` its
    eigen-direction's index, ``side`` +1 or -1, ``step`` in standard deviations (1, or
    less where a bound is nearer)."""

    direction: int
    side: int
    step: float
    values: dict[str, float]


@dataclass
class Propagation:
    """What :func:`plan_propagation` found: the keys whose uncertainty is carried, their
    covariance, the points to simulate, the keys left out and why, or why there is none
    (``blocked``)."""

    keys: list[str] = field(default_factory=list)
    centre: dict[str, float] = field(default_factory=dict)
    stderr: dict[str, float] = field(default_factory=dict)
    covariance: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))
    sd: np.ndarray = field(default_factory=lambda: np.zeros(0))
    directions: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))
    points: list[SigmaPoint] = field(default_factory=list)
    without: dict[str, str] = field(default_factory=dict)
    blocked: str | None = None


def _overridden(key: str, predict_keys: Sequence[str]) -> str | None:
    for pk in predict_keys:
        if key == pk or key.startswith(pk + "."):
            return pk
    return None


def _no_stderr_reason(record: dict, key: str) -> str:
    p = record["parameters"][key]
    ident = record.get("identifiability") or {}
    if not p.get("determined", True):
        return ("not determined alone by this measurement (only a combination of keys is: "
                "see the fit's identifiability)")
    if ident.get("not_computed"):
        return f"the fit has no standard errors: {record.get('message', '')}".rstrip(": ")
    note = record.get("status_note")
    return "the fit gives it no standard error" + (f": {note}" if note else "")


def plan_propagation(record: dict, predict: Sequence[str]) -> Propagation:
    """The points at which to simulate the prediction, from the fit's record (fit.json's
    ``parameters``, ``correlation`` and ``model_check``) and the ``--predict`` items
    (``KEY=VALUE``).

    A key that ``--predict`` sets does not enter (its fitted value is replaced); a key
    without a standard error (not determined alone, no standard errors under
    ``--max-evaluations``, not a measurement) is left out, with the reason in
    ``without``; where the fit's verdict is that the model does not describe the
    measurement there is no propagation at all (``blocked``)."""
    predict_keys = [str(s).split("=", 1)[0].strip() for s in predict]
    prop = Propagation()
    after = (record.get("model_check") or {}).get("after") or {}
    if not after.get("describes", True):
        prop.blocked = (f"the fit's verdict: {after.get('verdict', 'the model does not describe this measurement')}; "
                        f"its standard errors say nothing of the part where the model does "
                        f"not describe it")
        return prop
    for k, p in record["parameters"].items():
        pk = _overridden(k, predict_keys)
        se = p.get("stderr")
        if pk is not None:
            prop.without[k] = f"set by --predict ({pk}): its fitted value and uncertainty do not enter"
        elif se is None or not math.isfinite(float(se)):
            prop.without[k] = _no_stderr_reason(record, k)
        elif p.get("confident") is False:
            prop.without[k] = _no_stderr_reason(record, k)
        else:
            prop.keys.append(k)
            prop.centre[k] = float(p["value"])
            prop.stderr[k] = float(se)
    if not prop.keys:
        prop.blocked = ("no fitted key with a standard error reaches the prediction"
                        + ("" if not prop.without else ": " + "; ".join(
                            f"{k}: {why}" for k, why in prop.without.items())))
        return prop
    se = np.array([prop.stderr[k] for k in prop.keys])
    corr = np.array([[float(record["correlation"][a][b]) for b in prop.keys] for a in prop.keys])
    cov = corr * np.outer(se, se)
    w, v = np.linalg.eigh(0.5 * (cov + cov.T))
    keep = w > 0
    prop.covariance = cov
    prop.sd = np.sqrt(w[keep])
    prop.directions = v[:, keep]
    x = np.array([prop.centre[k] for k in prop.keys])
    lo = np.array([float(record["parameters"][k]["bounds"][0]) for k in prop.keys])
    hi = np.array([float(record["parameters"][k]["bounds"][1]) for k in prop.keys])
    for i in range(prop.sd.size):
        step = prop.sd[i] * prop.directions[:, i]
        for side in (1, -1):
            room = _room(x, side * step, lo, hi)
            t = 1.0 if room >= 1.0 else BOUND_SHARE * room
            if t <= 0.0:
                continue
            xs = x + side * t * step
            prop.points.append(SigmaPoint(i, side, t, dict(zip(prop.keys, map(float, xs)))))
    return prop


def _room(x, step, lo, hi) -> float:
    """How many ``step``s fit from ``x`` before a bound."""
    room = math.inf
    for xi, s, a, b in zip(x, step, lo, hi):
        if s > 0:
            room = min(room, (b - xi) / s)
        elif s < 0:
            room = min(room, (a - xi) / s)
    return max(room, 0.0)


def _lookup(metrics: dict, path: str) -> float | None:
    node: Any = metrics
    for part in path.split("."):
        if not isinstance(node, dict) or part not in node:
            return None
        node = node[part]
    if isinstance(node, bool) or not isinstance(node, (int, float)):
        return None
    return float(node) if math.isfinite(float(node)) else None


def combine_propagation(prop: Propagation, centre: dict, at_points: Sequence[dict | None],
                        *, seed: Any = None,
                        unit: Callable[[str], str] | None = None, positions: int = 1) -> dict:
    """The uncertainty of each of :data:`PREDICTED_QUANTITIES` from the metrics of the
    prediction at the fitted values (``centre``) and at each of ``prop.points``
    (``at_points``, in order; None where that simulation failed): ``{"method", "seed",
    "simulations", "keys", "without", "complete", "quantities": {path: {"label", "unit",
    "value", "u", "U", "coverage_factor", "second_order_shift", "per_key": {key:
    {"sensitivity", "alone"}}}}, "directions": [...]}``.  ``unit`` gives a key's unit for
    the sensitivities (value unit per key unit); ``positions``: the simulations behind each
    point's metrics (the prediction window's positions), for the count."""
    by_dir: dict[int, dict[int, tuple[float, dict | None]]] = {}
    for pt, m in zip(prop.points, at_points):
        by_dir.setdefault(pt.direction, {})[pt.side] = (pt.step, m)
    failed = [i for i, sides in by_dir.items() if any(m is None for _, m in sides.values())]
    quantities = {}
    for path, qunit, label in PREDICTED_QUANTITIES:
        y0 = _lookup(centre, path)
        if y0 is None:
            continue
        d = np.zeros(prop.sd.size)
        c = np.zeros(prop.sd.size)
        usable = True
        for i in range(prop.sd.size):
            sides = by_dir.get(i, {})
            tp, mp = sides.get(1, (0.0, centre))
            tm, mm = sides.get(-1, (0.0, centre))
            yp = None if mp is None else _lookup(mp, path)
            ym = None if mm is None else _lookup(mm, path)
            if yp is None or ym is None or tp + tm <= 0:
                usable = False
                continue
            d[i] = (yp - ym) / (tp + tm)
            if tp == 1.0 and tm == 1.0:
                c[i] = 0.5 * (yp + ym - 2.0 * y0)
        first, second = float(np.sum(d ** 2)), 2.0 * float(np.sum(c ** 2))
        u = math.sqrt(first + second)
        # the sensitivities to each key (per key unit): g = V diag(1 / s) d
        g = prop.directions @ (d / prop.sd) if prop.sd.size else np.zeros(len(prop.keys))
        per_key = {k: {"sensitivity": float(g[j]),
                       "sensitivity_unit": (f"{qunit} per {unit(k)}" if unit and unit(k)
                                            else f"{qunit} per unit of the key"),
                       "alone": float(abs(g[j]) * prop.stderr[k])}
                   for j, k in enumerate(prop.keys)}
        quantities[path] = {"label": label, "unit": qunit, "value": y0,
                            "u": u if usable else None,
                            "U": COVERAGE_FACTOR * u if usable else None,
                            "coverage_factor": COVERAGE_FACTOR,
                            "u_first_order": math.sqrt(first) if usable else None,
                            "second_order_shift": float(np.sum(c)),
                            "smooth": second <= first, "per_key": per_key}
    dirs = []
    for i in range(prop.sd.size):
        sides = by_dir.get(i, {})
        dirs.append({"step_per_key": {k: float(prop.sd[i] * prop.directions[j, i])
                                      for j, k in enumerate(prop.keys)},
                     "steps_sd": {("+" if s > 0 else "-"): t for s, (t, _) in sides.items()},
                     "values": {("+" if s > 0 else "-"):
                                (None if m is None else
                                 {p: _lookup(m, p) for p, _, _ in PREDICTED_QUANTITIES})
                                for s, (_, m) in sides.items()},
                     "failed": i in failed})
    return {"method": METHOD, "seed": seed, "points": 1 + len(prop.points),
            "window_positions": int(positions),
            "simulations": (1 + len(prop.points)) * int(positions),
            "coverage_factor": COVERAGE_FACTOR,
            "keys": list(prop.keys),
            "stderr": dict(prop.stderr),
            "without": dict(prop.without),
            "complete": not failed and not any(
                not why.startswith("set by --predict") for why in prop.without.values()),
            "quantities": quantities, "directions": dirs,
            "per_key_note": ("'alone': the change of the number that one key's standard "
                             "error makes, the others held; with correlated keys these do "
                             "not add up to u, which carries the correlations")}


def _fmt(v: float | None) -> str:
    return "n/a" if v is None else f"{v:.4g}"


def _simulations(unc: dict) -> str:
    positions = int(unc.get("window_positions", 1))
    if positions <= 1:
        return f"{unc['simulations']} simulations"
    return (f"{unc.get('points', unc['simulations'] // positions)} points x {positions} window "
            f"positions = {unc['simulations']} simulations")


def _spread(prediction: dict, path: str, qunit: str) -> str:
    s = (prediction.get("window_spread") or {}).get(path)
    return "" if s is None else f"; over where the marks fall in the window: +- {_fmt(s)} {qunit}"


def prediction_lines(prediction: dict) -> list[str]:
    """The prediction's summary in words: whether it is backed by a fit that describes the
    measurement, the window it was simulated over, each headline number with its standard
    uncertainty (k = 1) and the expanded one (k = 2) and its spread over where the marks
    fall in the window, the keys that carry none and why (or that the uncertainty was not
    computed)."""
    settings = ", ".join(prediction.get("settings", []))
    lines = []
    if not prediction.get("measurement_backed", True):
        lines.append(f"prediction ({settings}): NOT a measurement-backed forecast: "
                     f"{prediction.get('note', '')}")
    window = (["  " + prediction["window"]["description"]]
              if (prediction.get("window") or {}).get("description") else [])
    unc = prediction.get("uncertainty")
    if unc is None:
        skipped = bool(prediction.get("uncertainty_skipped"))
        lines.append(f"prediction ({settings}): "
                     + ("uncertainty not computed: " if skipped else "no uncertainty: ")
                     + f"{prediction.get('no_uncertainty', '')}")
        lines += window
        for path, qunit, label in PREDICTED_QUANTITIES:
            v = (prediction.get("values") or {}).get(path)
            if v is not None:
                lines.append(f"  {label} = {_fmt(v)} {qunit} (uncertainty "
                             f"{'not computed' if skipped else 'not known'}"
                             f"{_spread(prediction, path, qunit)})")
        return lines
    lines.append(f"prediction ({settings}), the fitted keys' uncertainty propagated "
                 f"({', '.join(unc['keys'])}; {_simulations(unc)}, seed "
                 f"{unc.get('seed')} in each; outside --max-evaluations):")
    lines += window
    for path, q in unc["quantities"].items():
        spread = _spread(prediction, path, q["unit"])
        if q["u"] is None:
            lines.append(f"  {q['label']} = {_fmt(q['value'])} {q['unit']} (uncertainty not "
                         f"known: a simulation failed{spread})")
            continue
        rough = ("" if q.get("smooth", True) else
                 f"; not linear in the keys over +-1 standard error (first order alone +- "
                 f"{_fmt(q['u_first_order'])}): a rough figure")
        lines.append(f"  {q['label']} = {_fmt(q['value'])} +- {_fmt(q['u'])} {q['unit']} "
                     f"(standard uncertainty, k=1; k={COVERAGE_FACTOR:g}: +- {_fmt(q['U'])} "
                     f"{q['unit']}{rough}{spread})")
    for k, why in unc.get("without", {}).items():
        lines.append(f"  without the uncertainty of {k}: {why}")
    lines.append("  (the parameters' uncertainty only: the model's own error is not in it)")
    return lines
