"""Nelder–Mead simplex search with random restarts (bounded; scipy's algorithm, every seed at once).

Nelder, J. A., Mead, R. (1965). A simplex method for function minimization. The Computer Journal
7(4), 308-313. doi:10.1093/comjnl/7.4.308 (the paper's reference [52] only *uses* the method).
Gao, F., Han, L. (2012). Implementing the Nelder-Mead simplex algorithm with adaptive parameters.
Computational Optimization and Applications 51(1), 259-277 (the ``adaptive`` option).

The paper gives no settings for its Nelder–Mead runs; MATLAB's ``fminsearch`` is the likely tool.
We follow ``scipy.optimize.minimize(method="Nelder-Mead", bounds=...)`` (scipy 1.17.1,
``scipy.optimize._optimize._minimize_neldermead``), whose defaults match ``fminsearch``'s (initial
simplex: each coordinate of ``x0`` perturbed by 5 %, or set to ``0.00025`` if it is 0;
``xatol = fatol = 1e-4``; at most ``200 D`` iterations and ``200 D`` evaluations), plus box
handling (simplex points are clipped to the bounds).

Why not call scipy. scipy's loop owns the iteration and calls the objective itself, one point at
a time, so it can step one seed only: a fit block then ran one scipy loop per seed in a greenlet
and stacked the seeds' one-point asks into one kernel call, and scipy's per-iteration Python, the
greenlet switches and the per-seed accounting cost several times the kernel's time. This module
re-implements scipy's algorithm over arrays of seeds (simplexes shaped seeds × (D + 1) × D, one
generator for all seeds): at each step every live seed asks exactly the next point scipy would
evaluate. The arithmetic is scipy's, expression for expression (the same coefficients applied in
the same order, the centroid added vertex after vertex as ``np.add.reduce`` adds, ``np.clip``'s
comparisons), so a seed's points and values are scipy's bit for bit:
``tests/unit/test_nelder_mead.py`` holds it to ``scipy.optimize.minimize`` itself, driven one
seed at a time, on bounded test functions, with budgets that end inside a restart's initial
simplex and inside a shrink, with the ``adaptive`` option and with starts on a bound.

Why compiled. Written as numpy operations over the seeds (every branch computed for every seed,
kept where a mask says), a step cost about 100 small array operations: 30 seeds on a cheap
objective spent 218 us a step outside it, 97 us with the compiled step (loaded machine), where
the kernel takes about 170 us for their 30 points (Nelder–Mead ran at 3.0× its kernel bound).
The step is one numba call (:func:`_step`) that takes each live seed through scipy's branch
in scalars. scipy orders a simplex by ``np.argsort``, which is not stable and whose order of
tied values is numpy's own (AVX-512 sorts on some machines): the compiled step sorts a simplex
whose values are all distinct (any sort gives that one order) and leaves one with tied values
(vertices clipped onto one face, failed simulations at +inf) to ``np.argsort`` itself.

One local search (scipy's, with ``N = D``; ``rho, chi, psi, sigma = 1, 2, 1/2, 1/2``, or with
``adaptive`` ``1, 1 + 2/N, 3/4 - 1/(2N), 1 - 1/N``)::

    x0 <- clip(x0, lb, ub)
    simplex: x0, and for k = 1..N x0 with its k-th coordinate times 1.05 (0.00025 if it is 0);
             a coordinate above ub is reflected to 2 ub - x, then every vertex clipped to the box
    evaluate the N + 1 vertices in order; sort them by value (np.argsort, twice, as scipy)
    while evaluations < maxfev and iterations < maxiter:
        stop if max |x_i - x_0| <= xatol and max |f_0 - f_i| <= fatol
        xbar <- sum of the N best vertices / N
        xr <- clip((1 + rho) xbar - rho x_N)                            # reflection
        if f(xr) < f_0:
            xe <- clip((1 + rho chi) xbar - rho chi x_N)                 # expansion
            x_N <- xe if f(xe) < f(xr) else xr
        elif f(xr) < f_{N-1}:  x_N <- xr
        elif f(xr) < f_N:
            xc <- clip((1 + psi rho) xbar - psi rho x_N)                 # outside contraction
            x_N <- xc if f(xc) <= f(xr), else shrink
        else:
            xcc <- clip((1 - psi) xbar + psi x_N)                        # inside contraction
            x_N <- xcc if f(xcc) < f_N, else shrink
        shrink: x_j <- clip(x_0 + sigma (x_j - x_0)), evaluated for j = 1..N in order
        iterations += 1; sort the vertices by value
    a call that would exceed maxfev ends the search instead

Around it, per seed::

    while budget left:
        x0 <- uniform in [lb, ub]
        the local search above from x0, until it stops (or hits its own maxfev / maxiter)
        # every evaluation counts toward the budget; the search ends where the budget does

Budget / iteration mapping. A local search has no population, so "an iteration" is defined as
``pop_size`` objective evaluations: the first ``pop_size`` evaluations close iteration 0 and every
further ``pop_size`` evaluations close one more iteration (``Runs.close_spent``, as for
quasi-Newton). Hence ``Budget(iterations=T, pop_size=P)`` spends exactly ``(T + 1) P`` evaluations
-- the same as a population method with ``P`` agents that evaluates its initial population and
then ``T`` populations (the paper: 20 x 500 = 10,000 moves + 20 initial points) -- and
``Budget(max_nfe=N)`` spends exactly ``N``. The best value across all restarts is the result.

Settings (scipy's ``options`` of the same names and defaults): ``xatol``, ``fatol``, ``maxiter``,
``maxfev``, ``adaptive``; scipy's ``initial_simplex`` is not supported (the simplex is built from
the random start).

Differences vs scipy's ``minimize``: none in the points evaluated and their order. scipy warns
when ``x0`` lies outside the bounds; the uniform starts never do (they are clipped all the same).
A value that is NaN (a simulation that blew up) is ``+inf`` here, as every optimizer's tracker
makes it. ``maxfev < 1`` is refused (scipy would stop at once, and the restarts never end).
Differences vs a plain single-start ``fminsearch``: restarts from fresh random points
until the budget is spent (so a converged local search does not waste the budget the population
methods get), and bounds (``fminsearch`` is unconstrained). mealpy has no Nelder–Mead.
"""

