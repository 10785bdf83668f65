"""Identification on noise-free synthetic data: the truth is recoverable.

Measured (``python -m avoa_pipeline recovery --scenario 1 --case 2``): at the paper's budget
(20 × 500) AVOA pins Vnom, Vdis and τ but leaves Rtr 2-9 % off over seeds, because R0 and Rtr
trade off along a narrow valley of the ISE (mealpy's OriginalAVOA lands at the same 2-7 %).
With 10,000 iterations every seed tried (6) gets all parameters within 1 %; that is the test.
"""

import numpy as np
import pytest

from avoa_pipeline import fit, problem, seeds
from avoa_pipeline.optimizers import Budget, minimize


@pytest.fixture(scope="module")
def clean_s1c2(cfg):
    prob = problem.build(cfg, 1, 2, noise=False)
    fit.warm_up(prob, 20)
    return prob


def fit_avoa(prob, iterations: int):
    """AVOA (20 agents) on ``prob``, with the random stream of fit 1 of scenario 1, case 2."""
    rng = seeds.stream(20230508, "fit", 1, 2, "avoa", 1)
    return minimize("avoa", prob.objective, prob.lb, prob.ub, Budget(20, iterations), rng)


def relative_errors(prob, res) -> dict[str, float]:
    """|fitted / true - 1| per free parameter."""
    return dict(zip(prob.names, np.abs(res.best_x / prob.true_free() - 1.0), strict=True))


def test_avoa_recovers_scenario1_case2_within_1pct(clean_s1c2):
    rel = relative_errors(clean_s1c2, fit_avoa(clean_s1c2, 10_000))
    assert max(rel.values()) < 0.01, rel


def test_paper_budget_pins_the_voltages(clean_s1c2):
    """At 20 × 500 the OCV parameters are already tight; the resistances are what lag."""
    prob = clean_s1c2
    res = fit_avoa(prob, 500)
    rel = relative_errors(prob, res)
    assert rel["vnom"] < 1e-3, rel
    assert rel["vdis"] < 1e-3, rel
    # far better than a random point of the box: the objective is informative
    rand = prob.lb + np.random.default_rng(0).random((50, len(prob.names))) * (prob.ub - prob.lb)
    assert res.best_f < 1e-3 * np.median(prob.objective(rand))
