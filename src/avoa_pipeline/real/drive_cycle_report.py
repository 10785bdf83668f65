"""Experiment 1's figure and table, from the workflow's outputs alone (or a small demo run).

- :func:`summary_table`: RMSE per unseen cycle, one row per model and temperature, with the median
  over the unseen cycles (the goal's figure of merit) and the median maximum error.
- :func:`figure`: measured against predicted voltage on each temperature's figure cycle, with
  the error below; the paper model shown is its best optimizer by median RMSE.
- :func:`demo`: the same three inputs from a reduced experiment (25 °C, US06 unseen, Nelder–Mead
  with one seed and a small budget), so the notebook runs on its own.
"""

from __future__ import annotations

import copy
import tempfile
from pathlib import Path

import numpy as np
import pandas as pd
from matplotlib.figure import Figure

from ..report.figures import save


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


def shown_models(rmse: pd.DataFrame, temperature_c: float) -> list[str]:
    """The models drawn at one temperature: the best paper model with and without the RC
    branch and every other model (those with predicted voltages: the C/20 circuits and each
    diagnosis's selected model)."""
    at = rmse[rmse["temperature_c"] == temperature_c]
    med = at.groupby("model")["rmse_mv"].median()
    out = []
    for prefix in ("paper_rc_", "paper_norc_"):
        cands = med[med.index.str.startswith(prefix)]
        if len(cands):
            out.append(str(cands.idxmin()))
    out += [m for m in med.index if not m.startswith("paper_")]
    return out


def figure(pred: pd.DataFrame, rmse: pd.DataFrame, ambient: dict[str, float], stem) -> None:
    """Measured and predicted voltage of each temperature's figure cycle → stem.png, stem.pdf."""
    temps = list(dict.fromkeys(pred["temperature"]))
    fig = Figure(figsize=(10, 3.4 * max(1, len(temps))), layout="constrained")
    axes = fig.subplots(2 * max(1, len(temps)), 1, height_ratios=[2, 1] * max(1, len(temps)))
    for k, temp in enumerate(temps):
        ax_v, ax_e = axes[2 * k], axes[2 * k + 1]
        part = pred[pred["temperature"] == temp]
        cycle = part["cycle"].iloc[0]
        first = part[part["model"] == part["model"].iloc[0]]
        t_h = first["time_s"].to_numpy() / 3600.0
        measured = first["measured_v"].to_numpy()
        ax_v.plot(t_h, measured, color="k", lw=0.6, label="measured")
        tc = ambient.get(temp, np.nan)
        here = rmse[(rmse["temperature_c"] == tc) & (rmse["cycle"] == cycle)].set_index("model")
        for model in shown_models(rmse, tc):
            m = part[part["model"] == model]
            if m.empty:
                continue
            v = m["model_v"].to_numpy()
            r = here["rmse_mv"].get(model, np.nan)
            line = ax_v.plot(t_h, v, lw=0.6, label=f"{model} (RMSE {r:.0f} mV)")[0]
            ax_e.plot(t_h, 1e3 * (v - measured), lw=0.5, color=line.get_color())
        ax_v.set_ylabel("voltage [V]")
        ax_v.set_title(f"{temp}: {cycle} (not seen by any fit)", fontsize=10)
        ax_v.legend(fontsize=7, loc="lower left", ncol=2)
        ax_e.axhline(0.0, color="k", lw=0.4)
        ax_e.set_ylim(-150, 150)
        ax_e.set_ylabel("model − measured [mV]")
        ax_e.set_xlabel("time [h]")
    save(fig, stem)


def demo(cfg: dict, out_dir=None) -> dict:
    """A reduced experiment 1 (25 °C, LA92 → US06, Nelder–Mead seed 1 at 10 × 30, the C/20
    circuits) written to ``out_dir``; the notebook's inputs when the workflow's are not given."""
    from .. import plan
    from ..jobs import real as jobs
    from . import drive_cycles as dc
    from . import panasonic

    out = Path(out_dir or tempfile.mkdtemp(prefix="real_drive_cycles_"))
    cfg = copy.deepcopy(cfg)
    pan = cfg["real"]["panasonic"]
    exp = pan["experiment"]
    exp.update(
        train={"25degC": "la92"},
        algorithms=["nelder_mead"],
        seeds=[1],
        budget={"pop_size": 10, "iterations": 30},
        figure_cycle={"25degC": "us06"},
    )
    t25 = pan["temperatures"]["25degC"]
    t25["drive_cycles"] = {c: t25["drive_cycles"][c] for c in ("la92", "us06")}
    pan["temperatures"] = {"25degC": t25}
    paths = {}
    for name in ("25degC/la92", "25degC/us06", "25degC/ocv_c20"):
        paths[name] = out / f"{plan.canonical_name(name)}.csv"
        panasonic.import_named(cfg, name, paths[name])
    ocv = out / "ocv_c20.csv"
    jobs.panasonic_ocv(paths["25degC/ocv_c20"], ocv)
    tests = {"us06": paths["25degC/us06"]}
    fits = [out / "paper_rc.json", out / "c20.json"]
    jobs.paper_fit_one(dc.fit_settings(cfg, "25degC"), cfg["base_seed"], "25degC", "paper_rc",
                       "nelder_mead", paths["25degC/la92"], tests, fits[0])  # fmt: skip
    jobs.c20_fit_one("25degC", paths["25degC/la92"], tests, ocv, fits[1])
    res = {"rmse_csv": out / "drive_cycle_rmse.csv", "runs_csv": out / "drive_cycle_runs.csv",
           "predictions": out / "figure_predictions.parquet", "train": exp["train"]}  # fmt: skip
    jobs.drive_cycle_table(cfg, fits, {}, {"25degC/us06": paths["25degC/us06"]}, res["rmse_csv"],
                           res["runs_csv"], res["predictions"])  # fmt: skip
    return res
