"""Seeds stepped together (ask/tell): a fit block's records are those of one seed at a time.

Two independent checks. (1) Against the code before ask/tell: the references in
``tests/data/fit_references_bec3407.json`` are the numbers commit bec3407 computed one seed at a
time (``tests/data/make_fit_references.py`` says how), for every algorithm on two problems and
three budgets (an iteration budget, an evaluation budget that ends inside an iteration, both);
the lockstep block must give them to stated relative tolerances (``fit.ISE_RTOL``,
``fit.PATH_RTOL``: another CPU rounds the objective's last bits otherwise), and on the machine
that runs the test the block and the single-seed path give each other's numbers bit for bit.
(2) Lockstep against the
single-seed driver of the same code on the test functions, over budgets around the population
size, so the driver itself is held to "same random stream, same moves, same accounting" on any
machine. Plus the premise both rest on: a row's value does not depend on the other rows of the
kernel call.

The references were made on this project's machine (x86-64 with AVX-512, numpy 2.4.6, scipy
1.17.1, numba 0.68.1); on another CPU or library version, numpy's vectorised transcendental
functions may round differently: that is what the tolerances allow for. A mismatch beyond it is a
change of the optimizers (or a chaotic divergence of one run: remake the references there with
the script and compare the two machines' before reading it as one).
"""

from __future__ import annotations

import importlib.util
import json
import time
from pathlib import Path

import numpy as np
import pytest
from optim_helpers import Recorder, shifted

from avoa_pipeline import fit, problem
from avoa_pipeline.optimizers import (
    ALGORITHMS,
    Budget,
    Runs,
    minimize,
    minimize_together,
)
from avoa_pipeline.optimizers.testfunctions import rastrigin, rosenbrock

REFERENCES = Path(__file__).parents[1] / "data" / "fit_references_bec3407.json"
algorithms = pytest.mark.parametrize("name", ALGORITHMS)


