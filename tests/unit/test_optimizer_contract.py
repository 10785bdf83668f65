"""The contract of every registered optimizer, written once and run for each of the seven.

Reproducibility (the seed alone decides the result; no global generator is touched), evaluation
accounting (exact ``max_nfe``, iteration budgets, the first budget reached wins, the history), the
box (every evaluated point finite and inside it), and performance on shared problems. Where the
algorithms differ -- evaluations per iteration, smallest population, and how well they do -- the
one table ``EXPECT`` says so; every bar in it was measured (comments) and is held per algorithm.
Every run of a performance test also goes through :func:`checked_run`, so the long runs check the
box too. Tests of one algorithm's own machinery stay in ``test_<algorithm>.py``.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import pytest
from optim_helpers import (
    Recorder,
    assert_global_generators_untouched,
    assert_history_consistent,
    assert_seed_determines_result,
    minimize_seeded,
    shifted,
)

from avoa_pipeline.optimizers import (
    ALGORITHMS,
    REGISTRY,
    Budget,
    OptimResult,
    Runs,
    drive,
)
from avoa_pipeline.optimizers.testfunctions import rastrigin, rosenbrock, sphere

P = 20  # population size of the shared problems
SHIFT = np.array([12.3, -45.6, 7.8, -1.9, 33.3])  # sphere optimum away from the origin
RASTRIGIN_SHIFT = [0.61, -1.37, 2.05, -0.42, 1.11]
# an asymmetric box (catches lb/ub mix-ups); D + 1 = 5 divides P, so even quasi-Newton's
# gradient calls of D + 1 points close each iteration exactly
LB4, UB4 = [-5.0, 0.0, 10.0, -1.0], [5.0, 1.0, 20.0, 3.0]


@dataclass(frozen=True)
class Bar:
    """A measured performance bar: runs with ``budget`` for every seed and dimension; each best
    value must stay below ``worst``, their median below ``median``."""

    budget: Budget | dict[int, Budget]  # or one per dimension
    seeds: tuple[int, ...] = (0, 1, 2)
    dims: tuple[int, ...] = (5,)
    worst: float = math.inf
    median: float = math.inf
    atol: float | None = None  # |best_x - optimum| in every coordinate (shifted sphere)
    vs_random: float | None = None  # best_f < vs_random * best of as many uniform random points
    improvement: float | None = None  # best_f < improvement * best of the initial population

    def budget_for(self, dim: int) -> Budget:
        return self.budget[dim] if isinstance(self.budget, dict) else self.budget


@dataclass(frozen=True)
class Expect:
    """How one algorithm spends its budget, and the bars it is held to."""

    evals_per_iteration: Callable[[int], int] | None  # pop_size -> evaluations (None: varies)
    calls_per_iteration: int | None  # objective calls per iteration, if whole populations
    min_pop: int  # smallest population it accepts
    sphere: Bar  # D-dimensional sphere on [-100, 100]^D
    shifted_sphere: Bar  # 5-D sphere with its optimum at SHIFT, on [-100, 100]^5
    rosenbrock: Bar  # D-dimensional Rosenbrock on [-30, 30]^D
    rastrigin: bool  # beats random search on the shifted 5-D Rastrigin (20 x 500, seeds 0-4)


def one_per_agent(p: int) -> int:
    return p


EXPECT: dict[str, Expect] = {
    "nelder_mead": Expect(
        # a local search has no population: an iteration is pop_size evaluations
        evals_per_iteration=one_per_agent,
        calls_per_iteration=None,  # one point per call
        min_pop=1,
        # both local methods solve these smooth problems to ~1e-7 or better with 4,020
        # evaluations; random search with the same budget stays above 1 (sphere) / 1e3
        # (rosenbrock, 5-D). A local search does not plan by its budget, so a shorter run is the
        # start of a longer one: on the sphere the same bar now holds after 1,020 evaluations
        # (measured: 3e-8 in 5-D), at 1e-6 of random search's best (measured: <= 1e-9); on
        # Rosenbrock 2-D after 1,020 (measured: 3e-10), 5-D needs the 4,020 (2e-2 after 2,020)
        sphere=Bar(Budget(P, 50), seeds=(1,), dims=(2, 5), worst=1e-4, vs_random=1e-6),
        rosenbrock=Bar({2: Budget(P, 50), 5: Budget(P, 200)}, seeds=(1,), dims=(2, 5), worst=1e-4),
        # measured: seed 0 2e-9, |x - SHIFT| <= 4e-5; seeds 0-9 worst 1e-8, |x - SHIFT| <= 8e-5
        shifted_sphere=Bar(Budget(P, 50), seeds=(0,), worst=1e-6, atol=1e-2),
        # a local search does not beat random search on Rastrigin: measured median 10 (RS 17.5)
        rastrigin=False,
    ),
    "quasi_newton": Expect(
        evals_per_iteration=one_per_agent,
        calls_per_iteration=None,  # D + 1 points (f and a gradient) per call
        min_pop=1,
        # as Nelder-Mead (same comment); both bars hold after 1,020 evaluations (measured:
        # sphere 2e-12, rosenbrock 4e-8), the sphere one at 1e-8 of random search's best
        # (measured: <= 2e-12)
        sphere=Bar(Budget(P, 50), seeds=(1,), dims=(2, 5), worst=1e-4, vs_random=1e-8),
        rosenbrock=Bar(Budget(P, 50), seeds=(1,), dims=(2, 5), worst=1e-4),
        # measured: seed 0 2e-12, |x - SHIFT| <= 1e-6; seeds 0-9 worst 4e-12, |x - SHIFT| <= 2e-6
        shifted_sphere=Bar(Budget(P, 50), seeds=(0,), worst=1e-9, atol=1e-4),
        # local search; and on Rastrigin the restarts cost ~0.7 ms per evaluation (scipy)
        rastrigin=False,
    ),
    "ga": Expect(
        # elites keep their scores: P - ceil(0.05 P) evaluations per generation, as MATLAB ga
        evals_per_iteration=lambda p: p - math.ceil(0.05 * p),
        calls_per_iteration=1,
        min_pop=2,  # one elite and one child
        # measured over 20 seeds with 2000 evaluations: worst 2.5e-2, median 4e-4;
        # random search with the same budget: best 4e2 of 20 seeds
        sphere=Bar(Budget(P, None, 2000), worst=0.5, vs_random=1e-3),
        # measured (seeds 0-9): worst 1.6e-2, |x - SHIFT| <= 0.12 (at 20 x 500: 3e-14, 2e-7)
        shifted_sphere=Bar(Budget(P, 100), worst=0.5, atol=1.0),
        # measured: seed 0 1.1; seeds 0-9 median 11, worst 1.6e3; random search ~1e4
        rosenbrock=Bar(Budget(P, 100), seeds=(0,), worst=10.0),
        # not held to it: it passes (seeds 0-4: median 4.0 < 17.5 / 3, worst 8.0 < 11.8), but
        # with little margin
        rastrigin=False,
    ),
    "gwo": Expect(
        evals_per_iteration=one_per_agent,
        calls_per_iteration=1,
        min_pop=1,
        # random search with the same 2,020 points reaches ~1e3 (5-D) / ~1e4 (10-D);
        # GWO reaches ~1e-13 / ~1e-7 (a broken move or schedule stalls far above 1e-3)
        # (best / random search, measured: <= 1.2e-10)
        sphere=Bar(Budget(P, 100), dims=(5, 10), worst=1e-3, improvement=1e-6, vs_random=1e-6),
        # measured (seeds 0-4): median 0.21, worst 4.9 (GWO is biased towards the origin; its
        # a-schedule has its own test in test_gwo)
        shifted_sphere=Bar(Budget(P, 100), seeds=(0, 1, 2, 3, 4), median=1.0, worst=50.0),
        # GWO gets into the valley (f ~ 1-3) but not to the minimum at these budgets; random
        # search with the same budget stays at ~1e4
        rosenbrock=Bar(Budget(P, 300), seeds=(0, 1, 2, 3, 4), median=5.0),
        rastrigin=False,  # not held to it (time); it passes (seeds 0-4: median 2.0, worst 5.0)
    ),
    "run": Expect(
        # one evaluation per agent, plus ESQ (p = 0.5), plus the conditional Eq. 20 step
        evals_per_iteration=None,
        calls_per_iteration=None,
        min_pop=4,  # three partners besides the agent
        # measured over 20 seeds with 2000 evaluations: worst 1.5e-21, median 1e-28;
        # random search with the same budget: best 4e2 of 20 seeds
        sphere=Bar(Budget(P, None, 2000), worst=1e-10, vs_random=1e-8),
        # measured: seed 0 3e-4, |x - SHIFT| <= 0.015; seeds 0-9 worst 0.5 (RUN: ~60 ms per run)
        shifted_sphere=Bar(Budget(P, 30), seeds=(0,), worst=1e-2, atol=0.5),
        # measured: seed 0 1.8; seeds 0-9 median 2.8, worst 3.2; random search ~1e4
        rosenbrock=Bar(Budget(P, 30), seeds=(0,), worst=10.0),
        rastrigin=False,  # not run: ~1 s per 20 x 500 run
    ),
    "avoa": Expect(
        evals_per_iteration=one_per_agent,
        calls_per_iteration=1,
        min_pop=1,
        # measured (seeds 0-9): ~1e-297 -- AVOA's moves are drawn towards the origin (and the
        # run down to ~1e-300 meets 0/0 in eqs. 27-28: every point must stay finite)
        sphere=Bar(Budget(P, 500), seeds=(0,), worst=1e-8, vs_random=1e-6),
        # measured (seeds 0-9): median 1e-12, worst 1e-11; random search with the same budget: ~400
        shifted_sphere=Bar(Budget(P, 500), worst=1e-8, atol=1e-3),
        # measured: seed 0 1.9; seeds 0-9 median 2.3, worst 3.1; random search ~1e4
        rosenbrock=Bar(Budget(P, 100), seeds=(0,), worst=10.0),
        # measured: AVOA median ~1.5-2 (worst ~4), random search median ~15 (best ~10)
        rastrigin=True,
    ),
    "gto": Expect(
        evals_per_iteration=lambda p: 2 * p,  # exploration + exploitation
        calls_per_iteration=2,
        min_pop=1,
        # measured (seeds 0-9): exactly 0.0 -- GTO's moves are drawn towards the origin; with
        # 2,000 evaluations instead of 20 x 500: worst 4e-39
        sphere=Bar(Budget(P, None, 2000), worst=1e-8, vs_random=1e-6),
        # measured (seeds 0-9): median 3e-29, worst 3e-28; random search with the same budget: ~300
        shifted_sphere=Bar(Budget(P, 500), worst=1e-20, atol=1e-8),
        # measured: seed 0 6e-20; seeds 0-9 worst 6e-15 (3-D)
        rosenbrock=Bar(Budget(P, 200), seeds=(0,), dims=(3,), worst=1e-8),
        # measured: GTO median ~2 (worst ~6), random search median ~13 (best ~10)
        rastrigin=True,
    ),
}
assert set(EXPECT) == set(ALGORITHMS)

algorithms = pytest.mark.parametrize("name", ALGORITHMS)


class StrictRuns(Runs):
    """Fails if the optimizer asks for an evaluation after the budget is spent."""

    def ask(self, X, live=None):
        asking = np.ones(self.n, dtype=bool) if live is None else live
        assert not (self.done & asking).any(), "ask() called after the budget was exhausted"
        return super().ask(X, live)


def strict_result(name, rec, lb, ub, budget, rng) -> OptimResult:
    """One run of ``name`` whose every ask is checked against the budget."""
    runs = StrictRuns(rec, lb, ub, budget, 1)
    drive(runs, REGISTRY[name](runs, [rng], budget.pop_size))
    return runs.result(0)


def checked_run(name, f, lb, ub, budget, seed=0, **settings) -> tuple[OptimResult, Recorder]:
    """``minimize``, then check that every evaluated point was finite and inside the box."""
    rec = Recorder(f)
    res = minimize_seeded(name, rec, lb, ub, budget, seed, **settings)
    pts = rec.all
    assert pts.shape == (res.nfe, len(lb))
    assert np.all(np.isfinite(pts))
    assert np.all(pts >= np.asarray(lb))
    assert np.all(pts <= np.asarray(ub))
    return res, rec


def expected_history_nfe(name: str, pop_size: int, max_nfe: int) -> np.ndarray | None:
    """Cumulative evaluations after each iteration under ``max_nfe``: whole iterations, then the
    partial last one (None if the evaluations per iteration vary)."""
    per_iteration = EXPECT[name].evals_per_iteration
    if per_iteration is None:
        return None
    return np.r_[np.arange(pop_size, max_nfe, per_iteration(pop_size)), max_nfe]


def assert_meets(bar: Bar, finals: list[float], what: str) -> None:
    assert max(finals) < bar.worst, (what, finals)
    assert np.median(finals) < bar.median, (what, finals)


# --- registry, reproducibility -------------------------------------------------------------------


@algorithms
def test_registered(name):
    assert name in REGISTRY


@algorithms
def test_same_seed_same_result_different_seed_different_result(name):
    b = Budget(pop_size=10, iterations=30)
    r1, r2, r3 = (minimize_seeded(name, rosenbrock, LB4, UB4, b, s) for s in (11, 11, 12))
    assert_seed_determines_result(r1, r2, r3)
    assert r1.best_f != r3.best_f
    assert not np.array_equal(r1.history_best, r3.history_best)


@algorithms
def test_uses_only_the_given_generator(name):
    # the legacy global generators must be left untouched
    assert_global_generators_untouched(
        lambda: minimize_seeded(name, sphere, [-10.0] * 3, [10.0] * 3, Budget(10, 20))
    )


@algorithms
def test_unknown_setting_is_rejected(name):
    with pytest.raises(TypeError, match="no_such_setting"):
        minimize_seeded(name, sphere, [-1.0], [1.0], Budget(5, 2), no_such_setting=1)


# --- budgets and history -------------------------------------------------------------------------


# around P = 20 and 2 P (GTO: before / after the exploitation evaluation) and D + 1 = 5
# (quasi-Newton's gradient calls), and long runs
MAX_NFE = (1, 4, 5, 7, 19, 20, 21, 40, 50, 60, 61, 80, 95, 123, 237, 333, 537, 1000, 1001)


@algorithms
def test_evaluation_budget_is_respected_exactly(name):
    # one test item per algorithm, not one per budget: pytest's overhead of ~4 ms per item would
    # about double this test's time
    lb, ub = np.full(4, -10.0), np.full(4, 10.0)
    for max_nfe in MAX_NFE:
        rec = Recorder(sphere)
        budget = Budget(pop_size=P, iterations=None, max_nfe=max_nfe)
        res = strict_result(name, rec, lb, ub, budget, np.random.default_rng(0))
        assert res.nfe == max_nfe
        assert rec.all.shape[0] == max_nfe  # rows past the budget never reach the objective
        assert res.history_nfe[-1] == max_nfe  # a partial last iteration is recorded
        expected = expected_history_nfe(name, P, max_nfe)
        if expected is not None:
            np.testing.assert_array_equal(res.history_nfe, expected, err_msg=f"{max_nfe=}")


@algorithms
@pytest.mark.parametrize(("pop_size", "iterations"), [(20, 7), (10, 25)])
def test_iteration_budget_is_respected(name, pop_size, iterations):
    rec = Recorder(sphere)
    res = minimize_seeded(name, rec, [-10.0] * 4, [10.0] * 4, Budget(pop_size, iterations))
    assert res.iterations == iterations
    assert len(res.history_best) == len(res.history_nfe) == len(res.history_time) == iterations + 1
    assert res.nfe == rec.all.shape[0] == res.history_nfe[-1]
    assert res.history_nfe[0] == pop_size  # the initial population is iteration 0
    expect = EXPECT[name]
    if expect.evals_per_iteration is not None:
        k = expect.evals_per_iteration(pop_size)
        np.testing.assert_array_equal(res.history_nfe, pop_size + k * np.arange(iterations + 1))
    if expect.calls_per_iteration is not None:  # whole populations, one call each
        c = expect.calls_per_iteration
        k = expect.evals_per_iteration(pop_size)
        assert [len(x) for x in rec.calls] == [pop_size] + [k // c] * (c * iterations)


@algorithms
def test_both_budgets_stop_at_the_first_reached(name):
    lb, ub = [-10.0] * 4, [10.0] * 4
    res = minimize_seeded(name, sphere, lb, ub, Budget(pop_size=P, iterations=10, max_nfe=90))
    assert res.nfe == 90
    assert res.iterations < 10
    res = minimize_seeded(name, sphere, lb, ub, Budget(pop_size=P, iterations=3, max_nfe=900))
    assert res.iterations == 3
    assert res.nfe < 900
    per_iteration = EXPECT[name].evals_per_iteration
    if per_iteration is not None:
        assert res.nfe == P + 3 * per_iteration(P)


@algorithms
def test_history_is_consistent(name):
    rec = Recorder(rosenbrock)
    res = minimize_seeded(name, rec, LB4, UB4, Budget(pop_size=P, iterations=None, max_nfe=1010))
    assert_history_consistent(res, rosenbrock)
    assert res.nfe == 1010
    f_all = rosenbrock(rec.all)
    assert res.best_f == f_all.min()  # the reported best is the best point actually evaluated
    # the history's best after each iteration is the best of the evaluations so far
    for nfe, best in zip(res.history_nfe, res.history_best, strict=True):
        assert best == f_all[:nfe].min()
    expected = expected_history_nfe(name, P, 1010)
    if expected is not None:  # whole iterations, then the partial last one
        np.testing.assert_array_equal(res.history_nfe, expected)


@algorithms
def test_smallest_population_runs(name):
    p = EXPECT[name].min_pop
    res = minimize_seeded(name, sphere, [-1.0] * 2, [1.0] * 2, Budget(pop_size=p, iterations=30))
    assert res.iterations == 30
    assert np.isfinite(res.best_f)
    per_iteration = EXPECT[name].evals_per_iteration
    if per_iteration is not None:
        assert res.nfe == p + 30 * per_iteration(p)


@pytest.mark.parametrize("name", [n for n in ALGORITHMS if EXPECT[n].min_pop > 1])
def test_too_small_population_is_rejected(name):
    p = EXPECT[name].min_pop - 1
    with pytest.raises(ValueError, match="pop_size"):
        minimize_seeded(name, sphere, [-1.0] * 2, [1.0] * 2, Budget(pop_size=p, iterations=5))


# --- the box -------------------------------------------------------------------------------------


@algorithms
def test_every_evaluated_point_is_inside_the_box_and_reaches_its_faces(name):
    # the sphere's optimum lies outside the box in three coordinates, so the moves overshoot
    lb = np.array([-5.0, 0.0, 2.0, -1.0, 10.0])
    ub = np.array([5.0, 1.0, 3.0, 4.0, 20.0])
    centre = np.array([7.0, -2.0, 2.5, 0.0, 25.0])
    _, rec = checked_run(name, shifted(sphere, centre), lb, ub, Budget(10, 60), seed=3)
    X = rec.all
    # clipped onto the faces nearest the optimum, as the references do (measured: all seven)
    assert X[:, 0].max() == ub[0]
    assert X[:, 1].min() == lb[1]
    assert X[:, 4].max() == ub[4]


# --- performance ---------------------------------------------------------------------------------


@algorithms
def test_converges_on_sphere_and_beats_random_search(name):
    bar = EXPECT[name].sphere
    for dim in bar.dims:
        finals = []
        for seed in bar.seeds:
            res, _ = checked_run(
                name, sphere, [-100.0] * dim, [100.0] * dim, bar.budget_for(dim), seed
            )
            finals.append(res.best_f)
            if bar.vs_random is not None:
                rs = sphere(np.random.default_rng(seed).uniform(-100, 100, (res.nfe, dim)))
                assert res.best_f < bar.vs_random * rs.min(), (dim, seed, res.best_f, rs.min())
            if bar.improvement is not None:
                assert res.history_best[-1] < bar.improvement * res.history_best[0]
        assert_meets(bar, finals, dim)


@algorithms
def test_converges_on_shifted_sphere(name):
    bar = EXPECT[name].shifted_sphere
    f, lb, ub = shifted(sphere, SHIFT), [-100.0] * 5, [100.0] * 5
    finals = []
    for seed in bar.seeds:
        res, _ = checked_run(name, f, lb, ub, bar.budget_for(5), seed)
        finals.append(res.best_f)
        if bar.atol is not None:
            np.testing.assert_allclose(res.best_x, SHIFT, rtol=0, atol=bar.atol)
    assert_meets(bar, finals, "shifted sphere")


@algorithms
def test_converges_on_rosenbrock(name):
    bar = EXPECT[name].rosenbrock
    for dim in bar.dims:
        runs = [
            checked_run(name, rosenbrock, [-30.0] * dim, [30.0] * dim, bar.budget_for(dim), s)[0]
            for s in bar.seeds
        ]
        assert_meets(bar, [r.best_f for r in runs], dim)


@pytest.mark.parametrize("name", [n for n in ALGORITHMS if EXPECT[n].rastrigin])
def test_beats_random_search_on_shifted_rastrigin(name):
    f = shifted(rastrigin, RASTRIGIN_SHIFT)
    lb, ub, budget = [-5.12] * 5, [5.12] * 5, Budget(pop_size=P, iterations=500)
    runs = [checked_run(name, f, lb, ub, budget, seed=s)[0] for s in range(5)]
    ours = [r.best_f for r in runs]
    nfe = runs[0].nfe
    rs = [f(-5.12 + 10.24 * np.random.default_rng(s).random((nfe, 5))).min() for s in range(5)]
    assert np.median(ours) < np.median(rs) / 3
    assert max(ours) < min(rs)
