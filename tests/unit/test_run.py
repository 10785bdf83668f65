"""RUN (Runge-Kutta optimizer): evaluations per iteration, NaN objectives, the mean variant.

The contract it shares with the other optimizers (bounds, budgets, reproducibility, history,
convergence, smallest population) is in test_optimizer_contract.py.
"""

import numpy as np

from avoa_pipeline.optimizers import Budget, minimize
from avoa_pipeline.optimizers.testfunctions import sphere


def test_iteration_budget_and_evaluations_per_iteration():
    P, T = 12, 25
    r = minimize("run", sphere, [-10.0] * 6, [10.0] * 6, Budget(P, T), np.random.default_rng(2))
    assert r.iterations == T
    assert r.history_best.size == T + 1
    assert r.history_nfe[0] == P
    per_iter = np.diff(r.history_nfe)
    # one evaluation per agent, plus ESQ (p = 0.5), plus the conditional Eq. 20 step: P..3P
    assert np.all(per_iter >= P)
    assert np.all(per_iter <= 3 * P)
    assert 1.2 * P < per_iter.mean() < 2.2 * P  # ~1.5-1.8 P observed; ESQ must actually happen


def test_nan_objective_is_never_accepted():
    def f(X):
        v = sphere(X)
        return np.where(X[:, 0] > 0, np.nan, v)

    r = minimize("run", f, [-5.0] * 3, [5.0] * 3, Budget(10, 30), np.random.default_rng(0))
    assert np.isfinite(r.best_f)
    assert r.best_x[0] <= 0


def test_population_mean_variant_runs():
    r = minimize(
        "run",
        sphere,
        [-10.0] * 3,
        [10.0] * 3,
        Budget(10, 20),
        np.random.default_rng(0),
        esq_overwrites_mean=False,
    )
    assert r.iterations == 20
    assert r.best_f < 1.0
