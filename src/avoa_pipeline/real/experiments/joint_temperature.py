"""One model of the Panasonic cell over temperature (issue 28; docs/real-data.md, "One model over
temperature (issue 28)"): the diagnosis of every temperature's training records together, beside
each temperature's own diagnosis, on the same unseen cycles.

The fit is the diagnosis as it stands (``jobs.real.diagnose_one``); with records whose measured
temperature spans more than ``ecm.THERMAL_MIN_RANGE_C`` its ``thermal`` and ``bv_arrhenius``
elements are candidates like any other. This module only puts its predictions of the unseen
cycles beside the per-temperature models' (rule ``panasonic_joint_table``).
"""

from __future__ import annotations

import pandas as pd

COLUMNS = ("temperature_c", "cycle", "joint_rmse_mv", "joint_max_err_mv",
           "per_temperature_rmse_mv", "per_temperature_max_err_mv", "joint_model",
           "per_temperature_model")  # fmt: skip


def key(temp: str, cycle: str) -> str:
    """The name of an unseen cycle among every temperature's: ``<temperature>/<cycle>``."""
    return f"{temp}/{cycle}"


def _selected(record: dict) -> tuple[str, dict]:
    """(the selected configuration's effects, its errors per unseen cycle) of a table record
    (``drive_cycles.diagnosis_record``)."""
    m = record["models"][f"{record['prefix']}_selected"]
    return record["selected"], m["cycles"]


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
