"""Fit records → two flat tables (parquet): one row per run, one row per history entry.

Tables and figures read only these aggregates (docs/records.md has the schema).
"""

from __future__ import annotations

import json
from collections.abc import Iterable
from pathlib import Path

import numpy as np
import pandas as pd

from .io import atomic_path
from .model.battery import PARAM_NAMES

KEYS = ["scenario", "case", "algorithm", "seed"]


def excess(ise, true_ise):
    """The excess over the truth, (ISE − ISE_true) / ISE_true (docs/reproduction-notes.md, E1):
    NaN where the truth's ISE is unknown or not positive (a real cell has no truth)."""
    ise = np.asarray(ise, dtype=float)
    t = np.asarray(true_ise, dtype=float)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(np.isfinite(t) & (t > 0), (ise - t) / t, np.nan)


def median_position(values, ties=None) -> int | None:
    """Position of the median run among ``values`` (a run's best ISE or training error): for an
    even count the lower of the two middle ones, so that it is a real run, not an average; ties
    broken by ``ties`` (the seed), then by position; non-finite values left out (a run that
    never finished). None if no value is finite. The one median-run rule of the paper's
    parameter tables, its fit figures and the real-cell experiments."""
    v = np.asarray(values, dtype=float)
    pos = np.arange(v.size)
    keys = (pos, pos if ties is None else np.asarray(ties), v)  # lexsort: last key first
    order = [k for k in np.lexsort(keys) if np.isfinite(v[k])]
    return int(order[(len(order) - 1) // 2]) if order else None


def run_row(rec: dict) -> dict:
    hist_nfe = rec["history"]["nfe"]
    iters = max(int(rec["iterations"]), 1)
    row = {k: rec[k] for k in KEYS}
    true_ise = np.nan if rec.get("true_ise") is None else float(rec["true_ise"])
    row.update(
        best_ise=float(rec["best_ise"]),
        true_ise=true_ise,
        excess_ise=float(excess(rec["best_ise"], true_ise)),
        nfe=int(rec["nfe"]),
        iterations=int(rec["iterations"]),
        n_samples=int(rec["n_samples"]),
        wall_s=float(rec["wall_s"]),
        time_per_iter_s=float(rec["wall_s"]) / iters,
        evals_per_iter=(int(rec["nfe"]) - int(hist_nfe[0])) / iters,
        time_per_eval_s=float(rec["wall_s"]) / max(int(rec["nfe"]), 1),
    )
    truth = rec.get("true_params") or {}
    rel = rec.get("rel_error") or {}
    for p in PARAM_NAMES:
        row[f"est_{p}"] = float(rec["best_params"].get(p, np.nan))
        row[f"true_{p}"] = float(truth.get(p, np.nan))
        row[f"relerr_{p}"] = float(rel.get(p, np.nan))
    return row


def run_row_columns() -> list[str]:
    """The columns of runs.parquet, in order (for an empty table of a pair that did not run)."""
    cols = [
        *KEYS,
        "best_ise",
        "true_ise",
        "excess_ise",
        "nfe",
        "iterations",
        "n_samples",
        "wall_s",
        "time_per_iter_s",
        "evals_per_iter",
        "time_per_eval_s",
    ]
    return cols + [f"{k}_{p}" for p in PARAM_NAMES for k in ("est", "true", "relerr")]


def empty_runs() -> pd.DataFrame:
    """A typed runs table with no rows: a pair this configuration does not run."""
    ints = {"scenario", "case", "seed", "nfe", "iterations", "n_samples"}
    return pd.DataFrame(
        {
            c: pd.Series(dtype="int64" if c in ints else "str" if c == "algorithm" else "float64")
            for c in run_row_columns()
        }
    )


def history_frame(rec: dict) -> pd.DataFrame:
    h = rec["history"]
    n = len(h["best_ise"])
    true_ise = np.nan if rec.get("true_ise") is None else float(rec["true_ise"])
    df = pd.DataFrame(
        {
            "iteration": np.arange(n, dtype=np.int64),
            "best_ise": np.asarray(h["best_ise"], dtype=float),
            "excess_ise": excess(h["best_ise"], true_ise),
            "nfe": np.asarray(h["nfe"], dtype=np.int64),
            "wall_s": np.asarray(h["wall_s"], dtype=float),
        }
    )
    for k in reversed(KEYS):
        df.insert(0, k, rec[k])
    return df


def collect(records: Iterable[dict]) -> tuple[pd.DataFrame, pd.DataFrame]:
    recs = list(records)
    runs = pd.DataFrame([run_row(r) for r in recs])
    hist = pd.concat([history_frame(r) for r in recs], ignore_index=True)
    runs = runs.sort_values(KEYS, kind="stable").reset_index(drop=True)
    hist = hist.sort_values([*KEYS, "iteration"], kind="stable").reset_index(drop=True)
    return runs, hist


def from_files(paths: Iterable[str | Path]) -> tuple[pd.DataFrame, pd.DataFrame]:
    return collect(json.loads(Path(p).read_text()) for p in paths)


def write(runs: pd.DataFrame, hist: pd.DataFrame, runs_path, hist_path) -> None:
    for df, path in ((runs, runs_path), (hist, hist_path)):
        with atomic_path(path) as tmp:
            df.to_parquet(tmp, index=False)
