"""C/20-OCV equivalent circuits with optional effects, and their choice by blocked cross-validation
on the training record alone (experiment 1; docs/real-data.md, "Choosing the circuit").

The base circuit is ``c20_2rc_lowsoc`` of :mod:`.drive_cycles`: the C/20 discharge curve plus a
fitted offset as OCV, R0 and two RC branches, all resistances scaled by 1 + k·exp(−SOC/σ). Each
effect below adds one physical mechanism, argued before any fit:

- ``ocv_ir``: the C/20 curve is a *loaded* curve: at 0.145 A the cell sits below its OCV by the
  steady-state drop I_C20·(R0 + R1 + R2)·scale(SOC), which grows where the resistance rises near
  empty. The OCV is the curve plus that drop (with the model's own resistances) plus the offset.
- ``thermal``: resistances × exp(−b·(T − 25 °C)), T the measured cell temperature; the cells warm
  by up to 7 K (25 °C US06) and 14 K (0 °C US06) during aggressive cycles.
- ``hyst``: one-state hysteresis (Plett 2004, doi:10.1016/j.jpowsour.2004.02.031, eq. 13):
  h ← a·h + (1 − a)·sgn(i_charge), a = exp(−γ·|i|·Δt / (3600·Q)); V += M·h.
- ``rc3``: a third, slow RC branch (τ 500-20,000 s), for diffusion slower than R2's.
- ``q_c20``: the capacity held at the C/20 test's 2.997 Ah instead of fitted.
- ``hppc``: the same temperature's HPPC test joins the training data (it covers the SOC below the
  training drive cycle's end); a record-specific offset is fitted for it.
- ``ocv_hppc``: the OCV levelled on the rested voltages of the same temperature's HPPC test
  (:func:`table_for`). The C/20 curve is one loaded discharge at 25 °C, measured in May on a
  cell that had by then lost capacity; the HPPC rests are the same week as the drive cycles and at
  their temperature, 5-10 % SOC apart down to ~8 %. Between the rest points the C/20 curve keeps
  its shape; at each point it is moved to the rested voltage.

**Choice.** :func:`blocked_cv`: the training drive cycle is cut into ``folds`` contiguous blocks
of equal length; for each block the circuit is fitted with that block's residuals left out (the
simulation runs through it, so the state is carried) and scored on it. The score is the RMSE
over all held-out samples. Nothing from the unseen cycles enters.

Hand-written numerics: the hysteresis state is a sign-switching recursion that no scipy filter
expresses, so it is a small compiled loop (numba); the rest are linear filters
(``scipy.signal.lfilter``) on a table lookup (``numpy.interp``), fitted by scipy ``least_squares``.
"""

from __future__ import annotations

import itertools
import time

import numba
import numpy as np
import pandas as pd
from scipy.signal import lfilter

from ..errors import ConfigError, DataError
from .drive_cycles import _C20_PARAMS, _step, errors_mv, multistart_least_squares
from .panasonic import REST_A

EFFECTS = ("ocv_ir", "thermal", "hyst", "rc3", "q_c20", "hppc", "ocv_hppc")
HPPC_EFFECTS = ("hppc", "ocv_hppc")  # effects that need the HPPC record
REST_MIN_S = 1500.0  # ocv_hppc: a rest this long (or the opening one) gives an OCV point
T_REF_C = 25.0  # the C/20 test's temperature: the OCV and its IR correction hold there

_EXTRA = {  # (lower, upper, start values)
    "b": (0.0, 0.15, (0.02,)),
    "m": (0.0, 0.05, (0.005,)),
    "gamma": (0.1, 500.0, (20.0,)),
    "r3": (1e-5, 0.3, (0.005,)),
    "tau3": (500.0, 20000.0, (3000.0,)),
    "offset_hppc": (-0.2, 0.2, (0.0,)),
}
_BOX = {**_C20_PARAMS, **_EXTRA}


def needs_hppc(candidates) -> bool:
    """Whether any of these candidate effects needs the same temperature's HPPC record."""
    return bool(set(HPPC_EFFECTS) & set(candidates))


