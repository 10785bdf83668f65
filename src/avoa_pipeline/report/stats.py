"""Statistics over seeds: equal-budget readings of the histories, ranks, Friedman, Holm-Wilcoxon.

Inputs are the aggregates of ``docs/records.md``: a *runs* frame (one row per fit, with at least
``scenario, case, algorithm, seed, best_ise``) and a *histories* frame (one row per fit × history
entry: ``scenario, case, algorithm, seed, iteration, best_ise, nfe``). Every function that
compares algorithms reads only ``best_ise`` from its frame, so the frame returned by
:func:`best_at_nfe` / :func:`at_budget` (same key columns, ``best_ise`` read at an equal budget)
can stand in for *runs* to compare algorithms at equal evaluations.

Conventions
- Rows whose ``best_ise`` is NaN (a run that never reached the budget) are left out.
- Seeds are the blocks of every paired comparison: a comparison uses only the seeds that every
  algorithm involved has (for Friedman and the mean per-seed rank: all algorithms present in
  that scenario × case).
- Algorithms appear in the paper's column order (``ALGORITHMS``); names not in it follow, sorted.
- Wilcoxon signed-rank tests are scipy's (``zero_method="wilcox"``: zero differences are dropped;
  exact null distribution for n ≤ 50 without ties/zeros, normal approximation otherwise). With
  fewer than :data:`MIN_SEEDS` matched seeds a comparison is not tested ("too few seeds", p NaN);
  with every difference zero it is not tested either and gets p = 1 (no evidence of a
  difference), which is also what scipy would give if it did not divide 0 by 0.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
import pandas as pd
from scipy import stats as st

from ..optimizers import ALGORITHMS, PAPER_LABELS

KEYS = ["scenario", "case", "algorithm", "seed"]
MIN_SEEDS = 6
"""Fewest matched seeds for which a Wilcoxon comparison is run (two-sided exact p ≥ 0.03 at
n = 6, so below that nothing could reach α = 0.05 after a Holm correction over six)."""


# ------------------------------------------------------------------------------------- helpers
def algorithm_order(names) -> list[str]:
    """``names`` (any iterable) in the paper's column order; unknown names last, sorted."""
    present = set(names)
    return [a for a in ALGORITHMS if a in present] + sorted(present - set(ALGORITHMS))


def algorithm_key(name) -> str:
    """Our algorithm key from a key or a printed heading ("RK", "Nelder-Mead", "AVOA", ...)."""
    key = str(name).strip()
    if key in ALGORITHMS:
        return key
    by_label = {v.lower().replace("–", "-"): k for k, v in PAPER_LABELS.items()}
    return by_label.get(key.lower().replace("–", "-"), key)


def scenario_cases(df: pd.DataFrame) -> list[tuple[int, int]]:
    """The sorted (scenario, case) pairs present in ``df``."""
    pairs = df[["scenario", "case"]].drop_duplicates().itertuples(index=False)
    return sorted((int(s), int(c)) for s, c in pairs)


def _select(df: pd.DataFrame, scenario: int, case: int) -> pd.DataFrame:
    sub = df[(df["scenario"] == scenario) & (df["case"] == case)]
    return sub[sub["best_ise"].notna()]


def _wide(df: pd.DataFrame, scenario: int, case: int, algorithms=None) -> pd.DataFrame:
    sub = _select(df, scenario, case)
    if algorithms is not None:
        sub = sub[sub["algorithm"].isin(list(algorithms))]
    if sub.duplicated(["algorithm", "seed"]).any():
        dup = sub[sub.duplicated(["algorithm", "seed"], keep=False)].iloc[0]
        raise ValueError(
            f"scenario {scenario} case {case}: algorithm {dup['algorithm']!r} seed "
            f"{dup['seed']} appears more than once"
        )
    wide = sub.pivot(index="seed", columns="algorithm", values="best_ise")
    order = algorithm_order(wide.columns) if algorithms is None else list(algorithms)
    return wide.reindex(columns=order).sort_index()


def seed_matrix(df: pd.DataFrame, scenario: int, case: int, algorithms=None) -> pd.DataFrame:
    """Seeds × algorithms matrix of ``best_ise`` for one scenario × case, complete seeds only.

    Raises ``ValueError`` if a (algorithm, seed) appears twice.
    """
    return _wide(df, scenario, case, algorithms).dropna()


def holm(p) -> np.ndarray:
    """Holm step-down adjusted p-values; NaN entries are ignored (and stay NaN)."""
    p = np.asarray(p, dtype=float)
    out = np.full(p.shape, np.nan)
    ok = ~np.isnan(p)
    m = int(ok.sum())
    if m == 0:
        return out
    idx = np.flatnonzero(ok)
    order = np.argsort(p[idx], kind="stable")
    adj = (m - np.arange(m)) * p[idx][order]
    adj = np.minimum(np.maximum.accumulate(adj), 1.0)
    out[idx[order]] = adj
    return out


