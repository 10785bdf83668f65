"""The one-seed-at-a-time driver of the optimizers before issue 30, kept as a test oracle.

Until issue 30 every optimizer was a generator per seed over a :class:`Tracker` (one run's
accounts), stepped in lockstep by :func:`step_together`, and scipy's Nelder–Mead and L-BFGS-B ran
inside a greenlet (:func:`search_steps`) that turned each objective call into an ask. The
package now moves all seeds of a block as arrays (``avoa_pipeline.optimizers.base.Runs``); this
module keeps the old driver so that the tests can hold the batched local searches to
``scipy.optimize.minimize`` itself, run one seed at a time exactly as before
(``test_nelder_mead.py``, ``test_quasi_newton.py``), and the shared accounting rules to a second,
independent statement (``test_base.py``).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Generator, Sequence
from typing import Any

import numpy as np
from greenlet import greenlet

from avoa_pipeline.optimizers.base import (
    Budget,
    Objective,
    ObjectiveOne,
    OptimResult,
    Steps,
    evaluate_rows,
)


class BudgetExhausted(Exception):  # a control-flow signal, not an error
    """Raised inside scipy callbacks to stop a local search when the budget is spent."""


class Tracker:
    """One run's accounts: cuts asks to the budget, counts evaluations, keeps the best, records
    the history, and keeps the run's clock. ``objective`` (and ``objective_one``) answer the asks
    of :meth:`evaluate` / :meth:`evaluate_one`, for callers that drive no generator."""

    def __init__(
        self,
        objective: Objective,
        lb,
        ub,
        budget: Budget,
        objective_one: ObjectiveOne | None = None,
    ):
        self.objective = objective
        self.objective_one = objective_one
        self.lb = np.asarray(lb, dtype=float)
        self.ub = np.asarray(ub, dtype=float)
        if self.lb.shape != self.ub.shape or self.lb.ndim != 1:
            raise ValueError("lb and ub must be 1-D arrays of the same length")
        if np.any(self.lb >= self.ub):
            bad = int(np.flatnonzero(self.lb >= self.ub)[0])
            raise ValueError(f"lb >= ub for dimension {bad}: {self.lb[bad]} >= {self.ub[bad]}")
        self.dim = self.lb.size
        self.budget = budget
        self.nfe = 0
        self.iteration = 0
        self.best_x = None
        self.best_f = np.inf
        self._hist_best: list[float] = []
        self._hist_nfe: list[int] = []
        self._hist_time: list[float] = []
        self._elapsed = 0.0
        self._running_since: float | None = None

    # --- the run's clock (driven by step_together) ---------------------------------------------
    def resume(self) -> None:
        """The run's generator starts a step: its clock runs."""
        self._running_since = time.perf_counter()

    def pause(self) -> None:
        """The run's generator has yielded (or ended): its clock stops."""
        if self._running_since is not None:
            self._elapsed += time.perf_counter() - self._running_since
            self._running_since = None

    def charge(self, seconds: float) -> None:
        """Add this run's share of an evaluation to its clock."""
        self._elapsed += seconds

    @property
    def elapsed(self) -> float:
        """Seconds on the run's clock so far."""
        if self._running_since is None:
            return self._elapsed
        return self._elapsed + (time.perf_counter() - self._running_since)

    # --- budget -----------------------------------------------------------------------------
    @property
    def nfe_left(self) -> float:
        return np.inf if self.budget.max_nfe is None else self.budget.max_nfe - self.nfe

    @property
    def done(self) -> bool:
        if self.budget.max_nfe is not None and self.nfe >= self.budget.max_nfe:
            return True
        return self.budget.iterations is not None and self.iteration >= self.budget.iterations

    # --- ask / tell ---------------------------------------------------------------------------
    def ask(self, X: np.ndarray) -> Generator[np.ndarray, np.ndarray, np.ndarray]:
        """``f = yield from tracker.ask(X)``: the objective of each row of ``X``.

        Yields the rows that fit into the evaluation budget (none: nothing is yielded) and is sent
        their values; rows past the budget get ``+inf``, and so does a NaN (a simulation that
        blew up is never better than any number)."""
        X = np.atleast_2d(np.asarray(X, dtype=float))
        n = X.shape[0]
        f = np.full(n, np.inf)
        k = int(min(n, self.nfe_left))
        if k <= 0:
            return f
        fk = yield X[:k]
        f[:k] = np.where(np.isnan(fk), np.inf, fk)
        self.nfe += k
        i = int(np.argmin(f))
        if f[i] < self.best_f:
            self.best_f = float(f[i])
            self.best_x = X[i].copy()
        return f

    def ask_one(self, x: np.ndarray) -> Generator[np.ndarray, np.ndarray, float]:
        """``f = yield from tracker.ask_one(x)``: :meth:`ask` of one point, as a float (the path
        of RUN's agents and Nelder–Mead, where the population path's array handling would cost
        more than the accounting itself)."""
        max_nfe = self.budget.max_nfe
        if max_nfe is not None and self.nfe >= max_nfe:
            return np.inf
        f = float((yield x[None, :])[0])
        if f != f:  # NaN: a simulation that blew up is never better than any number
            f = np.inf
        self.nfe += 1
        if f < self.best_f:
            self.best_f = f
            self.best_x = np.array(x, dtype=float)
        return f

    def evaluate(self, X: np.ndarray) -> np.ndarray:
        """:meth:`ask`, answered at once by this tracker's objective."""
        return _answer(self.ask(X), self)

    def evaluate_one(self, x: np.ndarray) -> float:
        """:meth:`ask_one`, answered at once by this tracker's objective (``objective_one`` if
        given)."""
        return _answer(self.ask_one(np.asarray(x, dtype=float)), self)

    def end_iteration(self) -> None:
        """Close an iteration (the initial population is iteration 0) and record the history."""
        self._hist_best.append(self.best_f)
        self._hist_nfe.append(self.nfe)
        self._hist_time.append(self.elapsed)
        if len(self._hist_best) > 1:
            self.iteration += 1

    def clip(self, X: np.ndarray) -> np.ndarray:
        return np.clip(X, self.lb, self.ub)

    def random_uniform(self, rng: np.random.Generator, n: int) -> np.ndarray:
        return self.lb + rng.random((n, self.dim)) * (self.ub - self.lb)

    def result(self) -> OptimResult:
        if not self._hist_best or self._hist_nfe[-1] != self.nfe:
            # evaluations after the last closed iteration (a partial one at the budget's end)
            self._hist_best.append(self.best_f)
            self._hist_nfe.append(self.nfe)
            self._hist_time.append(self.elapsed)
        return OptimResult(
            best_x=np.asarray(self.best_x, dtype=float),
            best_f=float(self.best_f),
            nfe=int(self.nfe),
            iterations=len(self._hist_best) - 1,
            wall_s=float(self._hist_time[-1]),
            history_best=np.asarray(self._hist_best),
            history_nfe=np.asarray(self._hist_nfe, dtype=np.int64),
            history_time=np.asarray(self._hist_time),
        )


