"""Real-coded GA (MATLAB-ga-like): elitism and offspring split, selection, mutations, settings.

The contract it shares with the other optimizers (bounds, budgets, reproducibility, history,
convergence -- all with the default adaptfeasible mutation) is in test_optimizer_contract.py.
"""

import math

import numpy as np
import pytest
from optim_helpers import Recorder, assert_seed_determines_result, shifted

from avoa_pipeline.optimizers import Budget, minimize
from avoa_pipeline.optimizers.ga import rank_expectation, stochastic_uniform
from avoa_pipeline.optimizers.testfunctions import rastrigin, sphere

LB = np.array([-5.0, 0.0, 2.0, -1.0, 10.0])
UB = np.array([5.0, 1.0, 3.0, 4.0, 20.0])
CENTRE = np.array([7.0, -2.0, 2.5, 0.0, 25.0])  # partly outside the box: pushes points to bounds


shifted_sphere = shifted(sphere, CENTRE)


@pytest.mark.parametrize("P", [10, 20, 41])
def test_iteration_budget_and_matlab_offspring_split(P):
    T = 12
    r = minimize("ga", sphere, [-10.0] * 6, [10.0] * 6, Budget(P, T), np.random.default_rng(2))
    n_elite = math.ceil(0.05 * P)
    assert r.iterations == T
    assert r.history_best.size == T + 1
    # elites keep their scores: P - n_elite evaluations per generation, as MATLAB ga
    assert np.all(np.diff(r.history_nfe) == P - n_elite)
    assert r.nfe == P + T * (P - n_elite)


def test_elite_count_setting():
    r = minimize(
        "ga", sphere, [-1.0] * 3, [1.0] * 3, Budget(20, 5), np.random.default_rng(0), elite_count=4
    )
    assert np.all(np.diff(r.history_nfe) == 16)


def test_gaussian_mutation_keeps_every_evaluated_point_within_bounds():
    # the default mutation (adaptfeasible) is held to the contract in test_optimizer_contract.py
    rec = Recorder(shifted_sphere)
    budget = Budget(pop_size=20, iterations=80)
    minimize("ga", rec, LB, UB, budget, np.random.default_rng(3), mutation="gaussian")
    pts = rec.all
    assert pts.shape[0] == 20 + 80 * 19
    assert np.all(pts >= LB)
    assert np.all(pts <= UB)
    # the box optimum is on its faces; the GA must get close to them
    assert pts[:, 0].max() > UB[0] - 0.05
    assert pts[:, 1].min() < LB[1] + 0.05


def test_gaussian_mutation_same_seed_identical_different_seed_different():
    args = ("ga", rastrigin, [-5.12] * 5, [5.12] * 5, Budget(pop_size=20, iterations=30))
    a = minimize(*args, np.random.default_rng(42), mutation="gaussian")
    b = minimize(*args, np.random.default_rng(42), mutation="gaussian")
    c = minimize(*args, np.random.default_rng(43), mutation="gaussian")
    assert_seed_determines_result(a, b, c)


def test_best_improves_substantially():
    # measured: about 1e-5 of the initial best after 60 generations; a stuck GA fails this
    r = minimize("ga", sphere, [-10.0] * 5, [10.0] * 5, Budget(20, 60), np.random.default_rng(7))
    assert r.history_best[-1] < 1e-2 * r.history_best[0]


def test_rank_scaling_and_stochastic_uniform_selection():
    # two runs at once, the second with the scores in reverse order: each ranks its own
    score = np.array([[3.0, 1.0, 2.0, 10.0], [10.0, 2.0, 1.0, 3.0]])
    e, order = rank_expectation(score, 8)
    assert order.tolist() == [[1, 2, 0, 3], [2, 1, 3, 0]]
    np.testing.assert_allclose(e[1], e[0, ::-1], rtol=1e-15)
    e = e[0]
    assert e.sum() == pytest.approx(8.0)
    assert e[1] / e[2] == pytest.approx(np.sqrt(2.0))
    assert e[1] / e[3] == pytest.approx(2.0)
    offsets = np.random.default_rng(0).random(50)
    picks = stochastic_uniform(offsets, np.tile(e, (50, 1)), 8)
    # numpy's own roulette lookup (searchsorted) on one run's wheel
    wheel = np.cumsum(e) / e.sum()
    for offset, got in zip(offsets, picks, strict=True):
        want = np.searchsorted(wheel, offset / 8 + np.arange(8) / 8, side="left")
        np.testing.assert_array_equal(got, np.minimum(want, 3))
    for counts in (np.bincount(p, minlength=4) for p in picks):
        # stochastic uniform sampling: each count is floor or ceil of its expectation
        assert np.all(counts >= np.floor(e))
        assert np.all(counts <= np.ceil(e))
        assert counts.sum() == 8


def test_invalid_settings_rejected():
    args = ("ga", sphere, [-1.0] * 2, [1.0] * 2, Budget(10, 3), np.random.default_rng(0))
    with pytest.raises(ValueError, match="mutation"):
        minimize(*args, mutation="uniform")
    with pytest.raises(ValueError, match="elite_count"):
        minimize(*args, elite_count=10)
    with pytest.raises(ValueError, match="crossover_fraction"):
        minimize(*args, crossover_fraction=1.5)
