"""Quasi-Newton's batched driver against ``scipy.optimize.minimize`` itself.

``quasi_newton`` drives scipy's private L-BFGS-B core (``scipy.optimize._lbfgsb.setulb``) for every
seed of a block with a loop of its own, in place of ``minimize(method="L-BFGS-B")``, its wrappers
and a greenlet per seed (the module docstring lists what of scipy's loop it copies). Here the
previous version -- ``minimize`` called one seed at a time, each gradient call counted against the
budget as before -- is kept as the reference, and the block must give each seed's numbers bit for
bit and ask for the same rows in the same calls, on test functions with bounds, with budgets that
end inside a gradient call, with settings that make scipy stop its searches (``maxiter``,
``maxfun``) and with values that are not finite. A scipy upgrade that changes the core's
arguments, its task codes or the loop around it fails here.
"""

from __future__ import annotations

import inspect
import itertools

import numpy as np
import pytest
import scipy.optimize
from one_seed_driver import Tracker
from optim_helpers import Recorder, shifted
from scipy.optimize import Bounds
from scipy.optimize import minimize as scipy_minimize

from avoa_pipeline.optimizers import Budget, OptimResult, minimize_together, quasi_newton
from avoa_pipeline.optimizers.quasi_newton import LBFGSB_DEFAULTS
from avoa_pipeline.optimizers.testfunctions import rastrigin, rosenbrock, sphere

LB, UB = np.array([-5.0, 0.0, 10.0, -1.0]), np.array([5.0, 1.0, 20.0, 3.0])
SEEDS = [3, 1, 4, 1, 5]  # a repeated seed must give the same run twice
REL_STEP = np.sqrt(np.finfo(float).eps)  # quasi_newton's default
BIG = 1e300  # quasi_newton's f at a point whose value is not finite


class Spent(Exception):
    """The reference's budget is spent (the previous version's BudgetExhausted)."""


def scipy_run(f, lb, ub, budget: Budget, rng, **settings) -> OptimResult:
    """The previous quasi_newton, one seed: ``scipy.optimize.minimize(method="L-BFGS-B",
    jac=True)`` restarted from uniform points, each ``fun`` call one evaluation of ``D + 1``
    rows, an iteration closed every ``pop_size`` evaluations, the call that does not fit cut to
    what fits and then the end (its greenlet only changed who evaluates the rows)."""
    settings = dict(settings)
    rel_step = settings.pop("rel_step", REL_STEP)
    tracker = Tracker(f, lb, ub, budget)
    lb, ub, P, D = tracker.lb, tracker.ub, budget.pop_size, tracker.dim
    h = rel_step * (ub - lb)
    cap = np.inf if budget.max_nfe is None else budget.max_nfe
    if budget.iterations is not None:
        cap = min(cap, (budget.iterations + 1) * P)
    next_mark = [P]

    def fun(x):
        x = np.clip(x, lb, ub)
        steps = np.where(x + h <= ub, h, -h)
        X = np.vstack([x, x + np.diag(steps)])
        k = int(min(D + 1, cap - tracker.nfe))
        if k <= 0:
            raise Spent
        values = np.full(D + 1, np.inf)
        values[:k] = tracker.evaluate(X[:k])
        while tracker.nfe >= next_mark[0]:
            tracker.end_iteration()
            next_mark[0] += P
        if k < D + 1:
            raise Spent
        if not np.isfinite(values[0]):
            return BIG, np.zeros(D)
        g = (values[1:] - values[0]) / steps
        g[~np.isfinite(g)] = 0.0
        return float(values[0]), g

    bounds = Bounds(lb, ub)
    while not tracker.done:
        x0 = tracker.random_uniform(rng, 1)[0]
        try:
            with np.errstate(invalid="ignore", over="ignore"):
                scipy_minimize(
                    fun, x0, jac=True, method="L-BFGS-B", bounds=bounds, options=settings
                )
        except Spent:
            break
    return tracker.result()


def assert_same_run(a: OptimResult, b: OptimResult) -> None:
    np.testing.assert_array_equal(a.best_x, b.best_x)
    assert a.best_f == b.best_f
    assert (a.nfe, a.iterations) == (b.nfe, b.iterations)
    np.testing.assert_array_equal(a.history_best, b.history_best)
    np.testing.assert_array_equal(a.history_nfe, b.history_nfe)


def assert_block_is_scipy(f, budget: Budget, lb=LB, ub=UB, **settings) -> list[np.ndarray]:
    """Each seed of a block equals the reference, and each step's call holds the rows every
    unfinished seed's reference evaluated at that step, seed by seed. Returns the calls."""
    block_rec = Recorder(f)
    block = minimize_together(
        "quasi_newton", block_rec, lb, ub, budget, [np.random.default_rng(s) for s in SEEDS],
        **settings,
    )  # fmt: skip
    recs = [Recorder(f) for _ in SEEDS]
    refs = [
        scipy_run(rec, lb, ub, budget, np.random.default_rng(s), **settings)
        for s, rec in zip(SEEDS, recs, strict=True)
    ]
    for got, want in zip(block, refs, strict=True):
        assert_same_run(got, want)
    steps = max(len(rec.calls) for rec in recs)
    assert len(block_rec.calls) == steps
    for t, call in enumerate(block_rec.calls):
        want = np.vstack([rec.calls[t] for rec in recs if t < len(rec.calls)])
        np.testing.assert_array_equal(call, want)
    return block_rec.calls


