"""Nelder–Mead simplex search with random restarts (bounded, scipy).

Nelder, J. A., Mead, R. (1965). A simplex method for function minimization. The Computer Journal
7(4), 308-313. doi:10.1093/comjnl/7.4.308 (the paper's reference [52] only *uses* the method).

The paper gives no settings for its Nelder–Mead runs; MATLAB's ``fminsearch`` is the likely tool.
We use ``scipy.optimize.minimize(method="Nelder-Mead", bounds=...)``, whose defaults match
``fminsearch``'s (initial simplex: each coordinate of ``x0`` perturbed by 5 %, or by ``0.00025`` if
it is 0; ``xatol = fatol = 1e-4``; at most ``200 D`` iterations and ``200 D`` evaluations),
plus box handling (simplex points are clipped to the bounds, scipy >= 1.7).

Pseudo-code::

    while budget left:
        x0 <- uniform in [lb, ub]
        run scipy Nelder-Mead from x0 until it converges (or hits its own maxfev / maxiter)
        # every objective call goes through the tracker and counts toward the budget;
        # the call that would exceed the budget raises BudgetExhausted and ends the run

Ask/tell: scipy's loop calls the objective itself, so the search runs in a greenlet
(:func:`.base.search_steps`) and each objective call becomes an ask of one point; the seeds of a
fit block stepped together are evaluated as one population of one point per seed.

Budget / iteration mapping. A local search has no population, so "an iteration" is defined as
``pop_size`` objective evaluations: the first ``pop_size`` evaluations close iteration 0 and every
further ``pop_size`` evaluations close one more iteration (``tracker.end_iteration()``). Hence
``Budget(iterations=T, pop_size=P)`` spends exactly ``(T + 1) P`` evaluations -- the same as a
population method with ``P`` agents that evaluates its initial population and then ``T``
populations (the paper: 20 x 500 = 10,000 moves + 20 initial points) -- and
``Budget(max_nfe=N)`` spends exactly ``N``. The best value across all restarts is the result.

Settings (forwarded as scipy ``options``): ``xatol``, ``fatol``, ``maxiter``, ``maxfev``,
``adaptive``, ``initial_simplex`` is not supported (it is built from the random start).

Differences vs a plain single-start ``fminsearch``: restarts from fresh random points until the
budget is spent (so a converged local search does not waste the budget the population methods
get), and bounds (``fminsearch`` is unconstrained). mealpy has no Nelder–Mead.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
from scipy.optimize import Bounds, minimize

from .base import BudgetExhausted, Steps, Tracker, register, search_steps

NM_OPTIONS = ("xatol", "fatol", "maxiter", "maxfev", "adaptive")


class LocalSearchAccounting:
    """Evaluation accounting shared by the local searches (Nelder–Mead, quasi-Newton).

    Evaluates with ``ask`` (the tracker's asks, through :func:`.base.search_steps`), closes an
    iteration every ``pop_size`` evaluations, and never evaluates past the budget: the evaluation
    cap is ``max_nfe`` and/or ``(iterations + 1) * pop_size``. :meth:`evaluate` raises
    :class:`BudgetExhausted` when nothing is left.
    """

    def __init__(self, tracker: Tracker, pop_size: int, ask: Callable[[np.ndarray], Any]):
        self.tracker = tracker
        self.pop_size = pop_size
        self.ask = ask
        budget = tracker.budget
        cap = np.inf
        if budget.max_nfe is not None:
            cap = budget.max_nfe
        if budget.iterations is not None:
            cap = min(cap, (budget.iterations + 1) * pop_size)
        self.cap = cap
        self._next_mark = tracker.nfe + pop_size

    @property
    def remaining(self) -> float:
        return self.cap - self.tracker.nfe

    def evaluate(self, X: np.ndarray) -> tuple[np.ndarray, bool]:
        """Objective of the rows of ``X`` that fit into the budget (``+inf`` for the others).

        Returns the values and whether every row was evaluated. Raises ``BudgetExhausted`` if
        no row fits.
        """
        X = np.atleast_2d(X)
        n = X.shape[0]
        k = int(min(n, self.remaining))
        if k <= 0:
            raise BudgetExhausted
        f = np.full(n, np.inf)
        f[:k] = self.ask(X[:k])
        self._close_iterations()
        return f, k == n

    def evaluate_one(self, x: np.ndarray) -> float:
        """:meth:`evaluate` of one point, as a float; ``BudgetExhausted`` if none is left."""
        if self.remaining < 1:
            raise BudgetExhausted
        f = self.ask(np.asarray(x, dtype=float))
        self._close_iterations()
        return f

    def _close_iterations(self) -> None:
        """Close an iteration for every ``pop_size`` evaluations spent since the last one."""
        while self.tracker.nfe >= self._next_mark:
            self.tracker.end_iteration()
            self._next_mark += self.pop_size


def restart_loop(tracker: Tracker, rng: np.random.Generator, search_from) -> None:
    """Call ``search_from(x0)`` from fresh uniform random starts until the budget is spent."""
    while not tracker.done:
        x0 = tracker.random_uniform(rng, 1)[0]
        try:
            # a local search on an objective that returns +inf (a failed simulation) computes
            # inf - inf internally; that is harmless, so keep it out of the warnings
            with np.errstate(invalid="ignore", over="ignore"):
                search_from(x0)
        except BudgetExhausted:
            break


@register("nelder_mead")
def nelder_mead(tracker: Tracker, rng: np.random.Generator, pop_size: int, **settings) -> Steps:
    """Bounded Nelder–Mead (scipy) restarted from random points until the budget is spent."""
    unknown = set(settings) - set(NM_OPTIONS)
    if unknown:
        raise TypeError(f"nelder_mead: unknown settings {sorted(unknown)}; known: {NM_OPTIONS}")
    bounds = Bounds(tracker.lb, tracker.ub)

    def search(ask) -> None:
        acc = LocalSearchAccounting(tracker, pop_size, ask)

        def search_from(x0: np.ndarray) -> None:
            minimize(
                acc.evaluate_one, x0, method="Nelder-Mead", bounds=bounds, options=dict(settings)
            )

        restart_loop(tracker, rng, search_from)

    yield from search_steps(tracker, search)
