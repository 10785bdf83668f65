"""Shared machinery of every optimizer: ask/tell steps, budget, evaluation accounting, history,
registry, and the drivers that answer the asks.

Every optimizer is a generator function ``fn(tracker, rng, pop_size, **settings)`` registered under
its name: a state machine that describes its moves and asks for their values, with
``f = yield from tracker.ask(X)`` (rows of ``X`` = candidates) or ``f = yield from
tracker.ask_one(x)``, and calls ``tracker.end_iteration()`` once per iteration. The :class:`Tracker`
cuts an ask to the budget, yields the rows to evaluate to whoever drives the generator, and is told
their values (the generator's ``send``); it counts evaluations, keeps the best point, enforces the
budget and records the per-iteration history. So the budget rules (the paper's 500 iterations, or
a fixed number of evaluations) are written once, here, an algorithm only describes its search
moves, and the driver decides how the asks are evaluated (nevergrad's ask/tell; evosax's
strategies vectorised over seeds):

- :func:`minimize`: one run; each ask is one objective call (one point through ``objective_one``).
- :func:`minimize_together`: several runs of one algorithm on one objective (the seeds of a fit
  block) stepped in lockstep by :func:`step_together`: each step advances every unfinished run to
  its next ask and evaluates all their rows in one objective call. Each run's numbers are those
  :func:`minimize` gives it: a run's moves depend only on its own generator and tracker, and row
  ``i`` of a population objective depends on row ``i`` alone (the model kernel scores every
  candidate by its own recursion, bit for bit whatever the other rows; tested).

Issue 30 moved the optimizers' own work across seeds: an algorithm registered with
``batched=True`` is one generator ``fn(runs, rngs, pop_size, **settings)`` over a :class:`Runs`
(the accounts of every seed as arrays) that moves all seeds in array operations shaped seeds ×
population × dimension (the way evosax or EvoTorch step many populations as one) and asks for
all their rows at once (:func:`drive`). Each seed still draws from its own generator, in the
order its one-seed code drew, so every record is what that code gave, bit for bit
(``tests/unit/test_lockstep.py``); one seed alone is a block of one. :func:`minimize_together`
picks the driver from the registration.

A search whose loop belongs to a library that calls the objective itself (scipy's Nelder–Mead and
L-BFGS-B) runs inside a greenlet (:func:`search_steps`): each objective call suspends it and
becomes an ask, so the local searches step together too, with scipy's code unchanged.

Time. A run's clock (``wall_s`` and the history's times) counts the time its own generator runs
plus its share of every evaluation it asked for (the evaluation's time × its rows ÷ all rows).
For one run that is its wall time; for runs stepped together it is each run's cost, and the
runs' clocks add up to the block's wall time (``docs/records.md``).

Budget semantics:
- ``iterations``: stop after this many completed iterations (the paper: 500). The evaluation of the
  initial population is iteration 0 of the history.
- ``max_nfe``: stop once this many objective evaluations are spent. A population ask that would
  overrun the budget asks only the rows that fit; the rest get ``+inf`` and are never accepted as
  best. Algorithms check ``tracker.done`` between moves.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Generator, Sequence
from dataclasses import dataclass, field

import numpy as np
from greenlet import greenlet

Objective = Callable[[np.ndarray], np.ndarray]
"""Population in (shape ``(P, D)``), objective values out (shape ``(P,)``)."""

ObjectiveOne = Callable[[np.ndarray], float]
"""One point in (shape ``(D,)``), its objective value out; must equal ``Objective`` on one row."""

Steps = Generator[np.ndarray, np.ndarray, None]
"""A run of an optimizer: yields the rows it asks to evaluate (shape ``(k, D)``), is sent their
objective values (shape ``(k,)``)."""

REGISTRY: dict[str, Callable[..., Steps]] = {}


def register(name: str, *, batched: bool = False):
    """Register an optimizer under ``name`` (the one name used in config, CLI and file names).

    ``batched``: the function is ``fn(runs, rngs, pop_size, **settings)`` over a :class:`Runs`
    (every seed's moves as array operations, one generator for all), not one run's
    ``fn(tracker, rng, pop_size, **settings)``."""

    def deco(fn):
        if name in REGISTRY:
            raise ValueError(f"optimizer {name!r} registered twice")
        REGISTRY[name] = fn
        fn.optimizer_name = name
        fn.batched = batched
        return fn

    return deco


class BudgetExhausted(Exception):  # a control-flow signal, not an error
    """Raised inside scipy callbacks to stop a local search when the budget is spent."""


@dataclass(frozen=True)
class Budget:
    pop_size: int = 20
    iterations: int | None = 500
    max_nfe: int | None = None

    def __post_init__(self):
        if self.pop_size < 1:
            raise ValueError(f"pop_size must be positive, got {self.pop_size}")
        if self.iterations is None and self.max_nfe is None:
            raise ValueError("budget needs iterations or max_nfe")
        if self.iterations is not None and self.iterations < 1:
            raise ValueError(f"iterations must be positive, got {self.iterations}")
        if self.max_nfe is not None and self.max_nfe < 1:
            raise ValueError(f"max_nfe must be positive, got {self.max_nfe}")


@dataclass
class OptimResult:
    best_x: np.ndarray
    best_f: float
    nfe: int
    iterations: int
    wall_s: float  # the run's clock (see the module docstring)
    history_best: np.ndarray  # best objective after iteration 0..T
    history_nfe: np.ndarray  # cumulative evaluations after iteration 0..T
    history_time: np.ndarray  # the run's clock (s) after iteration 0..T
    extra: dict = field(default_factory=dict)


def _values(objective: Objective, objective_one: ObjectiveOne | None, X: np.ndarray) -> np.ndarray:
    """Objective values of the rows of ``X``; one row through ``objective_one`` if given."""
    if X.shape[0] == 1 and objective_one is not None:
        return np.array([objective_one(X[0])], dtype=float)
    return np.asarray(objective(X), dtype=float).reshape(X.shape[0])


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

    # --- schedules ----------------------------------------------------------------------------
    def planned_iterations(self, evals_per_iteration: float) -> int:
        """Iteration horizon ``T`` over which an algorithm stretches its ``t/T`` schedules.

        For algorithms whose iterations each cost a fixed ``evals_per_iteration`` evaluations
        (AVOA, GWO: ``P``; GTO: ``2 P``). An iteration budget gives its ``iterations``. An
        evaluation budget gives the number of iterations that ``max_nfe`` allows after the initial
        population of ``budget.pop_size``, rounded up (the last one may be cut short by the
        budget): ``ceil((max_nfe - pop_size) / evals_per_iteration)``. With both budgets, the
        smaller; never less than 1, so ``t/T`` is always defined.
        """
        if evals_per_iteration <= 0:
            raise ValueError(f"evals_per_iteration must be positive, got {evals_per_iteration}")
        budget = self.budget
        horizons = []
        if budget.iterations is not None:
            horizons.append(budget.iterations)
        if budget.max_nfe is not None:
            horizons.append(math.ceil((budget.max_nfe - budget.pop_size) / evals_per_iteration))
        return max(1, min(horizons))

    def progress(self, *, count_initial: bool = False) -> float:
        """Fraction of the run that will be done when the running iteration ends, in [0, 1].

        For the schedules of algorithms whose iterations cost a varying number of evaluations
        (RUN, GA), called before the iteration spends any. The running iteration is
        ``t = iteration + 1``. An iteration budget ``T`` gives ``t / T``, or with
        ``count_initial`` (a reference that counts the initial population as its iteration 1)
        ``(t + 1) / (T + 1)``. An evaluation budget gives the share of ``max_nfe`` that will be
        spent if this iteration costs as many evaluations as the last closed one (the initial
        population for ``t = 1``), at most 1. With both budgets, the larger.
        """
        frac = 0.0
        T = self.budget.iterations
        if T is not None:
            t = self.iteration + 1
            frac = (t + 1) / (T + 1) if count_initial else t / T
        N = self.budget.max_nfe
        if N is not None:
            hist = self._hist_nfe
            last = hist[-1] - hist[-2] if len(hist) > 1 else (hist[-1] if hist else 0)
            frac = max(frac, min(1.0, (self.nfe + last) / N))
        return frac

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


class Runs:
    """The accounts of ``n`` runs of one algorithm stepped as one (a fit block's seeds), as arrays
    over the runs: what :class:`Tracker` keeps for one run, for all of them at once, so an
    algorithm written over arrays shaped runs × population × dimension (``register(...,
    batched=True)``) moves every seed in one numpy operation and asks for all their rows in one
    ask. Each run's numbers are those a :class:`Tracker` would keep for it alone: the same budget
    cut, the same NaN rule, the same strict "better" (tested against the references of the
    one-seed-at-a-time code, ``tests/unit/test_lockstep.py``).

    Time: each run's clock is charged an equal share of the algorithm's own time between two asks
    (every unfinished run moved in it) and its share of each evaluation in proportion to its rows,
    as :func:`step_together` charges per run."""

    def __init__(
        self,
        objective: Objective,
        lb,
        ub,
        budget: Budget,
        n: int,
        objective_one: ObjectiveOne | None = None,
    ):
        probe = Tracker(objective, lb, ub, budget, objective_one)  # the one check of the box
        self.objective, self.objective_one = objective, objective_one
        self.lb, self.ub, self.dim, self.budget = probe.lb, probe.ub, probe.dim, budget
        if n < 1:
            raise ValueError(f"need at least one run, got {n}")
        self.n = n
        self.nfe = np.zeros(n, dtype=np.int64)
        self.iteration = np.zeros(n, dtype=np.int64)
        self.best_f = np.full(n, np.inf)
        self.best_x = np.full((n, self.dim), np.nan)
        self._seen = np.zeros(n, dtype=bool)  # best_x set (Tracker: best_x is not None)
        self._hist_best: list[list[float]] = [[] for _ in range(n)]
        self._hist_nfe: list[list[int]] = [[] for _ in range(n)]
        self._hist_time: list[list[float]] = [[] for _ in range(n)]
        self.elapsed = np.zeros(n)
        self._rows = np.zeros(n, dtype=np.int64)  # rows each run asked in the pending ask

    # --- budget -----------------------------------------------------------------------------
    @property
    def nfe_left(self) -> np.ndarray:
        """Evaluations left per run (float; ``inf`` without an evaluation budget)."""
        if self.budget.max_nfe is None:
            return np.full(self.n, np.inf)
        return (self.budget.max_nfe - self.nfe).astype(float)

    @property
    def done(self) -> np.ndarray:
        """Per run: the budget is spent (:attr:`Tracker.done`)."""
        out = np.zeros(self.n, dtype=bool)
        if self.budget.max_nfe is not None:
            out |= self.nfe >= self.budget.max_nfe
        if self.budget.iterations is not None:
            out |= self.iteration >= self.budget.iterations
        return out

    def planned_iterations(self, evals_per_iteration: float) -> int:
        """:meth:`Tracker.planned_iterations` (it depends on the budget alone)."""
        return Tracker.planned_iterations(self, evals_per_iteration)

    def progress(
        self, *, count_initial: bool = False, which: np.ndarray | None = None
    ) -> np.ndarray:
        """:meth:`Tracker.progress` of each run, or of the runs in the mask ``which`` (in their
        order; for algorithms whose runs start their iterations at different steps)."""
        runs = range(self.n) if which is None else np.flatnonzero(which)
        out = np.zeros(len(runs))
        T, N = self.budget.iterations, self.budget.max_nfe
        for j, s in enumerate(runs):
            frac = 0.0
            if T is not None:
                t = int(self.iteration[s]) + 1
                frac = (t + 1) / (T + 1) if count_initial else t / T
            if N is not None:
                hist = self._hist_nfe[s]
                last = hist[-1] - hist[-2] if len(hist) > 1 else (hist[-1] if hist else 0)
                frac = max(frac, min(1.0, (int(self.nfe[s]) + last) / N))
            out[j] = frac
        return out

    # --- ask / tell ---------------------------------------------------------------------------
    def ask(
        self, X: np.ndarray, live: np.ndarray | None = None
    ) -> Generator[np.ndarray, np.ndarray, np.ndarray]:
        """``F = yield from runs.ask(X)``: the objective of every row of ``X`` (shape ``(n, k,
        D)``, run × row × dimension), shape ``(n, k)``.

        Per run, :meth:`Tracker.ask`: the rows that fit into its budget are evaluated (all runs'
        rows in one yield, run by run), the others and NaN get ``+inf``; runs not ``live`` (a
        boolean mask) ask nothing and get ``+inf``."""
        n, k = X.shape[0], X.shape[1]
        take = np.minimum(k, self.nfe_left)
        if live is not None:
            take = np.where(live, take, 0)
        take = take.astype(np.int64)
        f = np.full((n, k), np.inf)
        self._rows = take
        if not take.any():
            return f
        if (take == k).all():
            fk = yield X.reshape(n * k, X.shape[2])
            f[:] = fk.reshape(n, k)
        else:
            mask = np.arange(k)[None, :] < take[:, None]
            fk = yield X[mask]
            f[mask] = fk
        f[np.isnan(f)] = np.inf
        self.nfe += take
        i = np.argmin(f, axis=1)
        fi = f[np.arange(n), i]
        better = fi < self.best_f
        if better.any():
            self.best_f[better] = fi[better]
            self.best_x[better] = X[better, i[better]]
            self._seen |= better
        return f

    def end_iteration(self, which: np.ndarray | None = None) -> None:
        """:meth:`Tracker.end_iteration` of every run, or of the runs in the mask ``which``."""
        for s in range(self.n) if which is None else np.flatnonzero(which):
            self._close(s)

    def _close(self, s: int) -> None:
        self._hist_best[s].append(float(self.best_f[s]))
        self._hist_nfe[s].append(int(self.nfe[s]))
        self._hist_time[s].append(float(self.elapsed[s]))
        if len(self._hist_best[s]) > 1:
            self.iteration[s] += 1

    # --- moves' helpers -----------------------------------------------------------------------
    def clip(self, X: np.ndarray) -> np.ndarray:
        return np.clip(X, self.lb, self.ub)

    def random_uniform(self, rngs: Sequence[np.random.Generator], k: int) -> np.ndarray:
        """:meth:`Tracker.random_uniform` of each run from its own generator, shape (n, k, D)."""
        return np.stack([self.lb + rng.random((k, self.dim)) * (self.ub - self.lb) for rng in rngs])

    # --- clocks and results -------------------------------------------------------------------
    def charge_moves(self, seconds: float, runs: np.ndarray) -> None:
        """Split the algorithm's time of one step equally over the runs it moved."""
        if runs.any():
            self.elapsed[runs] += seconds / runs.sum()

    def charge_rows(self, seconds: float) -> None:
        """Split an evaluation's time over the runs in proportion to the rows each asked."""
        total = self._rows.sum()
        if total:
            self.elapsed += seconds * self._rows / total

    def result(self, s: int) -> OptimResult:
        """Run ``s``'s result, as :meth:`Tracker.result` gives it."""
        hb, hn, ht = self._hist_best[s], self._hist_nfe[s], self._hist_time[s]
        if not hb or hn[-1] != self.nfe[s]:
            hb.append(float(self.best_f[s]))
            hn.append(int(self.nfe[s]))
            ht.append(float(self.elapsed[s]))
        if not self._seen[s]:
            raise RuntimeError("the run evaluated no point")
        return OptimResult(
            best_x=self.best_x[s].copy(),
            best_f=float(self.best_f[s]),
            nfe=int(self.nfe[s]),
            iterations=len(hb) - 1,
            wall_s=float(ht[-1]),
            history_best=np.asarray(hb),
            history_nfe=np.asarray(hn, dtype=np.int64),
            history_time=np.asarray(ht),
        )


def drive(runs: Runs, steps: Steps) -> None:
    """Run a batched algorithm's ``steps`` over ``runs`` to its end: each ask's rows (all runs')
    in one objective call, the clocks charged as :class:`Runs` says."""
    values = None
    while True:
        moving = ~runs.done
        t0 = time.perf_counter()
        try:
            rows = steps.send(values)
        except StopIteration:
            runs.charge_moves(time.perf_counter() - t0, moving)
            return
        runs.charge_moves(time.perf_counter() - t0, moving)
        t0 = time.perf_counter()
        values = _values(runs.objective, runs.objective_one, rows)
        runs.charge_rows(time.perf_counter() - t0)


def _answer(steps: Generator, tracker: Tracker):
    """Drive a single ask of ``tracker`` to its value with the tracker's own objective."""
    try:
        rows = next(steps)
        while True:
            rows = steps.send(_values(tracker.objective, tracker.objective_one, rows))
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
        F = _values(objective, objective_one, X)
        told, lo = [], 0
        for rows in asks:
            told.append(F[lo : lo + rows.shape[0]])
            lo += rows.shape[0]
        per_row = (time.perf_counter() - t0) / X.shape[0]
        for (tracker, _), rows in zip(asking, asks, strict=True):
            tracker.charge(per_row * rows.shape[0])
        live = asking


def minimize_together(
    name: str,
    objective: Objective,
    lb,
    ub,
    budget: Budget,
    rngs: Sequence[np.random.Generator],
    objective_one: ObjectiveOne | None = None,
    **settings,
) -> list[OptimResult]:
    """One run of the registered optimizer ``name`` per generator in ``rngs``, stepped together
    (:func:`step_together`); each result equals :func:`minimize` with that generator alone."""
    if name not in REGISTRY:
        raise KeyError(f"unknown algorithm {name!r}; known: {', '.join(sorted(REGISTRY))}")
    fn = REGISTRY[name]
    if fn.batched:
        block = Runs(objective, lb, ub, budget, len(rngs), objective_one)
        drive(block, fn(block, list(rngs), budget.pop_size, **settings))
        try:
            return [block.result(s) for s in range(block.n)]
        except RuntimeError:
            raise RuntimeError(f"{name} evaluated no point") from None
    trackers = [Tracker(objective, lb, ub, budget, objective_one) for _ in rngs]
    runs = [
        (t, REGISTRY[name](t, rng, budget.pop_size, **settings))
        for t, rng in zip(trackers, rngs, strict=True)
    ]
    step_together(runs, objective, objective_one)
    for tracker in trackers:
        if tracker.best_x is None:
            raise RuntimeError(f"{name} evaluated no point")
    return [tracker.result() for tracker in trackers]


def minimize(
    name: str,
    objective: Objective,
    lb,
    ub,
    budget: Budget,
    rng: np.random.Generator,
    objective_one: ObjectiveOne | None = None,
    **settings,
) -> OptimResult:
    """Run the registered optimizer ``name`` on ``objective`` within ``[lb, ub]``.

    ``objective_one``, if given, evaluates a single point faster than ``objective`` on one row and
    gives the same value.
    """
    return minimize_together(name, objective, lb, ub, budget, [rng], objective_one, **settings)[0]
