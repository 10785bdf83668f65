"""Local searches with restarts (Nelder–Mead, quasi-Newton): their evaluation granularity, restarts,
quasi-Newton's finite-difference gradient at the bounds, non-finite values, settings.

The contract they share with the other optimizers (bounds, budgets, reproducibility, history,
convergence) is in test_optimizer_contract.py.
"""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from optim_helpers import Recorder, shifted

from avoa_pipeline.optimizers import Budget, minimize
from avoa_pipeline.optimizers.testfunctions import rastrigin, rosenbrock, sphere

LOCAL = ("nelder_mead", "quasi_newton")
LB = np.array([-5.0, 0.0, 10.0, -1.0])
UB = np.array([5.0, 1.0, 20.0, 3.0])


def run(name, objective=sphere, lb=LB, ub=UB, budget=None, seed=0, **settings):
    budget = budget or Budget(pop_size=10, iterations=30)
    return minimize(name, objective, lb, ub, budget, np.random.default_rng(seed), **settings)


@pytest.mark.parametrize("name", LOCAL)
def test_iteration_budget_is_pop_size_evaluations_per_iteration(name):
    rec = Recorder(rosenbrock)
    res = run(name, rec, budget=Budget(pop_size=7, iterations=40))
    assert res.iterations == 40
    assert res.nfe == 7 * 41 == rec.all.shape[0]  # iteration 0 + 40 iterations of pop_size
    # iteration k closes with the call that reaches 7 (k + 1) evaluations: one point at a time
    # for Nelder–Mead, D + 1 = 5 points (f and a gradient) at a time for quasi-Newton
    chunk = 1 if name == "nelder_mead" else LB.size + 1
    lag = res.history_nfe - 7 * np.arange(1, 42)
    assert np.all(lag >= 0)
    assert np.all(lag < chunk)
    assert lag[-1] == 0


@pytest.mark.parametrize("name", LOCAL)
def test_restarts_use_the_whole_budget(name):
    # one local search on a 2-D sphere converges within ~100 evaluations; the rest are restarts
    rec = Recorder()
    lb, ub = np.full(2, -10.0), np.full(2, 10.0)
    res = run(name, rec, lb, ub, Budget(pop_size=20, iterations=None, max_nfe=3000))
    assert res.nfe == 3000
    assert res.best_f < 1e-8
    # each restart begins at a fresh uniform point; count the far-apart jumps to a new start
    assert len(rec.calls) > 1
    starts = [c[0] for c in rec.calls]
    jumps = sum(np.linalg.norm(b - a) > 1.0 for a, b in itertools.pairwise(starts))
    assert jumps >= 5


def test_quasi_newton_gradient_is_one_population_call_of_d_plus_1():
    rec = Recorder(rosenbrock)
    D = 4
    res = run("quasi_newton", rec, budget=Budget(pop_size=10, iterations=None, max_nfe=503))
    sizes = [c.shape[0] for c in rec.calls]
    assert set(sizes[:-1]) == {D + 1}
    assert sizes[-1] == 503 % (D + 1) or sizes[-1] == D + 1
    assert res.nfe == 503
    # each call: x, then x + s_i e_i with |s_i| = sqrt(eps) * (ub_i - lb_i)
    h = np.sqrt(np.finfo(float).eps) * (UB - LB)
    for c in rec.calls[:-1]:
        steps = c[1:] - c[0]
        np.testing.assert_allclose(np.abs(np.diag(steps)), h, rtol=1e-6)
        assert np.count_nonzero(steps - np.diag(np.diag(steps))) == 0


def test_quasi_newton_steps_inward_at_the_upper_bound():
    # minimum in the upper corner: L-BFGS-B ends on the bound, where the step must go down
    rec = Recorder(shifted(sphere, UB + 1.0))
    run("quasi_newton", rec, budget=Budget(pop_size=10, iterations=20))
    at_ub = [c for c in rec.calls if np.all(c[0] == UB)]
    assert at_ub, "never reached the upper corner"
    for c in at_ub:
        assert np.all(np.diag(c[1:] - c[0]) < 0)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_quasi_newton_gradient_is_right_at_the_upper_bound(seed):
    # minimum just inside the upper corner: the first quasi-Newton step overshoots onto the bound,
    # and only a backward difference with the right sign brings it back (30 evaluations)
    target = UB - 0.01 * (UB - LB)
    res = run(
        "quasi_newton",
        shifted(sphere, target),
        budget=Budget(pop_size=10, iterations=None, max_nfe=30),
        seed=seed,
    )
    assert res.best_f < 1e-10  # dividing by +h instead of the inward step: stuck at 0.0217


def test_quasi_newton_closes_several_iterations_in_one_gradient_call():
    # D + 1 = 5 evaluations per call > pop_size = 2: history entries share an evaluation count
    res = run("quasi_newton", budget=Budget(pop_size=2, iterations=None, max_nfe=40))
    assert res.nfe == 40
    assert res.iterations == 19  # iteration 0 + 19 more, one per 2 evaluations
    assert np.all(np.diff(res.history_nfe) >= 0)
    assert res.history_nfe[-1] == 40


@pytest.mark.parametrize("name", LOCAL)
def test_survives_non_finite_objective_values(name):
    # a "simulation" that fails (NaN) on part of the box, +inf on another part
    def flaky(X):
        f = rastrigin(X)
        f[X[:, 0] > 2.0] = np.nan
        f[X[:, 1] > 0.8] = np.inf
        return f

    res = run(name, flaky, budget=Budget(pop_size=10, iterations=60))
    assert np.isfinite(res.best_f)
    assert res.best_x[0] <= 2.0
    assert res.best_x[1] <= 0.8
    assert res.nfe == 610


def test_settings_are_forwarded_and_checked():
    few = run("nelder_mead", rosenbrock, budget=Budget(10, iterations=50), maxfev=30)
    assert few.nfe == 510
    with pytest.raises(TypeError, match="unknown settings"):
        run("nelder_mead", xtol=1.0)
    with pytest.raises(TypeError, match="unknown settings"):
        run("quasi_newton", fatol=1.0)
    with pytest.raises(ValueError, match="rel_step"):
        run("quasi_newton", rel_step=0.0)
