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

import weakref

import numpy as np
import pandas as pd

from ..records import at_rest
from . import elements, kernel, loopgen
from .elements.element import FARADAY, GAS_R, N_KNOTS, Physical

# isort: off
from .layout import (  # noqa: F401 - the parameter table and layout, read as ecm's
    BASE_PARAMS, BVG, BY_REPORT, D0, DUDT, ETA, EXTRAS_COLUMNS, GAM, H0, HM, IDX, IOFF, KD,
    KLOW, KQ, L0, L1, LIMITS, N_SCALAR, NAMES, NEUTRAL, NP, NX, OMB, PARAMS, PHYS, R0, R1, R2,
    R3, RHO, SIG, SOC0, TAU1, TAU2, TAU3, TAUD, TH0, TH1, THBV, THTAU, VECTORS, VNOM, VOFF, Q,
    columns, element_params, to_physical,
)  # fmt: skip

from .config import Config
from .ocv_source import TABLE_POINTS, Knots, OcvTable, ocv_values  # noqa: F401 - as above
from .record import (  # noqa: F401 - as above
    MIN_OPENING_SAMPLES, OPENING_WINDOW_S, T_DEFAULT_K, THERMAL_MIN_RANGE_C, Record, load_window,
    opening,
)  # fmt: skip
# isort: on

