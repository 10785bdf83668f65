"""Bounded quasi-Newton (L-BFGS-B) with finite-difference gradients and random restarts.

Byrd, R. H., Lu, P., Nocedal, J., Zhu, C. (1995). A limited memory algorithm for bound constrained
optimization. SIAM J. Sci. Comput. 16(5), 1190-1208. doi:10.1137/0916069 (scipy's L-BFGS-B; the
paper's reference [53] only *uses* "the quasi-Newton method", presumably MATLAB's BFGS
``fminunc``, with no settings reported).

Pseudo-code::

    h_i <- rel_step * (ub_i - lb_i)                      # rel_step = sqrt(machine eps)
    fun(x):                                              # returns (f, grad) in ONE population call
        x <- clip(x, lb, ub)
        s_i <- +h_i, or -h_i if x_i + h_i > ub_i         # step inward at the upper bound
        [f0, f_1..f_D] <- F([x; x + s_1 e_1; ...; x + s_D e_D])   # D + 1 evaluations
        g_i <- (f_i - f0) / s_i
    while budget left:
        x0 <- uniform in [lb, ub]
        scipy L-BFGS-B(fun, x0, jac=True, bounds) until it converges (ftol / gtol) or fails its
        line search; the call that does not fit into the budget evaluates what fits, then
        the run ends

Non-finite values (a simulation that failed, mapped to ``+inf`` by the accounts): if ``f0`` is
not finite, ``fun`` returns ``(1e300, 0)`` so that the line search backs off; non-finite
difference quotients are set to 0. Both are only safeguards; no such point is ever the best.

SciPy's core, driven for every seed at once. What runs is exactly what
``scipy.optimize.minimize(fun, x0, jac=True, method="L-BFGS-B", bounds=Bounds(lb, ub),
options=settings)`` runs -- the same calls of scipy's compiled L-BFGS-B routine ``setulb`` with
the same arguments, hence the same points and the same records bit for bit -- but the loop around
``setulb`` is ours, written over the seeds of a fit block (:class:`.base.Runs`,
``base.register``): each step moves every seed's search to the next point where it
needs ``f`` and ``g`` and asks the ``D + 1`` rows of all seeds in one ask. No ``minimize``
wrapper, no ``ScalarFunction``/``MemoizeJac`` objects, no greenlet per seed: on the paper's fit
block (``benchmarks/bench_fit_block.py --algorithms quasi_newton``: scenario 4 case 4, 30 seeds;
the previous version and this one run alternately, twice, load 2.5-3.3 on two cores) the block
took 5.2-5.5 s, 3.2-3.5 times its kernel bound, before, and 1.8-1.9 s, 1.1-1.2 times, after; the
records are the same. With 10 seeds of scenario 1 case 1 (a cheaper kernel call, so the steps'
own cost weighs more): 2.1 s, 8.0 times, before; 1.2 s, 4.3 times, after.
:class:`LbfgsbSearch` is scipy 1.17.1's ``_minimize_lbfgsb`` loop (``scipy/optimize/
_lbfgsb_py.py``) for one search, with what its wrappers do to the calls kept:

- the workspace, the bounds (``nbd`` codes 0-3), ``factr = ftol / eps``, ``pgtol = gtol``, ``m =
  maxcor``, ``maxls``; ``x0`` clipped to the box; ``g`` passed as a fresh float64 copy each call
  (the core can write into it; the memo's ``g`` stays as told);
- ``ScalarFunction`` evaluates ``fun`` at ``x0`` before the first ``setulb`` call (which still
  gets ``f = 0``, ``g = 0``) and answers a request for the point it holds (``np.array_equal``)
  from its memo, without an evaluation (this happens at the first request, ``x0`` itself);
- after each new iterate (task ``NEW_X``) the search stops once ``maxiter`` iterations are done,
  or once more than ``maxfun`` points were evaluated (scipy's stop tasks 504 and 502; ``setulb``
  is called once more with the stop task, as scipy does);
- ``MemoizeJac`` compares points with ``==``, so a point with a NaN coordinate (never seen here:
  the core gets finite ``f`` and ``g``) would be evaluated twice, ``f`` from the first
  evaluation and ``g`` from the second; kept.

This depends on a private scipy module, ``scipy.optimize._lbfgsb`` (its ``setulb`` signature,
task codes and workspace sizes), and on the loop of ``_minimize_lbfgsb``, as of scipy 1.17.1 (the
pinned version, ``environment.txt``). ``tests/unit/test_quasi_newton.py`` holds this module to
``scipy.optimize.minimize`` itself, run one seed at a time as the previous version did, on test
functions and budgets that end inside a gradient call: a scipy upgrade that changes either fails
there, loudly.

Budget / iteration mapping: as for Nelder–Mead (see ``nelder_mead.py``), "an iteration" is
``pop_size`` objective evaluations; an iteration closes each time another ``pop_size``
evaluations have been spent (once after the first ``pop_size``). Every gradient costs ``D + 1``
evaluations, so one call can close two iterations when ``D + 1 > pop_size``.
``Budget(iterations=T)`` spends exactly ``(T + 1) pop_size`` evaluations, ``Budget(max_nfe=N)``
exactly ``N`` (the last call is truncated to the evaluations that fit).

Settings: ``rel_step`` (default ``sqrt(eps)``), and scipy L-BFGS-B options ``ftol``, ``gtol``,
``maxcor``, ``maxls``, ``maxiter``, ``maxfun`` (scipy defaults, :data:`LBFGSB_DEFAULTS`).

Differences vs MATLAB ``fminunc`` (BFGS, unconstrained, step ``sqrt(eps) max(|x|, 1)``): bounds
(L-BFGS-B), a box-relative step, random restarts until the budget is spent. mealpy has no
quasi-Newton method.
"""