from __future__ import annotations

import numba as nb
import numpy as np

from .base import Runs, Steps, register, uniform_in_box

__all__ = [
    "NM_OPTIONS",
    "Simplexes",
    "centroid",
    "nelder_mead",
    "scipy_limits",
]

NM_OPTIONS = ("xatol", "fatol", "maxiter", "maxfev", "adaptive")

NONZDELT = 0.05  # scipy: the initial simplex perturbs each nonzero coordinate of x0 by 5 %
ZDELT = 0.00025  # scipy: ... and sets a zero coordinate to this value
ITERATIONS_PER_DIM = 200  # scipy's default maxiter and maxfev: 200 N

# what each seed's next evaluation is for (the branch of scipy's loop it is in)
INIT, REFLECT, EXPAND, CONTRACT_OUT, CONTRACT_IN, SHRINK = range(6)


def scipy_limits(n: int, maxiter, maxfev) -> tuple[float, float]:
    """scipy's ``maxiter`` and ``maxfev`` for ``n`` variables: both ``200 n`` if neither is set;
    if only one is set, the other is unlimited (``200 n`` if the given one is itself inf)."""
    default = n * ITERATIONS_PER_DIM
    if maxiter is None and maxfev is None:
        return default, default
    if maxiter is None:
        return (default if maxfev == np.inf else np.inf), maxfev
    if maxfev is None:
        return maxiter, (default if maxiter == np.inf else np.inf)
    return maxiter, maxfev


@nb.njit(cache=True, inline="always")
def _clip(x, lo, hi):
    """``np.clip`` of one coordinate as numpy computes it: the bound when equal to it (a signed
    zero takes the bound's sign), a NaN kept."""
    if x == x and not x > lo:
        x = lo
    if x == x and not x < hi:
        x = hi
    return x


