"""Experiment 1's table, from the workflow's outputs alone (or the small demo run of
``jobs.real.drive_cycle_demo``); its figure is ``report.real_figures.drive_cycle_figure``.

:func:`summary_table`: RMSE per unseen cycle, one row per model and temperature, with the median
over the unseen cycles (the goal's figure of merit) and the median maximum error.
"""

from __future__ import annotations

import pandas as pd


def summary_table(rmse: pd.DataFrame) -> pd.DataFrame:
    """Rows model × temperature; RMSE per unseen cycle, then medians over the cycles."""
    if rmse.empty:
        return pd.DataFrame(columns=["temperature_c", "model", "median_rmse_mv"])
    wide = rmse.pivot_table(index=["temperature_c", "model"], columns="cycle", values="rmse_mv")
    wide.columns = [f"rmse_{c}_mv" for c in wide.columns]
    g = rmse.groupby(["temperature_c", "model"])
    wide["median_rmse_mv"] = g["rmse_mv"].median()
    wide["median_max_err_mv"] = g["max_err_mv"].median()
    out = wide.reset_index().sort_values(["temperature_c", "median_rmse_mv"],
                                         ascending=[False, True])  # fmt: skip
    return out.reset_index(drop=True)
