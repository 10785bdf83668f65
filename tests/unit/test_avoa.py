"""AVOA's own machinery (reference MATLAB semantics): Lévy sigma, best-two memory, horizon,
settings.

The contract it shares with the other optimizers (bounds, budgets, reproducibility, history,
convergence) is in test_optimizer_contract.py.
"""

import numpy as np
import pytest
from optim_helpers import runner

from avoa_pipeline.optimizers import Budget
from avoa_pipeline.optimizers.avoa import BestTwo, levy_sigma
from avoa_pipeline.optimizers.base import Runs
from avoa_pipeline.optimizers.testfunctions import sphere

run = runner("avoa")


def test_levy_sigma_is_the_reference_one():
    # Mantegna sigma with Gamma((1+b)/2) in the denominator (the code), not Fahmy's eq. 31 (0.5396)
    assert levy_sigma(1.5) == pytest.approx(0.6965745025576967, rel=1e-12)


def test_best_two_memory_follows_the_reference_update():
    X = np.arange(5.0)[:, None] * np.ones((1, 2))
    # two runs at once: each keeps its own memories
    best = BestTwo(2, 2)
    f = np.array([[5.0, 3.0, 4.0, 1.0, 2.0], [3.0, 2.0, 1.0, 1.0, np.inf]])
    best.update(f, np.stack([X, X]))
    assert best.f1[0] == 1.0
    assert np.array_equal(best.x1[0], X[3])
    assert best.f2[0] == 2.0
    assert np.array_equal(best.x2[0], X[4])
    # an old best is not demoted to second best (the code's quirk); a tie is neither
    assert best.f1[1] == 1.0
    assert np.array_equal(best.x1[1], X[2])
    assert best.f2[1] == np.inf
    assert not best.set2[1]
    assert best.set1.all()
    assert best.set2[0]


def test_best_two_memory_equals_the_references_vulture_by_vulture_loop():
    # the reference's loop, written out; values from a few integers make ties and infs common
    rng = np.random.default_rng(7)
    for _ in range(200):
        n, P = 3, 6
        f = rng.integers(0, 5, (n, P)).astype(float)
        f[rng.random((n, P)) < 0.2] = np.inf
        X = rng.random((n, P, 2))
        best = BestTwo(n, 2)
        best.f1[:] = rng.choice([np.inf, 1.0, 3.0], n)  # memories from an earlier iteration
        best.f2[:] = np.maximum(best.f1, rng.choice([np.inf, 2.0, 4.0], n))
        expect = []
        for s in range(n):
            f1, f2, k1, k2 = best.f1[s], best.f2[s], None, None
            for k in range(P):
                if f[s, k] < f1:
                    f1, k1 = f[s, k], k
                if f1 < f[s, k] < f2:
                    f2, k2 = f[s, k], k
            expect.append((f1, f2, k1, k2))
        x1, x2 = best.x1.copy(), best.x2.copy()
        best.update(f, X)
        for s, (f1, f2, k1, k2) in enumerate(expect):
            assert (best.f1[s], best.f2[s]) == (f1, f2)
            np.testing.assert_array_equal(best.x1[s], x1[s] if k1 is None else X[s, k1])
            np.testing.assert_array_equal(best.x2[s], x2[s] if k2 is None else X[s, k2])


def test_horizon_under_an_evaluation_budget():
    t = Runs(sphere, [0.0], [1.0], Budget(pop_size=20, iterations=None, max_nfe=10020), 1)
    assert t.planned_iterations(20) == 500
    t = Runs(sphere, [0.0], [1.0], Budget(pop_size=20, iterations=100, max_nfe=10020), 1)
    assert t.planned_iterations(20) == 100


@pytest.mark.parametrize(
    "settings",
    [{"p1": 1.5}, {"p2": -0.1}, {"alpha": 0.7}, {"alpha": 0.5, "beta": 0.2}, {"gamma": 0}],
)
def test_invalid_settings_are_rejected(settings):
    with pytest.raises(ValueError, match=r"must be"):
        run(sphere, [-1.0], [1.0], Budget(pop_size=5, iterations=2), **settings)
