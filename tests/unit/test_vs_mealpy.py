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

- ``not_worse`` (both implement the same reference code): fail if ``p_worse_holm < ALPHA``, where
  ``p_worse_holm`` is ``p_worse`` Holm-adjusted over the ``not_worse`` cells of the same pair
  (``m`` cells, p-values sorted ``p_(1) <= ... <= p_(m)``: ``p_worse_holm`` of the ``k``-th is
  ``max over j <= k of min(1, (m - j + 1) p_(j))``).
- ``worse`` / ``better`` (a deliberate difference with a predictable effect): assert
  ``p_worse < ALPHA`` / ``p_better < ALPHA`` (unadjusted: asserting an effect).
- ``none`` (a deliberate difference with no honest prior direction, or one too weak to assert
  reliably at this number of seeds): record only.

Every cell also asserts sanity: both medians beat the median of pure random search with the same
``N`` evaluations, and every value is finite.

Multiplicity: without a correction, two *identical* algorithms would flag at least one of a pair's
six ``not_worse`` cells by chance for about 1 - 0.99^6 = 6 % of seed sets (about 15 % over all 16
``not_worse`` cells). Holm's step-down correction keeps that chance at most ``ALPHA`` per pair,
whatever the dependence between the cells, and rejects at least what Bonferroni would. Seeds are
fixed, so the outcome is deterministic for given code; a failure should still be confirmed with
``benchmarks/compare_mealpy.py --seeds 30`` before acting on it. A cell's test computes the other
``not_worse`` cells of its pair too (cached for the session), since its verdict depends on them.

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
        {"sphere": "not_worse", "rosenbrock": "none", "rastrigin": "not_worse"},
        "both follow Ahmadianfar et al. 2021's MATLAB RUN, except that mealpy draws Eq. 18's "
        "mu = 0.5 + U(0, 1) where the reference draws 0.5 + 0.1 randn (mean 1.0 instead of 0.5: "
        "longer steps towards the best and between random agents). On Rosenbrock this makes ours "
        "worse (30 seeds, `compare_mealpy.py --seeds 30`: medians 1.52 vs 0.92 in 5-D, "
        "p = 6e-7; 7.66 vs 6.94 in 10-D, p = 7e-8); with mealpy's mu in our code ours was better "
        "than mealpy instead (p(ours better) = 6e-7 / 4e-6, measured before RUN drew its random "
        "numbers in bulk), so mu explains the gap. Rosenbrock is recorded, not asserted: before "
        "that change, at this test's 10 seeds the direction was stable but the significance was "
        "not (5-D p < 0.01 in 2 of 4 disjoint seed sets, 10-D in 3 of 4)",
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


def holm(pvalues: dict) -> dict:
    """Holm-adjusted p-values (same keys): compare each with ``ALPHA``."""
    adjusted, running = {}, 0.0
    m = len(pvalues)
    for j, key in enumerate(sorted(pvalues, key=pvalues.get)):
        running = max(running, min(1.0, (m - j) * pvalues[key]))
        adjusted[key] = running
    return adjusted


def compare(pair: Pair, fn: str, dim: int, seeds=None, n_evals: int = N_EVALS) -> dict:
    """One cell: both sides' best values, the p-values and sanity; ``judge`` adds the verdict."""
    if seeds is None:
        seeds = tuple(range(pair.n_seeds))
    ours = np.array([run_ours(pair.ours, fn, dim, s, n_evals) for s in seeds])
    theirs = np.array([run_mealpy(pair, fn, dim, s, n_evals) for s in seeds])
    rand = np.array([random_search(fn, dim, s, n_evals) for s in seeds])
    p_worse = float(mannwhitneyu(ours, theirs, alternative="greater").pvalue)
    p_better = float(mannwhitneyu(ours, theirs, alternative="less").pvalue)
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
        "expect": pair.expect[fn],
        "observed": observed,
        "sane": sane,
    }


def judge(cells: dict) -> None:
    """Add ``ok`` (and ``p_worse_holm`` for ``not_worse``) to one pair's cells, keyed (fn, dim).

    The Holm family is the ``not_worse`` cells among ``cells``: pass all of the pair's.
    """
    family = {k: r["p_worse"] for k, r in cells.items() if r["expect"] == "not_worse"}
    adjusted = holm(family)
    for k, r in cells.items():
        expect = r["expect"]
        if expect == "not_worse":
            r["p_worse_holm"] = adjusted[k]
            r["ok"] = adjusted[k] >= ALPHA
        elif expect == "worse":
            r["ok"] = r["p_worse"] < ALPHA
        elif expect == "better":
            r["ok"] = r["p_better"] < ALPHA
        else:
            r["ok"] = True


_CELLS: dict = {}


def ci_cell(pair: Pair, fn: str, dim: int) -> dict:
    """``compare`` on the CI grid, computed once per session."""
    key = (pair.ours, fn, dim)
    if key not in _CELLS:
        _CELLS[key] = compare(pair, fn, dim)
    return _CELLS[key]


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
    family = [(f, d) for f in FUNCTION_NAMES for d in DIMS if pair.expect[f] == "not_worse"]
    cells = {k: ci_cell(pair, *k) for k in {*family, (fn, dim)}}
    judge(cells)
    r = cells[(fn, dim)]
    holm_note = (
        f" (Holm over {len(family)} cells: {r['p_worse_holm']:.3g})" if "p_worse_holm" in r else ""
    )
    summary = (
        f"{pair.ours} vs {pair.mealpy_class} on {fn} {dim}-D, {N_EVALS} evaluations, "
        f"{len(r['ours'])} seeds: median ours {np.median(r['ours']):.4g}, "
        f"mealpy {np.median(r['theirs']):.4g}, random search {np.median(r['random']):.4g}; "
        f"p(ours worse) = {r['p_worse']:.3g}{holm_note}, p(ours better) = {r['p_better']:.3g}; "
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


def test_holm_adjustment():
    # sorted: a 0.01 x 3 = 0.03; c 0.03 x 2 = 0.06; b 0.04 x 1 = 0.04, raised to the running 0.06
    adjusted = holm({"a": 0.01, "b": 0.04, "c": 0.03})
    assert adjusted == pytest.approx({"a": 0.03, "b": 0.06, "c": 0.06})
    assert holm({"a": 0.5, "b": 0.9}) == {"a": 1.0, "b": 1.0}
    assert holm({}) == {}
