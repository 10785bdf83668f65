"""Experiment 2: R0, Rtr and τtr of the Samsung 30Q from its HPPC pulses at 20/30/40 °C, and an
Arrhenius fit R(T) = A·exp(Ea / (R_gas·T)) of each against temperature.

Per 1C discharge pulse (10 s at 3 A, then 180 s rest; 20 pulses per file, 100 % → 5 % SOC):

- **R0 (step)**: the instantaneous voltage step, (V before − V at the first pulse sample) / ΔI. With
  1 s sampling the first sample already holds up to 1 s of the fast polarisation, so this is the
  1-s resistance. The step at the pulse's end (``r0_release_ohm``) is recorded beside it.
- **Rtr, τtr**: the model library's fit (``model.fitted.fit_model``) of R0 and one RC branch to
  the pulse and its rest (window: the last rest sample before the pulse to the last sample before
  the next current step), with the discretisation of the paper's eq. 3:
  Vtr[k+1] = a·Vtr[k] + Rtr·(1 − a)·I[k], a = exp(−Ts/τ), V = E − s·q − R0·I − Vtr
  (:func:`pulse_config`). Free: E (the OCV at the window's start), R0 (``r0_fit_ohm``), Rtr, τ. The
  OCV's change with the charge the pulse removes (8 mAh, 2-9 mV) is not left to the fit: its slope
  s [V/Ah] comes from the rested voltages before consecutive pulses (1 h rests) against the charge
  between them. Vtr starts at zero (the cell rested 1 h).
- SOC of a pulse: 1 − (charge discharged before it)/(nominal 3.0 Ah); the programmed 5 % steps are
  0.15 Ah = 5 % of the nominal capacity.

Arrhenius: ordinary least squares of ln R on 1/T (T = mean measured cell temperature over the
pulse window, K), Ea = R_gas·slope, 95 % CI from Student's t. With three temperatures a per-pulse
fit has **one** residual degree of freedom (t = 12.7): its CI is wide, and the Arrhenius *form*
itself is tested by that one degree of freedom only. Two pooled estimates, one Ea common to the
pulses of ``real.samsung.pooled_soc_pct`` with a prefactor per pulse: ``pooled_pulses`` treats
every pulse as an independent measurement (dof = pulses × 3 − pulses − 1; optimistic: all pulses
at one temperature come from one run of one cell, so a run-level error moves them together);
``pooled_runs`` fits the three SOC-adjusted run means (dof 1), which is what three temperatures
can really support. ``pair`` rows give the two-point Ea of 20→30 and 30→40 °C: equal values are
what the Arrhenius form predicts.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

import numpy as np
import pandas as pd
from scipy import constants, stats

from ... import records
from ...errors import DataError
from ...io import atomic_path
from ...model import ecm
from ...model.ecm import Config, OcvTable
from ...model.fitted import fit_model

GAS_CONSTANT = constants.R  # J/(mol K)
ZERO_C = constants.zero_Celsius

REST_CURRENT_A = 0.1
"""|current| below this counts as rest (the charge pulse is 0.3 A, noise a few mA)."""

QUANTITIES = ("r0_step_ohm", "r0_fit_ohm", "rtr_ohm", "tau_s")
"""Columns of the per-pulse table that get an Arrhenius fit."""

RC_COLUMNS = (
    "temperature", "ambient_c", "pulse", "soc_pct", "q_out_ah", "cell_temp_c", "current_a",
    "ocv_v", "ocv_slope_v_per_ah", "r0_step_ohm", "r0_release_ohm", "r0_fit_ohm", "rtr_ohm",
    "tau_s", "rtr_se_ohm", "tau_se_s", "fit_rmse_mv", "n_samples", "min_voltage_v", "pooled",
)  # fmt: skip

ARRHENIUS_COLUMNS = (
    "quantity", "scope", "pulse", "soc_pct", "soc_range_pct", "temperatures", "n_points", "dof",
    "ea_kj_mol", "ea_se_kj_mol", "ea_ci_low_kj_mol", "ea_ci_high_kj_mol", "prefactor", "rmse_ln",
    "ratio_low_high",
)  # fmt: skip


def find_pulses(current_a: np.ndarray, min_current_a: float, min_samples: int, max_samples: int):
    """[start, end) of each run of ``min_samples``..``max_samples`` samples above
    ``min_current_a`` that has a rest sample before it."""
    hi = np.r_[False, current_a > min_current_a, False]
    edges = np.flatnonzero(np.diff(hi.astype(int)))
    starts, ends = edges[::2], edges[1::2]
    keep = (ends - starts >= min_samples) & (ends - starts <= max_samples) & (starts >= 1)
    return [(int(a), int(b)) for a, b in zip(starts[keep], ends[keep], strict=True)]


def pulse_config(e_v: float, ocv_slope: float) -> Config:
    """The model library's configuration of a pulse window: R0 and one RC on an OCV that falls
    linearly with the charge the pulse removes, OCV = E − s·q. Written as a table over SOC with a
    nominal 1 Ah capacity and the window starting at SOC 1, so SOC = 1 − q (q in Ah); the table's
    fitted offset is the correction to E."""
    grid = np.linspace(0.0, 1.0, 1001)
    table = OcvTable(0.0, grid[1], np.ascontiguousarray(e_v + ocv_slope * (grid - 1.0)))
    return Config((), table)


def rc_voltage(params, current_a: np.ndarray, ocv_slope: float, ts: float) -> np.ndarray:
    """Terminal voltage of the pulse model (E, R0, Rtr, τ) over a window (the library's
    simulator; the input enters the RC branch one sample late, as in eq. 3)."""
    e, r0, rtr, tau = params
    frame = pd.DataFrame({"time_s": np.arange(current_a.size) * ts, "current_a": current_a,
                          "voltage_v": np.zeros(current_a.size)})  # fmt: skip
    x = ecm.vector({"capacity_ah": 1.0, "soc0": 1.0, "r0_ohm": r0, "r1_ohm": rtr,
                    "tau1_s": tau})  # fmt: skip
    cfg = pulse_config(e, ocv_slope)
    return ecm.simulate_rows(ecm.Record.from_frame(frame), x, ecm.Knots(0.0, 0.2), cfg.table)[:, 0]


def fit_pulse(current_a, voltage_v, ts: float, ocv_slope: float, r0_guess: float) -> dict:
    """R0, Rtr, τ (and E) of one pulse window by the library's least squares (``fit_model``:
    capacity and initial SOC held, the offset of E free); standard errors of Rtr and τ from the
    Gauss–Newton covariance at the optimum. ``r0_guess`` is kept for the record: the library
    starts R0 from the window's own voltage steps."""
    frame = pd.DataFrame({"time_s": np.arange(len(current_a)) * ts, "current_a": current_a,
                          "voltage_v": voltage_v})  # fmt: skip
    fit = fit_model(frame, pulse_config(float(voltage_v[0]), ocv_slope), capacity_ah=1.0,
                    soc0=1.0)  # fmt: skip
    m = fit.model
    p = m.parameters()
    # covariance of (offset, R0, Rtr, τ) from a forward-difference Jacobian in physical units
    names = ("voltage_offset_v", "r0_ohm", "r1_ohm", "tau1_s")
    base = [p[n] for n in names]
    e0 = float(voltage_v[0]) + base[0]

    def model_v(q):
        return rc_voltage((float(voltage_v[0]) + q[0], q[1], q[2], q[3]), np.asarray(current_a,
                          dtype=float), ocv_slope, ts)  # fmt: skip

    v0 = model_v(base)
    resid = v0 - voltage_v
    jac = np.empty((resid.size, 4))
    for j, q in enumerate(base):
        h = 1e-6 * max(abs(q), 1e-3)
        step = list(base)
        step[j] = q + h
        jac[:, j] = (model_v(step) - v0) / h
    dof = max(len(voltage_v) - 4, 1)
    s2 = float(resid @ resid) / dof
    try:
        se = np.sqrt(np.clip(np.diag(np.linalg.inv(jac.T @ jac) * s2), 0, None))
    except np.linalg.LinAlgError:
        se = np.full(4, np.nan)
    return {
        "e_v": e0,
        "r0_fit_ohm": p["r0_ohm"],
        "rtr_ohm": p["r1_ohm"],
        "tau_s": p["tau1_s"],
        "rtr_se_ohm": se[2],
        "tau_se_s": se[3],
        "fit_rmse_mv": float(np.sqrt(np.mean(resid**2)) * 1e3),
        "r0_guess_ohm": r0_guess,
    }


