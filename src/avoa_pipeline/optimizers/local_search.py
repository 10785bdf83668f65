"""The evaluation accounting and restart loop of a local search run inside a greenlet, one seed at
a time (:func:`.base.search_steps`): quasi-Newton's L-BFGS-B, whose loop belongs to scipy.

Budget / iteration mapping. A local search has no population, so "an iteration" is defined as
``pop_size`` objective evaluations: the first ``pop_size`` evaluations close iteration 0 and every
further ``pop_size`` evaluations close one more iteration (``tracker.end_iteration()``). Hence
``Budget(iterations=T, pop_size=P)`` spends exactly ``(T + 1) P`` evaluations and
``Budget(max_nfe=N)`` exactly ``N``. Nelder–Mead keeps the same accounts over arrays of seeds
(:mod:`.nelder_mead`).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from .base import BudgetExhausted, Tracker


class LocalSearchAccounting:
    """Evaluation accounting shared by the local searches run one seed at a time.

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
