"""Tracker schedules: the iteration horizon and the run's progress, written once for all."""

import numpy as np
import pytest

from avoa_pipeline.optimizers import Budget, Tracker
from avoa_pipeline.optimizers.testfunctions import sphere


def tracker(**budget) -> Tracker:
    return Tracker(sphere, [-1.0, -1.0], [1.0, 1.0], Budget(**budget))


@pytest.mark.parametrize(
    ("budget", "evals_per_iteration", "horizon"),
    [
        (dict(pop_size=20, iterations=500), 20, 500),
        (dict(pop_size=20, iterations=500), 40, 500),  # an iteration budget ignores the cost
        (dict(pop_size=20, iterations=None, max_nfe=10_020), 20, 500),  # (10,020 - 20) / 20
        (dict(pop_size=20, iterations=None, max_nfe=2000), 20, 99),  # 1,980 / 20, exact
        (dict(pop_size=20, iterations=None, max_nfe=2010), 20, 100),  # rounded up: partial last
        (dict(pop_size=20, iterations=None, max_nfe=2000), 40, 50),  # GTO: 2 P per iteration
        (dict(pop_size=20, iterations=None, max_nfe=2000), 30.5, 65),  # 64.9: a float cost
        (dict(pop_size=20, iterations=50, max_nfe=10**6), 20, 50),  # both: the smaller
        (dict(pop_size=20, iterations=500, max_nfe=1020), 20, 50),
        (dict(pop_size=20, iterations=None, max_nfe=20), 20, 1),  # never below 1
        (dict(pop_size=20, iterations=None, max_nfe=5), 20, 1),  # less than the population
    ],
)
def test_planned_iterations(budget, evals_per_iteration, horizon):
    assert tracker(**budget).planned_iterations(evals_per_iteration) == horizon


def test_planned_iterations_is_what_a_fixed_cost_algorithm_runs():
    # P evaluations per iteration: the horizon is the number of iterations the budget lets it run,
    # the last one partial when max_nfe - P is not a multiple of P (1013: 100 full + 3 evaluations)
    for max_nfe in (1000, 1013):
        t = tracker(pop_size=10, iterations=None, max_nfe=max_nfe)
        T = t.planned_iterations(10)
        t.evaluate(np.zeros((10, 2)))
        t.end_iteration()
        while not t.done:
            t.evaluate(np.zeros((10, 2)))
            t.end_iteration()
        assert t.iteration == T
        assert t.result().iterations == T


def test_planned_iterations_rejects_a_non_positive_cost():
    with pytest.raises(ValueError, match="evals_per_iteration"):
        tracker(pop_size=20, iterations=10).planned_iterations(0)


def test_progress_under_an_iteration_budget():
    t = tracker(pop_size=4, iterations=10)
    t.evaluate(np.zeros((4, 2)))
    t.end_iteration()  # the initial population: iteration 0
    assert t.progress() == 1 / 10  # iteration t = 1 of T = 10
    assert t.progress(count_initial=True) == 2 / 11  # the reference's it = 2 of MaxIt = 11
    for _ in range(9):
        t.evaluate(np.zeros((4, 2)))
        t.end_iteration()
    assert t.progress() == 1.0  # the last iteration
    assert t.progress(count_initial=True) == 1.0


def test_progress_under_an_evaluation_budget_extrapolates_the_last_iteration():
    t = tracker(pop_size=4, iterations=None, max_nfe=100)
    t.evaluate(np.zeros((4, 2)))
    t.end_iteration()
    assert t.progress() == (4 + 4) / 100  # first iteration: as costly as the initial population
    t.evaluate(np.zeros((10, 2)))  # an iteration of 10 evaluations
    t.end_iteration()
    assert t.progress() == (14 + 10) / 100
    assert t.progress(count_initial=True) == t.progress()  # no iteration count to shift
    t.evaluate(np.zeros((80, 2)))
    t.end_iteration()
    assert t.progress() == 1.0  # 94 + 80 would overrun: capped


def test_progress_with_both_budgets_is_the_larger_fraction():
    t = tracker(pop_size=4, iterations=100, max_nfe=40)
    t.evaluate(np.zeros((4, 2)))
    t.end_iteration()
    assert t.progress() == 8 / 40  # the evaluations run out first
    t = tracker(pop_size=4, iterations=2, max_nfe=10**6)
    t.evaluate(np.zeros((4, 2)))
    t.end_iteration()
    assert t.progress() == 1 / 2  # the iterations run out first


def _counting_objective_one(x):
    return float(sphere(np.asarray(x)[None, :])[0])


@pytest.mark.parametrize("one", [None, _counting_objective_one])
def test_evaluate_one_keeps_the_accounts_of_evaluate(one):
    budget = Budget(pop_size=2, iterations=None, max_nfe=3)
    fast = Tracker(sphere, [-1.0, -1.0], [1.0, 1.0], budget, objective_one=one)
    slow = Tracker(sphere, [-1.0, -1.0], [1.0, 1.0], budget)
    points = np.array([[0.5, 0.5], [0.1, -0.2], [0.9, 0.0], [0.0, 0.0]])
    got = [fast.evaluate_one(x) for x in points]
    want = [float(slow.evaluate(x[None, :])[0]) for x in points]
    assert got == want
    assert got[-1] == np.inf  # past max_nfe: not evaluated, never best
    assert (fast.nfe, fast.best_f) == (slow.nfe, slow.best_f) == (3, slow.best_f)
    np.testing.assert_array_equal(fast.best_x, [0.1, -0.2])


def test_evaluate_one_treats_nan_as_worst():
    tr = Tracker(sphere, [-1.0], [1.0], Budget(pop_size=1, iterations=1), lambda x: np.nan)
    assert tr.evaluate_one(np.array([0.3])) == np.inf
    assert tr.best_x is None
    assert tr.nfe == 1
