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
replacement loop only writes X_i/S, which nothing else in that loop reads). Kept sequential,
as in the code: the "other gorillas" move (it reads GX rows that may already have been
regenerated in the same loop) and the follow-silverback move (its mean of GX changes as rows are
replaced). A fixed-evaluation budget is checked between the two evaluations.

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
11. Horizon T for It/T: :meth:`.base.Tracker.planned_iterations` with 2 P evaluations per
    iteration: the budget's ``iterations``; under a pure evaluation budget the number of
    iterations that fit, ceil((max_nfe - P) / (2 P)) (the smaller of the two if both are set).
"""

from __future__ import annotations

import math

import numpy as np

from .base import Steps, Tracker, register


class _Troop:
    """Positions X, their costs, and the silverback; group formation = greedy replacement."""

    def __init__(self, X: np.ndarray, cost: np.ndarray):
        self.X = X
        self.cost = cost
        k = int(np.argmin(cost))
        self.silverback = X[k].copy()
        self.silverback_cost = float(cost[k])

    def group_formation(self, GX: np.ndarray, cost: np.ndarray) -> None:
        better = cost < self.cost
        self.X[better] = GX[better]
        self.cost[better] = cost[better]
        k = int(np.argmin(cost))
        if cost[k] < self.silverback_cost:
            self.silverback = GX[k].copy()
            self.silverback_cost = float(cost[k])


@register("gto")
def gto(
    tracker: Tracker,
    rng: np.random.Generator,
    pop_size: int,
    p: float = 0.03,
    beta: float = 3.0,
    w: float = 0.8,
) -> Steps:
    """GTO as in the authors' MATLAB code (see the module docstring for every deviation)."""
    if not 0.0 <= p <= 1.0:
        raise ValueError(f"p must be in [0, 1], got {p}")

    P, D = pop_size, tracker.dim
    lb, ub = tracker.lb, tracker.ub

    X = tracker.random_uniform(rng, P)
    troop = _Troop(X, (yield from tracker.ask(X)))
    GX = X.copy()
    tracker.end_iteration()
    T = tracker.planned_iterations(2 * P)

    while not tracker.done:
        It = tracker.iteration + 1
        C = (math.cos(2.0 * rng.random()) + 1.0) * max(0.0, 1.0 - It / T)
        L = C * (2.0 * rng.random() - 1.0)
        X = troop.X

        # --- exploration ----------------------------------------------------------------------
        u_unknown = rng.random(P) < p
        u_known = rng.random(P) >= 0.5
        r = rng.random(P)  # r1 / r2 / r3 of the one move each gorilla makes
        Z = rng.uniform(-C, C, (P, D))
        idx = rng.integers(0, P, size=(P, 3))  # X_r, GX_r1, GX_r2
        unknown = u_unknown
        known = ~u_unknown & u_known
        others = ~u_unknown & ~u_known
        old = GX
        GX = np.empty_like(old)
        GX[unknown] = (ub - lb) * r[unknown, None] + lb
        GX[known] = (r[known, None] - C) * X[idx[known, 0]] + L * Z[known] * X[known]
        for i in np.flatnonzero(others):
            # rows before i were regenerated already in the reference loop, the others not yet
            j1, j2 = idx[i, 1], idx[i, 2]
            g1 = GX[j1] if j1 < i else old[j1]
            g2 = GX[j2] if j2 < i else old[j2]
            GX[i] = X[i] - L * (L * (X[i] - g1) + r[i] * (X[i] - g2))
        GX = tracker.clip(GX)
        troop.group_formation(GX, (yield from tracker.ask(GX)))
        if tracker.done:
            break

        # --- exploitation (the silverback after the exploration evaluation) --------------------
        S = troop.silverback
        if w <= C:  # follow the silverback; the mean of GX changes as its rows are replaced
            for i in range(P):
                M = np.abs(GX.mean(axis=0))
                GX[i] = L * M * (X[i] - S) + X[i]
        else:  # competition for adult females
            vector = rng.random(P) >= 0.5
            E = np.where(vector[:, None], rng.standard_normal((P, D)), rng.standard_normal((P, 1)))
            Q = 2.0 * rng.random((P, 1)) - 1.0
            GX = S - (S * Q - X * Q) * (beta * E)
        GX = tracker.clip(GX)
        troop.group_formation(GX, (yield from tracker.ask(GX)))
        tracker.end_iteration()
