"""Hand-made aggregates for the report tests (docs/records.md's histories layout)."""

import numpy as np
import pandas as pd


def history(algorithm, seed, nfe, best, scenario=4, case=4, excess=None) -> pd.DataFrame:
    """One run's history: best-so-far ISE ``best`` after ``nfe`` evaluations, one row per
    iteration; ``excess`` (the excess over the truth) becomes a column when given."""
    cols = {
        "scenario": scenario,
        "case": case,
        "algorithm": algorithm,
        "seed": seed,
        "iteration": np.arange(len(nfe)),
        "best_ise": np.asarray(best, dtype=float),
    }
    if excess is not None:
        cols["excess_ise"] = np.asarray(excess, dtype=float)
    return pd.DataFrame({**cols, "nfe": np.asarray(nfe), "wall_s": 0.0})