def wilcoxon_pair(a, b, min_n: int = MIN_SEEDS) -> dict:
    """Paired Wilcoxon signed-rank test of ``a`` against ``b`` (same length, matched).

    Returns ``n`` (pairs), ``n_nonzero`` (non-zero differences), ``median_diff`` (median of
    a − b), ``p_two`` (two-sided), ``p_less`` (H1: a tends to be lower), ``p_greater``.
    """
    a = np.asarray(a, dtype=float)
    b = np.asarray(b, dtype=float)
    d = a - b
    n = len(d)
    nz = int(np.count_nonzero(d))
    out = {
        "n": n,
        "n_nonzero": nz,
        "median_diff": float(np.median(d)) if n else np.nan,
        "p_two": np.nan,
        "p_less": np.nan,
        "p_greater": np.nan,
    }
    if n < min_n:
        return out
    if nz == 0:
        out.update(p_two=1.0, p_less=1.0, p_greater=1.0)
        return out
    for key, alt in (("p_two", "two-sided"), ("p_less", "less"), ("p_greater", "greater")):
        out[key] = float(st.wilcoxon(a, b, alternative=alt, zero_method="wilcox").pvalue)
    return out


# ---------------------------------------------------------------------- equal-budget readings
def _best_at(histories: pd.DataFrame, column: str, limit) -> pd.DataFrame:
    h = histories[[*KEYS, "iteration", "nfe", "best_ise"]].reset_index(drop=True)
    if isinstance(limit, Mapping):
        lim = pd.Series(
            [
                limit.get((int(s), int(c)), np.nan)
                for s, c in zip(h["scenario"], h["case"], strict=True)
            ],
            index=h.index,
            dtype=float,
        )
    else:
        lim = pd.Series(float(limit), index=h.index)
    within = h[h[column] <= lim].sort_values([*KEYS, "iteration"], kind="stable")
    last = within.groupby(KEYS, sort=False).tail(1)
    runs = h[KEYS].drop_duplicates().copy()
    runs[f"budget_{column}"] = lim.loc[runs.index].to_numpy()
    out = runs.merge(last[[*KEYS, "best_ise", "iteration", "nfe"]], on=KEYS, how="left")
    out = out.sort_values(KEYS, kind="stable").reset_index(drop=True)
    return out[[*KEYS, "best_ise", "iteration", "nfe", f"budget_{column}"]]


def best_at_nfe(histories: pd.DataFrame, nfe) -> pd.DataFrame:
    """Each run's best ISE after at most ``nfe`` objective evaluations.

    ``nfe`` is a number, or a mapping ``{(scenario, case): N}`` (combinations missing from it
    give NaN). The value is ``best_ise`` of the run's last history entry with ``nfe ≤ N`` (the
    history is best-so-far, so this is the best found within N evaluations); a run with no such
    entry (N below its initial population) gets NaN. Returns one row per run: ``scenario, case,
    algorithm, seed, best_ise, iteration, nfe`` (of the entry read) and ``budget_nfe`` (N).
    """
    return _best_at(histories, "nfe", nfe)


def best_at_iteration(histories: pd.DataFrame, iteration) -> pd.DataFrame:
    """As :func:`best_at_nfe`, by iteration count (0 = after the initial population)."""
    return _best_at(histories, "iteration", iteration)


def _final(histories: pd.DataFrame, scenario: int, case: int, column: str) -> int:
    h = histories[(histories["scenario"] == scenario) & (histories["case"] == case)]
    if h.empty:
        raise ValueError(f"no history for scenario {scenario} case {case}")
    return int(h.groupby(["algorithm", "seed"])[column].max().min())


def common_nfe(histories: pd.DataFrame, scenario: int, case: int) -> int:
    """The equal budget of one scenario × case: the largest N every run reaches.

    The minimum over all runs (every algorithm, every seed) of the run's final ``nfe``.
    """
    return _final(histories, scenario, case, "nfe")


def common_iterations(histories: pd.DataFrame, scenario: int, case: int) -> int:
    """The smallest final iteration over all runs of one scenario × case."""
    return _final(histories, scenario, case, "iteration")


