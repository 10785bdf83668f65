"""Real-coded genetic algorithm modelled on MATLAB's ``ga`` defaults for bound-constrained problems.

Why MATLAB's ``ga``. Fahmy et al. (2023) give no GA settings beyond population 20 and 500
iterations, and their GA citation ([55], Fan et al. 2023, J. Energy Storage 57:106277) is an
application paper, not an algorithm specification. The study's tooling makes MATLAB's Global
Optimization Toolbox ``ga`` the most likely implementation, so its documented defaults are the
reference here (MathWorks documentation "How the Genetic Algorithm Works", "Genetic Algorithm
Options", "Vary Mutation and Crossover").

Pseudo-code
-----------
::

    X ← P uniform points in [lb, ub];  score ← f(X)                   # gacreationuniform
    n_e ← ceil(0.05·P);  n_x ← round(0.8·(P − n_e));  n_m ← P − n_e − n_x   # P = 20: 1, 15, 4
    Δ ← 1                                                              # adaptive step size
    for generation t = 1, 2, ... while budget left:
        e ← 1/sqrt(rank of score), scaled to sum 2·n_x + n_m           # fitscalingrank
        parents ← stochastic uniform sampling of 2·n_x + n_m indices   # selectionstochunif
        parents ← random permutation of parents
        elite   ← the n_e best of X (kept with their scores, not re-evaluated)
        for each consecutive pair (p, q) of the first 2·n_x parents:   # crossoverscattered
            child ← X_p where rand(D) < 0.5, else X_q
        for each of the last n_m parents p:                            # mutation
            adaptfeasible (default): Δ ← 1 for t ≤ 2; else Δ ← min(1, 4Δ) if the best score
                improved in generation t−1, else max(√eps, Δ/4);
                d ← U(−1, 1)^D ⊙ (ub − lb); flip d_j where X_p + Δ·d leaves the box on that
                side; child ← X_p + s·Δ·d with the largest s ≤ 1 keeping the child inside.
            gaussian: child ← clip(X_p + σ_t·(ub − lb)⊙N(0, 1)^D), σ_t = scale·(1 − shrink·t/T)
        X ← [elite; crossover children; mutation children];  score ← [elite scores; f(children)]

Evaluations per generation: P − n_e (19 for P = 20). The children are evaluated in one batch; an
evaluation budget that ends inside a batch evaluates the rows that fit (the rest get +inf) and that
partial generation is not closed as an iteration.

Seeds in one array. The runs of a fit block (its seeds) move together, as arrays shaped runs ×
individuals × dimension: ranking, selection, crossover, mutation and the elite bookkeeping are
each one array operation over every run (they share the budget, so they are always in the same
generation; each keeps its own step size Δ). Each run draws from its own generator exactly what
the one-run algorithm drew, in the same order, per generation: the selection's offset
(``rng.random()``), the parents' shuffle (``rng.permutation``), then the crossover masks' and the
adaptfeasible directions' uniforms in one ``rng.random`` call (consecutive doubles of one stream
are the same whether drawn in one call or two, and ``uniform(-1, 1)`` is ``-1 + 2 d`` of the same
double), or the crossover masks' uniforms and the Gaussian mutation's normals.

Differences between (a) MATLAB ``ga`` as documented, (b) the Fahmy et al. paper and (c) mealpy
3.0.2 ``BaseGA``, and the choice made here
-----------------------------------------------------------------------------------------------
1. Population / iterations. (a) PopulationSize 50 (≤ 5 variables) or 200, MaxGenerations 100·D;
   (b) 20 and 500; (c) caller's. Choice: the budget (paper: 20 and 500).
2. Stopping. (a) also stops after MaxStallGenerations = 50 generations whose average relative
   change of the best score is below FunctionTolerance = 1e-6; (b) not stated (its convergence
   plots run over 500 iterations); (c) the termination dict, checked once per epoch. Choice: only
   the budget (no stall stop), so all algorithms get the same budget.
3. Elitism. (a) EliteCount = ceil(0.05·P) best individuals survive unchanged and are not
   re-evaluated; (c) none as such: each child replaces the worst of a random 10 % tournament if
   better (steady-state survivor selection). Choice: (a).
4. Offspring split. (a) CrossoverFraction 0.8 of the non-elite children by crossover, the rest by
   mutation only (crossover children are not mutated); (c) pc = 0.95 per pair, then every child
   is mutated. Choice: (a).
5. Scaling and selection. (a) rank scaling (expectation ∝ 1/√rank) + stochastic uniform
   selection, parents shuffled; (c) k-way tournament with k = 20 % of the population. Choice: (a).
6. Crossover. (a) scattered: each gene from either parent with probability 1/2 (one child per
   pair); (c) uniform with two complementary children per pair. Choice: (a).
7. Mutation. (a) for problems with bounds the default is mutationadaptfeasible ("randomly
   generates directions that are adaptive with respect to the last successful or unsuccessful
   generation ... chooses a direction and step length that satisfies bounds"); its internals
   (tangent-cone and random positive-basis directions, exact constants) are not documented.
   mutationgaussian (the unconstrained default, σ shrinking linearly to (1 − Shrink)·σ_0) does
   not respect bounds; (c) per-gene uniform reset with pm = 0.025 ("flip"). Choice: an
   adaptive-feasible mutation written from the documented behaviour (step ×4 / ÷4 on success /
   failure, feasible by direction flipping and step truncation - our reading, not MathWorks' code);
   ``mutation="gaussian"`` selects Gaussian mutation with linear shrink and clipping.
8. Bounds. (a) creation, scattered crossover and adaptfeasible mutation all keep points feasible;
   (c) clips every child. Choice: feasible by construction; Gaussian mutation is clipped.
9. Evaluations per generation. (a) P − n_e; (c) P. Choice: (a).
"""

