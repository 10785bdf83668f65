"""Parameter recovery on noise-free synthetic data, for every algorithm.

The paper could not know its cell's true parameters; we can. This runs each algorithm over
seeds on the noise-free dataset of one scenario × case and reports each estimate's relative
error, whatever it is, as a flat table (one row per run) and a per-algorithm summary.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from . import fit, problem
from .optimizers import ALGORITHMS, Budget


def recover(
    cfg: dict, scenario: int, case: int, seeds, budget: Budget, algorithms=ALGORITHMS
) -> pd.DataFrame:
    prob = problem.build(cfg, scenario, case, noise=False)
    rows = []
    for alg in algorithms:
        for seed in seeds:
            rec = fit.run(cfg, prob, alg, seed, budget)
            row = {
                "scenario": scenario,
                "case": case,
                "algorithm": alg,
                "seed": seed,
                "best_ise": rec["best_ise"],
                "nfe": rec["nfe"],
            }
            row.update({f"err_{n}_pct": 100 * e for n, e in rec["rel_error"].items()})
            rows.append(row)
    return pd.DataFrame(rows)


def summary(runs: pd.DataFrame) -> pd.DataFrame:
    """Median and worst |relative error| (%) per algorithm and parameter, and the median ISE."""
    err_cols = [c for c in runs.columns if c.startswith("err_")]
    g = runs.assign(**{c: runs[c].abs() for c in err_cols}).groupby("algorithm", sort=False)
    med = g[err_cols].median().add_suffix("_median")
    worst = g[err_cols].max().add_suffix("_max")
    out = pd.concat([g["best_ise"].median().rename("median_ise"), med, worst], axis=1)
    return out[["median_ise", *(f"{c}_{s}" for c in err_cols for s in ("median", "max"))]]


def to_markdown(table: pd.DataFrame) -> str:
    fmt = table.map(lambda v: f"{v:.3g}" if isinstance(v, float | np.floating) else v)
    return fmt.to_markdown()