@nb.njit(cache=True, inline="always")
def _copy(src, dst):
    """``dst[:] = src`` of two vectors element by element (numba's slice assignment checks for
    overlap and may copy through a temporary: a few times this step's arithmetic)."""
    for j in range(dst.size):
        dst[j] = src[j]


@nb.njit(cache=True, inline="always")
def _centroid_of(sim, out):
    """scipy's centroid ``np.add.reduce(sim[:-1], 0) / N`` of one simplex (``sim``: (N + 1) ×
    N, sorted) into ``out``: the vertices added one after the other, x_0 + x_1 first, as numpy
    adds along an axis that is not the contiguous one (tested on sums whose rounding depends on
    the order)."""
    N = sim.shape[1]
    for j in range(N):
        acc = sim[0, j]
        for i in range(1, N):
            acc += sim[i, j]
        out[j] = acc / N


@nb.njit(cache=True)
def centroid(sim: np.ndarray) -> np.ndarray:
    """Each seed's scipy centroid of its ``N`` best vertices (``sim``: seeds × (N + 1) × N,
    sorted), as the compiled step computes it."""
    out = np.empty((sim.shape[0], sim.shape[2]))
    for s in range(sim.shape[0]):
        _centroid_of(sim[s], out[s])
    return out


@nb.njit(cache=True, inline="always")
def _sort_distinct(sim, fsim, order, fbuf, xbuf) -> bool:
    """Sort one seed's simplex ``sim`` by its values ``fsim`` if they are pairwise distinct:
    then every sort gives the one order, numpy's unstable argsort included. On a tie it leaves
    both untouched and returns False (numpy must order the ties: :meth:`Simplexes._numpy_sort`).
    ``order``, ``fbuf``, ``xbuf``: scratch of the simplex's shapes."""
    n = fsim.shape[0]
    for i in range(n):  # insertion sort of the vertex indices
        k, v, j = i, fsim[i], i - 1
        while j >= 0 and fsim[order[j]] > v:
            order[j + 1] = order[j]
            j -= 1
        order[j + 1] = k
    for i in range(n - 1):
        if not fsim[order[i]] < fsim[order[i + 1]]:
            return False
    for i in range(n):
        fbuf[i] = fsim[order[i]]
        _copy(sim[order[i]], xbuf[i])
    for i in range(n):
        fsim[i] = fbuf[i]
        _copy(xbuf[i], sim[i])
    return True


@nb.njit(cache=True, inline="always")
def _next_point(s, phase, sim, xbar, xr, point, coef, lb, ub):
    """Seed ``s``'s next point in its branch ``phase``: scipy's xr, xe, xc or xcc, a xbar + b x_N
    (the coefficients of ``coef[phase]``), clipped."""
    a, b = coef[phase, 0], coef[phase, 1]
    N = xbar.shape[1]
    for j in range(N):
        point[s, j] = _clip(a * xbar[s, j] + b * sim[s, N, j], lb[j], ub[j])
        if phase == REFLECT:
            xr[s, j] = point[s, j]


@nb.njit(cache=True, inline="always")
def _begin(s, sim, fsim, xbar, xr, point, phase, fcalls, iterations, limits, coef, lb, ub):
    """The head of scipy's loop for seed ``s``, its simplex sorted: the loop's condition, the
    convergence test, then the centroid and the reflected point. Returns False if the search
    stopped. ``limits``: xatol, fatol, maxiter, maxfev."""
    xatol, fatol, maxiter, maxfev = limits
    if not (fcalls[s] < maxfev and iterations[s] < maxiter):
        return False
    N = xbar.shape[1]
    converged = True  # max |x_i - x_0| <= xatol and max |f_0 - f_i| <= fatol (a NaN: not)
    for i in range(1, N + 1):
        if not np.abs(fsim[s, 0] - fsim[s, i]) <= fatol:
            converged = False
        for j in range(N):
            if not np.abs(sim[s, i, j] - sim[s, 0, j]) <= xatol:
                converged = False
    if converged:
        return False
    _centroid_of(sim[s], xbar[s])
    phase[s] = REFLECT
    _next_point(s, REFLECT, sim, xbar, xr, point, coef, lb, ub)
    return True


