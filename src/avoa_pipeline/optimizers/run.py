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
check of the budget (the seed's ``Runs.done``), so a ``max_nfe`` budget is met exactly.

Sequential updates (kept on purpose). The reference updates agent i in place before agent i+1
moves, and agent i+1 sees that: x_lbest and the random partners read the updated population, and
x* is refreshed after each agent. Vectorising over the population would change the algorithm, so
the agent loop is kept. Every random number an agent may need (those of untaken branches included)
is drawn per iteration in bulk, which changes the random stream but not the distribution.

Seeds as arrays (the batched state machine). The seeds of a fit block are one generator over
:class:`~.base.Runs` (``base.register``); vectorising over seeds changes nothing in
any seed's algorithm. Each step, every live seed asks for its next single candidate, all of them in
one ``runs.ask`` of shape (seeds, 1, D). The seeds fall out of phase (an agent costs 1, 2 or 3
evaluations), so each carries its own place in its iteration: its agent ``i`` and the phase of
that agent's next candidate (0: Eq. 18, 1: ESQ, 2: Eq. 20). The agent loop is a state machine
(:func:`_advance`, compiled) advanced for all seeds in one call per step: it applies each seed's
told value (greedy replacement, and at the agent's end the refresh of x*) and moves the seed on to
its next candidate or to the end of its iteration. The seeds at the end of their iteration close
it (``runs.end_iteration``) and, budget left, begin the next one: τ
(``runs.progress(count_initial=True)``) and the random numbers (each seed from its own
generator, in the order the one-seed code drew them, compiled and several iterations ahead:
:class:`_Draws`, :func:`_draw_ahead`), then a second call of
:func:`_advance` gives their first candidates. A seed whose budget is spent stops before asking,
as the one-seed loop checked ``tracker.done`` before every evaluation, so a last iteration cut by
an evaluation budget stays open (the history's partial last entry). One run is the same state
machine with one seed.

Why compiled: as plain numpy on 6-element vectors the moves cost about as much Python time as the
model costs to simulate (RUN was half of the full grid's optimizer time). The moves are the
reference's vector expressions written per coordinate (every one is elementwise: the same
operations in the same order give the same numbers) so that a step allocates nothing; the
evaluations, the budget and the history stay with :class:`~.base.Runs`.

Schedule. The reference counts ``it = 2..MaxIt`` with the initial population as ``it = 1`` and uses
``τ = it/MaxIt``. With an iteration budget T (our iteration t = 1..T after the initial population)
this is ``τ = (t+1)/(T+1)``, which reaches 1 in the last iteration exactly as the reference does.
With an evaluation budget, τ is the fraction of the budget that will have been spent by the end of
the iteration, estimated from the evaluations of the previous iteration
(``min(1, (nfe + nfe_prev_iteration)/max_nfe)``); with both budgets the larger fraction is used.
Both are :meth:`.base.Runs.progress` with ``count_initial=True``.

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
   Choice: our budget accounts (``base.Runs``: exact evaluation budget; the paper's
   "500 iterations" = 500 update iterations after the initial population - the reference itself
   would run MaxIt−1 = 499).
9. Bounds. (a), (c): clip to [lb, ub] after every move. Choice: the same.
10. Ties. (a) ``Cost(i) < Cost(k)`` and greedy ``CostNew < Cost(i)`` strict; (c) strict. Same.
"""

from __future__ import annotations

from collections.abc import Sequence

import numba as nb
import numpy as np

from .base import Runs, Steps, register

# The uniform draws of one seed and iteration live in one flat row, a field per use, in the order
# the seed's generator gives them; each group below is filled by one ``rng.random`` call (between
# two groups the generator gives integers or normals, see :meth:`_Draws.draw`). A field holds
# P × its width values: width 1 (a scalar per agent), D (a vector per agent), 4 (the factors of
# K1..K4 per agent) or P (a row of partner keys per agent).
(
    _SF,  # Eq. 17.5: SF's rand
    _RK1_C,  # main RK: c = randi([1, 2])·(1 − rand), its rand
    _RK1_R1,  # main RK: r1 (vector)
    _RK1_R2,  # main RK: r2 (vector)
    _RK1_Q,  # main RK: the four factors of K1..K4
    _RK2_C,  # Eq. 20 RK: c's rand
    _RK2_R1,
    _RK2_R2,
    _RK2_Q,
    _KEYS1,  # RndX keys of the partners a, b, c
    _GAMMA,  # Eq. 11: γ's scalar rand
    _STP,  # Stp: rand·x̄
    _G,  # Eq. 18: g = 2·rand
    _BRANCH,  # Eq. 18: which of its two forms
    _ESQ_GATE,  # ESQ taken iff < 0.5
    _V_GAMMA,  # γ: rand(D)·(ub − lb)
    _V_STP,  # Stp's factor (vector)
    _V_DELX,  # Δx's factor (vector)
    _V_L,  # L = rand(D) < 0.5
    _V_SIGN,  # r = ±1 per coordinate
    _ESQ_U,  # ESQ: u = 2·rand(D)
    _ESQ_W,  # ESQ: w's rand(D)
    _ESQ_BETA,  # ESQ: β
    _V_EQ20,  # Eq. 20: rand(D) of 2·rand(D)·x*
    _ESQ_DECAY,  # ESQ: the rand in w's decay
    _ESQ_R,  # ESQ: r ∈ {−1, 0, 1}
    _KEYS2,  # RndX keys of the three agents averaged by ESQ
    _EQ20_GATE,  # Eq. 20 taken iff < w[random coordinate]
    _X3_RAND,  # Eq. 20: x3's rand
) = range(29)
_UNIFORM_GROUPS = (
    ((_SF, "1"),),
    ((_RK1_C, "1"), (_RK1_R1, "D"), (_RK1_R2, "D"), (_RK1_Q, "4")),
    (
        (_RK2_C, "1"), (_RK2_R1, "D"), (_RK2_R2, "D"), (_RK2_Q, "4"), (_KEYS1, "P"),
        (_GAMMA, "1"), (_STP, "1"), (_G, "1"), (_BRANCH, "1"), (_ESQ_GATE, "1"),
        (_V_GAMMA, "D"), (_V_STP, "D"), (_V_DELX, "D"), (_V_L, "D"), (_V_SIGN, "D"),
    ),
    ((_ESQ_U, "D"), (_ESQ_W, "D"), (_ESQ_BETA, "D")),
    ((_V_EQ20, "D"), (_ESQ_DECAY, "1"), (_ESQ_R, "1"), (_KEYS2, "P"), (_EQ20_GATE, "1")),
    ((_X3_RAND, "1"),),
)  # fmt: skip

# integer draws (ints[s, k]) and normal draws (normals[s, k]) of one seed and iteration
_RK1_INT, _RK2_INT, _W_COORD = range(3)  # randi([1, 2]) of each RK's c; Eq. 20's coordinate
_MU, _ESQ_NORMAL = range(2)  # μ = 0.5 + 0.1·randn(D); ESQ's randn(D)

# Each seed's state between two steps. Its status: its run is over; a candidate of it waits for
# its value; its iteration is over; it begins an iteration. Its phase: which of its agent's moves
# the pending candidate is (Eq. 18, ESQ, Eq. 20).
_STOPPED, _CANDIDATE, _ENDED, _START = range(4)
_MAIN, _ESQ, _EQ20 = range(3)


# Iterations of random numbers a seed draws per call of :func:`_draw_ahead`. numpy's calls cost
# about 45 us a seed and iteration (three ``rng.integers`` at 10 us each, measured), the compiled
# draws a few us; handing a generator to numba costs about 18 us (its unboxing), paid once for
# this many iterations. The numbers drawn ahead are those the iterations would draw (the
# generator serves nothing else during the run); a run ending early leaves some unused.
DRAWN_AHEAD = 8


class _Draws:
    """The random numbers of every seed's running iteration: ``uniform`` (seeds × the fields
    above, flat), ``ints`` (seeds × 3 × P), ``normals`` (seeds × 2 × P × D), and the partners
    :func:`_advance` chooses from the keys, ``partners`` (seeds × 2 × P × 3: a, b, c; ESQ's
    three). Each seed's next :data:`DRAWN_AHEAD` iterations wait in a bank of the same fields."""

    def __init__(self, S: int, P: int, D: int):
        width = {"1": 1, "D": D, "4": 4, "P": P}
        self.offset = np.zeros(_X3_RAND + 1, dtype=np.int64)
        calls, pos = [], 0
        for group in _UNIFORM_GROUPS:
            start = pos
            for field, unit in group:
                self.offset[field] = pos
                pos += P * width[unit]
            calls.append((start, pos))
        self.calls = np.array(calls, dtype=np.int64)
        self.P = P
        self.uniform = np.empty((S, pos))
        self.ints = np.empty((S, 3, P), dtype=np.int64)
        self.normals = np.empty((S, 2, P, D))
        self.partners = np.empty((S, 2, P, 3), dtype=np.int64)
        K = DRAWN_AHEAD
        self._bank = (np.empty((S, K, pos)), np.empty((S, K, 3, P), dtype=np.int64),
                      np.empty((S, K, 2, P, D)))  # fmt: skip
        self._next = np.full(S, K)  # each seed's next iteration in its bank (K: none left)

    def draw(self, s: int, rng: np.random.Generator) -> None:
        """Seed ``s``'s numbers for one iteration from its generator ``rng`` (its bank, refilled
        by :func:`_draw_ahead` when empty)."""
        uniform, ints, normals = self._bank
        if self._next[s] == DRAWN_AHEAD:
            _draw_ahead(rng, self.calls, uniform[s], ints[s], normals[s])
            self._next[s] = 0
        k = self._next[s]
        self.uniform[s] = uniform[s, k]
        self.ints[s] = ints[s, k]
        self.normals[s] = normals[s, k]
        self._next[s] = k + 1


@nb.njit(cache=True)
def _draw_ahead(rng, calls, uniform, ints, normals):
    """One seed's numbers for the next ``K`` iterations from its generator ``rng``, iteration
    after iteration: ``uniform`` (K × fields), ``ints`` (K × 3 × P), ``normals`` (K × 2 × P ×
    D); ``calls``: the uniform fields' groups (start, end).

    The one-seed code drew, one call per use, in this order: SF's rand(P); the main RK's
    randi([1, 2]), then its rand(P), r1, r2 and K-factors; the same for Eq. 20's RK; the partner
    keys rand(P, P); the rands of γ, Stp, g, the Eq. 18 branch and the ESQ gate; the vectors of
    γ, Stp, Δx, L and the sign r; μ's randn; ESQ's u, w, β; ESQ's randn; Eq. 20's rand(D); ESQ's
    decay and r; ESQ's partner keys; Eq. 20's gate; the randi of w's coordinate; x3's rand. Here
    consecutive uniform draws are one call (a stream gives the same doubles whether drawn by one
    call or several); every integer and normal draw is the call it was. numba's generator
    methods are numpy's algorithms on the same bit generator, so the numbers are numpy's
    (``tests/unit/test_run.py`` holds them to numpy's calls)."""
    K, P, D = ints.shape[0], ints.shape[2], normals.shape[3]
    for k in range(K):
        u = uniform[k]
        for g in range(calls.shape[0]):
            a, b = calls[g, 0], calls[g, 1]
            u[a:b] = rng.random(b - a)
            if g == 0:
                ints[k, _RK1_INT] = rng.integers(1, 3, size=P)
            elif g == 1:
                ints[k, _RK2_INT] = rng.integers(1, 3, size=P)
            elif g == 2:
                normals[k, _MU] = rng.standard_normal(P * D).reshape(P, D)
            elif g == 3:
                normals[k, _ESQ_NORMAL] = rng.standard_normal(P * D).reshape(P, D)
            elif g == 4:
                ints[k, _W_COORD] = rng.integers(0, D, size=P)


# The moves below are the reference's vector expressions written per coordinate (every one of
# them is elementwise), so that no step allocates: each coordinate's value is computed by the same
# operations in the same order as the vector form, hence the same number.


@nb.njit(cache=True, inline="always")
def _runge_kutta(xb, xw, delx, c, r1, r2, q):
    """One coordinate of the RK4-like search mechanism SM of the reference (``RungeKutta``):
    K1..K4 with the steps h = 1/2, 1/2, 1 and the weights 1, 2, 2, 1."""
    k = 0.5 * (q[0] * xw - c * xb)
    total = k
    for j in range(3):
        h, weight = (0.5, 2.0) if j < 2 else (1.0, 1.0)
        step = h * k * delx
        k = 0.5 * (q[j + 1] * (xw + r2 * step) - (c * xb + r1 * step))
        total += weight * k
    return total / 6.0


@nb.njit(cache=True, inline="always")
def _clip(x, lo, hi):
    """``np.minimum(np.maximum(x, lo), hi)`` of one coordinate (a NaN stays NaN)."""
    if x < lo:
        x = lo
    if x > hi:
        x = hi
    return x


@nb.njit(cache=True)
def _main_move(
    s, i, X, cost, best_x, x_mean, wk, cand, tau, sf, u, o, ints, normals, partners, lb, ub
):
    """Agent ``i``'s move of Eq. 18 (seed ``s``), into ``wk[s, 3]`` and ``cand[s, 0]``;
    Δx into ``wk[s, 0]`` (Eq. 20 reuses it)."""
    D = X.shape[2]
    Xs, cs, xs = X[s], cost[s], best_x[s]
    a, b, c3 = partners[s, 0, i]
    k = a  # the best of a, b, c (the first if tied, as argmin)
    if cs[b] < cs[k]:
        k = b
    if cs[c3] < cs[k]:
        k = c3
    lbest = np.argmin(cs)  # x_lbest = X[lbest]
    i_better = cs[i] < cs[k]  # x_b = X_i, x_w = X_k; else swapped
    decay_gamma = np.exp(-4.0 * tau)
    c = ints[s, _RK1_INT, i] * (1.0 - u[o[_RK1_C] + i])
    q = u[o[_RK1_Q] + 4 * i : o[_RK1_Q] + 4 * i + 4]
    g = 2.0 * u[o[_G] + i]
    eq18_c = u[o[_BRANCH] + i] < 0.5  # the x_c form of Eq. 18, else the x_m form
    for j in range(D):
        iv = i * D + j  # agent i's coordinate j in a vector field
        gamma = u[o[_GAMMA] + i] * (Xs[i, j] - u[o[_V_GAMMA] + iv] * (ub[j] - lb[j])) * decay_gamma
        stp = u[o[_V_STP] + iv] * ((xs[j] - u[o[_STP] + i] * x_mean[s, j]) + gamma)
        delx = 2.0 * u[o[_V_DELX] + iv] * np.abs(stp)
        wk[s, 0, j] = delx
        if i_better:
            xb, xw = Xs[i, j], Xs[k, j]
        else:
            xb, xw = Xs[k, j], Xs[i, j]
        sm = _runge_kutta(xb, xw, delx, c, u[o[_RK1_R1] + iv], u[o[_RK1_R2] + iv], q)
        if u[o[_V_L] + iv] < 0.5:
            xc, xm = Xs[i, j], xs[j]
        else:
            xc, xm = Xs[a, j], Xs[lbest, j]
        r = 1.0 if u[o[_V_SIGN] + iv] < 0.5 else -1.0
        mu = 0.5 + 0.1 * normals[s, _MU, i, j]
        if eq18_c:
            x_new = xc + r * sf * g * xc + sf * sm + mu * (xm - xc)
        else:
            x_new = xm + r * sf * g * xm + sf * sm + mu * (Xs[a, j] - Xs[b, j])
        wk[s, 3, j] = cand[s, 0, j] = _clip(x_new, lb[j], ub[j])


@nb.njit(cache=True)
def _esq_move(
    s, i, X, best_x, x_mean, wk, cand, tau, u, o, normals, partners, lb, ub, overwrite_mean
):
    """Agent ``i``'s enhanced-solution-quality move (Eq. 19, seed ``s``), into ``wk[s, 2]`` and
    ``cand[s, 0]``; w into ``wk[s, 1]`` (Eq. 20's gate reads it)."""
    D = X.shape[2]
    Xs = X[s]
    decay_w = np.exp(-5.0 * u[o[_ESQ_DECAY] + i] * tau)
    r_esq = np.floor(-1.0 + 3.0 * u[o[_ESQ_R] + i])  # Unifrnd(-1, 2) floored: -1, 0, 1
    a0, a1, a2 = partners[s, 1, i]
    for j in range(D):
        iv = i * D + j
        uu = 2.0 * u[o[_ESQ_U] + iv]
        w = 2.0 * u[o[_ESQ_W] + iv] * decay_w
        wk[s, 1, j] = w
        x_avg3 = (Xs[a0, j] + Xs[a1, j] + Xs[a2, j]) / 3.0
        if overwrite_mean:
            x_mean[s, j] = x_avg3
        beta = u[o[_ESQ_BETA] + iv]
        x1 = beta * best_x[s, j] + (1.0 - beta) * x_avg3
        n = normals[s, _ESQ_NORMAL, i, j]
        if w < 1.0:
            x2 = x1 + r_esq * w * np.abs((x1 - x_avg3) + n)
        else:
            x2 = (x1 - x_avg3) + r_esq * w * np.abs((uu * x1 - x_avg3) + n)
        wk[s, 2, j] = cand[s, 0, j] = _clip(x2, lb[j], ub[j])


@nb.njit(cache=True)
def _eq20_move(s, i, X, best_x, wk, cand, sf, u, o, ints, lb, ub):
    """Agent ``i``'s Eq. 20 move from the rejected ESQ point ``wk[s, 2]`` (seed ``s``), into
    ``wk[s, 3]`` and ``cand[s, 0]``."""
    D = X.shape[2]
    c = ints[s, _RK2_INT, i] * (1.0 - u[o[_RK2_C] + i])
    q = u[o[_RK2_Q] + 4 * i : o[_RK2_Q] + 4 * i + 4]
    x3_rand = u[o[_X3_RAND] + i]
    for j in range(D):
        iv = i * D + j
        x2 = wk[s, 2, j]
        sm = _runge_kutta(X[s, i, j], x2, wk[s, 0, j], c, u[o[_RK2_R1] + iv], u[o[_RK2_R2] + iv], q)
        x3 = (x2 - x3_rand * x2) + sf * (sm + (2.0 * u[o[_V_EQ20] + iv] * best_x[s, j] - x2))
        wk[s, 3, j] = cand[s, 0, j] = _clip(x3, lb[j], ub[j])


@nb.njit(cache=True)
def rndx(keys, i, out):
    """``RndX`` of agent ``i``: the three agents other than ``i`` with the smallest ``keys``
    (uniform doubles), in increasing order of key, into ``out``.

    A selection inside the compiled step instead of the one-seed code's ``np.argsort`` of the
    keys with ``keys[i] = inf``: the same three in the same order whenever the keys differ;
    of two equal keys (two equal doubles of one stream) the lower index comes first, where
    argsort's order is unspecified."""
    out[:] = -1
    for j in range(keys.size):
        if j == i:
            continue
        key = keys[j]
        if out[0] < 0 or key < keys[out[0]]:
            out[2], out[1], out[0] = out[1], out[0], j
        elif out[1] < 0 or key < keys[out[1]]:
            out[2], out[1] = out[1], j
        elif out[2] < 0 or key < keys[out[2]]:
            out[2] = j


@nb.njit(cache=True)
def _advance(
    act, status, done, f, agent, phase, cand,
    X, cost, best_x, best_f, x_mean, wk, tau, sf_scale,
    uniform, o, ints, normals, partners, lb, ub, overwrite_mean,
):  # fmt: skip
    """One step of the agent loop of the seeds whose ``status`` is ``act`` (the module
    docstring's state machine); returns how many seeds then have a candidate and how many have
    ended their iteration.

    ``act`` = :data:`_START`: the seed begins its iteration (RndX's partners from the keys, x̄,
    agent 0's move). ``act`` = :data:`_CANDIDATE`: the seed takes the value ``f[s]`` of its
    pending candidate (greedy replacement), then moves on: to the same agent's next move (ESQ if
    its gate opens; Eq. 20 if ESQ was rejected and its gate opens), or to the agent's end (x*
    refreshed) and the next agent's move, or to the end of its iteration (:data:`_ENDED`). A seed
    with a new candidate (in ``cand[s, 0]``) whose budget is spent (``done``) stops
    (:data:`_STOPPED`) instead of asking. ``X``, ``cost``, ``best_x``, ``best_f``, ``x_mean`` and
    ``wk`` (what an agent reuses across its candidates: Δx, w, the ESQ point, the last candidate)
    are each seed's state, in place."""
    S, P = X.shape[0], X.shape[1]
    for s in range(S):
        if status[s] != act:
            continue
        u = uniform[s]
        if act == _START:
            for i in range(P):
                for t, field in enumerate((_KEYS1, _KEYS2)):
                    keys = u[o[field] + i * P : o[field] + (i + 1) * P]
                    rndx(keys, i, partners[s, t, i])
            for j in range(X.shape[2]):  # the population mean, summed in numpy's order (row by
                acc = X[s, 0, j]  # row); element by element: a vector `+=` allocated a temporary
                for p in range(1, P):
                    acc += X[s, p, j]
                x_mean[s, j] = acc / P
            i = 0
        else:
            i = agent[s]
            sf = 2.0 * (0.5 - u[o[_SF] + i]) * sf_scale[s]  # Eq. 17.5
            ph = phase[s]
            # the pending candidate is wk[s, 3] (Eq. 18 or 20) or wk[s, 2] (ESQ)
            accepted = f[s] < cost[s, i]
            if accepted:
                X[s, i] = wk[s, 2 if ph == _ESQ else 3]
                cost[s, i] = f[s]
            if ph == _MAIN and u[o[_ESQ_GATE] + i] < 0.5:  # enhanced solution quality
                _esq_move(s, i, X, best_x, x_mean, wk, cand, tau[s], u, o, normals, partners,
                          lb, ub, overwrite_mean)  # fmt: skip
                phase[s], status[s] = _ESQ, _STOPPED if done[s] else _CANDIDATE
                continue
            w_coord = ints[s, _W_COORD, i]
            if ph == _ESQ and not accepted and u[o[_EQ20_GATE] + i] < wk[s, 1, w_coord]:
                _eq20_move(s, i, X, best_x, wk, cand, sf, u, o, ints, lb, ub)
                phase[s], status[s] = _EQ20, _STOPPED if done[s] else _CANDIDATE
                continue
            if cost[s, i] < best_f[s]:  # the agent is done: refresh x*
                best_x[s] = X[s, i]
                best_f[s] = cost[s, i]
            i += 1
            if i == P:
                status[s] = _ENDED
                continue
        agent[s] = i
        sf = 2.0 * (0.5 - u[o[_SF] + i]) * sf_scale[s]
        _main_move(s, i, X, cost, best_x, x_mean, wk, cand, tau[s], sf, u, o, ints, normals,
                   partners, lb, ub)  # fmt: skip
        phase[s], status[s] = _MAIN, _STOPPED if done[s] else _CANDIDATE
    asking, ended = 0, 0
    for s in range(S):
        if status[s] == _CANDIDATE:
            asking += 1
        elif status[s] == _ENDED:
            ended += 1
    return asking, ended


@register("run")
def run(
    runs: Runs,
    rngs: Sequence[np.random.Generator],
    pop_size: int,
    *,
    esq_overwrites_mean: bool = True,
) -> Steps:
    """Minimise with RUN (see the module docstring), every seed of ``runs`` from its own
    generator in ``rngs``. ``pop_size`` must be at least 4."""
    S, P, D = runs.n, int(pop_size), runs.dim
    if P < 4:
        raise ValueError(f"RUN needs pop_size >= 4 (three partners besides the agent), got {P}")
    lb, ub = runs.lb, runs.ub

    X, cost = yield from runs.initial_population(rngs, P)  # X: (S, P, D)
    ib = np.argmin(cost, axis=1)
    best_x, best_f = X[np.arange(S), ib], cost[np.arange(S), ib]
    draws = _Draws(S, P, D)
    x_mean, wk = np.empty((S, D)), np.empty((S, 4, D))
    tau, sf_scale = np.zeros(S), np.zeros(S)
    agent, phase = np.zeros(S, dtype=np.int64), np.zeros(S, dtype=np.int64)
    status, f = np.full(S, _STOPPED), np.zeros(S)
    cand = np.empty((S, 1, D))

    def step(act: int, done: np.ndarray) -> tuple[int, int]:
        return _advance(act, status, done, f, agent, phase, cand, X, cost, best_x, best_f,
                        x_mean, wk, tau, sf_scale, draws.uniform, draws.offset, draws.ints,
                        draws.normals, draws.partners, lb, ub, esq_overwrites_mean)  # fmt: skip

    starting, asking = ~runs.done, 0
    while True:
        if starting is not None and np.count_nonzero(starting):  # these begin an iteration
            seeds = np.flatnonzero(starting)
            status[seeds] = _START
            tau[seeds] = runs.progress(count_initial=True, which=starting)  # it/MaxIt
            sf_scale[seeds] = 20.0 * np.exp(-12.0 * tau[seeds])  # Eq. 17.6
            for s in seeds:
                draws.draw(s, rngs[s])
            asking, _ = step(_START, runs.done)
        if not asking:
            return
        F = yield from runs.ask(cand, status == _CANDIDATE)  # copies the rows it yields
        f[:] = F[:, 0]
        asking, ended = step(_CANDIDATE, runs.done)
        starting = None
        if ended:  # these seeds close their iteration and, budget left, begin the next
            closing = status == _ENDED
            runs.end_iteration(closing)
            status[closing] = _STOPPED
            starting = closing & ~runs.done
