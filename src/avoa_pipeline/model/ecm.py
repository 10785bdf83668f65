"""The one equivalent-circuit model library: a base plus composable elements, one compiled
simulator for any combination, one parameter table, one initial-SOC rule.

In the spirit of PyBaMM's Thevenin model (a base and elements assembled from validated options):
a model is an OCV source (the paper's rational eq. 5, or a measured table), R0, one RC branch, a
capacity and an initial SOC, plus any of the elements of :data:`EFFECTS` (each declared in its
own module of ``model/elements/``, its physics stated once; this module holds the base, the
OCV sources, records and the initial-SOC rule; ``layout.py`` the parameter table). The
paper's model (``battery.py``/``kernel.py``), the C/20 circuits of the real-data experiment and
the diagnosis's candidates are configurations of it. ``gap/withheld.py`` stays independent on
purpose (the test oracle).

Per sample k (current i positive = discharge, Δt_k = t[k+1] − t[k], zero-order hold; one sign
convention everywhere):

    i_k     = i_meas,k + b                     current_offset b; with the paper's load resistor
                                               i_k = i_meas,k + b + V_k/R_load, solved exactly
    s̃_k     = s_k − δ_k                         diffusion: the OCV sees a surface SOC
    OCV     = Vnom·s̃/(1 − β(1 − s̃))  or  table(s̃),  + Σ_j d_j·φ_j(s̃)   (ocv_shape: hat functions)
    g_k     = 1 + k_low·exp(−s_k/σ)            soc_resistance: resistances rise near empty
    f0, f1  = exp(θ0,1·(1/T_k − 1/T_ref))      thermal (Arrhenius, measured T in K)
    τ_j     → τ_j·exp(θτ·(1/T_k − 1/T_ref))    thermal_tau
    OCV     += (∂U/∂T)·(T_k − T_ref)           entropic
    Q       → Q·(1 + κQ·(T_k − T_ref))          capacity_temperature (in eq. 6 below)
    V_k     = OCV + M·h_k + c − f0·g_k·R0·i_k − Σ_j v_j,k − (2RT/F)·asinh(i_k/(2 i0))
    v_j,k+1 = a_j·v_j,k + f1·g_k·R_j·(1 − a_j)·i_k,  a_j = exp(−Δt/τ_j),  j = 1..3 (eq. 3)
    δ_k+1   = a_d·δ_k + (1 − a_d)·κ·i_k,  a_d = exp(−Δt/τ_d)
    ie_k    = i_k if i_k > 0 else η·i_k        coulombic_efficiency η (charge)
    h_k+1   = e_k·h_k − (1 − e_k)·sgn(i_k),  e_k = exp(−|γ·ie_k·Δt/(3600 Q)|)
              (Plett 2004, doi:10.1016/j.jpowsour.2004.02.031, eq. 13: h → −1 while
              discharging, V += M·h; the only hysteresis convention in the package)
    s_k+1   = s_k − ie_k·Δt/(3600 Q)           eq. 6

Neutral values (the element is then absent and the model is the base exactly): b = 0, δ: κ = 0,
d = 0, k_low = 0, θ = 0, θτ = 0, ∂U/∂T = 0, κQ = 0, M = 0, c = 0, R2 = R3 = 0, 1/i0 = 0, η = 1.
So every candidate nests the base and elements stack.

Two vectors per parameter set. *Internal* (the optimiser's coordinates, :data:`NAMES`): log10 for
capacity, time constants, σ and the hysteresis rate, log10(1 − β) for the OCV curvature, and the
free coordinates u of the OCV correction. *Physical* (the simulator's, :data:`PHYS`): the values
themselves, with 1 − β and the correction at the knots. :data:`PARAMS` is the one table of
parameters (the base's here, the elements' from their modules): report name, transform, neutral
value, limits and their reason, element, and whether the value belongs to a record (initial
state) rather than to the cell. A fit's bounds and priors follow the records' current scale
(``fitting.bounds_for``, ``fitting.priors_for``).

Why hand-written numerics: the recursion is sequential in time and its current depends on the
voltage under a load, so it is compiled with numba; one call steps a whole set of parameter rows
together (time outer, rows inner) so that a finite-difference Jacobian costs one pass. Its source
is written by ``model/loopgen.py`` from the base's statement and each element's (``Kernel``), one
numba function per version (:data:`COMPILED`). The
paper's population kernel (``kernel.py``) stays as a specialised fast path for the optimiser grid;
``tests/unit/test_ecm.py`` shows it is the same model as :func:`paper_rows`' configuration.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from functools import cached_property

import numpy as np
import pandas as pd
from scipy.interpolate import PchipInterpolator

from ..records import at_rest, current_scale
from . import elements, kernel, loopgen
from .elements.element import FARADAY, GAS_R, N_KNOTS, Physical

# isort: off
from .layout import (  # noqa: F401 - the parameter table and layout, read as ecm's
    BASE_PARAMS, BVG, BY_REPORT, D0, DUDT, ETA, EXTRAS_COLUMNS, GAM, H0, HM, IDX, IOFF, KD,
    KLOW, KQ, L0, L1, LIMITS, N_SCALAR, NAMES, NEUTRAL, NP, NX, OMB, PARAMS, PHYS, R0, R1, R2,
    R3, RHO, SIG, SOC0, TAU1, TAU2, TAU3, TAUD, TH0, TH1, THBV, THTAU, VECTORS, VNOM, VOFF, Q,
    columns, element_params, to_physical,
)  # fmt: skip
# isort: on

T_DEFAULT_K = 298.15
KELVIN_PER_TWO_RT_F = FARADAY / (2.0 * GAS_R)  # T = (2RT/F) × this: the loop reads T from 2RT/F
TABLE_POINTS = 4001
"""Measured OCV tables are resampled onto this uniform SOC grid (0.025 % steps) by a monotone
cubic (:meth:`OcvTable.from_points`); the simulator interpolates linearly between its points.
Why so fine (issue 37; 1001 points, linearly resampled, earlier): the model's voltage is then
piecewise linear in SOC, and a fit's finite-difference Jacobian (steps of about 1e-6) reads each
cell's slope, not the OCV's. Along the flat offset-capacity-initial-SOC valley that slope noise
passed for information: on issue 37's clean record with its true OCV given at 201 points the
offset's standard deviation came out 7.3 mV; with the monotone cubic at 4001 points 71 mV, near
the smooth limit (84 mV at 100,001 points). 4001 doubles are 32 kB, inside a core's L2 cache."""

