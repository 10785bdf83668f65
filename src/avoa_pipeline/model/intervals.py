"""Parameter intervals of a fit, honest on autocorrelated residuals, and what they say of
identifiability.

Method: the Gauss–Newton covariance of the fitted parameters, s²·(JᵀJ)⁻¹ (J the Jacobian of the
weighted residuals the fit minimised, s² their variance per sample), inflated by the residuals'
integrated autocorrelation time τ: residuals of neighbouring samples are not independent (a model
miss lasts seconds to minutes, and a 1-s or 10-Hz log samples it many times), so n samples carry the
information of n/τ independent ones and every variance grows by τ (the effective-sample-size
correction of time-series regression). τ is estimated per record from its own residuals in time
order with Sokal's automatic window (the smallest window M with M ≥ 5·τ(M), as emcee does), and the
records' effective sizes add up.

Why this and not a library: lmfit's ``conf_interval`` profiles every parameter (a refit per point,
minutes on 10⁵ samples), pints' samplers likewise; numdifftools would rebuild the Jacobian our
fit already has in one compiled pass. Neither corrects for autocorrelated residuals, which is
what makes naive intervals on battery records 3-30 times too narrow. The check against brute force
(refits on independent noise, tests/unit/test_intervals.py) is what the issue asks for.

What is flagged:

- a parameter within ``fitting.AT_BOUND`` of its searched range from a bound: the bound set it, not
  the records; it is held fixed for the others' covariance and gets no interval;
- a pair whose correlation is beyond ±CORR_LIMIT: the records do not separate the two;
- a parameter whose interval covers more than half its searched range: not identified.

A parameter the fit held at a given value (the capacity of ``--capacity-ah``) is reported as
``held``, with no interval: the user set it, the records did not.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from . import ecm, fitting
from .ecm import IDX

Z95 = 1.959963984540054
"""Two-sided 95 % point of a normal: the intervals are 95 % ones."""
CORR_LIMIT = 0.99
"""Two parameters correlated beyond ±0.99 are not separately identified: the records determine a
combination of them (their 95 % joint region is a needle along one direction, at least 7 times
longer than the narrower of the two marginal intervals would suggest)."""
UNIDENTIFIED_SHARE = 0.5
"""A 95 % interval wider than half the searched range: the records hardly constrain the
parameter (the fit's answer there is its start or its prior)."""


def correlation(cov: np.ndarray, sd: np.ndarray) -> np.ndarray:
    """The correlation matrix of a covariance ``cov`` with standard deviations ``sd`` (nan where
    one is not finite), clipped to ±1: a pair the records do not separate rounds to |ρ| a few
    1e-7 above 1 (the covariance's own rounding), which no reader of a correlation accepts
    (model.json's schema: within ±1; an LFP HPPC record's fit gave -1.0000003)."""
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(np.isfinite(sd)[:, None] & np.isfinite(sd),
                        np.clip(cov / np.outer(sd, sd), -1.0, 1.0), np.nan)  # fmt: skip


def autocorrelation(e: np.ndarray) -> np.ndarray:
    """The residuals' autocorrelation ρ_0..ρ_M (ρ_0 = 1) up to Sokal's automatic window M (the
    smallest with M ≥ 5·τ(M), as emcee does): beyond it the estimate is noise."""
    e = np.asarray(e, dtype=float)
    n = e.size
    if n < 8:
        return np.ones(1)
    # each array let go once read (issue 42, a long record's residual: the centred copy, the
    # spectrum and the doubled transform no longer live beside the later ones); the same
    # operations, so the same bits (not squared in place: numpy's in-place complex product
    # rounds differently)
    f = np.fft.rfft(e - e.mean(), n=2 * n)
    acf = np.fft.irfft(f * np.conjugate(f))
    del f
    if not acf[0] > 0:
        return np.ones(1)
    rho = acf[:n] / acf[0]
    del acf
    taus = 2.0 * np.cumsum(rho) - 1.0
    window = np.arange(n) >= 5.0 * taus
    m = int(np.argmax(window)) if window.any() else n - 1
    return rho[: m + 1]


def autocorrelation_time(e: np.ndarray) -> float:
    """Integrated autocorrelation time of a residual series, 1 + 2 Σ ρ_k over Sokal's window
    (at least 1)."""
    return _time_of(autocorrelation(e))


def _time_of(rho: np.ndarray) -> float:
    return float(max(2.0 * rho.sum() - 1.0, 1.0))


def mean_variance_factor(rho: np.ndarray, m: int) -> float:
    """Var(mean of m neighbouring residuals) ÷ (σ²/m): 1 + 2 Σ_{k<m} (1 − k/m) ρ_k, clipped to
    [1, m] (never better than independent, never worse than one sample)."""
    k = np.arange(1, min(m, rho.size))
    f = 1.0 + 2.0 * float(np.sum((1.0 - k / m) * rho[k]))
    return float(min(max(f, 1.0), m))


@dataclass(frozen=True)
class Intervals:
    """The covariance of a fit's free parameters (internal coordinates) and what it says."""

    names: tuple[str, ...]  # internal names of the free parameters
    value: np.ndarray  # internal values
    lo: np.ndarray  # the searched bounds (internal)
    hi: np.ndarray
    sd: np.ndarray  # standard deviations (internal); nan at a bound
    corr: np.ndarray  # correlations (nan rows at a bound)
    n: int  # residuals used
    n_eff: float  # their effective number
    s_v: float  # residual SD per sample (V)
    held: tuple[tuple[str, float], ...] = ()  # the cell's parameters the fit held (name, value)

    @property
    def at_bound(self) -> np.ndarray:
        return fitting.at_bound(self.value, self.lo, self.hi)

    def bounds95(self) -> tuple[np.ndarray, np.ndarray]:
        """The 95 % intervals (internal), inside the searched bounds."""
        half = np.where(np.isnan(self.sd), np.inf, Z95 * self.sd)  # no estimate: unconstrained
        return np.maximum(self.value - half, self.lo), np.minimum(self.value + half, self.hi)

    def excludes(self, name: str, neutral: float) -> bool:
        """The 95 % interval of ``name`` lies off ``neutral`` (an element's 'does nothing' value)
        and the parameter is not at a bound."""
        k = self.names.index(name)
        if self.at_bound[k] or not np.isfinite(self.sd[k]):
            return False
        a, b = self.bounds95()
        return not a[k] <= neutral <= b[k]

    def pairs(self) -> list[tuple[str, str, float]]:
        """Pairs correlated beyond ±CORR_LIMIT."""
        out = []
        for i in range(len(self.names)):
            for j in range(i + 1, len(self.names)):
                c = self.corr[i, j]
                if np.isfinite(c) and abs(c) >= CORR_LIMIT:
                    out.append((self.names[i], self.names[j], float(c)))
        return out

    def report(self) -> dict:
        """Report-named intervals (physical units) and flags, for model.json and diagnosis.json."""
        a, b = self.bounds95()
        params = {}
        for k, n in enumerate(self.names):
            ends = sorted(_physical(n, z) for z in (a[k], b[k]))
            bound = bool(self.at_bound[k])
            params[ecm.PARAMS[n].report] = {
                "value": _physical(n, self.value[k]),
                "low95": None if bound else ends[0],
                "high95": None if bound else ends[1],
                "at_bound": bound,
                "identified": not bound and identified(b[k] - a[k], self.lo[k], self.hi[k]),
                "held": False,
            }
        for n, z in self.held:  # given, not fitted (a capacity from --capacity-ah): no interval
            params[ecm.PARAMS[n].report] = {"value": _physical(n, z), "low95": None,
                                            "high95": None, "at_bound": False,
                                            "identified": False, "held": True}  # fmt: skip
        pairs = [
            {"a": ecm.PARAMS[x].report, "b": ecm.PARAMS[y].report, "correlation": c}
            for x, y, c in self.pairs()
        ]
        return {
            "method": "Gauss-Newton covariance × the residuals' integrated autocorrelation time",
            "level": LEVEL,
            "samples": self.n,
            "effective_samples": self.n_eff,
            "residual_sd_mv": 1e3 * self.s_v,
            "parameters": params,
            "correlated_pairs": pairs,
            "flags": flags(params, pairs),
        }


LEVEL = 0.95
"""The intervals' confidence level (``Z95``)."""


def identified(width: float, lo: float, hi: float) -> bool:
    """A 95 % interval of ``width`` (internal coordinates) in the searched range [lo, hi]
    identifies its parameter: at most UNIDENTIFIED_SHARE of the range (an unconstrained one spans
    all of it)."""
    return bool(np.isfinite(width) and width <= UNIDENTIFIED_SHARE * (hi - lo))


def flags(params: dict, pairs: list[dict]) -> list[str]:
    """The warning lines of a report's entries and pairs (one per flagged parameter or pair):
    written into the report for readers, and recomputed from the entries when a model.json is
    read (``model/fitted.py``)."""
    out = []
    for rep, e in params.items():
        if e["at_bound"]:
            out.append(f"{rep} at a bound of its fit")
        elif not (e["identified"] or e["held"]):
            out.append(f"{rep} not identified (its 95 % interval spans over half its range)")
    return out + [f"{p['a']} and {p['b']} not separately identified (correlation "
                  f"{p['correlation']:+.3f})" for p in pairs]  # fmt: skip


def _physical(name: str, z: float) -> float:
    return ecm.report(np.where(np.arange(ecm.NX) == IDX[name], z, ecm.NEUTRAL), [name])[
        ecm.PARAMS[name].report
    ]


def of_fit(recs, st: fitting.Structure, X: np.ndarray, masks=None) -> Intervals:
    """The intervals of the free parameters of ``st`` fitted as rows ``X`` to ``recs``, from the
    samples the fit used (``masks``: those of each record, default all; thinned as the fit
    thins them).

    The covariance is the sandwich A⁻¹BA⁻¹ of the records' weighted residuals e and Jacobian J
    (A = JᵀJ; the weak priors left out, so a parameter only they hold gets no interval): B is
    the Newey–West estimate of the residuals' long-run covariance with the Jacobian, per record,
    Σ_k w_k Σ_t (J_t e_t)(J_{t−k} e_{t−k})ᵀ with Bartlett weights over HAC_LAGS autocorrelation
    times of the record's residuals, which weighs each parameter's own sensitivity pattern
    against the correlation (a constant-like sensitivity gets the full n/τ penalty, a quickly
    changing one less). Plus the opening rule's share (:func:`_opening_cov`). A direction the
    records do not constrain gets an infinite variance for every parameter in it."""
    X = np.atleast_2d(np.asarray(X, dtype=float))
    idxs = fitting.indices(recs, masks, fitting.MAX_FIT_POINTS)
    prob = fitting.Problem(recs, st, X, idxs)
    z = st.z_of(X)
    res = prob.residuals(z)
    J = prob.jacobian(z)
    p = z.size
    n = int(sum(i.size for i in idxs))
    free = ~fitting.at_bound(z, st.lo, st.hi)
    Jd, ed = J[:n][:, free], res[:n]
    A_pinv, touched = _pinv(Jd.T @ Jd)
    B = np.zeros_like(A_pinv)
    n_eff, ss, off = 0.0, 0.0, 0
    taus = []
    for i in idxs:
        e, Jr = ed[off : off + i.size], Jd[off : off + i.size]
        off += i.size
        rho = autocorrelation(e)
        tau = _time_of(rho)
        taus.append(rho)
        B += _long_run(Jr * e[:, None], int(np.ceil(HAC_LAGS * tau)))
        n_eff, ss = n_eff + i.size / tau, ss + float(np.sum(e**2))
    sd = np.full(p, np.nan)
    corr = np.full((p, p), np.nan)
    if free.any():
        cov = A_pinv @ B @ A_pinv
        if st.soc0_rule:
            cov = cov + _opening_cov(recs, st, X, idxs, prob, res, Jd, A_pinv, taus)
        cov[touched, :] = np.inf
        cov[:, touched] = np.inf
        d = np.sqrt(np.clip(np.diag(cov), 0.0, None))
        sd[free] = d
        corr[np.ix_(free, free)] = correlation(cov, d)
    s_v = float(np.sqrt(ss / max(n, 1)))  # weighted: records alike, as the fit counts them
    held = tuple((m, float(X[0, IDX[m]])) for m in st.config.names()
                 if not ecm.PARAMS[m].per_record and m not in st.shared)  # fmt: skip
    return Intervals(st.shared, z, st.lo.copy(), st.hi.copy(), sd, corr, n, n_eff, s_v, held)


HAC_LAGS = 10.0
"""Newey–West bandwidth in autocorrelation times of the residuals: Bartlett weights (1 − k/(L+1))
bias the long-run variance low by about τ/L (an AR(1) with τ = 19: 5 % at L = 10τ), and the
estimate's own noise grows with √(L/n); ten times τ keeps the first small while L stays far
below n for any record worth fitting."""


def _long_run(U: np.ndarray, lags: int) -> np.ndarray:
    """Σ_{|k|≤L} (1 − |k|/(L+1)) Σ_t U_t U_{t−k}ᵀ (Newey–West), by FFT over the rows of U."""
    n, p = U.shape
    if n == 0:
        return np.zeros((p, p))
    lags = int(min(max(lags, 0), n - 1))
    m = 1 << int(np.ceil(np.log2(2 * n)))
    F = np.fft.rfft(U, n=m, axis=0)
    # cross-correlations C_ab(k) = Σ_t U_a(t+k) U_b(t) for k = 0..lags, one a at a time: all at
    # once the spectra and their transforms were two (m, p, p) arrays, 40-80 MB each on a fit's
    # 20,000 points, twice over when two threads check fits (issue 42: the peak of a long
    # record's diagnosis); each line is transformed alone either way, so the bits are the same
    C = np.empty((lags + 1, p, p))
    conj = np.conjugate(F)
    for a in range(p):
        C[:, a, :] = np.fft.irfft(F[:, a, None] * conj, n=m, axis=0)[: lags + 1]
    w = 1.0 - np.arange(lags + 1) / (lags + 1.0)
    S = np.tensordot(w[1:], C[1:], axes=1) if lags > 0 else np.zeros((p, p))
    return C[0] + S + S.T


OPENING_STEP_V = 1e-4
"""Finite-difference step of the opening voltage (0.1 mV, a cycler's voltage resolution): the
initial SOC moves by about 1e-4 of its range, far inside the linear range of the OCV."""


def _opening_cov(recs, st, X, idxs, prob, res, Jd, A_pinv, taus) -> np.ndarray:
    """The variance the opening rule adds: each record starts at the SOC its opening voltage
    (the mean over ``ecm.OPENING_WINDOW_S``) gives, and that mean carries the logger's noise,
    which moves every later residual of the record at once and the fitted parameters with it
    (dz = −A⁻¹Jᵀg·δV, g the residuals' change per volt of opening voltage). Its variance is the
    residual variance over the window's effective samples (:func:`mean_variance_factor`)."""
    out = np.zeros_like(A_pinv)
    z = st.z_of(X)
    off = 0
    for r, (rec, i, w, rho) in enumerate(zip(recs, idxs, prob.wr, taus, strict=True)):
        e = res[off : off + i.size] / w
        off += i.size
        n_w = max(ecm.opening(rec.t, rec.i, rec.v)[2], 1)
        var_open = float(np.mean(e**2)) * mean_variance_factor(rho, n_w) / n_w
        shifted = [replace(x, v_open=x.v_open + OPENING_STEP_V) if k == r else x
                   for k, x in enumerate(recs)]  # fmt: skip
        g = (fitting.Problem(shifted, st, X, idxs).residuals(z) - res) / OPENING_STEP_V
        G = A_pinv @ (Jd.T @ g[: Jd.shape[0]])
        out += var_open * np.outer(G, G)
    return out


NULL_EIGEN = 1e-12
"""Eigenvalues of the scaled Gauss–Newton matrix (unit diagonal) below this are directions nothing
constrains (the round-off of a double in a matrix of sums of squares is about 1e-16 of its
largest entry; 1e-12 leaves room for the finite-difference Jacobian's error): a correlation of
1 − 1e-12 between two parameters."""


def _pinv(A: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The inverse of a Gauss–Newton matrix on the directions the records constrain, and which
    parameters lie in a direction they do not. Judged on the matrix scaled to unit diagonal
    (parameters in ohms, seconds and decades are not comparable otherwise): eigenvalues below
    NULL_EIGEN are unconstrained directions, and a parameter whose unit vector has more than
    NULL_WEIGHT of its length in them is not identified."""
    d = np.sqrt(np.clip(np.diag(A), 0.0, None))
    zero = d <= 0
    d = np.where(zero, 1.0, d)
    As = A / np.outer(d, d)
    lam, vec = np.linalg.eigh(0.5 * (As + As.T))
    null = lam <= NULL_EIGEN * max(float(lam.max()) if lam.size else 0.0, 0.0)
    inv = np.where(null, 0.0, 1.0 / np.where(null, 1.0, lam))
    touched = zero | (np.sum(vec[:, null] ** 2, axis=1) > NULL_WEIGHT**2)
    return ((vec * inv) @ vec.T) / np.outer(d, d), touched


NULL_WEIGHT = 1e-3
"""A parameter with more than 0.1 % of its (scaled) unit vector in an unconstrained direction is
not identified: along that direction it moves a thousandth of its own scale for every unit the
others move, with nothing to stop it; below that, the eigenvectors' own round-off."""
