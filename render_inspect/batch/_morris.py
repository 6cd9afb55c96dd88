"""Morris elementary effects: a screening design for the sensitivity of a simulation's
outputs to its inputs, and its indices (Morris 1991 [1]_, with the mean absolute effect
mu* of Campolongo, Cariboni & Saltelli 2007 [2]_).

Each factor varies over [low, high] (linearly, or logarithmically with ``log = true``),
mapped from the unit interval, on ``levels`` equally spaced levels u = 0, 1/(p-1), ..., 1.
A *trajectory* starts at a random point of the grid and changes one factor at a time, each
once, by Delta = p / (2 (p - 1)) (up or down), in a random order: k + 1 runs for k factors.
The elementary effect of factor i on an output y in a trajectory is

    EE_i = (y(after) - y(before)) / (+-Delta)

in unit-interval coordinates (the change of y over the whole range of the factor, for a
linear y).  Over ``r`` trajectories: mu = mean EE_i, mu* = mean |EE_i| (the factor's
importance), sigma = standard deviation of EE_i (non-linearity and interactions).  A
factor whose mu* is small against the others' does not matter over its range; a large
sigma / mu* says its effect depends on where the others are.

A sweep file gets a design from its ``[morris]`` table (:class:`MorrisConfig`):

    [morris]
    trajectories = 10
    levels = 4
    seed = 1
    outputs = ["residual.Sq_nm", "residual.Sa_nm"]
    [[morris.factor]]
    key = "material.edge_radius_nm"
    low = 10.0
    high = 100.0
    log = true

and its points run as a study named ``morris``; the sweep writes ``morris.json`` (the
indices of every output) and one plot per output.  Dependency-free: numpy only.

References
----------
.. [1] M. D. Morris, "Factorial sampling plans for preliminary computational experiments,"
       Technometrics 33(2), 161-174 (1991). :DOI:`10.1080/00401706.1991.10484804`
.. [2] F. Campolongo, J. Cariboni, A. Saltelli, "An effective screening design for
       sensitivity analysis of large models," Environmental Modelling & Software 22(10),
       1509-1518 (2007). :DOI:`10.1016/j.envsoft.2006.10.004`
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
import math
from typing import Any

import numpy as np
from pydantic import Field, model_validator

from ..core.section import Section

__all__ = ["MorrisFactor", "MorrisConfig", "morris_unit_design", "morris_design",
           "elementary_effects", "morris_indices", "point_key", "MORRIS_STUDY"]

#: the name of the study a sweep file's ``[morris]`` points run as
MORRIS_STUDY = "morris"
#: significant digits a factor's value is matched on (a result's value and the design's)
_DIGITS = 12


class MorrisFactor(Section):
    """``[[morris.factor]]``: one input and its range."""
    key: str = Field(..., description="dotted scene key")
    low: float
    high: float
    log: bool = Field(False, description="levels spaced logarithmically (low > 0)")
    integer: bool = Field(False, description="round the value to an integer")

    @model_validator(mode="after")
    def _range(self):
        if not self.high > self.low:
            raise ValueError(f"high must be > low ({self.low}), received {self.high}")
        if self.log and self.low <= 0:
            raise ValueError(f"low must be > 0 for log = true, received {self.low}")
        if len(self.key.split(".")) < 2:
            raise ValueError(f"key must be a dotted scene key such as 'tool.nose_radius', "
                             f"received {self.key!r}")
        return self

    def value(self, u: float) -> int | float:
        """The factor's value at ``u`` in [0, 1]."""
        if self.log:
            v = math.exp(math.log(self.low) + u * (math.log(self.high) - math.log(self.low)))
        else:
            v = self.low + u * (self.high - self.low)
        v = min(max(v, self.low), self.high)
        return int(round(v)) if self.integer else float(v)


class MorrisConfig(Section):
    """``[morris]``: a Morris elementary-effects design (module docstring)."""
    trajectories: int = Field(10, ge=2, le=1000, description="r, trajectories")
    levels: int = Field(4, ge=2, le=100, description="p, levels per factor (even)")
    seed: int = Field(0, ge=0, description="seed of the design")
    outputs: list[str] = Field(default_factory=lambda: ["residual.Sq_nm", "residual.Sa_nm"],
                               description="metrics (dotted paths into metrics.json) analysed")
    factor: list[MorrisFactor] = Field(..., min_length=1)

    @model_validator(mode="after")
    def _checks(self):
        if self.levels % 2:
            raise ValueError(f"levels must be even (then each step is half the levels), "
                             f"received {self.levels}")
        keys = [f.key for f in self.factor]
        dup = sorted({k for k in keys if keys.count(k) > 1})
        if dup:
            raise ValueError(f"factor keys must be unique, received {dup} more than once")
        return self

    @property
    def delta(self) -> float:
        return self.levels / (2.0 * (self.levels - 1))

    def unit_design(self) -> np.ndarray:
        """(r, k + 1, k) unit-interval coordinates of every trajectory."""
        return morris_unit_design(len(self.factor), self.trajectories, self.levels, self.seed)

    def design(self) -> list[list[dict]]:
        """Every trajectory's k + 1 points as ``{key: value}``."""
        return morris_design(self.factor, self.unit_design())