EFFECTS = elements.NAMES
"""Elements a model may add to its base (the registry, ``model/elements/``, in its order)."""
REQUIRES = {e.name: e.requires for e in elements.REGISTRY.values() if e.requires}

REST_BLIND = frozenset({"thermal", "butler_volmer", "bv_arrhenius"})
"""Elements whose every temperature term multiplies the current (R0's and the RC resistances'
Arrhenius factors, the Butler–Volmer overpotential and its exchange current): at zero current
they make the temperature irrelevant, which :attr:`Record.rest_held` relies on. Any other element
that reads the temperature (a law acting at rest, such as an entropic OCV term or temperature-
dependent time constants) turns the held rest temperature off wherever it is not neutral
(:func:`temperature_acts_at_rest`); a new one belongs here only if it too acts through the
current alone, with a case in ``tests/unit/test_long_records.py``."""


_REST_ACTING = np.array([IDX[n] for n, p in PARAMS.items()
                         if p.element in elements.REGISTRY and p.element not in REST_BLIND
                         and elements.get(p.element).needs_temperature], dtype=int)  # fmt: skip


def temperature_acts_at_rest(P: np.ndarray) -> bool:
    """Whether any physical row of ``P`` has an element that reads the temperature at zero
    current (one not in REST_BLIND, not neutral; a vector parameter is not checked, so assumed
    to act)."""
    if _REST_ACTING.size == 0:
        return False
    if _REST_ACTING.max() >= N_SCALAR:
        return True
    neutral = to_physical(NEUTRAL)[0, _REST_ACTING]
    return bool(np.any(P[:, _REST_ACTING] != neutral))


def physical(x: np.ndarray, knots: Knots) -> Physical:
    """The physical values of internal vector ``x`` by name (an element's report and export)."""
    P = to_physical(x)[0]
    scalars = dict(zip(NAMES[:N_SCALAR], P[:N_SCALAR], strict=True))
    at_knots = {e: P[col : col + N_KNOTS] for e, _, _, col in VECTORS}
    return Physical(scalars, at_knots, knots.grid())


def report(x: np.ndarray, names) -> dict[str, float]:
    """Report-named physical values of the internal ``names`` of vector ``x``."""
    out = {}
    for n in names:
        p, v = PARAMS[n], float(x[IDX[n]])
        if p.transform == "log10":
            v = 10.0**v
        elif p.transform == "log10_1m":
            v = 1.0 - 10.0**v
        out[p.report] = v
    return out


def internal_value(report_name: str, value: float) -> tuple[str, float]:
    """(internal name, internal value) of one report-named physical value."""
    if report_name not in BY_REPORT:
        raise KeyError(f"unknown parameter {report_name!r}")
    n = BY_REPORT[report_name]
    t = PARAMS[n].transform
    if t == "log10":
        return n, float(np.log10(value))
    if t == "log10_1m":
        return n, float(np.log10(1.0 - value))
    return n, float(value)