from __future__ import annotations

import math

import numpy as np

from .base import Runs, Steps, register

_SQRT_EPS = math.sqrt(np.finfo(float).eps)


def rank_expectation(score: np.ndarray, n_parents: int) -> tuple[np.ndarray, np.ndarray]:
    """``fitscalingrank`` of every run (rows of ``score``): expectation ∝ 1/sqrt(rank), summing to
    ``n_parents``; also each run's order (best first, ties in index order)."""
    order = np.argsort(score, axis=1, kind="stable")
    rank = np.empty(score.shape)
    np.put_along_axis(rank, order, np.arange(1.0, score.shape[1] + 1.0), axis=1)
    e = 1.0 / np.sqrt(rank)
    return e * (n_parents / e.sum(axis=1, keepdims=True)), order


def stochastic_uniform(offset: np.ndarray, expectation: np.ndarray, n: int) -> np.ndarray:
    """``selectionstochunif`` of every run: ``n`` equally spaced pointers over its wheel (a row of
    ``expectation``), shifted by the run's ``offset`` (a U(0, 1) draw) times the spacing; the
    indices picked, shape (runs, n)."""
    wheel = np.cumsum(expectation, axis=1) / expectation.sum(axis=1, keepdims=True)
    step = 1.0 / n
    pointers = offset[:, None] * step + step * np.arange(n)
    # the leftmost wheel slot not below each pointer (numpy's searchsorted(side="left") of a
    # nondecreasing wheel), for every run at once
    idx = np.count_nonzero(wheel[:, None, :] < pointers[:, :, None], axis=2)
    return np.minimum(idx, expectation.shape[1] - 1)


def adaptive_feasible(
    unit: np.ndarray, parents: np.ndarray, delta: np.ndarray, lb, ub
) -> np.ndarray:
    """Random directions ``unit`` (U(-1, 1), shape runs x parents x D) scaled to each run's
    adapted step ``delta``, turned and shortened so that every child stays feasible."""
    span = ub - lb
    d = unit * span * delta[:, None, None]
    trial = parents + d
    # a coordinate that would leave the box on one side moves the other way instead
    d = np.where((trial > ub) | (trial < lb), -d, d)
    # shorten the whole step (same direction) where even the turned coordinate overshoots
    with np.errstate(divide="ignore", invalid="ignore"):
        room = np.where(d > 0, (ub - parents) / d, np.where(d < 0, (lb - parents) / d, np.inf))
    s = np.minimum(1.0, room.min(axis=2, initial=np.inf))
    child = parents + s[:, :, None] * d
    return np.clip(child, lb, ub)  # rounding only; the step is already feasible


def generation_sizes(P: int, elite_count: int | None, crossover_fraction: float):
    """The elite, crossover children and mutation children of a generation of ``P`` (MATLAB's
    ``EliteCount``, default ``ceil(0.05 P)``, and ``CrossoverFraction`` of the rest, rounded)."""
    n_elite = math.ceil(0.05 * P) if elite_count is None else int(elite_count)
    if not 0 <= n_elite < P:
        raise ValueError(f"elite_count must be in [0, pop_size), got {n_elite}")
    if not 0.0 <= crossover_fraction <= 1.0:
        raise ValueError(f"crossover_fraction must be in [0, 1], got {crossover_fraction}")
    n_xover = math.floor(crossover_fraction * (P - n_elite) + 0.5)  # MATLAB round()
    return n_elite, n_xover, P - n_elite - n_xover