def morris_unit_design(k: int, r: int, levels: int = 4, seed: int = 0) -> np.ndarray:
    """``r`` Morris trajectories of ``k`` factors on a ``levels``-level unit grid.

    Returns
    -------
    (r, k + 1, k) float64: point j + 1 of a trajectory differs from point j in one factor,
    by +-Delta; every factor changes once per trajectory.
    """
    if k < 1 or r < 1 or levels < 2 or levels % 2:
        raise ValueError(f"need k >= 1, r >= 1 and an even levels >= 2, received k = {k}, "
                         f"r = {r}, levels = {levels}")
    rng = np.random.default_rng(seed)
    delta = levels / (2.0 * (levels - 1))
    step = 1.0 / (levels - 1)
    # base levels from which +Delta stays inside [0, 1]: 0 .. 1 - Delta
    n_base = levels // 2
    out = np.empty((r, k + 1, k))
    for t in range(r):
        base = rng.integers(0, n_base, size=k) * step
        direction = rng.choice([-1.0, 1.0], size=k)
        x = np.where(direction > 0, base, base + delta)
        order = rng.permutation(k)
        out[t, 0] = x
        for j, i in enumerate(order):
            x = x.copy()
            x[i] += direction[i] * delta
            out[t, j + 1] = x
    return np.round(out, 12)


def morris_design(factors: Sequence[MorrisFactor], unit: np.ndarray) -> list[list[dict]]:
    """The unit design's points as ``{factor.key: value}`` dicts (trajectory by
    trajectory)."""
    return [[{f.key: f.value(float(u)) for f, u in zip(factors, point)} for point in traj]
            for traj in unit]


def elementary_effects(unit: np.ndarray, y: np.ndarray) -> np.ndarray:
    """(r, k) elementary effects of the outputs ``y`` (r, k + 1) of the unit design
    ``unit`` (r, k + 1, k); NaN where an output is missing."""
    unit = np.asarray(unit, dtype=np.float64)
    y = np.asarray(y, dtype=np.float64)
    r, n, k = unit.shape
    ee = np.full((r, k), np.nan)
    for t in range(r):
        d = np.diff(unit[t], axis=0)              # (k, k): one non-zero per row
        i = np.argmax(np.abs(d), axis=1)
        step = d[np.arange(k), i]
        ee[t, i] = np.diff(y[t]) / step
    return ee


def _match(value) -> float:
    return float(f"{float(value):.{_DIGITS}g}")


def morris_indices(cfg: MorrisConfig, lookup: Callable[[dict], Any]) -> dict:
    """mu, mu*, sigma of every factor for every output of ``cfg``.

    Parameters
    ----------
    cfg : MorrisConfig
    lookup : callable
        ``lookup(point)`` -> dict of outputs (dotted metric -> value) for a design point
        ``{key: value}``, or None when the point has no result.

    Returns
    -------
    dict
        ``factors`` (keys, ranges), ``trajectories``, ``levels``, ``delta``, ``complete``
        (trajectories with every point), and per output ``{key: {mu, mu_star, sigma, n}}``
        under ``indices``, sorted by mu* (largest first), plus ``ranking``.
    """
    unit = cfg.unit_design()
    design = morris_design(cfg.factor, unit)
    r, n, k = unit.shape
    results = [[lookup(p) for p in traj] for traj in design]
    complete = sum(all(x is not None for x in traj) for traj in results)
    out: dict[str, Any] = {"factors": [f.model_dump() for f in cfg.factor], "trajectories": r,
           "levels": cfg.levels, "delta": cfg.delta, "seed": cfg.seed, "complete": complete,
           "indices": {}, "ranking": {}}
    for name in cfg.outputs:
        y = np.array([[np.nan if x is None or x.get(name) is None else float(x[name])
                       for x in traj] for traj in results])
        ee = elementary_effects(unit, y)
        ind = {}
        for j, f in enumerate(cfg.factor):
            e = ee[:, j][np.isfinite(ee[:, j])]
            ind[f.key] = {"mu": float(e.mean()) if e.size else None,
                          "mu_star": float(np.abs(e).mean()) if e.size else None,
                          "sigma": float(e.std(ddof=1)) if e.size > 1 else None,
                          "n": int(e.size)}
        order = sorted(ind, key=lambda key: -(ind[key]["mu_star"] or 0.0))
        out["indices"][name] = {key: ind[key] for key in order}
        out["ranking"][name] = order
    return out


def point_key(values: dict) -> tuple:
    """A design point's identity for matching results: its values to 12 digits, by key."""
    return tuple(sorted((k, _match(v)) for k, v in values.items()))