def at_budget(histories: pd.DataFrame, fraction: float = 1.0, by: str = "nfe") -> pd.DataFrame:
    """Every run's best ISE at ``fraction`` of the common budget of its scenario × case.

    ``by="nfe"``: the budget is :func:`common_nfe` (equal evaluations); ``by="iteration"``: it
    is :func:`common_iterations` (the paper's protocol: equal iterations). The limit is
    ``floor(fraction × budget)``. Returns the frame of :func:`best_at_nfe` /
    :func:`best_at_iteration`.
    """
    if by not in ("nfe", "iteration"):
        raise ValueError(f"by must be 'nfe' or 'iteration', got {by!r}")
    if not 0 < fraction <= 1:
        raise ValueError(f"fraction must lie in (0, 1], got {fraction}")
    final = common_nfe if by == "nfe" else common_iterations
    combos = histories[["scenario", "case"]].drop_duplicates().itertuples(index=False)
    limits = {
        (int(s), int(c)): int(np.floor(fraction * final(histories, s, c) + 1e-9)) for s, c in combos
    }
    return _best_at(histories, by, limits)


# ------------------------------------------------------------------------------------- ranks
def ranks(df: pd.DataFrame) -> pd.DataFrame:
    """Ranks of the algorithms per scenario × case (1 = lowest ISE).

    Columns: ``scenario, case, algorithm, n_seeds`` (runs with an ISE), ``mean_ise,
    median_ise, rank_by_mean, rank_by_median`` (ties share the lowest rank), ``mean_rank``: the
    mean over seeds of the algorithm's rank among all algorithms on that seed (ties averaged;
    complete seeds only, as in the Friedman test), ``n_blocks`` (those seeds), and
    ``rank_by_mean_rank`` (the order of ``mean_rank``).
    """
    d = df[df["best_ise"].notna()]
    cols = [
        "scenario",
        "case",
        "algorithm",
        "n_seeds",
        "mean_ise",
        "median_ise",
        "rank_by_mean",
        "rank_by_median",
        "mean_rank",
        "n_blocks",
        "rank_by_mean_rank",
    ]
    parts = []
    for (s, c), sub in d.groupby(["scenario", "case"], sort=True):
        g = sub.groupby("algorithm")["best_ise"]
        t = pd.DataFrame({"n_seeds": g.size(), "mean_ise": g.mean(), "median_ise": g.median()})
        t = t.reindex(algorithm_order(t.index))
        wide = seed_matrix(df, s, c)
        t["mean_rank"] = wide.rank(axis=1, method="average").mean() if len(wide) else np.nan
        t["n_blocks"] = len(wide)
        t["rank_by_mean"] = t["mean_ise"].rank(method="min")
        t["rank_by_median"] = t["median_ise"].rank(method="min")
        t["rank_by_mean_rank"] = t["mean_rank"].rank(method="min")
        t = t.rename_axis("algorithm").reset_index()
        t.insert(0, "case", int(c))
        t.insert(0, "scenario", int(s))
        parts.append(t)
    if not parts:
        return pd.DataFrame(columns=cols)
    out = pd.concat(parts, ignore_index=True)[cols]
    for col in ("rank_by_mean", "rank_by_median", "rank_by_mean_rank"):
        out[col] = out[col].astype("Int64")
    return out


def friedman(df: pd.DataFrame, scenario: int, case: int) -> dict:
    """Friedman test over the algorithms of one scenario × case, seeds as blocks.

    Only seeds every algorithm has are used. Returns ``{"statistic", "p", "n_blocks", "k"}``
    (``k`` algorithms); NaN statistic and p with fewer than 2 blocks or 3 algorithms. When every
    block is tied throughout (all algorithms equal on every seed) the statistic is 0 and p = 1.
    """
    wide = seed_matrix(df, scenario, case)
    n, k = wide.shape
    out = {"statistic": np.nan, "p": np.nan, "n_blocks": int(n), "k": int(k)}
    if n < 2 or k < 3:
        return out
    values = wide.to_numpy()
    if np.all(values == values[:, :1]):
        out.update(statistic=0.0, p=1.0)
        return out
    res = st.friedmanchisquare(*values.T)
    out.update(statistic=float(res.statistic), p=float(res.pvalue))
    return out