def vector(params: dict) -> np.ndarray:
    """Internal vector from report-named values (absent ones neutral)."""
    x = NEUTRAL.copy()
    for key, value in params.items():
        if key == "tref_k" or key.startswith(("ocv_knot", "ocv_d", "r0_knot", "r1_knot")):
            continue
        n, v = internal_value(key, value)
        x[IDX[n]] = v
    return x


# ----------------------------------------------------------------------------------------------
# the OCV source


@dataclass(frozen=True)
class Knots:
    """Where the ocv_shape correction lives: N_KNOTS knots from ``lo`` in steps of ``step``."""

    lo: float
    step: float

    def grid(self) -> np.ndarray:
        return self.lo + self.step * np.arange(N_KNOTS)


@dataclass(frozen=True)
class OcvTable:
    """A measured OCV on a uniform SOC grid (``values`` strictly increasing)."""

    lo: float
    step: float
    values: np.ndarray
    capacity_ah: float | None = None  # the slow test's capacity, if it came from one
    source: str = ""
    how: str = ""  # how it was made (which branches, why)
    notes: tuple[str, ...] = ()  # what is odd about it (warnings for the user)
    # how far the table may lie from the cell's OCV (V, one standard deviation) and why; None:
    # not measured (``ocv.offset_prior`` then gives the default)
    offset_sd_v: float | None = None
    offset_why: str = ""
    capacity_sd_ah: float | None = None  # the slow test's capacity's uncertainty (ocv.py)

    @classmethod
    def from_points(cls, soc, ocv_v, capacity_ah=None, source="", how="") -> OcvTable:
        """The table of points (soc, ocv_v) in any order, resampled onto TABLE_POINTS by the
        monotone cubic (scipy's PCHIP: it passes through the points, rises where they rise and
        has no overshoot; points at one SOC averaged), then made strictly increasing (the
        initial-SOC rule inverts it) by at most 1 µV."""
        soc = np.asarray(soc, dtype=float)
        v = np.asarray(ocv_v, dtype=float)
        soc, where = np.unique(soc, return_inverse=True)
        v = np.bincount(where, weights=v) / np.bincount(where)
        grid = np.linspace(soc[0], soc[-1], TABLE_POINTS)
        vals = PchipInterpolator(soc, v)(grid) if soc.size > 2 else np.interp(grid, soc, v)
        vals = np.maximum.accumulate(vals) + np.linspace(0.0, 1e-6, grid.size)
        step = (soc[-1] - soc[0]) / (TABLE_POINTS - 1)
        return cls(float(soc[0]), float(step), np.ascontiguousarray(vals), capacity_ah, source, how)

    def grid(self) -> np.ndarray:
        return self.lo + self.step * np.arange(self.values.size)

    def __call__(self, soc) -> np.ndarray:
        return np.interp(soc, self.grid(), self.values)


@dataclass(frozen=True)
class Config:
    """A model configuration: the OCV source, the elements added to the base, the load."""

    effects: tuple[str, ...] = ()
    table: OcvTable | None = None  # None: the paper's rational OCV with free Vnom, β
    load_ohm: float | None = None  # the paper's load resistor across the cell

    def __post_init__(self):
        for e in self.effects:
            el = elements.get(e)
            if el.requires and el.requires not in self.effects:
                raise ValueError(f"element {e!r} needs {el.requires!r}")
            why = el.conflict(self.table is not None, self.load_ohm is not None)
            if why:
                raise ValueError(f"element {e!r}: {why}")

    @property
    def ocv_kind(self) -> str:
        return "rational" if self.table is None else "table"

    def names(self) -> tuple[str, ...]:
        """Internal names of this configuration's parameters (base first, then elements)."""
        out = list(element_params("base", self.ocv_kind))
        for e in self.effects:
            out.extend(element_params(e))
        return tuple(out)

    def with_effect(self, effect: str) -> Config:
        return Config((*self.effects, effect), self.table, self.load_ohm)

    @property
    def name(self) -> str:
        base = "table" if self.table is not None else "rational"
        return "+".join((base, *self.effects))


def ocv_values(P_row: np.ndarray, soc, knots: Knots, table: OcvTable | None) -> np.ndarray:
    """OCV (with correction and offset, no hysteresis) of physical row ``P_row`` at ``soc``."""
    soc = np.asarray(soc, dtype=float)
    if table is None:
        sc = np.clip(soc, 0.0, 1.2)
        omb = P_row[OMB]
        v = P_row[VNOM] * sc / (omb + (1.0 - omb) * sc)
    else:
        sc = soc
        v = table(sc)
    d = P_row[D0 : D0 + N_KNOTS]
    if np.any(d != 0.0):
        v = v + np.interp(sc, knots.grid(), d)
    return v + P_row[VOFF]


