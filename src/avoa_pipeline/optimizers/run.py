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
the agent loop is kept. Every random number an agent may need (those of untaken branches included)
is drawn per iteration in bulk, which changes the random stream but not the distribution.

Why compiled: the loop is a numba generator (:func:`_agents`) that yields each candidate and is
resumed with its objective value. As plain numpy on 6-element vectors, the moves cost about as much
Python time as the model costs to simulate (RUN was half of the full grid's optimizer time); the
generator keeps the algorithm's control flow in one place while the evaluations, the budget and
the history stay with the Python :class:`~.base.Tracker`. Each candidate becomes an ask of one
point (``tracker.ask_one``), so the seeds of a fit block stepped together are evaluated as one
population of one candidate per seed (:func:`.base.step_together`).

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

import numba as nb
import numpy as np

from .base import Steps, Tracker, register


def _three_partners(rng: np.random.Generator, P: int) -> np.ndarray:
    """For every agent i, three distinct random agents other than i (``RndX``), shape (P, 3)."""
    keys = rng.random((P, P))
    np.fill_diagonal(keys, np.inf)
    return np.argsort(keys, axis=1)[:, :3]


def _rk_draws(rng: np.random.Generator, P: int, D: int) -> tuple:
    """Random numbers of one ``RungeKutta`` call per agent: c = randi([1, 2])·(1 − rand), the
    two coordinate vectors r1, r2 and the four scalar factors of K1..K4."""
    c = rng.integers(1, 3, size=P) * (1.0 - rng.random(P))
    return c, rng.random((P, D)), rng.random((P, D)), rng.random((P, 4))


@nb.njit(cache=True)
def _runge_kutta(xb, xw, delx, c, r1, r2, q):
    """The RK4-like search mechanism SM of the reference (``RungeKutta``)."""
    k = 0.5 * (q[0] * xw - c * xb)
    total = k.copy()
    for j in range(3):
        h, weight = (0.5, 2.0) if j < 2 else (1.0, 1.0)
        step = h * k * delx
        k = 0.5 * (q[j + 1] * (xw + r2 * step) - (c * xb + r1 * step))
        total += weight * k
    return total / 6.0


@nb.njit(cache=True)
def _clip(x, lb, ub):
    return np.minimum(np.maximum(x, lb), ub)


@nb.njit(cache=True)
def _agents(
    X, cost, best_x, best_f, x_mean, fbox, wk, lb, ub, tau, overwrite_mean, sf_all, m, v, esq
):
    """The agent loop of one iteration, as a generator: it yields each candidate to evaluate and
    reads its objective value from ``fbox[0]`` when resumed; ``X``, ``cost``, ``best_x``,
    ``best_f`` and ``x_mean`` are updated in place, so stopping early (budget spent) leaves the
    state of the agents moved so far, as the Python loop it replaces did.

    ``m`` holds the main move's random numbers per agent (see :func:`run`), ``v`` the vector ones
    (shape (P, k, D)), ``esq`` the ESQ / Eq. 20 scalars.
    """
    P = X.shape[0]
    span = ub - lb
    decay_gamma = np.exp(-4.0 * tau)
    for i in range(P):
        a, b = int(m[i, 0]), int(m[i, 1])
        p3 = m[i, 0:3].astype(np.int64)
        k = p3[np.argmin(cost[p3])]
        x_lbest = X[np.argmin(cost)].copy()
        gamma = m[i, 3] * (X[i] - v[i, 0] * span) * decay_gamma
        stp = v[i, 1] * ((best_x - m[i, 4] * x_mean) + gamma)
        wk[0] = 2.0 * v[i, 2] * np.abs(stp)  # Δx, reused by Eq. 20
        delx = wk[0]
        if cost[i] < cost[k]:
            xb, xw = X[i].copy(), X[k].copy()
        else:
            xb, xw = X[k].copy(), X[i].copy()
        sm = _runge_kutta(xb, xw, delx, m[i, 5], v[i, 3], v[i, 4], m[i, 6:10])
        L = v[i, 5] < 0.5
        xc = np.where(L, X[i], X[a])
        xm = np.where(L, best_x, x_lbest)
        r = np.where(v[i, 6] < 0.5, 1.0, -1.0)
        g, mu, sf = m[i, 10], v[i, 7], sf_all[i]
        if m[i, 11] < 0.5:
            x_new = xc + r * sf * g * xc + sf * sm + mu * (xm - xc)
        else:
            x_new = xm + r * sf * g * xm + sf * sm + mu * (X[a] - X[b])
        wk[3] = _clip(x_new, lb, ub)
        yield wk[3].copy()
        if fbox[0] < cost[i]:
            X[i] = wk[3]
            cost[i] = fbox[0]

        if m[i, 12] < 0.5:  # enhanced solution quality (Eq. 19)
            decay_w = np.exp(-5.0 * esq[i, 0] * tau)
            r_esq = np.floor(-1.0 + 3.0 * esq[i, 1])  # Unifrnd(-1, 2) floored: -1, 0, 1
            u = 2.0 * v[i, 8]
            wk[1] = 2.0 * v[i, 9] * decay_w
            w = wk[1]
            a3 = esq[i, 2:5].astype(np.int64)
            x_avg3 = (X[a3[0]] + X[a3[1]] + X[a3[2]]) / 3.0
            if overwrite_mean:
                x_mean[:] = x_avg3
            beta = v[i, 10]
            x1 = beta * best_x + (1.0 - beta) * x_avg3
            n = v[i, 11]
            x2 = np.where(
                w < 1.0,
                x1 + r_esq * w * np.abs((x1 - x_avg3) + n),
                (x1 - x_avg3) + r_esq * w * np.abs((u * x1 - x_avg3) + n),
            )
            wk[2] = _clip(x2, lb, ub)
            yield wk[2].copy()
            # (locals holding arrays must not live across a yield: numba 0.68 generators corrupt
            # the heap then, so the vectors reused after a yield live in ``wk``)
            if fbox[0] < cost[i]:
                X[i] = wk[2]
                cost[i] = fbox[0]
            elif esq[i, 5] < wk[1, int(esq[i, 6])]:  # Eq. 20
                x2 = wk[2]
                sm = _runge_kutta(
                    X[i].copy(), x2, wk[0], esq[i, 7], v[i, 12], v[i, 13], esq[i, 8:12]
                )
                x3 = (x2 - esq[i, 12] * x2) + sf_all[i] * (sm + (2.0 * v[i, 14] * best_x - x2))
                wk[3] = _clip(x3, lb, ub)
                yield wk[3].copy()
                if fbox[0] < cost[i]:
                    X[i] = wk[3]
                    cost[i] = fbox[0]

        if cost[i] < best_f[0]:
            best_x[:] = X[i]
            best_f[0] = cost[i]


@register("run")
def run(
    tracker: Tracker,
    rng: np.random.Generator,
    pop_size: int,
    *,
    esq_overwrites_mean: bool = True,
) -> Steps:
    """Minimise with RUN (see the module docstring). ``pop_size`` must be at least 4."""
    P, D = int(pop_size), tracker.dim
    if P < 4:
        raise ValueError(f"RUN needs pop_size >= 4 (three partners besides the agent), got {P}")
    lb, ub = tracker.lb, tracker.ub

    X = tracker.random_uniform(rng, P)
    cost = yield from tracker.ask(X)
    tracker.end_iteration()
    ib = int(np.argmin(cost))
    best_x, best_f = X[ib].copy(), np.array([cost[ib]])
    fbox = np.zeros(1)
    wk = np.zeros((4, D))

    while not tracker.done:
        tau = tracker.progress(count_initial=True)  # the reference's it/MaxIt
        x_mean = X.mean(axis=0)
        SF = 2.0 * (0.5 - rng.random(P)) * (20.0 * np.exp(-12.0 * tau))  # Eqs. 17.5-17.6
        # Every random number an agent may need, drawn for all agents in bulk (those of branches
        # not taken go unused): same distributions as the reference's draws on demand.
        rk1, rk2 = _rk_draws(rng, P, D), _rk_draws(rng, P, D)
        m = np.column_stack(
            [
                _three_partners(rng, P),  # 0-2: a, b, c
                rng.random(P),  # 3: γ factor
                rng.random(P),  # 4: Stp: rand·x̄
                rk1[0],  # 5: RK c
                rk1[3],  # 6-9: RK K1..K4 factors
                2.0 * rng.random(P),  # 10: g
                rng.random(P),  # 11: branch of Eq. 18
                rng.random(P),  # 12: ESQ gate
            ]
        )
        v = np.stack(
            [
                rng.random((P, D)),  # 0: γ: rand(D)·(ub − lb)
                rng.random((P, D)),  # 1: Stp factor
                rng.random((P, D)),  # 2: Δx factor
                rk1[1],  # 3: RK r1
                rk1[2],  # 4: RK r2
                rng.random((P, D)),  # 5: L
                rng.random((P, D)),  # 6: sign r
                0.5 + 0.1 * rng.standard_normal((P, D)),  # 7: μ
                rng.random((P, D)),  # 8: ESQ u
                rng.random((P, D)),  # 9: ESQ w
                rng.random((P, D)),  # 10: ESQ β
                rng.standard_normal((P, D)),  # 11: ESQ normals
                rk2[1],  # 12: Eq. 20 RK r1
                rk2[2],  # 13: Eq. 20 RK r2
                rng.random((P, D)),  # 14: Eq. 20 rand(D)
            ],
            axis=1,
        )
        esq = np.column_stack(
            [
                rng.random(P),  # 0: decay of w
                rng.random(P),  # 1: r ∈ {−1, 0, 1}
                _three_partners(rng, P),  # 2-4: the three agents averaged
                rng.random(P),  # 5: Eq. 20 gate
                rng.integers(D, size=P),  # 6: coordinate of w compared with it
                rk2[0],  # 7: RK c
                rk2[3],  # 8-11: RK K1..K4 factors
                rng.random(P),  # 12: x3's rand
            ]
        )
        complete = True
        for x in _agents(
            X,
            cost,
            best_x,
            best_f,
            x_mean,
            fbox,
            wk,
            lb,
            ub,
            tau,
            esq_overwrites_mean,
            SF,
            m,
            v,
            esq,
        ):
            if tracker.done:
                complete = False
                break
            fbox[0] = yield from tracker.ask_one(x)
        if not complete:
            break
        tracker.end_iteration()
