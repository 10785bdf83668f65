"""Small in-memory runs, so every notebook also runs on its own without the workflow's files."""

from __future__ import annotations

import pandas as pd

from .. import aggregate, fit, problem
from ..optimizers import Budget

DEMO_ALGORITHMS = ("nelder_mead", "avoa", "gto")


def runs_and_histories(
    cfg: dict,
    pairs,
    algorithms=DEMO_ALGORITHMS,
    seeds=(1, 2),
    pop_size: int = 10,
    iterations: int = 20,
) -> tuple[pd.DataFrame, pd.DataFrame]:
    """Aggregates of a few short fits for each (scenario, case) in ``pairs``."""
    budget = Budget(pop_size=pop_size, iterations=iterations)
    records = []
    for scenario, case in pairs:
        prob = problem.build(cfg, scenario, case)
        records += [fit.run(cfg, prob, a, s, budget) for a in algorithms for s in seeds]
    return aggregate.collect(records)


def runs_for(
    cfg: dict, pairs, runs: str = "", histories: str = "", not_run: bool = False
) -> tuple[pd.DataFrame, pd.DataFrame | None]:
    """A notebook's runs and histories: the workflow's parquet files (comma-separated paths), an
    empty runs table when the configuration does not run ``pairs`` (histories ``None``), or, for
    a notebook run on its own, a short demo fit of ``pairs``."""
    if runs:

        def read(paths):
            return pd.concat([pd.read_parquet(p) for p in paths.split(",") if p], ignore_index=True)

        return read(runs), (read(histories) if histories else None)
    if not_run:
        return aggregate.empty_runs(), None
    return runs_and_histories(cfg, pairs)