# ----------------------------------------------------------------------------------------------
# records


THERMAL_MIN_RANGE_C = 2.0
"""The thermal element needs the measured temperature to move at least this much (°C): with
less, an Arrhenius factor is a constant that R0 and R1 already absorb."""

OPENING_WINDOW_S = 60.0
"""The initial state is read from 60 s of a record's opening: the last 60 s of its opening rest
(at 1 Hz sixty samples, so the logger's noise enters √60 times less than through one sample, and
the end of the rest is its most relaxed part; docs/gap-diagnosis.md, "Selection judged like
prediction"), or the first 60 s of a record that starts under load (issue 37: the model is
simulated over them, :func:`soc0_rows`; one sample left the initial SOC, and with it the offset
and capacity that trade along it, at the mercy of one sample's noise)."""

MIN_OPENING_SAMPLES = 25
"""The opening window holds at least this many samples (the last ones of the opening rest, or the
first under load), however long they last. Why: a cycler logs a rest every 30-300 s, so 60 s of
it may be one or two samples, and the initial state then carries one sample's noise through the
whole record as a constant offset (issue 37's fit-back cases: the true model, started by the rule
on rests logged every 60 s, scored 1.39-1.42 × the noise). With n samples the rule adds σ²/n to
the squared error, so the RMSE ÷ noise of a model that is otherwise exact is √(1 + 1/n);
n ≥ 25 keeps it within 1.02 (the fit-back goal). At a 1 Hz log the 60 s already hold 60."""


def opening(t: np.ndarray, i: np.ndarray, v: np.ndarray) -> tuple[float, float, int]:
    """(voltage, current, samples) that start a record: their means over the last
    OPENING_WINDOW_S of the opening rest (the leading samples ``records.at_rest``), or, if the
    record starts under load, over its first OPENING_WINDOW_S (each at least MIN_OPENING_SAMPLES
    samples where the record has them; the rule
    then simulates the model over those samples, :func:`load_window`)."""
    moving = np.flatnonzero(~at_rest(i, max(current_scale(i), 1e-6)))
    end = int(moving[0]) if moving.size else i.size
    if end == 0:
        w = load_window(t, i)
        return float(np.mean(v[:w])), float(np.mean(i[:w])), w
    first = int(np.searchsorted(t[:end], t[end - 1] - OPENING_WINDOW_S, side="left"))
    first = max(0, min(first, end - MIN_OPENING_SAMPLES))
    return float(np.mean(v[first:end])), float(np.mean(i[first:end])), end - first


def load_window(t: np.ndarray, i: np.ndarray) -> int:
    """Samples of the opening window of a record that starts under load (the first
    OPENING_WINDOW_S, at least MIN_OPENING_SAMPLES where there are), or 0 if it starts at rest
    (``records.at_rest``)."""
    if i.size == 0 or at_rest(float(i[0]), max(current_scale(i), 1e-6)):
        return 0
    w = int(np.searchsorted(t, t[0] + OPENING_WINDOW_S, side="left"))
    return min(max(w, MIN_OPENING_SAMPLES), i.size)


