"""Helpers shared by the optimizer tests (test_optimizer_contract, which holds the contract every
optimizer must pass, and test_avoa, test_gto, test_gwo, test_run, test_ga, test_local): an
objective that records what it evaluates, shifted test functions, and the contract checks
(history, seeding, global generators)."""

from __future__ import annotations

import functools
import random

import numpy as np

from avoa_pipeline.optimizers import Budget, OptimResult, minimize
from avoa_pipeline.optimizers.testfunctions import sphere


class Recorder:
    """Objective wrapper that keeps a copy of every population it is called with."""

    def __init__(self, f=sphere):
        self.f = f
        self.calls: list[np.ndarray] = []

    def __call__(self, X):
        X = np.atleast_2d(np.asarray(X, dtype=float))
        self.calls.append(X.copy())
        return self.f(X)

    @property
    def all(self) -> np.ndarray:
        """Every evaluated point, in evaluation order (rows)."""
        return np.vstack(self.calls)


def shifted(f, shift):
    """``f`` with its optimum moved from the origin to ``shift``."""
    shift = np.asarray(shift, dtype=float)

    def g(X):
        return f(np.atleast_2d(X) - shift)

    return g


def minimize_seeded(name: str, f, lb, ub, budget: Budget, seed: int = 0, **settings) -> OptimResult:
    """``minimize`` with float bounds and a fresh generator from ``seed``."""
    lb, ub = np.asarray(lb, float), np.asarray(ub, float)
    return minimize(name, f, lb, ub, budget, np.random.default_rng(seed), **settings)


def runner(name: str):
    """``run(f, lb, ub, budget, seed=0, **settings)`` for one algorithm."""
    return functools.partial(minimize_seeded, name)


def assert_history_consistent(res: OptimResult, f) -> None:
    """The per-iteration history agrees with itself and with the reported result."""
    n = res.history_best.size
    assert res.history_nfe.size == n
    assert res.history_time.size == n
    assert np.all(np.diff(res.history_best) <= 0)  # best-so-far never gets worse
    assert np.all(np.diff(res.history_nfe) > 0)
    assert np.all(np.diff(res.history_time) >= 0)
    assert res.history_best[-1] == res.best_f
    assert res.history_nfe[-1] == res.nfe
    # the reported best is a point actually evaluated, with its true value
    assert f(res.best_x[None])[0] == res.best_f


def assert_seed_determines_result(a: OptimResult, b: OptimResult, c: OptimResult) -> None:
    """``a`` and ``b`` ran with the same seed, ``c`` with another."""
    assert np.array_equal(a.best_x, b.best_x)
    assert a.best_f == b.best_f
    assert np.array_equal(a.history_best, b.history_best)
    assert np.array_equal(a.history_nfe, b.history_nfe)
    assert not np.array_equal(a.best_x, c.best_x)


def assert_global_generators_untouched(call) -> None:
    """``call()`` draws only from the generator it is given, not numpy's or Python's global one."""
    np.random.seed(0)  # noqa: NPY002
    random.seed(0)
    before = (np.random.get_state()[1].copy(), random.getstate())  # noqa: NPY002
    call()
    assert np.array_equal(np.random.get_state()[1], before[0])  # noqa: NPY002
    assert random.getstate() == before[1]