@nb.njit(cache=True, inline="always")
def _told_vertex(s, fs, sim, fsim, point, phase, idx, iterations) -> int:
    """The value ``fs`` of a vertex of seed ``s``'s initial simplex or shrink: returns 0 if a
    vertex is left (now its ``point``), else 2 (the simplex was initial) or 1 (a shrink: its
    iteration ended)."""
    N = point.shape[1]
    k = idx[s]
    fsim[s, k] = fs
    k += 1
    idx[s] = k
    if k <= N:
        _copy(sim[s, k], point[s])
        return 0
    if phase[s] == INIT:
        return 2
    iterations[s] += 1
    return 1


@nb.njit(cache=True, inline="always")
def _told_move(s, fs, sim, fsim, xr, fxr, point, phase, idx, iterations, sigma, lb, ub):
    """The value ``fs`` of seed ``s``'s reflected, expanded or contracted point: returns 1 if
    its worst vertex was replaced (the iteration ended), 0 if a second point follows (expansion,
    contraction: ``phase`` set) or a shrink begins (its first vertex is the ``point``)."""
    N = point.shape[1]
    ph = phase[s]
    if ph == REFLECT:
        fxr[s] = fs
        if fs < fsim[s, 0]:
            phase[s] = EXPAND
            return 0
        if not fs < fsim[s, N - 1]:
            phase[s] = CONTRACT_OUT if fs < fsim[s, N] else CONTRACT_IN
            return 0
        take, x = True, xr[s]
    elif ph == EXPAND:  # xe if f(xe) < f(xr), else xr
        take = True
        if fs < fxr[s]:
            x = point[s]
        else:
            x, fs = xr[s], fxr[s]
    else:  # xc if f(xc) <= f(xr); xcc if f(xcc) < f_N; else shrink
        take = fs <= fxr[s] if ph == CONTRACT_OUT else fs < fsim[s, N]
        x = point[s]
    if take:
        _copy(x, sim[s, N])
        fsim[s, N] = fs
        iterations[s] += 1
        return 1
    for i in range(1, N + 1):  # shrink: each vertex depends on x_0 and itself only
        for j in range(N):
            best = sim[s, 0, j]
            sim[s, i, j] = _clip(best + sigma * (sim[s, i, j] - best), lb[j], ub[j])
    phase[s] = SHRINK
    idx[s] = 1
    _copy(sim[s, 1], point[s])
    return 0


@nb.njit(cache=True)
def _step(f, alive, sim, fsim, xbar, xr, fxr, point, phase, idx, fcalls, iterations, limits,
          coef, sigma, lb, ub, ended, tied, order, fbuf, xbuf):  # fmt: skip
    """Every live seed's value ``f`` of its ``point`` taken through scipy's loop to the seed's
    next point (:meth:`Simplexes.advance`); ``ended`` marks the seeds whose search ended. A seed
    whose simplex, to be sorted, has tied values waits with ``tied`` 1 (sort once) or 2 (an
    initial simplex: scipy sorts it twice) for numpy's sort and :func:`_begin_seeds`; returns
    how many wait."""
    n_tied = 0
    for s in range(f.size):
        ended[s] = False
        tied[s] = 0
        if not alive[s]:
            continue
        if phase[s] == INIT or phase[s] == SHRINK:
            told = _told_vertex(s, f[s], sim, fsim, point, phase, idx, iterations)
        else:
            told = _told_move(s, f[s], sim, fsim, xr, fxr, point, phase, idx, iterations,
                              sigma, lb, ub)  # fmt: skip
            if not told and phase[s] != SHRINK:  # the expansion or contraction follows
                _next_point(s, phase[s], sim, xbar, xr, point, coef, lb, ub)
        if told:  # an iteration begins: sort, then the head of the loop
            if _sort_distinct(sim[s], fsim[s], order, fbuf, xbuf):
                ended[s] = not _begin(s, sim, fsim, xbar, xr, point, phase, fcalls, iterations,
                                      limits, coef, lb, ub)  # fmt: skip
            else:
                tied[s] = told
                n_tied += 1
        if fcalls[s] >= limits[3]:  # a call past maxfev ends the search instead
            ended[s] = True
    return n_tied