@dataclass(frozen=True)
class Record:
    """The inputs a simulation needs, prepared once per record."""

    t: np.ndarray
    i: np.ndarray
    v: np.ndarray
    temp_c: np.ndarray | None
    dt: np.ndarray  # dt[k] = t[k+1] − t[k]; the last is the median step (never used by V)
    uniform: bool
    tref_k: float
    dinv_t: np.ndarray
    two_rt_f: np.ndarray
    source: str = "<data>"
    v_open: float = np.nan  # what starts the record (:func:`opening`)
    i_open: float = 0.0
    n_load_open: int = 0  # starts under load: samples of its opening window (:func:`load_window`)

    @property
    def n(self) -> int:
        return self.t.size

    @property
    def temperature_varies(self) -> bool:
        return self.temp_c is not None and float(np.ptp(self.temp_c)) >= THERMAL_MIN_RANGE_C

    @classmethod
    def from_frame(cls, frame: pd.DataFrame, tref_k: float | None = None, source=None) -> Record:
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
        v_open, i_open, _ = opening(t, i, v)
        return cls(
            t=t, i=i, v=v, temp_c=temp, dt=np.ascontiguousarray(dt), uniform=uniform,
            tref_k=float(tref_k), dinv_t=np.ascontiguousarray(1.0 / tk - 1.0 / tref_k),
            two_rt_f=np.ascontiguousarray(2.0 * GAS_R * tk / FARADAY),
            source=str(source if source is not None else frame.attrs.get("source", "<data>")),
            v_open=v_open, i_open=i_open, n_load_open=load_window(t, i),
        )  # fmt: skip

    @classmethod
    def join(cls, recs: list[Record]) -> Record:
        """One record of several, end to end (time made continuous, the next record a median
        step after the last sample), for what reads the residual against current, time and
        temperature (the diagnosis's localization and signatures)."""
        if len(recs) == 1:
            return recs[0]
        t, start = [], 0.0
        for r in recs:
            t.append(r.t - r.t[0] + start)
            start = t[-1][-1] + float(np.median(r.dt))
        temps = None
        if all(r.temp_c is not None for r in recs):
            temps = np.concatenate([r.temp_c for r in recs])
        joined = {k: np.concatenate([getattr(r, k) for r in recs])
                  for k in ("i", "v", "dt", "dinv_t", "two_rt_f")}  # fmt: skip
        return cls(t=np.concatenate(t), temp_c=temps, uniform=False, tref_k=recs[0].tref_k,
                   source="+".join(r.source for r in recs), **joined)  # fmt: skip

    @cached_property
    def rest_held(self) -> tuple[np.ndarray, np.ndarray]:
        """``dinv_t`` and ``two_rt_f`` with each run of zero current given its first sample's
        values (what :func:`simulate_physical` passes the simulator where no current flows
        at rest).

        Why: at zero current the temperature acts on nothing the simulator computes (its
        factors multiply the current: R0's and the RC resistances' Arrhenius factors, the
        Butler–Volmer term's RT/F and exchange current; every state increment is then 0 and
        the voltage is the OCV side, whatever the temperature), but a measured temperature
        that flickers by a hundredth of a kelvin breaks the simulator's held-current shortcut
        (``_loop``: a thermal model's hold needs the same temperature) at every sample. The
        Panasonic HPPC records rest 93 % of their ~90,000 samples, and the thermocouple moves
        at 94 % of them. Held this way, a rest is one hold, and every voltage is the same bit
        for bit (``tests/unit/test_long_records.py``)."""
        rest = self.i == 0.0
        start = rest & ~np.concatenate([[False], rest[:-1]])  # the first sample of each rest
        # per sample, the index of the last sample that is not inside a rest's tail
        src = np.where(rest & ~start, 0, np.arange(self.n))
        np.maximum.accumulate(src, out=src)
        return (np.ascontiguousarray(self.dinv_t[src]),
                np.ascontiguousarray(self.two_rt_f[src]))  # fmt: skip

    @cached_property
    def opening_record(self) -> Record:
        """The record's first ``n_load_open`` samples (what :func:`soc0_rows` simulates for a
        record that starts under load)."""
        k = max(self.n_load_open, 1)
        cut = {f: getattr(self, f)[:k] for f in ("t", "i", "v", "dt", "dinv_t", "two_rt_f")}
        temp = None if self.temp_c is None else self.temp_c[:k]
        return replace(self, temp_c=temp, uniform=self.uniform, n_load_open=0, **cut)

    def charge_ah(self) -> np.ndarray:
        """Charge removed since the start (Ah) at each sample (discharge positive)."""
        return np.concatenate([[0.0], np.cumsum(self.i[:-1] * self.dt[:-1])]) / 3600.0

    def imax(self) -> float:
        return max(current_scale(self.i), 1e-6)


# ----------------------------------------------------------------------------------------------
# the compiled simulator: written by model/loopgen.py from the base's and the elements' statements
# (model/_simulator.py), one compiled function per version; "extras" carries the elements
# compiled only where a row uses one (``Element.compiled``)


COMPILED = loopgen.compiled()
"""The compiled simulator's module (``SIMULATE``: its two versions; ``step``: the SOC filter's
one-sample step; ``STATES``: the step's state columns) for the registry as imported."""
_SIMULATE = COMPILED.SIMULATE
_NO_TABLE = np.empty(0)


