"""One model of the Panasonic cell over temperature (issue 28; docs/real-data.md, "One model over
temperature (issue 28)"): the diagnosis of every temperature's training records together, beside
each temperature's own diagnosis, on the same unseen cycles.

The fit is the diagnosis as it stands (``jobs.real.diagnose_one``); with records whose measured
temperature spans more than ``ecm.THERMAL_MIN_RANGE_C`` its ``thermal`` and ``bv_arrhenius``
elements are candidates like any other. This module only puts its predictions of the unseen
cycles beside the per-temperature models' (rule ``panasonic_joint_table``).

Self-heating predicted (issue 28, item 2; :func:`heat_rows`): where the joint model.json carries
a heat block (``model/heat.py``, fitted by the diagnosis on the training records), each unseen
cycle's cell temperature is predicted from its ambient alone (the sidecar's
``ambient_temperature_c``, ``heat.ambient_of``) and scored against the thermocouple, and the
voltage is predicted on it beside the voltage on the measured temperature. The unseen cycles are
predicted and scored, and used for nothing else.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

COLUMNS = ("temperature_c", "cycle", "joint_rmse_mv", "joint_max_err_mv",
           "per_temperature_rmse_mv", "per_temperature_max_err_mv", "joint_model",
           "per_temperature_model")  # fmt: skip
HEAT_COLUMNS = ("temperature_rmse_k", "temperature_max_err_k", "joint_rmse_predicted_t_mv",
                "joint_max_err_predicted_t_mv", "joint_rmse_measured_t_mv", "ambient_c",
                "fixed_point_passes", "fixed_point_last_change_k")  # fmt: skip
"""What :func:`heat_rows` adds per unseen cycle: the temperature predicted from the ambient
against the thermocouple (RMSE, largest error, K), the joint model's voltage on it (RMSE,
largest error, mV) beside its voltage on the measured temperature (RMSE, mV: the table's
``joint_rmse_mv`` recomputed from model.json, a check that both run the same model), the ambient
the passes of the fixed point and the largest change of its last pass (K; converged below
``heat.FIXED_POINT_TOL_K``)."""


def key(temp: str, cycle: str) -> str:
    """The name of an unseen cycle among every temperature's: ``<temperature>/<cycle>``."""
    return f"{temp}/{cycle}"


def _selected(record: dict) -> tuple[str, dict]:
    """(the selected configuration's effects, its errors per unseen cycle) of a table record
    (``drive_cycles.diagnosis_record``); none where it refused every unseen cycle."""
    m = record["models"].get(f"{record['prefix']}_selected")
    return record["selected"], m["cycles"] if m else {}


def table(joint: dict, own: dict[str, dict], ambient: dict[str, float]) -> pd.DataFrame:
    """Per temperature and unseen cycle, the joint model's RMSE and largest error beside the
    per-temperature model's (NaN where that temperature has no model of its own).

    ``joint``: the table record of the joint diagnosis, its cycles named by :func:`key`;
    ``own``: temperature → the table record of that temperature's diagnosis; ``ambient``:
    temperature → its chamber temperature (°C)."""
    name, cycles = _selected(joint)
    rows = []
    for k, err in cycles.items():
        temp, cycle = k.split("/", 1)
        own_name, own_err = _selected(own[temp]) if temp in own else (None, {})
        other = own_err.get(cycle) or {}
        rows.append({"temperature_c": ambient[temp], "cycle": cycle,
                     "joint_rmse_mv": err["rmse_mv"], "joint_max_err_mv": err["max_err_mv"],
                     "per_temperature_rmse_mv": other.get("rmse_mv"),
                     "per_temperature_max_err_mv": other.get("max_err_mv"),
                     "joint_model": name, "per_temperature_model": own_name})  # fmt: skip
    df = pd.DataFrame(rows, columns=list(COLUMNS))
    num = [c for c in COLUMNS if c.endswith("_mv")]
    df[num] = df[num].astype(float)
    return df.sort_values(["temperature_c", "cycle"], ascending=[False, True], ignore_index=True)


def medians(df: pd.DataFrame) -> pd.DataFrame:
    """The median RMSE over each temperature's unseen cycles, joint and per temperature (the
    comparison the rule names)."""
    cols = ["joint_rmse_mv", "per_temperature_rmse_mv"]
    return df.groupby("temperature_c", sort=False)[cols].median().reset_index()


def heat_rows(model, tests: dict) -> tuple[pd.DataFrame, pd.DataFrame]:
    """Per unseen cycle (``tests``: :func:`key` → ``records.Checked``), the :data:`HEAT_COLUMNS`
    of the joint ``model`` (a ``FittedModel`` with a heat block), and the traces behind them
    (key, time_s, measured and predicted cell temperature °C) for the figure."""
    from ...model import heat
    from ...model.fitted import prediction_errors

    rows, traces = [], []
    for k, rec in tests.items():
        frame = rec.frame
        ambient, _ = heat.ambient_of(rec)
        # a model of per-temperature sets (docs/temperature-rule.md parts 2-4): its set at the
        # cycle's ambient, with that set's heat block where it has one
        run = model.at_ambient(ambient)
        pred = heat.predict(run, run.heat or model.heat, frame, ambient)
        measured = frame["temperature_c"].to_numpy(dtype=float)
        predicted = pred.temp_k - heat.KELVIN
        e = predicted - measured
        on_pred = prediction_errors(pred.voltage_v, frame["voltage_v"])
        on_meas = prediction_errors(run.simulate(frame), frame["voltage_v"])
        rows.append({"key": k, "temperature_rmse_k": float(np.sqrt(np.mean(e**2))),
                     "temperature_max_err_k": float(np.max(np.abs(e))),
                     "joint_rmse_predicted_t_mv": on_pred["rmse_mv"],
                     "joint_max_err_predicted_t_mv": on_pred["max_err_mv"],
                     "joint_rmse_measured_t_mv": on_meas["rmse_mv"], "ambient_c": ambient,
                     "fixed_point_passes": pred.passes,
                     "fixed_point_last_change_k": pred.last_change_k})  # fmt: skip
        traces.append(pd.DataFrame({"key": k, "time_s": frame["time_s"].to_numpy(),
                                    "temperature_c": measured,
                                    "temperature_c_predicted": predicted}))  # fmt: skip
    cols = ["key", "time_s", "temperature_c", "temperature_c_predicted"]
    trace = pd.concat(traces, ignore_index=True) if traces else pd.DataFrame(columns=cols)
    return pd.DataFrame(rows, columns=["key", *HEAT_COLUMNS]), trace


def with_heat(df: pd.DataFrame, heat_df: pd.DataFrame | None,
              ambient: dict[str, float]) -> pd.DataFrame:  # fmt: skip
    """The table with :data:`HEAT_COLUMNS` (from :func:`heat_rows`; empty where ``heat_df`` is
    None: the joint model has no heat block)."""
    out = df.copy()
    for col in HEAT_COLUMNS:
        out[col] = np.nan
    if heat_df is None:
        return out
    for row in heat_df.itertuples(index=False):
        temp, cycle = row.key.split("/", 1)
        at = (out["temperature_c"] == ambient[temp]) & (out["cycle"] == cycle)
        for col in HEAT_COLUMNS:
            out.loc[at, col] = getattr(row, col)
    return out
