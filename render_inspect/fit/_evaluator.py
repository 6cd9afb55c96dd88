"""The fit's evaluations: :class:`Evaluator` runs the forward model at parameter vectors
(in this process or on Dask), caches each by the hash of its task, turns it into features
and the residual vector (:class:`Evaluation`), and counts them against
``--max-evaluations`` (:mod:`._budget`)."""

from __future__ import annotations

import contextlib
import logging
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field

import numpy as np

from ..core.errors import InputError
from ..core.progress import Task
from ._budget import BudgetExhausted
from ._cache import EvaluationCache, task_hash
from ._dispatch import features as predict_features
from ._dispatch import residuals as residual_vector
from ._features import Target, soft_l1
from ._local import _timed_compute, run_local

__all__ = ["Evaluation", "Evaluator", "FAILED_RESIDUAL"]

log = logging.getLogger("render_inspect")

#: residual entries of an evaluation the forward model refused (a value it cannot cut)
FAILED_RESIDUAL = 1e3  # not a unit conversion


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
        Distinct evaluations allowed (cached ones count): a hard limit, which no evaluation
        passes (``evaluate`` raises :class:`BudgetExhausted` instead).  ``limit`` (default
        the same) is the current phase's own limit: :func:`~render_inspect.fit.solve` lowers it
        for the search, keeping :func:`~._budget.uncertainty_reserve` evaluations for the
        standard errors.
    quiet : callable, optional
        Context manager wrapped around each evaluation run in this process (the pipeline
        silences the forward model's own progress bars with it).
    threads : int
        Evaluations of one batch run at once in this process (threads; without a
        ``client``).  ``compute`` must then be safe to run in several threads at once, and
        give each task the same result as when run alone.
    """

    def __init__(self, params, target: Target, make_task, compute, cache: EvaluationCache, *,
                 client=None, max_evaluations: int = 150, quiet=None, threads: int = 1):
        self.params = params
        self.target = target
        self.make_task = make_task
        self.compute = compute
        self.cache = cache
        self.client = client
        self.max_evaluations = int(max_evaluations)
        self.limit = self.max_evaluations  # the current phase's (the search's) limit
        self.quiet = quiet
        self.threads = max(1, int(threads))
        self.seen: dict = {}          # key -> Evaluation
        self.history: list = []       # Evaluations in the order made
        # (None until the first evaluation, which every solve makes before reading it)
        self.best: Evaluation = None  # type: ignore[assignment]
        self.step: Task | None = None  # progress task
        self.seconds = 0.0            # forward-model seconds (not cached)

    @property
    def count(self) -> int:
        return len(self.seen)

    def _values(self, u) -> np.ndarray:
        return np.array([p.from_unit(float(v)) for p, v in zip(self.params, u)])

    def evaluate_units(self, us: Iterable[Sequence[float] | np.ndarray]) -> list[Evaluation]:
        return self.evaluate([self._values(u) for u in us])

    def evaluate(self, xs: Sequence[Sequence[float] | np.ndarray], *,
                 budget: bool = True) -> list[Evaluation]:
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
        # ``budget``: within the current phase's limit (the search's); every evaluation,
        # the uncertainty's too, within max_evaluations
        cap = min(self.limit, self.max_evaluations) if budget else self.max_evaluations
        if todo and self.count + len(todo) > cap:
            raise BudgetExhausted()
        if todo:
            self._run(todo)
        return [self.seen[k] for k in keys]

    def _run(self, todo: dict) -> None:
        items = list(todo.items())
        if self.client is None:
            tasks = [t for _, (_, t) in items]
            with self.quiet() if self.quiet is not None else contextlib.nullcontext():
                for (h, meta, dt, err), (k, (x, _)) in zip(
                        run_local(self.compute, tasks, self.threads), items):
                    self._finish(x, k, h, meta, dt, err)
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
                error, terms = str(e), {}  # (d and a: a failed evaluation's, below)
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
