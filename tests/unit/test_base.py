"""The accounts of a block of runs: the iteration horizon, each run's progress, asks of one row."""

import numpy as np
import pytest

from avoa_pipeline.optimizers import Budget, Runs
from avoa_pipeline.optimizers.testfunctions import sphere


class OneRun:
    """One run's view of a :class:`Runs` of one, in the scalars the tests below read."""

    def __init__(self, **budget):
        self.runs = Runs(sphere, [-1.0, -1.0], [1.0, 1.0], Budget(**budget), 1)

    def planned_iterations(self, cost):
        return self.runs.planned_iterations(cost)

    def evaluate(self, X):
        return self.runs.evaluate(X[None])[0]

    def end_iteration(self):
        self.runs.end_iteration()

    def progress(self, **kw):
        return float(self.runs.progress(**kw)[0])

    @property
    def done(self):
        return bool(self.runs.done[0])

    @property
    def iteration(self):
        return int(self.runs.iteration[0])

    def result(self):
        return self.runs.result(0)


def tracker(**budget) -> OneRun:
    return OneRun(**budget)


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
def test_asks_of_one_row_keep_the_accounts_of_population_asks(one):
    # an ask of one row goes through objective_one where given: the same values and accounts
    budget = Budget(pop_size=2, iterations=None, max_nfe=3)
    fast = Runs(sphere, [-1.0, -1.0], [1.0, 1.0], budget, 1, objective_one=one)
    slow = Runs(sphere, [-1.0, -1.0], [1.0, 1.0], budget, 1)
    points = np.array([[0.5, 0.5], [0.1, -0.2], [0.9, 0.0], [0.0, 0.0]])
    got = [float(fast.evaluate(x[None, None, :])[0, 0]) for x in points]
    want = [float(slow.evaluate(x[None, None, :])[0, 0]) for x in points]
    assert got == want
    assert got[-1] == np.inf  # past max_nfe: not evaluated, never best
    assert (fast.nfe[0], fast.best_f[0]) == (slow.nfe[0], slow.best_f[0]) == (3, slow.best_f[0])
    np.testing.assert_array_equal(fast.best_x[0], [0.1, -0.2])


def test_a_nan_is_the_worst_value():
    runs = Runs(sphere, [-1.0], [1.0], Budget(pop_size=1, iterations=1), 1, lambda x: np.nan)
    assert runs.evaluate(np.array([[[0.3]]]))[0, 0] == np.inf
    assert runs.nfe[0] == 1
    with pytest.raises(RuntimeError, match="no point"):
        runs.result(0)


def test_a_local_search_closes_an_iteration_every_pop_size_evaluations():
    # D + 1 = 7 rows per ask, pop_size 3: one ask may close two iterations; the cap is
    # (iterations + 1) pop_size or max_nfe, whichever is smaller
    runs = Runs(sphere, [-1.0] * 6, [1.0] * 6, Budget(pop_size=3, iterations=5), 2)
    assert runs.evaluation_cap(3) == 18
    assert Runs(sphere, [-1.0], [1.0], Budget(3, 5, max_nfe=10), 1).evaluation_cap(3) == 10
    runs.evaluate(np.zeros((2, 7, 6)), live=np.array([True, False]))
    runs.close_spent(3)  # run 0: 7 evaluations passed the marks 3 and 6
    np.testing.assert_array_equal(runs.iteration, [1, 0])
    runs.evaluate(np.zeros((2, 1, 6)))
    runs.close_spent(3)  # 8 and 1 evaluations: no mark passed
    np.testing.assert_array_equal(runs.nfe, [8, 1])
    np.testing.assert_array_equal(runs.iteration, [1, 0])
    runs.evaluate(np.zeros((2, 2, 6)))
    runs.close_spent(3)  # 10 and 3: run 0 passed 9, run 1 its first mark (iteration 0)
    np.testing.assert_array_equal(runs.iteration, [2, 0])
    np.testing.assert_array_equal(runs.result(0).history_nfe, [7, 7, 10])
    np.testing.assert_array_equal(runs.result(1).history_nfe, [3])
