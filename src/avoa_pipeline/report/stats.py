"""Statistics over seeds: equal-budget readings of the histories, ranks, Friedman, Holm-Wilcoxon.

Inputs are the aggregates of ``docs/records.md``: a *runs* frame (one row per fit, with at least
``scenario, case, algorithm, seed, best_ise``) and a *histories* frame (one row per fit × history
entry: ``scenario, case, algorithm, seed, iteration, best_ise, nfe``). Every function that
compares algorithms reads only ``best_ise`` from its frame, so the frame returned by
:func:`best_at_nfe` / :func:`at_budget` (same key columns, ``best_ise`` read at an equal budget)
can stand in for *runs* to compare algorithms at equal evaluations.

What is compared: ``excess_ise`` (the excess over the truth, docs/reproduction-notes.md E1)
where a frame has it for its rows, else ``best_ise`` (:func:`value_column`); within one scenario
× case the two give the same p-values, the excess reads as a size. Every paired comparison also
gets an equivalence test (two one-sided Wilcoxon tests against a margin, E2-E3) and one of four
verdicts: "lower", "higher", "practically equivalent", "inconclusive" (:func:`four_way`).

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
from functools import cache

import numpy as np
import pandas as pd
from scipy import stats as st

# median_position lives in aggregate (below the experiments, which also pick their median run by
# it); the tables and figures read it as stats.median_position.
from ..aggregate import median_position  # noqa: F401
from ..optimizers import ALGORITHMS, PAPER_LABELS

KEYS = ["scenario", "case", "algorithm", "seed"]


DELTA_V = 1e-4
"""The equivalence margin's model error, 0.1 mV RMS (docs/reproduction-notes.md, E2)."""
TIME_RATIO = 1.25
"""Time ratios inside [1/1.25, 1.25] are practically equivalent (E5)."""
SHARE_MARGIN = 0.10
"""Shares (parameter accuracy, E7) closer than 10 percentage points are practically equivalent."""
BUDGET_FRACTIONS = (0.01, 0.02, 0.05, 0.1, 0.2, 0.5, 1.0)
"""Fixed budgets, as fractions of a scenario × case's common evaluation count N (E8)."""
EXCESS_TARGETS = (0.1, 0.01, 0.001)
"""Excess-over-truth targets of the fixed-budget ECDFs (E8): 10 %, 1 %, 0.1 % of ISE_true."""
ACCURACY_TOLERANCES = (0.01, 0.05)
"""Parameter accuracy (E7): every identified parameter within 1 % (5 %) of the truth."""
LOWER, HIGHER, EQUIVALENT = "lower", "higher", "practically equivalent"
INCONCLUSIVE = "inconclusive"
TOO_FEW = "too few seeds"
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


def value_column(df: pd.DataFrame) -> str:
    """``"excess_ise"`` if ``df`` has that column with a value on every row that has an ISE,
    else ``"best_ise"`` (records without a truth, or frames built before the column existed)."""
    if "excess_ise" in df.columns:
        has = df["best_ise"].notna() if "best_ise" in df.columns else slice(None)
        if len(df) and df.loc[has, "excess_ise"].notna().all():
            return "excess_ise"
    return "best_ise"


def with_excess(runs: pd.DataFrame, histories: pd.DataFrame | None = None):
    """``runs`` (and ``histories``) with ``excess_ise``, computed from ``best_ise`` and the run's
    ``true_ise`` where the column is missing (aggregates written before it existed). Returns
    ``runs`` alone, or ``(runs, histories)`` when histories are given."""
    from ..aggregate import excess

    runs = runs.copy()
    if "excess_ise" not in runs.columns:
        t = runs["true_ise"] if "true_ise" in runs.columns else np.nan
        runs["excess_ise"] = excess(runs["best_ise"], t)
    if histories is None:
        return runs
    histories = histories.copy()
    if "excess_ise" not in histories.columns:
        if "true_ise" in runs.columns:
            t = histories[KEYS].merge(runs[[*KEYS, "true_ise"]], on=KEYS, how="left")["true_ise"]
            histories["excess_ise"] = excess(histories["best_ise"], t.to_numpy())
        else:
            histories["excess_ise"] = np.nan
    return runs, histories


