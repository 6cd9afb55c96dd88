"""The optimiser: a bounded least-squares fit (scipy's trust-region reflective
``least_squares``) of the free parameters, with the forward model's evaluations run in
batches (the Jacobian's columns, an optional Latin-hypercube start, the misfit profiles) on
Dask when a client is given, cached by the hash of each evaluation's task.

Parameters are fitted in scaled units ``u = 1 + (x - start) / scale`` (``scale``: 10 % of
the start value; :class:`~render_inspect.fit.FreeParameter`), so one step size and one
tolerance suit them all.  The Jacobian is taken by forward differences of ``fd_step``
scaled units (1 % of the value by default): large enough that the forward model's
quantisation (the camera's bits, the path's sampling) and the random parts of the machine
that are redrawn when the timing of the cut changes do not swamp it.

Uncertainty: the formal covariance ``s^2 (J^T J)^-1`` at the solution, ``s^2`` the residual
variance per degree of freedom (residuals taken as independent: the standard errors are a
lower bound when the map's residuals are correlated).  Pairs of parameters whose
correlation exceeds :data:`UNRESOLVED` cannot be told apart by the data.
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import least_squares

from ..core.errors import InputError, RenderInspectError
from ..core.progress import task as progress_task
from ._cache import EvaluationCache, task_hash
from ._features import (Target, predict_features, realisation_shifts, residual_vector,
                        robust_weights, soft_l1)

__all__ = ["Evaluation", "Evaluator", "FitResult", "solve", "UNRESOLVED", "BudgetExhausted"]

log = logging.getLogger("render_inspect")

#: |correlation| above which two parameters are reported as not told apart
UNRESOLVED = 0.95
#: residual entries of an evaluation the forward model refused (a value it cannot cut)
FAILED_RESIDUAL = 1e3  # not a unit conversion


class BudgetExhausted(Exception):
    """The fit reached its largest number of evaluations."""


@dataclass
class Evaluation:
    """One run of the forward model at parameter ``values``."""

    values: np.ndarray
    key: str
    height: np.ndarray | None
    d: np.ndarray               # normalised residuals
    a: np.ndarray               # each entry's term weight
    cost: float                 # sum a^2 soft_l1(d)
    terms: dict
    seconds: float
    cached: bool
    meta: dict = field(default_factory=dict)
    error: str | None = None


class Evaluator:
    """Evaluate parameter vectors: a task per vector (``make_task(values) -> dict``), the
    predicted map by ``compute(task) -> (height, meta)`` (in this process, or on a Dask
    ``client``), the cache, the features and the residual vector.

    Parameters
    ----------
    params : list of FreeParameter
    target : Target
    make_task, compute : callables
        ``compute`` must be a module-level function (it is sent to Dask workers).
    cache : EvaluationCache
    client : distributed.Client, optional
    max_evaluations : int
        Distinct evaluations allowed (cached ones count).
    quiet : callable, optional
        Context manager wrapped around each evaluation run in this process (the pipeline
        silences the forward model's own progress bars with it).
    """

    def __init__(self, params, target: Target, make_task, compute, cache: EvaluationCache, *,
                 client=None, max_evaluations: int = 150, quiet=None):
        self.params = params
        self.target = target
        self.make_task = make_task
        self.compute = compute
        self.cache = cache
        self.client = client
        self.max_evaluations = int(max_evaluations)
        self.quiet = quiet
        self.seen: dict = {}          # key -> Evaluation
        self.history: list = []       # Evaluations in the order made
        self.best: Evaluation | None = None
        self.step = None              # progress task
        self.seconds = 0.0            # forward-model seconds (not cached)

    @property
    def count(self) -> int:
        return len(self.seen)

    def _values(self, u) -> np.ndarray:
        return np.array([p.from_unit(float(v)) for p, v in zip(self.params, u)])

    def evaluate_units(self, us) -> list[Evaluation]:
        return self.evaluate([self._values(u) for u in us])

    def evaluate(self, xs, *, budget: bool = True) -> list[Evaluation]:
        tasks, keys = [], []
        for x in xs:
            t = self.make_task({p.key: float(v) for p, v in zip(self.params, x)})
            tasks.append(t)
            keys.append(task_hash(t))
        todo = {}
        for x, t, k in zip(xs, tasks, keys):
            if k in self.seen or k in todo:
                continue
            hit = self.cache.get(k)
            if hit is not None:
                self._record(x, k, hit[0], hit[1], 0.0, cached=True)
                continue
            todo[k] = (x, t)
        if todo and budget and self.count + len(todo) > self.max_evaluations:
            raise BudgetExhausted()
        if todo:
            self._run(todo)
        return [self.seen[k] for k in keys]

    def _run(self, todo: dict) -> None:
        items = list(todo.items())
        if self.client is None:
            for k, (x, t) in items:
                t0 = time.perf_counter()
                try:
                    if self.quiet is not None:
                        with self.quiet():
                            h, meta = self.compute(t)
                    else:
                        h, meta = self.compute(t)
                    err = None
                except RenderInspectError as e:
                    h, meta, err = None, {}, str(e)
                self._finish(x, k, h, meta, time.perf_counter() - t0, err)
            return
        from distributed import as_completed

        futures = {}
        for k, (x, t) in items:
            fut = self.client.submit(_timed_compute, self.compute, t,
                                     key=f"render-inspect-fit-{k[:16]}", pure=False)
            futures[fut] = (k, x)
        # the client need not be this process's default one (the batch helpers make theirs
        # with set_as_default=False): the futures are awaited on its own event loop
        for fut in as_completed(list(futures), loop=self.client.loop):
            k, x = futures[fut]
            h, meta, dt, err = fut.result()
            self._finish(x, k, h, meta, dt, err)

    def _finish(self, x, k, h, meta, dt, err) -> None:
        self.seconds += dt
        if err is None:
            h = self.cache.put(k, h, meta)
        self._record(x, k, h, meta, dt, cached=False, error=err)

    def _record(self, x, k, h, meta, dt, *, cached: bool, error: str | None = None) -> None:
        if error is None:
            try:
                pred = predict_features(h, self.target, x)
                d, a, terms = residual_vector(pred, self.target)
            except InputError as e:  # a predicted map with too few valid points
                error, d, a, terms = str(e), None, None, {}
        if error is not None:
            a = self._weights()
            d = np.full(a.size, FAILED_RESIDUAL)
            terms = {}
            log.warning("the forward model failed at %s: %s", self._text(x), error)
        cost = float(np.sum(a * a * soft_l1(d)))
        ev = Evaluation(np.asarray(x, dtype=np.float64), k, h, d, a, cost, terms, dt,
                        cached, dict(meta or {}), error)
        self.seen[k] = ev
        self.history.append(ev)
        if self.step is not None:
            self.step.advance(1)
        if error is None and (self.best is None or ev.cost < self.best.cost):
            self.best = ev
            log.info("evaluation %d: misfit %.5g (best so far) %s%s", self.count, ev.cost,
                     self._text(x), " [cached]" if cached else "")
        else:
            log.debug("evaluation %d: misfit %.5g %s", self.count, ev.cost, self._text(x))

    def _weights(self) -> np.ndarray:
        for ev in self.history:
            if ev.error is None:
                return ev.a
        return np.ones(1)

    def _text(self, x) -> str:
        return ", ".join(f"{p.key}={v:.6g}" for p, v in zip(self.params, x))


def _timed_compute(compute, task):
    """Run on a worker: (height, meta, seconds, error text or None)."""
    t0 = time.perf_counter()
    try:
        h, meta = compute(task)
        return h, meta, time.perf_counter() - t0, None
    except RenderInspectError as e:
        return None, {}, time.perf_counter() - t0, str(e)


@dataclass
class FitResult:
    """What :func:`solve` found."""

    params: list
    values: np.ndarray
    stderr: np.ndarray
    covariance: np.ndarray
    correlation: np.ndarray
    best: Evaluation
    start: Evaluation
    evaluations: int
    cache_hits: int
    status: str
    message: str
    global_search: dict | None
    profiles: dict
    unresolved: list
    seconds: float
    model_seconds: float
    history: list
    stderr_formal: np.ndarray | None = None      # from the residuals alone
    stderr_realisations: np.ndarray | None = None  # from the random parts' realisations
    realisations: int = 0


def _unit_bounds(params):
    lo = np.array([p.to_unit(p.lower) for p in params])
    hi = np.array([p.to_unit(p.upper) for p in params])
    return lo, hi


def _jacobian(ev: Evaluator, u, lo, hi, steps, sw):
    """Forward-difference Jacobian in scaled units; the columns' points run as one batch.

    ``steps`` (per parameter, scaled units; updated in place and kept from one Jacobian to
    the next): a column whose step changes the residual vector by more than the misfit
    itself (and more than 1) is taken again with a step ten times smaller (at most twice).
    A sharply determined parameter (the feed, fixed by the marks' frequency to a small
    fraction of a per cent) needs a smaller step than a weakly determined one, whose effect
    must rise above the forward model's noise (the simulation grid's aliasing of the marks,
    the random parts of the machine)."""
    base = ev.evaluate_units([u])[0]
    cols = [None] * u.size
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
    linearised least-squares step ``-pinv(J) weights shift``.  None without realisations."""
    pred = predict_features(best.height, target, best.values)
    shifts = realisation_shifts(pred, target)
    if shifts.shape[0] < 2 or shifts.shape[1] != j_units.shape[0]:
        return None
    du = -(np.linalg.pinv(j_units) @ (weights[None, :] * shifts).T).T
    dx = du * scales[None, :]
    return np.atleast_2d(np.cov(dx, rowvar=False, ddof=1))