def pulse_table(
    frame: pd.DataFrame, sidecar: Mapping, cfg_samsung: Mapping, temperature: str
) -> pd.DataFrame:
    """One row per 1C discharge pulse of a canonical HPPC record (columns :data:`RC_COLUMNS`)."""
    source = str(sidecar.get("source_file", temperature))
    t = frame["time_s"].to_numpy()
    i = frame["current_a"].to_numpy()
    v = frame["voltage_v"].to_numpy()
    temp = frame["temperature_c"].to_numpy()
    dt = np.diff(t)
    ts = float(np.median(dt))
    if np.max(np.abs(dt - ts)) > 1e-6 * ts:
        raise DataError(f"{source}: column 'time_s': not uniformly sampled (HPPC fit needs it)")
    lo, hi = cfg_samsung["pulse_samples"]
    pulses = find_pulses(i, float(cfg_samsung["pulse_min_current_a"]), int(lo), int(hi))
    if len(pulses) < 3:
        raise DataError(
            f"{source}: column 'current_a': {len(pulses)} discharge pulses found; need 3"
        )
    q_out = np.r_[0.0, np.cumsum(i[:-1])] * ts / 3600.0
    starts = np.array([a for a, _ in pulses])
    ocv = v[starts - 1]
    # OCV slope from the rested voltages before consecutive pulses (1 h rests)
    slope = -np.gradient(ocv, q_out[starts])
    q_nom = float(sidecar.get("nominal_capacity_ah", cfg_samsung["nominal_capacity_ah"]))
    soc_lo, soc_hi = cfg_samsung["pooled_soc_pct"]
    rows = []
    for j, (a, b) in enumerate(pulses, start=1):
        rest = np.flatnonzero(np.abs(i[b:]) >= REST_CURRENT_A)
        end = b + (int(rest[0]) if rest.size else len(i) - b)
        if end - b < 10:
            raise DataError(f"{source}: pulse {j} at time_s {t[a]:g}: no rest after it")
        w = slice(a - 1, end)
        d_i_on = i[a] - i[a - 1]
        d_i_off = i[b - 1] - i[b]
        r0_step = (v[a - 1] - v[a]) / d_i_on
        fit = fit_pulse(i[w], v[w], ts, float(slope[j - 1]), r0_step)
        soc = 100.0 * (1.0 - q_out[a] / q_nom)
        rows.append(
            {
                "temperature": temperature,
                "ambient_c": float(sidecar["ambient_temperature_c"]),
                "pulse": j,
                "soc_pct": soc,
                "q_out_ah": q_out[a],
                "cell_temp_c": float(np.mean(temp[w])),
                "current_a": float(np.mean(i[a:b])),
                "ocv_v": v[a - 1],
                "ocv_slope_v_per_ah": float(slope[j - 1]),
                "r0_step_ohm": r0_step,
                "r0_release_ohm": (v[b] - v[b - 1]) / d_i_off,
                **{
                    k: fit[k]
                    for k in (
                        "r0_fit_ohm",
                        "rtr_ohm",
                        "tau_s",
                        "rtr_se_ohm",
                        "tau_se_s",
                        "fit_rmse_mv",
                    )
                },
                "n_samples": end - a + 1,
                "min_voltage_v": float(np.min(v[w])),
                "pooled": bool(soc_lo - 0.5 <= soc <= soc_hi + 0.5),
            }
        )
    return pd.DataFrame(rows, columns=list(RC_COLUMNS))


