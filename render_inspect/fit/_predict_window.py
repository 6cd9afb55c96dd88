"""The window a prediction of the next cut is simulated over (``fit --predict``), and its
numbers averaged over where the marks fall in it.

A roughness number of a window a few feed periods wide depends on where the marks fall in
the window: on a turned part the spiral's phase at the window moves through a whole
period when the feed per revolution changes by p / (R0 - r) of itself (R0 the radius the
cut starts at, r the window's: 0.2 % for the shipped grid's window), so that predictions at
nearby feeds read the window at unrelated phases.  Two effects make a number depend on
that phase: a window that holds a non-whole number of periods (its mean and variance carry
a part of a period more or less), and curved marks over a window whose area grows across
them (a turned part's rings: even whole periods are weighted by the radius, an effect of
the order of p / (2 pi r)).  Neither is the next cut's: no setting of it places its marks
to a fraction of a period.

So the window is simulated at :data:`PHASES` positions moved across the marks by
0, 1 / K, ..., (K - 1) / K of their period and each number is the mean over the positions:
the K-point mean of a number periodic in the phase is exact for its harmonics below K (a
feed scallop's harmonics fall as 1 / k^2), so the mean no longer jumps with the phase.
The spread over the positions (their standard deviation) is reported beside it: how much
one window of the next part scatters with where its marks fall.  A window holding fewer
than :data:`MIN_PERIODS` periods across the marks is grown about its centre until it holds
that many (the bias of a truncated period falls as 1 / periods^2)."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

__all__ = ["PredictionWindow", "prediction_window", "phase_average", "PHASES", "MIN_PERIODS"]

#: positions of the window across the marks (0, 1/K, ..., (K-1)/K of their period)
PHASES = 4
#: the fewest periods of the marks the window holds across them (grown to it)
MIN_PERIODS = 8.0
#: the metrics groups whose numbers depend on the window (averaged over the positions);
#: the others (the analytic scallop, the path's feed) are the first position's
WINDOW_GROUPS = ("residual",)


@dataclass
class PredictionWindow:
    """Where a prediction is simulated: ``region`` (x0, y0, x1, y1 mm, the first position),
    ``shifts`` (dx, dy mm of each position from it), the marks' ``pattern`` and
    ``period_mm`` (None: no periodic marks, one position), ``across`` (the unit vector
    across the marks at the window's centre), ``periods`` (the marks' periods across the
    window) and ``fit_region`` (the fit's window it was taken from)."""

    region: list[float]
    fit_region: list[float]
    shifts: list[tuple[float, float]] = field(default_factory=lambda: [(0.0, 0.0)])
    pattern: str | None = None
    period_mm: float | None = None
    across: tuple[float, float] | None = None
    periods: float | None = None

    @property
    def grown(self) -> bool:
        """Whether the fit's window was grown to hold :data:`MIN_PERIODS` periods."""
        return self.region != self.fit_region

    def regions(self) -> list[list[float]]:
        """The simulated region of each position, the first the window itself."""
        x0, y0, x1, y1 = self.region
        return [[x0 + dx, y0 + dy, x1 + dx, y1 + dy] for dx, dy in self.shifts]

    def describe(self) -> dict:
        """``prediction.window`` of fit.json and predict/metrics.json."""
        x0, y0, x1, y1 = self.region
        rule = ("the fit's window (grown about its centre to hold at least "
                f"{MIN_PERIODS:g} periods of the predicted marks across it), simulated at "
                f"{len(self.shifts)} positions moved across the marks by equal fractions of "
                "their period; each number is the mean over the positions, and its spread "
                "the standard deviation over them" if self.period_mm else
                "the fit's window (no periodic marks: one position)")
        out: dict[str, Any] = {
            "region_mm": list(self.region), "side_mm": [x1 - x0, y1 - y0],
            "fit_window_mm": list(self.fit_region), "grown": self.grown,
            "min_periods": MIN_PERIODS, "marks": self.pattern, "period_mm": self.period_mm,
            "periods": self.periods,
            "across": None if self.across is None else list(self.across),
            "positions": len(self.shifts), "shifts_mm": [list(s) for s in self.shifts],
            "rule": rule}
        out["description"] = _text(out)
        return out


def _across(pattern: str, centre: Sequence[float], marks_centre: Sequence[float],
            direction: Sequence[float]) -> tuple[float, float]:
    if pattern == "circular":
        dx, dy = centre[0] - marks_centre[0], centre[1] - marks_centre[1]
    else:
        dx, dy = float(direction[0]), float(direction[1])
    n = math.hypot(dx, dy)
    return (1.0, 0.0) if n < 1e-12 else (dx / n, dy / n)


def prediction_window(window: Sequence[float], marks: Any, *,
                      phases: int = PHASES) -> PredictionWindow:
    """The window of a prediction from the fit's ``window`` (x0, y0, x1, y1 mm) and the
    predicted cut's ``marks`` (a :class:`~render_inspect.core.marks.ToolMarks`, or None):
    grown about its centre to hold :data:`MIN_PERIODS` periods across the marks, with
    ``phases`` positions moved across them by equal fractions of the period."""
    fit_region = [float(v) for v in window]
    period = None if marks is None else marks.period_mm
    if not period or not math.isfinite(float(period)) or float(period) <= 0:
        return PredictionWindow(list(fit_region), fit_region)
    p = float(period)
    x0, y0, x1, y1 = fit_region
    cx, cy = 0.5 * (x0 + x1), 0.5 * (y0 + y1)
    u = _across(marks.pattern, (cx, cy), marks.center_mm, marks.direction)
    # the marks the window spans: its extent along u over the period
    periods = ((x1 - x0) * abs(u[0]) + (y1 - y0) * abs(u[1])) / p
    grow = max(1.0, MIN_PERIODS / periods)
    hx, hy = 0.5 * (x1 - x0) * grow, 0.5 * (y1 - y0) * grow
    region = fit_region if grow == 1.0 else [cx - hx, cy - hy, cx + hx, cy + hy]
    shifts = [(j / phases * p * u[0], j / phases * p * u[1]) for j in range(int(phases))]
    return PredictionWindow(region, fit_region, shifts, str(marks.pattern), p, u,
                            periods * grow)


def _number(v: Any) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(float(v))


def phase_average(metrics: Sequence[dict]) -> tuple[dict, dict]:
    """The metrics of the positions (``simulate``'s metrics.json, in order) reduced to one:
    the numbers of :data:`WINDOW_GROUPS` averaged over the positions, the rest the first
    position's; and ``{path: standard deviation over the positions}`` of the averaged
    numbers."""
    first = metrics[0]
    out = dict(first)
    spread = {}
    for group in WINDOW_GROUPS:
        g = first.get(group)
        if not isinstance(g, dict):
            continue
        avg = dict(g)
        for k, v in g.items():
            vals = [m.get(group, {}).get(k) for m in metrics]
            if _number(v) and all(_number(x) for x in vals):
                a = np.asarray(vals, dtype=np.float64)
                avg[k] = float(a.mean())
                spread[f"{group}.{k}"] = float(a.std())
        out[group] = avg
    return out, spread


def _text(window: dict) -> str:
    """The prediction's window in words."""
    x0, y0, x1, y1 = window["region_mm"]
    where = (f"{x1 - x0:.4g} x {y1 - y0:.4g} mm at x {x0:.4g}..{x1:.4g}, y {y0:.4g}..{y1:.4g} "
             f"mm")
    if not window.get("period_mm"):
        return f"window {where} (the fit's; no periodic marks)"
    grown = " (the fit's window grown to hold them)" if window.get("grown") else ""
    return (f"window {where}: {window['periods']:.3g} periods of the {window['marks']} marks "
            f"({window['period_mm']:.4g} mm) across it{grown}; each number the mean over "
            f"{window['positions']} positions moved across the marks by 1/"
            f"{window['positions']} period, +- its spread over them")