from __future__ import annotations

import math

import numpy as np

# private: scipy exposes no public reverse-communication L-BFGS-B; see the module docstring
from scipy.optimize import _lbfgsb

from .base import Runs, Steps, register, uniform_in_box

LBFGSB_DEFAULTS = {
    "ftol": 2.2204460492503131e-09,
    "gtol": 1e-5,
    "maxcor": 10,
    "maxls": 20,
    "maxiter": 15000,
    "maxfun": 15000,
}
"""scipy 1.17.1's defaults of these L-BFGS-B options (``_minimize_lbfgsb``'s signature)."""
LBFGSB_OPTIONS = tuple(LBFGSB_DEFAULTS)
_BIG = 1e300  # f at a point whose value is not finite: the line search backs off from it

# scipy 1.17.1's task codes (``status_messages``, ``task_messages`` in ``_lbfgsb_py.py``)
_NEW_X = 1  # a new iterate: the caller checks its iteration and evaluation limits
_FG = 3  # the core asks for f and g at x
_STOP = 5
_STOP_ITERATIONS = 504  # "TOTAL NO. OF ITERATIONS REACHED LIMIT"
_STOP_EVALUATIONS = 502  # "TOTAL NO. OF F,G EVALUATIONS EXCEEDS LIMIT"


class LbfgsbCore:
    """What every search of a run shares: the core's bounds and settings, as
    ``_minimize_lbfgsb`` prepares them."""

    def __init__(self, lb: np.ndarray, ub: np.ndarray, settings: dict):
        opts = {**LBFGSB_DEFAULTS, **settings}
        if not opts["maxls"] > 0:
            raise ValueError("maxls must be positive.")  # scipy's check and message
        self.lb, self.ub = lb, ub
        self.m = opts["maxcor"]
        self.factr = opts["ftol"] / np.finfo(float).eps
        self.pgtol = opts["gtol"]
        self.maxls = opts["maxls"]
        self.maxiter = opts["maxiter"]
        self.maxfun = opts["maxfun"]
        finite_lb, finite_ub = ~np.isinf(lb), ~np.isinf(ub)
        self.low = np.where(finite_lb, lb, 0.0)
        self.up = np.where(finite_ub, ub, 0.0)
        # scipy's bounds_map: 0 unbounded, 1 lower only, 2 both, 3 upper only
        nbd = np.where(finite_lb, np.where(finite_ub, 2, 1), np.where(finite_ub, 3, 0))
        self.nbd = nbd.astype(np.int32)