def solve(params, evaluator: Evaluator, *, global_points: int = 0, seed: int = 0,
          fd_step: float = 0.1, xtol: float = 1e-3, ftol: float = 1e-3,
          profile_points: int = 5, max_rounds: int = 8) -> FitResult:
    """Fit ``params`` (list of FreeParameter) with ``evaluator``.

    Parameters
    ----------
    global_points : int
        Latin-hypercube points over the bounds (all finite) evaluated first as one batch; the
        best of them and the start begins the local fit.
    seed : int
        Seed of the Latin hypercube.
    fd_step : float
        Forward-difference step in scaled units (0.1 = 1 % of the start value).
    xtol, ftol : float
        ``least_squares`` tolerances (scaled units; relative misfit change).
    profile_points : int
        Points either side of the solution along each parameter for the misfit profiles
        (0: none).
    max_rounds : int
        Trust-region rounds at most (each starts afresh from the best point).
    """
    t_all = time.perf_counter()
    n = len(params)
    lo, hi = _unit_bounds(params)
    u0 = np.ones(n)
    # least_squares needs a start strictly inside the bounds
    inside = 1e-6 * np.maximum(hi - lo, 1e-12)  # not a unit conversion
    u0 = np.clip(u0, lo + inside, hi - inside)
    budget = evaluator.max_evaluations
    with progress_task(f"fit: up to {budget} evaluations", total=budget) as step:
        evaluator.step = step
        start = evaluator.evaluate_units([u0])[0]
        if start.error is not None:
            raise InputError(f"the forward model fails at the scene's values: {start.error}")
        glob = None
        if global_points:
            glob = _global_start(params, evaluator, global_points, seed, lo, hi)
            best_g = min(glob["evaluations"], key=lambda e: e.cost)
            if best_g.cost < start.cost:
                u0 = np.clip(np.array([p.to_unit(v) for p, v in zip(params, best_g.values)]),
                             lo + inside, hi - inside)
            glob = {"points": global_points, "seed": seed, "best_cost": best_g.cost,
                    "best": {p.key: float(v) for p, v in zip(params, best_g.values)},
                    "used": bool(best_g.cost < start.cost)}
        status, message = "converged", ""

        # iteratively re-weighted least squares: within a round the robust weights are
        # held at their values at the round's start, and the round minimises
        # sum (sqrt(w) a d)^2 by a trust-region method
        sw = robust_weights(start.d)

        def fun(u):
            e = evaluator.evaluate_units([u])[0]
            return sw * e.a * e.d

        steps = np.full(n, float(fd_step))

        def jac(u):
            return _jacobian(evaluator, np.asarray(u, dtype=np.float64), lo, hi, steps, sw)

        # trust-region rounds: a round ends when its region has shrunk to nothing (the
        # misfit is not smooth at the scale of the forward model's noise); the next starts
        # afresh from the best point, until a round gains less than ``ftol``
        rounds = 0
        try:
            while True:
                rounds += 1
                before = evaluator.best.cost
                if rounds == 1 and glob is not None and glob["used"]:
                    sw[:] = robust_weights(evaluator.best.d)
                sol = least_squares(fun, u0, jac=jac, bounds=(lo, hi), method="trf",
                                    x_scale="jac", xtol=xtol, ftol=ftol, gtol=1e-10,
                                    max_nfev=10 * budget)
                message = str(sol.message)
                status = "converged" if sol.status > 0 else "stopped"
                gain = (before - evaluator.best.cost) / max(before, 1e-300)
                if gain < ftol or rounds >= max_rounds:
                    break
                u0 = np.clip(np.array([p.to_unit(v)
                                       for p, v in zip(params, evaluator.best.values)]),
                             lo + inside, hi - inside)
                sw[:] = robust_weights(evaluator.best.d)
                log.info("trust-region round %d gained %.3g of the misfit; starting again from "
                         "the best point", rounds, gain)
        except BudgetExhausted:
            status, message = "budget", (f"stopped after {evaluator.count} evaluations "
                                         f"(--max-evaluations); the best point is reported")
        message = f"{message} ({rounds} trust-region round{'s' if rounds > 1 else ''})"
        best = evaluator.best
        u_best = np.array([p.to_unit(v) for p, v in zip(params, best.values)])
        sw = robust_weights(best.d)
        try:
            j = _jacobian(evaluator, u_best, lo, hi, steps, sw)
        except BudgetExhausted:
            evaluator.max_evaluations += 3 * n + 1  # the uncertainty needs its Jacobian
            j = _jacobian(evaluator, u_best, lo, hi, steps, sw)
        scales = np.array([p.scale for p in params])
        cov, stderr, corr = _covariance(j, sw * best.a * best.d, scales)
        stderr_formal, stderr_real = stderr, None
        cov_real = _realisation_covariance(j, sw * best.a, best, evaluator.target, scales)
        if cov_real is not None:
            stderr_real = np.sqrt(np.maximum(np.diag(cov_real), 0.0))
            cov = cov + cov_real
            stderr = np.sqrt(np.maximum(np.diag(cov), 0.0))
            corr = _correlation(cov, stderr)
    evaluator.step = None
    profiles = {}
    if profile_points:
        profiles = _profiles(params, evaluator, best, stderr, profile_points)
    unresolved = [[params[a].key, params[b].key, float(corr[a, b])]
                  for a in range(n) for b in range(a + 1, n) if abs(corr[a, b]) > UNRESOLVED]
    return FitResult(params, best.values.copy(), stderr, cov, corr, best, start,
                     evaluator.count, evaluator.cache.hits, status, message, glob, profiles,
                     unresolved, time.perf_counter() - t_all, evaluator.seconds,
                     list(evaluator.history), stderr_formal, stderr_real,
                     len(evaluator.target.draws))


def _global_start(params, evaluator, points, seed, lo, hi):
    from scipy.stats import qmc

    if not (np.all(np.isfinite(lo)) and np.all(np.isfinite(hi))) or any(
            p.upper - p.lower > 1e8 for p in params):
        raise InputError("--global needs finite bounds on every free key: give --bounds "
                         "KEY=A,B for those the schema leaves open")
    sample = qmc.LatinHypercube(d=len(params), seed=seed).random(points)
    us = lo + sample * (hi - lo)
    with progress_task(f"fit: {points} Latin-hypercube points", total=points):
        evs = evaluator.evaluate_units(list(us))
    return {"evaluations": evs}


def _profiles(params, evaluator, best, stderr, k):
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
    out = {p.key: {"values": [], "misfit": [], "terms": []} for p in params}
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