def margin_of(df: pd.DataFrame, scenario: int, case: int, delta_v: float = DELTA_V) -> float:
    """The equivalence margin of one scenario × case in the units of :func:`value_column`:
    the rise of the ISE that a model error of ``delta_v`` (RMS, volts) causes on that record,
    N·δ² (E2), relative to the truth's ISE for the excess (δ²/σ₀², σ₀² = ISE_true / N). NaN
    when the frame lacks ``n_samples`` (or, for the excess, ``true_ise``)."""
    sub = df[(df["scenario"] == scenario) & (df["case"] == case)]
    if "n_samples" not in sub.columns or sub["n_samples"].isna().all():
        return np.nan
    n = float(sub["n_samples"].median())
    if value_column(df) == "best_ise":
        return n * delta_v**2
    if "true_ise" not in sub.columns or sub["true_ise"].isna().all():
        return np.nan
    return n * delta_v**2 / float(sub["true_ise"].median())


def _select(df: pd.DataFrame, scenario: int, case: int) -> pd.DataFrame:
    sub = df[(df["scenario"] == scenario) & (df["case"] == case)]
    return sub[sub["best_ise"].notna()]


def _wide(df: pd.DataFrame, scenario: int, case: int, algorithms=None) -> pd.DataFrame:
    value = value_column(df)
    sub = _select(df, scenario, case)
    if algorithms is not None:
        sub = sub[sub["algorithm"].isin(list(algorithms))]
    if sub.duplicated(["algorithm", "seed"]).any():
        dup = sub[sub.duplicated(["algorithm", "seed"], keep=False)].iloc[0]
        raise ValueError(
            f"scenario {scenario} case {case}: algorithm {dup['algorithm']!r} seed "
            f"{dup['seed']} appears more than once"
        )
    wide = sub.pivot(index="seed", columns="algorithm", values=value)
    order = algorithm_order(wide.columns) if algorithms is None else list(algorithms)
    return wide.reindex(columns=order).sort_index()


