"""Artificial Gorilla Troops Optimizer (GTO).

Reference: B. Abdollahzadeh, F. S. Gharehchopogh, S. Mirjalili, "Artificial gorilla troops
optimizer: A new nature-inspired metaheuristic algorithm for global optimization problems",
International Journal of Intelligent Systems 36 (2021) 5887-5958, doi:10.1002/int.22535.
The algorithm here follows the authors' reference MATLAB code (``GTO.m``, MathWorks File Exchange
95953 / github.com/Benyamin-abdollahzadeh/Artificial-gorilla-troops-optimizer). Fahmy et al. 2023
(Mathematics 11, 2215) use GTO only as a comparator (their ref. [57]) and print none of its
equations or settings.

Names: the code's ``a`` is the paper's C, the code's ``C`` is the paper's L; below the paper's
names are used. X = the gorillas' positions (memory, greedy-updated), GX = candidate positions,
S = silverback (best position ever evaluated). ``It`` = 1..T.

Pseudo-code (one iteration = two population evaluations)::

    X <- uniform in [lb, ub]^D (P gorillas); evaluate; S <- best; GX <- X
    while budget left:
        C = (cos(2 rand) + 1) (1 - It/T);  L = C (2 rand - 1)              # once per iteration
        # exploration (sequential: a "GX_r" row already regenerated this iteration is the new one)
        for i = 1..P:
            if rand < p:       GX_i = (ub - lb) r + lb                     # r one scalar
            elif rand >= 0.5:  GX_i = (r - C) X_r + L Z * X_i, Z ~ U(-C, C)^D
            else:              GX_i = X_i - L (L (X_i - GX_r1) + r (X_i - GX_r2))
        GX <- clip(GX); evaluate GX; X_i <- GX_i where strictly better; S <- best ever
        # exploitation (S is the silverback after the exploration evaluation)
        if C >= w:   for i = 1..P (sequential):                            # follow the silverback
                         M = |mean over rows of GX|  (rows 1..i-1 already replaced)
                         GX_i = L M * (X_i - S) + X_i
        else:        GX_i = S - (S Q - X_i Q) beta E, Q = 2 rand - 1,      # compete for females
                     E ~ N(0, 1)^D or one N(0, 1) scalar, with probability 1/2 each
        GX <- clip(GX); evaluate GX; greedy replacement; S <- best ever

Vectorised where the code's semantics allow it: all random draws, the "unknown place" and "known
place" moves, the competition move, the evaluations and the greedy replacement (the code's
replacement loop only writes X_i/S, which nothing else in that loop reads). Kept sequential over
the gorillas, as in the code: the "other gorillas" move (it reads GX rows that may already have
been regenerated in the same loop) and the follow-silverback move (its mean of GX changes as rows
are replaced). A fixed-evaluation budget is checked between the two evaluations.

Seeds in one array. The runs of a fit block (its seeds) move together, as arrays shaped runs x
gorillas x dimension (they share the budget, so they are always at the same iteration and phase):
every move above is one array operation over all runs, and the two sequential loops are
compiled loops (numba) over the runs and gorillas, because as numpy operations over the runs, one
per gorilla, they cost more than all the array moves. C and L are drawn per run, so whether a
run follows the silverback or competes (C >= w) is a mask over the runs. Each run draws from its
own generator exactly what the one-run algorithm drew, in the same order, per iteration: C's and
L's uniforms, u_unknown, u_known, r and Z in one ``rng.random`` call (consecutive doubles of one
stream are the same whether drawn in one call or several, and ``uniform(-C, C)`` is
``-C + 2C d`` of the same double), then the rows ``rng.integers(0, P, (P, 3))``; after the
exploration evaluation, only if it competes, the vector/scalar choice, E's normals (one
``standard_normal`` call for the P x D and the P of them) and Q's uniforms. C is computed with
``math.cos`` run by run, the one-run code's function (numpy's vectorised cosine is not promised
to round as libm's does on every CPU).

Differences between (a) the authors' code, (b) the original GTO paper, (c) Fahmy et al. (no GTO
equations printed, nothing to compare) and (d) mealpy 3.0.2 ``OriginalAGTO`` (mealpy's ``GTO`` is
the unrelated Giant Trevally Optimizer); **choice** = what this module does.
(b) is the paper's printed form as widely reproduced; it was not re-checked against the PDF here.

1.  C and L: (a) both drawn once per iteration; (b) same formulas (C = F (1 - It/MaxIt),
    F = cos(2 r4) + 1, L = C l, l ~ U(-1, 1)); (d) as (a). **choice: (a)**, It = 1..T.
2.  Migration to an unknown place (rand < p): (a), (b) (ub - lb) r1 + lb with one scalar r1, i.e.
    a point on the box diagonal; (d) an independent uniform per dimension. **choice: (a).**
3.  Moving to a known place (rand >= 0.5): (r2 - C) X_r + L H, H = Z * X_i, Z ~ U(-C, C)^D,
    X_r a random row of X -- (a), (b), (d) agree. **choice: (a).**
4.  Moving toward other gorillas (rand < 0.5): (a) X_i - L (L (X_i - GX_r1) + r3 (X_i - GX_r2))
    with two independent random rows of the candidate array GX, overwritten in place during the
    loop; (b) one random GX_r in both places; (d) X_i - L (L X_i - X_id1) + r (X_i - X_id2) with
    id1 != id2 != i drawn from the memory population X -- another formula (L X_i - X_id1 instead
    of L (X_i - GX_r); the r-term outside the L factor, with + sign). **choice: (a).**
5.  Group formation: (a), (b) evaluate all candidates, then X_i <- GX_i if strictly better and
    S <- the best; (d) in its default "single" mode replaces X_i immediately, so later gorillas of
    the same phase already see the new X. **choice: (a)** (batch evaluation).
6.  Following the silverback (C >= w): (a) M = (|mean(GX)|^g)^(1/g), g = 2^L, where GX is being
    overwritten row by row in the same loop; (b) M = (|1/N sum GX_i|^g)^(1/g) (no order given);
    (d) the mean of the memory population X, computed once. **choice: (a)**, computing M as
    |mean(GX)|, which equals (|m|^g)^(1/g) for every g = 2^L > 0 up to rounding and cannot overflow.
7.  Competition for adult females (C < w): S - (S Q - X_i Q) A, A = beta E -- (a), (b), (d) agree
    ((d) rearranged as S - Q (S - X_i) beta E). **choice: (a).**
8.  Bounds: (a) clips the candidate array after each phase (boundaryCheck); (d) clips each
    candidate; (b) silent. **choice: clip** after each phase.
9.  Evaluations: 2 P per iteration plus P for the initial population in (a) and (d) and here.
10. Parameters: p = 0.03, beta = 3, w = 0.8 in (a), (b); (d) names them p1, beta, p2.
11. Horizon T for It/T: :meth:`.base.Runs.planned_iterations` with 2 P evaluations per
    iteration: the budget's ``iterations``; under a pure evaluation budget the number of
    iterations that fit, ceil((max_nfe - P) / (2 P)) (the smaller of the two if both are set).
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

from .base import Runs, Steps, register


class _Troop:
    """Every run's positions X, their costs, and its silverback (arrays over runs); group
    formation = greedy replacement."""

    def __init__(self, X: np.ndarray, cost: np.ndarray):
        self.X = X  # (runs, P, D)
        self.cost = cost  # (runs, P)
        each = np.arange(X.shape[0])
        k = np.argmin(cost, axis=1)
        self.silverback = X[each, k]  # (runs, D)
        self.silverback_cost = cost[each, k]

    def group_formation(self, GX: np.ndarray, cost: np.ndarray) -> None:
        better = cost < self.cost
        self.X[better] = GX[better]
        self.cost[better] = cost[better]
        k = np.argmin(cost, axis=1)
        best = cost[np.arange(GX.shape[0]), k]
        m = best < self.silverback_cost
        if m.any():
            self.silverback[m] = GX[m, k[m]]
            self.silverback_cost[m] = best[m]


@nb.njit(cache=True, nogil=True)
def _move_to_others(GX, old, X, idx, others, L, r) -> None:
    """The "other gorillas" move of every run, in place, gorilla by gorilla as the reference's
    loop: row ``i`` of a run that makes this move reads the candidates ``GX_r1``, ``GX_r2``
    (``idx[:, i, 1:]``) as already regenerated if they come before ``i``, else from ``old``."""
    n, P, D = GX.shape
    for s in range(n):
        for i in range(P):
            if not others[s, i]:
                continue
            j1, j2 = idx[s, i, 1], idx[s, i, 2]
            for d in range(D):
                g1 = GX[s, j1, d] if j1 < i else old[s, j1, d]
                g2 = GX[s, j2, d] if j2 < i else old[s, j2, d]
                x = X[s, i, d]
                GX[s, i, d] = x - L[s] * (L[s] * (x - g1) + r[s, i] * (x - g2))


@nb.njit(cache=True, nogil=True)
def _follow_silverback(GX, X, silverback, L, follow) -> None:
    """The follow-the-silverback move of every run in ``follow``, in place, gorilla by gorilla as
    the reference's loop: row ``i`` uses M = |mean of GX's rows| with the rows before ``i``
    already replaced. The mean adds the rows in order and divides by their number, as numpy's
    ``mean(axis=0)`` of a population of two or more dimensions does (of one dimension numpy
    sums pairwise, which may round a last bit differently)."""
    n, P, D = GX.shape
    for s in range(n):
        if not follow[s]:
            continue
        for i in range(P):
            for d in range(D):  # M's coordinate d depends on column d alone
                total = GX[s, 0, d]
                for j in range(1, P):
                    total += GX[s, j, d]
                M = abs(total / P)
                GX[s, i, d] = L[s] * M * (X[s, i, d] - silverback[s, d]) + X[s, i, d]


class _Draws:
    """Every run's random numbers of one iteration, drawn in the one-run code's order: C's and
    L's uniforms, u_unknown, u_known, r (P each) and Z (P x D) in ``uniform``, the rows X_r,
    GX_r1, GX_r2 in ``idx``; after the exploration evaluation, only by a run that competes,
    the vector/scalar choice, E's normals (P x D, then P) and Q's uniforms (zeros until drawn:
    a following run's are never used)."""

    def __init__(self, S: int, P: int, D: int):
        self.P = P
        self.uniform = np.empty((S, 2 + 3 * P + P * D))
        self.idx = np.empty((S, P, 3), dtype=np.int64)
        self.choice = np.zeros((S, P))
        self.normals = np.zeros((S, P * D + P))
        self.q = np.zeros((S, P))

    def exploration(self, rngs: list[np.random.Generator], decay: float) -> np.ndarray:
        """Draw the exploration's numbers of every run; its C, with libm's ``math.cos`` run by
        run (the module docstring says why)."""
        C = np.empty(len(rngs))
        for s, rng in enumerate(rngs):
            rng.random(out=self.uniform[s])
            self.idx[s] = rng.integers(0, self.P, size=(self.P, 3))
            C[s] = (math.cos(2.0 * self.uniform[s, 0]) + 1.0) * decay
        return C

    def competition(self, rngs: list[np.random.Generator], compete: np.ndarray) -> None:
        """Draw the competition's numbers of the runs in the mask ``compete``."""
        for s in np.flatnonzero(compete):
            rng = rngs[s]
            rng.random(out=self.choice[s])
            rng.standard_normal(out=self.normals[s])
            rng.random(out=self.q[s])


def explore(X, GX, draws: _Draws, C, L, p: float, lb, ub) -> np.ndarray:
    """Every gorilla's exploration candidate (unclipped; ``GX`` is the last candidates, read by
    the move toward other gorillas): migration to an unknown place (rand < p), to a known place
    (rand >= 0.5) or toward other gorillas."""
    S, P, D = X.shape
    Cb, Lb = C[:, None, None], L[:, None, None]
    per = draws.uniform[:, 2 : 2 + 3 * P].reshape(S, 3, P)
    unknown = per[:, 0] < p
    known = ~unknown & (per[:, 1] >= 0.5)
    others = ~unknown & ~known
    r = per[:, 2]  # r1 / r2 / r3 of the one move each gorilla makes
    lo = -Cb
    Z = lo + (Cb - lo) * draws.uniform[:, 2 + 3 * P :].reshape(S, P, D)  # rng.uniform(-C, C)
    which = np.arange(S)[:, None]  # each run's own rows in fancy indexing
    new = np.where(
        unknown[:, :, None],
        (ub - lb) * r[:, :, None] + lb,
        (r[:, :, None] - Cb) * X[which, draws.idx[:, :, 0]] + Lb * Z * X,
    )
    _move_to_others(new, GX, X, draws.idx, others, L, r)
    return new


def exploit(GX, X, silverback, draws: _Draws, L, follow, beta: float) -> np.ndarray:
    """Every gorilla's exploitation candidate (unclipped): the runs in ``follow`` (C >= w)
    follow the silverback (``GX`` changed in place, row by row), the others compete for adult
    females."""
    S, P, D = GX.shape
    compete = ~follow
    new = GX
    if follow.any():  # follow the silverback; the mean of GX changes as its rows are replaced
        _follow_silverback(GX, X, silverback, L, follow)
    if compete.any():  # competition for adult females
        E = np.where(
            (draws.choice >= 0.5)[:, :, None],
            draws.normals[:, : P * D].reshape(S, P, D),
            draws.normals[:, P * D :, None],
        )
        Q = 2.0 * draws.q[:, :, None] - 1.0
        competed = silverback[:, None] - (silverback[:, None] * Q - X * Q) * (beta * E)
        new = np.where(follow[:, None, None], GX, competed)
    return new


@register("gto")
def gto(
    runs: Runs,
    rngs: list[np.random.Generator],
    pop_size: int,
    p: float = 0.03,
    beta: float = 3.0,
    w: float = 0.8,
) -> Steps:
    """GTO as in the authors' MATLAB code (see the module docstring for every deviation), every
    run of ``runs`` moved as one array operation, each from its own generator in ``rngs``."""
    if not 0.0 <= p <= 1.0:
        raise ValueError(f"p must be in [0, 1], got {p}")

    S, P, D = runs.n, pop_size, runs.dim
    X, cost = yield from runs.initial_population(rngs, P)  # X: (S, P, D)
    troop = _Troop(X, cost)
    GX = X.copy()
    T = runs.planned_iterations(2 * P)
    draws = _Draws(S, P, D)

    while not runs.done.all():  # the runs move in step: one budget, the same evaluations each
        It = int(runs.iteration[0]) + 1
        C = draws.exploration(rngs, max(0.0, 1.0 - It / T))
        L = C * (2.0 * draws.uniform[:, 1] - 1.0)
        X = troop.X

        GX = runs.clip(explore(X, GX, draws, C, L, p, runs.lb, runs.ub))
        troop.group_formation(GX, (yield from runs.ask(GX)))
        if runs.done.all():
            break

        # the silverback after the exploration evaluation
        follow = w <= C
        draws.competition(rngs, ~follow)
        GX = runs.clip(exploit(GX, X, troop.silverback, draws, L, follow, beta))
        troop.group_formation(GX, (yield from runs.ask(GX)))
        runs.end_iteration()
