"""RUN, the RUNge Kutta optimizer (the paper's "RK").

Reference
---------
I. Ahmadianfar, A. A. Heidari, A. H. Gandomi, X. Chu, H. Chen (2021). RUN beyond the metaphor:
An efficient optimization algorithm based on Runge Kutta method. Expert Systems with Applications
181:115079. doi:10.1016/j.eswa.2021.115079

Followed: the authors' MATLAB reference code ``RUN.m`` (header "Last update: 04-22-2021") as
published in the GitHub repository aliasgharheidaricom/RUN-Beyond-the-Metaphor-An-Efficient-
Optimization-Algorithm-Based-on-Runge-Kutta-Method, with its helpers ``RungeKutta``, ``Unifrnd``
and ``RndX``. This module is an independent re-implementation of that code's semantics.

Pseudo-code (reference semantics; ``it/MaxIt`` is written ``τ``, see "Schedule" below)
-------------------------------------------------------------------------------------
::

    X ← P uniform points in [lb, ub];  cost ← f(X);  (x*, f*) ← best
    while budget left:                                          # one iteration
        f_τ  ← 20·exp(−12·τ)                                    # Eq. 17.6
        x̄    ← mean(X)                                          # population mean
        SF_i ← 2·(0.5 − rand)·f_τ  for every agent              # Eq. 17.5
        for i = 1..P  (SEQUENTIALLY, population updated in place):
            x_lbest ← X[argmin cost]                            # current-population best
            a, b, c ← three distinct random agents ≠ i          # RndX
            k       ← the best of a, b, c
            γ   ← rand·(X_i − rand(D)·(ub − lb))·exp(−4τ)        # Eq. 11
            Stp ← rand(D)·((x* − rand·x̄) + γ);  Δx ← 2·rand(D)·|Stp|
            (x_b, x_w) ← (X_i, X_k) if cost_i < cost_k else (X_k, X_i)
            SM  ← RungeKutta(x_b, x_w, Δx)                      # K1..K4, (K1+2K2+2K3+K4)/6
            L   ← rand(D) < 0.5
            x_c ← L·X_i + (1−L)·X_a;   x_m ← L·x* + (1−L)·x_lbest  # Eqs. 17.3, 17.4
            r ← ±1 per coordinate;  g ← 2·rand;  μ ← 0.5 + 0.1·randn(D)
            if rand < 0.5:  x_new ← x_c + r·SF_i·g·x_c + SF_i·SM + μ·(x_m − x_c)     # Eq. 18
            else:           x_new ← x_m + r·SF_i·g·x_m + SF_i·SM + μ·(X_a − X_b)
            x_new ← clip(x_new);  greedy replace X_i                # evaluation 1
            if rand < 0.5:                                      # ESQ, Eq. 19
                w ← 2·rand(D)·exp(−5·rand·τ);  r ← floor(−1 + 3·rand) ∈ {−1, 0, 1}
                u ← 2·rand(D);  a, b, c ← RndX;  x̄ ← (X_a + X_b + X_c)/3   (overwrites x̄!)
                β ← rand(D);  x_1 ← β·x* + (1−β)·x̄
                x_2 ← x_1 + r·w·|x_1 − x̄ + randn|            where w < 1
                      (x_1 − x̄) + r·w·|u·x_1 − x̄ + randn|     where w ≥ 1
                x_2 ← clip(x_2);  greedy replace X_i                # evaluation 2
                if x_2 was not accepted and rand < w[random coordinate]:          # Eq. 20
                    SM  ← RungeKutta(X_i, x_2, Δx)
                    x_3 ← (x_2 − rand·x_2) + SF_i·(SM + (2·rand(D)·x* − x_2))
                    x_3 ← clip(x_3);  greedy replace X_i            # evaluation 3
            if cost_i < f*:  (x*, f*) ← (X_i, cost_i)

Evaluations per agent and iteration: 1, 2 or 3 (not 1-2: the Eq. 20 step is a third, conditional
evaluation), so an iteration costs between P and 3·P evaluations: measured about 1.75·P early
in a run and 1.6·P late (5-D sphere/Rosenbrock, P = 20). Every evaluation is preceded by a
``tracker.done`` check, so a ``max_nfe`` budget is met exactly.

Sequential updates (kept on purpose). The reference updates agent i in place before agent i+1
moves, and agent i+1 sees that: x_lbest and the random partners read the updated population, and
x* is refreshed after each agent. Vectorising over the population would change the algorithm, so
the agent loop is kept; only the random numbers of fixed shape are drawn per iteration in bulk
(the three-partner draws included), which changes the random stream but not the distribution.

Schedule. The reference counts ``it = 2..MaxIt`` with the initial population as ``it = 1`` and uses
``τ = it/MaxIt``. With an iteration budget T (our iteration t = 1..T after the initial population)
this is ``τ = (t+1)/(T+1)``, which reaches 1 in the last iteration exactly as the reference does.
With an evaluation budget, τ is the fraction of the budget that will have been spent by the end of
the iteration, estimated from the evaluations of the previous iteration
(``min(1, (nfe + nfe_prev_iteration)/max_nfe)``); with both budgets the larger fraction is used.
Both are :meth:`.base.Tracker.progress` with ``count_initial=True``.

Differences between (a) the reference code, (b) the paper and (c) mealpy 3.0.2 ``OriginalRUN``
--------------------------------------------------------------------------------------------------
The paper text could not be consulted in this environment; the (b) entries marked "recalled" are
from memory of the published equations and should be checked against the article.

1. ``μ`` in Eq. 18. (a) ``0.5 + 0.1·randn(D)``; (b) recalled: "μ·randn" in the printed equation;
   (c) ``0.5 + 1·U(0,1)^D`` (mean 1.0 instead of 0.5, never below 0.5). Choice: (a).
   Effect: at equal evaluations ours is worse than (c) on Rosenbrock; with (c)'s μ it is better
   (``tests/unit/test_vs_mealpy.py`` records the cell with the numbers).
2. ``f`` in Eq. 17.6. (a) ``20·exp(−12·it/MaxIt)``; (b) recalled: ``a·exp(−b·rand·it/MaxIt)``
   (a random factor in the exponent); (c) as (a) but with ``epoch/self.epoch`` (epoch = 1..E; the
   reference's first update uses it = 2). Choice: (a) with the τ mapping above.
3. Global best x* inside an iteration. (a) refreshed after every agent; (c) refreshed only at the
   end of the epoch (``update_global_best_agent``), so within an epoch every agent uses the
   epoch-start best. Choice: (a).
4. Population mean in γ/Stp. (a) the ESQ step overwrites the variable ``Xavg`` with the mean of
   its three random agents, so every later agent of the same iteration uses that three-agent mean
   in Stp (a side effect of variable reuse); (c) always the population mean. Choice: (a) by default
   (``esq_overwrites_mean=True``); ``False`` gives (c)'s behaviour.
5. Best-of-three partner. The current GitHub ``RUN.m`` picks ``ABC(ind1)``; an older copy with the
   same header indexes ``Cost(ind1)``/``X(ind1,:)`` directly, i.e. compares with agent 1, 2 or 3 of
   the population instead of the best of a, b, c (a bug). (c) follows the fixed version.
   Choice: fixed version.
6. Eq. 20 trigger. (a) ``rand < w(randi(D))``; (c) ``w[randint] > rand`` - same. Same in both:
   the RK step of Eq. 20 reuses Δx of the main step.
7. ESQ normals. (a) one ``randn`` per coordinate, used by whichever branch the coordinate takes;
   (c) two independent normal vectors, one per branch - same distribution. Choice: (a).
8. Termination. (a) MaxIt iterations, initial population counted as iteration 1; (c) checks the
   budget only at the end of an epoch, so ``max_fe`` can be overshot by up to ~3·P evaluations.
   Choice: our Tracker (exact evaluation budget; the paper's "500 iterations" = 500 update
   iterations after the initial population - the reference itself would run MaxIt−1 = 499).
9. Bounds. (a), (c): clip to [lb, ub] after every move. Choice: the same.
10. Ties. (a) ``Cost(i) < Cost(k)`` and greedy ``CostNew < Cost(i)`` strict; (c) strict. Same.
"""

