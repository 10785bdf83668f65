"""Bounded quasi-Newton (L-BFGS-B) with finite-difference gradients and random restarts.

Byrd, R. H., Lu, P., Nocedal, J., Zhu, C. (1995). A limited memory algorithm for bound constrained
optimization. SIAM J. Sci. Comput. 16(5), 1190-1208. doi:10.1137/0916069 (scipy's L-BFGS-B; the
paper's reference [53] only *uses* "the quasi-Newton method", presumably MATLAB's BFGS
``fminunc``, with no settings reported).

Pseudo-code::

    h_i <- rel_step * (ub_i - lb_i)                      # rel_step = sqrt(machine eps)
    fun(x):                                              # returns (f, grad) in ONE population call
        s_i <- +h_i, or -h_i if x_i + h_i > ub_i         # step inward at the upper bound
        [f0, f_1..f_D] <- F([x; x + s_1 e_1; ...; x + s_D e_D])   # D + 1 evaluations
        g_i <- (f_i - f0) / s_i
    while budget left:
        x0 <- uniform in [lb, ub]
        scipy L-BFGS-B(fun, x0, jac=True, bounds) until it converges (ftol / gtol) or fails its
        line search; the call that does not fit into the budget evaluates what fits, then
        raises BudgetExhausted, which ends the run

Non-finite values (a simulation that failed, mapped to ``+inf`` by the tracker): if ``f0`` is not
finite, ``fun`` returns ``(1e300, 0)`` so that the line search backs off; non-finite difference
quotients are set to 0. Both are only safeguards; the tracker never accepts such points as best.

Ask/tell: as Nelder–Mead's (see ``nelder_mead.py``), L-BFGS-B runs in a greenlet and each
``fun`` call becomes an ask of its ``D + 1`` points.

Budget / iteration mapping: as for Nelder–Mead (see ``nelder_mead.py``), "an iteration" is
``pop_size`` objective evaluations; ``tracker.end_iteration()`` is called each time another
``pop_size`` evaluations have been spent (once after the first ``pop_size``). Every gradient costs
``D + 1`` evaluations, so one call can close two iterations when ``D + 1 > pop_size``.
``Budget(iterations=T)`` spends exactly ``(T + 1) pop_size`` evaluations, ``Budget(max_nfe=N)``
exactly ``N`` (the last call is truncated to the evaluations that fit).

Settings: ``rel_step`` (default ``sqrt(eps)``), and scipy L-BFGS-B options ``ftol``, ``gtol``,
``maxcor``, ``maxls``, ``maxiter``, ``maxfun`` (scipy defaults).

Differences vs MATLAB ``fminunc`` (BFGS, unconstrained, step ``sqrt(eps) max(|x|, 1)``): bounds
(L-BFGS-B), a box-relative step, random restarts until the budget is spent. mealpy has no
quasi-Newton method.
"""

from __future__ import annotations

import numpy as np
from scipy.optimize import Bounds, minimize

from .base import BudgetExhausted, Steps, Tracker, register, search_steps
from .nelder_mead import LocalSearchAccounting, restart_loop

LBFGSB_OPTIONS = ("ftol", "gtol", "maxcor", "maxls", "maxiter", "maxfun")
_BIG = 1e300


@register("quasi_newton")
def quasi_newton(tracker: Tracker, rng: np.random.Generator, pop_size: int, **settings) -> Steps:
    """L-BFGS-B, forward-difference gradient in one population call, restarts until the budget."""
    settings = dict(settings)
    rel_step = float(settings.pop("rel_step", np.sqrt(np.finfo(float).eps)))
    unknown = set(settings) - set(LBFGSB_OPTIONS)
    if unknown:
        raise TypeError(
            f"quasi_newton: unknown settings {sorted(unknown)}; known: rel_step, {LBFGSB_OPTIONS}"
        )
    if not rel_step > 0:
        raise ValueError(f"rel_step must be positive, got {rel_step}")
    lb, ub = tracker.lb, tracker.ub
    h = rel_step * (ub - lb)
    D = tracker.dim
    bounds = Bounds(lb, ub)

    def search(ask) -> None:
        acc = LocalSearchAccounting(tracker, pop_size, ask)

        def fun(x: np.ndarray) -> tuple[float, np.ndarray]:
            x = np.clip(x, lb, ub)
            steps = np.where(x + h <= ub, h, -h)
            X = np.vstack([x, x + np.diag(steps)])
            f, complete = acc.evaluate(X)
            if not complete:
                raise BudgetExhausted
            if not np.isfinite(f[0]):
                return _BIG, np.zeros(D)
            g = (f[1:] - f[0]) / steps
            g[~np.isfinite(g)] = 0.0
            return float(f[0]), g

        def search_from(x0: np.ndarray) -> None:
            minimize(fun, x0, jac=True, method="L-BFGS-B", bounds=bounds, options=settings)

        restart_loop(tracker, rng, search_from)

    yield from search_steps(tracker, search)