def _reference_script():
    """tests/data/make_fit_references.py as a module: what it writes is what the test reads."""
    path = REFERENCES.parent / "make_fit_references.py"
    spec = importlib.util.spec_from_file_location("make_fit_references", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


REF = _reference_script()
_numbers = REF.numbers


@pytest.fixture(scope="module")
def references():
    runs = json.loads(REFERENCES.read_text())["runs"]
    assert len(runs) == len(REF.PROBLEMS) * len(REF.BUDGETS) * len(ALGORITHMS)
    return runs


@pytest.fixture(scope="module")
def problems(cfg):
    return {(s, c): problem.build(cfg, s, c) for s, c in ((4, 4), (1, 2))}


def _close(got: dict, ref: dict, what) -> None:
    for key in ("seed", "nfe", "iterations", "history_nfe"):
        assert got[key] == ref[key], (what, key)
    # the tolerances and their reasons: fit.ISE_RTOL, fit.PATH_RTOL
    for key, rtol in (("best_ise", fit.ISE_RTOL), ("best_params", fit.PATH_RTOL),
                      ("history_best_ise", fit.PATH_RTOL)):  # fmt: skip
        np.testing.assert_allclose(got[key], ref[key], rtol=rtol, atol=0, err_msg=f"{what} {key}")


@algorithms
def test_block_records_equal_the_one_seed_records_of_bec3407(name, cfg, references, problems):
    # across machines: the stored references to ISE_RTOL and PATH_RTOL (another CPU rounds its
    # last bits otherwise); on this machine: the block against one seed at a time, both computed
    # here, bit for bit (the property the lockstep driver is for)
    runs = [r for r in references if r["algorithm"] == name]
    assert len(runs) == len(REF.PROBLEMS) * len(REF.BUDGETS)
    for ref in runs:
        prob = problems[ref["scenario"], ref["case"]]
        budget = Budget(**ref["budget"])
        seeds = [r["seed"] for r in ref["records"]]
        block = [_numbers(r) for r in fit.run_seeds(cfg, prob, name, seeds, budget)]
        what = (ref["scenario"], ref["case"], ref["budget"])
        for got, want in zip(block, ref["records"], strict=True):
            _close(got, want, what)
        # the command line's one fit (the same driver with one run) gives the block's numbers
        assert _numbers(fit.run(cfg, prob, name, seeds[1], budget)) == block[1], what


# --- the driver against itself, on the test functions -------------------------------------------

LB, UB = np.array([-5.0, 0.0, 10.0, -1.0]), np.array([5.0, 1.0, 20.0, 3.0])
BUDGETS = [
    Budget(pop_size=10, iterations=15),
    Budget(pop_size=10, iterations=None, max_nfe=97),  # ends inside an iteration
    Budget(pop_size=6, iterations=30, max_nfe=121),
    Budget(pop_size=6, iterations=4, max_nfe=10_000),
]


def _assert_same_run(a, b) -> None:
    np.testing.assert_array_equal(a.best_x, b.best_x)
    assert a.best_f == b.best_f
    assert (a.nfe, a.iterations) == (b.nfe, b.iterations)
    np.testing.assert_array_equal(a.history_best, b.history_best)
    np.testing.assert_array_equal(a.history_nfe, b.history_nfe)


@algorithms
@pytest.mark.parametrize("f", [rosenbrock, shifted(rastrigin, [0.5, 0.3, 14.0, 1.0])])
def test_lockstep_equals_one_seed_at_a_time(name, f):
    seeds = [3, 1, 4, 1, 5]  # a repeated seed must give the same run twice
    for budget in BUDGETS:
        block_rec = Recorder(f)
        block = minimize_together(
            name, block_rec, LB, UB, budget, [np.random.default_rng(s) for s in seeds]
        )
        single_recs = [Recorder(f) for _ in seeds]
        singles = [
            minimize(name, rec, LB, UB, budget, np.random.default_rng(s))
            for s, rec in zip(seeds, single_recs, strict=True)
        ]
        for a, b in zip(block, singles, strict=True):
            _assert_same_run(a, b)
        # each step evaluates one ask of every unfinished seed, all in one call
        assert len(block_rec.calls) == max(len(rec.calls) for rec in single_recs)
        assert block_rec.all.shape[0] == sum(r.nfe for r in singles)


def _calls_of_one(name, f, budget, seed):
    rec = Recorder(f)
    minimize(name, rec, LB, UB, budget, np.random.default_rng(seed))
    return rec.calls


@algorithms
def test_one_call_per_step(name):
    # five seeds of the same run ask for the same rows at every step: each call holds five
    # copies of one ask, and there are as many calls as one seed alone makes
    budget = Budget(pop_size=10, iterations=8)
    one = _calls_of_one(name, rosenbrock, budget, 7)
    rec = Recorder(rosenbrock)
    minimize_together(name, rec, LB, UB, budget, [np.random.default_rng(7) for _ in range(5)])
    assert len(rec.calls) == len(one)
    for got, ask in zip(rec.calls, one, strict=True):
        np.testing.assert_array_equal(got, np.tile(ask, (5, 1)))


def test_clocks_of_a_block_add_up_to_no_more_than_its_wall_time():
    # each run is charged its own generator's time and its rows' share of every evaluation:
    # disjoint pieces of the block's time
    t0 = time.perf_counter()
    res = minimize_together(
        "run", rosenbrock, LB, UB, Budget(10, 30), [np.random.default_rng(s) for s in range(4)]
    )
    wall = time.perf_counter() - t0
    assert sum(r.wall_s for r in res) <= wall
    for r in res:
        assert r.wall_s > 0
        assert np.all(np.diff(r.history_time) >= 0)
        assert r.history_time[-1] == r.wall_s


@pytest.mark.parametrize("name", ["nelder_mead", "quasi_newton", "run", "avoa"])
def test_an_evaluation_that_fails_ends_the_block_cleanly(name):
    # the error reaches the caller; the suspended searches (greenlets, generators) end with it,
    # without "exception ignored" warnings (errors under this project's pytest config)
    calls = []

    def failing(X):
        calls.append(len(X))
        if len(calls) == 5:
            raise FloatingPointError("simulation failed")
        return rosenbrock(X)

    with pytest.raises(FloatingPointError, match="simulation failed"):
        minimize_together(
            name, failing, LB, UB, Budget(10, 20), [np.random.default_rng(s) for s in range(3)]
        )


def test_runs_answer_their_own_asks():
    # without a driver, evaluate() is an ask answered by the runs' objective, cut to each budget
    runs = Runs(rosenbrock, LB, UB, Budget(pop_size=4, iterations=None, max_nfe=5), 2)
    X = np.array([[0.0, 0.5, 12.0, 1.0], [1.0, 0.5, 11.0, 0.0], [2.0, 0.2, 13.0, 2.0]])
    np.testing.assert_array_equal(runs.evaluate(np.stack([X, X])), [rosenbrock(X)] * 2)
    f = runs.evaluate(np.stack([X, X]), live=np.array([True, False]))  # two rows left
    np.testing.assert_array_equal(f, [[*rosenbrock(X[:2]), np.inf], [np.inf] * 3])
    np.testing.assert_array_equal(runs.nfe, [5, 3])
    f = runs.evaluate(np.stack([X[2:], X[2:]]))  # run 0's budget is spent, run 1 has two left
    assert f.tolist() == [[np.inf], [rosenbrock(X[2:])[0]]]


# --- the premise: a row's value does not depend on the other rows --------------------------------


@pytest.mark.parametrize(("scenario", "case"), [(s, c) for s in (1, 2, 3, 4) for c in (1, 2, 3, 4)])
def test_rows_of_a_large_kernel_call_equal_one_candidate_calls(cfg, scenario, case):
    # the population kernel steps its rows in SIMD lanes, padded with copies of the last row
    # (kernel.LANES; fewer rows one by one in scalars), the single-candidate kernel in scalars:
    # every row must get the same value either way
    prob = problem.build(cfg, scenario, case)
    rng = np.random.default_rng(scenario)
    X = prob.lb + rng.random((203, prob.lb.size)) * (prob.ub - prob.lb)  # odd: padded
    block = prob.objective(X)
    np.testing.assert_array_equal(block, [prob.objective_one(x) for x in X])
    # 43 rows padded to 48, 9 to 16, 5 (fewer than LANES) not padded
    for lo, hi in ((17, 60), (60, 69), (69, 74)):
        np.testing.assert_array_equal(block[lo:hi], prob.objective(X[lo:hi]))
