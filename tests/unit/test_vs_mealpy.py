"""Formal comparison of our optimizers with mealpy 3.0.2 at an equal number of evaluations.

Grid: every pair below x {sphere, rosenbrock, rastrigin} x D in {5, 10} x 10 seeds (20 for GWO),
``N_EVALS = 2000`` objective evaluations each, population 20. 2,000 evaluations (100 "iterations"
of 20, a fifth of the paper's 500) keeps the whole grid at about a minute on 2 cores, so it runs
in CI; ``benchmarks/compare_mealpy.py`` runs the same grid (optionally with more seeds or
evaluations) and writes ``docs/mealpy-comparison.md``.

Equal budgets, exactly:

- ours: ``Budget(max_nfe=N, iterations=None, pop_size=20)``; the tracker evaluates exactly ``N``
  points (the initial population included).
- mealpy: ``termination={"max_fe": N}``. mealpy counts every ``get_target`` call including the
  initial population (``nfe_counter`` is reset to 0 when a termination is given), but checks the
  termination only at the end of an epoch, so it overshoots ``N`` by up to one epoch. We therefore
  wrap its objective and take the best of its *first* ``N`` evaluations (the one probe evaluation
  ``Problem.n_objs`` makes before the run is excluded). Its ``epoch`` parameter -- which drives its
  schedules (``a = 2 - 2 epoch / epochs`` etc.) -- is set so the schedule ends where ``N`` runs out:
  ``epochs = ceil((N - 20) / (k 20))`` with ``k`` mealpy's evaluations per agent per epoch
  (1; AGTO 2; RUN variable, about 1.6 at this budget, so ``k = 1.55`` to make sure mealpy's epochs
  cover at least ``N`` evaluations, which the test asserts).

Decision rule: one-sided Mann–Whitney U on the best values (``scipy.stats.mannwhitneyu``),
``p_worse`` for "ours > mealpy" and ``p_better`` for "ours < mealpy", at ``ALPHA = 0.01``:

- ``not_worse`` (both implement the same reference code): fail if ``p_worse < ALPHA``.
- ``worse`` / ``better`` (a deliberate difference with a predictable effect): assert
  ``p_worse < ALPHA`` / ``p_better < ALPHA``.
- ``none`` (a deliberate difference with no honest prior direction): record only.

Every cell also asserts sanity: both medians beat the median of pure random search with the same
``N`` evaluations, and every value is finite.

The 30 cells are tested separately at ``ALPHA`` each, without a multiplicity correction; for two
*identical* algorithms about 1 - 0.99^18 = 17 % of the 18 ``not_worse`` cells would still flag once
by chance for some seed set. Seeds are fixed, so the outcome is deterministic for given code; a
failure should be confirmed with ``benchmarks/compare_mealpy.py --seeds 30`` before acting on it.

Pairs whose algorithm is not (yet) registered are skipped with the reason; once registered they run.
"""

from __future__ import annotations

import importlib
import math
from dataclasses import dataclass

import numpy as np
import pytest
from scipy.stats import mannwhitneyu

from avoa_pipeline.optimizers import REGISTRY, Budget, minimize
from avoa_pipeline.optimizers.testfunctions import FUNCTIONS

N_EVALS = 2000
POP = 20
SEEDS = tuple(range(10))
DIMS = (5, 10)
FUNCTION_NAMES = ("sphere", "rosenbrock", "rastrigin")
ALPHA = 0.01


@dataclass(frozen=True)
class Pair:
    ours: str
    mealpy_class: str  # "module:Class" under mealpy
    evals_per_agent_epoch: float  # k, see module docstring
    expect: dict  # function name -> "not_worse" | "worse" | "better" | "none"
    why: str
    n_seeds: int = len(SEEDS)


def _same(kind: str) -> dict:
    return dict.fromkeys(FUNCTION_NAMES, kind)


# The parametrize table: (ours -> mealpy), expected direction per function, and why.
PAIRS = (
    Pair(
        "avoa",
        "mealpy.swarm_based.AVOA:OriginalAVOA",
        1.0,
        _same("not_worse"),
        "both follow Abdollahzadeh et al. 2021's MATLAB AVOA",
    ),
    Pair(
        "gto",
        "mealpy.swarm_based.AGTO:OriginalAGTO",  # mealpy's GTO is Giant Trevally, not gorillas
        2.0,
        _same("not_worse"),
        "both follow Abdollahzadeh et al. 2021's MATLAB GTO (2 evaluations per agent, iteration)",
    ),
    Pair(
        "run",
        "mealpy.math_based.RUN:OriginalRUN",
        1.55,
        _same("not_worse"),
        "both follow Ahmadianfar et al. 2021's MATLAB RUN",
    ),
    Pair(
        "gwo",
        "mealpy.swarm_based.GWO:OriginalGWO",
        1.0,
        {"sphere": "worse", "rosenbrock": "none", "rastrigin": "not_worse"},
        "mealpy adds greedy selection (more exploitation, less diversity): expected faster on the "
        "unimodal sphere (asserted: ours worse) and more stagnation on multimodal Rastrigin "
        "(ours better in every pilot seed set, but p = 0.002-0.06 at 20 seeds, so only 'not worse' "
        "is asserted); Rosenbrock's valley: no prior, recorded. 20 seeds (GWO runs are cheap)",
        n_seeds=20,
    ),
    Pair(
        "ga",
        "mealpy.evolutionary_based.GA:BaseGA",
        1.0,
        _same("none"),
        "ours models MATLAB ga (elitism, scattered crossover, Gaussian/adaptive mutation); "
        "BaseGA uses different selection/crossover/mutation: no honest prior direction",
    ),
)