def rc_vs_temperature(canonical_csvs: Mapping[str, str | Path], cfg_samsung: Mapping):
    """The per-pulse table of every temperature (keys like "20degC" → canonical CSV)."""
    tables = []
    for temperature, path in canonical_csvs.items():
        record = records.read(path)
        tables.append(pulse_table(record.frame, record.meta, cfg_samsung, temperature))
    rc = pd.concat(tables, ignore_index=True)
    counts = rc.groupby("temperature")["pulse"].max()
    if counts.nunique() != 1:
        raise DataError(
            "Samsung HPPC: the temperatures have different pulse counts "
            f"({counts.to_dict()}); pulses are matched across temperatures by number"
        )
    return rc.sort_values(["pulse", "ambient_c"], ignore_index=True)


def _ols(x: np.ndarray, y: np.ndarray):
    """Coefficients, covariance, residuals and dof of y = x @ beta."""
    beta, *_ = np.linalg.lstsq(x, y, rcond=None)
    resid = y - x @ beta
    dof = len(y) - x.shape[1]
    s2 = float(resid @ resid) / dof if dof > 0 else np.nan
    cov = np.linalg.inv(x.T @ x) * s2
    return beta, cov, resid, dof


def arrhenius(temperature_k, values, level: float = 0.95) -> dict:
    """Ea [kJ/mol] with its standard error and ``level`` CI, and A, from R(T) = A·exp(Ea/(R T))."""
    tk = np.asarray(temperature_k, dtype=float)
    y = np.asarray(values, dtype=float)
    if tk.shape != y.shape or tk.size < 2:
        raise DataError("Arrhenius fit: need matching temperature and value arrays, 2 or more")
    if np.any(y <= 0) or np.any(tk <= 0):
        raise DataError("Arrhenius fit: values and temperatures [K] must be positive")
    x = np.c_[np.ones_like(tk), 1.0 / tk]
    return _summary(x, np.log(y), 1, level, prefactor_col=0)


