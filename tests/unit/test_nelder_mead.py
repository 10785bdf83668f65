"""Nelder–Mead over arrays of seeds against scipy.optimize.minimize(method="Nelder-Mead") itself,
bit for bit: every point asked, in scipy's order, and where each local search ends (scipy's
convergence test, maxiter, maxfev); and a fit block's records against scipy driven one seed at a
time through the greenlet path the module replaced (kept here as the reference), over budgets
that end inside a restart's initial simplex and inside a shrink.

Its bounds, budgets and history contract is in test_optimizer_contract.py, its restarts and
settings in test_local.py.
"""

from __future__ import annotations

import numpy as np
import pytest
from one_seed_driver import (
    LocalSearchAccounting,
    Tracker,
    restart_loop,
    search_steps,
    step_together,
)
from optim_helpers import Recorder, shifted
from scipy.optimize import Bounds, OptimizeWarning, minimize

from avoa_pipeline.optimizers import Budget, minimize_together
from avoa_pipeline.optimizers.nelder_mead import Simplexes, centroid, scipy_limits
from avoa_pipeline.optimizers.testfunctions import rastrigin, rosenbrock, sphere

LB, UB = np.array([-5.0, 0.0, 10.0, -1.0]), np.array([5.0, 1.0, 20.0, 3.0])


def outside_optimum(X):
    """A sphere whose optimum lies outside the box in three coordinates: the moves overshoot and
    are clipped onto the faces, where vertices coincide and values tie."""
    return shifted(sphere, [7.0, -2.0, 15.0, 4.0])(X)


def rastrigin_inside(X):
    """Rastrigin with its optimum inside the box: many local searches, many shrinks."""
    return rastrigin(X - np.array([0.5, 0.3, 14.0, 1.0]))


def plateaus(X):
    """:func:`rastrigin_inside` rounded down to integers: many ties, where np.argsort's order
    (not stable) decides which vertex is dropped."""
    return np.floor(rastrigin_inside(X))


def failing(X):
    """Rosenbrock with failed simulations: NaN on part of the box, +inf on another."""
    f = rosenbrock(X)
    f[X[:, 0] > 2.0] = np.nan
    f[X[:, 1] > 0.8] = np.inf
    return f


def failing_corners(X):
    """Rosenbrock with failed simulations (NaN, +inf) in two corners of the box only. Under
    :func:`failing` a seed that starts in the failing part sees nothing but +inf for a whole
    search (it shrinks onto its start), and a short budget leaves it no point to report."""
    f = rosenbrock(X)
    f[(X[:, 0] > 4.0) & (X[:, 3] > 2.0)] = np.nan
    f[(X[:, 1] > 0.9) & (X[:, 2] > 18.0)] = np.inf
    return f


FUNCTIONS = [rosenbrock, outside_optimum, plateaus, failing]
SETTINGS = [
    {},
    {"adaptive": True},
    {"maxfev": 23},  # restarts every 23 evaluations, inside an iteration
    {"maxiter": 9, "xatol": 1e-2, "fatol": 1e-2},
    {"maxiter": 40, "maxfev": np.inf},
]
functions = pytest.mark.parametrize("f", FUNCTIONS, ids=lambda f: f.__name__)
settings = pytest.mark.parametrize("options", SETTINGS, ids=str)


def _values(f, x):
    """The tracker's value of one point: a NaN is +inf."""
    v = float(f(x[None, :])[0])
    return np.inf if v != v else v


def _scipy_search(f, lb, ub, x0, options) -> list[np.ndarray]:
    """The points scipy's Nelder–Mead evaluates from ``x0``, in order, to its end."""
    points = []

    def fun(x):
        points.append(x.copy())
        return _values(f, x)

    with np.errstate(invalid="ignore", over="ignore"):
        minimize(fun, x0, method="Nelder-Mead", bounds=Bounds(lb, ub), options=dict(options))
    return points


