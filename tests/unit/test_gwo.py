"""Grey Wolf Optimizer's own machinery: leader update, moves, the a-schedule and its horizon.

The contract it shares with the other optimizers (bounds, budgets, reproducibility, history,
convergence) is in test_optimizer_contract.py.
"""

from __future__ import annotations

import numpy as np
import pytest
from optim_helpers import Recorder, shifted

from avoa_pipeline.optimizers import Budget, Runs, minimize
from avoa_pipeline.optimizers.gwo import update_leaders
from avoa_pipeline.optimizers.testfunctions import sphere

LB = np.array([-5.0, 0.0, 10.0, -1.0])
UB = np.array([5.0, 1.0, 20.0, 3.0])


def run(objective=sphere, lb=LB, ub=UB, budget=None, seed=0):
    budget = budget or Budget(pop_size=10, iterations=30)
    return minimize("gwo", objective, lb, ub, budget, np.random.default_rng(seed))


def test_schedule_length():
    def tracker(budget):
        return Runs(sphere, LB, UB, budget, 1)

    assert tracker(Budget(pop_size=20, iterations=500)).planned_iterations(20) == 500
    assert tracker(Budget(20, iterations=None, max_nfe=2000)).planned_iterations(20) == 99
    assert tracker(Budget(20, iterations=None, max_nfe=2010)).planned_iterations(20) == 100
    assert tracker(Budget(20, iterations=50, max_nfe=10**6)).planned_iterations(20) == 50
    assert tracker(Budget(20, iterations=None, max_nfe=5)).planned_iterations(20) == 1


def test_leader_update_is_the_reference_rule():
    # the reference does not demote alpha to beta when a better alpha arrives; two runs at once,
    # each with its own leaders (the second sees the values in reverse order)
    pos, score = np.zeros((2, 3, 1)), np.full((2, 3), np.inf)
    X = np.array([[5.0], [4.0], [3.0], [6.0], [3.5], [7.0], [3.0]])
    both = np.stack([X, X[::-1]])
    update_leaders(both[:, :, 0], both, pos, score)
    # 5 -> alpha; 4 -> alpha; 3 -> alpha; 6 -> beta; 3.5 -> beta; 7 -> delta; 3 (tie) ignored
    np.testing.assert_array_equal(score[0], [3.0, 3.5, 7.0])
    np.testing.assert_array_equal(pos[0, :, 0], [3.0, 3.5, 7.0])
    # 3 -> alpha; 7 -> beta; 3.5 -> beta; 6 -> delta; 3 (tie) ignored; 4 -> delta; 5 ignored
    np.testing.assert_array_equal(score[1], [3.0, 3.5, 4.0])
    np.testing.assert_array_equal(pos[1, :, 0], [3.0, 3.5, 4.0])


def test_a_schedule_reaches_a_shifted_optimum():
    # GWO is biased towards the origin; a shifted optimum checks the schedule and the moves
    # (the shared shifted-sphere bar is in test_optimizer_contract.py; this shift separates a
    # working a-schedule from a constant one more clearly)
    shift = np.array([31.0, -47.0, 12.5, 60.0, -8.0])
    finals = [
        run(
            shifted(sphere, shift),
            np.full(5, -100.0),
            np.full(5, 100.0),
            Budget(pop_size=20, iterations=100),
            seed,
        ).best_f
        for seed in range(5)
    ]
    # ours: median ~0.04; with a constant a = 2 (no exploitation phase): ~20
    assert np.median(finals) < 1.0


def test_moves_match_the_reference_step():
    """Two iterations recomputed with the reference's scalar loops and the same random numbers."""
    P, D, T = 6, 4, 10
    rec = Recorder(shifted(sphere, 0.5))
    run(rec, budget=Budget(pop_size=P, iterations=T), seed=11)

    rng = np.random.default_rng(11)
    X = LB + rng.random((P, D)) * (UB - LB)
    np.testing.assert_array_equal(rec.calls[0], X)
    alpha = beta = delta = np.zeros(D)
    s_alpha = s_beta = s_delta = np.inf
    for t in (1, 2):
        for i in range(P):  # the reference's fitness loop
            fit = float(np.sum((X[i] - 0.5) ** 2))
            if fit < s_alpha:
                s_alpha, alpha = fit, X[i].copy()
            if s_alpha < fit < s_beta:
                s_beta, beta = fit, X[i].copy()
            if s_alpha < fit and s_beta < fit < s_delta:
                s_delta, delta = fit, X[i].copy()
        a = 2 - (t - 1) * (2 / T)
        r1, r2 = rng.random((3, P, D)), rng.random((3, P, D))
        new = np.empty_like(X)
        for i in range(P):
            for j in range(D):
                parts = []
                for k, leader in enumerate((alpha, beta, delta)):
                    A = 2 * a * r1[k, i, j] - a
                    C = 2 * r2[k, i, j]
                    parts.append(leader[j] - A * abs(C * leader[j] - X[i, j]))
                new[i, j] = (parts[0] + parts[1] + parts[2]) / 3
        X = np.clip(new, LB, UB)
        np.testing.assert_allclose(rec.calls[t], X, rtol=1e-12, atol=1e-12)


def test_takes_no_settings():
    with pytest.raises(TypeError, match="no settings"):
        minimize(
            "gwo", sphere, LB, UB, Budget(pop_size=5, iterations=2), np.random.default_rng(0), a=1
        )
