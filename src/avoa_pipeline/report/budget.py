"""Fixed-budget curves in the style of IOHprofiler / COCO, read from the recorded histories.

No fit is rerun (docs/reproduction-notes.md, E8). A history is one run's best-so-far excess over
the truth, e = (ISE − ISE_true) / ISE_true (E1; may be negative), logged once per iteration with
the evaluations used so far (``nfe``). Read at b evaluations, it is the best a run had found after
≤ b evaluations.

- :func:`hitting_nfe`: per run × target t, the evaluations the run needed to reach e ≤ t (the
  ``nfe`` of its first history entry within the target, so resolved to one iteration).
- :func:`ecdf`: per algorithm × target, the share of its seeds that reached the target within
  b evaluations, against b (an empirical CDF of the hitting evaluations; a run that never reached
  the target counts in the denominator, so a curve ends below 1 when some seeds never get there).
  Higher and further left is better: more seeds get there, sooner.
- :func:`rank_curve`: per algorithm, the mean over seeds of its rank among all algorithms on that
  seed (1 = lowest excess after ≤ b evaluations) against b, with the median excess at b. Where
  the curves cross, which algorithm is "best" depends on the budget.
- :func:`budget_grid`: the default budgets, log-spaced up to the pair's common N
  (:func:`.stats.common_nfe`), with the fractions of N of E8 included exactly.

What a reading at b means: for algorithms whose steps do not depend on the budget (Nelder-Mead,
quasi-Newton, GA, GWO) it is exactly what a run stopped at b would have returned. AVOA, GTO and
RUN schedule their exploration by iteration / maximum iteration, so for them the reading at b is
the run of the full budget seen at b, not a run given b evaluations (E8); a run given a budget b
would have moved from exploring to exploiting sooner.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from . import stats
from .stats import EXCESS_TARGETS, KEYS

GRID_POINTS = 60
"""Log-spaced budgets of :func:`budget_grid` (before the E8 fractions are added)."""


def _check_excess(histories: pd.DataFrame) -> None:
    if "excess_ise" not in histories.columns:
        raise ValueError(
            "histories: no excess_ise column (older aggregate? call stats.with_excess first)"
        )


def _pair(df: pd.DataFrame, scenario: int, case: int) -> pd.DataFrame:
    sub = df[(df["scenario"] == scenario) & (df["case"] == case)]
    if sub.empty:
        raise ValueError(f"no rows for scenario {scenario} case {case}")
    return sub


def hitting_nfe(histories: pd.DataFrame, targets=EXCESS_TARGETS) -> pd.DataFrame:
    """Per run × target: the fewest evaluations after which the run's best excess was ≤ target.

    Returns ``scenario, case, algorithm, seed, target, hit_nfe, last_nfe``: ``hit_nfe`` is the
    ``nfe`` of the run's first history entry with ``excess_ise ≤ target`` (NaN if no entry of its
    history is: never reached, or no truth to compare with); ``last_nfe`` the run's final ``nfe``
    (how far it was watched). Rows sorted by run, then target in the given order.
    """
    _check_excess(histories)
    targets = [float(t) for t in targets]
    h = histories[[*KEYS, "nfe", "excess_ise"]]
    runs = h.groupby(KEYS, sort=True)["nfe"].max().rename("last_nfe").reset_index()
    excess = h["excess_ise"].to_numpy(dtype=float)
    parts = []
    for k, t in enumerate(targets):
        within = h[excess <= t]
        first = within.groupby(KEYS, sort=False)["nfe"].min().rename("hit_nfe").reset_index()
        part = runs.merge(first, on=KEYS, how="left")
        part.insert(len(KEYS), "target", t)
        part["_t"] = k
        parts.append(part)
    out = pd.concat(parts, ignore_index=True).sort_values([*KEYS, "_t"], kind="stable")
    out["hit_nfe"] = out["hit_nfe"].astype(float)
    return out[[*KEYS, "target", "hit_nfe", "last_nfe"]].reset_index(drop=True)


def budget_grid(
    histories: pd.DataFrame, scenario: int, case: int, points: int = GRID_POINTS
) -> np.ndarray:
    """Budgets (evaluations) for the curves of one scenario × case: ``points`` log-spaced from
    the smallest first-history ``nfe`` of any run to the common N, rounded to integers, with
    floor(f · N) for each fraction f of ``stats.BUDGET_FRACTIONS`` at or above that start (so the
    curves pass through the E8 readings exactly). Sorted, unique."""
    sub = _pair(histories, scenario, case)
    n = stats.common_nfe(histories, scenario, case)
    lo = int(sub.groupby(["algorithm", "seed"])["nfe"].min().min())
    lo = max(min(lo, n), 1)
    grid = np.rint(np.geomspace(lo, n, points)).astype(int)
    fractions = np.floor(np.asarray(stats.BUDGET_FRACTIONS) * n + 1e-9).astype(int)
    return np.unique(np.concatenate([grid, fractions[fractions >= lo]]))


def ecdf(hits: pd.DataFrame, scenario: int, case: int, budgets) -> pd.DataFrame:
    """Per algorithm × target × budget b: the share of the algorithm's runs with ``hit_nfe ≤ b``.

    ``hits`` is :func:`hitting_nfe`'s frame. The denominator is every run of the algorithm in the
    pair, including those that never reached the target. Returns ``scenario, case, algorithm,
    target, nfe, share, n_hit, n_runs``; algorithms in the paper's order, targets as in ``hits``.
    """
    sub = _pair(hits, scenario, case)
    b = np.asarray(budgets, dtype=float)
    parts = []
    for algo in stats.algorithm_order(sub["algorithm"]):
        a = sub[sub["algorithm"] == algo]
        for t in pd.unique(a["target"]):
            h = a.loc[a["target"] == t, "hit_nfe"].to_numpy(dtype=float)
            n_hit = np.searchsorted(np.sort(h[~np.isnan(h)]), b, side="right")
            parts.append(
                pd.DataFrame(
                    {
                        "scenario": int(scenario),
                        "case": int(case),
                        "algorithm": algo,
                        "target": float(t),
                        "nfe": b.astype(int),
                        "share": n_hit / len(h),
                        "n_hit": n_hit,
                        "n_runs": len(h),
                    }
                )
            )
    return pd.concat(parts, ignore_index=True)


def rank_curve(histories: pd.DataFrame, scenario: int, case: int, budgets) -> pd.DataFrame:
    """Per budget b × algorithm: the mean per-seed rank of the best excess after ≤ b evaluations.

    Ranks as in :func:`.stats.ranks` (1 = lowest; ties averaged; only the seeds on which every
    algorithm has a value at b, so a b below some run's first entry has no rank). Returns
    ``scenario, case, nfe, algorithm, mean_rank, n_blocks`` (those seeds), ``median_excess``
    (over the algorithm's runs with a value at b) and ``n_runs`` (those runs).
    """
    _check_excess(histories)
    sub = _pair(histories, scenario, case)
    order = stats.algorithm_order(sub["algorithm"])
    parts = []
    for b in np.asarray(budgets, dtype=int):
        at = stats.best_at_nfe(sub, int(b))
        wide = stats.seed_matrix(at, scenario, case, order)
        mean_rank = (
            wide.rank(axis=1, method="average").mean()
            if len(wide)
            else pd.Series(np.nan, index=order)
        )
        g = at.dropna(subset=["best_ise"]).groupby("algorithm")["excess_ise"]
        parts.append(
            pd.DataFrame(
                {
                    "scenario": int(scenario),
                    "case": int(case),
                    "nfe": int(b),
                    "algorithm": order,
                    "mean_rank": mean_rank.reindex(order).to_numpy(dtype=float),
                    "n_blocks": len(wide),
                    "median_excess": g.median().reindex(order).to_numpy(dtype=float),
                    "n_runs": g.size().reindex(order).fillna(0).astype(int).to_numpy(),
                }
            )
        )
    return pd.concat(parts, ignore_index=True)


def _lower_median(x: pd.Series) -> float:
    v = np.sort(x.to_numpy(dtype=float))
    return float(v[(len(v) - 1) // 2])


def summary(hits: pd.DataFrame, histories: pd.DataFrame) -> pd.DataFrame:
    """Per scenario × case × algorithm × target, read at the pair's common N: ``n_runs``,
    ``share_by_n`` (runs that reached the target within N evaluations), ``median_nfe`` (the
    lower median over all runs of the evaluations needed, a run that did not reach the target
    within N counting as infinitely many: the evaluations by which half the seeds were there,
    where the ECDF reaches 0.5; NaN when fewer than half got there within N) and ``common_nfe``
    (N). The lower median, not the midpoint of the two middle runs, so that it is an evaluation
    count some run needed."""
    parts = []
    for s, c in stats.scenario_cases(hits):
        n = stats.common_nfe(histories, s, c)
        sub = hits[(hits["scenario"] == s) & (hits["case"] == c)].copy()
        sub["_h"] = sub["hit_nfe"].where(sub["hit_nfe"] <= n, np.inf)
        g = sub.groupby(["algorithm", "target"], sort=False)["_h"]
        t = pd.DataFrame(
            {
                "n_runs": g.size(),
                "share_by_n": g.apply(lambda x: float(np.isfinite(x).mean())),
                "median_nfe": g.apply(_lower_median).replace(np.inf, np.nan),
            }
        ).reset_index()
        t.insert(0, "case", int(c))
        t.insert(0, "scenario", int(s))
        t["common_nfe"] = n
        parts.append(t)
    out = pd.concat(parts, ignore_index=True)
    rank = {a: i for i, a in enumerate(stats.algorithm_order(out["algorithm"]))}
    out["_o"] = out["algorithm"].map(rank)
    out = out.sort_values(["scenario", "case", "_o", "target"], ascending=[True, True, True, False])
    return out.drop(columns="_o").reset_index(drop=True)
