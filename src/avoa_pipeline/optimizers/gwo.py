"""Grey Wolf Optimizer (GWO).

Mirjalili, S., Mirjalili, S. M., Lewis, A. (2014). Grey Wolf Optimizer. Advances in Engineering
Software 69, 46-61. doi:10.1016/j.advengsoft.2013.12.007

Follows the authors' reference MATLAB code (``GWO.m``, MathWorks File Exchange 44974), written
here from its description, vectorised over the population.

Pseudo-code (``P`` wolves, ``T`` planned iterations, leaders alpha/beta/delta with scores
``+inf`` and positions ``0``)::

    X <- uniform in [lb, ub]                        # P x D
    f <- F(X); update_leaders(X, f)                 # iteration 0
    for t = 1..T:
        a <- 2 - 2 (t - 1) / T                      # linearly 2 -> 2/T
        for each leader L in (alpha, beta, delta), independently per wolf and dimension:
            A <- 2 a r1 - a;  C <- 2 r2             # r1, r2 ~ U(0, 1)
            X_L <- L - A |C L - X|
        X <- clip((X_alpha + X_beta + X_delta) / 3, lb, ub)
        f <- F(X); update_leaders(X, f)

    update_leaders (sequentially over the wolves, in order, exactly as the reference):
        if f_i < s_alpha:                         alpha <- (x_i, f_i)
        if s_alpha < f_i < s_beta:                beta  <- (x_i, f_i)
        if s_alpha < f_i, s_beta < f_i < s_delta: delta <- (x_i, f_i)

Faithful details of the reference (kept on purpose):

- The leaders are the best positions *ever* seen (they persist across iterations), but the update
  rule is the reference's: a new alpha does not demote the old alpha to beta (nor beta to delta).
  So beta/delta are "the best points found after alpha was last bettered that are worse than
  alpha", not the 2nd/3rd best ever.
- No greedy selection: every wolf moves to its new position whether or not it is better; the
  population is not sorted.
- Out-of-box coordinates are clipped to the bound (the reference's ``Flag4ub/Flag4lb`` step).
- Unset leaders keep the reference's initial position ``zeros(1, dim)``. With ``P >= 3`` wolves in
  random order a leader stays unset only if the first ``P`` fitness values are strictly decreasing
  (probability ``1/P!``), so this matters only for degenerate populations.

Iteration / budget mapping: the reference evaluates at the *start* of each of its ``Max_iter``
loops and computes ``a = 2 - l * 2 / Max_iter`` (``l = 0..Max_iter-1``) for the move that follows;
its last move is never evaluated. Here the initial population is iteration 0 (``P`` evaluations)
and each of the ``T`` iterations evaluates one moved population, with the move of iteration ``t``
using the reference's ``l = t - 1``. So ``Budget(iterations=500)`` gives the reference's run with
``Max_iter = 501`` evaluation rounds and the ``a``-schedule of ``Max_iter = 500``. Under a pure
evaluation budget ``Budget(max_nfe=N, iterations=None)``, ``T = ceil((N - P) / P)``
(:meth:`.base.Runs.planned_iterations`); the last, possibly partial population is cut by the
budget's accounts (:class:`.base.Runs`).

Seeds in one array. The runs of a fit block (its seeds) move together, as arrays shaped runs x
wolves x dimension: one ``a`` for all (they share the budget, so they are always at the same
iteration), one array operation for every run's move. Each run draws from its own generator
exactly what the one-run algorithm drew, in the same order: per iteration ``r1`` then ``r2``,
each ``3 x P x D`` uniforms, here as one ``rng.random`` call per run (consecutive doubles of one
stream are the same whether drawn in one call or two). The leader update stays sequential over
the wolves, as in the reference: a compiled loop (numba) over the runs and wolves, because as
numpy operations over the runs, one per wolf and comparison, it costs more than the whole move
(a few array operations over every run at once).

Differences vs mealpy 3.0.2 ``GWO.OriginalGWO``:

- mealpy applies **greedy selection** (a wolf keeps its old position unless the new one is
  better; in the default ``mode="single"`` this is per wolf, right after evaluating it) and picks
  alpha/beta/delta as the 3 best of the *current* population at the start of the epoch. Its
  population is therefore a set of personal bests, and its leaders are the true three best points.
  Expected direction: greedy selection is *more exploitative* and loses diversity, so at equal
  evaluation budgets mealpy should reach lower values on the unimodal sphere (observed at 2,000
  evaluations: ~100x lower median, p < 1e-5 at 20 seeds) and stagnate more on multimodal
  Rastrigin (observed: ours lower in every pilot seed set, p = 0.002-0.06); no clear prior and no
  significant difference on Rosenbrock. See ``tests/unit/test_vs_mealpy.py`` and
  ``docs/reproduction-notes.md`` (section Optimizers).
- mealpy's ``a = 2 - 2 epoch / epochs`` (``epoch = 1..epochs``) starts at ``2 - 2/epochs`` and ends
  at 0; ours starts at 2 and ends at ``2/T`` (the reference's schedule).
- mealpy draws ``A``/``C`` per wolf as vectors; same distribution as ours.
"""