class LbfgsbSearch:
    """One L-BFGS-B search from ``x0``: scipy's ``_minimize_lbfgsb`` loop around ``setulb``, with
    ``ScalarFunction``'s memo, answered by :meth:`tell` instead of by calling ``fun``.

    ``point`` is where ``f`` and ``g`` are wanted (the first: ``x0``); :meth:`advance` runs the
    core to the next such point."""

    __slots__ = (
        "core", "dsave", "f", "f_point", "g", "g_point", "isave", "iterations", "iwa", "ln_task",
        "lsave", "nfev", "point", "started", "task", "wa", "x",
    )  # fmt: skip

    def __init__(self, x0: np.ndarray, core: LbfgsbCore):
        n, m = x0.size, core.m
        self.core = core
        x0 = np.clip(x0, core.lb, core.ub)
        self.x = np.array(x0, dtype=np.float64)  # the core's iterate, changed in place
        self.f = np.array(0.0, dtype=np.float64)
        self.g = np.zeros(n, dtype=np.float64)
        self.wa = np.zeros(2 * m * n + 5 * n + 11 * m * m + 8 * m, np.float64)
        self.iwa = np.zeros(3 * n, dtype=np.int32)
        self.task = np.zeros(2, dtype=np.int32)
        self.ln_task = np.zeros(2, dtype=np.int32)
        self.lsave = np.zeros(4, dtype=np.int32)
        self.isave = np.zeros(44, dtype=np.int32)
        self.dsave = np.zeros(29, dtype=np.float64)
        self.iterations = 0
        self.nfev = 0  # points evaluated (ScalarFunction.nfev)
        self.point = x0.astype(np.float64)  # ScalarFunction.x: evaluated at construction
        self.f_point: float | None = None
        self.g_point: np.ndarray | None = None
        self.started = False

    def tell(self, f: float, g: np.ndarray) -> None:
        """``fun``'s value and gradient at :attr:`point`."""
        self.nfev += 1
        self.f_point, self.g_point = f, g
        if self.started:  # scipy's ``f, g = func_and_grad(x)``; the value at x0 waits in the memo
            self.f, self.g = f, g

    def advance(self) -> bool:
        """Run the core until it wants ``f`` and ``g`` at a point other than the one held (True,
        now :attr:`point`) or the search ends (False: converged, stopped or failed)."""
        core, x, task = self.core, self.x, self.task
        setulb = _lbfgsb.setulb
        self.started = True
        while True:
            # scipy upcasts g before every call (gh-18730), a fresh copy the core may write into
            self.g = g = self.g.astype(np.float64)
            setulb(core.m, x, core.low, core.up, core.nbd, self.f, g, core.factr, core.pgtol,
                   self.wa, self.iwa, task, self.lsave, self.isave, self.dsave, core.maxls,
                   self.ln_task)  # fmt: skip
            t = task[0]
            if t == _FG:
                point = self.point
                # ScalarFunction's memo (np.array_equal); the first coordinate settles most asks
                if x[0] == point[0] and (x == point).all():
                    self.f, self.g = self.f_point, self.g_point
                    continue
                self.point = x.copy()
                return True
            if t != _NEW_X:
                return False
            self.iterations += 1
            if self.iterations >= core.maxiter:
                task[0], task[1] = _STOP, _STOP_ITERATIONS
            elif self.nfev > core.maxfun:
                task[0], task[1] = _STOP, _STOP_EVALUATIONS


def parse_settings(settings: dict) -> tuple[float, dict]:
    """``rel_step`` (the forward difference's step, relative to the box) and the L-BFGS-B
    options, checked."""
    settings = dict(settings)
    rel_step = float(settings.pop("rel_step", np.sqrt(np.finfo(float).eps)))
    unknown = set(settings) - set(LBFGSB_OPTIONS)
    if unknown:
        raise TypeError(
            f"quasi_newton: unknown settings {sorted(unknown)}; known: rel_step, {LBFGSB_OPTIONS}"
        )
    if not rel_step > 0:
        raise ValueError(f"rel_step must be positive, got {rel_step}")
    return rel_step, settings


