"""The optimiser: a bounded least-squares fit (scipy's trust-region reflective
``least_squares``) of the free parameters, with the forward model's evaluations run in
batches (the start candidates, the Jacobian's columns, the probes, the misfit profiles) on
Dask when a client is given, cached by the hash of each evaluation's task.

Parameters are fitted in scaled units ``u = 1 + (x - start) / scale`` (``scale``: 10 % of
the start value; :class:`~render_inspect.fit.FreeParameter`), so one step size and one
tolerance suit them all.  The Jacobian is taken by forward differences of ``fd_step``
scaled units (1 % of the value by default): large enough that the forward model's
quantisation (the camera's bits, the path's sampling) and the random parts of the machine
that are redrawn when the timing of the cut changes do not swamp it.

Capture: the local solve starts from the best of the scene's values, the values the
measurement proposes (the feed from the marks' period, the nose radius from their
amplitude) and a scrambled Sobol design over the search box.  ``converged`` is said only
when the misfit probed either side of the result along every parameter is higher and a
second local solve from a start far from the first agrees with it.

Uncertainty: the formal covariance ``s^2 (J^T J)^-1`` at the solution (``s^2`` the residual
variance per degree of freedom; ``J`` by central differences across the misfit's
fine-scale steps, :func:`_smoothed`), plus the spread of the solution over realisations of
the random parts scaled by the Birge ratio (the misfit over the misfit those realisations
alone leave, when above 1: the model's error), plus the distance to the minimum of the
misfit smoothed over the difference steps, plus half the two starts' disagreement.
Combinations of parameters the measurement does not determine are found from the
covariance's eigenvectors (:func:`identifiability`); pairs whose correlation exceeds
:data:`UNRESOLVED` are named too.
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from ..core.errors import InputError
from ..core.lazy import lazy_attr
from ..core.progress import task as progress_task
from ._budget import (BudgetExhausted, budget_message, candidates_error, no_stderr_message,
                      uncertainty_reserve, without_standard_errors)
from ._differences import _jacobian, stderr_differences
from ._evaluator import Evaluation, Evaluator
from ._features import robust_weights
from ._params import FreeParameter
from ._uncertainty import (_correlation, _covariance, _realisation_covariance, identifiability,
                           search_box)
from ._uncertainty import profiles as _profiles
from ._uncertainty import probe as _probe

__all__ = ["Evaluation", "Evaluator", "FitResult", "solve", "UNRESOLVED", "BudgetExhausted"]

#: SciPy, imported on first use (render_inspect.core.lazy): every run imports this module
least_squares = lazy_attr("scipy.optimize", "least_squares")

log = logging.getLogger("render_inspect")

#: |correlation| above which two parameters are reported as not told apart
UNRESOLVED = 0.95


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
    checks: dict = field(default_factory=dict)     # the minimum's probes, the second start
    identifiability: dict = field(default_factory=dict)
    goodness: dict = field(default_factory=dict)   # the misfit against the noise floor
    stderr_solver: np.ndarray | None = None       # the two starts' disagreement
    birge: float = 1.0                            # the model-error scale of the random parts
    stderr_steps: np.ndarray | None = None        # to the smoothed misfit's minimum
    budget: dict = field(default_factory=dict)    # --max-evaluations: the search's share


def _unit_bounds(params):
    lo = np.array([p.to_unit(p.lower) for p in params])
    hi = np.array([p.to_unit(p.upper) for p in params])
    return lo, hi


def _local(params, evaluator, u0, lo, hi, steps, *, xtol, ftol, max_rounds, budget):
    """The local solve from ``u0`` (scaled units): iteratively re-weighted trust-region
    rounds.  Returns (status, message, rounds, best evaluation of this solve)."""
    # iteratively re-weighted least squares: within a round the robust weights are held at
    # their values at the round's start, and the round minimises sum (sqrt(w) a d)^2 by a
    # trust-region method
    first = evaluator.evaluate_units([u0])[0]
    sw = robust_weights(first.d)
    mine = {"best": first}

    def fun(u):
        e = evaluator.evaluate_units([u])[0]
        if e.error is None and e.cost < mine["best"].cost:
            mine["best"] = e
        return sw * e.a * e.d

    def jac(u):
        return _jacobian(evaluator, np.asarray(u, dtype=np.float64), lo, hi, steps, sw)

    inside = 1e-6 * np.maximum(hi - lo, 1e-12)  # not a unit conversion
    rounds, status, message = 0, "stopped", ""
    try:
        while True:
            rounds += 1
            before = mine["best"].cost
            sol = least_squares(fun, u0, jac=jac, bounds=(lo, hi), method="trf",
                                x_scale="jac", xtol=xtol, ftol=ftol, gtol=1e-10,
                                max_nfev=10 * budget)
            message = str(sol.message)
            status = "stopped" if sol.status <= 0 else "local minimum"
            gain = (before - mine["best"].cost) / max(before, 1e-300)
            if gain < ftol or rounds >= max_rounds:
                break
            u0 = np.clip(np.array([p.to_unit(v) for p, v in zip(params, mine["best"].values)]),
                         lo + inside, hi - inside)
            sw[:] = robust_weights(mine["best"].d)
            log.info("trust-region round %d gained %.3g of the misfit; starting again from "
                     "the best point", rounds, gain)
    except BudgetExhausted:
        status, message = "budget", budget_message(evaluator)
    return status, f"{message} ({rounds} trust-region round{'s' if rounds > 1 else ''})", \
        mine["best"]


def _units(params, values):
    return np.array([p.to_unit(v) for p, v in zip(params, values)])


def solve(params: list[FreeParameter], evaluator: Evaluator, *, global_points: int = 0,
          seed: int = 0, fd_step: float = 0.1, xtol: float = 1e-3, ftol: float = 1e-3,
          profile_points: int = 5, max_rounds: int = 8,
          starts: Sequence[dict[str, float]] = (),
          search: dict[str, Sequence[float]] | None = None, verify: bool = True,
          reserve: int = 0) -> FitResult:
    """Fit ``params`` (list of FreeParameter) with ``evaluator``.

    The fit runs in four steps: the candidates (the scene's values, the ``starts`` the
    measurement proposes and ``global_points`` points of a scrambled Sobol design over the
    search box, one batch); the local solve from the best of them; the checks that the
    result is a minimum (the misfit probed either side along each parameter, and a second
    local solve from the best candidate far from the first result, which must agree); and
    the uncertainty (the formal one, the random parts', the disagreement of the two
    starts, scaled by how far the misfit exceeds the noise floor) with the combinations of
    parameters the measurement does not determine.

    Parameters
    ----------
    global_points : int
        Points of the Sobol design (rounded up to a power of 2; 0: none).
    seed : int
        Seed of the Sobol design's scrambling.
    fd_step : float
        Forward-difference step in scaled units (0.1 = 1 % of the start value).
    xtol, ftol : float
        ``least_squares`` tolerances (scaled units; relative misfit change).
    profile_points : int
        Points either side of the solution along each parameter for the misfit profiles
        (0: none).
    max_rounds : int
        Trust-region rounds at most (each starts afresh from the best point).
    starts : list of dict
        Start values proposed by the measurement (key -> value; missing keys at the
        scene's values), e.g. the feed from the marks' period.
    search : dict key -> (lower, upper), optional
        The global phase's box (default: :func:`search_box`).
    verify : bool
        Probe the minimum and solve again from a second start (``converged`` needs both).
    reserve : int
        Evaluations the caller makes after the solve (each arm's own estimate), kept out of
        the search as the standard errors' are (:func:`uncertainty_reserve`).

    ``evaluator.max_evaluations`` is a hard limit on all the evaluations: the search (the
    start, the candidates, the local solves and their checks) may make
    ``max_evaluations - uncertainty_reserve(...)`` of them (at least two), the rest is kept
    for the standard errors, the misfit profiles and ``reserve``.  Where the standard
    errors' differences do not fit in what is left, the standard errors are not given
    (NaN) and the status is ``budget``.

    The result's ``status``: ``converged`` (a minimum: no probe lower and the second start
    agreeing), ``not a minimum`` (a probe found a lower misfit), ``starts disagree``
    (the second start ended elsewhere), ``budget`` (the evaluations ran out), ``stopped``
    (the trust region shrank to nothing before the tolerances were met) or ``unverified``
    (``verify`` off).  ``message`` says why.
    """
    t_all = time.perf_counter()
    n = len(params)
    lo, hi = _unit_bounds(params)
    inside = 1e-6 * np.maximum(hi - lo, 1e-12)  # not a unit conversion
    budget = evaluator.max_evaluations
    kept = uncertainty_reserve(n, profile_points=profile_points, extra=reserve)
    evaluator.limit = max(min(2, budget), budget - kept)
    search_limit = evaluator.limit
    checks: dict = {}
    with progress_task(f"fit: up to {budget} evaluations", total=budget) as step:
        evaluator.step = step
        u_start = np.clip(np.ones(n), lo + inside, hi - inside)
        start = evaluator.evaluate_units([u_start])[0]
        if start.error is not None:
            raise InputError(f"the forward model fails at the scene's values: {start.error}")
        # ---------------------------------------------------------------- candidates
        cands, kinds = [], []
        for s in starts or ():
            vals = [float(np.clip(s.get(p.key, p.start), p.lower, p.upper)) for p in params]
            cands.append(_units(params, vals))
            kinds.append("measured")
        glob = None
        if global_points:
            from scipy.stats import qmc

            slo, shi = search_box(params, search)
            m = int(math.ceil(math.log2(max(global_points, 1))))
            sample = qmc.Sobol(d=n, scramble=True, seed=seed).random_base2(m)
            for row in sample:
                cands.append(_units(params, slo + row * (shi - slo)))
                kinds.append("sobol")
            glob = {"points": int(2 ** m), "design": "scrambled Sobol", "seed": int(seed),
                    "box": {p.key: [float(a), float(b)] for p, a, b in zip(params, slo, shi)}}
        cand_evs = []
        if cands:
            cands = [np.clip(c, lo + inside, hi - inside) for c in cands]
            with progress_task(f"fit: {len(cands)} start candidates", total=len(cands)):
                try:
                    cand_evs = evaluator.evaluate_units(cands)
                except BudgetExhausted:
                    raise candidates_error(evaluator, len(cands) + 1, kept) from None
        pool = [(start.cost, u_start, "scene")] + [
            (e.cost if e.error is None else math.inf, c, k)
            for e, c, k in zip(cand_evs, cands, kinds)]
        pool.sort(key=lambda t: t[0])
        u0 = pool[0][1]
        if glob is not None or starts:
            glob = dict(glob or {}, candidates=len(pool), best_from=pool[0][2],
                        best_cost=float(pool[0][0]),
                        best={p.key: float(p.from_unit(v)) for p, v in zip(params, u0)},
                        used=pool[0][2] != "scene")
        # ---------------------------------------------------------------- local solve
        steps = np.full(n, float(fd_step))
        status, message, first = _local(params, evaluator, u0, lo, hi, steps, xtol=xtol,
                                        ftol=ftol, max_rounds=max_rounds, budget=budget)
        best = evaluator.best
        # ---------------------------------------------------------------- its checks
        second = None
        if verify and status != "budget":
            try:
                sw = robust_weights(best.d)
                j = _jacobian(evaluator, _units(params, best.values), lo, hi, steps, sw)
                _, sig_phys, _ = _covariance(j, sw * best.a * best.d,
                                             np.array([p.scale for p in params]))
                sig_u = sig_phys / np.array([p.scale for p in params])
                lower, made = _probe(params, evaluator, best, sig_u, lo, hi, fd_step)
                for _ in range(3):
                    if not lower:
                        break
                    # again from the lowest probe
                    u1 = np.clip(_units(params, min(lower, key=lambda e: e.cost).values),
                                 lo + inside, hi - inside)
                    status, message, first = _local(params, evaluator, u1, lo, hi, steps,
                                                    xtol=xtol, ftol=ftol,
                                                    max_rounds=max_rounds, budget=budget)
                    best = evaluator.best
                    lower, made2 = _probe(params, evaluator, best, sig_u, lo, hi, fd_step)
                    made += made2
                first = best
                checks["probes"] = made
                checks["probe_lower"] = [{p.key: float(v) for p, v in zip(params, e.values)}
                                         for e in lower]
                # the second start: the result moved by 0.3 scale (3 % of the start
                # value) along every parameter, signs alternating
                ub = _units(params, best.values)
                shift = 0.3 * np.where(np.arange(n) % 2 == 0, 1.0, -1.0)
                shift = np.where((ub + shift > hi) | (ub + shift < lo), -shift, shift)
                u2 = np.clip(ub + shift, lo + inside, hi - inside)
                # (with the difference steps the first solve refined)
                s2, m2, second = _local(params, evaluator, u2, lo, hi, steps.copy(),
                                        xtol=xtol, ftol=ftol, max_rounds=max_rounds,
                                        budget=budget)
                checks["second_start"] = {p.key: float(p.from_unit(v))
                                          for p, v in zip(params, u2)}
                checks["second_result"] = {p.key: float(v)
                                           for p, v in zip(params, second.values)}
                checks["second_misfit"] = float(second.cost)
                checks["first_misfit"] = float(first.cost)
                best = evaluator.best
                if lower:
                    status = "not a minimum"
                    message = ("the misfit is lower beside the result along " + ", ".join(
                        sorted({params[int(np.argmax(np.abs(_units(params, e.values) - ub)))].key
                                for e in lower})) + ": the solve stopped on a slope")
                else:
                    status = "pending"
            except BudgetExhausted:
                status = "budget"
                message = budget_message(evaluator).replace(
                    "; the best point", " while checking the minimum; the best point")
        best = evaluator.best
        u_best = _units(params, best.values)
        sw = robust_weights(best.d)
        scales = np.array([p.scale for p in params])
        # the differences of the standard errors come out of what the search left of
        # --max-evaluations (never past it)
        evaluator.limit = evaluator.max_evaluations
        # the covariance from central differences over the solver's step and over fd_step,
        # whichever is the less steep (across the misfit's fine-scale steps), and the
        # distance to the minimum of the misfit smoothed over them (_smoothed)
        j_found, smooth = stderr_differences(evaluator, u_best, lo, hi, steps, fd_step, sw)
        no_stderr = j_found is None
        if no_stderr:
            # --max-evaluations left too few evaluations for the differences: no
            # standard errors (NaN), and the status says why
            status, message = "budget", no_stderr_message(evaluator)
        # (without differences a stand-in: the numbers below are dropped)
        j = np.ones((best.d.size, n)) if j_found is None else j_found
        stderr_steps = None
        j_local = j  # one step per key: which combinations the measurement leaves free
        if smooth is not None:
            j, steps_u = smooth
            stderr_steps = np.abs(steps_u) * scales
        cov, stderr, corr = _covariance(j, sw * best.a * best.d, scales)
        stderr_formal, stderr_real = stderr, None
        cov_real, floor_ss = _realisation_covariance(j, sw * best.a, best, evaluator.target,
                                                     scales)
        rss = float(np.sum((sw * best.a * best.d) ** 2))
        birge = 1.0
        goodness = {"misfit_weighted_ss": rss, "noise_floor_ss": floor_ss}
        if cov_real is not None:
            birge = max(1.0, rss / max(floor_ss, 1e-300))
            stderr_real = np.sqrt(np.maximum(np.diag(cov_real), 0.0))
            cov = cov + birge * cov_real
            goodness["ratio"] = rss / max(floor_ss, 1e-300)
        if stderr_steps is not None:
            # one displacement, along the combinations the measurement determines: its
            # outer product (the keys' standard errors take its square, their correlations
            # its direction)
            shift = steps_u * scales
            cov = cov + np.outer(shift, shift)
        # the second start's disagreement is the solver's own uncertainty
        stderr_model = np.sqrt(np.maximum(np.diag(cov), 0.0))
        stderr_solver = None
        same = False
        if second is not None:
            other = second if second is not best else first
            diff = np.abs(other.values - best.values)
            gap = (other.cost - best.cost) / max(best.cost, 1e-300)
            # the second start in the same minimum (the same values within two standard
            # errors or ten times the solver's tolerance, or a misfit as low): its distance
            # is the solver's own precision
            tol = np.maximum(2 * stderr_model, 10 * xtol * scales)
            agree = bool(np.all(diff <= tol))
            same = agree or gap <= 0.01
            if same:
                stderr_solver = diff / 2.0
                cov = cov + np.diag(stderr_solver ** 2)
        stderr = np.sqrt(np.maximum(np.diag(cov), 0.0))
        corr = _correlation(cov, stderr)
        if status == "pending":
            worst = int(np.argmax(diff / np.maximum(stderr_model, 1e-300)))
            if agree:
                status, message = "converged", (
                    "a minimum: the misfit is higher on both sides along every parameter, "
                    "and a second start ended at the same values")
            elif best is second:
                status, message = "starts disagree", (
                    f"a second start found a lower misfit ({100 * gap:.2g} % lower) at "
                    f"{params[worst].key} = {best.values[worst]:.6g} (the first solve "
                    f"ended at {other.values[worst]:.6g}); the lower one is reported")
            elif same:
                status, message = "starts disagree", (
                    f"a second start ended at {params[worst].key} = "
                    f"{other.values[worst]:.6g} with as low a misfit (the reported "
                    f"{best.values[worst]:.6g}): the misfit is flat there; the spread "
                    f"enters the standard errors")
            else:
                status, message = "converged", (
                    f"a minimum: the misfit is higher on both sides along every parameter; "
                    f"a second start fell into another minimum {100 * gap:.2g} % higher "
                    f"({params[worst].key} = {other.values[worst]:.6g}), so the standard "
                    f"errors leave out the solver's own precision"
                    + ("" if stderr_steps is None else
                       " (they take in the distance to the minimum of the misfit smoothed "
                       "over the difference steps)"))
        elif status in ("local minimum", "stopped") and second is None:
            status, message = "unverified", f"{message}; the minimum was not checked"
    evaluator.step = None
    # a combination left free shows as a singular information matrix in the Jacobian of
    # the solver's own steps; the smoothed columns, each over the span that suits its key,
    # would blur an exact null direction into a merely weak one
    ident = identifiability(params, best.values, cov,
                            (j_local / scales[None, :]).T @ (j_local / scales[None, :]))
    if no_stderr:
        cov, stderr, corr, ident = without_standard_errors(n, ident)
        stderr_formal, stderr_real, stderr_solver, stderr_steps = stderr, None, None, None
    profiles = {}
    if profile_points:
        try:
            profiles = _profiles(params, evaluator, best, stderr, profile_points)
        except BudgetExhausted:
            log.warning("the misfit profiles were not computed: --max-evaluations %d was "
                        "reached", evaluator.max_evaluations)
    unresolved = [[params[a].key, params[b].key, float(corr[a, b])]
                  for a in range(n) for b in range(a + 1, n) if abs(corr[a, b]) > UNRESOLVED]
    checks["status_reason"] = message
    return FitResult(params, best.values.copy(), stderr, cov, corr, best, start,
                     evaluator.count, evaluator.cache.hits, status, message, glob, profiles,
                     unresolved, time.perf_counter() - t_all, evaluator.seconds,
                     list(evaluator.history), stderr_formal, stderr_real,
                     len(evaluator.target.draws), checks, ident, goodness, stderr_solver,
                     birge, stderr_steps,
                     {"max_evaluations": int(budget), "search": int(search_limit),
                      "kept_for_standard_errors": int(budget - search_limit)})