def param_names(effects) -> tuple[str, ...]:
    bad = set(effects) - set(EFFECTS)
    if bad:
        raise ConfigError(f"unknown circuit effect(s) {sorted(bad)}; choose from {EFFECTS}")
    names = ["r0", "r1", "tau1", "r2", "tau2", "offset", "k", "sigma"]
    if "q_c20" not in effects:
        names.insert(0, "q")
    if "thermal" in effects:
        names.append("b")
    if "hyst" in effects:
        names += ["m", "gamma"]
    if "rc3" in effects:
        names += ["r3", "tau3"]
    if "hppc" in effects:
        names.append("offset_hppc")
    return tuple(names)


def hppc_rest_points(hppc: pd.DataFrame, capacity_ah: float, min_rest_s: float = REST_MIN_S):
    """(SOC, rested voltage) at the end of the HPPC record's opening rest and of every later rest
    (|I| ≤ ``REST_A``) of at least ``min_rest_s``; SOC = 1 − charge out / ``capacity_ah`` (the C/20
    capacity, so the points sit on the C/20 table's SOC axis)."""
    cur = hppc["current_a"].to_numpy()
    volt = hppc["voltage_v"].to_numpy()
    dt = np.diff(hppc["time_s"].to_numpy(), append=np.nan)
    charge = np.r_[0.0, np.cumsum(cur[:-1] * dt[:-1])] / 3600.0  # Ah out before each sample
    rest = np.abs(cur) <= REST_A
    edges = np.flatnonzero(np.diff(np.r_[0, rest.astype(int), 0]))
    pts = []
    for a, b in zip(edges[::2], edges[1::2], strict=True):
        length = hppc["time_s"].iloc[b - 1] - hppc["time_s"].iloc[a]
        if a == 0 or length >= min_rest_s:
            pts.append((1.0 - charge[b - 1] / capacity_ah, volt[b - 1]))
    if len(pts) < 2:
        source = hppc.attrs.get("source", "HPPC record")
        raise DataError(f"{source}: column 'current_a': {len(pts)} rest(s) of ≥ "
                        f"{min_rest_s:.0f} s, need 2 for the ocv_hppc table")  # fmt: skip
    return np.array(sorted(pts))


def moved_table(ocv: pd.DataFrame, points) -> pd.DataFrame:
    """The C/20 table moved onto (SOC, OCV) ``points``: at each point by (its voltage − the
    table's at that SOC), linearly in between, constant beyond the first and last point; kept
    strictly increasing for the inverse lookup. ``attrs['rest_points']`` holds the points."""
    grid, table = ocv["soc"].to_numpy(), ocv["ocv_v"].to_numpy()
    pts = np.asarray(points, dtype=float)
    shift = pts[:, 1] - np.interp(pts[:, 0], grid, table)
    moved = np.maximum.accumulate(table + np.interp(grid, pts[:, 0], shift))
    out = pd.DataFrame({"soc": grid, "ocv_v": moved + np.arange(grid.size) * 1e-9})
    out.attrs.update(ocv.attrs)
    out.attrs["rest_points"] = pts.tolist()
    return out


def table_for(effects, ocv: pd.DataFrame, hppc: pd.DataFrame | None) -> pd.DataFrame:
    """The OCV table a circuit with ``effects`` simulates with: the C/20 table, or with
    ``ocv_hppc`` that table moved onto the HPPC record's rest points."""
    if "ocv_hppc" not in effects:
        return ocv
    if hppc is None:
        raise ConfigError("circuit effect 'ocv_hppc' needs the HPPC record")
    cap = float(ocv.attrs.get("capacity_ah", 2.997))
    return moved_table(ocv, hppc_rest_points(hppc, cap))


def model_table(model: dict, ocv: pd.DataFrame) -> pd.DataFrame:
    """The OCV table of a fitted model record (of :func:`choose`): the C/20 table, moved onto
    the rest points the record kept if it has any."""
    pts = model.get("ocv_rest_points")
    return moved_table(ocv, pts) if pts else ocv


@numba.njit(cache=True)
def _hysteresis(cur, ts, gamma, q):  # pragma: no cover - compiled
    h = np.empty(cur.size)
    state = 0.0
    for n in range(cur.size):
        h[n] = state
        a = np.exp(-gamma * abs(cur[n]) * ts / (3600.0 * q))
        # positive current = discharge: the state tends to −1 while discharging, +1 charging
        state = a * state - (1.0 - a) * np.sign(cur[n])
    return h


