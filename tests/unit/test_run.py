"""RUN (Runge-Kutta optimizer): evaluations per iteration, NaN objectives, the mean variant, the
partner choice, seeds out of phase under an evaluation budget, the compiled draws against
numpy's calls.

The contract it shares with the other optimizers (bounds, budgets, reproducibility, history,
convergence, smallest population) is in test_optimizer_contract.py.
"""

import numpy as np
import pytest

from avoa_pipeline.optimizers import Budget, minimize, minimize_together
from avoa_pipeline.optimizers.run import (
    _ESQ_NORMAL,
    _MU,
    _RK1_INT,
    _RK2_INT,
    _W_COORD,
    DRAWN_AHEAD,
    _Draws,
    rndx,
)
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


def test_rndx_takes_the_three_smallest_keys_besides_the_agent_in_order():
    rng = np.random.default_rng(5)
    P = 9
    out = np.empty(3, dtype=np.int64)
    for _ in range(50):
        keys = rng.random(P)
        for i in range(P):
            rndx(keys, i, out)
            masked = keys.copy()
            masked[i] = np.inf
            np.testing.assert_array_equal(out, np.argsort(masked)[:3])
    # equal keys: the lower index first
    rndx(np.array([0.5, 0.2, 0.2, 0.9, 0.2]), 2, out)
    np.testing.assert_array_equal(out, [1, 4, 0])


def test_an_evaluation_budget_ends_each_seed_inside_its_own_iteration():
    # the seeds of a block fall out of phase (an agent costs 1, 2 or 3 evaluations): each stops
    # at the budget exactly, its closed iterations cost P..3P, its last one is left open
    P, max_nfe = 6, 125
    seeds = range(6)
    block = minimize_together(
        "run",
        sphere,
        [-10.0] * 3,
        [10.0] * 3,
        Budget(P, None, max_nfe),
        [np.random.default_rng(s) for s in seeds],
    )
    ends = set()
    for r in block:
        assert r.nfe == max_nfe
        assert r.history_nfe[-1] == max_nfe
        closed = np.diff(r.history_nfe[:-1])
        assert np.all((closed >= P) & (closed <= 3 * P))
        ends.add(tuple(r.history_nfe))
    assert len(ends) > 1  # out of phase indeed
    # fewer evaluations than any whole iteration costs: iterations cut short by the budget
    assert any(r.history_nfe[-1] - r.history_nfe[-2] < P for r in block)


def _numpy_draws(draws: _Draws, rng: np.random.Generator):
    """One iteration's numbers by numpy's own calls, in the order the one-seed code drew them."""
    P, D = draws.P, draws.normals.shape[-1]
    u = np.empty(draws.uniform.shape[1])
    ints, normals = np.empty((3, P), dtype=np.int64), np.empty((2, P, D))
    for g, (a, b) in enumerate(draws.calls):
        rng.random(out=u[a:b])
        if g == 0:
            ints[_RK1_INT] = rng.integers(1, 3, size=P)
        elif g == 1:
            ints[_RK2_INT] = rng.integers(1, 3, size=P)
        elif g == 2:
            rng.standard_normal(out=normals[_MU])
        elif g == 3:
            rng.standard_normal(out=normals[_ESQ_NORMAL])
        elif g == 4:
            ints[_W_COORD] = rng.integers(D, size=P)
    return u, ints, normals


@pytest.mark.parametrize(("P", "D"), [(20, 6), (5, 3), (7, 1)])
def test_compiled_draws_are_numpys_calls(P, D):
    # numba's generator methods on the generator's own bit generator, several banks in a row
    # (odd P: integer draws leave half of a 64-bit word in the generator between calls; a
    # random 32-bit word never, or rarely, rejected by Lemire's method of a range of 2 or D)
    for seed in range(4):
        draws, rng = _Draws(1, P, D), np.random.default_rng(seed)
        want = np.random.default_rng(seed)
        rng.random(3), want.random(3)  # a used generator, as after the initial population
        for _ in range(2 * DRAWN_AHEAD + 3):
            draws.draw(0, rng)
            u, ints, normals = _numpy_draws(draws, want)
            np.testing.assert_array_equal(draws.uniform[0], u)
            np.testing.assert_array_equal(draws.ints[0], ints)
            np.testing.assert_array_equal(draws.normals[0], normals)