class Restarts:
    """Every seed's running L-BFGS-B search, a new one from a random point once it ends, and
    the seeds whose point has a NaN (scipy's ``MemoizeJac`` evaluates it twice: f from the
    first evaluation, g from the second)."""

    def __init__(self, rngs: list[np.random.Generator], core: LbfgsbCore):
        self.rngs, self.core = rngs, core
        self.searches: list[LbfgsbSearch | None] = [None] * len(rngs)
        self.again = [False] * len(rngs)  # the point has a NaN: evaluated a second time
        self.f_first = [0.0] * len(rngs)  # fun's f at such a point, from its first evaluation

    def points(self) -> np.ndarray:
        """Where each seed wants f and g (the lower bound for a seed that never started)."""
        lb = self.core.lb
        return np.array([lb if search is None else search.point for search in self.searches])

    def moves_on(self, s: int, done: bool) -> bool:
        """Seed ``s``'s search to its next point, or a new search once it has ended (restart_loop:
        none once the budget is spent, False)."""
        search = self.searches[s]
        if search is not None and search.advance():
            return True
        if done:
            return False
        x0 = uniform_in_box(self.rngs[s], self.core.lb, self.core.ub, 1)[0]
        self.searches[s] = LbfgsbSearch(x0, self.core)
        return True

    def tell(self, s: int, f: float, g: np.ndarray, has_nan: bool, done: bool) -> bool:
        """Seed ``s``'s ``fun`` at its point; whether it asks again."""
        if self.again[s]:  # the second evaluation gives g; f is the first's
            self.again[s] = False
            f = self.f_first[s]
        elif has_nan:
            self.again[s] = True
            self.f_first[s] = f
            return True
        self.searches[s].tell(f, g)
        return self.moves_on(s, done)


def ask_rows_that_fit(runs: Runs, X: np.ndarray, live: list[int], room: list[int]):
    """``F = yield from ask_rows_that_fit(...)``: the values of the first ``room[s]`` rows of
    each live seed's ``X`` (the rest +inf), in one ask unless the budgets left differ."""
    S, k_all = X.shape[0], X.shape[1]
    if len(live) == S and all(k == k_all for k in room):  # every seed asks a whole call
        return (yield from runs.ask(X))
    F = np.full((S, k_all), np.inf)
    for k in sorted({room[s] for s in live}):
        group = np.zeros(S, dtype=bool)
        group[[s for s in live if room[s] == k]] = True
        F[group, :k] = (yield from runs.ask(X[:, :k], group))[group]
    return F


@register("quasi_newton")
def quasi_newton(runs: Runs, rngs: list[np.random.Generator], pop_size: int, **settings) -> Steps:
    """L-BFGS-B restarted until the budget is spent, every seed's forward-difference gradient
    (``D + 1`` points) in one ask per step (see the module docstring)."""
    rel_step, settings = parse_settings(settings)
    S, D, P = runs.n, runs.dim, pop_size
    lb, ub = runs.lb, runs.ub
    h = rel_step * (ub - lb)
    seeds = Restarts(rngs, LbfgsbCore(lb, ub, settings))
    cap = runs.evaluation_cap(P)  # an iteration is P evaluations, as for Nelder–Mead
    diagonal = np.arange(D)
    shifts = np.zeros((S, D, D))

    done = runs.done.tolist()
    live = [s for s in range(S) if seeds.moves_on(s, done[s])]  # the seeds whose run goes on
    while True:
        room = np.minimum(D + 1, cap - runs.nfe).tolist()  # rows that fit into each budget
        live = [s for s in live if room[s] > 0]  # nothing fits: the run ends (BudgetExhausted)
        if not live:
            return

        # every seed's fun(x) as one array operation (the rows of ended runs are not asked)
        points = seeds.points()
        x = np.clip(points, lb, ub)
        steps = np.where(x + h <= ub, h, -h)
        shifts[:, diagonal, diagonal] = steps
        X = np.concatenate([x[:, None, :], x[:, None, :] + shifts], axis=1)  # (S, D + 1, D)
        F = yield from ask_rows_that_fit(runs, X, live, room)
        runs.close_spent(P)
        with np.errstate(invalid="ignore", over="ignore"):  # inf - inf, huge / step
            G = (F[:, 1:] - F[:, :1]) / steps
        G[~np.isfinite(G)] = 0.0
        f0 = F[:, 0].tolist()
        has_nan = np.isnan(points).any(axis=1).tolist()
        done = runs.done.tolist()
        moving = []
        for s in live:
            if room[s] < D + 1:  # a cut call ends the run (BudgetExhausted)
                continue
            f, g = (f0[s], G[s]) if math.isfinite(f0[s]) else (_BIG, np.zeros(D))
            if seeds.tell(s, f, g, has_nan[s], done[s]):
                moving.append(s)
        live = moving