def simulate(params: dict, frame: pd.DataFrame, ocv: pd.DataFrame, effects=(),
             offset_key: str = "offset") -> np.ndarray:  # fmt: skip
    """Terminal voltage of the circuit on a canonical record, s0 from its first sample."""
    grid, table = ocv["soc"].to_numpy(), ocv["ocv_v"].to_numpy()
    q = float(ocv.attrs.get("capacity_ah", 2.997)) if "q_c20" in effects else params["q"]
    i_c20 = float(ocv.attrs.get("current_a", 0.145))
    cur = frame["current_a"].to_numpy()
    ts = _step(frame)
    p = params
    off = p[offset_key]
    rc = [("r1", "tau1"), ("r2", "tau2")] + ([("r3", "tau3")] if "rc3" in effects else [])
    r_ss = p["r0"] + sum(p[r] for r, _ in rc)  # steady-state resistance at C/20

    def scale(s):
        return 1.0 + p["k"] * np.exp(-np.clip(s, -0.5, 2.0) / p["sigma"])

    def ocv_at(s):
        v = np.interp(s, grid, table) + off
        if "ocv_ir" in effects:
            v = v + i_c20 * r_ss * scale(s)
        return v

    # s0: OCV(s0) = V0 + R0·scale·I0, solved on the grid (the OCV is increasing in SOC)
    v0 = frame["voltage_v"].iloc[0]
    target = v0 + p["r0"] * cur[0] * scale(grid)
    temp_f = 1.0
    if "thermal" in effects:
        temp = frame["temperature_c"].to_numpy()
        temp_f = np.exp(-p["b"] * (temp - T_REF_C))
        target = v0 + p["r0"] * cur[0] * scale(grid) * temp_f[0]
    gap = ocv_at(grid) - target
    s0 = float(np.interp(0.0, gap, grid)) if np.all(np.diff(gap) > 0) else float(
        np.clip(np.interp(v0 - off, table, grid), 0, 1))  # fmt: skip
    s0 = min(max(s0, 0.0), 1.0)
    soc = s0 - np.r_[0.0, np.cumsum(cur[:-1])] * ts / (3600.0 * q)
    drive = scale(soc) * temp_f * cur
    v = ocv_at(soc) - p["r0"] * drive
    for r, tau in rc:
        a = np.exp(-ts / p[tau])
        v = v - lfilter([0.0, p[r] * (1.0 - a)], [1.0, -a], drive)
    if "hyst" in effects:
        v = v + p["m"] * _hysteresis(np.ascontiguousarray(cur, dtype=float), ts, p["gamma"], q)
    return v


def fit(effects, train: pd.DataFrame, ocv: pd.DataFrame, hppc: pd.DataFrame | None = None,
        mask: np.ndarray | None = None, start: dict | None = None) -> dict:  # fmt: skip
    """Least squares on the training record's samples where ``mask`` (default: all), plus the
    HPPC record if the ``hppc`` effect is on; the best of the start values' grid, or one run
    from ``start`` (a previous fit's parameters). With ``ocv_hppc`` the record keeps the rest
    points its OCV table was moved onto (``ocv_rest_points``; :func:`model_table`)."""
    effects = tuple(effects)
    names = param_names(effects)
    for eff in HPPC_EFFECTS:
        if eff in effects and hppc is None:
            raise ConfigError(f"circuit effect {eff!r} needs the HPPC record")
    ocv = table_for(effects, ocv, hppc)
    volt = train["voltage_v"].to_numpy()
    keep = np.ones(volt.size, bool) if mask is None else np.asarray(mask, bool)
    weight_h = 0.0
    if "hppc" in effects:
        # the HPPC record weighs as much in total as the training samples kept
        weight_h = np.sqrt(keep.sum() / len(hppc))
        v_h = hppc["voltage_v"].to_numpy()

    def residual(x):
        p = dict(zip(names, x, strict=True))
        r = (simulate(p, train, ocv, effects) - volt)[keep]
        if weight_h:
            rh = simulate(p, hppc, ocv, effects, offset_key="offset_hppc") - v_h
            r = np.r_[r, weight_h * rh]
        return r

    t0 = time.perf_counter()
    best = multistart_least_squares(
        residual, names, _BOX, None if start is None else [[start[n] for n in names]]
    )
    params = dict(zip(names, map(float, best.x), strict=True))
    r = simulate(params, train, ocv, effects) - volt
    out = {
        "effects": list(effects),
        "params": params,
        "train_rmse_mv": 1e3 * float(np.sqrt(np.mean(r[keep] ** 2))),
        "nfev": int(best.nfev),
        "wall_s": time.perf_counter() - t0,
    }
    if "rest_points" in ocv.attrs:
        out["ocv_rest_points"] = ocv.attrs["rest_points"]
    return out