KELVIN_PER_TWO_RT_F = FARADAY / (2.0 * GAS_R)  # T = (2RT/F) × this: the loop reads T from 2RT/F
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

    ``idx``: return only these samples (sorted), shape (idx.size, m); the record is simulated
    up to the latest of them. Where no row carries a current offset (so that no current flows at
    the record's zero-current samples), no element reads the temperature at rest
    (:func:`temperature_acts_at_rest`), no load and no traces: the temperature held through each
    rest (:attr:`Record.rest_held`; the same voltages, faster), and with ``idx`` each rest
    between returned samples merged into one step (:func:`_rests_merged`; the same voltages
    within rounding).
    """
    P = np.ascontiguousarray(np.atleast_2d(P), dtype=float)
    cur, dt, uniform = rec.i, rec.dt, rec.uniform
    dinv_t, two_rt_f = rec.dinv_t, rec.two_rt_f
    sel = _selection(rec.n, idx)
    at_rest = load_ohm is None and not traces and not np.any(P[:, IOFF] != 0.0)
    if at_rest and not temperature_acts_at_rest(P):
        dinv_t, two_rt_f = rec.rest_held
        if idx is not None:
            steps = _rests_merged(rec, idx)
            if steps is not None:
                cur, dt, dinv_t, two_rt_f, sel = steps
                uniform = False
    out = np.empty((rec.n if idx is None else idx.size, P.shape[0]))
    tr = np.zeros((5, rec.n)) if traces else np.empty((0, 0))  # an absent element's trace: 0
    tab = _NO_TABLE if table is None else table.values
    t_lo, t_step = (0.0, 1.0) if table is None else (table.lo, table.step)
    shape = _NO_TABLE if table is None else table.dudt_shape()
    g = 0.0 if load_ohm is None else 1.0 / load_ohm
    extras = bool(np.any(P[:, EXTRAS_COLUMNS] != 0.0))
    _SIMULATE[extras](P, tab, t_lo, t_step, shape, N_KNOTS, knots.lo, knots.step, cur, dt,
                      uniform, dinv_t, two_rt_f, g, sel, out, tr)  # fmt: skip
    return (out, tr) if traces else out


_PER_INDEX: dict[tuple, tuple] = {}


def _once_per_index(idx, tag: str, make, owner=None):
    """``make()``, made once per index array ``idx`` (and ``owner``, an object it also depends
    on: held by a weak reference and compared by identity) and held while the array lives: a fit
    simulates its records hundreds of times with the same ``idx``. The entry goes with its
    array (an id is reused only after that); an ``idx`` that is not an ndarray (a list) is not
    held."""
    key = (id(idx), tag, id(owner))
    hit = _PER_INDEX.get(key)
    if hit is not None and hit[0]() is idx and (hit[1] is None or hit[1]() is owner):
        return hit[2]
    value = make()
    try:
        ref = weakref.ref(idx, lambda _, k=key: _PER_INDEX.pop(k, None))
    except TypeError:
        return value
    _PER_INDEX[key] = (ref, None if owner is None else weakref.ref(owner), value)
    return value


def _rests_merged(rec: Record, idx: np.ndarray):
    """The steps a thinned simulation needs, each rest between returned samples merged into one
    step (``cur, dt, dinv_t, two_rt_f, sel`` for the simulator), or None where no step would
    go. Only for what :func:`simulate_physical` holds at rest (:attr:`Record.rest_held`: no
    current offset, no load, no element that reads the temperature at zero current): there,
    over a run of zero current, every state's update is a decay by exp(−Δt/τ) (the RC
    branches, diffusion) or nothing (the SOC, hysteresis), with the rest's first temperature
    throughout, so one step of the run's length gives the same states as its samples stepped
    one by one, within rounding (exp(−Σ Δt/τ) for the product of the samples' factors: a few
    units in the last place; no longer bit for bit, issue 42). Samples after the last returned
    one are not stepped at all.

    Why: the fits' multi-start trials and the fit check compare models on 2,500 samples but
    stepped every sample of the record between them; a Panasonic HPPC test rests at 93 % of its
    97,854 samples (1 s apart), so most of a thinned simulation's work was stepping rests. Made
    once per record and ``idx`` array (:func:`_once_per_index`).

    Merged always, not only where it removes many steps: the merged steps are uneven, but the
    simulator makes its decays afresh only where the step changes, so a drive cycle costs about
    the same merged or not (``benchmarks/bench_merged_rests.py``, merged ÷ unmerged: the
    Panasonic 25 °C training cycle LA92, 2 % at rest, 0.98-1.00; two withheld-effect drive
    records, 13 % at rest, 1.03-1.08). A threshold would save at most those few per cent and
    need a constant of its own."""

    def make():
        last = int(idx.max()) + 1 if idx.size else 1  # idx need not be sorted
        keep = ~rec.rest_tail(last)  # a rest's first sample starts its merged step
        keep[idx] = True
        if last == rec.n and keep.all():
            return None
        dinv_t, two_rt_f = rec.rest_held
        at = np.flatnonzero(keep)
        return (np.ascontiguousarray(rec.i[at]), np.add.reduceat(rec.dt[:last], at),
                np.ascontiguousarray(dinv_t[at]), np.ascontiguousarray(two_rt_f[at]),
                np.ascontiguousarray(_selection(rec.n, idx)[at]))  # fmt: skip

    return _once_per_index(idx, "rests merged", make, owner=rec)


def _selection(n: int, idx: np.ndarray | None) -> np.ndarray:
    """Per sample, its place among the returned samples ``idx`` (−1: not returned); all of them
    without ``idx``. On a record of 10⁵ samples making the array took a tenth of a short
    simulation: made once per ``idx`` array and length (:func:`_once_per_index`; never written
    to: left writeable because numba types a read-only array apart and would compile the
    simulator again for it)."""
    if idx is None:
        return np.arange(n)

    def make():
        sel = np.full(n, -1)
        sel[idx] = np.arange(idx.size)
        return sel

    return _once_per_index(idx, f"selection of {n}", make)


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
    profile = table is not None and table.dudt_shape().size > 0  # entropic's term moves with s
    v0 = v_open - P[:, HM] * P[:, H0] - (0.0 if profile else P[:, DUDT] * dtemp0)
    shaped = np.any(P[:, D0 : D0 + N_KNOTS] != 0.0, axis=1)
    socr0 = np.any(P[:, L0 : L0 + N_KNOTS] != 0.0, axis=1)
    if table is None and not np.any(P[:, KLOW] != 0) and not (shaped | socr0).any():
        return rational_soc0(P[:, VNOM], P[:, OMB], v0 + P[:, R0] * f0 * i0 - P[:, VOFF])
    rows = np.arange(P.shape[0])
    # the parts of the gap that do not move with the SOC, computed once; each the same
    # operations in the same order as where they move, so that the roots are the same bit for
    # bit (a soc_resistance factor of 0 leaves g at exactly 1: its exponential is finite, σ
    # being at least 0.005 and the SOC at least −0.5)
    klow, shaped, socr0 = bool(np.any(P[:, KLOW] != 0.0)), bool(shaped.any()), bool(socr0.any())
    voff, r0 = P[:, VOFF], P[:, R0]
    drop = None if klow or socr0 else v0 + r0 * f0 * i0

    def at_knots(x, col):  # per row, its knot values at its own SOC (flat beyond the knots)
        u = np.clip((x - knots.lo) / knots.step, 0.0, N_KNOTS - 1.0)
        j = np.minimum(u.astype(int), N_KNOTS - 2)
        w = u - j
        return (1.0 - w) * P[rows, col + j] + w * P[rows, col + j + 1]

    def gap(s):  # OCV − (V0 + ohmic drop), one SOC per row
        if table is None:
            sc = np.clip(s, 0.0, 1.2)
            e = P[:, VNOM] * sc / (P[:, OMB] + (1.0 - P[:, OMB]) * sc)
        else:
            sc = s
            e = table(sc)
        if shaped:
            e = e + at_knots(sc, D0)
        if profile:
            e = e + P[:, DUDT] * table.entropic_shape(sc) * dtemp0
        if drop is not None:
            return e + voff - drop
        g = 1.0 + P[:, KLOW] * np.exp(-np.clip(s, -0.5, 2.0) / P[:, SIG]) if klow else None
        if socr0:
            g = np.exp(at_knots(s, L0)) if g is None else g * np.exp(at_knots(s, L0))
        return e + voff - (v0 + r0 * g * f0 * i0)

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
    every = bool(inside.all())  # the usual case: no row to bisect, no mask to apply
    side = np.zeros(m)
    c = c_last = 0.5 * (a + b)
    for _ in range(iterations):
        if every:
            c = (a * fb - b * fa) / (fb - fa)
        else:
            c = (a * fb - b * fa) / np.where(inside, fb - fa, 1.0)
            c = np.where(inside, c, 0.5 * (a + b))
        fc = gap(c)
        if np.all(np.abs(fc if every else fc[inside]) < tol) or np.array_equal(c, c_last):
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