def _batched_searches(f, lb, ub, X0, options) -> list[list[np.ndarray]]:
    """The points :class:`Simplexes` asks for from each row of ``X0``, every start at once, each
    to the end of its search."""
    n = len(X0)
    search = Simplexes(lb, ub, n, **options)
    search.restart(np.arange(n), X0)
    alive = np.ones(n, dtype=bool)
    points: list[list[np.ndarray]] = [[] for _ in range(n)]
    while alive.any():
        values = np.full(n, np.inf)
        for s in np.flatnonzero(alive):
            points[s].append(search.point[s].copy())
            values[s] = _values(f, search.point[s])
        search.fcalls += alive
        alive &= ~search.advance(values, alive)
    return points


def _starts(lb, ub, rng, n=6):
    """Uniform starts, plus starts on the lower and the upper bound, a coordinate at 0 and a
    coordinate just below the upper bound (its 5 % step leaves the box: scipy reflects it)."""
    X0 = lb + rng.random((n, lb.size)) * (ub - lb)
    X0[0, 1:3] = lb[1:3]
    X0[1] = ub
    X0[2, 0] = 0.0
    X0[3, 2] = ub[2] * (1 - 1e-3)
    X0[4, [0, 3]] = lb[0], ub[3]
    return X0


@functions
@settings
def test_every_point_is_scipys(f, options):
    X0 = _starts(LB, UB, np.random.default_rng(4))
    got = _batched_searches(f, LB, UB, X0, options)
    for x0, points in zip(X0, got, strict=True):
        want = _scipy_search(f, LB, UB, x0, options)
        assert len(points) == len(want)  # the search ends where scipy's does
        np.testing.assert_array_equal(np.array(points), np.array(want))


def test_a_start_outside_the_box_is_clipped_as_scipy_clips_it():
    X0 = np.array([[-7.0, 0.5, 25.0, 1.0], [6.0, -1.0, 15.0, 3.5]])
    got = _batched_searches(rosenbrock, LB, UB, X0, {})
    for x0, points in zip(X0, got, strict=True):
        with pytest.warns(OptimizeWarning, match="not within the specified bounds"):
            want = _scipy_search(rosenbrock, LB, UB, x0, {})
        np.testing.assert_array_equal(np.array(points), np.array(want))


@pytest.mark.parametrize("dim", [1, 2, 7, 12])
def test_other_dimensions(dim):
    # the centroid of up to 12 vertices (np.add.reduce over vertices of many seeds at once)
    # and the adaptive coefficients of other dimensions
    lb, ub = np.full(dim, -3.0), np.linspace(2.0, 5.0, dim)
    X0 = _starts(lb, ub, np.random.default_rng(dim)) if dim > 3 else lb + 0.3 * (ub - lb)[None]
    for options in ({"maxfev": 400}, {"adaptive": True, "maxfev": 400}, {"maxfev": 60}):
        got = _batched_searches(rosenbrock, lb, ub, X0, options)
        for x0, points in zip(X0, got, strict=True):
            np.testing.assert_array_equal(
                np.array(points), np.array(_scipy_search(rosenbrock, lb, ub, x0, options))
            )


@pytest.mark.parametrize("dim", [1, 2, 3, 5, 8, 9, 12, 17])
def test_centroid_adds_as_scipy_adds(dim):
    # vertices of very different magnitudes and signs: the rounded sum depends on the order of
    # the additions (checked below), and each seed's centroid must be scipy's
    rng = np.random.default_rng(dim)
    sim = rng.standard_normal((30, dim + 1, dim)) * 10.0 ** rng.integers(-8, 17, (30, dim + 1, dim))
    got = centroid(sim)
    for s in range(30):
        np.testing.assert_array_equal(got[s], np.add.reduce(sim[s][:-1], 0) / dim)
    if dim > 2:
        backwards = np.add.reduce(sim[:, -2::-1], 1) / dim
        assert not np.array_equal(got, backwards)


def test_limits_are_scipys():
    assert scipy_limits(5, None, None) == (1000, 1000)
    assert scipy_limits(5, None, 30) == (np.inf, 30)
    assert scipy_limits(5, None, np.inf) == (1000, np.inf)
    assert scipy_limits(5, 7, None) == (7, np.inf)
    assert scipy_limits(5, np.inf, None) == (np.inf, 1000)
    with pytest.raises(ValueError, match="maxfev"):
        Simplexes(LB, UB, 1, maxfev=0)


