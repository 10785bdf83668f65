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
evaluate, and which branch each seed takes is a mask over seeds. The arithmetic is scipy's,
expression for expression (the same coefficients applied in the same order, the centroid as
``np.add.reduce`` over the vertices, the same non-stable ``np.argsort`` on each seed's values), so
a seed's points and values are scipy's bit for bit: ``tests/unit/test_nelder_mead.py`` holds it to
``scipy.optimize.minimize`` itself, driven one seed at a time, on bounded test functions, with
budgets that end inside a restart's initial simplex and inside a shrink, with the ``adaptive``
option and with starts on a bound.

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


def centroid(sim: np.ndarray) -> np.ndarray:
    """Each seed's scipy centroid of its ``N`` best vertices (``sim``: seeds × (N + 1) × N,
    sorted): ``np.add.reduce(sim[:-1], 0) / N`` adds the vertices one after the other, x_0 + x_1
    first (numpy's pairwise summation is along a contiguous reduced axis only), and so does this
    reduction over the vertex axis of every seed at once (tested on sums whose rounding depends
    on the order)."""
    return np.add.reduce(sim[:, :-1], 1) / (sim.shape[1] - 1)


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
        self.lb, self.ub = lb, ub
        N = self.N = lb.size
        self.xatol, self.fatol = xatol, fatol
        self.maxiter, self.maxfev = scipy_limits(N, maxiter, maxfev)
        if not self.maxfev >= 1:
            raise ValueError(f"maxfev must be at least 1, got {maxfev}")  # else restarts forever
        if adaptive:  # scipy's expressions, so the coefficients round as scipy's do
            dim = float(N)
            rho, chi, psi, sigma = 1, 1 + 2 / dim, 0.75 - 1 / (2 * dim), 1 - 1 / dim
        else:
            rho, chi, psi, sigma = 1, 2, 0.5, 0.5
        self.sigma = sigma
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
        self.phase = np.full(n_seeds, INIT)
        self.idx = np.zeros(n_seeds, dtype=np.int64)
        self.fcalls = np.zeros(n_seeds, dtype=np.int64)
        self.iterations = np.ones(n_seeds, dtype=np.int64)

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

    def _sort(self, which: np.ndarray) -> None:
        """scipy's ``np.argsort`` of the values of each seed in the mask ``which``, the vertices
        in that order. The sort is not stable: tied values keep scipy's order because each seed's
        row is sorted by the same call on the same values (a row's order does not depend on the
        other rows of the call)."""
        ind = np.argsort(self.fsim, axis=1)
        rows = np.arange(ind.shape[0])[:, None]
        self.fsim = np.where(which[:, None], self.fsim[rows, ind], self.fsim)
        self.sim = np.where(which[:, None, None], self.sim[rows, ind], self.sim)

    @np.errstate(invalid="ignore", over="ignore")  # inf - inf of failed simulations: harmless
    def advance(self, f: np.ndarray, alive: np.ndarray) -> np.ndarray:
        """Take each live seed's value ``f`` of its ``point`` through scipy's loop to the seed's
        next point. Returns the seeds whose search has ended (converged, or at its ``maxiter`` /
        ``maxfev``): they need a restart.

        Every branch is computed for every seed (a few dozen seeds: an operation on all of them
        costs what one on a few does) and kept where the seed is in it."""
        code = np.where(alive, self.phase, -1)  # the branch each live seed was in when it asked
        completed, initialised = self._vertex_told(f, code)
        replaced, moving = self._move_told(f, code)
        completed |= replaced
        self.iterations += completed
        stopped, reflecting = self._begin_iterations(completed | initialised, initialised)
        moving |= reflecting
        if moving.any():
            self._next_points(moving)
        # a call past maxfev ends the search instead (scipy's _MaxFuncCallError)
        return alive & (stopped | (self.fcalls >= self.maxfev))

    def _vertex_told(self, f: np.ndarray, code: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Vertex by vertex, the initial simplex and a shrink: the seeds whose simplex is now
        evaluated, those of a shrink (``completed``: the iteration ended) and those of an
        initial simplex (``initialised``); the others' next vertex is their ``point``."""
        N, sim, fsim, point = self.N, self.sim, self.fsim, self.point
        completed = np.zeros(code.size, dtype=bool)
        initialised = np.zeros(code.size, dtype=bool)
        vertex = (code == INIT) | (code == SHRINK)
        if vertex.any():
            s = np.flatnonzero(vertex)
            k = self.idx[s]
            fsim[s, k] = f[s]
            k += 1
            self.idx[s] = k
            more = k <= N
            point[s[more]] = sim[s[more], k[more]]
            last = s[~more]
            init = code[last] == INIT
            initialised[last[init]] = True
            completed[last[~init]] = True
        return completed, initialised

    def _move_told(self, f: np.ndarray, code: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The value of a reflected, expanded or contracted point: the seeds whose worst vertex
        was replaced (their iteration ended) and those that go on to a second point (expansion
        or contraction); a failed contraction starts the shrink."""
        sim, fsim, point = self.sim, self.fsim, self.point
        # reflection: expand if f(xr) < f_0, take xr if f(xr) < f_{N-1}, else contract, outside
        # if f(xr) < f_N, inside otherwise
        reflect = code == REFLECT
        below_best = f < fsim[:, 0]
        take_xr = reflect & ~below_best & (f < fsim[:, -2])
        contraction = np.where(f < fsim[:, -1], CONTRACT_OUT, CONTRACT_IN)
        moving = reflect & ~take_xr
        # the second evaluation of an iteration: xe replaces the worst vertex if f(xe) < f(xr),
        # else xr does; xc if f(xc) <= f(xr); xcc if f(xcc) < f_N; else the simplex shrinks
        fxr = self.fxr
        take = np.where(
            code == EXPAND,
            f < fxr,
            np.where(code == CONTRACT_OUT, f <= fxr, (code == CONTRACT_IN) & (f < fsim[:, -1])),
        )
        expanded = code == EXPAND
        replace = take_xr | take | expanded
        np.copyto(sim[:, -1], np.where(take[:, None], point, self.xr), where=replace[:, None])
        fsim[:, -1] = np.where(replace, np.where(take | take_xr, f, fxr), fsim[:, -1])
        shrink = (code >= CONTRACT_OUT) & (code <= CONTRACT_IN) & ~take
        self.fxr = np.where(reflect, f, fxr)
        self.phase = np.where(moving, np.where(below_best, EXPAND, contraction), self.phase)

        if shrink.any():  # every shrunk vertex at once: each depends on x_0 and itself only
            s = np.flatnonzero(shrink)
            best = sim[s, :1]
            sim[s, 1:] = self.clip(best + self.sigma * (sim[s, 1:] - best))
            self.phase[s] = SHRINK
            self.idx[s] = 1
            point[s] = sim[s, 1]
        return replace, moving

    def _begin_iterations(
        self, starting: np.ndarray, initialised: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """The head of scipy's loop for the seeds ``starting`` an iteration: sort, its
        condition, the convergence test, then the centroid of the reflection. Returns the seeds
        that stopped and those that reflect."""
        stopped = np.zeros(starting.size, dtype=bool)
        go = np.zeros(starting.size, dtype=bool)
        if not starting.any():
            return stopped, go
        if initialised.any():  # scipy sorts the initial simplex twice
            self._sort(initialised)
        self._sort(starting)
        sim, fsim = self.sim, self.fsim
        go = starting & (self.fcalls < self.maxfev) & (self.iterations < self.maxiter)
        spread_x = np.abs((sim[:, 1:] - sim[:, :1]).reshape(len(sim), -1)).max(axis=1)
        spread_f = np.abs(fsim[:, :1] - fsim[:, 1:]).max(axis=1)
        go &= ~((spread_x <= self.xatol) & (spread_f <= self.fatol))
        stopped = starting & ~go
        if go.any():
            xbar = centroid(sim)
            self.xbar = np.where(go[:, None], xbar, self.xbar)
            self.phase = np.where(go, REFLECT, self.phase)
        return stopped, go

    def _next_points(self, moving: np.ndarray) -> None:
        """The next point of the seeds ``moving``: scipy's xr, xe, xc, xcc of their branch, a
        xbar + b x_N, clipped."""
        coef = self.coef[self.phase]
        new = self.clip(coef[:, :1] * self.xbar + coef[:, 1:] * self.sim[:, -1])
        self.point = np.where(moving[:, None], new, self.point)
        reflecting = moving & (self.phase == REFLECT)
        self.xr = np.where(reflecting[:, None], new, self.xr)


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
    while alive.any():
        f = (yield from runs.ask(search.point.copy()[:, None, :], alive))[:, 0]
        search.fcalls += alive
        runs.close_spent(pop_size)  # an iteration per pop_size evaluations
        alive &= ~runs.done
        ended = search.advance(f, alive)
        if ended.any():
            restart(ended)
