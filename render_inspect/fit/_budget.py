"""The fit's evaluation budget (``--max-evaluations``): a hard limit on every evaluation of
the scene at trial values, of which :func:`~render_inspect.fit.solve` keeps
:func:`uncertainty_reserve` out of the search for what follows it (the standard errors'
differences, the misfit profiles, each arm's own estimate).

Below the solver and the modules it calls (the arms' estimates raise and catch
:class:`BudgetExhausted` too), so that none of them imports the solver for it.
"""

from __future__ import annotations

from typing import Protocol

import numpy as np

from ..core.errors import InputError

__all__ = ["BudgetExhausted", "Budgeted", "budget_message", "uncertainty_reserve",
           "candidates_error", "no_stderr_message", "without_standard_errors"]


class BudgetExhausted(Exception):
    """The fit reached its largest number of evaluations."""


class Budgeted(Protocol):
    """What :func:`budget_message` reads of the fit's
    :class:`~render_inspect.fit.Evaluator`."""

    max_evaluations: int
    limit: int

    @property
    def count(self) -> int: ...


def uncertainty_reserve(n: int, *, profile_points: int = 0, extra: int = 0) -> int:
    """The evaluations :func:`~render_inspect.fit.solve` keeps out of the search for what
    follows it, of ``n`` free keys: the forward-difference Jacobian at the result (``n``),
    the central differences of the standard errors (``4 n``: two spans either side), the
    misfit profiles (``2 profile_points n``) and ``extra`` (the caller's: each arm's own
    estimate)."""
    return 5 * n + 2 * int(profile_points) * n + int(extra)


def budget_message(evaluator: Budgeted) -> str:
    """The status message of a search stopped by ``--max-evaluations``."""
    kept = evaluator.max_evaluations - evaluator.limit
    return (f"stopped by --max-evaluations {evaluator.max_evaluations}: the search made "
            f"{evaluator.count} evaluations, all it may make"
            + ("" if kept <= 0 else f" ({kept} are kept for the standard errors)")
            + "; the best point is reported")


def candidates_error(evaluator: Budgeted, candidates: int, kept: int) -> InputError:
    """The error of a budget too small for the search's ``candidates`` start candidates
    (the scene's values among them) besides the ``kept`` evaluations of the standard
    errors."""
    return InputError(
        f"--max-evaluations must leave the search at least the {candidates} start "
        f"candidates besides the {kept} evaluations kept for the standard errors: raise it "
        f"to {candidates + kept} or lower --global, received {evaluator.max_evaluations}")


def no_stderr_message(evaluator: Budgeted) -> str:
    """The status message of a fit whose standard errors' differences did not fit in what
    the search left of ``--max-evaluations``."""
    return (f"--max-evaluations {evaluator.max_evaluations} left too few evaluations for the "
            f"standard errors' differences after the search ({evaluator.count} made): no "
            f"standard errors; raise it")


def without_standard_errors(n: int, ident: dict) -> tuple[np.ndarray, np.ndarray, np.ndarray,
                                                          dict]:
    """What a fit of ``n`` free keys without standard errors (``--max-evaluations`` left too
    few for their differences) reports: (covariance, standard errors, correlation: NaN, NaN,
    the identity; the identifiability ``ident`` emptied, saying why)."""
    ident = {"directions": [], "undetermined": [], "hidden": [],
             "threshold_relative": ident.get("threshold_relative"),
             "not_computed": "no standard errors (--max-evaluations)"}
    return np.full((n, n), np.nan), np.full(n, np.nan), np.eye(n), ident