from __future__ import annotations

import numpy as np

from .base import Tracker, register


def _three_partners(rng: np.random.Generator, P: int) -> np.ndarray:
    """For every agent i, three distinct random agents other than i (``RndX``), shape (P, 3)."""
    keys = rng.random((P, P))
    np.fill_diagonal(keys, np.inf)
    return np.argsort(keys, axis=1)[:, :3]


def _runge_kutta(rng: np.random.Generator, xb, xw, delx) -> np.ndarray:
    """The RK4-like search mechanism SM of the reference (``RungeKutta``)."""
    D = xb.size
    c = rng.integers(1, 3) * (1.0 - rng.random())
    r1 = rng.random(D)
    r2 = rng.random(D)
    k = 0.5 * (rng.random() * xw - c * xb)
    total = k.copy()
    for h, weight in ((0.5, 2.0), (0.5, 2.0), (1.0, 1.0)):
        step = h * k * delx
        k = 0.5 * (rng.random() * (xw + r2 * step) - (c * xb + r1 * step))
        total += weight * k
    return total / 6.0


@register("run")
def run(
    tracker: Tracker,
    rng: np.random.Generator,
    pop_size: int,
    *,
    esq_overwrites_mean: bool = True,
) -> None:
    """Minimise with RUN (see the module docstring). ``pop_size`` must be at least 4."""
    P, D = int(pop_size), tracker.dim
    if P < 4:
        raise ValueError(f"RUN needs pop_size >= 4 (three partners besides the agent), got {P}")
    lb, ub = tracker.lb, tracker.ub
    span = ub - lb

    X = tracker.random_uniform(rng, P)
    cost = tracker.evaluate(X)
    tracker.end_iteration()
    ib = int(np.argmin(cost))
    best_x, best_f = X[ib].copy(), float(cost[ib])

    evaluate_one = tracker.evaluate_one
    while not tracker.done:
        tau = tracker.progress(count_initial=True)  # the reference's it/MaxIt
        f_amp = 20.0 * np.exp(-12.0 * tau)
        x_mean = X.mean(axis=0)
        SF = 2.0 * (0.5 - rng.random(P)) * f_amp
        # random numbers of fixed shape for the main move of every agent, drawn in bulk
        partners = _three_partners(rng, P)
        g_scalar = rng.random(P)  # γ factor
        g_vec = rng.random((P, D))  # γ: rand(D)·(ub − lb)
        s_vec = rng.random((P, D))  # Stp factor
        s_scalar = rng.random(P)  # Stp: rand·x̄
        d_vec = rng.random((P, D))  # Δx factor
        L_all = rng.random((P, D)) < 0.5
        r_all = np.where(rng.random((P, D)) < 0.5, 1.0, -1.0)
        g_all = 2.0 * rng.random(P)
        mu_all = 0.5 + 0.1 * rng.standard_normal((P, D))
        branch = rng.random(P) < 0.5
        esq_gate = rng.random(P) < 0.5
        decay_gamma = np.exp(-4.0 * tau)

        complete = True
        for i in range(P):
            if tracker.done:
                complete = False
                break
            x_lbest = X[int(np.argmin(cost))]
            a, b, _ = partners[i]
            k = partners[i][int(np.argmin(cost[partners[i]]))]

            gamma = g_scalar[i] * (X[i] - g_vec[i] * span) * decay_gamma
            stp = s_vec[i] * ((best_x - s_scalar[i] * x_mean) + gamma)
            delx = 2.0 * d_vec[i] * np.abs(stp)
            if cost[i] < cost[k]:
                xb, xw = X[i], X[k]
            else:
                xb, xw = X[k], X[i]
            sm = _runge_kutta(rng, xb, xw, delx)

            L = L_all[i]
            xc = np.where(L, X[i], X[a])
            xm = np.where(L, best_x, x_lbest)
            r, g, mu, sf = r_all[i], g_all[i], mu_all[i], SF[i]
            if branch[i]:
                x_new = xc + r * sf * g * xc + sf * sm + mu * (xm - xc)
            else:
                x_new = xm + r * sf * g * xm + sf * sm + mu * (X[a] - X[b])
            x_new = tracker.clip(x_new)
            f_new = evaluate_one(x_new)
            if f_new < cost[i]:
                X[i], cost[i] = x_new, f_new

            if esq_gate[i]:  # enhanced solution quality (Eq. 19)
                if tracker.done:
                    complete = False
                    break
                decay_w = np.exp(-5.0 * rng.random() * tau)
                r_esq = np.floor(-1.0 + 3.0 * rng.random())  # Unifrnd(-1, 2) floored: -1, 0, 1
                u = 2.0 * rng.random(D)
                w = 2.0 * rng.random(D) * decay_w
                a3 = _three_partners_of(rng, P, i)
                x_avg3 = X[a3].mean(axis=0)
                if esq_overwrites_mean:
                    x_mean = x_avg3
                beta = rng.random(D)
                x1 = beta * best_x + (1.0 - beta) * x_avg3
                n = rng.standard_normal(D)
                x2 = np.where(
                    w < 1.0,
                    x1 + r_esq * w * np.abs((x1 - x_avg3) + n),
                    (x1 - x_avg3) + r_esq * w * np.abs((u * x1 - x_avg3) + n),
                )
                x2 = tracker.clip(x2)
                f2 = evaluate_one(x2)
                if f2 < cost[i]:
                    X[i], cost[i] = x2, f2
                elif rng.random() < w[rng.integers(D)]:  # Eq. 20
                    if tracker.done:
                        complete = False
                        break
                    sm = _runge_kutta(rng, X[i], x2, delx)
                    x3 = (x2 - rng.random() * x2) + sf * (sm + (2.0 * rng.random(D) * best_x - x2))
                    x3 = tracker.clip(x3)
                    f3 = evaluate_one(x3)
                    if f3 < cost[i]:
                        X[i], cost[i] = x3, f3

            if cost[i] < best_f:
                best_x, best_f = X[i].copy(), float(cost[i])

        if not complete:
            break
        tracker.end_iteration()


def _three_partners_of(rng: np.random.Generator, P: int, i: int) -> np.ndarray:
    """Three distinct random agents other than ``i`` (``RndX`` for a single agent)."""
    picks = rng.choice(P - 1, size=3, replace=False)
    return picks + (picks >= i)