# --- a fit block against scipy one seed at a time (the greenlet path this module replaced) -------


def scipy_one_seed(tracker: Tracker, rng, pop_size, marks=None, **options):
    """The code this module replaced, as the reference: scipy's Nelder–Mead in a greenlet, one
    seed, restarted until the budget is spent. ``marks``, if given, collects the evaluation count
    at each restart (``"start"``) and after each iteration (``"iteration"``, scipy's callback)."""

    def search(ask) -> None:
        acc = LocalSearchAccounting(tracker, pop_size, ask)

        def search_from(x0):
            if marks is not None:
                marks.append(("start", tracker.nfe))

            def iteration_ended(intermediate_result):
                marks.append(("iteration", tracker.nfe))

            minimize(
                acc.evaluate_one,
                x0,
                method="Nelder-Mead",
                bounds=Bounds(tracker.lb, tracker.ub),
                options=dict(options),
                callback=None if marks is None else iteration_ended,
            )

        restart_loop(tracker, rng, search_from)

    yield from search_steps(tracker, search)


def _reference(f, budget, seed, marks=None, **options):
    rec = Recorder(f)
    tracker = Tracker(rec, LB, UB, budget)
    steps = scipy_one_seed(tracker, np.random.default_rng(seed), budget.pop_size, marks, **options)
    step_together([(tracker, steps)], rec)
    return tracker.result(), rec


def _budgets_inside(f, options) -> list[int]:
    """From a long reference run of seed 0: evaluation budgets that end inside the initial simplex
    of its second search (and just before it) and inside a shrink (between two of its N points:
    an iteration of N + 2 evaluations is reflection, contraction, shrink)."""
    marks = []
    _reference(f, Budget(pop_size=7, iterations=None, max_nfe=1500), 0, marks, **options)
    starts = [n for kind, n in marks if kind == "start"]
    assert len(starts) >= 2, "no restart in the reference run"
    budgets = [starts[1] - 1, starts[1] + 2]
    prev, shrinks = None, []
    for kind, n in marks:
        if kind == "iteration" and prev is not None and n - prev == LB.size + 2:
            shrinks.append(prev + 3)  # reflection, contraction and the first shrunk vertex
        prev = n if kind == "iteration" else n + LB.size + 1  # a start: its simplex first
    assert shrinks, "no shrink in the reference run"
    return sorted({*budgets, shrinks[0], shrinks[-1]})


@pytest.mark.parametrize(
    ("f", "options"),
    [
        (rosenbrock, {"maxfev": 150}),
        (plateaus, {}),
        (rastrigin_inside, {"adaptive": True}),
        (failing_corners, {"maxiter": 60}),
    ],
    ids=["rosenbrock-maxfev", "plateaus", "rastrigin_inside-adaptive", "failing_corners-maxiter"],
)
def test_block_equals_scipy_one_seed_at_a_time(f, options):
    budgets = [Budget(pop_size=7, iterations=None, max_nfe=n) for n in _budgets_inside(f, options)]
    budgets += [Budget(pop_size=5, iterations=60), Budget(pop_size=9, iterations=30, max_nfe=200)]
    seeds = [0, 3, 1, 1]  # a repeated seed must give the same run twice
    for budget in budgets:
        block_rec = Recorder(f)
        block = minimize_together(
            "nelder_mead",
            block_rec,
            LB,
            UB,
            budget,
            [np.random.default_rng(s) for s in seeds],
            **options,
        )
        refs = [_reference(f, budget, seed, **options) for seed in seeds]
        for got, (want, _) in zip(block, refs, strict=True):
            np.testing.assert_array_equal(got.best_x, want.best_x)
            assert got.best_f == want.best_f
            assert (got.nfe, got.iterations) == (want.nfe, want.iterations)
            np.testing.assert_array_equal(got.history_best, want.history_best)
            np.testing.assert_array_equal(got.history_nfe, want.history_nfe)
        # every step asks one point of every seed still running: the seed-0 rows are its points
        first = np.array([c[0] for c in block_rec.calls[: block[0].nfe]])
        np.testing.assert_array_equal(first, refs[0][1].all)