def seed_matrix(df: pd.DataFrame, scenario: int, case: int, algorithms=None) -> pd.DataFrame:
    """Seeds × algorithms matrix of :func:`value_column` for one scenario × case, complete seeds
    only.

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


@cache
def _signed_rank_cdf(n: int) -> np.ndarray:
    """Cumulative null distribution of the signed-rank sum R+ for n untied non-zero pairs:
    the number of subsets of {1..n} with each sum, over 2^n (the exact distribution)."""
    counts = np.zeros(n * (n + 1) // 2 + 1)
    counts[0] = 1.0
    for k in range(1, n + 1):
        counts[k:] = counts[k:] + counts[:-k].copy()
    return np.cumsum(counts) / 2.0**n


def signed_rank(d) -> tuple[float, float, float]:
    """p-values (two-sided, H1 "less", H1 "greater") of the Wilcoxon signed-rank test of the
    paired differences ``d``, as ``scipy.stats.wilcoxon(d, zero_method="wilcox")`` gives them
    with its default method (exact without zeros or ties for n ≤ 50; a permutation test for
    n ≤ 13 otherwise; else the normal approximation with the tie correction and no continuity
    correction), at a small part of its cost: this test runs some 25,000 times per claims
    table. ``tests/unit/test_report_stats.py`` checks it against scipy. Needs a non-zero
    difference."""
    d = np.asarray(d, dtype=float)
    nz = d[d != 0]
    n = len(nz)
    a = np.abs(nz)
    ranks = st.rankdata(a)
    _, tie_sizes = np.unique(a, return_counts=True)
    has_ties = bool((tie_sizes > 1).any())
    has_zero = n < len(d)
    r_plus = float(ranks[nz > 0].sum())
    if not (has_ties or has_zero) and len(d) <= 50:
        cdf = _signed_rank_cdf(n)
        k_lo, k_hi = int(np.ceil(r_plus)), int(np.floor(r_plus))
        p_less = float(cdf[k_lo])
        p_greater = float(1.0 - cdf[k_hi - 1]) if k_hi > 0 else 1.0
        return float(min(1.0, 2 * min(p_less, p_greater))), p_less, p_greater
    if len(d) <= 13:  # scipy's exact permutation test: every sign pattern of the pairs
        full = np.zeros(len(d))
        full[d != 0] = ranks
        flips = ((np.arange(2 ** len(d))[:, None] >> np.arange(len(d))) & 1).astype(bool)
        null = ((d > 0) ^ flips) & (d != 0)
        null_r = (null * full).sum(axis=1)
        gamma = abs(100 * np.finfo(float).eps * r_plus)
        p_less = float(np.mean(null_r <= r_plus + gamma))
        p_greater = float(np.mean(null_r >= r_plus - gamma))
        return float(min(1.0, 2 * min(p_less, p_greater))), p_less, p_greater
    mn = n * (n + 1) / 4
    se = np.sqrt((n * (n + 1) * (2 * n + 1) - np.sum(tie_sizes**3 - tie_sizes) / 2) / 24)
    z = (r_plus - mn) / se
    p_less, p_greater = float(st.norm.cdf(z)), float(st.norm.sf(z))
    return float(min(1.0, 2 * min(p_less, p_greater))), p_less, p_greater


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
    out["p_two"], out["p_less"], out["p_greater"] = signed_rank(d)
    return out


def tost_pair(a, b, margin: float, min_n: int = MIN_SEEDS) -> float:
    """Two one-sided Wilcoxon signed-rank tests that the paired differences ``a − b`` lie within
    ±``margin`` (H1 of the first: d − margin tends below 0; of the second: d + margin above 0).
    Returns the larger p (small: practically equivalent); NaN with fewer than ``min_n`` pairs or
    a margin that is not a positive number."""
    d = np.asarray(a, dtype=float) - np.asarray(b, dtype=float)
    if len(d) < min_n or not np.isfinite(margin) or margin <= 0:
        return np.nan
    below = signed_rank(d - margin)[1] if np.count_nonzero(d - margin) else 1.0
    above = signed_rank(d + margin)[2] if np.count_nonzero(d + margin) else 1.0
    return max(below, above)


def four_way(p_diff, p_less, p_greater, p_equiv, alpha: float = 0.05) -> str:
    """One comparison's verdict (docs/reproduction-notes.md, E3): "practically equivalent" if the
    equivalence p is below ``alpha`` (whatever the difference test says: a significant
    difference inside the margin does not matter), else "lower" / "higher" if the difference p
    is below ``alpha`` (by the smaller one-sided p), else "inconclusive"; "too few seeds" when
    the difference was not tested."""
    if p_diff is None or np.isnan(p_diff):
        return TOO_FEW
    if p_equiv is not None and not np.isnan(p_equiv) and p_equiv < alpha:
        return EQUIVALENT
    if p_diff < alpha:
        return LOWER if p_less < p_greater else HIGHER
    return INCONCLUSIVE


def combine_four(verdicts, lowest: bool = True) -> str:
    """A claim's verdict from its reference's verdicts against each rival (E4). For a "lowest"
    claim: "higher" if any rival beats the reference, else "inconclusive" if any comparison is
    undecided (or too few seeds), else "practically equivalent" if any is, else "lower". For a
    "highest" claim (``lowest=False``) the same with lower and higher swapped."""
    v = list(verdicts)
    bad, good = (HIGHER, LOWER) if lowest else (LOWER, HIGHER)
    if not v:
        return INCONCLUSIVE
    if bad in v:
        return bad
    if INCONCLUSIVE in v or TOO_FEW in v:
        return INCONCLUSIVE
    if EQUIVALENT in v:
        return EQUIVALENT
    return good


def interval_equivalent(lo: float, hi: float, margin: float) -> bool:
    """Whether a (1 − 2α) confidence interval lies inside ±margin (the interval form of TOST)."""
    return bool(np.isfinite(lo) and np.isfinite(hi) and -margin < lo and hi < margin)


def bootstrap_interval(statistic, samples, n_boot: int = 2000, level: float = 0.90, seed=0):
    """Percentile bootstrap interval of ``statistic(*resampled)``. The samples (equal-length
    arrays, one per group, paired by position: the seeds) are resampled together; ``statistic``
    works along the last axis (it gets arrays of shape (n_boot, n) and returns n_boot values),
    so the resamples are computed at once. Returns ``(estimate, lo, hi)``; NaNs for fewer than
    two pairs."""
    arrays = [np.asarray(x, dtype=float) for x in samples]
    n = len(arrays[0])
    if n < 2:
        est = float(statistic(*[x[None, :] for x in arrays])[0]) if n else np.nan
        return est, np.nan, np.nan
    est = float(statistic(*[x[None, :] for x in arrays])[0])
    idx = np.random.default_rng(seed).integers(0, n, size=(n_boot, n))
    vals = np.asarray(statistic(*[x[idx] for x in arrays]), dtype=float)
    lo, hi = np.quantile(vals, [(1 - level) / 2, (1 + level) / 2])
    return est, float(lo), float(hi)


def spread(x, axis: int = -1):
    """Mean absolute deviation from the median along ``axis`` (C7's reliability measure)."""
    x = np.asarray(x, dtype=float)
    return np.mean(np.abs(x - np.median(x, axis=axis, keepdims=True)), axis=axis)


def mcnemar_exact(x, y) -> dict:
    """Exact McNemar test of two paired binary outcomes (x[i], y[i] for seed i): binomial test on
    the discordant seeds. Returns ``n``, ``x_only``, ``y_only``, ``p_two``, ``p_greater`` (H1:
    x is true more often) and ``p_less``; p = 1 with no discordant seed."""
    x = np.asarray(x, dtype=bool)
    y = np.asarray(y, dtype=bool)
    b, c = int(np.sum(x & ~y)), int(np.sum(~x & y))
    out = {"n": len(x), "x_only": b, "y_only": c, "p_two": 1.0, "p_greater": 1.0, "p_less": 1.0}
    if b + c:
        for key, alt in (("p_two", "two-sided"), ("p_greater", "greater"), ("p_less", "less")):
            out[key] = float(st.binomtest(b, b + c, 0.5, alternative=alt).pvalue)
    return out


# ---------------------------------------------------------------------- equal-budget readings
def _best_at(histories: pd.DataFrame, column: str, limit) -> pd.DataFrame:
    vals = ["best_ise", *(["excess_ise"] if "excess_ise" in histories.columns else [])]
    h = histories[[*KEYS, "iteration", "nfe", *vals]].reset_index(drop=True)
    if isinstance(limit, Mapping):
        table = pd.DataFrame(
            [(int(s), int(c), float(v)) for (s, c), v in limit.items()],
            columns=["scenario", "case", "_limit"],
        )
        keys = h[["scenario", "case"]].astype("int64")
        lim = keys.merge(table, on=["scenario", "case"], how="left")["_limit"]
        lim.index = h.index
    else:
        lim = pd.Series(float(limit), index=h.index)
    within = h[h[column] <= lim].sort_values([*KEYS, "iteration"], kind="stable")
    last = within.groupby(KEYS, sort=False).tail(1)
    runs = h[KEYS].drop_duplicates().copy()
    runs[f"budget_{column}"] = lim.loc[runs.index].to_numpy()
    out = runs.merge(last[[*KEYS, *vals, "iteration", "nfe"]], on=KEYS, how="left")
    out = out.sort_values(KEYS, kind="stable").reset_index(drop=True)
    return out[[*KEYS, *vals, "iteration", "nfe", f"budget_{column}"]]


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


# ------------------------------------------------------------------------- parameter accuracy
def within_truth(runs: pd.DataFrame, tol: float) -> pd.Series:
    """Per run: whether every identified parameter (the run's non-NaN ``relerr_*`` columns) lies
    within ``tol`` (relative) of the truth; False for a run with no relative error at all."""
    cols = [c for c in runs.columns if c.startswith("relerr_")]
    if not cols:
        return pd.Series(False, index=runs.index)
    rel = runs[cols].abs()
    return (rel.le(tol) | rel.isna()).all(axis=1) & rel.notna().any(axis=1)


def share_column(tol: float) -> str:
    """The column of :func:`accuracy_shares` for tolerance ``tol`` (0.01 → share_within_1pct)."""
    return f"share_within_{round(100 * tol):d}pct"


def accuracy_shares(runs: pd.DataFrame, tols=ACCURACY_TOLERANCES) -> pd.DataFrame:
    """Per scenario × case × algorithm: ``n_seeds`` (runs with an ISE) and ``share_within_<x>pct``
    for each tolerance (the share of those seeds whose every identified parameter lies within
    x % of the truth; docs/reproduction-notes.md, E7)."""
    d = runs[runs["best_ise"].notna()].copy()
    names = [share_column(t) for t in tols]
    for name, t in zip(names, tols, strict=True):
        d[name] = within_truth(d, t).astype(float)
    g = d.groupby(["scenario", "case", "algorithm"], sort=True)
    out = g[names].mean()
    out.insert(0, "n_seeds", g.size())
    out = out.reset_index()
    order = {a: i for i, a in enumerate(algorithm_order(out["algorithm"]))}
    out["_order"] = out["algorithm"].map(order)
    out = out.sort_values(["scenario", "case", "_order"], kind="stable")
    return out.drop(columns="_order").reset_index(drop=True)


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
    df: pd.DataFrame,
    scenario: int,
    case: int,
    ref: str = "avoa",
    alpha: float = 0.05,
    margin: float | None = None,
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
      "no difference";
    - ``value`` (what was compared, :func:`value_column`), ``margin`` (``margin`` if given, else
      :func:`margin_of`), ``p_tost_holm`` (:func:`tost_pair`, Holm over the rivals) and
      ``size_verdict``: :func:`four_way` of ref against this rival ("lower": ref lower).
    """
    wide = _wide(df, scenario, case)
    margin = margin_of(df, scenario, case) if margin is None else float(margin)
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
                "_p_tost": tost_pair(pair[ref], pair[other], margin),
            }
        )
    out = pd.DataFrame(rows)
    if out.empty:
        return out
    out["p_holm"] = holm(out["p_raw"])
    out["p_one_sided_holm"] = holm(out["_p_less"])
    out["p_one_sided_greater_holm"] = holm(out["_p_greater"])
    out["value"] = value_column(df)
    out["margin"] = margin
    out["p_tost_holm"] = holm(out["_p_tost"])
    out["size_verdict"] = [
        four_way(*v, alpha)
        for v in zip(
            out["p_holm"], out["_p_less"], out["_p_greater"], out["p_tost_holm"], strict=True
        )
    ]

    def verdict(r) -> str:
        if np.isnan(r["p_raw"]):
            return "too few seeds"
        if r["p_holm"] < alpha:
            return "ref better" if r["_p_less"] < r["_p_greater"] else "ref worse"
        return "no difference"

    out["verdict"] = out.apply(verdict, axis=1)
    return out.drop(columns=["_p_less", "_p_greater", "_p_tost"])


def pairwise_wilcoxon(
    df: pd.DataFrame, scenario: int, case: int, margin: float | None = None, alpha: float = 0.05
) -> pd.DataFrame:
    """Paired Wilcoxon tests of every pair of algorithms, Holm-corrected over all pairs.

    Columns: ``a, b, n, median_diff`` (median of a − b), ``p_raw`` (two-sided), ``p_holm``,
    ``lower`` (the algorithm whose one-sided p is smaller: the one that tends to be lower;
    empty when the pair was not tested or all differences are zero), ``margin``,
    ``p_tost_holm`` (equivalence within ±margin, Holm over all pairs) and ``size_verdict``
    (:func:`four_way` of a against b).
    """
    wide = _wide(df, scenario, case)
    margin = margin_of(df, scenario, case) if margin is None else float(margin)
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
                    "_p_less": w["p_less"],
                    "_p_greater": w["p_greater"],
                    "_p_tost": tost_pair(pair[a], pair[b], margin),
                }
            )
    cols = ["a", "b", "n", "median_diff", "p_raw", "lower", "_p_less", "_p_greater", "_p_tost"]
    out = pd.DataFrame(rows, columns=cols)
    out.insert(5, "p_holm", holm(out["p_raw"]) if len(out) else [])
    out["margin"] = margin
    out["p_tost_holm"] = holm(out["_p_tost"]) if len(out) else []
    out["size_verdict"] = [
        four_way(*v, alpha)
        for v in zip(
            out["p_holm"], out["_p_less"], out["_p_greater"], out["p_tost_holm"], strict=True
        )
    ]
    return out.drop(columns=["_p_less", "_p_greater", "_p_tost"])


def mannwhitney(x, y, alternative: str = "less", min_n: int = MIN_SEEDS) -> float:
    """Mann-Whitney U p-value (unpaired) for ``alternative`` ("less": H1 ``x`` tends to be lower
    than ``y``; "greater"; "two-sided"). NaN when either sample has fewer than ``min_n`` values;
    1 when all values are equal.
    """
    x = np.asarray(x, dtype=float)
    y = np.asarray(y, dtype=float)
    x, y = x[~np.isnan(x)], y[~np.isnan(y)]
    if len(x) < min_n or len(y) < min_n:
        return np.nan
    both = np.concatenate([x, y])
    if np.all(both == both[0]):
        return 1.0
    return float(st.mannwhitneyu(x, y, alternative=alternative).pvalue)


def tost_ratio_unpaired(x, y, ratio: float = TIME_RATIO, min_n: int = MIN_SEEDS) -> float:
    """Two one-sided Mann-Whitney tests (unpaired) that ``x`` / ``y`` lies inside
    [1/``ratio``, ``ratio``] (E5), on log values shifted by ±log ``ratio``: H1 of the first,
    log x − log ratio tends below log y; of the second, log x + log ratio above it. Returns the
    larger p; NaN with fewer than ``min_n`` positive values in either sample."""
    x = np.asarray(x, dtype=float)
    y = np.asarray(y, dtype=float)
    x, y = x[np.isfinite(x) & (x > 0)], y[np.isfinite(y) & (y > 0)]
    if len(x) < min_n or len(y) < min_n:
        return np.nan
    lx, ly, lr = np.log(x), np.log(y), np.log(ratio)
    p1 = st.mannwhitneyu(lx - lr, ly, alternative="less").pvalue
    p2 = st.mannwhitneyu(lx + lr, ly, alternative="greater").pvalue
    return float(max(p1, p2))


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
