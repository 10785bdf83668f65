"""Sim-to-real gap diagnosis: where a model misses the training records, which unmodelled effect
it lacks, how much adding it helps, and the model a user should take (the method, its thresholds
and their reasons: docs/gap-diagnosis.md).

1. Base fit: the model library's base (``model/ecm.py``): the paper's rational OCV with free Vnom,
   β, capacity and initial SOC, or with ``--ocv`` the cell's measured OCV plus an offset; R0 and
   one RC branch. Several training records of one cell are fitted together (shared cell
   parameters, each record its own initial state).
2. Where: the base residual's energy by operating region, against a noise floor estimated from
   the residual's sample-to-sample differences where the current holds still.
3. Which, how far, and the ladder: every element of ``ecm.EFFECTS`` that the data can show,
   judged on held-out data by the one selection method (``avoa_pipeline.selection``).
4. The selected model (the ladder's last rung) is written as ``model.json``; records passed for
   validation are predicted by every rung of the ladder and never enter any choice.
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np
import pandas as pd
from scipy import stats

from .. import __version__, selection
from ..errors import DataError, UserError
from ..io import read_measurement, step_resistance
from ..model import ecm, fitting
from ..model.ecm import Config, Knots, Record
from ..model.fitted import FittedModel
from ..names import CURRENT_SIGNS

MIN_SAMPLES = 2000
"""Shorter records cannot be split into the held-out blocks long enough to hold a relaxation."""
MAX_CURRENT_A = 100.0
"""|I| (99th percentile) above this is taken for milliamperes: the pipeline models single cells."""
MAX_C_RATE = 50.0
"""With a given capacity, a 99th-percentile current above 50 C is taken for milliamperes."""
VOLTAGE_RANGE_V = (0.5, 6.0)
"""Cell voltages outside this are taken for a wrong unit (mV) or a pack."""
REGION_MIN_SHARE = 0.02
TIME_WINDOWS = 20
UNEXPLAINED_RATIO = 1.2  # base RMSE / noise floor above which a `none` verdict says a gap remains
STEP_FRACTION = 0.1  # a current step: |ΔI| above this fraction of the 99th-percentile |I|
REST_FRACTION = ecm.REST_FRACTION  # at rest: |I| below this fraction of the 99th-percentile |I|
SIGN_MAX_DT_S = 60.0
"""Steps for the sign check lie between samples at most this far apart: over longer logging gaps
the OCV drifts and the step says less about the ohmic response."""

# trimmed standard deviation of a normal (1 % per tail) relative to the untrimmed one
_Z_TRIM = stats.norm.ppf(0.99)
_TRIM_SD = float(stats.truncnorm(-_Z_TRIM, _Z_TRIM).std())


# ----------------------------------------------------------------------------------------------
# input


def check(
    frame: pd.DataFrame,
    source: str,
    capacity_ah: float | None = None,
    soc0: float | None = None,
    current_sign: str = "discharge-positive",
    min_samples: int = MIN_SAMPLES,
    sign_confirmed: bool = False,
) -> pd.DataFrame:
    """Checks beyond the CSV reader's: length, units, options, the current's sign (unless
    ``sign_confirmed``: a converted export, whose sign ``real.cycler`` confirmed against the
    current channel's steps). One-line DataError/UserError."""
    if not isinstance(frame, pd.DataFrame):
        raise DataError(f"{source}: not a table ({type(frame).__name__})")
    for col in ("time_s", "current_a", "voltage_v"):
        if col not in frame.columns:
            raise DataError(f"{source}: missing column {col!r} (need time_s, current_a, voltage_v)")
    cols = [c for c in ("time_s", "current_a", "voltage_v", "temperature_c") if c in frame.columns]
    out = {}
    for col in cols:
        values = pd.to_numeric(frame[col], errors="coerce").to_numpy(dtype=float)
        bad = ~np.isfinite(values)
        if bad.any():
            k = int(np.flatnonzero(bad)[0])
            raise DataError(f"{source}: column {col!r} row {k + 2}: missing or not a finite number")
        out[col] = values
    df = pd.DataFrame(out, columns=cols)
    if len(df) < min_samples:
        raise DataError(f"{source}: {len(df)} samples; the diagnosis needs at least {min_samples}")
    dt = np.diff(df["time_s"].to_numpy())
    if (dt <= 0).any():
        k = int(np.flatnonzero(dt <= 0)[0]) + 1
        raise DataError(f"{source}: column 'time_s' row {k + 2}: time not strictly increasing")
    if capacity_ah is not None and not (np.isfinite(capacity_ah) and capacity_ah > 0):
        raise UserError(f"--capacity-ah must be a positive number of Ah, got {capacity_ah}")
    if soc0 is not None and not (np.isfinite(soc0) and 0.0 <= soc0 <= 1.0):
        raise UserError(f"--soc0 must lie in [0, 1], got {soc0}")
    check_scale(df["current_a"], df["voltage_v"], source, capacity_ah)
    return df if sign_confirmed else apply_current_sign(df, source, current_sign)


def check_scale(
    current,
    voltage,
    source: str,
    capacity_ah: float | None = None,
    current_column: str = "current_a",
    voltage_column: str = "voltage_v",
) -> None:
    """One cell's scale: a 99th-percentile |I| within MAX_CURRENT_A (and MAX_C_RATE of a given
    capacity) and above zero, voltages within VOLTAGE_RANGE_V. DataError naming the column (a
    raw export's own, for ``real.cycler``)."""
    i = np.abs(np.asarray(current, dtype=float))
    v = np.asarray(voltage, dtype=float)
    i99 = float(np.quantile(i, 0.99))
    if i99 > MAX_CURRENT_A:
        raise DataError(
            f"{source}: column {current_column!r}: 99th-percentile |I| {i99:g} > "
            f"{MAX_CURRENT_A:g} A; looks like mA (need A)"
        )
    if capacity_ah is not None and i99 > MAX_C_RATE * capacity_ah:
        raise DataError(
            f"{source}: column {current_column!r}: 99th-percentile |I| {i99:g} A is over "
            f"{MAX_C_RATE:g} C for {capacity_ah:g} Ah; looks like mA (need A)"
        )
    if i99 <= 0:
        raise DataError(
            f"{source}: column {current_column!r}: no current flows; nothing to identify"
        )
    lo, hi = VOLTAGE_RANGE_V
    if v.min() < lo or v.max() > hi:
        raise DataError(
            f"{source}: column {voltage_column!r}: values {v.min():g}..{v.max():g} outside "
            f"{lo:g}..{hi:g} V of one cell (mV given?)"
        )


def read_record(
    path: str | Path,
    current_sign: str = "discharge-positive",
    min_samples: int = MIN_SAMPLES,
    cycler: str | None = None,
) -> pd.DataFrame:
    """The checked record of a CSV (time_s, current_a, voltage_v[, temperature_c]), or of a
    cycler's raw export when ``cycler`` is named (``real.cycler``; its output is already
    discharge-positive, so ``current_sign`` applies to canonical CSVs only)."""
    from ..real.cycler import read_any

    frame, _ = read_any(path, cycler)
    if frame is not None:
        return check(frame, str(path), min_samples=min_samples, sign_confirmed=True)
    df = read_measurement(path, min_samples=2)
    return check(df, str(path), current_sign=current_sign, min_samples=min_samples)


def step_resistance_of(frame: pd.DataFrame) -> tuple[float, int]:
    """``io.step_resistance`` of a record, over steps of at least STEP_FRACTION of its
    99th-percentile |I| between samples at most SIGN_MAX_DT_S apart."""
    i99 = float(np.quantile(np.abs(frame["current_a"].to_numpy()), 0.99))
    return step_resistance(frame["time_s"], frame["current_a"], frame["voltage_v"],
                           STEP_FRACTION * i99, SIGN_MAX_DT_S)  # fmt: skip


def apply_current_sign(frame: pd.DataFrame, source: str, current_sign: str) -> pd.DataFrame:
    """The record with positive current = discharge; DataError if the voltage says otherwise."""
    if current_sign not in CURRENT_SIGNS:
        raise UserError(f"--current-sign must be one of {', '.join(CURRENT_SIGNS)}")
    if current_sign == "charge-positive":
        frame = frame.assign(current_a=-frame["current_a"])
    r, n = step_resistance_of(frame)
    if n and not r > 0:
        other = CURRENT_SIGNS[1 - CURRENT_SIGNS.index(current_sign)]
        raise DataError(
            f"{source}: column 'current_a': the voltage rises with positive current (median "
            f"step -dV/dI {1e3 * r:.1f} mOhm over {n} steps), so the file is not "
            f"{current_sign}; rerun with --current-sign {other}"
        )
    return frame


# ----------------------------------------------------------------------------------------------
# pieces


def noise_floor(rec: Record, resid: np.ndarray) -> float:
    """Voltage noise RMS (V) from the residual's differences where the current holds still.

    White noise of RMS σ gives differences of RMS σ√2; the model's smooth misfit adds almost
    nothing between neighbouring samples. Samples next to a current step are left out (a misfit
    of R0 jumps there), and 1 % of each tail is trimmed (outliers) with the normal correction.
    """
    d = np.diff(resid)
    quiet = np.abs(np.diff(rec.i)) <= REST_FRACTION * rec.imax()
    if quiet.sum() >= 200:
        d = d[quiet]
    lo, hi = np.quantile(d, [0.01, 0.99])
    kept = d[(d >= lo) & (d <= hi)]
    if kept.size < 2 or np.std(kept) == 0:
        return float(np.sqrt(np.mean(d**2) / 2.0))
    return float(np.std(kept) / _TRIM_SD / np.sqrt(2.0))


# ----------------------------------------------------------------------------------------------
# where


def region_masks(rec: Record, soc: np.ndarray) -> list[tuple[str, str, np.ndarray]]:
    """(group, region, mask) for every operating region of the localization."""
    imax = rec.imax()
    a = np.abs(rec.i)
    rest = a <= REST_FRACTION * imax
    out = [
        ("mode", "rest", rest),
        ("mode", "load", ~rest),
        ("direction", "discharge", rec.i > REST_FRACTION * imax),
        ("direction", "charge", rec.i < -REST_FRACTION * imax),
    ]
    since = time_since_step(rec)
    out += [
        ("since_step", "since step < 10 s", since < 10.0),
        ("since_step", "since step 10-600 s", (since >= 10.0) & (since < 600.0)),
        ("since_step", "since step > 600 s", since >= 600.0),
    ]
    edges = np.linspace(0.0, 1.0, 6)
    sc = np.clip(soc, 0.0, 1.0)
    for j in range(5):
        m = (sc >= edges[j]) & ((sc < edges[j + 1]) if j < 4 else (sc <= 1.0))
        out.append(("soc", f"SOC {edges[j]:.1f}-{edges[j + 1]:.1f}", m))
    thr = REST_FRACTION * imax
    cut = [thr, imax / 3, 2 * imax / 3]
    out.append(("current", f"|I| < {thr:.3g} A", a < thr))
    out.append(("current", f"|I| {cut[0]:.3g}-{cut[1]:.3g} A", (a >= cut[0]) & (a < cut[1])))
    out.append(("current", f"|I| {cut[1]:.3g}-{cut[2]:.3g} A", (a >= cut[1]) & (a < cut[2])))
    out.append(("current", f"|I| >= {cut[2]:.3g} A", a >= cut[2]))
    if rec.temperature_varies:
        q = np.quantile(rec.temp_c, [0, 0.25, 0.5, 0.75, 1.0])
        for j in range(4):
            hi_ok = rec.temp_c <= q[j + 1] if j == 3 else rec.temp_c < q[j + 1]
            m = (rec.temp_c >= q[j]) & hi_ok
            out.append(("temperature", f"T {q[j]:.1f}-{q[j + 1]:.1f} °C", m))
    return out


def time_since_step(rec: Record) -> np.ndarray:
    """Seconds since the last current step (the record's start counts as one)."""
    step = np.abs(np.diff(rec.i)) > STEP_FRACTION * rec.imax()
    last = np.zeros(rec.n, dtype=int)
    idx = np.flatnonzero(step) + 1
    last[idx] = idx
    last = np.maximum.accumulate(last)
    return rec.t - rec.t[last]


def localize(rec, resid, soc, noise_v) -> tuple[list[dict], list[dict]]:
    total = float(np.sum(resid**2))
    regions = []
    for group, name, m in region_masks(rec, soc):
        n = int(m.sum())
        if n == 0:
            continue
        e = float(np.sum(resid[m] ** 2))
        rmse = float(np.sqrt(e / n))
        regions.append(
            {
                "group": group,
                "region": name,
                "n": n,
                "time_share": n / rec.n,
                "share": e / total if total > 0 else 0.0,
                "rmse_mv": 1e3 * rmse,
                "ratio_to_noise": rmse / noise_v if noise_v > 0 else None,
                "mean_mv": 1e3 * float(np.mean(resid[m])),
            }
        )
    edges = np.linspace(rec.t[0], rec.t[-1], TIME_WINDOWS + 1)
    windows = []
    for j in range(TIME_WINDOWS):
        m = (rec.t >= edges[j]) & ((rec.t < edges[j + 1]) if j < TIME_WINDOWS - 1 else True)
        n = int(m.sum())
        if n == 0:
            continue
        e = float(np.sum(resid[m] ** 2))
        windows.append(
            {
                "t_start_s": float(edges[j]),
                "t_end_s": float(edges[j + 1]),
                "share": e / total if total > 0 else 0.0,
                "rmse_mv": 1e3 * float(np.sqrt(e / n)),
            }
        )
    return regions, windows


def gap_region(regions: list[dict], n: int) -> dict:
    """The region where the misfit concentrates: the highest RMSE among regions of size."""
    big = [r for r in regions if r["n"] >= max(100, REGION_MIN_SHARE * n) and r["time_share"] < 1]
    return max(big or regions, key=lambda r: r["rmse_mv"])


# ----------------------------------------------------------------------------------------------
# why: residual signatures


def signatures(rec, resid, soc, runs: dict, base: selection.ModelRun, regions_of) -> dict:
    """Per effect: what the base residual looks like where that effect would act."""
    imax = rec.imax()
    rest = np.abs(rec.i) <= REST_FRACTION * imax
    charge = rec.i < -REST_FRACTION * imax
    dis = rec.i > REST_FRACTION * imax
    since = time_since_step(rec)
    mv = 1e3
    out = {}

    def mean(m):
        return mv * float(np.mean(resid[m])) if m.any() else None

    # second_rc: the residual after current steps, signed by the step's direction
    di = np.diff(rec.i)
    steps = np.flatnonzero(np.abs(di) > STEP_FRACTION * imax) + 1
    sign = np.zeros(rec.n)
    last = np.zeros(rec.n, dtype=int)
    last[steps] = steps
    last = np.maximum.accumulate(last)
    sign[steps] = np.sign(di[steps - 1])
    sgn = sign[last]
    aligned = {}
    for lo, hi in ((0, 10), (10, 60), (60, 600), (600, np.inf)):
        m = (since >= lo) & (since < hi) & (sgn != 0)
        aligned[f"{lo}-{hi if np.isfinite(hi) else 'end'} s"] = (
            mv * float(np.mean(-sgn[m] * resid[m])) if m.any() else None
        )
    out["second_rc"] = {
        "acts": "relaxation after current steps (10-600 s), beyond one time constant",
        "step_aligned_residual_mv": aligned,
    }
    # hysteresis: rest voltage depends on the last current's direction
    last_dir = _last_direction(rec)
    out["hysteresis"] = {
        "acts": "rest voltage after charge above that after discharge; load offset ±M",
        "rest_after_charge_mv": mean(rest & (last_dir < 0)),
        "rest_after_discharge_mv": mean(rest & (last_dir > 0)),
        "charge_mv": mean(charge),
        "discharge_mv": mean(dis),
    }
    # butler_volmer: overpotential not linear in current
    bands = {}
    a = np.abs(rec.i)
    for lo, hi in ((REST_FRACTION, 1 / 3), (1 / 3, 2 / 3), (2 / 3, np.inf)):
        m = (a >= lo * imax) & (a < hi * imax)
        bands[f"{lo:.2f}-{hi:.2f} Imax"] = (
            mv * float(np.mean(np.sign(rec.i[m]) * resid[m])) if m.any() else None
        )
    out["butler_volmer"] = {
        "acts": "load: sign(I)·residual changes with |I| (a linear R0 cannot follow asinh)",
        "signed_residual_by_current_mv": bands,
    }
    # thermal
    if rec.temperature_varies:
        load = ~rest
        x = rec.i[load] * (rec.temp_c[load] - rec.temp_c.mean())
        c = float(np.corrcoef(x, resid[load])[0, 1]) if np.std(x) > 0 else None
        out["thermal"] = {
            "acts": "load: residual follows I·(T − mean T)",
            "corr_residual_vs_i_dT": c,
        }
    else:
        out["thermal"] = {"acts": "load: residual follows I·(T − mean T)", "applicable": False}
    # ocv_shape: late-rest residual by SOC band
    late = rest & (since >= 600.0)
    edges = np.linspace(0, 1, 6)
    by_soc = {}
    for j in range(5):
        m = late & (soc >= edges[j]) & (soc < edges[j + 1] + (j == 4))
        by_soc[f"{edges[j]:.1f}-{edges[j + 1]:.1f}"] = mean(m) if m.any() else None
    out["ocv_shape"] = {"acts": "relaxed rest voltage against SOC", "late_rest_by_soc_mv": by_soc}
    # current_offset, coulombic_efficiency: drifts with time / charged charge
    th = (rec.t - rec.t[0]) / 3600.0
    charged = np.concatenate([[0.0], np.cumsum(np.minimum(rec.i[:-1], 0) * rec.dt[:-1])]) / -3600
    out["current_offset"] = {
        "acts": "SOC drift with time (rest voltage trend) and a constant ohmic shift",
        "rest_trend_mv_per_h": _slope(th[rest], resid[rest]),
    }
    out["coulombic_efficiency"] = {
        "acts": "SOC falls behind after charging: rest residual against charge put in",
        "rest_trend_mv_per_ah_charged": _slope(charged[rest], resid[rest]),
    }
    t_mean, _, _ = selection.loss_test(resid, np.zeros_like(resid), regions_of)
    out["voltage_offset"] = {
        "acts": "everywhere the same shift",
        "mean_residual_mv": mv * float(np.mean(resid)),
        "mean_residual_t": t_mean,
    }
    for e, run in runs.items():
        if e in out and run is not None:
            delta = run.v - base.v  # what the effect adds to the base model's voltage
            r = resid
            den = float(np.sum(r**2))
            out[e]["explained_share"] = 1.0 - float(np.sum((r - delta) ** 2)) / den if den else 0.0
            out[e]["correction_rms_mv"] = mv * float(np.sqrt(np.mean(delta**2)))
    return out


def _slope(x, y):
    if x.size < 3 or np.ptp(x) == 0:
        return None
    return 1e3 * float(np.polyfit(x, y, 1)[0])


def _last_direction(rec):
    """+1 after discharge, −1 after charge, 0 before any current (per sample)."""
    thr = REST_FRACTION * rec.imax()
    d = np.where(rec.i > thr, 1.0, np.where(rec.i < -thr, -1.0, 0.0))
    idx = np.where(d != 0, np.arange(rec.n), 0)
    idx = np.maximum.accumulate(idx)
    return d[idx]


# ----------------------------------------------------------------------------------------------
# the diagnosis


def concat(recs: list[Record]) -> Record:
    """One record of several, end to end (time made continuous), for the localization and the
    signatures, which read the residual against current, time and temperature."""
    if len(recs) == 1:
        return recs[0]
    t, start = [], 0.0
    for r in recs:
        t.append(r.t - r.t[0] + start)
        start = t[-1][-1] + float(np.median(r.dt))
    temps = None
    if all(r.temp_c is not None for r in recs):
        temps = np.concatenate([r.temp_c for r in recs])
    return Record(
        t=np.concatenate(t), i=np.concatenate([r.i for r in recs]),
        v=np.concatenate([r.v for r in recs]), temp_c=temps,
        dt=np.concatenate([r.dt for r in recs]), uniform=False, tref_k=recs[0].tref_k,
        dinv_t=np.concatenate([r.dinv_t for r in recs]),
        two_rt_f=np.concatenate([r.two_rt_f for r in recs]),
        source="+".join(r.source for r in recs),
    )  # fmt: skip


def reference_temperature(frames: list[pd.DataFrame]) -> float | None:
    """One reference temperature for all training records (the thermal and Butler–Volmer
    parameters are shared): the mean of every measured sample."""
    temps = [f["temperature_c"].to_numpy() for f in frames if "temperature_c" in f.columns]
    return float(np.mean(np.concatenate(temps))) + 273.15 if temps else None


def parameters(ctx: selection.Context, run: selection.ModelRun) -> dict:
    """Report-named parameters of a run: the cell's, then each record's initial state (flat for
    one record, as ``per_record`` for several)."""
    fm = fitted_model(ctx, run)
    out = fm.parameters()
    states = [ecm.report(run.X[r], run.st.config.names()) for r in range(len(ctx.recs))]
    per = [{k: v for k, v in s.items() if k in ("soc0", "hysteresis_h0")} for s in states]
    if len(per) == 1:
        out.update(per[0])
    else:
        out["per_record"] = [
            {"source": rec.source, **p} for rec, p in zip(ctx.recs, per, strict=True)
        ]
    if {"thermal", "butler_volmer"} & set(run.effects):
        out["tref_k"] = ctx.recs[0].tref_k
    return out


def fitted_model(ctx: selection.Context, run: selection.ModelRun, provenance=None) -> FittedModel:
    b = fitting.bounds_for(ctx.recs)
    names = [n for n in run.st.config.names() if not ecm.PARAMS[n].per_record]
    bounds = {n: b[n] for n in names}
    if ctx.fix_q:
        bounds["lq"] = (run.X[0, ecm.IDX["lq"]],) * 2
    return FittedModel(run.st.config, run.X[0].copy(), run.st.knots, ctx.recs[0].tref_k, bounds,
                       provenance or {})  # fmt: skip


def _errors(model_v: np.ndarray, v: np.ndarray, mask: np.ndarray | None = None) -> dict:
    e = model_v - v
    out = {
        "rmse_mv": 1e3 * float(np.sqrt(np.mean(e**2))),
        "max_err_mv": 1e3 * float(np.max(np.abs(e))),
    }
    if mask is not None:
        out["rmse_in_training_soc_mv"] = (1e3 * float(np.sqrt(np.mean(e[mask] ** 2)))
                                          if mask.any() else None)  # fmt: skip
        out["share_in_training_soc"] = float(np.mean(mask))
    return out


def training_soc_range(ctx: selection.Context, run: selection.ModelRun) -> tuple[float, float]:
    """The SOC range the training records cover under a model (its own SOC trajectory)."""
    lo, hi = np.inf, -np.inf
    for r, rec in enumerate(ctx.recs):
        _, tr = ecm.simulate_rows(rec, run.X[r], run.st.knots, run.st.config.table, traces=True)
        lo, hi = min(lo, float(tr[0].min())), max(hi, float(tr[0].max()))
    return lo, hi


def validation(ctx, rungs: dict[str, selection.ModelRun], frames: dict[str, pd.DataFrame]):
    """One row per validation record × model of the ladder: errors over the record and inside
    the SOC range the training data covered. Nothing here feeds back into any choice."""
    rows = []
    for name, run in rungs.items():
        fm = fitted_model(ctx, run)
        lo, hi = training_soc_range(ctx, run)
        for source, frame in frames.items():
            v, tr = fm.simulate(frame, traces=True)
            inside = (tr[0] >= lo) & (tr[0] <= hi)
            rows.append({"record": source, "model": name, "effects": list(run.effects),
                         "starts_at_rest": ecm.starts_at_rest(fm.record(frame)),
                         "soc0": float(tr[0][0]), "training_soc_range": [lo, hi],
                         **_errors(v, frame["voltage_v"].to_numpy(), inside)})  # fmt: skip
    return rows


def run(frames, capacity_ah=None, soc0=None, source="<data>", ocv_table=None, validate=None,
        current_sign="discharge-positive"):  # fmt: skip
    """The diagnosis report (JSON-able dict), the arrays its figure needs, and the selected model.

    ``frames``: one training record or a list of them (one cell); ``source``: its name or a list
    of names. ``ocv_table``: the cell's measured OCV (``model.ocv``), or None for the rational
    curve. ``validate``: {name: frame} of records never used for any choice.
    """
    t_start = time.perf_counter()
    frames = [frames] if isinstance(frames, pd.DataFrame) else list(frames)
    sources = [source] if isinstance(source, str) else list(source)
    if len(sources) != len(frames):
        sources = [f"{sources[0]}[{j}]" for j in range(len(frames))]
    if soc0 is not None and len(frames) > 1:
        raise UserError("--soc0 gives one record's initial SOC; with several training records "
                        "leave it out (each record's is fitted)")  # fmt: skip
    frames = [
        check(f, s, capacity_ah, soc0, current_sign) for f, s in zip(frames, sources, strict=True)
    ]
    vframes = {s: check(f, s, None, None, current_sign, min_samples=2)
               for s, f in (validate or {}).items()}  # fmt: skip
    for s, f in vframes.items():
        if set(f.columns) != set(frames[0].columns):
            raise DataError(f"{s}: columns {', '.join(f.columns)} differ from the training "
                            f"record's {', '.join(frames[0].columns)}")  # fmt: skip
    tref = reference_temperature(frames)
    recs = [Record.from_frame(f, tref_k=tref, source=s) for f, s in zip(frames, sources,
                                                                        strict=True)]  # fmt: skip
    ctx = selection.Context(recs, ocv_table, capacity_ah, soc0)
    table = ocv_table

    # 1. base fit
    st_b = ctx.structure((), Knots(0.0, 0.2))
    base = ctx.fit(st_b, fitting.base_starts(recs, Config(table=table), capacity_ah, soc0))
    st_b.knots = fitting.knots_for(recs, base.X)

    # 3a. candidates' fits (before the CV, so that the base can be re-polished)
    effects = [e for e in ecm.EFFECTS if selection.applicable(recs, e, (), table)[0]]
    cands = selection.try_effects(ctx, base, effects, cv=False)
    # a candidate whose element, set back to neutral, fits better than the base found a better
    # base optimum: refit the base from there (the base must be at its best)
    for e, c in cands.items():
        rb = ctx.run(st_b, fitting.neutralise(c.X, (e,)))
        if rb.rss < base.rss * (1 - 1e-9):
            idx = fitting.indices(recs, None, fitting.MAX_FIT_POINTS)
            base = ctx.run(st_b, fitting.fit_structure(recs, st_b, rb.X, idx).X)
    ctx.cross_validate(base)
    for c in cands.values():
        ctx.cross_validate(c)

    rec = concat(recs)
    resid = ctx.v - base.v
    soc = np.concatenate([ecm.simulate_rows(r, base.X[j], st_b.knots, table, traces=True)[1][0]
                          for j, r in enumerate(recs)])  # fmt: skip
    noise_v = noise_floor(rec, resid)

    # 2. where
    regions, windows = localize(rec, resid, soc, noise_v)
    gap = gap_region(regions, rec.n)

    # 3b. which
    rows = selection.judge(ctx, base, cands)
    for r in rows:
        r["params"] = parameters(ctx, cands[r["effect"]])
        r["applicable"] = True
    winner = selection.choose(ctx, rows, cands)
    skipped = [
        {"effect": e, "applicable": False, "reason": selection.applicable(recs, e, (), table)[1]}
        for e in ecm.EFFECTS
        if e not in cands
    ]
    sig = signatures(rec, resid, soc, cands, base, ctx.layout.batches)

    # 4. how far, and the ladder
    masks = {name: m for _, name, m in region_masks(rec, soc)}
    gap_mask = masks[gap["region"]]
    loss_b = ctx.ho_loss(base)

    def heldout_mv(loss, m=None):
        return 1e3 * float(np.sqrt(loss.mean() if m is None else loss[m].mean()))

    verdict = {"effect": "none", "shrink": 0.0}
    ladder, rungs = [], {"base": base}
    final = base
    if winner is not None:
        w = cands[winner]
        loss_w = ctx.ho_loss(w)
        row = next(r for r in rows if r["effect"] == winner)
        verdict = {
            "effect": winner,
            "shrink": row["shrink"],
            "heldout_rmse_before_mv": heldout_mv(loss_b),
            "heldout_rmse_after_mv": heldout_mv(loss_w),
            "region": gap["region"],
            "region_heldout_rmse_before_mv": heldout_mv(loss_b, gap_mask),
            "region_heldout_rmse_after_mv": heldout_mv(loss_w, gap_mask),
            "region_shrink": 1.0 - float(loss_w[gap_mask].sum() / loss_b[gap_mask].sum()),
            "delta_bic": row["delta_bic"],
            "t": row["t"],
        }
        ladder, runs = selection.climb(ctx, base, winner, w, ecm.EFFECTS)
        for lr, r in zip(ladder, runs, strict=True):
            lr["parameters"] = parameters(ctx, r)
            rungs["+".join(r.effects)] = r
        final = runs[-1]
    else:
        best = max((r for r in rows if r["shrink"] is not None), key=lambda r: r["shrink"],
                   default=None)  # fmt: skip
        if best is not None:
            verdict["best_candidate"] = best["effect"]
            verdict["best_candidate_shrink"] = best["shrink"]
        ratio = float(np.sqrt(base.rss / rec.n)) / noise_v if noise_v > 0 else np.inf
        verdict["note"] = (
            "the base model fits to about the noise floor"
            if ratio < UNEXPLAINED_RATIO
            else "a misfit beyond the noise floor that no candidate explains on held-out data"
        )
    remaining = float(np.sqrt(ctx.ho_loss(final).mean())) / noise_v if noise_v > 0 else None
    selected_name = "+".join(final.effects) or "base"
    model = fitted_model(ctx, final, provenance={
        "selected_by": "avoa_pipeline gap diagnosis: the ladder's last rung",
        "training": [{"source": r.source, "n_samples": r.n} for r in recs],
        "ocv": None if table is None else {"source": table.source, "how": table.how},
        "package_version": __version__,
    })  # fmt: skip

    report = {
        "source": sources[0] if len(sources) == 1 else sources,
        "n_samples": rec.n,
        "duration_s": float(sum(r.t[-1] - r.t[0] for r in recs)),
        "records": [
            {
                "source": r.source,
                "n_samples": r.n,
                "starts_at_rest": ecm.starts_at_rest(r),
                "step_resistance_ohm": step_resistance_of(f)[0],
            }
            for r, f in zip(recs, frames, strict=True)
        ],
        "ocv": {"kind": "rational (eq. 5), Vnom and beta free"}
        if table is None
        else {
            "kind": "measured table + fitted offset",
            "source": table.source,
            "how": table.how,
            "capacity_ah": table.capacity_ah,
        },
        "base": {
            "model": (
                "1-RC, "
                + ("rational OCV" if table is None else "measured OCV + offset")
                + ", free capacity and initial SOC"
            ),
            "parameters": parameters(ctx, base),
            "rmse_mv": 1e3 * float(np.sqrt(base.rss / rec.n)),
            "heldout_rmse_mv": heldout_mv(loss_b),
            "noise_floor_mv": 1e3 * noise_v,
            "rmse_to_noise": float(np.sqrt(base.rss / rec.n)) / noise_v if noise_v > 0 else None,
            "n_params": base.k,
            "capacity_given": capacity_ah is not None,
            "soc0_given": soc0 is not None,
        },
        "localization": regions,
        "time_windows": windows,
        "gap_region": gap["region"],
        "candidates": rows + skipped,
        "verdict": verdict,
        "ladder": ladder,
        "selected": {
            "name": selected_name,
            "effects": list(final.effects),
            "heldout_rmse_mv": heldout_mv(ctx.ho_loss(final)),
            "parameters": parameters(ctx, final),
        },
        "final_heldout_rmse_to_noise": remaining,
        "signatures": sig,
        "method": {
            "folds": selection.N_FOLDS,
            "blocks_per_fold": selection.BLOCKS_PER_FOLD,
            "batches_per_fold": selection.BATCHES_PER_FOLD,
            "min_shrink": selection.MIN_SHRINK,
            "alpha_family": selection.ALPHA,
            "bic_max": selection.BIC_MAX,
            "fit_points_max": fitting.MAX_FIT_POINTS,
            "fits": ctx.fits,
        },
        "wall_s": time.perf_counter() - t_start,
        "version": __version__,
    }
    if vframes:
        report["validation"] = validation(ctx, rungs, vframes)
    arrays = {
        "t": rec.t,
        "i": rec.i,
        "v": rec.v,
        "v_base": base.v,
        "ho_base": base.ho,
        "v_final": final.v,
        "ho_final": final.ho,
        "v_verdict": cands[winner].v if winner else None,
        "ho_verdict": cands[winner].ho if winner else None,
        "soc": soc,
    }
    return _jsonable(report), arrays, model


def diagnose(frame, capacity_ah: float | None = None, soc0: float | None = None,
             source="<data>", **kw) -> dict:  # fmt: skip
    """The diagnosis (the dict written to diagnosis.json); DataError on bad input."""
    return run(frame, capacity_ah, soc0, source, **kw)[0]


def _jsonable(obj):
    if isinstance(obj, dict):
        return {str(k): _jsonable(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [_jsonable(v) for v in obj]
    if isinstance(obj, np.bool_ | bool):
        return bool(obj)
    if isinstance(obj, np.integer | int):
        return int(obj)
    if isinstance(obj, np.floating | float):
        x = float(obj)
        return x if np.isfinite(x) else None
    return obj