# --- runners (also used by benchmarks/compare_mealpy.py) ---------------------------------------
def run_ours(name: str, fn: str, dim: int, seed: int, n_evals: int = N_EVALS) -> float:
    f, lo, hi = FUNCTIONS[fn]
    budget = Budget(pop_size=POP, iterations=None, max_nfe=n_evals)
    res = minimize(name, f, np.full(dim, lo), np.full(dim, hi), budget, np.random.default_rng(seed))
    assert res.nfe == n_evals, f"{name} spent {res.nfe} evaluations, budget {n_evals}"
    return res.best_f


def mealpy_epochs(pair: Pair, n_evals: int = N_EVALS) -> int:
    return max(1, math.ceil((n_evals - POP) / (pair.evals_per_agent_epoch * POP)))


def run_mealpy(pair: Pair, fn: str, dim: int, seed: int, n_evals: int = N_EVALS) -> float:
    """Best of mealpy's first ``n_evals`` evaluations (see module docstring)."""
    from mealpy import FloatVar, Problem

    module, cls = pair.mealpy_class.split(":")
    optimizer_cls = getattr(importlib.import_module(module), cls)
    f, lo, hi = FUNCTIONS[fn]
    calls = {"n": 0, "best": np.inf}

    def objective(x):
        value = float(f(np.asarray(x)[None, :])[0])
        if calls["n"] < n_evals:
            calls["best"] = min(calls["best"], value)
        calls["n"] += 1
        return value

    problem = Problem(
        bounds=FloatVar(lb=[lo] * dim, ub=[hi] * dim),
        minmax="min",
        obj_func=objective,
        log_to=None,
    )
    assert problem.n_objs == 1  # mealpy's probe evaluation; not part of the run
    calls.update(n=0, best=np.inf)
    model = optimizer_cls(epoch=mealpy_epochs(pair, n_evals), pop_size=POP)
    model.solve(problem, seed=seed, termination={"max_fe": n_evals})
    assert calls["n"] >= n_evals, (
        f"mealpy {cls} stopped after {calls['n']} < {n_evals} evaluations; lower k for it"
    )
    return calls["best"]


def random_search(fn: str, dim: int, seed: int, n_evals: int = N_EVALS) -> float:
    f, lo, hi = FUNCTIONS[fn]
    rng = np.random.default_rng(10_000 + seed)
    return float(np.min(f(rng.uniform(lo, hi, (n_evals, dim)))))


def compare(pair: Pair, fn: str, dim: int, seeds=None, n_evals: int = N_EVALS) -> dict:
    if seeds is None:
        seeds = tuple(range(pair.n_seeds))
    ours = np.array([run_ours(pair.ours, fn, dim, s, n_evals) for s in seeds])
    theirs = np.array([run_mealpy(pair, fn, dim, s, n_evals) for s in seeds])
    rand = np.array([random_search(fn, dim, s, n_evals) for s in seeds])
    p_worse = float(mannwhitneyu(ours, theirs, alternative="greater").pvalue)
    p_better = float(mannwhitneyu(ours, theirs, alternative="less").pvalue)
    expect = pair.expect[fn]
    if expect == "not_worse":
        ok = p_worse >= ALPHA
    elif expect == "worse":
        ok = p_worse < ALPHA
    elif expect == "better":
        ok = p_better < ALPHA
    else:
        ok = True
    sane = bool(
        np.all(np.isfinite(ours))
        and np.all(np.isfinite(theirs))
        and np.median(ours) < np.median(rand)
        and np.median(theirs) < np.median(rand)
    )
    if p_worse < ALPHA:
        observed = "ours worse"
    elif p_better < ALPHA:
        observed = "ours better"
    else:
        observed = "no significant difference"
    return {
        "ours": ours,
        "theirs": theirs,
        "random": rand,
        "p_worse": p_worse,
        "p_better": p_better,
        "expect": expect,
        "observed": observed,
        "ok": ok,
        "sane": sane,
    }


CELLS = [
    pytest.param(pair, fn, dim, id=f"{pair.ours}-{fn}-{dim}d")
    for pair in PAIRS
    for fn in FUNCTION_NAMES
    for dim in DIMS
]


@pytest.mark.parametrize(("pair", "fn", "dim"), CELLS)
def test_against_mealpy(pair: Pair, fn: str, dim: int):
    if pair.ours not in REGISTRY:
        pytest.skip(f"{pair.ours!r} is not registered yet (its module has not landed)")
    r = compare(pair, fn, dim)
    summary = (
        f"{pair.ours} vs {pair.mealpy_class} on {fn} {dim}-D, {N_EVALS} evaluations, "
        f"{len(r['ours'])} seeds: median ours {np.median(r['ours']):.4g}, "
        f"mealpy {np.median(r['theirs']):.4g}, random search {np.median(r['random']):.4g}; "
        f"p(ours worse) = {r['p_worse']:.3g}, p(ours better) = {r['p_better']:.3g}; "
        f"expected {r['expect']!r} ({pair.why}), observed {r['observed']}"
    )
    assert r["sane"], "sanity failed: " + summary
    assert r["ok"], summary


def test_pairs_cover_the_metaheuristics():
    """Every population method of the paper has a mealpy counterpart in the table."""
    assert {p.ours for p in PAIRS} == {"avoa", "gto", "run", "gwo", "ga"}
    for pair in PAIRS:
        assert set(pair.expect) == set(FUNCTION_NAMES)
        assert set(pair.expect.values()) <= {"not_worse", "worse", "better", "none"}
