"""The functions Snakemake rules call: one per rule, arguments straight from the rule.

Fit jobs run inside the Snakemake process (``run:`` with ``--force-use-threads``, set in the
workflow profile), so a job costs no interpreter start and no re-import: at 3,360 fits that start
would cost more than the fits. Each job's kernel runs single-threaded and releases the GIL, so
``-j2`` runs two fits on two cores. Every function writes its outputs atomically and a one-line
log.
"""

from __future__ import annotations

import copy
from pathlib import Path

import numba
import pandas as pd
import yaml

from . import aggregate, config, fit, problem, synthetic
from .io import atomic_path, write_json


def _checked(cfg) -> dict:
    cfg = copy.deepcopy(dict(cfg))
    config.validate(cfg, source="snakemake config")
    return cfg


def _log(path, text: str) -> None:
    if path:
        Path(path).parent.mkdir(parents=True, exist_ok=True)
        Path(path).write_text(text.rstrip() + "\n")


def effective_config(cfg, out_yaml: str) -> None:
    """The configuration this run used, for notebooks and for the record."""
    cfg = _checked(cfg)
    with atomic_path(out_yaml) as tmp:
        tmp.write_text(yaml.safe_dump(cfg, sort_keys=False))


def dataset(cfg, scenario, case, out_csv: str, log: str | None = None) -> None:
    ds = synthetic.generate(_checked(cfg), int(scenario), int(case))
    synthetic.write(ds, out_csv)
    _log(log, f"wrote {out_csv}: {ds.time_s.size} samples, truth {ds.meta['true_params']}")


def fit_one(
    cfg, data_csv: str, scenario, case, algorithm: str, seed, out_json: str, log: str | None = None
) -> None:
    numba.set_num_threads(1)
    cfg = _checked(cfg)
    budget = fit.budget_from(cfg)
    prob = problem.build(cfg, int(scenario), int(case), data=data_csv)
    rec = fit.run(cfg, prob, algorithm, int(seed), budget)
    write_json(rec, out_json)
    _log(
        log,
        f"{algorithm} s{scenario} c{case} seed {seed}: ISE {rec['best_ise']:.6g}, "
        f"nfe {rec['nfe']}, {rec['wall_s']:.3f} s",
    )


def aggregate_runs(records, runs_out: str, hist_out: str, log: str | None = None) -> None:
    runs, hist = aggregate.from_files(records)
    aggregate.write(runs, hist, runs_out, hist_out)
    _log(log, f"{len(runs)} runs, {len(hist)} history rows")


def concat_parquet(paths, out: str, log: str | None = None) -> None:
    df = pd.concat([pd.read_parquet(p) for p in paths], ignore_index=True)
    with atomic_path(out) as tmp:
        df.to_parquet(tmp, index=False)
    _log(log, f"{out}: {len(df)} rows from {len(paths)} files")
