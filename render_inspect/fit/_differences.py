"""The fit's finite differences: the Jacobian the local solve refines its steps with
(:func:`_jacobian`) and the smoothed central differences its standard errors are taken
from (:func:`_smoothed`), both within what the search left of ``--max-evaluations``
(:func:`stderr_differences`).  ``ev`` / ``evaluator``: the fit's
:class:`~render_inspect.fit.Evaluator`."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from ._budget import BudgetExhausted
from ._uncertainty import SINGULAR


def _jacobian(ev, u, lo, hi, steps, sw):
    """Forward-difference Jacobian in scaled units; the columns' points run as one batch.

    ``steps`` (per parameter, scaled units; updated in place and kept from one Jacobian to
    the next): a column whose step changes the residual vector by more than the misfit
    itself (and more than 1) is taken again with a step ten times smaller (at most twice).
    A sharply determined parameter (the feed, fixed by the marks' frequency to a small
    fraction of a per cent) needs a smaller step than a weakly determined one, whose effect
    must rise above the forward model's noise (the simulation grid's aliasing of the marks,
    the random parts of the machine)."""
    base = ev.evaluate_units([u])[0]
    cols: list = [None] * u.size
    todo = list(range(u.size))
    for _ in range(3):
        pts, used = [], []
        for i in todo:
            s = steps[i] if u[i] + steps[i] <= hi[i] else -steps[i]
            if u[i] + s < lo[i]:
                s = (hi[i] - u[i]) if hi[i] - u[i] > u[i] - lo[i] else (lo[i] - u[i])
            v = u.copy()
            v[i] += s
            pts.append(v)
            used.append(s)
        evs = ev.evaluate_units(pts)
        again = []
        for i, s, e in zip(todo, used, evs):
            cols[i] = sw * (e.a * e.d - base.a * base.d) / s
            change = e.a * e.d - base.a * base.d
            if e.error is None and float(change @ change) > max(base.cost, 1.0):
                again.append(i)
                steps[i] = steps[i] / 10.0
        todo = again
        if not todo:
            break
    return np.column_stack(cols)


def _smoothed(evaluator, u, lo, hi, spans, sw):
    """The Jacobian the covariance is taken from, and the minimum of the misfit smoothed
    over the difference spans.

    The misfit of a sharply determined parameter can have fine-scale steps: the feed's
    harmonic features are read from the spectrum's discrete frequency cells, so that as the
    predicted marks' frequency moves the cells of the fundamental's annulus and the bin of
    its peak change by whole cells, and the misfit jumps by more than itself over a few
    hundredths of a per cent of the feed.  The solver stops beside such a step, and a
    forward difference of the solver's (refined) step taken across it is a slope several
    times steeper than the trend along which the measurement's noise moves the minimum:
    the formal standard error comes out far too small.

    Each column is therefore a central difference, over each of ``spans[i]`` (scaled
    units) either side, of which the one that changes the residuals least is kept (on a
    smooth misfit they agree; a span across a step is the steeper).  The weighted
    residuals at those 2n points, averaged, are the residual of the misfit smoothed over
    the spans (a smooth residual's mean over +-h is its value at the centre, to second
    order); the Gauss-Newton step from that mean, ``-pinv(J) mean``, is how far the
    smoothed misfit's minimum lies from the reported one: the fine-scale steps' share of
    the error, which no second start measures.

    Returns (J (m, n) or None where a parameter has no central pair inside the bounds or
    an evaluation failed, the step in scaled units or None, the spans used)."""
    n = u.size
    pts, where = [], []
    for i in range(n):
        for h in sorted({float(v) for v in spans[i]}):
            if u[i] - h < lo[i] or u[i] + h > hi[i] or h <= 0:
                continue
            for sgn in (1.0, -1.0):
                v = u.copy()
                v[i] += sgn * h
                pts.append(evaluator._values(v))
                where.append((i, h, sgn))
    evs = evaluator.evaluate(pts, budget=False) if pts else []
    found: dict = {}
    for (i, h, sgn), e in zip(where, evs):
        found.setdefault((i, h), {})[sgn] = e
    cols, means, used = [], [], []
    for i in range(n):
        best = None
        for (k, h), pair in found.items():
            if k != i or len(pair) != 2 or any(e.error is not None for e in pair.values()):
                continue
            rp = sw * pair[1.0].a * pair[1.0].d
            rm = sw * pair[-1.0].a * pair[-1.0].d
            col = (rp - rm) / (2 * h)
            if best is None or float(col @ col) < float(best[0] @ best[0]):
                best = (col, rp, rm, h)
        if best is None:
            return None, None, None
        cols.append(best[0])
        means += [best[1], best[2]]
        used.append(best[3])
    j = np.column_stack(cols)
    # only along the combinations the measurement determines: a direction it leaves free
    # (a singular value below sqrt(SINGULAR) of the largest, as identifiability() judges
    # the information matrix) has no minimum to move to
    step = -(np.linalg.pinv(j, rcond=math.sqrt(SINGULAR)) @ np.mean(means, axis=0))
    return j, step, np.array(used)


def stderr_differences(evaluator: Any, u: np.ndarray, lo: np.ndarray, hi: np.ndarray,
                       steps: np.ndarray, fd_step: float, sw: np.ndarray
                       ) -> tuple[np.ndarray | None, tuple[np.ndarray, np.ndarray] | None]:
    """The differences the standard errors are taken from at the result ``u`` (scaled
    units), out of what the search left of ``--max-evaluations`` (never past it): the
    forward-difference Jacobian over the solver's ``steps`` (:func:`_jacobian`), and the
    central differences over the solver's step and over ``fd_step``, whichever is the less
    steep, with the step to the minimum of the misfit smoothed over them
    (:func:`_smoothed`).

    Returns (the Jacobian, or None where the budget left too few evaluations for the
    differences; (the smoothed Jacobian, its step in scaled units), or None where a key has
    no central pair inside the bounds, an evaluation failed or the budget ran out)."""
    try:
        j = _jacobian(evaluator, u, lo, hi, steps, sw)
    except BudgetExhausted:
        return None, None
    try:
        j_smooth, step, _ = _smoothed(evaluator, u, lo, hi,
                                      [(steps[i], float(fd_step)) for i in range(u.size)], sw)
    except BudgetExhausted:
        return None, None
    return j, (None if j_smooth is None or step is None else (j_smooth, step))