@nb.njit(cache=True)
def _begin_seeds(seeds, sim, fsim, xbar, xr, point, phase, fcalls, iterations, limits, coef,
                 lb, ub, ended):  # fmt: skip
    """:func:`_begin` for the ``seeds`` whose simplexes numpy sorted; a stopped one is
    ``ended``."""
    for s in seeds:
        if not _begin(s, sim, fsim, xbar, xr, point, phase, fcalls, iterations, limits, coef,
                      lb, ub):  # fmt: skip
            ended[s] = True


class Simplexes:
    """Every seed's Nelder–Mead search as arrays over seeds: the simplexes ``sim`` (seeds × (N +
    1) × N) and their values ``fsim``, the centroid and the reflected point of the running
    iteration, and per seed the branch it is in (``phase``), the vertex it evaluates (``idx``,
    initial simplex and shrink), its evaluations and iterations in the running search (scipy's
    ``fcalls`` and ``iterations``) and the ``point`` it asks next."""

    def __init__(
        self,
        lb: np.ndarray,
        ub: np.ndarray,
        n_seeds: int,
        xatol: float = 1e-4,
        fatol: float = 1e-4,
        maxiter: float | None = None,
        maxfev: float | None = None,
        adaptive: bool = False,
    ):
        self.lb = np.ascontiguousarray(lb, dtype=float)
        self.ub = np.ascontiguousarray(ub, dtype=float)
        N = self.N = lb.size
        maxiter, maxfev = scipy_limits(N, maxiter, maxfev)
        if not maxfev >= 1:
            raise ValueError(f"maxfev must be at least 1, got {maxfev}")  # else restarts forever
        self.limits = np.array([xatol, fatol, maxiter, maxfev], dtype=float)
        if adaptive:  # scipy's expressions, so the coefficients round as scipy's do
            dim = float(N)
            rho, chi, psi, sigma = 1, 1 + 2 / dim, 0.75 - 1 / (2 * dim), 1 - 1 / dim
        else:
            rho, chi, psi, sigma = 1, 2, 0.5, 0.5
        self.sigma = float(sigma)
        # each branch's new point as a xbar + b x_N, a row per branch: scipy's expressions, as
        # x - c y is x + (-c) y bit for bit and the coefficients are computed as scipy's
        self.coef = np.zeros((SHRINK + 1, 2))
        self.coef[REFLECT] = 1 + rho, -rho
        self.coef[EXPAND] = 1 + rho * chi, -(rho * chi)
        self.coef[CONTRACT_OUT] = 1 + psi * rho, -(psi * rho)
        self.coef[CONTRACT_IN] = 1 - psi, psi
        self.sim = np.empty((n_seeds, N + 1, N))
        self.fsim = np.full((n_seeds, N + 1), np.inf)
        self.xbar = np.empty((n_seeds, N))
        self.xr = np.empty((n_seeds, N))
        self.fxr = np.full(n_seeds, np.inf)
        self.point = np.empty((n_seeds, N))
        self.phase = np.full(n_seeds, INIT, dtype=np.int64)
        self.idx = np.zeros(n_seeds, dtype=np.int64)
        self.fcalls = np.zeros(n_seeds, dtype=np.int64)
        self.iterations = np.ones(n_seeds, dtype=np.int64)
        self._ended = np.zeros(n_seeds, dtype=bool)
        self._tied = np.zeros(n_seeds, dtype=np.int64)
        self._scratch = (np.empty(N + 1, dtype=np.int64), np.empty(N + 1), np.empty((N + 1, N)))

    def clip(self, X: np.ndarray) -> np.ndarray:
        return np.clip(X, self.lb, self.ub)

    def restart(self, s: np.ndarray, x0: np.ndarray) -> None:
        """Start a new search of the seeds ``s`` (indices) from ``x0`` (one row each): scipy's
        initial simplex; the first vertex is asked next."""
        N = self.N
        x0 = self.clip(x0)
        sim = np.repeat(x0[:, None, :], N + 1, axis=1)
        k = np.arange(N)
        sim[:, k + 1, k] = np.where(x0 != 0, (1 + NONZDELT) * x0, ZDELT)
        # scipy: a vertex above the upper bound is reflected into the box, then all are clipped
        sim = self.clip(np.where(sim > self.ub, 2 * self.ub - sim, sim))
        self.sim[s] = sim
        self.fsim[s] = np.inf
        self.phase[s] = INIT
        self.idx[s] = 0
        self.fcalls[s] = 0
        self.iterations[s] = 1
        self.point[s] = sim[:, 0]

    def advance(self, f: np.ndarray, alive: np.ndarray) -> np.ndarray:
        """Take each live seed's value ``f`` of its ``point`` through scipy's loop to the seed's
        next point (one compiled call, :func:`_step`). Returns the seeds whose search has ended
        (converged, or at its ``maxiter`` / ``maxfev``): they need a restart.

        scipy sorts each simplex by ``np.argsort``, which is not stable: the compiled step sorts
        a simplex whose values are distinct (one order only), numpy sorts one with tied values
        (:meth:`_numpy_sort`), as scipy would."""
        ended, tied = self._ended, self._tied
        state = (self.sim, self.fsim, self.xbar, self.xr, self.fxr, self.point, self.phase,
                 self.idx, self.fcalls, self.iterations)  # fmt: skip
        f = np.ascontiguousarray(f, dtype=float)
        if _step(f, alive, *state, self.limits, self.coef, self.sigma, self.lb, self.ub, ended,
                 tied, *self._scratch):  # fmt: skip
            seeds = np.flatnonzero(tied)
            self._numpy_sort(seeds[tied[seeds] == 2])  # scipy sorts the initial simplex twice
            self._numpy_sort(seeds)
            _begin_seeds(seeds, self.sim, self.fsim, self.xbar, self.xr, self.point, self.phase,
                         self.fcalls, self.iterations, self.limits, self.coef, self.lb, self.ub,
                         ended)  # fmt: skip
        return ended.copy()

    def _numpy_sort(self, seeds: np.ndarray) -> None:
        """scipy's ``np.argsort`` of the values of each of the ``seeds``, the vertices in that
        order. Tied values keep scipy's order: each seed's row is sorted by the same numpy sort
        on the same values (a row's order does not depend on the other rows of the call)."""
        if seeds.size:
            ind = np.argsort(self.fsim[seeds], axis=1)
            rows = np.arange(seeds.size)[:, None]
            self.fsim[seeds] = self.fsim[seeds][rows, ind]
            self.sim[seeds] = self.sim[seeds][rows, ind]