from __future__ import annotations

import numba as nb
import numpy as np

from .base import Runs, Steps, register


@nb.njit(cache=True, nogil=True)
def update_leaders(f: np.ndarray, X: np.ndarray, pos: np.ndarray, score: np.ndarray) -> None:
    """The reference's sequential alpha/beta/delta update (see the module docstring) of every run:
    ``f`` (runs x wolves), ``X`` (runs x wolves x D); ``pos`` (runs x 3 x D) and ``score``
    (runs x 3) are updated in place, wolf by wolf in index order."""
    for s in range(f.shape[0]):
        for i in range(f.shape[1]):
            fi = f[s, i]
            if fi < score[s, 0]:
                score[s, 0] = fi
                pos[s, 0] = X[s, i]
            if fi > score[s, 0] and fi < score[s, 1]:
                score[s, 1] = fi
                pos[s, 1] = X[s, i]
            if fi > score[s, 0] and fi > score[s, 1] and fi < score[s, 2]:
                score[s, 2] = fi
                pos[s, 2] = X[s, i]


@register("gwo")
def gwo(runs: Runs, rngs: list[np.random.Generator], pop_size: int, **settings) -> Steps:
    """Grey Wolf Optimizer (reference MATLAB version), every run of ``runs`` moved as one array
    operation, each from its own generator in ``rngs``; no tunable settings."""
    if settings:
        raise TypeError(f"gwo takes no settings, got {sorted(settings)}")
    S, P, D = runs.n, pop_size, runs.dim
    T = runs.planned_iterations(P)  # the a-schedule's horizon

    leader_pos = np.zeros((S, 3, D))  # alpha, beta, delta (reference: zeros(1, dim))
    leader_score = np.full((S, 3), np.inf)

    X, f = yield from runs.initial_population(rngs, P)  # X: (S, P, D)
    update_leaders(f, X, leader_pos, leader_score)
    draws = np.empty((S, 2, 3, P, D))  # per run: r1, r2

    t = 0
    while not runs.done.all():  # the runs move in step: one budget, the same evaluations each
        t += 1
        a = 2.0 - 2.0 * (t - 1) / T
        for s, rng in enumerate(rngs):
            rng.random(out=draws[s])
        A = 2.0 * a * draws[:, 0] - a  # (S, 3, P, D)
        C = 2.0 * draws[:, 1]
        L = leader_pos[:, :, None, :]  # (S, 3, 1, D)
        X = runs.clip(np.mean(L - A * np.abs(C * L - X[:, None]), axis=1))
        update_leaders((yield from runs.ask(X)), X, leader_pos, leader_score)
        runs.end_iteration()