def simulate_physical(rec: Record, P: np.ndarray, knots: Knots, table: OcvTable | None = None,
                      load_ohm: float | None = None, traces: bool = False,
                      idx: np.ndarray | None = None):  # fmt: skip
    """Voltage (n, m) of physical rows ``P`` (m, NP); with traces, also (5, n) of row 0.

    ``idx``: return only these samples (sorted), shape (idx.size, m); the whole record is
    simulated all the same. Where no row carries a current offset (so that no current flows at
    the record's zero-current samples), no element reads the temperature at rest
    (:func:`temperature_acts_at_rest`), no load and no traces: the temperature held through each
    rest (:attr:`Record.rest_held`; the same voltages, faster).
    """
    P = np.ascontiguousarray(np.atleast_2d(P), dtype=float)
    dinv_t, two_rt_f = rec.dinv_t, rec.two_rt_f
    at_rest = load_ohm is None and not traces and not np.any(P[:, IOFF] != 0.0)
    if at_rest and not temperature_acts_at_rest(P):
        dinv_t, two_rt_f = rec.rest_held
    if idx is None:
        sel = np.arange(rec.n)
    else:
        sel = np.full(rec.n, -1)
        sel[idx] = np.arange(idx.size)
    out = np.empty((rec.n if idx is None else idx.size, P.shape[0]))
    tr = np.zeros((5, rec.n)) if traces else np.empty((0, 0))  # an absent element's trace: 0
    tab = _NO_TABLE if table is None else table.values
    t_lo, t_step = (0.0, 1.0) if table is None else (table.lo, table.step)
    g = 0.0 if load_ohm is None else 1.0 / load_ohm
    extras = bool(np.any(P[:, EXTRAS_COLUMNS] != 0.0))
    _SIMULATE[extras](P, tab, t_lo, t_step, N_KNOTS, knots.lo, knots.step, rec.i, rec.dt,
                      rec.uniform, dinv_t, two_rt_f, g, sel, out, tr)  # fmt: skip
    return (out, tr) if traces else out


def simulate_rows(rec: Record, X: np.ndarray, knots: Knots, table: OcvTable | None = None,
                  load_ohm: float | None = None, traces: bool = False,
                  idx: np.ndarray | None = None):  # fmt: skip
    """As :func:`simulate_physical`, for internal rows ``X`` (m, NX)."""
    return simulate_physical(rec, to_physical(X), knots, table, load_ohm, traces, idx)


def simulate_params(frame: pd.DataFrame, params: dict, config: Config | None = None,
                    knots: Knots | None = None) -> np.ndarray:  # fmt: skip
    """Terminal voltage of ``frame``'s current under report-named ``params`` (tests, benchmarks,
    demos); ``knots``: where an ocv_shape correction lives (default SOC 0-1)."""
    cfg = config or Config()
    rec = Record.from_frame(frame, tref_k=params.get("tref_k"))
    return simulate_rows(rec, vector(params), knots or Knots(0.0, 0.2), cfg.table,
                         cfg.load_ohm)[:, 0]  # fmt: skip


# ----------------------------------------------------------------------------------------------
# the paper's configuration


def paper_rows(P_paper: np.ndarray, qdis_ah: float, soc0: float, fade_factors=None,
               dynamics: bool = True) -> np.ndarray:  # fmt: skip
    """Physical library rows of the paper's model: fresh-cell parameters (vnom, q, vdis, r0,
    rtr, tau; ``battery.PARAM_NAMES``) with fade applied (eqs. 7-9: effective = fresh × factor)
    and β from Vocv(Qdis/Q) = Vdis (eq. 5). Without dynamics the RC branch is absent."""
    E = np.atleast_2d(np.asarray(P_paper, dtype=float))
    if fade_factors is not None:
        E = E * np.asarray(fade_factors, dtype=float)
    vnom, q, vdis, r0, rtr, tau = E.T
    soc1 = qdis_ah / q
    beta = kernel.paper_beta(vnom, vdis, soc1)
    P = to_physical(np.repeat(NEUTRAL[None, :], E.shape[0], axis=0))
    P[:, VNOM], P[:, OMB], P[:, Q], P[:, SOC0], P[:, R0] = vnom, 1.0 - beta, q, soc0, r0
    P[:, R1] = rtr if dynamics else 0.0
    P[:, TAU1] = tau if dynamics else 1.0
    return P


# ----------------------------------------------------------------------------------------------
# the one initial-SOC rule


def starts_at_rest(rec: Record) -> bool:
    return bool(at_rest(float(rec.i[0]), rec.imax()))


