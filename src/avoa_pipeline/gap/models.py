"""Candidate cell models for the gap diagnosis: the paper's model and its augmentations.

The base model is the paper's (eqs. 3-6), with the rational OCV of ``model/battery.py`` written
with β as a parameter instead of through Vdis (the two are the same curve; the diagnosis knows no
Qdis of an unknown cell), a free capacity and a free initial SOC. Each effect of
:data:`avoa_pipeline.gap.EFFECTS` adds its own parameters; at its *neutral* values the augmented
model is the base model exactly, so every candidate nests the base and the ladder can stack them.

Per sample k (current i positive = discharge, Δt_k = t[k+1] − t[k], zero-order hold):

    i_k     = i_meas,k + b                                       current_offset (b)
    OCV(s)  = Vnom·s / (1 − β(1 − s)) + Σ_j d_j·φ_j(s)            ocv_shape: hat functions φ_j on
                                                                  K knots over the visited SOC
    f0_k    = exp(θ0 (1/T_k − 1/Tref)),  f1_k likewise with θ1   thermal (Arrhenius, T in K)
    V_k     = OCV(s_k) − M·h_k − f0_k·R0·i_k − v1_k − v2_k       hysteresis M,
              − (2RT_k/F)·asinh(g·i_k/2) + c                     Butler–Volmer g = 1/i0, offset c
    v1_k+1  = a1·v1_k + f1_k·R1(1 − a1)·i_k,  a1 = exp(−Δt/τ1)    eq. 3 (v2: second_rc, R2, τ2)
    ie_k    = i_k if i_k > 0 else η·i_k                          coulombic_efficiency η (charge)
    h_k+1   = e_k·h_k + (1 − e_k)·sign(i_k),  e_k = exp(−|ie_k·γ·Δt/(3600 Q)|)
                                                                  Plett's one-state hysteresis
    s_k+1   = s_k − ie_k·Δt/(3600 Q)                              eq. 6

Neutral values: b = 0, d = 0, θ0 = θ1 = 0, M = 0, g = 0, c = 0, R2 = 0, η = 1.

Why hand-written numerics: the recursion is sequential in time (as in ``model/kernel.py``), so it
is compiled with numba; one call steps a whole set of parameter rows together (time outer, rows
inner) so that a finite-difference Jacobian costs one pass over the record. Fitting is scipy's
``least_squares`` (trust-region reflective, box bounds) on that Jacobian.

Optimisation runs in internal coordinates: log10 for capacity, time constants and the hysteresis
rate, and log10(1 − β) for the OCV curvature (β → 1 flattens the curve; its natural scale is
logarithmic). :func:`Fitted.params` reports physical values.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numba as nb
import numpy as np
import pandas as pd
from scipy.optimize import brentq, least_squares

from . import EFFECTS

FARADAY = 96485.33212
GAS_R = 8.314462618
T_DEFAULT_K = 298.15
N_KNOTS = 6  # ocv_shape: knots over the visited SOC range (5 segments)

# internal parameter layout (one full vector per model; absent effects sit at neutral values)
_NAMES = (
    "vnom", "lc", "lq", "soc0", "r0", "r1", "ltau1", "r2", "ltau2",
    "hm", "lgamma", "h0", "bvg", "th0", "th1", "ioff", "voff", "eta",
)  # fmt: skip
IDX = {n: k for k, n in enumerate(_NAMES)}
D0 = len(_NAMES)
KNOT_NAMES = tuple(f"d{j}" for j in range(N_KNOTS))  # correction at the knots (derived)
SHAPE_NAMES = tuple(f"u{j}" for j in range(N_KNOTS - 2))  # its free coordinates
U0 = D0 + N_KNOTS
NFULL = U0 + len(SHAPE_NAMES)
for _j, _n in enumerate(KNOT_NAMES):
    IDX[_n] = D0 + _j
for _j, _n in enumerate(SHAPE_NAMES):
    IDX[_n] = U0 + _j


def _shape_basis() -> np.ndarray:
    """(N_KNOTS, N_KNOTS − 2): knot corrections orthogonal to a constant and a linear trend.

    A constant or a tilt of the OCV is already in the base model's reach (Vnom, β, capacity,
    SOC0); leaving them out of the correction keeps the fit well posed, and keeps ocv_shape
    from mimicking a voltage offset. Columns: discrete orthogonal polynomials of degree 2..5,
    scaled to a largest entry of 1 (so u is in volts).
    """
    x = np.linspace(-1.0, 1.0, N_KNOTS)
    q, _ = np.linalg.qr(np.vander(x, N_KNOTS, increasing=True))
    b = q[:, 2:]
    return b / np.abs(b).max(axis=0)


SHAPE_BASIS = _shape_basis()

BASE_PARAMS = ("vnom", "lc", "lq", "soc0", "r0", "r1", "ltau1")
EFFECT_PARAMS = {
    "second_rc": ("r2", "ltau2"),
    "hysteresis": ("hm", "lgamma", "h0"),
    "butler_volmer": ("bvg",),
    "thermal": ("th0", "th1"),
    "ocv_shape": SHAPE_NAMES,
    "current_offset": ("ioff",),
    "voltage_offset": ("voff",),
    "coulombic_efficiency": ("eta",),
}
assert set(EFFECT_PARAMS) == set(EFFECTS)

NEUTRAL = np.zeros(NFULL)
NEUTRAL[IDX["eta"]] = 1.0
NEUTRAL[IDX["ltau2"]] = 1.0  # irrelevant while R2 = 0
NEUTRAL[IDX["lgamma"]] = 2.0  # irrelevant while M = 0

# physical names in reports: internal name -> (report name, to-physical)
_REPORT = {
    "vnom": ("vnom_v", lambda x: x),
    "lc": ("beta", lambda x: 1.0 - 10.0**x),
    "lq": ("capacity_ah", lambda x: 10.0**x),
    "soc0": ("soc0", lambda x: x),
    "r0": ("r0_ohm", lambda x: x),
    "r1": ("r1_ohm", lambda x: x),
    "ltau1": ("tau1_s", lambda x: 10.0**x),
    "r2": ("r2_ohm", lambda x: x),
    "ltau2": ("tau2_s", lambda x: 10.0**x),
    "hm": ("hysteresis_m_v", lambda x: x),
    "lgamma": ("hysteresis_gamma", lambda x: 10.0**x),
    "h0": ("hysteresis_h0", lambda x: x),
    "bvg": ("bv_inv_i0_per_a", lambda x: x),
    "th0": ("thermal_theta_r0_k", lambda x: x),
    "th1": ("thermal_theta_rc_k", lambda x: x),
    "ioff": ("current_offset_a", lambda x: x),
    "voff": ("voltage_offset_v", lambda x: x),
    "eta": ("coulombic_efficiency", lambda x: x),
    **{n: (f"ocv_{n}_v", lambda x: x) for n in KNOT_NAMES},
    **{n: (f"ocv_shape_{n}_v", lambda x: x) for n in SHAPE_NAMES},
}


_INVERSE = {
    "beta": ("lc", lambda v: np.log10(1.0 - v)),
    "capacity_ah": ("lq", np.log10),
    "tau1_s": ("ltau1", np.log10),
    "tau2_s": ("ltau2", np.log10),
    "hysteresis_gamma": ("lgamma", np.log10),
}


def vector(params: dict) -> np.ndarray:
    """Internal full vector from report-named parameters (absent ones neutral)."""
    by_report = {rep: name for name, (rep, _) in _REPORT.items()}
    x = NEUTRAL.copy()
    for key, value in params.items():
        if key in _INVERSE:
            name, fn = _INVERSE[key]
            x[IDX[name]] = fn(float(value))
        elif key in by_report and by_report[key] not in KNOT_NAMES:
            x[IDX[by_report[key]]] = float(value)
        elif key not in ("tref_k",) and not key.startswith(("ocv_knot", "ocv_d")):
            raise KeyError(f"unknown parameter {key!r}")
    return x


def simulate_params(frame: pd.DataFrame, params: dict, knots: Knots | None = None) -> np.ndarray:
    """Terminal voltage of ``frame``'s current under report-named ``params`` (tests, benchmarks).

    ``knots``: where the ocv_shape correction lives (default SOC 0-1).
    """
    rec = Record.from_frame(frame, tref_k=params.get("tref_k"))
    return simulate_rows(rec, vector(params)[None, :], knots or Knots(0.0, 0.2))[:, 0]


# ----------------------------------------------------------------------------------------------
# compiled simulation


@nb.njit(cache=True, nogil=True)
def _simulate(P, nk, cur, dt, uniform, dinv_t, two_rt_f, s_lo, ds, sel, out, tr):
    """Terminal voltage of every row of ``P`` (internal layout) at the selected samples.

    ``sel[k]``: the row of ``out`` (n_selected, m) that sample k goes to, or −1. ``tr`` (4, n)
    records SOC, h, v1 + v2 and the thermal R0 factor of row 0 when non-empty.
    An effect whose parameter is neutral in every row is skipped (the flags below do not change
    within the loops, so the compiler can take the branches out of them).
    """
    m = P.shape[0]
    n = cur.shape[0]
    record = tr.shape[0] > 0
    vnom = P[:, 0].copy()
    omb = 10.0 ** P[:, 1]
    beta = 1.0 - omb
    q3600 = 3600.0 * 10.0 ** P[:, 2]
    soc = P[:, 3].copy()
    r0 = P[:, 4].copy()
    r1 = P[:, 5].copy()
    tau1 = 10.0 ** P[:, 6]
    r2 = P[:, 7].copy()
    tau2 = 10.0 ** P[:, 8]
    hm = P[:, 9].copy()
    gam = 10.0 ** P[:, 10]
    h = P[:, 11].copy()
    bvg = P[:, 12].copy()
    th0 = P[:, 13].copy()
    th1 = P[:, 14].copy()
    ioff = P[:, 15].copy()
    voff = P[:, 16].copy()
    eta = P[:, 17].copy()
    d = P[:, D0 : D0 + nk].copy()
    a1 = np.exp(-dt[0] / tau1)
    a2 = np.exp(-dt[0] / tau2)
    v1 = np.zeros(m)
    v2 = np.zeros(m)
    hyst = np.any(hm != 0.0)
    therm0 = np.any(th0 != 0.0)
    therm1 = np.any(th1 != 0.0)
    bv = np.any(bvg != 0.0)
    shape = np.any(d != 0.0)
    rc2 = np.any(r2 != 0.0)
    for k in range(n):
        dtk = dt[k]
        ik0 = cur[k]
        dinv = dinv_t[k]
        rtf = two_rt_f[k]
        row = sel[k]
        if not uniform:
            for c in range(m):
                a1[c] = np.exp(-dtk / tau1[c])
                a2[c] = np.exp(-dtk / tau2[c])
        for c in range(m):
            i = ik0 + ioff[c]
            s = soc[c]
            sc = min(max(s, 0.0), 1.2)  # the rational curve is singular outside
            v = vnom[c] * sc / (omb[c] + beta[c] * sc) - v1[c] - v2[c] + voff[c]
            if shape:
                x = (sc - s_lo) / ds
                if x <= 0.0:
                    v += d[c, 0]
                elif x >= nk - 1:
                    v += d[c, nk - 1]
                else:
                    j = int(x)
                    w = x - j
                    v += (1.0 - w) * d[c, j] + w * d[c, j + 1]
            f0 = np.exp(th0[c] * dinv) if therm0 else 1.0
            f1 = np.exp(th1[c] * dinv) if therm1 else 1.0
            v -= f0 * r0[c] * i
            if hyst:
                v -= hm[c] * h[c]
            if bv:
                v -= rtf * np.arcsinh(0.5 * bvg[c] * i)
            if row >= 0:
                out[row, c] = v
            if record and c == 0:
                tr[0, k] = s
                tr[1, k] = h[c]
                tr[2, k] = v1[c] + v2[c]
                tr[3, k] = f0
            v1[c] = a1[c] * v1[c] + f1 * r1[c] * (1.0 - a1[c]) * i
            if rc2:
                v2[c] = a2[c] * v2[c] + f1 * r2[c] * (1.0 - a2[c]) * i
            ie = i if i > 0.0 else eta[c] * i
            dq = ie * dtk / q3600[c]
            if hyst and i != 0.0:
                e = np.exp(-abs(dq * gam[c]))
                h[c] = e * h[c] + (1.0 - e) * (1.0 if i > 0.0 else -1.0)
            soc[c] = s - dq


# ----------------------------------------------------------------------------------------------
# records


@dataclass(frozen=True)
class Record:
    """The inputs a simulation needs, prepared once per record."""

    t: np.ndarray
    i: np.ndarray
    v: np.ndarray
    temp_c: np.ndarray | None
    dt: np.ndarray  # dt[k] = t[k+1] - t[k]; the last is the median step (never used by V)
    uniform: bool
    tref_k: float
    dinv_t: np.ndarray
    two_rt_f: np.ndarray

    @property
    def n(self) -> int:
        return self.t.size

    @property
    def temperature_varies(self) -> bool:
        return self.temp_c is not None and float(np.ptp(self.temp_c)) >= THERMAL_MIN_RANGE_C

    @classmethod
    def from_frame(cls, frame: pd.DataFrame, tref_k: float | None = None) -> Record:
        t = np.ascontiguousarray(frame["time_s"].to_numpy(dtype=float))
        i = np.ascontiguousarray(frame["current_a"].to_numpy(dtype=float))
        v = np.ascontiguousarray(frame["voltage_v"].to_numpy(dtype=float))
        temp = None
        if "temperature_c" in frame.columns:
            temp = np.ascontiguousarray(frame["temperature_c"].to_numpy(dtype=float))
        d = np.diff(t)
        step = float(np.median(d)) if d.size else 1.0
        dt = np.append(d, step)
        uniform = bool(np.all(np.abs(d - step) <= 1e-9 * max(step, 1.0)))
        if uniform:
            dt = np.full(t.size, step)
        tk = np.full(t.size, T_DEFAULT_K) if temp is None else temp + 273.15
        if tref_k is None:
            tref_k = float(np.mean(tk))
        return cls(
            t=t,
            i=i,
            v=v,
            temp_c=temp,
            dt=np.ascontiguousarray(dt),
            uniform=uniform,
            tref_k=float(tref_k),
            dinv_t=np.ascontiguousarray(1.0 / tk - 1.0 / tref_k),
            two_rt_f=np.ascontiguousarray(2.0 * GAS_R * tk / FARADAY),
        )

    def charge_ah(self) -> np.ndarray:
        """Charge removed since the start (Ah) at each sample (discharge positive)."""
        q = np.concatenate([[0.0], np.cumsum(self.i[:-1] * self.dt[:-1])]) / 3600.0
        return q

    def imax(self) -> float:
        return max(float(np.quantile(np.abs(self.i), 0.99)), 1e-6)


THERMAL_MIN_RANGE_C = 2.0
"""The thermal candidate needs the measured temperature to move at least this much (°C): with
less, an Arrhenius factor is a constant that R0 and R1 already absorb."""


@dataclass(frozen=True)
class Knots:
    lo: float
    step: float

    def grid(self) -> np.ndarray:
        return self.lo + self.step * np.arange(N_KNOTS)


def simulate_rows(
    rec: Record, P: np.ndarray, knots: Knots, traces: bool = False, idx: np.ndarray | None = None
):
    """Voltage (n, m) of parameter rows ``P`` (m, NFULL); with traces, also (4, n) of row 0.

    ``idx``: return only these samples (sorted), shape (idx.size, m); the whole record is
    simulated all the same.
    """
    P = np.array(np.atleast_2d(P), dtype=float)  # a copy: the knot columns are derived here
    P[:, D0:U0] = P[:, U0:] @ SHAPE_BASIS.T
    if idx is None:
        sel = np.arange(rec.n)
    else:
        sel = np.full(rec.n, -1)
        sel[idx] = np.arange(idx.size)
    out = np.empty((rec.n if idx is None else idx.size, P.shape[0]))
    tr = np.empty((4, rec.n)) if traces else np.empty((0, 0))
    _simulate(
        P, N_KNOTS, rec.i, rec.dt, rec.uniform, rec.dinv_t, rec.two_rt_f, knots.lo, knots.step,
        sel, out, tr,
    )  # fmt: skip
    return (out, tr) if traces else out


def ocv(x: np.ndarray, soc: np.ndarray, knots: Knots) -> np.ndarray:
    """The OCV curve (rational + ocv_shape correction + voltage offset) of internal vector x."""
    sc = np.clip(np.asarray(soc, dtype=float), 0.0, 1.2)
    omb = 10.0 ** x[IDX["lc"]]
    v = x[IDX["vnom"]] * sc / (omb + (1.0 - omb) * sc)
    d = SHAPE_BASIS @ x[U0:]
    if np.any(d != 0.0):
        v = v + np.interp(sc, knots.grid(), d)
    return v + x[IDX["voff"]]


# ----------------------------------------------------------------------------------------------
# structure: which parameters are free, their bounds and starts


@dataclass
class Structure:
    effects: tuple[str, ...]
    free: tuple[str, ...]
    lo: np.ndarray
    hi: np.ndarray
    knots: Knots
    prior: np.ndarray | None = None  # (n_free, 2): mean, sd (inf: none)

    @property
    def free_idx(self) -> np.ndarray:
        return np.array([IDX[n] for n in self.free], dtype=int)


def bounds_for(rec: Record) -> dict[str, tuple[float, float]]:
    """Wide, physically plausible bounds (internal coordinates) for one record."""
    q = rec.charge_ah()
    swing = float(np.ptp(q))
    imax = rec.imax()
    dt_med = float(np.median(rec.dt))
    duration = float(rec.t[-1] - rec.t[0])
    tau_lo = np.log10(max(dt_med, 0.05))
    tau_hi = np.log10(max(min(2e4, 2.0 * duration), 10.0 * dt_med))
    q_lo = max(0.01, 0.8 * swing)  # the record may not span more than 125 % of the capacity
    return {
        "vnom": (1.5, 5.0),
        "lc": (-4.0, np.log10(3.0)),  # β ∈ [−2, 0.9999]: OCV rising with SOC
        "lq": (np.log10(q_lo), np.log10(max(1000.0, 10 * q_lo))),
        "soc0": (0.0, 1.0),
        "r0": (0.0, 2.0),
        "r1": (0.0, 2.0),
        "ltau1": (tau_lo, tau_hi),
        "r2": (0.0, 2.0),
        "ltau2": (tau_lo, tau_hi),
        "hm": (0.0, 0.3),
        "lgamma": (-1.0, 4.0),
        "h0": (-1.0, 1.0),
        "bvg": (0.0, 100.0 / imax),
        "th0": (0.0, 12000.0),  # Ea/R; 12,000 K ≈ 100 kJ/mol
        "th1": (0.0, 12000.0),
        "ioff": (-0.1 * imax, 0.1 * imax),
        "voff": (-0.3, 0.3),
        "eta": (0.7, 1.0),
        **{n: (-0.5, 0.5) for n in SHAPE_NAMES},
    }


PRIOR_SCALE_V = 1e-3
"""Residual scale (V) of the weak priors below: one prior row weighs like one sample with 1 mV
noise, so data that inform a parameter outweigh its prior by orders of magnitude."""


def priors_for(rec: Record) -> dict[str, tuple[float, float]]:
    """Weak Gaussian priors (mean, sd; internal coordinates) centred on each effect's neutral
    value. They matter only where the data say nothing about a parameter — a hysteresis state
    at the start of a block held out, an efficiency without charge in the training blocks —
    and there they keep it neutral instead of letting the trust region wander to a bound."""
    imax = rec.imax()
    return {
        "r2": (0.0, 0.1),
        "hm": (0.0, 0.05),
        "h0": (0.0, 1.0),
        "bvg": (0.0, 10.0 / imax),
        "th0": (0.0, 5000.0),
        "th1": (0.0, 5000.0),
        "ioff": (0.0, 0.05 * imax),
        "voff": (0.0, 0.1),
        "eta": (1.0, 0.1),
        **{n: (0.0, 0.05) for n in SHAPE_NAMES},
    }


def structure(
    rec: Record,
    effects=(),
    knots: Knots | None = None,
    fix_capacity: bool = False,
    fix_soc0: bool = False,
) -> Structure:
    effects = tuple(effects)
    for e in effects:
        if e not in EFFECT_PARAMS:
            raise ValueError(f"unknown effect {e!r}")
    free = [n for n in BASE_PARAMS if not (n == "lq" and fix_capacity)]
    free = [n for n in free if not (n == "soc0" and fix_soc0)]
    for e in effects:
        free.extend(EFFECT_PARAMS[e])
    b = bounds_for(rec)
    lo = np.array([b[n][0] for n in free])
    hi = np.array([b[n][1] for n in free])
    pr = priors_for(rec)
    prior = np.array([pr.get(n, (0.0, np.inf)) for n in free])
    return Structure(effects, tuple(free), lo, hi, knots or Knots(0.0, 0.2), prior)


# ----------------------------------------------------------------------------------------------
# fitting


@dataclass
class FitResult:
    x: np.ndarray  # full internal vector
    cost_fit: float  # 0.5 * sum of squared fitting residuals (on the fitted subset)
    nfev: int


def _fd_steps(x: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    h = 1e-6 * np.maximum(np.abs(x), 1e-2 * (hi - lo))
    return np.where(x + h > hi, -h, h)


class _Problem:
    """Residuals and their forward-difference Jacobian for least_squares, one pass per call."""

    def __init__(self, rec: Record, st: Structure, x_full: np.ndarray, idx: np.ndarray):
        self.rec, self.st, self.idx = rec, st, idx
        self.base = x_full.copy()
        self.fi = st.free_idx
        self.vm = rec.v[idx]
        self.shape = "ocv_shape" in st.effects
        self._cache_z = None
        self._cache_v = None
        self.sel = idx
        self.pj = np.zeros(0, dtype=int)
        if st.prior is not None:
            self.pj = np.flatnonzero(np.isfinite(st.prior[:, 1]))
            self.pmu = st.prior[self.pj, 0]
            self.pw = PRIOR_SCALE_V / st.prior[self.pj, 1]
        if self.shape:
            self.grid = np.linspace(st.knots.lo, st.knots.lo + st.knots.step * (N_KNOTS - 1), 41)
            self.w_mono = 10.0 * np.sqrt(idx.size)

    def full(self, z: np.ndarray) -> np.ndarray:
        x = self.base.copy()
        x[self.fi] = z
        return x

    def _penalty(self, x: np.ndarray) -> np.ndarray:
        # monotone OCV: a falling step between grid points costs as much as w_mono volts
        d = np.diff(ocv(x, self.grid, self.st.knots))
        return self.w_mono * np.minimum(d, 0.0)

    def residuals(self, z: np.ndarray) -> np.ndarray:
        x = self.full(z)
        v = simulate_rows(self.rec, x[None, :], self.st.knots, idx=self.sel)[:, 0]
        self._cache_z, self._cache_v = z.copy(), v
        r = v - self.vm
        if self.shape:
            r = np.concatenate([r, self._penalty(x)])
        if self.pj.size:
            r = np.concatenate([r, self.pw * (z[self.pj] - self.pmu)])
        return r

    def jacobian(self, z: np.ndarray) -> np.ndarray:
        h = _fd_steps(z, self.st.lo, self.st.hi)
        X = np.repeat(self.full(z)[None, :], z.size + 1, axis=0)
        for j, k in enumerate(self.fi):
            X[j + 1, k] += h[j]
        # least_squares asks for the Jacobian where it has just evaluated the residuals
        if self._cache_z is not None and np.array_equal(z, self._cache_z):
            V = simulate_rows(self.rec, X[1:], self.st.knots, idx=self.sel)
            J = (V - self._cache_v[:, None]) / h
        else:
            V = simulate_rows(self.rec, X, self.st.knots, idx=self.sel)
            J = (V[:, 1:] - V[:, :1]) / h
        if self.shape:
            p0 = self._penalty(X[0])
            Jp = np.stack([(self._penalty(X[j + 1]) - p0) / h[j] for j in range(z.size)], 1)
            J = np.vstack([J, Jp])
        if self.pj.size:
            Jq = np.zeros((self.pj.size, z.size))
            Jq[np.arange(self.pj.size), self.pj] = self.pw
            J = np.vstack([J, Jq])
        return J


def fit_structure(
    rec: Record,
    st: Structure,
    x0: np.ndarray,
    idx: np.ndarray,
    max_nfev: int = 200,
    tol: float = 1e-8,
) -> FitResult:
    """Least-squares fit of the free parameters of ``st`` from full vector ``x0``.

    ``idx``: the samples whose residuals are fitted (the whole record is always simulated).
    """
    prob = _Problem(rec, st, x0, idx)
    z0 = np.clip(x0[st.free_idx], st.lo, st.hi)
    # strictly inside the box: trf needs an interior start
    span = st.hi - st.lo
    z0 = np.clip(z0, st.lo + 1e-10 * span, st.hi - 1e-10 * span)
    res = least_squares(
        prob.residuals,
        z0,
        jac=prob.jacobian,
        bounds=(st.lo, st.hi),
        method="trf",
        x_scale="jac",
        ftol=tol,
        xtol=tol,
        gtol=tol,
        max_nfev=max_nfev,
    )
    return FitResult(prob.full(res.x), float(res.cost), int(res.nfev))


def fit_indices(n: int, mask: np.ndarray | None, max_points: int) -> np.ndarray:
    """Samples fitted: those in ``mask``, thinned by a fixed stride to at most ``max_points``."""
    idx = np.arange(n) if mask is None else np.flatnonzero(mask)
    stride = int(np.ceil(idx.size / max_points))
    return idx[::stride] if stride > 1 else idx


# ----------------------------------------------------------------------------------------------
# starts


def _r0_guess(rec: Record) -> float:
    di = np.diff(rec.i)
    dv = np.diff(rec.v)
    big = np.abs(di) > 0.2 * rec.imax()
    if big.sum() >= 1:
        est = -dv[big] / di[big]
        est = est[np.isfinite(est) & (est > 0)]
        if est.size:
            return float(np.clip(np.median(est), 1e-4, 1.0))
    return 0.05


def base_starts(rec: Record, capacity_ah=None, soc0=None) -> list[np.ndarray]:
    """A handful of base-model starts spread over capacity, initial SOC and τ1."""
    b = bounds_for(rec)
    q = rec.charge_ah()
    swing = max(float(np.ptp(q)), 1e-6)
    r0 = _r0_guess(rec)
    caps = [capacity_ah] if capacity_ah else [1.25 * swing, 3.0 * swing, 10.0 * swing]
    starts = []
    for cap in caps:
        cap = float(np.clip(cap, 10 ** b["lq"][0], 10 ** b["lq"][1]))
        s_hi = 1.0 + float(np.min(q)) / cap  # SOC0 such that SOC stays ≤ 1
        s_lo = float(np.max(q)) / cap  # ... and ≥ 0
        if soc0 is not None:
            socs = [soc0]
        elif s_lo >= s_hi:
            socs = [float(np.clip(0.5 * (s_lo + s_hi), 0, 1))]
        else:
            socs = sorted({float(np.clip(s_lo + f * (s_hi - s_lo), 0.02, 1.0)) for f in (0.9, 0.4)})
        for s0 in socs:
            x = NEUTRAL.copy()
            x[IDX["lq"]] = np.log10(cap)
            x[IDX["soc0"]] = s0
            x[IDX["r0"]] = r0
            x[IDX["r1"]] = 0.5 * r0
            x[IDX["ltau1"]] = np.clip(np.log10(60.0), *b["ltau1"])
            x[IDX["vnom"]], x[IDX["lc"]] = _ocv_start(rec, x, cap, s0, r0, b)
            starts.append(x)
    return starts


def _ocv_start(rec, x, cap, s0, r0, b):
    """Vnom and log10(1−β) fitted to v + R0·i against the coulomb-counted SOC (no dynamics)."""
    soc = np.clip(s0 - rec.charge_ah() / cap, 0.0, 1.2)
    target = rec.v + r0 * rec.i
    sel = slice(None, None, max(1, rec.n // 2000))
    s, y = soc[sel], target[sel]

    def res(p):
        omb = 10.0 ** p[1]
        return p[0] * s / (omb + (1 - omb) * s) - y

    p0 = np.array([np.clip(np.max(y) + 0.05, *b["vnom"]), -1.0])
    r = least_squares(res, p0, bounds=([b["vnom"][0], b["lc"][0]], [b["vnom"][1], b["lc"][1]]))
    return r.x[0], r.x[1]


def effect_starts(rec: Record, x_base: np.ndarray, effect: str) -> list[np.ndarray]:
    """Starts for one added effect from a fitted vector (its other parameters kept)."""
    b = bounds_for(rec)
    imax = rec.imax()
    out = []

    def with_(**kw):
        x = x_base.copy()
        for k, v in kw.items():
            x[IDX[k]] = np.clip(v, *b[k])
        out.append(x)

    lt1 = x_base[IDX["ltau1"]]
    r1 = max(x_base[IDX["r1"]], 1e-4)
    if effect == "second_rc":
        with_(r2=0.3 * r1, ltau2=lt1 - 1.0)
        with_(r2=0.3 * r1, ltau2=lt1 + 1.0)
    elif effect == "hysteresis":
        for lg in (1.0, 2.0, 3.0):
            with_(hm=0.01, lgamma=lg, h0=0.0)
    elif effect == "butler_volmer":
        with_(bvg=1.0 / imax)
        with_(bvg=5.0 / imax)
    elif effect == "thermal":
        with_(th0=3000.0, th1=3000.0)
    elif effect == "ocv_shape":
        with_()
    elif effect == "current_offset":
        with_(ioff=0.0)
    elif effect == "voltage_offset":
        with_(voff=0.0)
    elif effect == "coulombic_efficiency":
        with_(eta=0.98)
    return out


# ----------------------------------------------------------------------------------------------
# public interface


@dataclass
class Fitted:
    """A fitted model: effects, parameters, and simulation of another record of the same cell."""

    effects: tuple[str, ...]
    x: np.ndarray
    knots: Knots
    tref_k: float
    free: tuple[str, ...]
    rmse_mv: float
    params: dict = field(default_factory=dict)

    @property
    def n_params(self) -> int:
        return len(self.free)

    @classmethod
    def build(cls, rec: Record, st: Structure, x: np.ndarray) -> Fitted:
        v = simulate_rows(rec, x[None, :], st.knots)[:, 0]
        rmse = float(np.sqrt(np.mean((v - rec.v) ** 2))) * 1e3
        names = list(BASE_PARAMS)
        for e in st.effects:
            names.extend(EFFECT_PARAMS[e])
        params = {_REPORT[n][0]: float(_REPORT[n][1](x[IDX[n]])) for n in names}
        if "ocv_shape" in st.effects:
            d = SHAPE_BASIS @ x[U0:]
            for j, s in enumerate(st.knots.grid()):
                params[f"ocv_knot{j}_soc"] = float(s)
                params[f"ocv_d{j}_v"] = float(d[j])
        if "thermal" in st.effects or "butler_volmer" in st.effects:
            params["tref_k"] = rec.tref_k
        return cls(st.effects, x.copy(), st.knots, rec.tref_k, st.free, rmse, params)

    def simulate(self, frame: pd.DataFrame, soc0: float | None = None) -> np.ndarray:
        """Model voltage for ``frame`` (another record of the same cell).

        ``soc0=None``: the initial SOC whose OCV equals the first sample's voltage corrected for
        the ohmic drop (the record is assumed to start at rest; no hysteresis, no RC voltage).
        """
        rec = Record.from_frame(frame, tref_k=self.tref_k)
        x = self.x.copy()
        x[IDX["soc0"]] = self.soc0_from_voltage(rec) if soc0 is None else float(soc0)
        x[IDX["h0"]] = 0.0 if soc0 is None else x[IDX["h0"]]
        return simulate_rows(rec, x[None, :], self.knots)[:, 0]

    def soc0_from_voltage(self, rec: Record) -> float:
        x = self.x
        target = rec.v[0] + x[IDX["r0"]] * (rec.i[0] + x[IDX["ioff"]])
        f = lambda s: float(ocv(x, np.array([s]), self.knots)[0]) - target  # noqa: E731
        lo, hi = 0.0, 1.0
        if f(lo) >= 0:
            return lo
        if f(hi) <= 0:
            return hi
        return float(brentq(f, lo, hi, xtol=1e-9))

    def trajectory(self, rec: Record) -> dict:
        v, tr = simulate_rows(rec, self.x[None, :], self.knots, traces=True)
        return {"voltage_v": v[:, 0], "soc": tr[0], "h": tr[1], "v_rc": tr[2]}


MAX_FIT_POINTS = 20000
"""Residuals fitted per least-squares problem at most; longer records are thinned by a fixed
stride for fitting (the model is always simulated at full resolution and scored on every sample)."""

COARSE_POINTS = 2500
"""Residuals per multi-start trial: the starts are compared on a thinned record, and only the best
is refined on the full set."""


def knots_for(rec: Record, x: np.ndarray, mask: np.ndarray | None = None) -> Knots:
    """ocv_shape knots spread evenly over the SOC range that model ``x`` visits on ``mask``.

    Beyond the knots the correction stays flat: a model fitted without some SOC range does not
    extrapolate a polynomial into it.
    """
    soc = np.clip(x[IDX["soc0"]] - rec.charge_ah() / 10.0 ** x[IDX["lq"]], 0.0, 1.2)
    if mask is not None:
        soc = soc[mask]
    lo, hi = float(soc.min()), float(soc.max())
    if hi - lo < 1e-3:
        lo, hi = lo - 5e-4, hi + 5e-4
    return Knots(lo, (hi - lo) / (N_KNOTS - 1))


def best_of(rec, st, starts, mask=None, max_nfev_coarse=60, max_nfev=200) -> FitResult:
    """Multi-start: each start on the thinned record, the best refined on the fitted samples."""
    idx_full = fit_indices(rec.n, mask, MAX_FIT_POINTS)
    if len(starts) == 1:
        return fit_structure(rec, st, starts[0], idx_full, max_nfev=max_nfev)
    idx_c = fit_indices(rec.n, mask, COARSE_POINTS)
    trials = [fit_structure(rec, st, x0, idx_c, max_nfev=max_nfev_coarse) for x0 in starts]
    best = min(trials, key=lambda r: r.cost_fit)
    return fit_structure(rec, st, best.x, idx_full, max_nfev=max_nfev)


def fit_base(rec: Record, capacity_ah=None, soc0=None, mask=None) -> tuple[Structure, FitResult]:
    st = structure(rec, (), fix_capacity=capacity_ah is not None, fix_soc0=soc0 is not None)
    res = best_of(rec, st, base_starts(rec, capacity_ah, soc0), mask)
    st.knots = knots_for(rec, res.x)
    return st, res


def fit(frame: pd.DataFrame, effects=(), capacity_ah=None, soc0=None) -> Fitted:
    """Fit the base model plus ``effects`` (names from EFFECTS) to one record."""
    rec = Record.from_frame(frame)
    st0, base = fit_base(rec, capacity_ah, soc0)
    x = base.x
    st = st0
    added: list[str] = []
    for e in effects:  # one effect at a time, each from the previous fit (as the ladder does)
        added.append(e)
        st = structure(
            rec, added, st0.knots, fix_capacity=capacity_ah is not None, fix_soc0=soc0 is not None
        )
        x = best_of(rec, st, effect_starts(rec, x, e)).x
    return Fitted.build(rec, st, x)
