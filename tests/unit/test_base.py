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