@register("nelder_mead")
def nelder_mead(runs: Runs, rngs: list[np.random.Generator], pop_size: int, **settings) -> Steps:
    """Bounded Nelder–Mead (scipy's algorithm) restarted from random points until the budget is
    spent, every seed of ``runs`` stepped at once (one point per seed per step), each seed's
    starts from its own generator in ``rngs``."""
    unknown = set(settings) - set(NM_OPTIONS)
    if unknown:
        raise TypeError(f"nelder_mead: unknown settings {sorted(unknown)}; known: {NM_OPTIONS}")
    search = Simplexes(runs.lb, runs.ub, runs.n, **settings)

    def restart(which: np.ndarray) -> None:
        s = np.flatnonzero(which)
        # one draw of D doubles per seed when its search starts
        search.restart(s, np.concatenate([uniform_in_box(rngs[i], runs.lb, runs.ub, 1) for i in s]))

    alive = ~runs.done
    restart(alive)
    # count_nonzero for .any(): a quarter of its cost on a few dozen seeds, paid every step
    while np.count_nonzero(alive):
        # the asked rows are copied by the ask; the points are read again (the best point) before
        # advance moves them
        f = (yield from runs.ask(search.point[:, None, :], alive))[:, 0]
        search.fcalls += alive
        runs.close_spent(pop_size)  # an iteration per pop_size evaluations
        alive &= ~runs.done
        ended = search.advance(f, alive)
        if np.count_nonzero(ended):
            restart(ended)
