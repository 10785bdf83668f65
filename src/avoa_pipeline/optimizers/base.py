"""Shared machinery of every optimizer: budget, evaluation accounting, history, registry.

Every optimizer is a plain function ``run(tracker, rng, pop_size, **settings) -> None`` registered
under its name. It asks the :class:`Tracker` to evaluate whole populations and calls
``tracker.end_iteration()`` once per iteration; the tracker counts objective evaluations, keeps the
best point, enforces the budget and records the per-iteration history. So the budget rules (the
paper's 500 iterations, or a fixed number of evaluations) are written once, here, and an
algorithm only describes its search moves.

Budget semantics:
- ``iterations``: stop after this many completed iterations (the paper: 500). The evaluation of the
  initial population is iteration 0 of the history.
- ``max_nfe``: stop once this many objective evaluations are spent. A population evaluation that
  would overrun the budget evaluates only the rows that fit; the rest get ``+inf`` and are never
  accepted as best. Algorithms check ``tracker.done`` between moves.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

Objective = Callable[[np.ndarray], np.ndarray]
"""Population in (shape ``(P, D)``), objective values out (shape ``(P,)``)."""

ObjectiveOne = Callable[[np.ndarray], float]
"""One point in (shape ``(D,)``), its objective value out; must equal ``Objective`` on one row."""

REGISTRY: dict[str, Callable[..., None]] = {}


def register(name: str):
    """Register an optimizer under ``name`` (the one name used in config, CLI and file names)."""

    def deco(fn):
        if name in REGISTRY:
            raise ValueError(f"optimizer {name!r} registered twice")
        REGISTRY[name] = fn
        fn.optimizer_name = name
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
    wall_s: float
    history_best: np.ndarray  # best objective after iteration 0..T
    history_nfe: np.ndarray  # cumulative evaluations after iteration 0..T
    history_time: np.ndarray  # cumulative optimizer wall time (s) after iteration 0..T
    extra: dict = field(default_factory=dict)


class Tracker:
    """Wraps the objective: counts evaluations, keeps the best, records the history."""

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
        self._t0 = time.perf_counter()

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

    # --- evaluation ---------------------------------------------------------------------------
    def evaluate(self, X: np.ndarray) -> np.ndarray:
        """Objective of each row of ``X`` (rows past the evaluation budget get ``+inf``)."""
        X = np.atleast_2d(np.asarray(X, dtype=float))
        n = X.shape[0]
        f = np.full(n, np.inf)
        k = int(min(n, self.nfe_left))
        if k <= 0:
            return f
        fk = np.asarray(self.objective(X[:k]), dtype=float).reshape(k)
        # a NaN objective (a simulation that blew up) is never better than any number
        f[:k] = np.where(np.isnan(fk), np.inf, fk)
        self.nfe += k
        i = int(np.argmin(f))
        if f[i] < self.best_f:
            self.best_f = float(f[i])
            self.best_x = X[i].copy()
        return f

    def evaluate_one(self, x: np.ndarray) -> float:
        """:meth:`evaluate` of one point, as a float: the path of the algorithms that move one
        agent at a time (RUN, the local searches), where the population path's array handling
        would cost more than the simulation."""
        max_nfe = self.budget.max_nfe
        if max_nfe is not None and self.nfe >= max_nfe:
            return np.inf
        if self.objective_one is None:
            f = float(self.objective(x[None, :])[0])
        else:
            f = float(self.objective_one(x))
        if f != f:  # NaN: a simulation that blew up is never better than any number
            f = np.inf
        self.nfe += 1
        if f < self.best_f:
            self.best_f = f
            self.best_x = np.array(x, dtype=float)
        return f

    def end_iteration(self) -> None:
        """Close an iteration (the initial population is iteration 0) and record the history."""
        self._hist_best.append(self.best_f)
        self._hist_nfe.append(self.nfe)
        self._hist_time.append(time.perf_counter() - self._t0)
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
            self._hist_time.append(time.perf_counter() - self._t0)
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
    if name not in REGISTRY:
        raise KeyError(f"unknown algorithm {name!r}; known: {', '.join(sorted(REGISTRY))}")
    tracker = Tracker(objective, lb, ub, budget, objective_one)
    REGISTRY[name](tracker, rng, budget.pop_size, **settings)
    if tracker.best_x is None:
        raise RuntimeError(f"{name} evaluated no point")
    return tracker.result()
