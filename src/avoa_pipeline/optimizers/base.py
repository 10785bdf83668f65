"""Shared machinery of every optimizer: the budget, the accounts of a block of runs (evaluations,
best point, history, clocks), the registry, and the driver that answers the asks.

Every optimizer is a generator function ``fn(runs, rngs, pop_size, **settings)`` registered under
its name: a state machine over a :class:`Runs` (the accounts of the seeds of a fit block, as
arrays over the seeds) that moves every seed in array operations shaped seeds × population ×
dimension (the way evosax or EvoTorch step many populations as one), asks for the values of all
their candidates at once with ``F = yield from runs.ask(X)`` (``X`` shaped seeds × rows ×
dimension, an optional mask of the seeds that ask) and calls ``runs.end_iteration()`` once per
iteration. :class:`Runs` cuts each seed's ask to its budget, yields the rows to evaluate to the
driver, and is told their values (the generator's ``send``); it counts evaluations, keeps each
seed's best point, enforces the budget and records the per-iteration history. So the budget
rules (the paper's 500 iterations, or a fixed number of evaluations) are written once, here; an
algorithm only describes its search moves (nevergrad's ask/tell).

- :func:`minimize_together`: several runs of one algorithm on one objective (the seeds of a fit
  block), every step's rows in one objective call (:func:`drive`).
- :func:`minimize`: one run, a block of one seed.

Each seed draws from its own generator, in the order the one-seed-at-a-time code drew (until
issue 30 every algorithm was a generator per seed, stepped in lockstep), so every record is
what that code gave, bit for bit: ``tests/unit/test_lockstep.py`` holds the block to references
of that code, ``tests/unit/test_nelder_mead.py`` and ``test_quasi_newton.py`` hold the local
searches to scipy itself run one seed at a time (the one-seed driver, ``Tracker`` and the
greenlet that turned scipy's calls into asks, lives on in ``tests/unit/one_seed_driver.py`` for
that). Row ``i`` of a population objective depends on row ``i`` alone (the model kernel scores
every candidate by its own recursion, bit for bit whatever the other rows; tested), so how the
seeds' rows are stacked changes no value.

Time. A run's clock (``wall_s`` and the history's times) counts its share of the algorithm's
own time (the block's move time split equally over the seeds it moved) plus its share of every
evaluation it asked for (the evaluation's time × its rows ÷ all rows). For one run that is its
wall time; for a block it is each run's cost, and the runs' clocks add up to the block's wall
time (``docs/records.md``).

Budget semantics:
- ``iterations``: stop after this many completed iterations (the paper: 500). The evaluation of the
  initial population is iteration 0 of the history.
- ``max_nfe``: stop once this many objective evaluations are spent. A population ask that would
  overrun the budget asks only the rows that fit; the rest get ``+inf`` and are never accepted as
  best. Algorithms check ``runs.done`` between moves.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Generator, Sequence
from dataclasses import dataclass, field

import numba as nb
import numpy as np

Objective = Callable[[np.ndarray], np.ndarray]
"""Population in (shape ``(P, D)``), objective values out (shape ``(P,)``)."""

ObjectiveOne = Callable[[np.ndarray], float]
"""One point in (shape ``(D,)``), its objective value out; must equal ``Objective`` on one row."""

Steps = Generator[np.ndarray, np.ndarray, None]
"""The runs of an optimizer over a block of seeds: yields the rows it asks to evaluate, every
asking seed's rows one after another (shape ``(k, D)``), is sent their objective values (shape
``(k,)``)."""

REGISTRY: dict[str, Callable[..., Steps]] = {}


def register(name: str):
    """Register an optimizer ``fn(runs, rngs, pop_size, **settings)`` under ``name`` (the one
    name used in config, CLI and file names)."""

    def deco(fn):
        if name in REGISTRY:
            raise ValueError(f"optimizer {name!r} registered twice")
        REGISTRY[name] = fn
        fn.optimizer_name = name
        return fn

    return deco


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


def evaluate_rows(
    objective: Objective, objective_one: ObjectiveOne | None, X: np.ndarray
) -> np.ndarray:
    """Objective values of the rows of ``X``; one row through ``objective_one`` if given."""
    if X.shape[0] == 1 and objective_one is not None:
        return np.array([objective_one(X[0])], dtype=float)
    return np.asarray(objective(X), dtype=float).reshape(X.shape[0])


def uniform_in_box(rng: np.random.Generator, lb: np.ndarray, ub: np.ndarray, k: int) -> np.ndarray:
    """``k`` uniform points in the box ``[lb, ub]`` from ``rng`` (``k`` × D doubles), shape
    (k, D): every start of a search, a population's or a local search's restart."""
    return lb + rng.random((k, lb.size)) * (ub - lb)


# Runs.ask's bookkeeping, compiled: as numpy operations it was about twenty calls on arrays of a
# few dozen elements, 29 us an ask (one point per seed, 30 seeds) against about 170 us for the
# kernel to score those points (Nelder–Mead and RUN ask one point per seed per step).


@nb.njit(cache=True)
def _budget_rows(X, live, nfe, max_nfe):
    """Per run the rows of ``X`` (run × row × dimension) it asks that fit its budget (``take``:
    its first ``min(k, max_nfe - nfe)``, none if not ``live``; ``max_nfe`` < 0: no evaluation
    budget), and those rows, run after run."""
    n, k, D = X.shape
    take = np.empty(n, dtype=np.int64)
    for s in range(n):
        take[s] = 0 if not live[s] else (k if max_nfe < 0 else min(k, max_nfe - nfe[s]))
    out = np.empty((take.sum(), D))
    r = 0
    for s in range(n):
        for i in range(take[s]):
            for j in range(D):  # element by element: no slice assignment to compile
                out[r, j] = X[s, i, j]
            r += 1
    return take, out


@nb.njit(cache=True)
def _told(fk, take, X, nfe, best_f, best_x):
    """The values ``fk`` of the asked rows (:func:`_budget_rows`' order) as a run × row array,
    ``+inf`` for a NaN and for a row not asked; the runs' evaluations counted and each run's
    best replaced by its first row of the smallest value if that is strictly smaller (in place).
    """
    n, k = X.shape[0], X.shape[1]
    f = np.full((n, k), np.inf)
    r = 0
    for s in range(n):
        for i in range(take[s]):
            if fk[r] == fk[r]:  # a NaN (a simulation that blew up) stays +inf
                f[s, i] = fk[r]
            r += 1
        nfe[s] += take[s]
        best = 0  # np.argmin's first index of the smallest value
        for i in range(1, k):
            if f[s, i] < f[s, best]:
                best = i
        if f[s, best] < best_f[s]:
            best_f[s] = f[s, best]
            for j in range(X.shape[2]):
                best_x[s, j] = X[s, best, j]
    return f


@nb.njit(cache=True)
def _charge(elapsed, done, move_s, rows, eval_s):
    """:meth:`Runs.charge` in one compiled call (as numpy operations, six a step)."""
    moved, total = 0, rows.sum()
    for s in range(done.size):
        moved += not done[s]
    for s in range(elapsed.size):
        if not done[s]:
            elapsed[s] += move_s / moved
        if total:
            elapsed[s] += rows[s] * (eval_s / total)


class Runs:
    """The accounts of ``n`` runs of one algorithm stepped as one (a fit block's seeds), as arrays
    over the runs: evaluations, iterations, each run's best point, its history and its clock.
    An algorithm moves every seed in one numpy operation and asks for all their rows in one ask.

    Time: each run's clock is charged an equal share of the algorithm's own time between two asks
    (every unfinished run moved in it) and its share of each evaluation in proportion to its
    rows."""

    def __init__(
        self,
        objective: Objective,
        lb,
        ub,
        budget: Budget,
        n: int,
        objective_one: ObjectiveOne | None = None,
    ):
        self.objective, self.objective_one = objective, objective_one
        self.lb = np.asarray(lb, dtype=float)
        self.ub = np.asarray(ub, dtype=float)
        if self.lb.shape != self.ub.shape or self.lb.ndim != 1:
            raise ValueError("lb and ub must be 1-D arrays of the same length")
        if np.any(self.lb >= self.ub):
            bad = int(np.flatnonzero(self.lb >= self.ub)[0])
            raise ValueError(f"lb >= ub for dimension {bad}: {self.lb[bad]} >= {self.ub[bad]}")
        self.dim, self.budget = self.lb.size, budget
        if n < 1:
            raise ValueError(f"need at least one run, got {n}")
        self.n = n
        self.nfe = np.zeros(n, dtype=np.int64)
        self.best_f = np.full(n, np.inf)
        self.best_x = np.full((n, self.dim), np.nan)
        self._hist_best: list[list[float]] = [[] for _ in range(n)]
        self._hist_nfe: list[list[int]] = [[] for _ in range(n)]
        self._hist_time: list[list[float]] = [[] for _ in range(n)]
        self.elapsed = np.zeros(n)
        self._rows = np.zeros(n, dtype=np.int64)  # rows each run asked in the pending ask
        self._everyone = np.ones(n, dtype=bool)  # the mask of an ask without one
        self._closed = np.zeros(n, dtype=np.int64)  # iterations closed, iteration 0 included
        # completed iterations, max(_closed - 1, 0), kept as an array: the algorithms and `done`
        # read it at every step (derived there, quasi-Newton's block ran ~8 % slower)
        self.iteration = np.zeros(n, dtype=np.int64)

    # --- budget -----------------------------------------------------------------------------
    @property
    def nfe_left(self) -> np.ndarray:
        """Evaluations left per run (float; ``inf`` without an evaluation budget)."""
        if self.budget.max_nfe is None:
            return np.full(self.n, np.inf)
        return (self.budget.max_nfe - self.nfe).astype(float)

    @property
    def done(self) -> np.ndarray:
        """Per run: the budget is spent."""
        max_nfe, iterations = self.budget.max_nfe, self.budget.iterations
        if max_nfe is None:
            return self.iteration >= iterations
        if iterations is None:
            return self.nfe >= max_nfe
        return (self.nfe >= max_nfe) | (self.iteration >= iterations)

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

    def evaluation_cap(self, pop_size: int) -> int:
        """The evaluations a local search may spend, whose "iteration" is ``pop_size``
        evaluations (Nelder–Mead, quasi-Newton): ``max_nfe`` and/or ``(iterations + 1) pop_size``,
        the number a population method spends on its initial population and ``iterations``
        populations (the paper: 20 × 500 + 20)."""
        caps = [] if self.budget.max_nfe is None else [self.budget.max_nfe]
        if self.budget.iterations is not None:
            caps.append((self.budget.iterations + 1) * pop_size)
        return min(caps)

    def close_spent(self, pop_size: int) -> None:
        """A local search's iterations: close one for every ``pop_size`` evaluations spent since
        the last one closed (the first ``pop_size`` close iteration 0; one ask of ``D + 1`` rows
        may close two)."""
        while True:
            closing = self.nfe >= (self._closed + 1) * pop_size
            if not np.count_nonzero(closing):  # .any() costs 4 times as much on a few dozen
                return
            self.end_iteration(closing)

    def progress(
        self, *, count_initial: bool = False, which: np.ndarray | None = None
    ) -> np.ndarray:
        """Fraction of each run that will be done when its running iteration ends, in [0, 1]; of
        the runs in the mask ``which`` only (in their order), for algorithms whose runs start
        their iterations at different steps.

        For the schedules of algorithms whose iterations cost a varying number of evaluations
        (RUN, GA), called before the iteration spends any. The running iteration is
        ``t = iteration + 1``. An iteration budget ``T`` gives ``t / T``, or with
        ``count_initial`` (a reference that counts the initial population as its iteration 1)
        ``(t + 1) / (T + 1)``. An evaluation budget gives the share of ``max_nfe`` that will be
        spent if this iteration costs as many evaluations as the last closed one (the initial
        population for ``t = 1``), at most 1. With both budgets, the larger.
        """
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

        Per run: the rows that fit into its budget are evaluated (all runs' rows in one yield,
        run by run), the others get ``+inf``, and so does a NaN (a simulation that blew up is
        never better than any number); runs not ``live`` (a boolean mask) ask nothing and get
        ``+inf``. The best point is the first row of the smallest value, if strictly better
        than the run's best so far."""
        X = np.ascontiguousarray(X, dtype=float)
        max_nfe = -1 if self.budget.max_nfe is None else self.budget.max_nfe
        take, rows = _budget_rows(X, self._everyone if live is None else live, self.nfe, max_nfe)
        self._rows = take
        if not rows.shape[0]:
            return np.full(X.shape[:2], np.inf)
        fk = yield rows
        return _told(np.asarray(fk, dtype=float).reshape(-1), take, X, self.nfe, self.best_f,
                     self.best_x)  # fmt: skip

    def evaluate(self, X: np.ndarray, live: np.ndarray | None = None) -> np.ndarray:
        """:meth:`ask`, answered at once by the runs' own objective (for callers that drive no
        generator)."""
        steps = self.ask(X, live)
        try:
            rows = next(steps)
            while True:
                rows = steps.send(evaluate_rows(self.objective, self.objective_one, rows))
        except StopIteration as stop:
            return stop.value

    def end_iteration(self, which: np.ndarray | None = None) -> None:
        """Close an iteration (the initial population is iteration 0) of every run, or of the
        runs in the mask ``which``, and record its history."""
        for s in range(self.n) if which is None else np.flatnonzero(which):
            self._close(s)

    def _close(self, s: int) -> None:
        self._closed[s] += 1
        if self._closed[s] > 1:
            self.iteration[s] += 1
        self._hist_best[s].append(float(self.best_f[s]))
        self._hist_nfe[s].append(int(self.nfe[s]))
        self._hist_time[s].append(float(self.elapsed[s]))

    # --- moves' helpers -----------------------------------------------------------------------
    def clip(self, X: np.ndarray) -> np.ndarray:
        return np.clip(X, self.lb, self.ub)

    def random_uniform(self, rngs: Sequence[np.random.Generator], k: int) -> np.ndarray:
        """``k`` uniform points in the box per run, each from its own generator, shape
        (n, k, D)."""
        return np.stack([uniform_in_box(rng, self.lb, self.ub, k) for rng in rngs])

    def initial_population(
        self, rngs: Sequence[np.random.Generator], k: int
    ) -> Generator[np.ndarray, np.ndarray, tuple[np.ndarray, np.ndarray]]:
        """``X, f = yield from runs.initial_population(rngs, k)``: a population method's start,
        :meth:`random_uniform`'s ``k`` points per run, their values (:meth:`ask`) and iteration
        0 of the history closed."""
        X = self.random_uniform(rngs, k)
        f = yield from self.ask(X)
        self.end_iteration()
        return X, f

    # --- clocks and results -------------------------------------------------------------------
    def charge(self, done: np.ndarray, move_s: float, eval_s: float) -> None:
        """One step's clocks: the algorithm's time ``move_s`` split equally over the runs it
        moved (those not ``done`` before it), the evaluation's time ``eval_s`` over the runs in
        proportion to the rows each asked."""
        _charge(self.elapsed, done, move_s, self._rows, eval_s)

    def result(self, s: int) -> OptimResult:
        """Run ``s``'s result; evaluations after its last closed iteration (a partial one at
        the budget's end) close the history."""
        hb, hn, ht = self._hist_best[s], self._hist_nfe[s], self._hist_time[s]
        if not hb or hn[-1] != self.nfe[s]:
            hb.append(float(self.best_f[s]))
            hn.append(int(self.nfe[s]))
            ht.append(float(self.elapsed[s]))
        if not self.best_f[s] < np.inf:  # no evaluated point was better than +inf
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
    """Run an algorithm's ``steps`` over ``runs`` to its end: each ask's rows (all runs')
    in one objective call, the clocks charged as :class:`Runs` says."""
    values = None
    while True:
        done = runs.done
        t0 = time.perf_counter()
        try:
            rows = steps.send(values)
        except StopIteration:
            runs.charge(done, time.perf_counter() - t0, 0.0)
            return
        t1 = time.perf_counter()
        values = evaluate_rows(runs.objective, runs.objective_one, rows)
        runs.charge(done, t1 - t0, time.perf_counter() - t1)


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
    """One run of the registered optimizer ``name`` per generator in ``rngs``, moved and
    evaluated together (:func:`drive`); each result equals :func:`minimize` with that generator
    alone."""
    if name not in REGISTRY:
        raise KeyError(f"unknown algorithm {name!r}; known: {', '.join(sorted(REGISTRY))}")
    block = Runs(objective, lb, ub, budget, len(rngs), objective_one)
    drive(block, REGISTRY[name](block, list(rngs), budget.pop_size, **settings))
    try:
        return [block.result(s) for s in range(block.n)]
    except RuntimeError:
        raise RuntimeError(f"{name} evaluated no point") from None


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
