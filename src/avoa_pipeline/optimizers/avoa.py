"""African Vultures Optimization Algorithm (AVOA).

Reference: B. Abdollahzadeh, F. S. Gharehchopogh, S. Mirjalili, "African vultures optimization
algorithm: A new nature-inspired metaheuristic algorithm for global optimization problems",
Computers & Industrial Engineering 158 (2021) 107408, doi:10.1016/j.cie.2021.107408.
The algorithm here follows the authors' reference MATLAB code (``AVOA.m`` with ``exploration``,
``exploitation``, ``random_select``, ``levyFlight``, ``boundaryCheck``; MathWorks File Exchange
94820), not the equations as printed in Fahmy et al. 2023 (Mathematics 11, 2215, Section 3,
eqs. 14-31), which differ from that code in several places (listed below).

Pseudo-code (one iteration = one population evaluation; ``t`` = completed iterations, 0..T-1)::

    X <- uniform in [lb, ub]^D (P vultures); evaluate; update the best-two memories B1, B2
    while budget left:
        g  = U(-2, 2) * (sin(pi/2 t/T)^gamma + cos(pi/2 t/T) - 1)          # Fahmy eq. 18
        P1 = (2 rand + 1) (1 - t/T) + g                                     # once per iteration
        for each vulture i (vectorised):
            F = P1 * (2 rand_i - 1)                                         # hunger, eq. 17
            R = B1 with probability alpha, else B2                          # eq. 15
            if |F| >= 1:                                                    # exploration, eq. 19
                if rand < p1:  X = R - |2 rand R - X| F                     # eq. 19a/20
                else:          X = R - F + rand ((ub - lb) rand + lb)       # eq. 19b
            elif |F| >= 0.5:                                                # medium exploitation
                if rand < p3:  X = |2 rand R - X| (F + rand) - (R - X)      # eq. 21-22
                else:          X = R - (S1 + S2),                           # eq. 23-25
                               S1 = R (rand X / 2pi) cos X, S2 = R (rand X / 2pi) sin X
            else:                                                           # late exploitation
                if rand < p2:  X = (A1 + A2) / 2,                           # eq. 26-28
                               Ak = Bk - (Bk X) / (Bk - X^2) F
                else:          X = R - |R - X| F Levy(D)                    # eq. 29-31
        X <- clip(X, lb, ub); evaluate; update B1, B2 (sequentially, in index order)

    Levy(D) = u sigma / |v|^(1/beta), u, v ~ N(0, 1)^D, beta = 1.5, and
    sigma = (Gamma(1 + beta) sin(pi beta / 2)
             / (Gamma((1 + beta) / 2) beta 2^((beta - 1) / 2)))^(1/beta) = 0.6966

All "rand" inside a move are one scalar per vulture (as in the MATLAB code), Levy is per dimension.
There is no greedy selection: every vulture moves every iteration; B1/B2 keep the elite.

Differences between (a) the authors' code, (b) the original AVOA paper, (c) Fahmy et al.'s printed
equations and (d) mealpy 3.0.2 ``OriginalAVOA``; **choice** = what this module does.
(b) is the paper's printed form as widely reproduced; it was not re-checked against the PDF here.

1.  Guide selection R (Fahmy eqs. 15-16). (a) roulette over the constants [alpha, beta] = [0.8, 0.2]
    per vulture; (b), (c) p_i = f_i / sum f (roulette on the fitness of the two best -- for
    minimisation this favours the *worse* one and is undefined for mixed-sign f); (d) as (a).
    **choice: (a).** ``beta`` is the complement of ``alpha`` (the code picks B1 iff rand <= alpha).
2.  B1/B2. (a) running memories: B1 = best-so-far; B2 is replaced only by a value strictly between
    B1 and B2 (an old B1 is never demoted to B2), starting at the origin with f = inf; (b), (c)
    best and second best of the current population; (d) two best of the current population.
    **choice: (a)**, except that while B2 was never set, B1 is used instead of the origin (the
    origin is arbitrary, may be infeasible, and is the optimum of the sphere test function).
3.  Hunger F (eqs. 17-18). (a) F_i = [(2 rand + 1)(1 - t/T) + g] (2 rand_i - 1): rand and h (in g)
    once per iteration, the sign factor z = 2 rand_i - 1 per vulture, so z also multiplies g;
    (b), (c) F = (2 rand + 1) z (1 - t/T) + g (z multiplies only the first term; Fahmy indexes
    rand per vulture and z per iteration); (d) as (a) but t = 1..T where (a) uses t = 0..T-1.
    **choice: (a)** with t = 0..T-1. Fahmy's k is the code's gamma (= 2.5).
4.  Exploration branch (eq. 19). (a), (b), (d) first branch iff rand < p1 (eq. 19's own condition
    p1 >= rand agrees); Fahmy's text says the reverse ("if rand >= p1 the first part"). In the
    second branch rand2 and rand3 are scalars (the same fraction in every dimension) in (a), (d).
    **choice: (a).**
5.  Medium exploitation, 0.5 <= |F| < 1 (eqs. 21-25). (a), (d) use **p3**: competition (eq. 21)
    iff rand < p3, else rotation (eq. 23); (b) uses p2 (competition iff p2 >= rand); (c) text uses
    p2 with competition iff rand >= p2. With p2 = 0.4, p3 = 0.6 the competition probability is
    0.6 in (a), (c), (d) and 0.4 in (b). **choice: (a).**
6.  Late exploitation, |F| < 0.5 (eqs. 26-30). (a), (d) use **p2**: aggregation (eq. 26) iff
    rand < p2, else Levy attack (eq. 29); (b) uses p3 (aggregation iff p3 >= rand); (c) text:
    aggregation iff rand >= p3. Aggregation probability 0.4 in (a), (c), (d), 0.6 in (b).
    **choice: (a).**
7.  Aggregation A1, A2 (eqs. 27-28). (a) Bk - (Bk X) / (Bk - X^2) F, elementwise -- the same as
    Fahmy's printed eq. 27 (eq. 28 misprints BestVulture_21 for BestVulture_2); (d) adds 1e-9 to
    the denominator. **choice: (a)**; a 0/0 coordinate (NaN) keeps the vulture's current value
    (the MATLAB code would carry the NaN on), +-inf is clipped to the bound.
8.  Levy flight (eqs. 30-31). (a) u sigma / |v|^(1/beta) with u, v ~ N(0, 1), no 0.01 factor,
    Gamma((1 + beta)/2) in sigma's denominator (sigma = 0.6966 for beta = 1.5); (b) prints a 0.01
    factor; (c) eq. 30: 0.01 r1 sigma / |r2|^(1/sigma) with r1, r2 ~ U(0, 1) and exponent 1/sigma,
    eq. 31: Gamma(1 + delta) in the denominator (sigma = 0.5396); (d) no 0.01 factor and the
    reference sigma, but draws u ~ N(0, sigma^2) with numpy's *scale* = sigma^2, i.e. std 0.485
    instead of 0.697. **choice: (a).**
9.  Bounds: (a) clips the whole population after each iteration (boundaryCheck); (d) clips each new
    position; (b), (c) silent. **choice: clip**, same effect as (a), (d).
10. Evaluation count: (a) evaluates at the start of each of its max_iter iterations, so its last
    move is never evaluated (max_iter * P evaluations); ours and (d) evaluate the initial
    population (iteration 0 of the history) and then once per iteration ((T + 1) * P
    evaluations for T iterations, the convention of :mod:`.base`).
11. Parameters: (a), (d) p1 = 0.6, p2 = 0.4, p3 = 0.6, alpha (L1) = 0.8, beta (L2) = 0.2,
    gamma (w, Fahmy's k) = 2.5; Fahmy gives no values (only P = 20, T = 500). **choice: (a).**
12. Horizon T for t/T: :meth:`.base.Runs.planned_iterations` with P evaluations per
    iteration: the budget's ``iterations``; under a pure evaluation budget the number of
    iterations that fit, ceil((max_nfe - P) / P) (the smaller of the two if both are set).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .base import Runs, Steps, register

LEVY_BETA = 1.5
"""Levy-flight exponent (fixed at 3/2 in the reference code; Fahmy's delta)."""


def levy_sigma(beta: float = LEVY_BETA) -> float:
    """Mantegna's sigma of the reference code (Gamma((1+beta)/2) in the denominator)."""
    num = math.gamma(1.0 + beta) * math.sin(math.pi * beta / 2.0)
    den = math.gamma((1.0 + beta) / 2.0) * beta * 2.0 ** ((beta - 1.0) / 2.0)
    return (num / den) ** (1.0 / beta)


class BestTwo:
    """The reference's best-two memories B1, B2 of every run (arrays over runs): ``f1``, ``x1``,
    ``f2``, ``x2``; a run's ``x`` is NaN until set."""

    def __init__(self, n: int, dim: int):
        self.f1 = np.full(n, np.inf)
        self.f2 = np.full(n, np.inf)
        self.x1 = np.full((n, dim), np.nan)
        self.x2 = np.full((n, dim), np.nan)

    @property
    def set1(self) -> np.ndarray:
        """Per run: B1 holds a vulture (only a value below +inf ever enters)."""
        return self.f1 < np.inf

    @property
    def set2(self) -> np.ndarray:
        """Per run: B2 holds a vulture."""
        return self.f2 < np.inf

    def guides(self, X: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Each run's B1 and B2 as the moves read them: an unset B2 is B1 (item 2 of the module
        docstring), an unset B1 the run's first vulture (only if every value was NaN or inf)."""
        b1 = np.where(self.set1[:, None], self.x1, X[:, 0])
        b2 = np.where(self.set2[:, None], self.x2, b1)
        return b1, b2

    def update(self, f: np.ndarray, X: np.ndarray) -> None:
        """The reference update, vulture by vulture in index order, for every run at once:
        B1 takes any strictly better value; B2 takes a value strictly between B1 (as updated so
        far) and B2. An old B1 is not demoted.

        Without the loop over vultures: B1 ends at the first smallest value if it beats B1.
        Vulture k can enter B2 only if its value exceeds B1 as it stands after k (the running
        minimum), and then does iff it is below B2 as it stands; so B2 ends at the first
        smallest of those eligible values if it beats B2. Ties keep the earlier vulture, as the
        strict comparisons do."""
        n = f.shape[0]
        rows = np.arange(n)
        running = np.minimum.accumulate(np.concatenate([self.f1[:, None], f], axis=1), axis=1)
        eligible = np.where(running[:, 1:] < f, f, np.inf)
        k2 = np.argmin(eligible, axis=1)
        v2 = eligible[rows, k2]
        m = v2 < self.f2
        if m.any():
            self.f2[m], self.x2[m] = v2[m], X[m, k2[m]]
        k1 = np.argmin(f, axis=1)
        v1 = f[rows, k1]
        m = v1 < self.f1
        if m.any():
            self.f1[m], self.x1[m] = v1[m], X[m, k1[m]]


def check_settings(p1, p2, p3, alpha, beta, gamma) -> None:
    """The reference's probabilities are probabilities, L1 + L2 = 1 and gamma > 0."""
    for name, value in (("p1", p1), ("p2", p2), ("p3", p3), ("alpha", alpha), ("beta", beta)):
        if not 0.0 <= value <= 1.0:
            raise ValueError(f"{name} must be in [0, 1], got {value}")
    if not math.isclose(alpha + beta, 1.0):
        raise ValueError(f"alpha + beta must be 1 (L1 + L2 = 1), got {alpha} + {beta}")
    if gamma <= 0:
        raise ValueError(f"gamma must be positive, got {gamma}")


def hunger_scale(frac: float, h: np.ndarray, r: np.ndarray, gamma: float) -> np.ndarray:
    """Each run's P1 = (2 r + 1)(1 - t/T) + g with g = h (sin(pi/2 t/T)^gamma + cos(pi/2 t/T)
    - 1), ``frac`` = t/T and ``h`` ~ U(-2, 2) (Fahmy eq. 18; drawn once per iteration): a
    vulture's hunger F is P1 times its sign factor."""
    g = h * (math.sin(math.pi / 2.0 * frac) ** gamma + math.cos(math.pi / 2.0 * frac) - 1.0)
    return (2.0 * r + 1.0) * (1.0 - frac) + g


@dataclass(slots=True)  # read some forty times a move
class Vultures:
    """Every run's vultures of one iteration as rows (run by run): the position ``x``, hunger
    ``F``, guide ``R`` and best two ``B1``, ``B2`` (rows of (n, D) or (n, 1)), the branch draw
    ``u``, the move's two uniforms ``r1``, ``r2`` and the Lévy step ``levy``."""

    x: np.ndarray
    F: np.ndarray
    R: np.ndarray
    B1: np.ndarray
    B2: np.ndarray
    u: np.ndarray
    r1: np.ndarray
    r2: np.ndarray
    levy: np.ndarray

    @classmethod
    def drawn(cls, X, P1, per, normals, b1, b2, alpha: float, sigma: float) -> Vultures:
        """The rows from each run's positions ``X`` (runs, P, D), its ``P1``, its per-vulture
        uniforms ``per`` (5, n: hunger sign, guide choice, branch, r1, r2) and its normals
        (runs, 2, P, D), guided by B1 with probability ``alpha`` (eq. 15), else by B2."""
        S, P, D = X.shape
        n = S * P
        F = (np.repeat(P1, P) * (2.0 * per[0] - 1.0))[:, None]  # (n, 1), eq. 17
        B1, B2 = np.repeat(b1, P, axis=0), np.repeat(b2, P, axis=0)
        R = np.where((per[1] <= alpha)[:, None], B1, B2)
        levy = (normals[:, 0] * sigma / np.abs(normals[:, 1]) ** (1.0 / LEVY_BETA)).reshape(n, D)
        return cls(X.reshape(n, D), F, R, B1, B2, per[2], per[3][:, None], per[4][:, None], levy)


def explore(new: np.ndarray, v: Vultures, m: np.ndarray, first: np.ndarray, lb, ub) -> None:
    """|F| >= 1 (eq. 19), the rows ``m`` of ``new``: ``first`` (rand < p1) moves to the guide
    at a distance |C R - X|, C = 2 rand (eqs. 19a, 20), the others to a random point of the box
    shifted by the guide (eq. 19b)."""
    k = m & first
    Rm, Xm, Fm = v.R[k], v.x[k], v.F[k]
    new[k] = Rm - np.abs(2.0 * v.r1[k] * Rm - Xm) * Fm
    k = m & ~first
    new[k] = v.R[k] - v.F[k] + v.r1[k] * ((ub - lb) * v.r2[k] + lb)


def exploit_medium(new: np.ndarray, v: Vultures, m: np.ndarray, compete: np.ndarray) -> None:
    """0.5 <= |F| < 1, the rows ``m``: food competition where ``compete`` (rand < p3; eqs.
    21-22), else the rotating flight (eqs. 23-25)."""
    k = m & compete
    Rm, Xm = v.R[k], v.x[k]
    new[k] = np.abs(2.0 * v.r1[k] * Rm - Xm) * (v.F[k] + v.r2[k]) - (Rm - Xm)
    k = m & ~compete
    Rm, Xm = v.R[k], v.x[k]
    s1 = Rm * (v.r1[k] * Xm / (2.0 * np.pi)) * np.cos(Xm)
    s2 = Rm * (v.r2[k] * Xm / (2.0 * np.pi)) * np.sin(Xm)
    new[k] = Rm - (s1 + s2)


def exploit_late(new: np.ndarray, v: Vultures, m: np.ndarray, gather: np.ndarray) -> None:
    """|F| < 0.5, the rows ``m``: aggregation at the best two where ``gather`` (rand < p2;
    eqs. 26-28), else the attack with a Lévy flight (eq. 29)."""
    k = m & gather
    B1m, B2m, Xm, Fm = v.B1[k], v.B2[k], v.x[k], v.F[k]
    a1 = B1m - (B1m * Xm) / (B1m - Xm**2) * Fm
    a2 = B2m - (B2m * Xm) / (B2m - Xm**2) * Fm
    new[k] = (a1 + a2) / 2.0
    k = m & ~gather
    Rm = v.R[k]
    new[k] = Rm - np.abs(Rm - v.x[k]) * v.F[k] * v.levy[k]


def move(v: Vultures, p1: float, p2: float, p3: float, lb, ub) -> np.ndarray:
    """Every vulture's new position (unclipped; NaN where a move divided 0 by 0): the stage
    its |F| puts it in, the branch its draw ``u`` picks there."""
    absF = np.abs(v.F[:, 0])
    far = absF >= 1.0  # exploration
    late = absF < 0.5
    medium = ~far & ~late
    new = np.empty_like(v.x)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        explore(new, v, far, v.u < p1, lb, ub)
        exploit_medium(new, v, medium, v.u < p3)
        exploit_late(new, v, late, v.u < p2)
    return new


@register("avoa")
def avoa(
    runs: Runs,
    rngs: list[np.random.Generator],
    pop_size: int,
    p1: float = 0.6,
    p2: float = 0.4,
    p3: float = 0.6,
    alpha: float = 0.8,
    beta: float = 0.2,
    gamma: float = 2.5,
) -> Steps:
    """AVOA as in the authors' MATLAB code (see the module docstring for every deviation), every
    run of ``runs`` moved as one array operation, each from its own generator in ``rngs``.

    Each run draws, per iteration and in this order, what the one-run code drew with one call
    each: the U(-2, 2) of g, the rand of P1, then per vulture the hunger sign, the guide choice,
    the branch draw, r1, r2 (together ``rng.random(2 + 5 P)``: consecutive doubles of one stream
    are the same whether drawn one call at a time or in one call, and ``uniform(-2, 2)`` is
    ``-2 + 4 d`` of the same double), then the Lévy flight's two normal arrays (one
    ``standard_normal`` call)."""
    check_settings(p1, p2, p3, alpha, beta, gamma)
    S, P, D = runs.n, pop_size, runs.dim
    sigma = levy_sigma()

    X, f = yield from runs.initial_population(rngs, P)  # X: (S, P, D)
    best = BestTwo(S, D)
    best.update(f, X)
    T = runs.planned_iterations(P)
    draws = np.empty((S, 2 + 5 * P))
    normals = np.empty((S, 2, P, D))

    while not runs.done.all():  # the runs move in step: one budget, the same evaluations each
        frac = int(runs.iteration[0]) / T  # the reference's current_iter (0..T-1) over T
        b1, b2 = best.guides(X)
        for s, rng in enumerate(rngs):
            rng.random(out=draws[s])
            rng.standard_normal(out=normals[s])  # in place: the same doubles, no copy
        P1 = hunger_scale(frac, -2.0 + 4.0 * draws[:, 0], draws[:, 1], gamma)
        # per-vulture draws (one scalar each, as the MATLAB rand() calls), Levy per dimension;
        # every seed's vultures as rows, seed by seed: the one-seed code's statements on n rows
        per = draws[:, 2:].reshape(S, 5, P).transpose(1, 0, 2).reshape(5, S * P)
        v = Vultures.drawn(X, P1, per, normals, b1, b2, alpha, sigma)
        new = move(v, p1, p2, p3, runs.lb, runs.ub)
        X = runs.clip(np.where(np.isnan(new), v.x, new)).reshape(S, P, D)

        best.update((yield from runs.ask(X)), X)
        runs.end_iteration()