def _answer(steps: Generator, tracker: Tracker):
    """Drive a single ask of ``tracker`` to its value with the tracker's own objective."""
    try:
        rows = next(steps)
        while True:
            rows = steps.send(evaluate_rows(tracker.objective, tracker.objective_one, rows))
    except StopIteration as stop:
        return stop.value


def search_steps(
    tracker: Tracker, search: Callable[[Callable[[np.ndarray], np.ndarray]], None]
) -> Steps:
    """``yield from search_steps(tracker, search)``: run ``search(evaluate)``, a loop that calls
    ``evaluate`` itself (a scipy driver), as this run's steps: ``evaluate(X)`` of rows ``X``
    (shape ``(k, D)``) is :meth:`Tracker.ask`, ``evaluate(x)`` of one point (shape ``(D,)``)
    :meth:`Tracker.ask_one`.

    Why a greenlet: scipy's Nelder–Mead and L-BFGS-B own their loops and call the objective from
    inside them, so they cannot yield. ``search`` runs in a greenlet of its own; each ``evaluate``
    switches back here with its argument, which becomes the ask, and the values are switched back
    in as its return value. Only one of the two runs at any moment, so the search sees exactly
    the calls and values it would see calling the objective directly.
    """

    def evaluate(X: np.ndarray):
        return child.parent.switch(X)

    child = greenlet(search)
    try:
        request = child.switch(evaluate)
        while not child.dead:
            if request.ndim == 1:
                values = yield from tracker.ask_one(request)
            else:
                values = yield from tracker.ask(request)
            child.parent = greenlet.getcurrent()
            request = child.switch(values)
    finally:
        if not child.dead:  # the run was abandoned mid-search: end the search too
            child.throw()


def step_together(
    runs: Sequence[tuple[Tracker, Steps]],
    objective: Objective,
    objective_one: ObjectiveOne | None = None,
) -> None:
    """Drive ``runs`` (tracker, steps) in lockstep until every one has ended: each step resumes
    every unfinished run until its next ask, evaluates all the asked rows in one ``objective``
    call (a single row through ``objective_one`` if given) and tells each run its values.

    Each run's clock runs while its generator runs and is charged the evaluation's time (with
    stacking and splitting) in proportion to its rows."""
    live = list(runs)
    told: list[np.ndarray | None] = [None] * len(live)
    while live:
        asking, asks = [], []
        for (tracker, steps), values in zip(live, told, strict=True):
            tracker.resume()
            try:
                rows = steps.send(values)
            except StopIteration:
                continue
            finally:
                tracker.pause()
            asking.append((tracker, steps))
            asks.append(rows)
        if not asking:
            return
        t0 = time.perf_counter()
        X = asks[0] if len(asks) == 1 else np.concatenate(asks)
        F = evaluate_rows(objective, objective_one, X)
        told, lo = [], 0
        for rows in asks:
            told.append(F[lo : lo + rows.shape[0]])
            lo += rows.shape[0]
        per_row = (time.perf_counter() - t0) / X.shape[0]
        for (tracker, _), rows in zip(asking, asks, strict=True):
            tracker.charge(per_row * rows.shape[0])
        live = asking


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
