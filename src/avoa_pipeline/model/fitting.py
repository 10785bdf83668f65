"""The one least-squares fit of the model library: several records of one cell at once (shared
cell parameters, each record started by the one initial-state rule), bounds and weak priors from
the registry, multi-start.

Why not a generic wrapper such as PyBOP: the Jacobian is built by simulating every perturbed
parameter row in one pass of the compiled simulator (``ecm._simulate`` steps rows together), which
is what makes a finite-difference Jacobian affordable on 10⁴-10⁵ samples; the solver itself is
scipy's ``least_squares`` (trust-region reflective, box bounds).

The free vector z holds the cell's parameters (``Structure.shared``); no state of a record is
fitted: each record starts by the library's one rule (``ecm.soc0_rows``), as every prediction
does. Each record counts alike, whatever its length: the fitted samples are shared equally between
the records and each record's residuals are scaled by √(n̄/n_r) (Plett's ``processDynamic`` and
PyBOP's ``MetaProblem`` weigh records alike too).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np
from scipy.optimize import least_squares

from . import ecm, elements, ocv
from .ecm import IDX, N_KNOTS, NEUTRAL, Config, Knots, Record

MAX_FIT_POINTS = 20000
"""Residuals fitted per least-squares problem at most (all records together); longer data are
thinned by a fixed stride for fitting (the model is always simulated at full resolution and
scored on every sample; the simulator computes the terminal voltage only at the fitted samples and
only steps the state between them, so a fit's cost on a long record is mostly that stepping)."""

COARSE_POINTS = 2500
"""Residuals per multi-start trial: the starts are compared on thinned records, and only the best
is refined on the full set."""

AT_BOUND = 1e-4
"""A fitted parameter within 1e-4 of its searched range (internal coordinates) of a bound is
pressed against it: the bound stopped the fit, not the data, so the value is not a finding (the
records would have taken it further). Bounded least squares stops within about 1e-8 of the range
from an active bound; 1e-4 leaves room for that and still lies below the values records set
(0.2 mΩ of a 0-2 Ω range, 0.06 % of a time constant over 5 decades)."""


def at_bound(x, lo, hi) -> np.ndarray:
    """Per parameter (internal coordinates): within AT_BOUND of its searched range of a bound."""
    x, lo, hi = (np.asarray(a, dtype=float) for a in (x, lo, hi))
    return np.minimum(x - lo, hi - x) <= AT_BOUND * (hi - lo)


PRIOR_SCALE_V = 1e-3
"""Residual scale (V) of the weak priors: one prior row weighs like one sample with 1 mV noise, so
data that inform a parameter outweigh its prior by orders of magnitude."""


def _stats(recs: list[Record]) -> dict:
    swing = max(float(np.ptp(r.charge_ah())) for r in recs)
    return {
        "swing": swing,
        "imax": max(r.imax() for r in recs),
        "dt": min(float(np.median(r.dt)) for r in recs),
        "duration": max(float(r.t[-1] - r.t[0]) for r in recs),
    }


def internal_limits(name: str) -> tuple[float, float]:
    """The library's physical range of a parameter (``ecm.LIMITS``) in internal coordinates."""
    rep = ecm.PARAMS[name].report
    lo, hi = sorted(ecm.internal_value(rep, v)[1] for v in ecm.LIMITS[name])
    return lo, hi


def bounds_for(recs: list[Record],
               table: ecm.OcvTable | None = None) -> dict[str, tuple[float, float]]:  # fmt: skip
    """Wide, physically plausible bounds (internal coordinates) for a cell's records: the
    library's physical range (``ecm.LIMITS``), narrowed where the records say more, and with a
    measured OCV ``table`` the offset within ``ocv.OFFSET_BOUND_SDS`` of its uncertainty
    (``ocv.offset_prior``)."""
    s = _stats(recs)
    imax = s["imax"]
    tau_lo = np.log10(max(s["dt"], 0.05))  # a time constant below the step is an R0
    tau_hi = np.log10(max(min(2e4, 2.0 * s["duration"]), 10.0 * s["dt"]))
    q_lo = max(0.01, 0.8 * s["swing"])  # no record spans more than 125 % of the capacity
    out = {n: internal_limits(n) for n in ecm.NAMES}
    for n, p in ecm.PARAMS.items():
        if p.scale == "tau":
            out[n] = (tau_lo, tau_hi)
        elif p.scaled is not None:
            out[n] = (_by_current(p.scaled[0], p, imax), _by_current(p.scaled[1], p, imax))
    out["lq"] = (np.log10(q_lo), np.log10(max(1000.0, 10 * q_lo)))
    if table is not None:
        reach = ocv.OFFSET_BOUND_SDS * ocv.offset_prior(table)[0]
        out["voff"] = (max(out["voff"][0], -reach), min(out["voff"][1], reach))
    return out


def priors_for(recs: list[Record],
               table: ecm.OcvTable | None = None) -> dict[str, tuple[float, float]]:  # fmt: skip
    """Weak Gaussian priors (mean, sd; internal coordinates) centred on each element's neutral
    value. They matter only where the data say nothing about a parameter — a hysteresis state at
    the start of a block held out, an efficiency without charge in the training blocks — and
    there they keep it neutral instead of letting the trust region wander to a bound.

    With a measured OCV ``table`` two are measured ones (issue 37): the offset at 0 with the
    table's own uncertainty (``ocv.offset_prior``: from its slow test's branches, else a C/20
    overpotential plus half a hysteresis loop), and the capacity at the slow test's, with its
    uncertainty (``ocv.capacity_prior``; none for a table given as is). Over the records the
    initial SOC, the capacity and the offset trade along a valley the OCV's curvature alone
    barely bends (issue 37's clean record: 0.1 µV of RMSE from offset 0 to 0.1 V), and one
    prior row (PRIOR_SCALE_V: a sample at 1 mV noise) decides where in it the fit lands; where
    the records do tell them apart the prior weighs like one sample against thousands."""
    imax = _stats(recs)["imax"]
    out = {n: (p.neutral, _by_current(p.prior_sd, p, imax)) for n, p in ecm.PARAMS.items()
           if p.prior_sd is not None}  # fmt: skip
    if table is not None:
        out["voff"] = (0.0, ocv.offset_prior(table)[0])
        cap = ocv.capacity_prior(table)
        if cap is not None:  # internal log10: sd of log10(Q) = sd(Q)/(Q ln 10)
            out["lq"] = (float(np.log10(cap[0])), cap[1] / (cap[0] * np.log(10.0)))
    return out


def _by_current(value: float, p, imax: float) -> float:
    """``value`` of parameter ``p`` at the records' largest current (``Param.scale``: "per_a"
    divides by it, "a" multiplies; otherwise the value stands)."""
    if p.scale == "per_a":
        return value / imax
    return value * imax if p.scale == "a" else value


@dataclass
class Structure:
    """Which parameters of a configuration are free (the cell's, shared by its records), their
    bounds, priors and OCV knots."""

    config: Config
    shared: tuple[str, ...]
    n_records: int
    lo: np.ndarray
    hi: np.ndarray
    prior: np.ndarray  # (nz, 2): mean, sd (inf: none)
    knots: Knots = field(default_factory=lambda: Knots(0.0, 0.2))
    soc0_rule: bool = True  # every record's SOC0 from its opening (ecm.soc0_rows), not given

    @property
    def effects(self) -> tuple[str, ...]:
        return self.config.effects

    @property
    def k(self) -> int:
        return len(self.shared)

    @property
    def shared_idx(self) -> np.ndarray:
        return np.array([IDX[n] for n in self.shared], dtype=int)

    def z_of(self, X: np.ndarray) -> np.ndarray:
        """The free vector of per-record internal rows ``X`` (R, NX)."""
        return np.array(np.atleast_2d(X)[0, self.shared_idx])

    def rows(self, z: np.ndarray, X0: np.ndarray) -> np.ndarray:
        """Per-record internal rows: ``X0`` with the free values of ``z`` written in."""
        X = np.array(X0, dtype=float)
        X[:, self.shared_idx] = z
        return X


def structure(recs: list[Record], config: Config, knots: Knots | None = None,
              fix_capacity: bool = False, fix_soc0: bool = False) -> Structure:  # fmt: skip
    """The free parameters of ``config`` on ``recs``: the cell's, shared by every record. No
    state of a record is fitted: its initial SOC is given (``fix_soc0``) or comes from the
    library's one rule (``ecm.soc0_rows``: from the record's opening, with the parameters being
    fitted), the rule that starts every prediction; its hysteresis state starts at 0
    (docs/gap-diagnosis.md, "Selection judged like prediction")."""
    names = config.names()
    shared = [n for n in names if not ecm.PARAMS[n].per_record]
    if fix_capacity:
        shared.remove("lq")
    b = bounds_for(recs, config.table)
    pr = priors_for(recs, config.table)
    lo = np.array([b[n][0] for n in shared])
    hi = np.array([b[n][1] for n in shared])
    prior = np.array([pr.get(n, (0.0, np.inf)) for n in shared])
    return Structure(config, tuple(shared), len(recs), lo, hi, prior,
                     knots or Knots(0.0, 0.2), not fix_soc0)  # fmt: skip


def complete(st: Structure, recs, X: np.ndarray) -> np.ndarray:
    """Rows ``X`` (one record each, or several rows of one record when ``recs`` has one) with
    the initial SOC set by the rule when the structure takes it from the rule."""
    X = np.array(X, dtype=float)
    if not st.soc0_rule:
        return X
    if len(recs) == 1 and X.ndim == 2:
        X[:, IDX["soc0"]] = ecm.soc0_rows(ecm.to_physical(X), recs[0], st.knots, st.config.table,
                                          load_ohm=st.config.load_ohm)  # fmt: skip
        return X
    for r, rec in enumerate(recs):
        X[r, IDX["soc0"]] = ecm.soc0_rows(ecm.to_physical(X[r]), rec, st.knots, st.config.table,
                                          load_ohm=st.config.load_ohm)[0]  # fmt: skip
    return X


# ----------------------------------------------------------------------------------------------
# fitting


@dataclass
class Fit:
    """A least-squares fit to records (the model layer's one result type); ``fitted.fit_model``'s
    also carries the fitted model and the records-alike training RMSE."""

    X: np.ndarray  # per-record internal rows (each record's initial state, by the rule, its own)
    cost_fit: float  # 0.5 · sum of squared residuals on the fitted samples (of the last fit)
    nfev: int
    model: FittedModel | None = None  # noqa: F821 - fitted.FittedModel: fitted imports this module
    train_rmse_mv: float | None = None
    checks: tuple[Check, ...] = ()  # the fit checks made (:func:`check_fit`), one per fit checked


def fit_indices(n: int, mask: np.ndarray | None, max_points: int) -> np.ndarray:
    """Samples fitted: those in ``mask``, thinned by a fixed stride to at most ``max_points``."""
    idx = np.arange(n) if mask is None else np.flatnonzero(mask)
    stride = int(np.ceil(idx.size / max(max_points, 1)))
    return idx[::stride] if stride > 1 else idx


def indices(recs: list[Record], masks, max_points: int) -> list[np.ndarray]:
    """Per record, the samples fitted: the point budget shared equally between the records (each
    record counts alike, whatever its length; :class:`Problem` weighs them so)."""
    masks = masks if masks is not None else [None] * len(recs)
    share = max(1, max_points // max(len(recs), 1))
    return [fit_indices(r.n, m, share) for r, m in zip(recs, masks, strict=True)]


def _fd_steps(z: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    h = 1e-6 * np.maximum(np.abs(z), 1e-2 * (hi - lo))
    return np.where(z + h > hi, -h, h)


class Problem:
    """Residuals and their forward-difference Jacobian for least_squares, one simulator pass per
    record per call."""

    def __init__(self, recs, st: Structure, X0: np.ndarray, idxs: list[np.ndarray]):
        self.recs, self.st, self.idxs = recs, st, idxs
        self.X0 = np.array(X0, dtype=float)
        self.vm = [r.v[i] for r, i in zip(recs, idxs, strict=True)]
        # each record's residuals scaled by √(n̄/n_r): every record's sum of squares enters
        # with one weight, whatever its length
        sizes = np.array([max(i.size, 1) for i in idxs], dtype=float)
        self.wr = np.sqrt(sizes.mean() / sizes)
        self.shape = "ocv_shape" in st.effects
        self._cache_z = None
        self._cache_v = None
        self.pj = np.flatnonzero(np.isfinite(st.prior[:, 1]))
        self.pmu = st.prior[self.pj, 0]
        self.pw = PRIOR_SCALE_V / st.prior[self.pj, 1]
        if self.shape:
            self.grid = np.linspace(st.knots.lo, st.knots.lo + st.knots.step * (N_KNOTS - 1), 41)
            self.w_mono = 10.0 * np.sqrt(sum(i.size for i in idxs))

    def _sim(self, r: int, X: np.ndarray) -> np.ndarray:
        c = self.st.config
        X = complete(self.st, [self.recs[r]], X)
        return ecm.simulate_rows(self.recs[r], X, self.st.knots, c.table, c.load_ohm,
                                 idx=self.idxs[r])  # fmt: skip

    def _penalty(self, x: np.ndarray) -> np.ndarray:
        # monotone OCV: a falling step between grid points costs as much as w_mono volts
        p = ecm.to_physical(x)[0]
        d = np.diff(ecm.ocv_values(p, self.grid, self.st.knots, self.st.config.table))
        return self.w_mono * np.minimum(d, 0.0)

    def residuals(self, z: np.ndarray) -> np.ndarray:
        X = self.st.rows(z, self.X0)
        v = [self._sim(r, X[r : r + 1])[:, 0] for r in range(len(self.recs))]
        self._cache_z, self._cache_v = z.copy(), v
        parts = [w * (vr - vm) for vr, vm, w in zip(v, self.vm, self.wr, strict=True)]
        if self.shape:
            parts.append(self._penalty(X[0]))
        if self.pj.size:
            parts.append(self.pw * (z[self.pj] - self.pmu))
        return np.concatenate(parts)

    def jacobian(self, z: np.ndarray) -> np.ndarray:
        st = self.st
        h = _fd_steps(z, st.lo, st.hi)
        X = st.rows(z, self.X0)
        ns = len(st.shared)
        cached = self._cache_z is not None and np.array_equal(z, self._cache_z)
        off = 0 if cached else 1
        blocks = []
        for r in range(len(self.recs)):
            rows = np.repeat(X[r : r + 1], ns + off, axis=0)
            rows[np.arange(ns) + off, st.shared_idx] += h
            V = self._sim(r, rows)
            v0 = self._cache_v[r] if cached else V[:, 0]
            blocks.append(self.wr[r] * (V[:, off:] - v0[:, None]) / h)
        if self.shape:
            p0 = self._penalty(X[0])
            Jp = np.zeros((p0.size, z.size))
            for j in range(ns):
                zj = z.copy()
                zj[j] += h[j]
                Jp[:, j] = (self._penalty(st.rows(zj, self.X0)[0]) - p0) / h[j]
            blocks.append(Jp)
        if self.pj.size:
            Jq = np.zeros((self.pj.size, z.size))
            Jq[np.arange(self.pj.size), self.pj] = self.pw
            blocks.append(Jq)
        return np.vstack(blocks)


def fit_structure(recs, st: Structure, X0: np.ndarray, idxs: list[np.ndarray],
                  max_nfev: int = 200, tol: float = 1e-8) -> Fit:  # fmt: skip
    """Least-squares fit of the free parameters of ``st`` from per-record rows ``X0``."""
    X0 = np.atleast_2d(np.asarray(X0, dtype=float))
    if X0.shape[0] == 1 and len(recs) > 1:
        X0 = np.repeat(X0, len(recs), axis=0)
    prob = Problem(recs, st, X0, idxs)
    span = st.hi - st.lo
    # strictly inside the box: trf needs an interior start
    z0 = np.clip(st.z_of(X0), st.lo + 1e-10 * span, st.hi - 1e-10 * span)
    res = least_squares(prob.residuals, z0, jac=prob.jacobian, bounds=(st.lo, st.hi),
                        method="trf", x_scale="jac", ftol=tol, xtol=tol, gtol=tol,
                        max_nfev=max_nfev)  # fmt: skip
    return Fit(complete(st, recs, st.rows(res.x, X0)), float(res.cost), int(res.nfev))


def best_of(recs, st: Structure, starts, masks=None, max_nfev_coarse=60, max_nfev=200,
            check: bool = True, taus=None) -> Fit:  # fmt: skip
    """Multi-start: each start on thinned records, the best refined on the fitted samples; then,
    with ``check``, the fit check (:func:`check_fit`; ``taus``: the time constants it restarts,
    None for every one)."""
    idx_full = indices(recs, masks, MAX_FIT_POINTS)
    if len(starts) == 1:
        fit = fit_structure(recs, st, starts[0], idx_full, max_nfev=max_nfev)
    else:
        idx_c = indices(recs, masks, COARSE_POINTS)
        trials = [fit_structure(recs, st, x0, idx_c, max_nfev=max_nfev_coarse) for x0 in starts]
        best = min(trials, key=lambda r: r.cost_fit)
        fit = fit_structure(recs, st, best.X, idx_full, max_nfev=max_nfev)
    return check_fit(recs, st, fit, masks, max_nfev_coarse, max_nfev, taus) if check else fit


# ----------------------------------------------------------------------------------------------
# the fit check (issue 37)

CHECK_ROUNDS = 3
"""Rounds of the fit check at most: each round restarts from the fit it has; a round whose best
restart lands no lower, or that removes less than one standard deviation of the cost (a gain the
noise of one record could undo), ends the check. Three bound the cost on a rough objective (a
flat OCV table: docs/gap-diagnosis.md "Fit check"), where each round finds a little more."""

CHECK_DIRECTIONS = 2
"""Least-constrained directions restarted along (both signs each): the two smallest singular
values of the scaled Jacobian. A stall between basins shows as a valley (a parameter trading
with another, or one the data barely see); two cover a valley and the next one, four fits."""

CHECK_STEP_SD = 1.0
"""Length of a step along a direction: the predicted (Gauss–Newton) rise of the cost equals this
many standard deviations of the cost itself, σ²·√(m/2) for m residuals of variance σ² (the
sum of m squared Gaussian residuals has variance 2mσ⁴). A rival optimum within that distance
could be hidden by the noise of one record: the check goes as far as the data cannot tell."""

CHECK_BOX_SHARE = 0.25
"""A step moves no parameter by more than a quarter of its searched range (internal
coordinates): along a direction the data barely constrain the predicted step is unbounded; a
quarter of the range is more than a decade of a time constant, far enough to leave a basin."""

TAU_STARTS_S = (10.0, 60.0, 300.0, 1500.0)
"""Time-constant starts (s), clipped to the records' bounds: a cycler's relaxations from the
first logged seconds of a pulse's response (10 s) to the diffusion of a half-hour rest (1500 s),
about a factor 5 apart, so any time constant lies within a factor of about 2.3 (half a step, in
log) of one start."""

TAU_NEAR_DECADES = 0.25
"""A time-constant restart within a quarter decade (a factor 1.8) of the fitted value is
skipped: it starts in the basin the fit already found."""

CHECK_RTOL = 1e-6
"""A restart counts as lower when its cost is below the fit's by more than this share: 100 times
the solver's tolerance (``fit_structure``'s 1e-8), so the solver's own scatter never triggers a
refinement."""


@dataclass
class Check:
    """What the fit check did to one fit: coarse restarts run, rounds whose refined restart
    replaced the fit, the fitted cost before and after, and the evaluations it spent."""

    restarts: int
    improved: int
    cost_before: float
    cost_after: float
    nfev: int

    @property
    def rss_gain(self) -> float:
        """The share of the fitted sum of squares the check removed (0: the fit stood)."""
        return 1.0 - self.cost_after / self.cost_before if self.cost_before > 0 else 0.0

    def report(self) -> dict:
        return {"restarts": self.restarts, "improved": self.improved, "rss_gain": self.rss_gain}

    def then(self, later: Check) -> Check:
        """This check followed by a ``later`` one on a fit that started from this one's result
        (restarts, improvements and evaluations added; the cost from before this to after
        that)."""
        return Check(self.restarts + later.restarts, self.improved + later.improved,
                     self.cost_before, later.cost_after, self.nfev + later.nfev)  # fmt: skip


def check_fit(recs, st: Structure, fit: Fit, masks=None, max_nfev_coarse=60,
              max_nfev=200, taus=None) -> Fit:  # fmt: skip
    """The fit check: is ``fit`` at its structure's optimum, or stalled short of it?

    Restarts from the fit perturbed along its least-constrained directions and from other time
    constants (:func:`restart_points`), each on the thinned records (``COARSE_POINTS``, as
    :func:`best_of`'s trials); the lowest, if below the fit's cost on the same samples, is
    refined on the fitted samples and replaces the fit if it ends lower; repeated while a round
    improves, at most ``CHECK_ROUNDS``. The fit returned is never worse than ``fit``, and
    carries the :class:`Check` in ``checks``.

    ``taus``: the time constants restarted at ``TAU_STARTS_S`` (parameter names; None: every one
    of the structure). A model nested in a checked one (an element removed, the rest at its
    checked optimum) restarts none; a model that adds an element restarts every one, the
    reference's included (only the element's own was tried first: thermal's fit-back case,
    seed 0, then ended at 4.26 mV against 0.99 mV of noise, since an element that changes how
    the others act moves their best time constants). The least-constrained directions are
    always restarted: they move every parameter at once.

    Cost: per round, one residual and one Jacobian on the fitted samples, 2·CHECK_DIRECTIONS
    coarse fits (≤ ``max_nfev_coarse`` evaluations each; in the first round also up to
    ``len(TAU_STARTS_S)`` per time constant), and one refinement on the fitted samples
    (≤ ``max_nfev``) only when a restart landed lower. Measured on the transfer benchmark's LFP
    record (1RC, a table; 5,715 samples): the first round (7 restarts) moved the fit from 7.2 to
    5.9 mV, a second (4) found nothing, 341 evaluations in all; a whole diagnosis took 2 to 6
    times the CPU time (docs/gap-diagnosis.md, "Fit check").
    """
    if st.k == 0:
        return fit
    idx_full = indices(recs, masks, MAX_FIT_POINTS)
    idx_c = indices(recs, masks, COARSE_POINTS)
    restarts = improved = nfev = 0
    best = fit
    for round_ in range(CHECK_ROUNDS):
        points, sd_cost = restart_points(recs, st, best.X, idx_full,
                                         taus=taus if round_ == 0 else ())  # fmt: skip
        nfev += 2  # the residual and the Jacobian at the fit
        trials = [fit_structure(recs, st, st.rows(z, best.X), idx_c, max_nfev=max_nfev_coarse)
                  for z in points]  # fmt: skip
        restarts += len(trials)
        nfev += sum(t.nfev for t in trials) + 1
        now = _cost(Problem(recs, st, best.X, idx_c), st.z_of(best.X))
        lowest = min(trials, key=lambda t: t.cost_fit, default=None)
        if lowest is None or not lowest.cost_fit < now * (1.0 - CHECK_RTOL):
            break
        new = fit_structure(recs, st, lowest.X, idx_full, max_nfev=max_nfev)
        nfev += new.nfev
        if not new.cost_fit < best.cost_fit * (1.0 - CHECK_RTOL):
            break
        gain = best.cost_fit - new.cost_fit
        best, improved = new, improved + 1
        if gain < sd_cost:
            break
    check = Check(restarts, improved, fit.cost_fit, best.cost_fit, nfev)
    return replace(best, nfev=fit.nfev + nfev, checks=(*fit.checks, check))


def _cost(prob: Problem, z: np.ndarray) -> float:
    r = prob.residuals(z)
    return 0.5 * float(r @ r)


def restart_points(recs, st: Structure, X: np.ndarray, idxs,
                   taus=None) -> tuple[list[np.ndarray], float]:  # fmt: skip
    """The fit check's restarts from fitted rows ``X`` (free vectors z): along the
    ``CHECK_DIRECTIONS`` least-constrained directions, both signs, and each time constant named
    in ``taus`` (None: every one) moved to each of ``TAU_STARTS_S`` not near its value; and the
    standard deviation
    of the cost at ``X``.

    The directions are the right singular vectors of the smallest singular values of the
    Jacobian at the fit, each column scaled by its norm as least_squares' ``x_scale='jac'``
    scales it (the scale the solver itself moved in); each step predicts a rise of the cost by
    ``CHECK_STEP_SD`` standard deviations of the cost, at most ``CHECK_BOX_SHARE`` of the
    range in any parameter, clipped to the bounds."""
    prob = Problem(recs, st, X, idxs)
    z = st.z_of(X)
    r = prob.residuals(z)
    J = prob.jacobian(z)
    norms = np.linalg.norm(J, axis=0)
    norms[norms == 0] = 1.0  # as least_squares' scaling: a column without effect keeps scale 1
    _, sv, vt = np.linalg.svd(J / norms, full_matrices=False)
    sd_cost = float(r @ r) / r.size * np.sqrt(r.size / 2.0)
    span = st.hi - st.lo
    out = []
    for k in range(1, min(CHECK_DIRECTIONS, sv.size) + 1):
        v = vt[-k] * np.sign(vt[-k][np.argmax(np.abs(vt[-k]))])  # one sign, whatever LAPACK's
        # Gauss–Newton: a step t along v raises the cost by ½ (s·t)²
        d = np.sqrt(2.0 * CHECK_STEP_SD * sd_cost) / max(sv[-k], 1e-300) * v / norms
        d *= min(1.0, CHECK_BOX_SHARE / max(float(np.max(np.abs(d) / span)), 1e-300))
        out += [np.clip(z + d, st.lo, st.hi), np.clip(z - d, st.lo, st.hi)]
    for j, name in enumerate(st.shared):
        if ecm.PARAMS[name].scale != "tau" or (taus is not None and name not in taus):
            continue
        for tau in TAU_STARTS_S:
            lt = float(np.clip(np.log10(tau), st.lo[j], st.hi[j]))
            if abs(lt - z[j]) > TAU_NEAR_DECADES:
                zt = z.copy()
                zt[j] = lt
                out.append(zt)
    return out, sd_cost


def knots_for(recs, X: np.ndarray, masks=None) -> Knots:
    """ocv_shape knots spread evenly over the SOC range the model visits on the (masked) records.

    Beyond the knots the correction stays flat: a model fitted without some SOC range does not
    extrapolate a polynomial into it.
    """
    lo, hi = np.inf, -np.inf
    masks = masks if masks is not None else [None] * len(recs)
    for r, (rec, m) in enumerate(zip(recs, masks, strict=True)):
        soc = X[r, IDX["soc0"]] - rec.charge_ah() / 10.0 ** X[r, IDX["lq"]]
        soc = np.clip(soc if m is None else soc[m], 0.0, 1.2)
        if soc.size:
            lo, hi = min(lo, float(soc.min())), max(hi, float(soc.max()))
    if hi - lo < 1e-3:
        lo, hi = lo - 5e-4, hi + 5e-4
    return Knots(lo, (hi - lo) / (N_KNOTS - 1))


# ----------------------------------------------------------------------------------------------
# starts


def r0_guess(recs) -> float:
    """R0 from the voltage jumps at large current steps (median −ΔV/ΔI)."""
    est = []
    for rec in recs:
        di, dv = np.diff(rec.i), np.diff(rec.v)
        big = np.abs(di) > 0.2 * rec.imax()
        e = -dv[big] / di[big]
        est.append(e[np.isfinite(e) & (e > 0)])
    est = np.concatenate(est) if est else np.empty(0)
    return float(np.clip(np.median(est), 1e-4, 1.0)) if est.size else 0.05


def base_starts(recs, config: Config, capacity_ah=None, soc0=None) -> list[np.ndarray]:
    """A handful of base-model starts (each (R, NX)) spread over capacity and SOC0 (without a
    table) or τ1 (with one)."""
    b = bounds_for(recs)
    swing = max(_stats(recs)["swing"], 1e-6)
    r0 = r0_guess(recs)
    if capacity_ah:
        caps = [capacity_ah]
    elif config.table is not None and config.table.capacity_ah:
        caps = [config.table.capacity_ah]  # the slow test measured it
    else:
        caps = [1.25 * swing, 3.0 * swing, 10.0 * swing]
    # with a table the capacity and the OCV are set, so the starts spread τ1 over the time
    # constants' starts (one start would leave best_of no choice); without, the six starts
    # over capacity and SOC0 take τ1 = 60 s and the fit check (check_fit) tries the others
    taus = TAU_STARTS_S if config.table is not None else (60.0,)
    starts = []
    for cap, tau in ((c, t) for c in caps for t in taus):
        cap = float(np.clip(cap, 10 ** b["lq"][0], 10 ** b["lq"][1]))
        x = NEUTRAL.copy()
        x[IDX["lq"]] = np.log10(cap)
        x[IDX["r0"]] = r0
        x[IDX["r1"]] = 0.5 * r0
        x[IDX["ltau1"]] = np.clip(np.log10(tau), *b["ltau1"])
        if config.table is not None:
            X = np.repeat(x[None, :], len(recs), axis=0)
            for r, rec in enumerate(recs):
                P = ecm.to_physical(X[r])[0]
                X[r, IDX["soc0"]] = (
                    soc0
                    if soc0 is not None
                    else ecm.soc0_from_voltage(P, rec, Knots(0, 0.2), config.table)
                )
            starts.append(X)
            continue
        fractions = (0.9, 0.4) if soc0 is None else (None,)
        for f in fractions:
            X = np.repeat(x[None, :], len(recs), axis=0)
            for r, rec in enumerate(recs):
                q = rec.charge_ah()
                s_hi = 1.0 + float(np.min(q)) / cap  # SOC0 such that SOC stays ≤ 1
                s_lo = float(np.max(q)) / cap  # ... and ≥ 0
                if soc0 is not None:
                    X[r, IDX["soc0"]] = soc0
                elif s_lo >= s_hi:
                    X[r, IDX["soc0"]] = float(np.clip(0.5 * (s_lo + s_hi), 0, 1))
                else:
                    X[r, IDX["soc0"]] = float(np.clip(s_lo + f * (s_hi - s_lo), 0.02, 1.0))
            X[:, IDX["vnom"]], X[:, IDX["lc"]] = _ocv_start(recs, X, cap, r0, b)
            starts.append(X)
    return starts


def _ocv_start(recs, X, cap, r0, b):
    """Vnom and log10(1−β) fitted to v + R0·i against the coulomb-counted SOC (no dynamics)."""
    s_all, y_all = [], []
    for r, rec in enumerate(recs):
        soc = np.clip(X[r, IDX["soc0"]] - rec.charge_ah() / cap, 0.0, 1.2)
        sel = slice(None, None, max(1, rec.n // 2000))
        s_all.append(soc[sel])
        y_all.append((rec.v + r0 * rec.i)[sel])
    s, y = np.concatenate(s_all), np.concatenate(y_all)

    def res(p):
        omb = 10.0 ** p[1]
        return p[0] * s / (omb + (1 - omb) * s) - y

    p0 = np.array([np.clip(np.max(y) + 0.05, *b["vnom"]), -1.0])
    r = least_squares(res, p0, bounds=([b["vnom"][0], b["lc"][0]], [b["vnom"][1], b["lc"][1]]))
    return r.x[0], r.x[1]


def effect_starts(recs, X_base: np.ndarray, effect: str) -> list[np.ndarray]:
    """Starts for one added element from fitted rows (their other parameters kept): the
    element's own starts (``Element.starts``), clipped to the records' bounds."""
    b = bounds_for(recs)
    row = dict(zip(ecm.NAMES, X_base[0], strict=True))
    out = []
    for start in elements.get(effect).starts(row, _stats(recs)["imax"]):
        X = np.array(X_base, dtype=float)
        for k, v in start.items():
            X[:, IDX[k]] = np.clip(v, *b[k])
        out.append(X)
    return out


def neutralise(X: np.ndarray, effects) -> np.ndarray:
    """Rows with the parameters of ``effects`` set back to neutral (the element removed)."""
    Y = np.array(X, dtype=float)
    for e in effects:
        for n in ecm.element_params(e):
            Y[:, IDX[n]] = NEUTRAL[IDX[n]]
    return Y
