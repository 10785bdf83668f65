"""The cell's temperature predicted from the ambient: a lumped thermal state (issue 28, item 2).

One heat capacity C_th (J/K) and one conductance hA (W/K) to an ambient T_amb (Bernardi,
Pawlikowski and Newman 1985, doi:10.1149/1.2113792; the lumped model of PyBaMM's Thevenin
model)::

    C_th·dT/dt = q(t) − hA·(T − T_amb)
    q = i·(OCV(s) − V) − i·T·dU/dT        i > 0 discharge, T in K

``i·(OCV − V)`` is the irreversible heat: every overpotential the identified model carries (R0,
the RC branches, Butler–Volmer, diffusion's surface SOC, hysteresis), read as the difference
between the model's OCV at the bulk SOC (``ecm.ocv_values``) and its terminal voltage, so a new
element's loss enters without a line here. ``−i·T·dU/dT`` is the reversible (entropic) heat.
The current is the model's battery current (its trace: measured current plus a fitted offset).

Discretisation: over each sample step the heat is held (zero-order hold, as the simulator holds
the current for its RC branches), so the linear ODE is stepped exactly:
T[k+1] = T_amb + a·(T[k] − T_amb) + (1 − a)·q[k]/hA, a = exp(−hA·Δt/C_th). The recursion is
compiled (numba): it is sequential in time, and a record holds up to 2·10⁵ samples.

Coupling: the heat depends on the voltage and the voltage on the temperature (the Arrhenius
factors of ``thermal``, the 2RT/F of Butler–Volmer). :func:`predict` solves it by fixed-point
passes of the unchanged simulator (``FittedModel.simulate``): pass 1 at T = T_amb, then the
heat of the last pass's voltage gives the next temperature, until a pass moves no sample by more
than :data:`FIXED_POINT_TOL_K` (at most :data:`MAX_PASSES`). The simulator itself is not
touched: its loop is one compiled function on purpose (``model/_simulator.py``, generated from
the elements' statements by ``model/loopgen.py``).

Identification (:func:`fit_heat`), sequential: the electrical model is fitted first with the
measured temperature (the diagnosis, as it stands); then C_th and hA (and dU/dT where identified)
are fitted by least squares (``scipy.optimize.least_squares``) of the temperature predicted from
the ambient against the measured one on the TRAINING records with a moving measured temperature,
each record counting alike, the electrical model held. In the fit the heat is the model's on the
measured temperature (the conditions it was fitted in), so the temperature is a linear filter of
a fixed heat and each evaluation costs one pass of the recursion; the written training RMSE is
the prediction's own (fixed point from the ambient). 95 % intervals: the sandwich covariance of
the fit (its Jacobian, each record's residual variance inflated by its integrated
autocorrelation time, ``intervals.autocorrelation_time``, as ``model/intervals.py`` does for the
electrical parameters); a value within ``fitting.AT_BOUND`` of its searched range is flagged.

The entropic term, dU/dT: one number (not its SOC profile, which needs OCV tests at several
temperatures; the Panasonic data have a C/20 test at 25 °C only). It is fitted only as a
candidate: kept when its 95 % interval excludes 0 and it is not at a bound (:func:`fit_heat`,
``entropic``), decided on the training records alone. It enters the heat only, not the OCV the
voltage sees (an entropic OCV shift is an electrical element's business, issue 28 item 1).
On the Panasonic 18650PF (the joint diagnosis's eight training records, 25 to −10 °C) it is
identified and admitted: −0.27 mV/K [−0.43, −0.10] (docs/real-data.md, "Self-heating predicted:
the measurement"): the drive cycles discharge the cell by 2-2.6 Ah each, so the reversible heat
does not cancel over a record, and the temperature records at four ambients tell it from the
irreversible heat, which grows with |i| (the reversible one with i). A model with an
electrical ``entropic`` element (issue 28 item 1) brings its own dU/dT: it is the reversible
heat's, and its OCV shift is part of the OCV in q (:data:`ELECTRICAL_DUDT`).

Whether or not the model has a temperature law (docs/temperature-rule.md part 6, issue 41):
the block predicts the cell temperature, which a user's simulation from the ambient needs either
way, and the heat is the model's own losses whichever elements it has (the ohmic and RC losses
are in i·(OCV − V) without any law). Where no element's voltage term reads the temperature
(:func:`temperature_readers` empty) the prediction leaves the voltage as it is, and
:func:`attach` says so (:data:`VOLTAGE_BLIND`).

Ambient of a record (:func:`ambient_of`): its sidecar's ``ambient_temperature_c`` where it has
one, else its first temperature sample (a record starts at rest, at the ambient it soaked in).
The predicted temperature starts at the ambient.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numba as nb
import numpy as np
import pandas as pd

from ..errors import DataError
from ..records import TEMPERATURE_RANGE_C
from . import ecm

KELVIN = 273.15

C_TH_LIMITS_J_PER_K = (0.5, 1e5)
"""Heat capacity of one cell (mass × c_p, c_p ≈ 0.8-1.1 J/(g·K) for lithium-ion cells): a
0.5 g micro coin cell holds about 0.5 J/K, an 18650 (≈ 45 g) about 40 J/K, a 5.5 kg 280 Ah
prismatic cell about 6 kJ/K; 10⁵ J/K (≈ 100 kg) leaves room for a cell clamped in a fixture."""
HA_LIMITS_W_PER_K = (1e-4, 100.0)
"""Conductance to the ambient, h·A: a coin cell in still air (h ≈ 5 W/(m²·K), A ≈ 1.3·10⁻³
m²) ≈ 6·10⁻³ W/K, an 18650 in a chamber 0.02-0.5 W/K; 10⁻⁴ W/K allows a cell wrapped in
insulation; 100 W/K a large pouch cell (0.2 m²) on a liquid-cooled plate (h ≈ 500 W/(m²·K))."""
DUDT_LIMITS_V_PER_K = (-2e-3, 2e-3)
"""Entropic coefficient dU/dT: measured values of lithium-ion chemistries (graphite against LCO,
NMC, NCA, LFP) lie within about ±1 mV/K over the SOC range (e.g. Viswanathan et al. 2010,
doi:10.1016/j.jpowsour.2009.11.103); ±2 mV/K leaves a margin."""
AMBIENT_RANGE_C = TEMPERATURE_RANGE_C
"""An ambient is a cell temperature a record may carry (``records.TEMPERATURE_RANGE_C``)."""

FIXED_POINT_TOL_K = 0.01
"""The coupling is solved when a pass moves no sample's temperature by more than 0.01 K: ten
times below a thermocouple's resolution (0.1 K), and through an Arrhenius factor of θ ≤ 12,000 K
at −20 °C a resistance change of 0.2 %."""
MAX_PASSES = 10
"""At most this many passes: each pass shrinks the change by the loop gain (the heat's rise with
temperature over hA, about 0.01-0.3 on an 18650 in a chamber), so 0.01 K is reached in 3-5;
a model that has not converged by 10 is reported (``Prediction.converged``), not hidden."""

MIN_RANGE_C = ecm.THERMAL_MIN_RANGE_C
"""A training record trains the heat block only if its measured temperature moves at least this
much (the thermal element's own threshold): below it the self-heating is within the sensor's
offsets and carries no information on C_th or hA."""

C_STARTS = (10.0, 100.0, 1000.0)
"""Starts of C_th (J/K): one per decade around an 18650's 40 J/K; the least squares is smooth
in log coordinates, so three starts find the one minimum the tests and the data show."""
HA_STARTS = (0.05, 0.5)
"""Starts of hA (W/K): the two ends of a cell's range in a chamber."""

AMBIENT_RULE = ("the record's sidecar's ambient_temperature_c where it has one, else its first "
                "temperature sample (a record starts at rest, at the ambient it soaked in); the "
                "predicted temperature starts at the ambient")  # fmt: skip
NAMES = ("c_th_j_per_k", "ha_w_per_k", "dudt_v_per_k")
UNITS = {"c_th_j_per_k": "J/K", "ha_w_per_k": "W/K", "dudt_v_per_k": "V/K"}


@nb.njit(cache=True, nogil=True)
def _step(dt, q, t_amb, c_th, ha, t0):  # pragma: no cover - compiled
    """T at every sample (K) of the exact zero-order-hold recursion (module docstring)."""
    n = q.shape[0]
    out = np.empty(n)
    tk = t0
    last = -1.0
    a = 0.0
    for k in range(n):
        out[k] = tk
        if dt[k] != last:  # a uniform record computes one exponential
            last = dt[k]
            a = math.exp(-ha * last / c_th)
        tk = t_amb + a * (tk - t_amb) + (1.0 - a) * q[k] / ha
    return out


def temperature(time_s, heat_w, ambient_k: float, c_th: float, ha: float,
                t0_k: float | None = None) -> np.ndarray:  # fmt: skip
    """The lumped cell temperature (K) at every sample, for the heat ``heat_w`` held over each
    step, from ``t0_k`` (default: the ambient)."""
    t = np.asarray(time_s, dtype=float)
    q = np.ascontiguousarray(heat_w, dtype=float)
    dt = np.ascontiguousarray(np.append(np.diff(t), 0.0))
    start = float(ambient_k if t0_k is None else t0_k)
    return _step(dt, q, float(ambient_k), float(c_th), float(ha), start)


def heat_parts(model, frame: pd.DataFrame, temp_k: np.ndarray,
               soc0: float | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:  # fmt: skip
    """(irreversible heat i·(OCV(s) − V) in W, the reversible heat per unit dU/dT −i·T in
    W/(V/K), model voltage V) of ``model`` on ``frame`` run at the cell temperature ``temp_k``
    (K, one per sample). With the model's own entropic element (:data:`ELECTRICAL_DUDT`) its
    OCV shift is in the OCV and its reversible heat in the first term."""
    temp_k = np.asarray(temp_k, dtype=float)
    run = frame.assign(temperature_c=temp_k - KELVIN)
    with np.errstate(all="ignore"):  # an extreme model is judged by its voltage, not here
        v, tr = model.simulate(run, soc0=soc0, traces=True)
    ocv = ecm.ocv_values(ecm.to_physical(model.x)[0], tr[0], model.knots, model.config.table)
    i = tr[4]  # the battery current (a fitted current offset included)
    ent = electrical_dudt(model)  # the model's own entropic term: its OCV, its reversible heat
    table = model.config.table
    if ent != 0.0 and table is not None:  # times the slow tests' profile where it has one
        ent = ent * table.entropic_shape(tr[0])
    ocv = ocv + ent * (temp_k - model.tref_k)
    return i * (ocv - v) - i * temp_k * ent, -i * temp_k, v


ELECTRICAL_DUDT = "entropic_dudt_v_per_k"
"""The report name of the dU/dT of an electrical ``entropic`` element (OCV + dU/dT·(T − Tref),
issue 28 item 1), where the library and the model have one: its OCV shift belongs to the OCV in
q (it is no overpotential) and its dU/dT gives the reversible heat, so the heat block admits no
dU/dT of its own beside it (:func:`fit_heat`)."""


def electrical_dudt(model) -> float:
    """The model's electrical dU/dT (V/K; 0 without an ``entropic`` element)."""
    return float(model.parameters().get(ELECTRICAL_DUDT, 0.0))


def heat_of(model, frame: pd.DataFrame, temp_k: np.ndarray, dudt: float = 0.0,
            soc0: float | None = None) -> tuple[np.ndarray, np.ndarray]:  # fmt: skip
    """(heat W, model voltage V) of ``model`` on ``frame`` run at the cell temperature
    ``temp_k``: i·(OCV(s) − V) − i·T·dU/dT (module docstring)."""
    irr, rev, v = heat_parts(model, frame, temp_k, soc0)
    return irr + dudt * rev, v


@dataclass(frozen=True)
class Heat:
    """The fitted thermal state of a cell, as model.json's ``heat`` block holds it."""

    c_th: float  # J/K
    ha: float  # W/K
    dudt: float = 0.0  # V/K; 0 where the entropic term is not identified
    entropic: bool = False  # dU/dT was admitted (its interval excludes 0)
    report: dict = field(default_factory=dict)  # intervals, records, RMSE (read, not used)

    @property
    def tau_s(self) -> float:
        return self.c_th / self.ha

    def to_json(self) -> dict:
        return {**self.report, "parameters": {"c_th_j_per_k": self.c_th, "ha_w_per_k": self.ha,
                                              "dudt_v_per_k": self.dudt},
                "entropic": self.entropic}  # fmt: skip

    @classmethod
    def from_json(cls, d: dict) -> Heat:
        """From a block that passed ``fitted.model_schema`` and ``fitted``'s checks."""
        p = d["parameters"]
        report = {k: v for k, v in d.items() if k not in ("parameters", "entropic")}
        return cls(float(p["c_th_j_per_k"]), float(p["ha_w_per_k"]), float(p["dudt_v_per_k"]),
                   bool(d["entropic"]), report)  # fmt: skip


@dataclass(frozen=True)
class Prediction:
    """The coupled solution on one record: temperature (K), voltage (V), heat (W), passes used,
    the last pass's largest change (K), whether it met FIXED_POINT_TOL_K."""

    temp_k: np.ndarray
    voltage_v: np.ndarray
    heat_w: np.ndarray
    passes: int
    last_change_k: float
    converged: bool


def predict(model, heat: Heat, frame: pd.DataFrame, ambient_c: float,
            soc0: float | None = None, passes: int = MAX_PASSES,
            tol_k: float = FIXED_POINT_TOL_K) -> Prediction:  # fmt: skip
    """The cell temperature and voltage of ``frame`` from the ambient alone, by fixed-point
    passes (module docstring): pass 1 at the ambient, each next one at the temperature the last
    pass's heat gives, until a pass changes no sample by more than ``tol_k``."""
    amb = float(ambient_c) + KELVIN
    t = np.asarray(frame["time_s"], dtype=float)
    temp = np.full(t.size, amb)
    change, done = math.inf, 0
    q, v = heat_of(model, frame, temp, heat.dudt, soc0)
    while done < passes:
        done += 1
        new = temperature(t, q, amb, heat.c_th, heat.ha)
        change = float(np.max(np.abs(new - temp))) if t.size else 0.0
        temp = new
        q, v = heat_of(model, frame, temp, heat.dudt, soc0)
        if not change > tol_k:  # a NaN change is no convergence: stop and report it
            break
    return Prediction(temp, v, q, done, change, bool(change <= tol_k))


def ambient_of(checked) -> tuple[float, str]:
    """(ambient °C, where it came from) of a checked record (``records.Checked``): its
    sidecar's ``ambient_temperature_c`` (read here: the input layer reads CSVs without theirs),
    else its first temperature sample; DataError if it has neither or the sidecar's is not a
    cell's temperature."""
    from ..io import read_sidecar

    meta = checked.meta or {}
    if not meta and checked.origin.get("read_as") == "canonical CSV":
        meta = read_sidecar(checked.source)
    if "ambient_temperature_c" in meta:
        where = f"{checked.source}'s sidecar: field 'ambient_temperature_c'"
        return check_ambient(meta["ambient_temperature_c"], where), "sidecar"
    if "temperature_c" in checked.frame.columns:
        return float(checked.frame["temperature_c"].iloc[0]), "first temperature sample"
    raise DataError(f"{checked.source}: missing column 'temperature_c' and no sidecar "
                    "'ambient_temperature_c': no ambient")  # fmt: skip


def ambient_if_any(checked) -> tuple[float, str] | None:
    """:func:`ambient_of`, or None for a record with neither a sidecar ambient nor a temperature
    column (the diagnosis then splits no error by test temperature; the SOC filter falls back to
    the model's reference temperature)."""
    try:
        return ambient_of(checked)
    except DataError:
        return None


def training_ambients(checked) -> list[tuple[float, str]]:
    """The ambient of every record that could train the heat block (a measured temperature
    moving at least MIN_RANGE_C), so that a bad sidecar is refused before a diagnosis runs."""
    return [ambient_of(c) for c in checked if _moves(c.frame)]


def _moves(frame: pd.DataFrame) -> bool:
    return "temperature_c" in frame.columns and float(np.ptp(frame["temperature_c"])) >= MIN_RANGE_C


AMBIENT_GROUP_K = 2.0
"""Records whose ambients lie within this of a group's coldest were run at one test temperature:
the tolerance a test standard allows a chamber's set point (IEC 62660-1, SAE J2464: ±2 K);
docs/soc-filter.md part 6."""


def ambient_groups(ambients_c) -> list[list[int]]:
    """The records' indices grouped by test temperature (:data:`AMBIENT_GROUP_K`), coldest
    first, each group's indices in the order of ``ambients_c``."""
    order = sorted(range(len(ambients_c)), key=lambda r: (ambients_c[r], r))
    groups: list[list[int]] = []
    for r in order:
        if groups and ambients_c[r] - ambients_c[groups[-1][0]] <= AMBIENT_GROUP_K:
            groups[-1].append(r)
        else:
            groups.append([r])
    return [sorted(g) for g in groups]


def check_ambient(value, where: str) -> float:
    """An ambient (°C): a finite number within AMBIENT_RANGE_C, else a one-line DataError."""
    lo, hi = AMBIENT_RANGE_C
    ok = isinstance(value, int | float) and not isinstance(value, bool)
    if not ok or not math.isfinite(value) or not lo <= value <= hi:
        raise DataError(f"{where}: {value!r}, not an ambient in {lo:g}..{hi:g} °C")
    return float(value)


# ----------------------------------------------------------------------------------------------
# identification on training records


@dataclass(frozen=True)
class Training:
    """One training record as the heat fit sees it: time, measured temperature (K), ambient (K),
    the model's heat on the measured temperature split as in :func:`heat_parts`."""

    source: str
    frame: pd.DataFrame
    time_s: np.ndarray
    measured_k: np.ndarray
    ambient_k: float
    ambient_from: str
    irreversible_w: np.ndarray
    reversible_w: np.ndarray

    def predicted_k(self, c_th: float, ha: float, dudt: float) -> np.ndarray:
        q = self.irreversible_w + dudt * self.reversible_w
        return temperature(self.time_s, q, self.ambient_k, c_th, ha)


def training_records(model, checked) -> list[Training]:
    """The checked records (``records.Checked``) that can train the heat block: a measured
    temperature moving at least MIN_RANGE_C; each with its ambient (:func:`ambient_of`) and the
    model's heat on its measured temperature."""
    out = []
    for c in checked:
        f = c.frame
        if not _moves(f):
            continue
        amb, where = ambient_of(c)
        measured = f["temperature_c"].to_numpy(dtype=float) + KELVIN
        irr, rev, _ = heat_parts(model, f, measured)
        out.append(Training(c.source, f, f["time_s"].to_numpy(dtype=float), measured,
                            amb + KELVIN, where, irr, rev))  # fmt: skip
    return out


def _bounds(entropic: bool) -> tuple[np.ndarray, np.ndarray]:
    """The searched range in the fit's coordinates: log10 C_th, log10 hA[, dU/dT]."""
    lo = [math.log10(C_TH_LIMITS_J_PER_K[0]), math.log10(HA_LIMITS_W_PER_K[0])]
    hi = [math.log10(C_TH_LIMITS_J_PER_K[1]), math.log10(HA_LIMITS_W_PER_K[1])]
    if entropic:
        lo.append(DUDT_LIMITS_V_PER_K[0])
        hi.append(DUDT_LIMITS_V_PER_K[1])
    return np.array(lo), np.array(hi)


def _unpack(z) -> tuple[float, float, float]:
    return 10.0 ** z[0], 10.0 ** z[1], (float(z[2]) if len(z) > 2 else 0.0)


def _residuals(z, recs: list[Training]) -> np.ndarray:
    """Predicted minus measured temperature, each record weighted by 1/√n (records alike)."""
    c, h, d = _unpack(z)
    return np.concatenate([(r.predicted_k(c, h, d) - r.measured_k) / math.sqrt(r.time_s.size)
                           for r in recs])  # fmt: skip


@dataclass(frozen=True)
class HeatFit:
    """A least-squares fit of the heat block in its coordinates (log10 C_th, log10 hA[, dU/dT]),
    its searched range and its sandwich covariance (nan rows where at a bound)."""

    z: np.ndarray
    lo: np.ndarray
    hi: np.ndarray
    cov: np.ndarray
    cost: float

    @property
    def at_bound(self) -> np.ndarray:
        from . import fitting

        return fitting.at_bound(self.z, self.lo, self.hi)

    def interval(self, k: int) -> tuple[float | None, float | None]:
        """The 95 % interval of coordinate k in its physical units (None at a bound)."""
        from .intervals import Z95

        sd = math.sqrt(self.cov[k, k]) if np.isfinite(self.cov[k, k]) else math.nan
        if self.at_bound[k] or not np.isfinite(sd):
            return None, None
        a = max(self.z[k] - Z95 * sd, self.lo[k])
        b = min(self.z[k] + Z95 * sd, self.hi[k])
        return (10.0**a, 10.0**b) if k < 2 else (float(a), float(b))

    def excludes_zero(self, k: int) -> bool:
        a, b = self.interval(k)
        return a is not None and not a <= 0.0 <= b


def fit_records(recs: list[Training], entropic: bool) -> HeatFit:
    """Least squares (``scipy.optimize.least_squares``, bounded) of the predicted temperature
    against the measured one from every start of C_STARTS × HA_STARTS; the best, with its
    covariance (:func:`_covariance`)."""
    from scipy.optimize import least_squares

    lo, hi = _bounds(entropic)
    best = None
    for c0 in C_STARTS:
        for h0 in HA_STARTS:
            z0 = np.clip([math.log10(c0), math.log10(h0), *([0.0] if entropic else [])], lo, hi)
            res = least_squares(_residuals, z0, bounds=(lo, hi), args=(recs,), x_scale="jac",
                                method="trf")  # fmt: skip
            if best is None or res.cost < best.cost:
                best = res
    cov = _covariance(best.x, best.jac, recs, lo, hi)
    return HeatFit(best.x.copy(), lo, hi, cov, float(best.cost))


def _covariance(z, jac, recs: list[Training], lo, hi) -> np.ndarray:
    """Sandwich covariance A⁻¹·B·A⁻¹ of the weighted fit (A = JᵀJ; B = Σ_r τ_r·s_r²/n_r·J_rᵀJ_r,
    s_r² the record's mean squared residual, τ_r its integrated autocorrelation time): a
    temperature miss lasts minutes, so n samples carry n/τ samples' information. Coordinates at a
    bound are held (nan)."""
    from . import fitting
    from .intervals import autocorrelation_time

    free = ~fitting.at_bound(z, lo, hi)
    J = np.asarray(jac)[:, free]
    c, h, d = _unpack(z)
    B = np.zeros((J.shape[1], J.shape[1]))
    start = 0
    for r in recs:
        n = r.time_s.size
        e = r.predicted_k(c, h, d) - r.measured_k
        Jr = J[start : start + n]
        B += autocorrelation_time(e) * float(np.mean(e**2)) / n * (Jr.T @ Jr)
        start += n
    A_inv = np.linalg.pinv(J.T @ J)
    cov = np.full((z.size, z.size), np.nan)
    cov[np.ix_(free, free)] = A_inv @ B @ A_inv
    return cov


def _entry(fit: HeatFit, k: int, value: float) -> dict:
    a, b = fit.interval(k)
    return {"value": value, "low95": a, "high95": b, "at_bound": bool(fit.at_bound[k])}


def fit_heat(model, checked) -> tuple[Heat | None, str]:
    """The heat block of ``model`` from its training records (``records.Checked``), or None and
    why not: a record must have a moving measured temperature (:func:`training_records`),
    whether or not the model has a temperature law (docs/temperature-rule.md part 6: the block
    predicts the cell temperature either way). C_th and hA fitted; dU/dT admitted where
    identified (module docstring)."""
    recs = training_records(model, checked)
    if not recs:
        return None, (f"no training record has a measured temperature_c moving "
                      f"{MIN_RANGE_C:g} °C or more: nothing to fit C_th and hA to")  # fmt: skip
    plain, ent = fit_records(recs, False), fit_records(recs, True)
    # with the model's own entropic element its dU/dT is already in the heat (heat_parts)
    entropic = bool(ent.excludes_zero(2)) and "entropic" not in model.config.effects
    fit = ent if entropic else plain
    c, h, d = _unpack(fit.z)
    intervals = {"c_th_j_per_k": _entry(fit, 0, c), "ha_w_per_k": _entry(fit, 1, h)}
    if entropic:
        intervals["dudt_v_per_k"] = _entry(fit, 2, d)
    heat = Heat(c, h, d, entropic)
    rows, sq = [], []
    for r in recs:  # the prediction's own error: the fixed point from the ambient
        p = predict(model, heat, r.frame, r.ambient_k - KELVIN)
        e = p.temp_k - r.measured_k
        sq.append(float(np.mean(e**2)))
        rows.append({"record": r.source, "ambient_c": r.ambient_k - KELVIN,
                     "ambient_from": r.ambient_from, "rmse_k": math.sqrt(sq[-1]),
                     "max_err_k": float(np.max(np.abs(e))), "passes": p.passes})  # fmt: skip
    report = {
        "method": METHOD,
        "ambient_rule": AMBIENT_RULE,
        "bounds": {"c_th_j_per_k": list(C_TH_LIMITS_J_PER_K),
                   "ha_w_per_k": list(HA_LIMITS_W_PER_K),
                   "dudt_v_per_k": list(DUDT_LIMITS_V_PER_K)},
        "intervals": intervals,
        "entropic_candidate": _entry(ent, 2, float(ent.z[2])),
        "records": rows,
        "rmse_k": math.sqrt(float(np.mean(sq))),
        "fixed_point": {"tolerance_k": FIXED_POINT_TOL_K, "max_passes": MAX_PASSES},
    }  # fmt: skip
    return Heat(c, h, d, entropic, report), ""


METHOD = ("lumped: C_th·dT/dt = q − hA·(T − T_amb), q = i·(OCV − V) − i·T·dU/dT, stepped exactly "
          "with q held over each sample; C_th, hA (and dU/dT where its 95 % interval excludes 0) "
          "by least squares of the temperature predicted from the ambient against the measured "
          "one on the training records (each alike), the electrical model held; intervals: "
          "sandwich covariance with each record's residual autocorrelation time")  # fmt: skip


def flags(heat: Heat) -> list[str]:
    """The heat block's parameters pressed against a bound (warning lines)."""
    iv = heat.report.get("intervals", {})
    return [f"heat.{k} = {e['value']:.4g} {UNITS[k]} at a bound of its fit: set by the bound, "
            "not by the records" for k, e in iv.items() if e["at_bound"]]  # fmt: skip


TEMPERATURE_QUANTITIES = frozenset({"rtf", "dinv", "dinv_t", "dtemp", "tk"})
"""The quantities of the compiled simulator's loop that carry the cell temperature
(``model/loopgen.py``'s slots: 2RT/F, 1/T − 1/Tref per sample and per record, T − Tref, T): an
element whose stated physics names one reads the temperature."""

VOLTAGE_BLIND = "the voltage does not depend on the temperature (no element of the model reads it)"
"""What :func:`attach` and diagnosis.json say of a heat block whose model's voltage reads no
temperature (:func:`temperature_readers` empty): the block predicts the cell temperature only."""


def temperature_readers(model) -> list[str]:
    """The model's elements whose voltage term reads the cell temperature, sorted: the
    temperature laws (``Element.needs_temperature``) and any other whose kernel names a
    temperature quantity (:data:`TEMPERATURE_QUANTITIES`; today Butler–Volmer's 2RT/F, which
    runs at 25 °C where a record has no temperature). Read from the elements' statements, so a
    new element is judged by its own physics."""
    import re

    from . import elements

    def reads(name: str) -> bool:
        el = elements.get(name)
        if el.needs_temperature:
            return True
        k = el.kernel
        if k is None:
            return False
        code = [c if isinstance(c, str) else c[1] for c in k.code.values()]
        names = set(k.reads).union(*(re.findall(r"[A-Za-z_]\w*", c)
                                     for c in (*code, *k.flags.values())))  # fmt: skip
        return bool(names & TEMPERATURE_QUANTITIES)

    return sorted(e for e in model.config.effects if reads(e))


def block_summary(model, line: str) -> dict:
    """diagnosis.json's ``heat`` entry: whether model.json holds a heat block, :func:`attach`'s
    line (what was fitted, or why nothing; :data:`VOLTAGE_BLIND` where it applies) and the
    elements whose voltage reads the temperature the block predicts."""
    return {"written": model.heat is not None, "summary": line,
            "voltage_reads_temperature": temperature_readers(model)}  # fmt: skip


def attach(model, checked) -> str:
    """``diagnose``'s hook: ``model.heat`` fitted on its training records (``records.Checked``)
    where they allow (:func:`fit_heat`); returns what was done, for the command's summary (and
    :func:`block_summary` the same for diagnosis.json)."""
    model.heat, why = fit_heat(model, checked)
    if model.heat is None:
        return f"no heat block ({why})"
    h = model.heat
    return (
        f"heat block: C_th {h.c_th:.3g} J/K, hA {h.ha:.3g} W/K"
        + (f", dU/dT {1e3 * h.dudt:.3g} mV/K" if h.entropic else "")
        + f", {h.report['rmse_k']:.2f} K RMS on its training records from the ambient"
        + ("" if temperature_readers(model) else f"; {VOLTAGE_BLIND}")
    )
