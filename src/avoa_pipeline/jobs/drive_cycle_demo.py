"""Experiment 1's three inputs (the RMSE table, the per-seed runs, the figure's predictions) from
a reduced run (25 °C, LA92 → US06, Nelder–Mead with one seed and a small budget), so that
notebooks/real_drive_cycles.ipynb runs on its own. It drives the workflow's real-data jobs, so it
sits with them, above the experiments (which never import ``jobs``)."""

from __future__ import annotations

import copy
import tempfile
from pathlib import Path


def demo(cfg: dict, out_dir=None) -> dict:
    """A reduced experiment 1 (25 °C, LA92 → US06, Nelder–Mead seed 1 at 10 × 30, the C/20
    circuits) written to ``out_dir``; the notebook's inputs when the workflow's are not given."""
    from .. import plan
    from ..importers import panasonic
    from ..real.experiments import drive_cycles as dc
    from . import real as jobs

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