def blocked_cv(effects, train: pd.DataFrame, ocv: pd.DataFrame, folds: int,
               hppc: pd.DataFrame | None = None, start: dict | None = None) -> dict:  # fmt: skip
    """Leave-one-block-out RMSE on the training record (blocks contiguous in time); each fold's
    fit starts from ``start`` (the fit to the whole record) if given."""
    if folds < 2:
        raise ConfigError(f"config: field real.panasonic.experiment.circuits.folds: {folds} < 2")
    n = len(train)
    edges = np.linspace(0, n, folds + 1).astype(int)
    volt = train["voltage_v"].to_numpy()
    sq = 0.0
    per_fold = []
    for a, b in itertools.pairwise(edges):
        mask = np.ones(n, bool)
        mask[a:b] = False
        rec = fit(effects, train, ocv, hppc=hppc, mask=mask, start=start)
        e = simulate(rec["params"], train, model_table(rec, ocv), effects)[a:b] - volt[a:b]
        sq += float(np.sum(e**2))
        per_fold.append(1e3 * float(np.sqrt(np.mean(e**2))))
    return {"cv_rmse_mv": 1e3 * float(np.sqrt(sq / n)), "fold_rmse_mv": per_fold}


def model_name(effects) -> str:
    return "c20_2rc_lowsoc" + "".join("+" + e for e in effects)


def choose(temp: str, train: pd.DataFrame, tests: dict[str, pd.DataFrame], ocv: pd.DataFrame,
           settings: dict, hppc: pd.DataFrame | None = None) -> dict:  # fmt: skip
    """Every candidate (the base, then each effect of ``settings['candidates']`` alone) fitted to
    the whole training record and scored by :func:`blocked_cv`; then all effects that lowered
    the base's CV RMSE by at least ``settings['min_gain']`` (relative) together as one more
    candidate. The selected model has the lowest CV RMSE. Every candidate is then run on the
    unseen cycles and reported, selected or not."""
    folds = int(settings["folds"])
    min_gain = float(settings.get("min_gain", 0.02))
    out = {"temperature": temp, "folds": folds, "min_gain": min_gain, "models": {}}

    def run(effects):
        t0 = time.perf_counter()
        rec = fit(effects, train, ocv, hppc=hppc)
        rec.update(blocked_cv(effects, train, ocv, folds, hppc=hppc, start=rec["params"]))
        rec["wall_s"] = time.perf_counter() - t0
        rec["cycles"] = {}
        table = model_table(rec, ocv)
        for c, f in tests.items():
            rec["cycles"][c] = errors_mv(simulate(rec["params"], f, table, effects), f)
        out["models"][model_name(effects)] = rec
        return rec["cv_rmse_mv"]

    base = run(())
    gains = []
    for eff in settings["candidates"]:
        cv = run((eff,))
        if cv <= base * (1.0 - min_gain):
            gains.append(eff)
    if len(gains) > 1:
        run(tuple(e for e in EFFECTS if e in gains))
    out["selected"] = min(out["models"], key=lambda m: out["models"][m]["cv_rmse_mv"])
    return out


def cross_cycle(temp: str, cycles: dict[str, pd.DataFrame], ocv: pd.DataFrame, models: dict,
                hppc: pd.DataFrame | None = None) -> list[dict]:  # fmt: skip
    """Diagnostic, not used for any choice: each circuit of ``models`` (name → effects) fitted to
    every drive cycle of ``cycles`` in turn and run on all of them. The diagonal (fitted and
    scored on the same cycle) is what the circuit can reach on that cycle at best; an unseen
    cycle's prediction error above its diagonal is what the transfer from the training cycle
    costs. One row per (model, cycle fitted on, cycle predicted)."""
    rows = []
    for name, effects in models.items():
        for fit_on, frame in cycles.items():
            rec = fit(effects, frame, ocv, hppc=hppc)
            table = model_table(rec, ocv)
            for predict, other in cycles.items():
                err = errors_mv(simulate(rec["params"], other, table, effects), other)
                rows.append({"temperature": temp, "model": name, "fit_on": fit_on,
                             "predict": predict, "in_sample": fit_on == predict,
                             **err})  # fmt: skip
    return rows