def arrhenius_pooled(temperature_k, values, groups, level: float = 0.95) -> dict:
    """One Ea shared by all groups (e.g. SOC levels), one prefactor per group."""
    tk = np.asarray(temperature_k, dtype=float)
    y = np.asarray(values, dtype=float)
    g = pd.Categorical(np.asarray(groups))
    if np.any(y <= 0) or np.any(tk <= 0):
        raise DataError("Arrhenius fit: values and temperatures [K] must be positive")
    dummies = np.eye(len(g.categories))[g.codes]
    x = np.c_[1.0 / tk, dummies]
    return _summary(x, np.log(y), 0, level, prefactor_col=None)


def _summary(x, ln_y, slope_col: int, level: float, prefactor_col) -> dict:
    beta, cov, resid, dof = _ols(x, ln_y)
    ea = GAS_CONSTANT * beta[slope_col] / 1e3
    se = GAS_CONSTANT * np.sqrt(cov[slope_col, slope_col]) / 1e3 if dof > 0 else np.nan
    half = stats.t.ppf(0.5 + level / 2, dof) * se if dof > 0 else np.nan
    return {
        "n_points": len(ln_y),
        "dof": dof,
        "ea_kj_mol": ea,
        "ea_se_kj_mol": se,
        "ea_ci_low_kj_mol": ea - half,
        "ea_ci_high_kj_mol": ea + half,
        "prefactor": float(np.exp(beta[prefactor_col])) if prefactor_col is not None else np.nan,
        "rmse_ln": float(np.sqrt(np.mean(resid**2))),
    }


def _pulse_rows(rc: pd.DataFrame, q: str, label: str, level: float) -> list[dict]:
    """One Arrhenius fit of quantity ``q`` per pulse seen at two temperatures or more."""
    rows = []
    for pulse, sub in rc.groupby("pulse"):
        if sub["ambient_c"].nunique() < 2:
            continue
        fit = arrhenius(sub["cell_temp_c"] + ZERO_C, sub[q], level)
        ratio = sub.sort_values("ambient_c")[q].to_numpy()
        rows.append(
            {
                "quantity": q,
                "scope": "pulse",
                "pulse": pulse,
                "soc_pct": float(sub["soc_pct"].mean()),
                "soc_range_pct": "",
                "temperatures": label,
                **fit,
                "ratio_low_high": ratio[0] / ratio[-1],
            }
        )
    return rows