def with_holes(f):
    """``f``, but +inf where x0 > 2 and NaN where x1 < 0.1: failed simulations."""

    def g(X):
        X = np.atleast_2d(X)
        out = f(X).astype(float)
        out[X[:, 0] > 2.0] = np.inf
        out[X[:, 1] < 0.1] = np.nan
        return out

    return g


FUNCTIONS = {
    "rosenbrock": rosenbrock,
    "rastrigin": shifted(rastrigin, [0.5, 0.3, 14.0, 1.0]),
    "sphere outside the box": shifted(sphere, [7.0, 0.5, 25.0, -3.0]),  # optimum on faces
    "rosenbrock with holes": with_holes(rosenbrock),
}
BUDGETS = {
    "iterations": Budget(pop_size=10, iterations=40),
    "max_nfe inside a gradient": Budget(pop_size=10, iterations=None, max_nfe=403),
    "both, D + 1 > pop_size": Budget(pop_size=3, iterations=60, max_nfe=1000),
    "both, max_nfe first": Budget(pop_size=7, iterations=200, max_nfe=333),
}


@pytest.mark.parametrize("f", FUNCTIONS.values(), ids=FUNCTIONS)
@pytest.mark.parametrize("budget", BUDGETS.values(), ids=BUDGETS)
def test_block_equals_scipy_minimize_one_seed_at_a_time(f, budget):
    assert_block_is_scipy(f, budget)


SETTINGS = {
    # scipy stops each search after 2 iterations (task 504): many short restarts
    "maxiter": {"maxiter": 2},
    # ... after more than 3 points evaluated (task 502), checked at each new iterate
    "maxfun": {"maxfun": 3},
    "short memory, short line search": {"maxcor": 2, "maxls": 1},
    "loose tolerances": {"ftol": 1e-3, "gtol": 1e-2},
    "large step": {"rel_step": 1e-3},
}


@pytest.mark.parametrize("settings", SETTINGS.values(), ids=SETTINGS)
def test_block_equals_scipy_minimize_with_settings(settings):
    assert_block_is_scipy(rosenbrock, Budget(pop_size=10, iterations=None, max_nfe=603), **settings)


def test_the_stop_settings_shorten_the_searches(monkeypatch):
    # the settings above do reach scipy's stop rules: the same budget holds more searches
    starts = []

    class Counted(quasi_newton.LbfgsbSearch):
        __slots__ = ()

        def __init__(self, x0, core):
            starts.append(x0)
            super().__init__(x0, core)

    monkeypatch.setattr(quasi_newton, "LbfgsbSearch", Counted)

    def searches(**settings):
        starts.clear()
        minimize_together(
            "quasi_newton", rosenbrock, LB, UB, Budget(10, None, 603), [np.random.default_rng(0)],
            **settings,
        )  # fmt: skip
        return len(starts)

    plain = searches()
    assert searches(maxiter=2) > 2 * plain
    assert searches(maxfun=3) > 2 * plain


def test_a_point_with_a_nan_coordinate_is_evaluated_twice_as_scipy_does(monkeypatch):
    # the core never proposes such a point here (it gets finite f and g); make it, in the core
    # both drivers call, to hold the copy of MemoizeJac's `x == x` re-evaluation to scipy's
    from scipy.optimize import _lbfgsb

    setulb = _lbfgsb.setulb

    def nan_setulb(m, x, *args):
        setulb(m, x, *args)
        task = args[9]
        if task[0] == 3 and x[0] > 3.0:  # an FG request in part of the box
            x[2] = np.nan

    monkeypatch.setattr(_lbfgsb, "setulb", nan_setulb)
    calls = assert_block_is_scipy(shifted(sphere, [4.5, 0.5, 15.0, 1.0]), Budget(10, 30))
    twice = [
        a for a, b in itertools.pairwise(calls)
        if np.isnan(a).any() and a.shape == b.shape and np.array_equal(a, b, equal_nan=True)
    ]  # fmt: skip
    assert twice  # the case happened


def test_the_defaults_are_scipys():
    # minimize's L-BFGS-B options are fmin_l_bfgs_b's arguments under other names
    sig = inspect.signature(scipy.optimize.fmin_l_bfgs_b).parameters
    scipys = {
        "ftol": sig["factr"].default * np.finfo(float).eps,
        "gtol": sig["pgtol"].default,
        "maxcor": sig["m"].default,
        "maxls": sig["maxls"].default,
        "maxiter": sig["maxiter"].default,
        "maxfun": sig["maxfun"].default,
    }
    assert scipys == LBFGSB_DEFAULTS


def test_a_line_search_of_no_steps_is_refused_as_scipy_does():
    with pytest.raises(ValueError, match="maxls must be positive"):
        scipy_run(sphere, LB, UB, Budget(10, 5), np.random.default_rng(0), maxls=0)
    with pytest.raises(ValueError, match="maxls must be positive"):
        minimize_together("quasi_newton", sphere, LB, UB, Budget(10, 5), [np.random.default_rng(0)],
                          maxls=0)  # fmt: skip