def scattered_crossover(X: np.ndarray, parents: np.ndarray, take_first: np.ndarray) -> np.ndarray:
    """``crossoverscattered`` of every run: child k takes each coordinate from parent 2k where
    ``take_first`` (a uniform below 1/2), else from parent 2k + 1."""
    which = np.arange(X.shape[0])[:, None]  # each run's own rows in fancy indexing
    n_xover = take_first.shape[1]
    p1, p2 = parents[:, 0 : 2 * n_xover : 2], parents[:, 1 : 2 * n_xover : 2]
    return np.where(take_first, X[which, p1], X[which, p2])


def adapted_step(delta: np.ndarray, best_last: np.ndarray, best_before: np.ndarray):
    """``mutationadaptfeasible``'s step of every run: four times larger (at most 1) after a
    generation that improved the best score, four times smaller (at least sqrt(eps)) else."""
    improved = best_last < best_before
    return np.where(improved, np.minimum(1.0, 4.0 * delta), np.maximum(_SQRT_EPS, delta / 4.0))


@register("ga")
def ga(
    runs: Runs,
    rngs: list[np.random.Generator],
    pop_size: int,
    *,
    elite_count: int | None = None,
    crossover_fraction: float = 0.8,
    mutation: str = "adaptfeasible",
    scale: float = 1.0,
    shrink: float = 1.0,
) -> Steps:
    """Minimise with the MATLAB-``ga``-like GA described in the module docstring, every run of
    ``runs`` moved as one array operation, each from its own generator in ``rngs``.

    ``elite_count`` defaults to ``ceil(0.05 * pop_size)``; ``scale`` and ``shrink`` apply only to
    ``mutation="gaussian"`` (MATLAB's mutationgaussian defaults, 1 and 1).
    """
    S, P, D = runs.n, int(pop_size), runs.dim
    if mutation not in ("adaptfeasible", "gaussian"):
        raise ValueError(f"mutation must be 'adaptfeasible' or 'gaussian', got {mutation!r}")
    n_elite, n_xover, n_mut = generation_sizes(P, elite_count, crossover_fraction)
    n_kids = n_xover + n_mut
    n_parents = 2 * n_xover + n_mut
    lb, ub = runs.lb, runs.ub
    adaptive = mutation == "adaptfeasible"
    which = np.arange(S)[:, None]  # each run's own rows in fancy indexing

    X, score = yield from runs.initial_population(rngs, P)  # X: (S, P, D)
    best_before, best_last = np.full(S, np.nan), score.min(axis=1)  # the last two generations'
    delta = np.ones(S)
    offset = np.empty(S)
    perm = np.empty((S, n_parents), dtype=np.int64)
    # per run: the crossover mask's uniforms, then (adaptfeasible) the mutation directions'
    uniforms = np.empty((S, (n_kids if adaptive else n_xover) * D))
    normals = np.empty((S, n_mut, D))

    t = 0
    while not runs.done.all():  # the runs move in step: one budget, the same evaluations each
        t += 1
        nfe_start = runs.nfe.copy()
        for s, rng in enumerate(rngs):
            offset[s] = rng.random()
            perm[s] = rng.permutation(n_parents)
            rng.random(out=uniforms[s])
            if not adaptive:
                normals[s] = rng.standard_normal((n_mut, D))
        expectation, order = rank_expectation(score, n_parents)
        parents = stochastic_uniform(offset, expectation, n_parents)
        parents = np.take_along_axis(parents, perm, axis=1)
        elite = order[:, :n_elite]

        take_first = uniforms[:, : n_xover * D].reshape(S, n_xover, D) < 0.5
        xover_kids = scattered_crossover(X, parents, take_first)
        mut_parents = X[which, parents[:, 2 * n_xover :]]
        if adaptive:
            if t > 2:
                delta = adapted_step(delta, best_last, best_before)
            unit = -1.0 + 2.0 * uniforms[:, n_xover * D :].reshape(S, n_mut, D)  # U(-1, 1)
            mut_kids = adaptive_feasible(unit, mut_parents, delta, lb, ub)
        else:
            sigma = scale * (1.0 - shrink * runs.progress())  # t/T
            noise = normals * (ub - lb) * sigma[:, None, None]
            mut_kids = np.clip(mut_parents + noise, lb, ub)

        kids = np.concatenate([xover_kids, mut_kids], axis=1)
        kid_score = yield from runs.ask(kids)
        X = np.concatenate([X[which, elite], kids], axis=1)
        score = np.concatenate([np.take_along_axis(score, elite, axis=1), kid_score], axis=1)
        best_before, best_last = best_last, score.min(axis=1)
        if (runs.nfe - nfe_start < n_kids).any():
            break  # the evaluation budget ended inside this generation
        runs.end_iteration()
