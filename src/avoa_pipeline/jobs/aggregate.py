"""The jobs of ``workflow/rules/aggregate.smk``: the fit records as runs and histories tables."""

from __future__ import annotations

import pandas as pd

from .. import aggregate
from ..io import atomic_path, write_log


def aggregate_runs(records, runs_out: str, hist_out: str, log: str | None = None) -> None:
    runs, hist = aggregate.from_files(records)
    aggregate.write(runs, hist, runs_out, hist_out)
    write_log(log, f"{len(runs)} runs, {len(hist)} history rows")


def concat_aggregates(runs_in, hist_in, runs_out: str, hist_out: str, log: str | None = None):
    """The per-pair aggregates of a run in one runs table and one histories table."""
    lines = []
    for paths, out in ((runs_in, runs_out), (hist_in, hist_out)):
        df = pd.concat([pd.read_parquet(p) for p in paths], ignore_index=True)
        with atomic_path(out) as tmp:
            df.to_parquet(tmp, index=False)
        lines.append(f"{out}: {len(df)} rows from {len(paths)} files")
    write_log(log, "\n".join(lines))