def soc0_rows(P: np.ndarray, rec: Record, knots: Knots, table: OcvTable | None = None,
              iterations: int = 60, load_ohm: float | None = None) -> np.ndarray:  # fmt: skip
    """The library's one initial-SOC rule, for every physical row of ``P``.

    A record that starts at rest: the SOC whose OCV equals the record's opening voltage
    corrected for the ohmic drop (:func:`opening`: the mean over the last OPENING_WINDOW_S of
    the opening rest), OCV(s0) + M·h0 = V_open + R0(s0)·f0·(I_open + b), R0(s0) with its SOC
    factors, no RC voltage. Closed form for the plain rational curve (:func:`rational_soc0`).

    A record that starts under load (issue 37): the SOC at which the model's mean voltage over
    the record's first OPENING_WINDOW_S (simulated, every element and ``load_ohm`` included,
    RC voltages 0 and h = h0 at the start) equals the measured mean there (``V_open``), i.e. the
    model's mean residual over the window is zero: the least-squares initial SOC of the window
    where the residual is linear in it, whose noise is the window mean's (√n times less than
    one sample's; one sample left the initial SOC 0.8 mV/OCV slope off at 1 mV noise, and with
    it the offset and capacity that trade along it).

    Solved on [0, 1] (the table's range for a table OCV) by the Illinois method (bracketed false
    position) on all rows at once (the two sides cross once: the OCV rises with SOC, the ohmic
    term falls or stays); clipped to the range's end when the voltage lies beyond it."""
    P = np.atleast_2d(np.asarray(P, dtype=float))
    lo_s, hi_s = (0.0, 1.0) if table is None else (table.lo, table.grid()[-1])
    if rec.n_load_open > 0 and not np.isnan(rec.v_open):
        return _soc0_under_load(P, rec, knots, table, load_ohm, (lo_s, hi_s), iterations)
    v_open = float(rec.v[0]) if np.isnan(rec.v_open) else rec.v_open
    i0 = rec.i_open + P[:, IOFF]
    f0 = np.exp(P[:, TH0] * rec.dinv_t[0]) * np.where(i0 < 0.0, np.exp(P[:, RHO]), 1.0)
    dtemp0 = rec.two_rt_f[0] * KELVIN_PER_TWO_RT_F - rec.tref_k  # entropic's T − Tref
    v0 = v_open - P[:, HM] * P[:, H0] - P[:, DUDT] * dtemp0
    shaped = np.any(P[:, D0 : D0 + N_KNOTS] != 0.0, axis=1)
    socr0 = np.any(P[:, L0 : L0 + N_KNOTS] != 0.0, axis=1)
    if table is None and not np.any(P[:, KLOW] != 0) and not (shaped | socr0).any():
        return rational_soc0(P[:, VNOM], P[:, OMB], v0 + P[:, R0] * f0 * i0 - P[:, VOFF])
    rows = np.arange(P.shape[0])

    def at_knots(x, col):  # per row, its knot values at its own SOC (flat beyond the knots)
        u = np.clip((x - knots.lo) / knots.step, 0.0, N_KNOTS - 1.0)
        j = np.minimum(u.astype(int), N_KNOTS - 2)
        w = u - j
        return (1.0 - w) * P[rows, col + j] + w * P[rows, col + j + 1]

    def gap(s):  # OCV − (V0 + ohmic drop), one SOC per row
        g = 1.0 + P[:, KLOW] * np.exp(-np.clip(s, -0.5, 2.0) / P[:, SIG])
        if table is None:
            sc = np.clip(s, 0.0, 1.2)
            e = P[:, VNOM] * sc / (P[:, OMB] + (1.0 - P[:, OMB]) * sc)
        else:
            sc = s
            e = table(sc)
        if shaped.any():
            e = e + at_knots(sc, D0)
        if socr0.any():
            g = g * np.exp(at_knots(s, L0))
        return e + P[:, VOFF] - (v0 + P[:, R0] * g * f0 * i0)

    return _illinois(gap, P.shape[0], lo_s, hi_s, iterations)


