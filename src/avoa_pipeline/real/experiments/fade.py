"""Experiment 3: capacity and resistance of NASA B0005 at its 168 ageing states, and the paper's
fade law (eqs. 7-9) fitted over them, against alternatives.

Per discharge (one slice of the canonical record, :mod:`.nasa`), with the samples where they were
measured (9-19 s apart, no resampling):

- **Load on**: the 2 A load switches on between the last rest sample and the first loaded one;
  the record does not say when. Taken at the last rest sample (:data:`LOAD_ON_FRACTION` = 0). The
  one discharge logged every 18.8 s amid 9.4-s ones (k = 43, between 42 and 44) decides it: with
  the switch at the last rest sample its 20-s resistance matches its neighbours' (−0.4 mΩ), with
  the switch half-way it is 2.1 mΩ high, at the first loaded sample 4.4 mΩ (as large as a
  quarter of the whole ageing trend).
- **Capacity** [Ah]: coulomb count of the measured current from the load switching on to the
  cut-off (``real.nasa.cutoff_v``, 2.7 V), trapezoids between samples; the cut-off instant is
  interpolated linearly in voltage between the last sample above and the first below it (the
  last loaded sample lies below 2.7 V: the tester's own detection is faster than its logging).
  NASA's ``Capacity`` field is kept beside it (``capacity_nasa_ah``).
- **Resistance** [Ω]: ``(V_rest − V(t_on + d)) / I`` with d = ``real.nasa.resistance_delay_s``
  (20 s), V interpolated linearly between the measured samples (t_on + 20 s always lies between
  the first and second loaded samples, never beyond the data). An instantaneous R0 cannot be read:
  the first loaded sample comes 10-19 s after the switch, and the raw first-sample step
  (``r_step_ohm``, kept for comparison) jumps by 5-7 mΩ where the sampling interval changes
  (k = 30 → 31, 42 → 43 → 44), which is more than a third of the trend. So this is a 20-s DC
  resistance: R0 plus most of the charge-transfer polarisation, the quantity eq. 9 scales as a
  whole ("all resistances"). The data hold no impedance spectra (the NASA set has EIS between
  some cycles, but these CSV extracts carry only the discharges).
- ``v_rest_v``: the rested voltage before the load, the measurable stand-in for eq. 7's Vnom
  (OCV at full charge). It is pinned by the 4.2 V CV charge and moves with the rest before the
  discharge and with the logging regime, so eq. 7 can hardly be tested on it; fitted all the same.

Fade laws, fitted with :func:`scipy.optimize.least_squares` against n = k − 1 (discharges before
this one) with N = the last n, so δ is the change from the first state to the last:

- ``sqrt`` (the paper's eqs. 8-9): y = y0·(1 + δ/100·√(n/N))
- ``linear`` (the form of eq. 7): y = y0·(1 + δ/100·n/N)
- ``power`` (exponent free): y = y0·(1 + δ/100·(n/N)^z); z = 0.5 is the paper's law.

Goodness: RMSE, largest residual, AIC and BIC (Gaussian likelihood with the variance as one more
parameter), the residuals' lag-1 autocorrelation (AIC/BIC and the standard errors assume
independent residuals; a high autocorrelation says they are not, and the SEs are too small:
``se_ar1_factor`` = √((1 + ρ)/(1 − ρ)) is the factor an AR(1) residual with lag-1 correlation ρ
inflates them by), and
the mean residual at the states after a long rest (``real.nasa.long_rest_h``), where the capacity
recovers (regeneration), against the others.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
import pandas as pd
from scipy.optimize import least_squares

from ... import records
from ...errors import DataError
from ...importers.nasa import discharge_slices
from ...io import atomic_path

LOAD_ON_FRACTION = 0.0
"""Where in the interval between the last rest sample and the first loaded sample the load is
taken to switch on (0 = at the rest sample); see the module docstring for the evidence."""

STATE_COLUMNS = (
    "discharge", "n", "nasa_cycle", "start", "rest_before_h", "after_long_rest", "sample_s",
    "capacity_ah", "capacity_nasa_ah", "resistance_ohm", "r_step_ohm", "v_rest_v",
    "cell_temp_start_c", "cell_temp_max_c",
)  # fmt: skip

QUANTITIES = {
    "capacity_ah": "eq. 8 (capacity)",
    "resistance_ohm": "eq. 9 (resistance, 20 s DC)",
    "v_rest_v": "eq. 7 (Vnom: rested voltage before discharge)",
}
LAWS = ("sqrt", "linear", "power")
LAW_TEXT = {
    "sqrt": "y0*(1 + d/100*sqrt(n/N))",
    "linear": "y0*(1 + d/100*n/N)",
    "power": "y0*(1 + d/100*(n/N)^z)",
}
FIT_COLUMNS = (
    "quantity", "equation", "law", "formula", "n_ref", "y0", "y0_se", "delta_pct", "delta_se_pct",
    "z", "z_se", "n_points", "k_params", "rmse", "rmse_rel_pct", "max_abs_resid", "aic", "bic",
    "delta_aic", "delta_bic", "resid_lag1_autocorr", "se_ar1_factor", "mean_resid_after_long_rest",
    "mean_resid_other", "n_after_long_rest",
)  # fmt: skip


def discharge_state(sub: pd.DataFrame, entry: Mapping, cfg_nasa: Mapping, source: str) -> dict:
    """Capacity, resistance and rested voltage of one discharge (see the module docstring)."""
    k = entry.get("discharge")
    t = sub["time_s"].to_numpy()
    i = sub["current_a"].to_numpy()
    v = sub["voltage_v"].to_numpy()
    on = np.flatnonzero(i > float(cfg_nasa["load_current_a"]))
    if on.size < 3:
        raise DataError(f"{source}: discharge {k}: column 'current_a': fewer than 3 loaded samples")
    a, b = int(on[0]), int(on[-1])
    if a == 0:
        raise DataError(f"{source}: discharge {k}: no rest sample before the load")
    t_on = t[a - 1] + LOAD_ON_FRACTION * (t[a] - t[a - 1])
    cutoff = float(cfg_nasa["cutoff_v"])
    below = np.flatnonzero(v[a : b + 1] <= cutoff)
    if below.size and below[0] > 0:
        c = a + int(below[0])  # first loaded sample at or below the cut-off
        frac = (v[c - 1] - cutoff) / (v[c - 1] - v[c])
        t_cut = t[c - 1] + frac * (t[c] - t[c - 1])
        i_cut = i[c - 1] + frac * (i[c] - i[c - 1])
        tt = np.r_[t_on, t[a:c], t_cut]
        ii = np.r_[i[a], i[a:c], i_cut]
    else:
        raise DataError(
            f"{source}: discharge {k}: column 'voltage_v' never crosses the cut-off "
            f"{cutoff:g} V under load (real.nasa.cutoff_v)"
        )
    capacity = float(np.trapezoid(ii, tt)) / 3600.0
    delay = float(cfg_nasa["resistance_delay_s"])
    t_r = t_on + delay
    if not t[a] <= t_r <= t[b]:
        raise DataError(
            f"{source}: discharge {k}: the first loaded sample comes {t[a] - t_on:.1f} s after the "
            f"load switches on, later than real.nasa.resistance_delay_s = {delay:g} s"
        )
    i_load = float(np.mean(i[a : min(a + 5, b + 1)]))
    return {
        "discharge": int(k),
        "sample_s": float(np.median(np.diff(t[a : b + 1]))),
        "capacity_ah": capacity,
        "resistance_ohm": (v[a - 1] - np.interp(t_r, t[a : b + 1], v[a : b + 1])) / i_load,
        "r_step_ohm": (v[a - 1] - v[a]) / i[a],
        "v_rest_v": v[a - 1],
        "cell_temp_start_c": float(sub["temperature_c"].iloc[a - 1]),
        "cell_temp_max_c": float(sub["temperature_c"].max()),
        "end_s": float(t[-1]),
    }


def states(frame: pd.DataFrame, sidecar: Mapping, cfg_nasa: Mapping, source: str = "<record>"):
    """One row per discharge (columns :data:`STATE_COLUMNS`)."""
    rows = []
    for entry, sub in discharge_slices(frame, sidecar, source):
        row = discharge_state(sub, entry, cfg_nasa, source)
        row.update(
            n=row["discharge"] - 1,
            nasa_cycle=entry.get("nasa_cycle"),
            start=entry.get("start"),
            start_s=float(sub["time_s"].iloc[0]),
            capacity_nasa_ah=entry.get("capacity_nasa_ah", np.nan),
        )
        rows.append(row)
    df = pd.DataFrame(rows).sort_values("discharge", ignore_index=True)
    if list(df["discharge"]) != list(range(1, len(df) + 1)):
        raise DataError(f"{source}: sidecar field 'discharges': not numbered 1..K")
    df["rest_before_h"] = (df["start_s"] - df["end_s"].shift(1)) / 3600.0
    df["after_long_rest"] = df["rest_before_h"] >= float(cfg_nasa["long_rest_h"])
    return df[list(STATE_COLUMNS)]


def law_values(law: str, p, n, n_ref: float) -> np.ndarray:
    x = np.asarray(n, dtype=float) / n_ref
    if law == "sqrt":
        shape = np.sqrt(x)
    elif law == "linear":
        shape = x
    elif law == "power":
        shape = x ** p[2]
    else:
        raise DataError(f"unknown fade law {law!r}; choose from {', '.join(LAWS)}")
    return p[0] * (1.0 + p[1] / 100.0 * shape)


def fit_law(n, y, law: str, n_ref: float | None = None) -> dict:
    """Least-squares fit of one fade law; parameters with standard errors and goodness."""
    n = np.asarray(n, dtype=float)
    y = np.asarray(y, dtype=float)
    if n.shape != y.shape or n.size < 4:
        raise DataError("fade-law fit: need matching n and y with at least 4 states")
    if not (np.isfinite(n).all() and np.isfinite(y).all()) or np.any(n < 0):
        raise DataError("fade-law fit: n must be finite and >= 0, y finite")
    n_ref = float(n.max()) if n_ref is None else float(n_ref)
    if not n_ref > 0:
        raise DataError("fade-law fit: the reference cycle N must be > 0")
    first = y[np.argmin(n)]
    change = 100.0 * (y[np.argmax(n)] / first - 1.0)
    x0 = [first, change] + ([0.5] if law == "power" else [])
    lo = [-np.inf, -np.inf] + ([0.02] if law == "power" else [])
    hi = [np.inf, np.inf] + ([10.0] if law == "power" else [])
    res = least_squares(
        lambda p: law_values(law, p, n, n_ref) - y, x0, bounds=(lo, hi), x_scale="jac"
    )
    resid = -res.fun  # measured − law
    m, k = y.size, len(x0)
    rss = float(resid @ resid)
    dof = m - k
    try:
        cov = np.linalg.inv(res.jac.T @ res.jac) * rss / dof
        se = np.sqrt(np.clip(np.diag(cov), 0, None))
    except np.linalg.LinAlgError:
        se = np.full(k, np.nan)
    # Gaussian log-likelihood at the ML variance; the variance counts as a parameter
    log_term = m * np.log(rss / m) if rss > 0 else -np.inf
    order = np.argsort(n)
    r = resid[order]
    lag1 = float(np.corrcoef(r[:-1], r[1:])[0, 1]) if np.std(r) > 0 else np.nan
    return {
        "law": law,
        "formula": LAW_TEXT[law],
        "n_ref": n_ref,
        "y0": res.x[0],
        "y0_se": se[0],
        "delta_pct": res.x[1],
        "delta_se_pct": se[1],
        "z": res.x[2] if law == "power" else (0.5 if law == "sqrt" else 1.0),
        "z_se": se[2] if law == "power" else np.nan,
        "n_points": m,
        "k_params": k,
        "rmse": float(np.sqrt(rss / m)),
        "rmse_rel_pct": float(100.0 * np.sqrt(rss / m) / np.mean(np.abs(y))),
        "max_abs_resid": float(np.max(np.abs(resid))),
        "aic": log_term + 2 * (k + 1),
        "bic": log_term + (k + 1) * np.log(m),
        "resid_lag1_autocorr": lag1,
        "se_ar1_factor": float(np.sqrt((1 + lag1) / (1 - lag1))) if -1 < lag1 < 1 else np.nan,
        "params": res.x,
        "resid": resid,
    }


def fade_fits(st: pd.DataFrame) -> tuple[pd.DataFrame, pd.DataFrame]:
    """Every law for every quantity: the per-state table with fitted columns, and the fit table."""
    out = st.copy()
    rows = []
    n = st["n"].to_numpy(dtype=float)
    long_rest = st["after_long_rest"].to_numpy(dtype=bool)
    for q, equation in QUANTITIES.items():
        fits = []
        for law in LAWS:
            f = fit_law(n, st[q].to_numpy(dtype=float), law)
            out[f"{q}_{law}"] = law_values(law, f["params"], n, f["n_ref"])
            resid = f.pop("resid")
            f.pop("params")
            f.update(
                quantity=q,
                equation=equation,
                mean_resid_after_long_rest=float(resid[long_rest].mean())
                if long_rest.any()
                else np.nan,
                mean_resid_other=float(resid[~long_rest].mean()),
                n_after_long_rest=int(long_rest.sum()),
            )
            fits.append(f)
        best_aic = min(f["aic"] for f in fits)
        best_bic = min(f["bic"] for f in fits)
        for f in fits:
            f["delta_aic"] = f["aic"] - best_aic
            f["delta_bic"] = f["bic"] - best_bic
        rows += fits
    return out, pd.DataFrame(rows, columns=list(FIT_COLUMNS))


def _write_csv(df: pd.DataFrame, path) -> None:
    with atomic_path(path) as tmp:
        df.to_csv(tmp, index=False)


def experiment(canonical_csv, cfg_nasa: Mapping, out_states, out_fits):
    """Experiment 3 end to end: both CSV outputs, written atomically; returns both tables."""
    record = records.read(canonical_csv)
    st = states(record.frame, record.meta, cfg_nasa, str(canonical_csv))
    table, fits = fade_fits(st)
    _write_csv(table, out_states)
    _write_csv(fits, out_fits)
    return table, fits


def summary(fits: pd.DataFrame) -> pd.DataFrame:
    """The report's table: each law's parameters and goodness, per quantity."""
    out = pd.DataFrame(
        {
            "quantity": fits["quantity"],
            "law": fits["law"],
            "y0": fits["y0"],
            "δ at N [%]": fits["delta_pct"],
            "z": fits["z"],
            "z SE (×AR(1) factor)": fits["z_se"] * fits["se_ar1_factor"],
            "RMSE": fits["rmse"],
            "RMSE [% of mean]": fits["rmse_rel_pct"],
            "max |resid|": fits["max_abs_resid"],
            "ΔAIC": fits["delta_aic"],
            "ΔBIC": fits["delta_bic"],
            "lag-1 autocorr.": fits["resid_lag1_autocorr"],
            "mean resid after long rest": fits["mean_resid_after_long_rest"],
        }
    )
    return out
