"""A fitted model (``model.json``) as a BMS-style lookup table: R0, the RC branches and the OCV
on an SOC × temperature grid, for a simulator written in Simulink, C or a BMS's firmware.

``python -m avoa_pipeline export DIR/model.json --to table --out cell.csv [--soc-grid ...]
[--temperatures ...]`` writes two files:

- ``cell.csv``, one row per grid point (temperature outer, SOC inner; the layout of Simscape's
  table-based battery block and of Plett's ESC tables, read as a 2-D table by any tool):
  ``temperature_c``, ``soc``, ``ocv_v``, ``r0_ohm`` (discharge, I > 0), ``r0_charge_ohm``
  (I < 0), ``r1_ohm``, ``tau1_s``, ``c1_f`` (= τ1/R1), the same three for branches 2 and 3 where
  the model has them, ``r_bv0_ohm`` with Butler–Volmer and ``capacity_ah`` with
  capacity_temperature: every SOC and temperature law of the model evaluated at the grid point
  (:func:`grid_values`, from each element's statement of how its law enters the table,
  ``Element.table``; thermal_tau's in the ``tau`` columns, entropic's in ``ocv_v``).
- ``cell.json`` (the sidecar, :func:`sidecar`): what each column means and its unit, the grids,
  the model's scalars (capacity, the surface-SOC lag κ and τ_d, hysteresis M and γ, the current
  offset, the coulombic efficiency, Butler–Volmer's i0 and its Arrhenius θ, the laws' own
  parameters), the recursion a table simulator runs, what the table cannot express, and how far
  a linear interpolation between the grid points strays from the model's laws at the middle of
  each grid cell (:func:`interpolation_error`).

A table simulator that interpolates linearly in this table and runs the Thevenin recursion in
the sidecar reproduces our simulator (``FittedModel.simulate``) to the interpolation error
(``tests/unit/test_export_table.py``). Hand-written: the laws are the model library's
(``ecm``'s docstring, ``model/elements/``) evaluated on a grid; no library writes such a table.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from .. import __version__, records
from ..errors import UserError
from ..model import ecm, elements
from ..model.elements.element import TableLaw
from ..model.elements.entropic import DUDT_SHAPE
from ..model.fitted import FittedModel

FORMAT = "avoa-pipeline-table"
FORMAT_VERSION = 1

SOC_STEP = 0.01
"""The default SOC grid: 0 to 1 in steps of 0.01 (101 points), plus the model's SOC knots (where
r0_soc, r1_soc and ocv_shape bend). A measured OCV moves by a few mV per 1 % of SOC on its flat
part; the sidecar's ``interpolation_error`` says what the step costs each column (most near
empty, where soc_resistance rises fastest). Give ``--soc-grid`` for another."""
TEMPERATURE_SPAN_K = 10.0
"""The default temperatures of a model whose laws depend on temperature: T_ref ± 10 K. A
model.json does not store its training records' temperature range; a fit at one chamber
temperature sees a few kelvin of self-heating (4 K in Panasonic's training records,
docs/real-data.md), so ± 10 K covers it and a little beyond. Give ``--temperatures`` for the
range you need (the Arrhenius laws extrapolate outside the training records' range)."""
TEMPERATURE_STEP_K = 2.0
"""The default temperature step: an Arrhenius factor with θ = 4,000 K bends by 0.23 % per K²
near 25 °C, so a linear interpolation over 2 K is off by about 0.1 % of the resistance
(h²/8 times the curvature)."""
SOC_RANGE = (0.0, 1.0)
"""A grid SOC lies in [0, 1]: the state of charge a BMS table covers."""
TEMPERATURE_DEPENDENT = frozenset(
    {e.name for e in elements.REGISTRY.values() if e.needs_temperature} | {"butler_volmer"}
)
"""Elements whose laws depend on the cell temperature: those the registry says need one, and
Butler–Volmer (through RT/F, at 25 °C without a temperature)."""
EXPRESSED = frozenset(n for n, e in elements.REGISTRY.items() if isinstance(e.table, TableLaw))
"""The elements whose laws the table writes (each element's ``table``: how its law enters, or why
it cannot). A model with another element is refused in one line rather than written without its
law: the table would be wrong where that element acts."""


def _expressed(name: str) -> bool:
    """Whether the registry has element ``name`` and it says how its law enters the table."""
    return name in elements.REGISTRY and isinstance(elements.get(name).table, TableLaw)


def _laws(model: FittedModel):
    """(p, the model's elements' table laws): p holds the physical values by internal name, and a
    vector element's values at the knots as a function of SOC (linear between, flat beyond)."""
    phys = ecm.physical(model.x, model.knots)
    knots = model.knots.grid()
    p = dict(phys.scalars) | {e: (lambda s, v=v: np.interp(s, knots, v))
                              for e, v in phys.at_knots.items()}  # fmt: skip
    table = model.config.table
    if table is not None and table.dudt_shape().size > 0:  # the slow tests' ∂U/∂T profile
        p[DUDT_SHAPE] = table.entropic_shape
    return p, [elements.get(e).table for e in elements.NAMES if e in model.config.effects]


def _product(value, laws, resistor: str, p, s, tk, tref):
    """``value`` times each law's factor of ``resistor``, by position, then registry order."""
    found = [f if isinstance(f, tuple) else (0, f)
             for law in laws if (f := law.factors.get(resistor)) is not None]  # fmt: skip
    for _, factor in sorted(found, key=lambda pf: pf[0]):
        value = value * factor(p, s, tk, tref)
    return value


def grid_values(model: FittedModel, soc, temperature_c, branches=()) -> pd.DataFrame:
    """Every column of the table at each (temperature, SOC) pair (temperature outer): R0 and the
    RC branches (each where its R is not 0, or numbered in ``branches``) times the factors the
    model's elements state for them (``Element.table``: SOC and temperature laws; ·exp(ρ) on
    charge), the OCV of the SOC (with ocv_shape and the offset) plus the elements' OCV terms,
    and the elements' own columns (Butler–Volmer's slope at I = 0, the capacity at the
    temperature). A model of per-temperature sets: :func:`sets_grid_values`."""
    if model.by_temperature is not None:
        return sets_grid_values(model, soc, temperature_c)
    P = ecm.to_physical(model.x)[0]
    s = np.asarray(soc, dtype=float)
    temps = np.asarray(temperature_c, dtype=float)
    S, T = np.meshgrid(s, temps)  # rows: temperatures, columns: SOC
    S, T = S.ravel(), T.ravel()
    tk = T + 273.15
    p, laws = _laws(model)
    at = (p, S, tk, model.tref_k)
    r0 = _product(P[ecm.R0] * np.ones_like(S), laws, "r0", *at)
    ocv = ecm.ocv_values(P, S, model.knots, model.config.table)
    for law in laws:
        if law.ocv is not None:
            ocv = ocv + law.ocv(*at)
    out = {"temperature_c": T, "soc": S, "ocv_v": ocv, "r0_ohm": r0,
           "r0_charge_ohm": _product(r0, laws, "r0_charge", *at)}  # fmt: skip
    for j, r, tau in _branches(P, branches):
        rj = _product(P[r] * np.ones_like(S), laws, "rc", *at)
        rj = _product(rj, laws, "r1", *at) if j == 1 else rj
        tj = _product(P[tau] * np.ones_like(S), laws, "tau", *at)
        cj = np.divide(tj, rj, out=np.full_like(tj, np.nan), where=rj != 0)  # no C without R
        out |= {f"r{j}_ohm": rj, f"tau{j}_s": tj, f"c{j}_f": cj}
    for law in laws:
        out |= {name: f(*at) for name, (_, _, f) in law.columns.items()}
    return pd.DataFrame(out)


def _branches(P: np.ndarray, keep=()) -> list[tuple[int, int, int]]:
    """The RC branches a table carries: (number, R column, τ column), each where its
    resistance is not 0 (a branch with R = 0 holds no voltage, and its C = τ/R has no value) or
    its number is in ``keep`` (another temperature's set has it); numbered as the model numbers
    them (branch 1 the base's, the others the elements')."""
    branches = [(1, ecm.R1, ecm.TAU1)] + [
        (j, ecm.IDX[f"r{j}"], ecm.IDX[f"ltau{j}"])
        for e in elements.REGISTRY.values() if (j := e.kernel.branch) is not None
    ]  # fmt: skip
    return [(j, r, t) for j, r, t in branches if P[r] != 0 or j in keep]


def sets_grid_values(model: FittedModel, soc, temperature_c) -> pd.DataFrame:
    """:func:`grid_values` of a model of per-temperature sets: the rows at each temperature
    those of ``FittedModel.at_ambient`` there (at a set's ambient, that set's own; between, the
    parameters interpolated in 1/T), with every RC branch any of them carries (R = 0 and C
    empty where one lacks it) and a ``capacity_ah`` column (each set has its own)."""
    runs = [model.at_ambient(t) for t in np.asarray(temperature_c, dtype=float)]
    keep = {j for m in runs for j, _, _ in _branches(ecm.to_physical(m.x)[0])}
    parts = []
    for t, m in zip(np.asarray(temperature_c, dtype=float), runs, strict=True):
        part = grid_values(m, soc, [t], keep)
        if "capacity_ah" not in part.columns:
            part["capacity_ah"] = float(10.0 ** m.x[ecm.IDX["lq"]])
        parts.append(part)
    return pd.concat(parts, ignore_index=True)


def default_soc_grid(model: FittedModel) -> np.ndarray:
    """0 to 1 in SOC_STEP, plus the model's knots inside [0, 1]."""
    uniform = np.round(np.linspace(0.0, 1.0, round(1.0 / SOC_STEP) + 1), 12)
    knots = np.round(model.knots.grid(), 12)  # a knot on the uniform grid is that point
    knots = knots[(knots > SOC_RANGE[0]) & (knots < SOC_RANGE[1])]
    return np.unique(np.concatenate([uniform, knots]))


def default_temperatures(model: FittedModel) -> np.ndarray:
    """T_ref alone for a model whose laws do not depend on temperature; else T_ref ±
    TEMPERATURE_SPAN_K in TEMPERATURE_STEP_K (°C, rounded to 0.01 K). A model of
    per-temperature sets: the sets' ambients (as a BMS table holds its test temperatures)."""
    if model.by_temperature is not None:
        return np.array([a for a, _ in model.by_temperature])
    tref_c = model.tref_k - 273.15
    if not TEMPERATURE_DEPENDENT & set(model.config.effects):
        return np.array([round(tref_c, 2)])
    n = round(2 * TEMPERATURE_SPAN_K / TEMPERATURE_STEP_K)
    return np.round(tref_c - TEMPERATURE_SPAN_K + TEMPERATURE_STEP_K * np.arange(n + 1), 2)


def parse_grid(text: str, option: str, limits: tuple[float, float], unit: str) -> np.ndarray:
    """A grid given on the command line: comma-separated numbers, strictly increasing, inside
    ``limits``; a one-line UserError naming ``option`` otherwise."""
    try:
        values = np.array([float(v) for v in text.split(",")])
    except ValueError:
        raise UserError(f"{option} {text!r}: need comma-separated numbers") from None
    if not np.all(np.isfinite(values)):
        raise UserError(f"{option} {text!r}: need finite numbers")
    lo, hi = limits
    if values.min() < lo or values.max() > hi:
        raise UserError(f"{option} {text!r}: every value must lie in [{lo:g}, {hi:g}] {unit}")
    if np.any(np.diff(values) <= 0):
        raise UserError(f"{option} {text!r}: values must increase strictly")
    return values


def check_grids(soc: np.ndarray, temperature_c: np.ndarray) -> None:
    """The grids a table needs: at least 2 SOC values (a table interpolates between them), 1 or
    more temperatures, inside SOC_RANGE and ``records.TEMPERATURE_RANGE_C``."""
    if soc.size < 2:
        raise UserError("--soc-grid: need at least 2 SOC values to interpolate between")
    grids = (("--soc-grid", soc, SOC_RANGE),
             ("--temperatures", temperature_c, records.TEMPERATURE_RANGE_C))  # fmt: skip
    for what, v, (lo, hi) in grids:
        if v.size == 0 or v.min() < lo or v.max() > hi or np.any(np.diff(v) <= 0):
            raise UserError(f"{what}: values must increase strictly inside [{lo:g}, {hi:g}]")


# ----------------------------------------------------------------------------------------------
# the sidecar


_RC_COLUMNS = {
    "r{j}_ohm": ("Ω", "RC branch {j}: resistance"),
    "tau{j}_s": ("s", "RC branch {j}: time constant (fixed, C{j} following R{j}, unless "
                 "thermal_tau: then τ{j}·exp(θτ·(1/T − 1/tref_k)))"),
    "c{j}_f": ("F", "RC branch {j}: capacitance τ{j}/R{j}"),
}  # fmt: skip
COLUMNS = {
    "temperature_c": ("°C", "the cell temperature of this row (grid)"),
    "soc": ("1", "the state of charge of this row (grid): the bulk SOC, which counts charge"),
    "ocv_v": ("V", "open-circuit voltage at this SOC: the model's OCV source (measured table or "
              "the paper's eq. 5) with ocv_shape and the fitted offset, plus entropic's "
              "(∂U/∂T)·(T − tref_k) at this row's temperature; with diffusion, read it at the "
              "surface SOC s − δ (scalars)"),
    "r0_ohm": ("Ω", "series resistance while discharging or at rest (I ≥ 0)"),
    "r0_charge_ohm": ("Ω", "series resistance while charging (I < 0): r0_ohm times "
                      "exp(r0_charge_log_ratio); equal to r0_ohm without r0_charge"),
    **{k.format(j=j): (u, m.format(j=j))
       for j in (1, *(e.kernel.branch for e in elements.REGISTRY.values() if e.kernel.branch))
       for k, (u, m) in _RC_COLUMNS.items()},
    **{name: (unit, meaning) for e in elements.REGISTRY.values()
       if isinstance(e.table, TableLaw) for name, (unit, meaning, _) in e.table.columns.items()},
}  # fmt: skip
"""Every column a table may have: (unit, meaning); the elements' own from their ``table``."""

RECURSION = (
    "Per sample k (current i_k positive on discharge, held over [t_k, t_k+1), Δt = t_k+1 − t_k; "
    "every column read at (T_k, s_k)): i = i_meas + current_offset_a; "
    "V_k = ocv_v(s_k − δ_k) + hysteresis_m_v·h_k − R0·i − Σ_j v_j − BV(i), R0 = r0_ohm if i ≥ 0 "
    "else r0_charge_ohm, BV(i) = (2RT/F)·asinh(i·bv_inv_i0(T)/2) (0 without Butler–Volmer); "
    "v_j ← a_j·v_j + (1 − a_j)·r_j_ohm·i, a_j = exp(−Δt/tau_j_s); "
    "δ ← a_d·δ + (1 − a_d)·diffusion_soc_per_a·i, a_d = exp(−Δt/diffusion_tau_s); "
    "ie = i if i > 0 else coulombic_efficiency·i; "
    "h ← e·h − (1 − e)·sgn(i), e = exp(−|hysteresis_gamma·ie·Δt/(3600·Q)|); "
    "s ← s − ie·Δt/(3600·Q), Q = the capacity_ah column at T_k where the table has one "
    "(capacity_temperature, or per-temperature sets), else the scalar capacity_ah. States "
    "start at v_j = δ = h = 0; the initial SOC is the record's (avoa-pipeline reads it from "
    "the OCV at the first sample)."
)


def scalars(model: FittedModel) -> dict:
    """The model's values that do not vary over the grid, report-named, with unit and meaning
    (neutral values where the model lacks the element: then they change nothing)."""
    p = model.parameters()
    P = ecm.to_physical(model.x)[0]
    effects = set(model.config.effects)

    def entry(value, unit, meaning):
        return {"value": float(value), "unit": unit, "meaning": meaning}

    out = {
        "capacity_ah": entry(p["capacity_ah"], "A·h", "the capacity the SOC counts (at tref_k "
                             "with capacity_temperature: then the capacity_ah column)"),
        "tref_k": entry(model.tref_k, "K", "the reference temperature of the Arrhenius laws "
                        "(the training records' mean temperature)"),
        "diffusion_soc_per_a": entry(P[ecm.KD], "1/A", "diffusion: κ, the surface-SOC lag per A "
                                     "held (0: none)"),
        "diffusion_tau_s": entry(P[ecm.TAUD], "s", "diffusion: τ_d, the lag's time constant"),
        "hysteresis_m_v": entry(P[ecm.HM], "V", "hysteresis: M, the voltage at h = ±1 (0: none)"),
        "hysteresis_gamma": entry(P[ecm.GAM], "1", "hysteresis: γ, its rate per capacity of "
                                  "charge"),
        "current_offset_a": entry(P[ecm.IOFF], "A", "an offset of the training records' current "
                                  "sensor, added to a measured current (0 for a true current)"),
        "coulombic_efficiency": entry(P[ecm.ETA], "1", "the share of a charge the SOC counts"),
    }  # fmt: skip
    if "butler_volmer" in effects:
        out["bv_inv_i0_per_a"] = entry(P[ecm.BVG], "1/A", "Butler–Volmer: 1/i0 at tref_k")
        out["bv_theta_i0_k"] = entry(P[ecm.THBV], "K", "bv_arrhenius: 1/i0 times "
                                     "exp(θ·(1/T − 1/tref_k)) (0: none)")  # fmt: skip
    if "thermal" in effects:
        out["thermal_theta_r0_k"] = entry(P[ecm.TH0], "K", "Arrhenius θ of R0 (in the columns)")
        out["thermal_theta_rc_k"] = entry(P[ecm.TH1], "K", "Arrhenius θ of the RC resistances "
                                          "(in the columns)")  # fmt: skip
    # the temperature laws of issue 28: in the columns, their parameters here for reference
    if "thermal_tau" in effects:
        out["thermal_theta_tau_k"] = entry(P[ecm.THTAU], "K", "Arrhenius θτ of the RC time "
                                           "constants (in the tau columns)")  # fmt: skip
    if "entropic" in effects:
        table = model.config.table
        profile = table is not None and table.dudt_shape().size > 0
        out["entropic_dudt_v_per_k"] = entry(P[ecm.DUDT], "V/K", "∂U/∂T of the OCV (in the "
                                             "ocv_v column)" + (
            "; where the slow tests' profile peaks: the profile's scale is this over "
            f"{table.dudt_peak():.4g} V/K" if profile else ""))  # fmt: skip
    if "capacity_temperature" in effects:
        out["capacity_temp_coeff_per_k"] = entry(P[ecm.KQ], "1/K", "κQ: the capacity is "
                                                 "Q·(1 + κQ·(T − tref_k)) (in the capacity_ah "
                                                 "column)")  # fmt: skip
    return out


def cannot(model: FittedModel) -> list[str]:
    """What the table cannot express, for this model."""
    effects = set(model.config.effects)
    out = ["Between grid points a linear interpolation differs from the model's laws "
           "(exponential in SOC and in 1/T): interpolation_error says by how much, per column, "
           "at the middle of each grid cell. Outside the grid the model's laws go on; a table "
           "holds or extrapolates, as its reader decides."]  # fmt: skip
    if "butler_volmer" in effects:
        out.append("Butler–Volmer's overpotential is nonlinear in the current, "
                   "(2RT/F)·asinh(I/(2·i0(T))): a table over SOC and temperature holds only its "
                   "slope at I = 0 (r_bv0_ohm), which overstates the drop at large currents "
                   "(x/asinh(x) times the drop, x = I/(2·i0): 1.05 at x = 0.6, 1.26 at x = 1.5); "
                   "bv_inv_i0_per_a and bv_theta_i0_k give the law")  # fmt: skip
    if "diffusion" in effects:
        out.append(
            "diffusion is a state, not a column: the OCV is read at the surface SOC "
            "s − δ, δ following the current with diffusion_soc_per_a and diffusion_tau_s"
        )
    if "hysteresis" in effects:
        out.append(
            "hysteresis is a state, not a column: V += hysteresis_m_v·h, h following the "
            "charge counted with hysteresis_gamma (the recursion)"
        )
    if "current_offset" in effects:
        out.append(
            "current_offset_a belongs to the training records' current sensor, not to "
            "the cell: add it to a current measured by that sensor, not to a true one"
        )
    if "coulombic_efficiency" in effects:
        out.append("coulombic_efficiency: charge counts less than discharge (the recursion)")
    if model.by_temperature is not None:
        out.append("per-temperature parameter sets: the model reads them at a record's ambient "
                   "(its sidecar's, else its first temperature sample) and holds them through "
                   "the record, where this table's reader may follow the cell temperature; "
                   "between the sets the model interpolates linearly in 1/T, a table reader "
                   "linearly in T (interpolation_error); the scalars differ by set: "
                   "by_temperature gives each set's, scalars the top level's")  # fmt: skip
    return out


def interpolation_error(model: FittedModel, soc: np.ndarray, temperature_c: np.ndarray) -> dict:
    """Per column, the largest |linear interpolation − the model's law| at the middle of each
    grid cell (SOC midpoints at every grid temperature, temperature midpoints at every grid
    SOC): absolute (the column's unit), where (SOC, °C), and the largest relative to the law."""
    on_grid = grid_values(model, soc, temperature_c)
    mid_s = 0.5 * (soc[1:] + soc[:-1])
    pairs = [(grid_values(model, mid_s, temperature_c), _midpoints(on_grid, soc.size, axis=1))]
    if temperature_c.size > 1:
        mid_t = 0.5 * (temperature_c[1:] + temperature_c[:-1])
        pairs.append((grid_values(model, soc, mid_t), _midpoints(on_grid, soc.size, axis=0)))
    out = {}
    for col in on_grid.columns[2:]:
        worst = {"max_abs": 0.0, "at_soc": None, "at_temperature_c": None, "max_rel": 0.0}
        for exact, linear in pairs:
            law = exact[col].to_numpy()
            d = np.abs(linear[col] - law)
            d = np.where(np.isfinite(d), d, 0.0)  # an empty C (a branch without R) strays nowhere
            k = int(np.argmax(d))
            if d[k] > worst["max_abs"]:
                worst |= {"max_abs": float(d[k]), "at_soc": float(exact["soc"].iloc[k]),
                          "at_temperature_c": float(exact["temperature_c"].iloc[k])}  # fmt: skip
            rel = np.divide(d, np.abs(law), out=np.zeros_like(d), where=law != 0)
            worst["max_rel"] = max(worst["max_rel"], float(rel.max()))
        out[col] = worst
    return out


def _midpoints(frame: pd.DataFrame, n_soc: int, axis: int) -> dict:
    """The mean of neighbouring grid values (a linear interpolation at the middle), along SOC
    (``axis`` 1) or temperature (0), per column, flattened as :func:`grid_values` orders."""
    out = {}
    for col in frame.columns[2:]:
        v = frame[col].to_numpy().reshape(-1, n_soc)
        mid = 0.5 * (v[:, 1:] + v[:, :-1]) if axis == 1 else 0.5 * (v[1:] + v[:-1])
        out[col] = mid.ravel()
    return out


SETS_COLUMNS = {
    "temperature_c": ("°C", "the ambient of this row (grid): at a per-temperature set's ambient "
                      "the rows are that set's own, between two sets each parameter is "
                      "interpolated linearly in 1/T (absolute temperature), outside them the "
                      "nearest set's; a set with a temperature law has it evaluated here"),
    "capacity_ah": ("A·h", "the capacity the SOC counts at this row's temperature (each "
                    "per-temperature set has its own)"),
}  # fmt: skip
"""What two columns mean in a table of a model of per-temperature sets (``by_temperature``)."""


def _column(model: FittedModel, name: str) -> tuple[str, str]:
    """(unit, meaning) of a column of ``model``'s table."""
    if model.by_temperature is not None and name in SETS_COLUMNS:
        return SETS_COLUMNS[name]
    return COLUMNS[name]


def sidecar(model: FittedModel, source: str, table: pd.DataFrame, soc: np.ndarray,
            temperature_c: np.ndarray, temperature_note: str) -> dict:  # fmt: skip
    out = {
        "format": FORMAT,
        "format_version": FORMAT_VERSION,
        "package_version": __version__,
        "source": str(source),
        "configuration": model.config.name,
        "layout": "one row per grid point, temperature outer, SOC inner: "
                  f"{temperature_c.size} temperatures × {soc.size} SOC values",
        "grid": {"soc": [float(v) for v in soc],
                 "temperature_c": [float(v) for v in temperature_c],
                 "temperature_note": temperature_note},
        "columns": {c: dict(zip(("unit", "meaning"), _column(model, c), strict=True))
                    for c in table.columns},
        "scalars": scalars(model),
        "recursion": RECURSION,
        "cannot": cannot(model),
        "interpolation_error": interpolation_error(model, soc, temperature_c),
        "parameters": model.parameters(),
    }  # fmt: skip
    if model.by_temperature is not None:  # each set's scalars and parameters, coldest first
        out["by_temperature"] = [{"ambient_c": float(a), "scalars": scalars(m),
                                  "parameters": m.parameters()}
                                 for a, m in model.by_temperature]  # fmt: skip
    return out


def export_table(model: FittedModel, source: str, soc: np.ndarray | None = None,
                 temperature_c: np.ndarray | None = None) -> tuple[pd.DataFrame, dict]:  # fmt: skip
    """(the table, its sidecar) of ``model`` on the grids (defaults: :func:`default_soc_grid`,
    :func:`default_temperatures`)."""
    if model.config.load_ohm is not None:
        raise UserError(f"{source}: field 'load_ohm': the paper's load resistor is part of its "
                        "test rig, not of the cell; a table of the cell has none")  # fmt: skip
    unknown = [e for e in model.config.effects if not _expressed(e)]
    if unknown:  # the element's own reason where it gives one
        why = "; ".join(f"{e}: {elements.get(e).table}" for e in unknown if e in elements.REGISTRY)
        raise UserError(f"{source}: field 'effects': the table export does not write the law of "
                        f"{', '.join(unknown)}" + (f" ({why})" if why else ""))  # fmt: skip
    soc = default_soc_grid(model) if soc is None else np.asarray(soc, dtype=float)
    if temperature_c is None:
        temperature_c = default_temperatures(model)
        note = ("default: the ambients of the model's per-temperature parameter sets"
                if model.by_temperature is not None else
                "default: T_ref alone (the model's laws do not depend on temperature)"
                if temperature_c.size == 1 else
                f"default: T_ref ± {TEMPERATURE_SPAN_K:g} K in {TEMPERATURE_STEP_K:g} K steps "
                "(model.json does not store its training records' temperature range; "
                "--temperatures sets them)")  # fmt: skip
    else:
        temperature_c = np.asarray(temperature_c, dtype=float)
        note = "given (--temperatures)"
    check_grids(soc, temperature_c)
    table = grid_values(model, soc, temperature_c)
    return table, sidecar(model, source, table, soc, temperature_c, note)