def _pooled_rows(rc: pd.DataFrame, q: str, temps: list, label: str, level: float) -> list[dict]:
    """Quantity ``q`` pooled over the pulses seen at every temperature: one fit with a level per
    pulse, one of the SOC-adjusted run means, and one per pair of neighbouring runs."""
    rows = []
    pool = rc[rc["pooled"]]
    complete = pool.groupby("pulse")["ambient_c"].transform("nunique") == len(temps)
    pool = pool[complete]
    if pool.empty:
        return []
    soc_range = f"{pool['soc_pct'].min():.0f}-{pool['soc_pct'].max():.0f}"
    fit = arrhenius_pooled(pool["cell_temp_c"] + ZERO_C, pool[q], pool["pulse"], level)
    # SOC-adjusted run means: ln R minus its pulse's mean over temperatures, averaged per run
    ln = np.log(pool[q].to_numpy())
    adj = ln - pool.assign(ln=ln).groupby("pulse")["ln"].transform("mean").to_numpy()
    runs = (
        pool.assign(adj=adj, tk=pool["cell_temp_c"] + ZERO_C)
        .groupby("ambient_c")[["adj", "tk"]]
        .mean()
        .sort_index()
    )
    ratio_runs = float(np.exp(runs["adj"].iloc[0] - runs["adj"].iloc[-1]))
    rows.append(
        {
            "quantity": q,
            "scope": "pooled_pulses",
            "soc_pct": np.nan,
            "temperatures": label,
            "soc_range_pct": soc_range,
            **fit,
            "ratio_low_high": ratio_runs,
        }
    )
    runs_fit = arrhenius(runs["tk"].to_numpy(), np.exp(runs["adj"].to_numpy()), level)
    runs_fit["prefactor"] = np.nan  # relative to the pulse means: not a resistance
    rows.append(
        {
            "quantity": q,
            "scope": "pooled_runs",
            "soc_pct": np.nan,
            "temperatures": label,
            "soc_range_pct": soc_range,
            **runs_fit,
            "ratio_low_high": ratio_runs,
        }
    )
    for (t1, r1), (t2, r2) in zip(runs.iloc[:-1].iterrows(), runs.iloc[1:].iterrows(), strict=True):
        pair = arrhenius([r1["tk"], r2["tk"]], np.exp([r1["adj"], r2["adj"]]), level)
        pair["prefactor"] = np.nan
        rows.append(
            {
                "quantity": q,
                "scope": "pair",
                "soc_pct": np.nan,
                "temperatures": f"{t1:g},{t2:g}",
                "soc_range_pct": soc_range,
                **pair,
                "ratio_low_high": float(np.exp(r1["adj"] - r2["adj"])),
            }
        )
    return rows


def arrhenius_table(rc: pd.DataFrame, level: float = 0.95) -> pd.DataFrame:
    """Every Arrhenius fit of :data:`QUANTITIES`: per pulse, pooled two ways, and pairs."""
    rows = []
    temps = sorted(rc["ambient_c"].unique())
    label = ",".join(f"{t:g}" for t in temps)
    for q in QUANTITIES:
        rows += _pulse_rows(rc, q, label, level)
        rows += _pooled_rows(rc, q, temps, label, level)
    return pd.DataFrame(rows, columns=list(ARRHENIUS_COLUMNS))


def _write_csv(df: pd.DataFrame, path) -> None:
    with atomic_path(path) as tmp:
        df.to_csv(tmp, index=False)


def experiment(canonical_csvs: Mapping[str, str | Path], cfg_samsung: Mapping, out_rc,
               out_arrhenius):  # fmt: skip
    """Experiment 2 end to end: both CSV outputs, written atomically; returns both tables."""
    rc = rc_vs_temperature(canonical_csvs, cfg_samsung)
    arr = arrhenius_table(rc)
    _write_csv(rc, out_rc)
    _write_csv(arr, out_arrhenius)
    return rc, arr


def summary(arr: pd.DataFrame) -> pd.DataFrame:
    """The report's table: pooled and pairwise Ea of each quantity, and the per-pulse spread."""
    rows = []
    for q, sub in arr.groupby("quantity", sort=False):
        per = sub[sub["scope"] == "pulse"]
        pooled = sub[sub["scope"] == "pooled_pulses"]
        runs = sub[sub["scope"] == "pooled_runs"]
        pairs = sub[sub["scope"] == "pair"]
        if pooled.empty:
            continue
        p, r = pooled.iloc[0], runs.iloc[0]
        rows.append(
            {
                "quantity": q,
                "SOC range [%]": p["soc_range_pct"],
                "Ea [kJ/mol]": p["ea_kj_mol"],
                "95 % CI, pulses independent": f"[{p['ea_ci_low_kj_mol']:.1f}, "
                f"{p['ea_ci_high_kj_mol']:.1f}] (dof {p['dof']})",
                "95 % CI, 3 runs": f"[{r['ea_ci_low_kj_mol']:.1f}, {r['ea_ci_high_kj_mol']:.1f}]"
                f" (dof {r['dof']})",
                "Ea 20→30 / 30→40 °C": " / ".join(f"{v:.1f}" for v in pairs["ea_kj_mol"]),
                "per-pulse Ea median [min, max]": f"{per['ea_kj_mol'].median():.1f} "
                f"[{per['ea_kj_mol'].min():.1f}, {per['ea_kj_mol'].max():.1f}]",
                "R(20 °C)/R(40 °C)": p["ratio_low_high"],
            }
        )
    return pd.DataFrame(rows)