def holm_wilcoxon(
    df: pd.DataFrame, scenario: int, case: int, ref: str = "avoa", alpha: float = 0.05
) -> pd.DataFrame:
    """Paired Wilcoxon signed-rank tests of ``ref`` against every other algorithm, Holm-corrected.

    Per rival, the seeds both have are matched; the differences are ``ref − other``. The Holm
    correction runs over the comparisons that were tested (the six rivals when all are present),
    separately for each kind of p-value. Columns:

    - ``ref, other, n`` (matched seeds), ``n_nonzero``, ``median_ref, median_other``,
      ``median_diff`` (median of the paired differences; < 0: ref lower);
    - ``p_raw`` (two-sided), ``p_holm`` (two-sided, Holm), ``p_one_sided_holm`` (H1: ref lower,
      Holm), ``p_one_sided_greater_holm`` (H1: ref higher, Holm);
    - ``verdict``: "too few seeds" (n < MIN_SEEDS, p NaN); else, when ``p_holm < alpha``,
      "ref better" or "ref worse" by the direction of the smaller one-sided p; else
      "no difference".
    """
    wide = _wide(df, scenario, case)
    if ref not in wide.columns:
        raise ValueError(f"scenario {scenario} case {case}: no runs of {ref!r}")
    rows = []
    for other in wide.columns:
        if other == ref:
            continue
        pair = wide[[ref, other]].dropna()
        w = wilcoxon_pair(pair[ref], pair[other])
        rows.append(
            {
                "ref": ref,
                "other": other,
                "n": w["n"],
                "n_nonzero": w["n_nonzero"],
                "median_ref": float(pair[ref].median()) if len(pair) else np.nan,
                "median_other": float(pair[other].median()) if len(pair) else np.nan,
                "median_diff": w["median_diff"],
                "p_raw": w["p_two"],
                "_p_less": w["p_less"],
                "_p_greater": w["p_greater"],
            }
        )
    out = pd.DataFrame(rows)
    if out.empty:
        return out
    out["p_holm"] = holm(out["p_raw"])
    out["p_one_sided_holm"] = holm(out["_p_less"])
    out["p_one_sided_greater_holm"] = holm(out["_p_greater"])

    def verdict(r) -> str:
        if np.isnan(r["p_raw"]):
            return "too few seeds"
        if r["p_holm"] < alpha:
            return "ref better" if r["_p_less"] < r["_p_greater"] else "ref worse"
        return "no difference"

    out["verdict"] = out.apply(verdict, axis=1)
    return out.drop(columns=["_p_less", "_p_greater"])


def pairwise_wilcoxon(df: pd.DataFrame, scenario: int, case: int) -> pd.DataFrame:
    """Paired Wilcoxon tests of every pair of algorithms, Holm-corrected over all pairs.

    Columns: ``a, b, n, median_diff`` (median of a − b), ``p_raw`` (two-sided), ``p_holm``,
    ``lower`` (the algorithm whose one-sided p is smaller: the one that tends to be lower;
    empty when the pair was not tested or all differences are zero).
    """
    wide = _wide(df, scenario, case)
    algos = list(wide.columns)
    rows = []
    for i, a in enumerate(algos):
        for b in algos[i + 1 :]:
            pair = wide[[a, b]].dropna()
            w = wilcoxon_pair(pair[a], pair[b])
            lower = ""
            if not np.isnan(w["p_two"]) and w["n_nonzero"]:
                lower = a if w["p_less"] < w["p_greater"] else b
            rows.append(
                {
                    "a": a,
                    "b": b,
                    "n": w["n"],
                    "median_diff": w["median_diff"],
                    "p_raw": w["p_two"],
                    "lower": lower,
                }
            )
    out = pd.DataFrame(rows, columns=["a", "b", "n", "median_diff", "p_raw", "lower"])
    out.insert(5, "p_holm", holm(out["p_raw"]) if len(out) else [])
    return out


def mannwhitney_less(x, y, min_n: int = MIN_SEEDS) -> float:
    """One-sided Mann-Whitney U p-value for H1: ``x`` tends to be lower than ``y`` (unpaired).

    NaN when either sample has fewer than ``min_n`` values; 1 when all values are equal.
    """
    x = np.asarray(x, dtype=float)
    y = np.asarray(y, dtype=float)
    x, y = x[~np.isnan(x)], y[~np.isnan(y)]
    if len(x) < min_n or len(y) < min_n:
        return np.nan
    both = np.concatenate([x, y])
    if np.all(both == both[0]):
        return 1.0
    return float(st.mannwhitneyu(x, y, alternative="less").pvalue)


def brown_forsythe(x, y) -> float:
    """Brown-Forsythe test of equal spread (one-way ANOVA on |value − group median|), two-sided.

    Written out (rather than ``scipy.stats.levene``) so degenerate samples give a defined
    answer without warnings: no spread anywhere → p = 1; no spread within either group but
    different spreads between them → p = 0.
    """
    x = np.asarray(x, dtype=float)
    y = np.asarray(y, dtype=float)
    zx, zy = np.abs(x - np.median(x)), np.abs(y - np.median(y))
    n1, n2 = len(zx), len(zy)
    if n1 < 2 or n2 < 2:
        return np.nan
    z = np.concatenate([zx, zy])
    grand = z.mean()
    between = n1 * (zx.mean() - grand) ** 2 + n2 * (zy.mean() - grand) ** 2
    within = ((zx - zx.mean()) ** 2).sum() + ((zy - zy.mean()) ** 2).sum()
    if within == 0:
        return 1.0 if between == 0 else 0.0
    f = between / (within / (n1 + n2 - 2))
    return float(st.f.sf(f, 1, n1 + n2 - 2))