def _soc0_under_load(P, rec: Record, knots: Knots, table, load_ohm, span, iterations):
    """:func:`soc0_rows` for a record that starts under load: the SOC at which the model's
    mean voltage over the opening window (``Record.opening_record``) is the measured mean.

    Each evaluation simulates the window (about 0.2 ms of call overhead however short it is), so
    the solve starts near the root: the OCV's inverse at the window's mean voltage corrected by
    R0 at its mean current (the rest rule's formula without the elements; no RC voltage), then
    ±LOAD_BRACKET_SOC around it in one call of both ends, widened to the range's end only where
    the root lies outside; on issue 37's record 6 evaluations instead of 10 from the range's
    ends."""
    win = rec.opening_record
    m = P.shape[0]
    lo_s, hi_s = span

    def gap(s):  # mean model voltage over the window − the measured mean, per row (stacked)
        Q = np.tile(P, (s.size // m, 1))
        Q[:, SOC0] = s
        return np.mean(simulate_physical(win, Q, knots, table, load_ohm), axis=0) - rec.v_open

    target = rec.v_open + P[:, R0] * (rec.i_open + P[:, IOFF]) - P[:, VOFF] - P[:, HM] * P[:, H0]
    if table is None:
        guess = rational_soc0(P[:, VNOM], P[:, OMB], target)
    else:
        guess = np.interp(target, table.values, table.grid())
    a = np.clip(guess - LOAD_BRACKET_SOC, lo_s, hi_s)
    b = np.clip(guess + LOAD_BRACKET_SOC, lo_s, hi_s)
    fa, fb = np.split(gap(np.concatenate([a, b])), 2)
    below, above = (fa >= 0) & (a > lo_s), (fb <= 0) & (b < hi_s)  # the root outside [a, b]
    if np.any(below | above):
        f_lo, f_hi = np.split(gap(np.concatenate([np.full(m, lo_s), np.full(m, hi_s)])), 2)
        b, fb = np.where(below, a, b), np.where(below, fa, fb)
        a, fa = np.where(below, lo_s, a), np.where(below, f_lo, fa)
        a, fa = np.where(above, b, a), np.where(above, fb, fa)
        b, fb = np.where(above, hi_s, b), np.where(above, f_hi, fb)
    return _illinois(gap, m, lo_s, hi_s, iterations, LOAD_RULE_TOL_V, start=(a, b, fa, fb))


LOAD_BRACKET_SOC = 0.05
"""Half the under-load rule's first bracket around the rest formula's SOC: the formula leaves out
the RC voltage built up over the window (R1·I, 30 mV on issue 37's record, 0.024 of SOC there);
0.05 holds that on curves of 1 V per unit SOC and more, and a root outside still gets found (the
bracket widens to the range's end)."""
LOAD_RULE_TOL_V = 1e-14
"""The under-load rule's voltage tolerance (V): a fit's finite-difference step of the offset is
about 1e-9 V, and along the offset-capacity-SOC valley the residuals move by a tenth of it, so a
1e-12 V tolerance (the rest rule's) put 1e-3 of noise into that Jacobian column, as much as the
column's own information there. 1e-14 V is about 20 rounding errors of a mean of 600 voltages
near 4 V; an iteration that no longer moves the SOC also stops."""


def _illinois(gap, m: int, lo_s: float, hi_s: float, iterations: int, tol: float = 1e-12,
              start=None) -> np.ndarray:  # fmt: skip
    """The root in [lo_s, hi_s] of the rising ``gap`` (one SOC per row of m), by Illinois
    (false position, the stale end's value halved): bracketed like bisection, superlinear; it
    stops once the voltage gap is below ``tol`` V in every row (or no row's SOC moved). A row
    whose gap has one sign over the whole range gets that end. ``start``: a bracket (a, b,
    gap(a), gap(b)) per row instead of the range's ends (an end of the range where the root
    does not lie inside it)."""
    if start is None:
        a, b = np.full(m, lo_s), np.full(m, hi_s)
        g_lo, g_hi = gap(a), gap(b)
    else:
        a, b, g_lo, g_hi = start
    a0, b0 = a, b
    fa, fb = g_lo.copy(), g_hi.copy()
    inside = (g_lo < 0) & (g_hi > 0)
    side = np.zeros(m)
    c = c_last = 0.5 * (a + b)
    for _ in range(iterations):
        c = (a * fb - b * fa) / np.where(inside, fb - fa, 1.0)
        c = np.where(inside, c, 0.5 * (a + b))
        fc = gap(c)
        if np.all(np.abs(fc[inside]) < tol) or np.array_equal(c, c_last):
            break
        c_last = c
        left = fc < 0  # the root lies above c
        fb = np.where(left & (side == 1), 0.5 * fb, fb)
        fa = np.where(~left & (side == -1), 0.5 * fa, fa)
        a, fa = np.where(left, c, a), np.where(left, fc, fa)
        b, fb = np.where(left, b, c), np.where(left, fb, fc)
        side = np.where(left, 1, -1)
    s = np.where(g_lo >= 0, a0, c)
    return np.where(g_hi <= 0, b0, s)


def soc0_from_voltage(P_row: np.ndarray, rec: Record, knots: Knots, table: OcvTable | None = None,
                      load_ohm: float | None = None) -> float:  # fmt: skip
    """:func:`soc0_rows` for one physical row."""
    return float(soc0_rows(P_row, rec, knots, table, load_ohm=load_ohm)[0])


def rational_soc0(vnom, omb, target) -> np.ndarray:
    """The SOC in [0, 1] at which the rational OCV (eq. 5) equals ``target``, in closed form,
    elementwise (vectorised over candidates): s = target·(1 − β) / (Vnom − β·target); clipped
    to [0, 1]. Where no SOC reaches the target (a non-positive denominator, possible only for
    β > 1, a curve with a pole inside [0, 1]) the cell is taken as full."""
    vnom, omb, target = np.broadcast_arrays(
        *(np.atleast_1d(np.asarray(a, dtype=float)) for a in (vnom, omb, target))
    )
    den = vnom - (1.0 - omb) * target
    with np.errstate(divide="ignore", invalid="ignore"):
        s = target * omb / den
    return np.clip(np.where(np.isfinite(s) & (den > 0), s, 1.0), 0.0, 1.0)
