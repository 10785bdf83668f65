"""The paper's claims, each decided by our runs under two protocols.

:func:`claims` returns one row per claim × place × protocol. Protocols:

- ``"paper: 500 iterations"`` — every algorithm's final best ISE after the paper's iteration
  budget (the *runs* frame), whatever each algorithm spends per iteration;
- ``"equal evaluations"`` — every algorithm's best ISE after the same number of objective
  evaluations N, read from the histories (N = :func:`~.stats.common_nfe` of the scenario × case:
  the largest N every run reaches).

Verdicts: "supported", "not supported", "inconclusive" (the data cannot decide: a rival or a
scenario × case is missing, or fewer than ``stats.MIN_SEEDS`` matched seeds). The claims and how
each is decided (α = ``alpha``; "Holm" = Holm correction over the comparisons of that row):

C1 *AVOA has the lowest ISE in every case.* Per scenario × case: paired one-sided Wilcoxon
   (H1: AVOA lower) against each of the six rivals on matched seeds, Holm over the six.
   Supported only if AVOA is significantly lower than all six; not supported otherwise (the
   evidence names the rivals it does not beat and any rival significantly *lower* than AVOA).
   "all": supported if supported in every scenario × case (an intersection-union test, so no
   further correction), not supported if not supported in any.
C2 *The printed ranks.* Per scenario × case, our order is the mean per-seed rank (Friedman
   style). Kendall's τ-b between the paper's ranks and ours is reported. Supported if no pair
   of algorithms is ordered against the paper (printed ties, e.g. "2,3", constrain nothing);
   not supported if some pair ordered against the paper differs significantly in our runs
   (two-sided paired Wilcoxon, Holm over all 21 pairs, in the direction opposite to the
   paper); inconclusive if pairs are reversed but none significantly. (Holm over 21 pairs
   needs at least 10 seeds before any pair can be significant.)
C3 *GA is worst in every case* (printed rank 7 everywhere). As C1 with GA as the reference and
   H1: GA higher.
C4 *AVOA has the best convergence curve.* Convergence is read at 10 % and 50 % of the budget
   (``CHECKPOINTS``; the paper protocol: of the iterations, the equal-evaluation protocol: of
   N evaluations); the end of the budget is C1. At each checkpoint the test of C1 is run on the
   best-so-far ISE; supported only if AVOA is significantly lower than all six at every
   checkpoint.
C5 *AVOA is the fastest* (Table 24, scenario 4 case 4; and over all runs, "all"). Time is
   protocol-independent, so the protocols select the measure: time per iteration (what Table 24
   prints) under the paper protocol, time per evaluation (the cost of an equal-evaluation
   budget) under equal evaluations. One-sided Mann-Whitney (H1: AVOA's times lower; runs are
   not paired by seed) against each rival, Holm over six; supported only if all six are
   significant. Evidence gives our ratios to AVOA next to the paper's.
C6 *Scenario 4 case 4 is the most time-consuming.* Its runs against each of the other scenario ×
   case combinations, blocked by (algorithm, seed): paired one-sided Wilcoxon (H1: S4C4
   slower), Holm over the other combinations; supported only if all are significant. Measure
   as in C5.
C7 *AVOA is the most reliable.* Reliability = spread of the final ISE over seeds. Brown-Forsythe
   test (ANOVA on |ISE − median|) of AVOA against each rival, Holm over six; supported only if
   every test is significant with AVOA's spread (mean |ISE − median|) the smaller.
C8 *AVOA reaches the lowest ISE of all.* The paper prints one run per algorithm, so this reads
   "AVOA's best run beats every rival's best run": min over seeds, descriptive (no test);
   supported if AVOA's minimum is strictly the lowest.

``paper_verdict`` is what the paper's own printed numbers say ("supported" / "not supported"),
or "claimed (no numbers)" / "claimed (figures only)" where the paper gives only words or
figures. For C1, C3 and C8 it reads the printed ISE of Tables 20-23; for C2 it says whether the
printed ranks agree with the printed ISE (they do not in S1/C4, where Quasi-Newton and RK are
swapped); for C5 it reads Table 24.
"""

from __future__ import annotations

import math
from itertools import combinations

import numpy as np
import pandas as pd
from scipy import stats as st

from ..optimizers import ALGORITHMS, PAPER_LABELS
from . import stats

PROTOCOL_PAPER = "paper: 500 iterations"
PROTOCOL_EQUAL = "equal evaluations"
CHECKPOINTS = (0.1, 0.5)
"""Fractions of the budget at which C4 compares the convergence curves."""

SUPPORTED, NOT_SUPPORTED, INCONCLUSIVE = "supported", "not supported", "inconclusive"
CLAIMED = "claimed (no numbers)"

CLAIM_TEXT = {
    "C1": (
        "AVOA has the lowest ISE in every case (Sec. 5: 'As shown in Tables 20-23, based on the "
        "integral square error (ISE) and convergence curve, the AVOA gives the least (ISE) and "
        "best convergence curves in all scenarios.')"
    ),
    "C2": "The printed ranks of the seven algorithms by ISE (Tables 20-23, 'Rank' rows)",
    "C3": "GA is worst in every case (Tables 20-23: GA ranked '7 (Max.)' in all 16 cases)",
    "C4": (
        "AVOA has the best convergence curve (Sec. 5: 'the AVOA shows the best results based on "
        "the least integral square error and best convergence curve'; Figures 4-19)"
    ),
    "C5": (
        "AVOA is the fastest (Sec. 5: 'the AVOA takes less computational time. It is much "
        "faster than the compared algorithms', Table 24; Sec. 6: 'The computational "
        "complexity and running time of the AVOA are much shorter than those of all the "
        "comparable algorithms.')"
    ),
    "C6": (
        "Scenario 4 case 4 is the most time-consuming (Sec. 5: 'Scenario (4)-Case (4), which "
        "is considered the most time-consuming scenario, as it includes loading, fading, and "
        "charge dynamics')"
    ),
    "C7": (
        "AVOA is the most reliable: smallest spread of ISE over seeds (Sec. 6: 'The AVOA "
        "produces the most reliable and effective solution.')"
    ),
    "C8": (
        "AVOA's best run reaches the lowest ISE (Sec. 6: 'When compared with other methods, "
        "the fitness function reaches the lowest value.')"
    ),
}

COLUMNS = [
    "claim_id",
    "claim",
    "where",
    "scenario",
    "case",
    "protocol",
    "paper_verdict",
    "our_verdict",
    "evidence",
]


# ------------------------------------------------------------------------------------ helpers
def _lab(a: str) -> str:
    return PAPER_LABELS.get(a, a)


def _p(p) -> str:
    return "n/a" if p is None or (isinstance(p, float) and math.isnan(p)) else f"{p:.2g}"


def _g(x) -> str:
    return "n/a" if x is None or (isinstance(x, float) and math.isnan(x)) else f"{x:.4g}"


def _where(s, c) -> str:
    return "all" if s is None else f"S{s}/C{c}"


def _row(cid, s, c, protocol, paper_verdict, verdict, evidence) -> dict:
    return {
        "claim_id": cid,
        "claim": CLAIM_TEXT[cid],
        "where": _where(s, c),
        "scenario": s,
        "case": c,
        "protocol": protocol,
        "paper_verdict": paper_verdict,
        "our_verdict": verdict,
        "evidence": evidence,
    }


def _missing(df: pd.DataFrame, s: int, c: int) -> list[str]:
    sub = df[(df["scenario"] == s) & (df["case"] == c) & df["best_ise"].notna()]
    return [a for a in ALGORITHMS if a not in set(sub["algorithm"])]


def _combine(verdicts: dict, expected: set) -> tuple[str, str]:
    """The "all" verdict from per-place verdicts, and its evidence."""
    sup = [k for k, v in verdicts.items() if v == SUPPORTED]
    nos = [k for k, v in verdicts.items() if v == NOT_SUPPORTED]
    inc = [k for k, v in verdicts.items() if v == INCONCLUSIVE]
    absent = sorted(expected - set(verdicts))
    if nos:
        verdict = NOT_SUPPORTED
    elif not inc and not absent and sup:
        verdict = SUPPORTED
    else:
        verdict = INCONCLUSIVE
    n = len(expected | set(verdicts))
    parts = [f"supported in {len(sup)}/{n}"]
    if nos:
        parts.append("not supported in " + ", ".join(_where(*k) for k in sorted(nos)))
    if inc:
        parts.append("inconclusive in " + ", ".join(_where(*k) for k in sorted(inc)))
    if absent:
        parts.append("no runs for " + ", ".join(_where(*k) for k in absent))
    return verdict, "; ".join(parts)


def _paper_lookup(paper_objective: pd.DataFrame | None) -> dict:
    """{(scenario, case): {algorithm: (ise, rank)}} from objective.csv."""
    out: dict = {}
    if paper_objective is None or paper_objective.empty:
        return out
    for r in paper_objective.itertuples(index=False):
        out.setdefault((int(r.scenario), int(r.case)), {})[stats.algorithm_key(r.algorithm)] = (
            float(r.ise),
            int(r.rank),
        )
    return out


def _paper_extreme(paper: dict, key, ref: str, lowest: bool) -> str:
    p = paper.get(key)
    if not p or ref not in p:
        return "not printed"
    mine = p[ref][0]
    others = [v[0] for a, v in p.items() if a != ref]
    ok = all(mine < o for o in others) if lowest else all(mine > o for o in others)
    return SUPPORTED if ok else NOT_SUPPORTED


def _dominance(df, s, c, ref, column, alpha, lower: bool) -> tuple[str, str]:
    """C1/C3 per scenario × case: ``ref`` significantly lower (higher) than all six rivals."""
    missing = _missing(df, s, c)
    if ref in missing:
        return INCONCLUSIVE, f"no runs of {_lab(ref)}"
    hw = stats.holm_wilcoxon(df, s, c, ref=ref, alpha=alpha)
    if hw.empty:
        return INCONCLUSIVE, "no rivals with runs"
    sig = hw[column] < alpha
    contra = hw[hw["verdict"] == ("ref worse" if lower else "ref better")]["other"]
    parts = [f"{_lab(ref)} median ISE {_g(hw['median_ref'].iloc[0])}"]
    for r in hw.itertuples(index=False):
        parts.append(
            f"vs {_lab(r.other)}: n={r.n}, median diff {_g(r.median_diff)}, "
            f"p_holm(one-sided)={_p(getattr(r, column))}"
        )
    if len(contra):
        word = "lower" if lower else "higher"
        parts.append(
            "rivals significantly " + word + " than " + _lab(ref) + ": "
            f"{', '.join(map(_lab, contra))}"
        )
    if missing:
        parts.append("no runs of " + ", ".join(map(_lab, missing)))
        return INCONCLUSIVE, "; ".join(parts)
    if (hw["verdict"] == "too few seeds").any():
        return INCONCLUSIVE, "; ".join(parts)
    not_beaten = hw[~sig]["other"]
    if len(not_beaten):
        parts.append(
            ("not significantly " + ("lower" if lower else "higher") + " than: ")
            + ", ".join(map(_lab, not_beaten))
        )
    return (SUPPORTED if sig.all() else NOT_SUPPORTED), "; ".join(parts)


# ------------------------------------------------------------------------------------ claims
def _c1_c3(df, combos, expected, paper, protocol, alpha, cid):
    ref, lower = ("avoa", True) if cid == "C1" else ("ga", False)
    column = "p_one_sided_holm" if lower else "p_one_sided_greater_holm"
    rows, verdicts = [], {}
    for s, c in combos:
        v, ev = _dominance(df, s, c, ref, column, alpha, lower)
        verdicts[(s, c)] = v
        rows.append(_row(cid, s, c, protocol, _paper_extreme(paper, (s, c), ref, lower), v, ev))
    v, ev = _combine(verdicts, expected)
    pv = [_paper_extreme(paper, k, ref, lower) for k in sorted(expected)]
    rows.append(_row(cid, None, None, protocol, _combine_paper(pv), v, ev))
    return rows


def _combine_paper(pv: list[str]) -> str:
    if not pv:
        return "not printed"
    if NOT_SUPPORTED in pv:
        return NOT_SUPPORTED
    return SUPPORTED if all(v == SUPPORTED for v in pv) else "partly printed"


def _kendall(x, y) -> tuple[float, float]:
    x, y = np.asarray(x, float), np.asarray(y, float)
    if len(x) < 3 or np.all(x == x[0]) or np.all(y == y[0]):
        return np.nan, np.nan
    res = st.kendalltau(x, y)
    return float(res.statistic), float(res.pvalue)


def _c2(df, combos, expected, paper, protocol, alpha):
    rows, verdicts, taus = [], {}, []
    rk = stats.ranks(df)
    for s, c in combos:
        pr = paper.get((s, c), {})
        missing = _missing(df, s, c)
        if missing or any(a not in pr for a in ALGORITHMS):
            why = "no runs of " + ", ".join(map(_lab, missing)) if missing else "ranks not printed"
            verdicts[(s, c)] = INCONCLUSIVE
            rows.append(_row("C2", s, c, protocol, "not printed", INCONCLUSIVE, why))
            continue
        # the paper's own consistency: printed ranks against the printed ISE order
        p_ise = pd.Series({a: pr[a][0] for a in ALGORITHMS})
        p_rank = pd.Series({a: pr[a][1] for a in ALGORITHMS})
        clash = [a for a in ALGORITHMS if p_ise.rank(method="min")[a] != p_rank[a]]
        pv = SUPPORTED if not clash else NOT_SUPPORTED
        r = rk[(rk["scenario"] == s) & (rk["case"] == c)].set_index("algorithm")
        ours = r["mean_rank"].reindex(list(ALGORITHMS))
        tau, tau_p = _kendall(p_rank.to_numpy(), ours.to_numpy())
        taus.append(tau)
        disc = [
            (a, b) if p_rank[a] < p_rank[b] else (b, a)
            for a, b in combinations(ALGORITHMS, 2)
            if (p_rank[a] - p_rank[b]) * (ours[a] - ours[b]) < 0
        ]
        order = " < ".join(f"{_lab(a)} ({ours[a]:.2f})" for a in ours.sort_values().index)
        parts = [
            f"Kendall tau-b = {_g(tau)} (p={_p(tau_p)}), n_blocks={int(r['n_blocks'].iloc[0])}",
            f"ours by mean rank: {order}",
        ]
        if clash:
            parts.append(
                "paper's printed ranks contradict its printed ISE for "
                + ", ".join(map(_lab, clash))
            )
        if int(r["n_blocks"].iloc[0]) < stats.MIN_SEEDS:
            verdicts[(s, c)] = INCONCLUSIVE
            rows.append(_row("C2", s, c, protocol, pv, INCONCLUSIVE, "; ".join(parts)))
            continue
        if not disc:
            v = SUPPORTED
            parts.append("no pair ordered against the paper")
        else:
            pw = stats.pairwise_wilcoxon(df, s, c).set_index(["a", "b"])
            reversed_sig, desc = [], []
            for better, worse in disc:  # the paper ranks `better` above `worse`
                key = (better, worse) if (better, worse) in pw.index else (worse, better)
                row = pw.loc[key]
                sig = row["p_holm"] < alpha and row["lower"] == worse
                reversed_sig.append(sig)
                desc.append(
                    f"{_lab(better)}/{_lab(worse)} reversed (p_holm={_p(row['p_holm'])}"
                    + (", significant" if sig else "")
                    + ")"
                )
            v = NOT_SUPPORTED if any(reversed_sig) else INCONCLUSIVE
            parts.append(f"{len(disc)} of 21 pairs ordered against the paper: " + ", ".join(desc))
        verdicts[(s, c)] = v
        rows.append(_row("C2", s, c, protocol, pv, v, "; ".join(parts)))
    v, ev = _combine(verdicts, expected)
    if taus:
        finite = [t for t in taus if np.isfinite(t)]
        ev += f"; mean Kendall tau-b {_g(float(np.mean(finite)) if finite else np.nan)}"
    pvs = [r["paper_verdict"] for r in rows]
    rows.append(_row("C2", None, None, protocol, _combine_paper(pvs), v, ev))
    return rows


def _c4(histories, combos, expected, protocol, alpha):
    by = "iteration" if protocol == PROTOCOL_PAPER else "nfe"
    frames = {f: stats.at_budget(histories, f, by=by) for f in CHECKPOINTS}
    rows, verdicts = [], {}
    for s, c in combos:
        vs, parts = [], []
        for f, fr in frames.items():
            v, ev = _dominance(fr, s, c, "avoa", "p_one_sided_holm", alpha, True)
            sub = fr[(fr["scenario"] == s) & (fr["case"] == c)]
            limit = sub[f"budget_{by}"].iloc[0] if len(sub) else np.nan
            med = sub.groupby("algorithm")["best_ise"].median()
            rank = int(med.rank(method="min").get("avoa", 0)) if med.notna().any() else 0
            vs.append(v)
            parts.append(
                f"at {f:.0%} ({by} ≤ {_g(float(limit))}): {v}; AVOA's median rank {rank}/"
                f"{med.notna().sum()}; {ev}"
            )
        if NOT_SUPPORTED in vs:
            v = NOT_SUPPORTED
        elif all(x == SUPPORTED for x in vs):
            v = SUPPORTED
        else:
            v = INCONCLUSIVE
        verdicts[(s, c)] = v
        rows.append(_row("C4", s, c, protocol, "claimed (figures only)", v, " | ".join(parts)))
    v, ev = _combine(verdicts, expected)
    rows.append(_row("C4", None, None, protocol, "claimed (figures only)", v, ev))
    return rows


def _time_measure(protocol: str) -> tuple[str, str]:
    if protocol == PROTOCOL_PAPER:
        return "time_per_iter_s", "time per iteration"
    return "time_per_eval_s", "time per evaluation"


def _c5(runs, paper_time, protocol, alpha):
    col, what = _time_measure(protocol)
    paper = {}
    if paper_time is not None and len(paper_time):
        paper = {
            stats.algorithm_key(a): float(t)
            for a, t in zip(paper_time["algorithm"], paper_time["seconds"], strict=True)
        }
    pv = "not printed"
    if "avoa" in paper and all(a in paper for a in ALGORITHMS):
        pv = (
            SUPPORTED
            if all(paper["avoa"] < paper[a] for a in ALGORITHMS if a != "avoa")
            else NOT_SUPPORTED
        )
    rows = []
    for where in ((4, 4), (None, None)):
        s, c = where
        sub = runs if s is None else runs[(runs["scenario"] == s) & (runs["case"] == c)]
        sub = sub[sub[col].notna()] if col in sub else sub.iloc[0:0]
        t = {a: sub[sub["algorithm"] == a][col].to_numpy() for a in ALGORITHMS}
        rivals = [a for a in ALGORITHMS if a != "avoa"]
        p_less = stats.holm([stats.mannwhitney_less(t["avoa"], t[a]) for a in rivals])
        p_more = stats.holm([stats.mannwhitney_less(t[a], t["avoa"]) for a in rivals])
        mean_avoa = float(np.mean(t["avoa"])) if len(t["avoa"]) else np.nan
        parts = [f"{what}: AVOA mean {_g(mean_avoa)} s"]
        for a, pl in zip(rivals, p_less, strict=True):
            ratio = float(np.mean(t[a])) / mean_avoa if len(t[a]) and mean_avoa > 0 else np.nan
            pr = ""
            if s is not None and a in paper and "avoa" in paper and col == "time_per_iter_s":
                pr = f", paper {paper[a] / paper['avoa']:.2f}x"
            if not len(t[a]):
                parts.append(f"{_lab(a)}: no runs")
                continue
            parts.append(f"{_lab(a)} {_g(ratio)}x AVOA (p_holm={_p(pl)}{pr})")
        faster = [_lab(a) for a, pm in zip(rivals, p_more, strict=True) if pm < alpha]
        if faster:
            parts.append("significantly faster than AVOA: " + ", ".join(faster))
        if col == "time_per_iter_s" and "evals_per_iter" in sub:
            epi = sub.groupby("algorithm")["evals_per_iter"].mean()
            parts.append(
                "evals/iteration: "
                + ", ".join(f"{_lab(a)} {_g(float(epi[a]))}" for a in ALGORITHMS if a in epi)
            )
        if col == "time_per_iter_s" and "time_per_eval_s" in sub:
            tpe = sub.groupby("algorithm")["time_per_eval_s"].mean()
            if "avoa" in tpe and tpe["avoa"] > 0:
                parts.append(
                    "per evaluation: "
                    + ", ".join(
                        f"{_lab(a)} {_g(float(tpe[a] / tpe['avoa']))}x" for a in rivals if a in tpe
                    )
                )
        if np.isnan(p_less).any():
            v = INCONCLUSIVE
        else:
            v = SUPPORTED if (p_less < alpha).all() else NOT_SUPPORTED
        if s is None:
            pvr = CLAIMED + "; Table 24 covers S4/C4 only"
        elif col == "time_per_iter_s":
            pvr = pv
        else:
            pvr = pv + " (per iteration; per evaluation not printed)" if pv != "not printed" else pv
        rows.append(_row("C5", s, c, protocol, pvr, v, "; ".join(parts)))
    return rows


def _c6(runs, protocol, alpha):
    col, what = _time_measure(protocol)
    if col not in runs:
        return [_row("C6", 4, 4, protocol, CLAIMED, INCONCLUSIVE, f"no {what} in the runs")]
    d = runs[runs[col].notna()]
    combos = stats.scenario_cases(d)
    target = (4, 4)
    if target not in combos or len(combos) < 2:
        return [_row("C6", 4, 4, protocol, CLAIMED, INCONCLUSIVE, "S4/C4 or other cases missing")]
    key = ["algorithm", "seed"]
    tgt = d[(d["scenario"] == 4) & (d["case"] == 4)].set_index(key)[col]
    others = [sc for sc in combos if sc != target]
    results = []
    for s, c in others:
        o = d[(d["scenario"] == s) & (d["case"] == c)].set_index(key)[col]
        both = pd.concat([tgt.rename("t"), o.rename("o")], axis=1, join="inner")
        w = stats.wilcoxon_pair(both["t"], both["o"])
        results.append((s, c, w["p_greater"], float(o.median()), w["n"]))
    p_holm = stats.holm([r[2] for r in results])
    med = {(s, c): m for s, c, _, m, _ in results}
    med[target] = float(tgt.median())
    order = sorted(med, key=med.get, reverse=True)
    parts = [
        f"{what}, blocked by algorithm × seed: S4/C4 median {_g(med[target])} s, "
        f"rank {order.index(target) + 1} of {len(order)} (1 = slowest)",
        f"slowest: {_where(*order[0])} ({_g(med[order[0]])} s)",
    ]
    weak = [
        f"{_where(s, c)} (p_holm={_p(p)})"
        for (s, c, _, _, _), p in zip(results, p_holm, strict=True)
        if not p < alpha
    ]
    if weak:
        parts.append("S4/C4 not significantly slower than: " + ", ".join(weak))
    if np.isnan(p_holm).any():
        v = INCONCLUSIVE
    else:
        v = SUPPORTED if (p_holm < alpha).all() else NOT_SUPPORTED
    return [_row("C6", 4, 4, protocol, CLAIMED, v, "; ".join(parts))]


def _c7(df, combos, expected, protocol, alpha):
    rows, verdicts = [], {}
    for s, c in combos:
        sub = df[(df["scenario"] == s) & (df["case"] == c) & df["best_ise"].notna()]
        missing = _missing(df, s, c)
        x = {a: sub[sub["algorithm"] == a]["best_ise"].to_numpy() for a in ALGORITHMS}
        spread = {
            a: float(np.mean(np.abs(v - np.median(v)))) if len(v) else np.nan for a, v in x.items()
        }
        iqr = {
            a: float(np.subtract(*np.percentile(v, [75, 25]))) if len(v) else np.nan
            for a, v in x.items()
        }
        rivals = [a for a in ALGORITHMS if a != "avoa"]
        enough = all(len(x[a]) >= stats.MIN_SEEDS for a in ALGORITHMS)
        p = stats.holm(
            [stats.brown_forsythe(x["avoa"], x[a]) if enough else np.nan for a in rivals]
        )
        rank = pd.Series(iqr).rank(method="min")
        parts = [
            f"IQR of ISE over seeds: AVOA {_g(iqr['avoa'])} (rank {_g(rank.get('avoa'))} of 7)"
        ]
        ok = []
        for a, pa in zip(rivals, p, strict=True):
            smaller = spread["avoa"] < spread[a]
            ok.append(bool(pa < alpha and smaller))
            parts.append(f"{_lab(a)} IQR {_g(iqr[a])} (Brown-Forsythe p_holm={_p(pa)})")
        if missing or not enough:
            v = INCONCLUSIVE
            parts.append(
                "too few runs" if not missing else "no runs of " + ", ".join(map(_lab, missing))
            )
        else:
            v = SUPPORTED if all(ok) else NOT_SUPPORTED
        verdicts[(s, c)] = v
        rows.append(_row("C7", s, c, protocol, CLAIMED, v, "; ".join(parts)))
    v, ev = _combine(verdicts, expected)
    rows.append(_row("C7", None, None, protocol, CLAIMED, v, ev))
    return rows


def _c8(df, combos, expected, paper, protocol):
    rows, verdicts = [], {}
    for s, c in combos:
        sub = df[(df["scenario"] == s) & (df["case"] == c) & df["best_ise"].notna()]
        missing = _missing(df, s, c)
        best = sub.groupby("algorithm")["best_ise"].min().reindex(list(ALGORITHMS))
        parts = [
            "best run over seeds: " + ", ".join(f"{_lab(a)} {_g(best[a])}" for a in ALGORITHMS)
        ]
        if missing:
            v = INCONCLUSIVE
            parts.append("no runs of " + ", ".join(map(_lab, missing)))
        else:
            others = best.drop("avoa")
            v = SUPPORTED if (best["avoa"] < others).all() else NOT_SUPPORTED
            parts.append(f"AVOA's best run ranks {int(best.rank(method='min')['avoa'])} of 7")
        verdicts[(s, c)] = v
        rows.append(
            _row(
                "C8",
                s,
                c,
                protocol,
                _paper_extreme(paper, (s, c), "avoa", True),
                v,
                "; ".join(parts),
            )
        )
    v, ev = _combine(verdicts, expected)
    pv = [_paper_extreme(paper, k, "avoa", True) for k in sorted(expected)]
    rows.append(_row("C8", None, None, protocol, _combine_paper(pv), v, ev))
    return rows


def claims(
    runs: pd.DataFrame,
    histories: pd.DataFrame,
    paper_objective: pd.DataFrame | None,
    paper_time: pd.DataFrame | None,
    alpha: float = 0.05,
) -> pd.DataFrame:
    """Decide the paper's claims (C1-C8 of the module docstring) under both protocols.

    ``runs`` and ``histories`` are the aggregates of docs/records.md; ``paper_objective`` and
    ``paper_time`` are config/paper/objective.csv and time_per_iteration.csv as DataFrames.
    Returns one row per claim × place × protocol with columns ``claim_id, claim, where``
    ("S<s>/C<c>" or "all"), ``scenario, case`` (nullable ints; empty for "all"), ``protocol,
    paper_verdict, our_verdict`` ("supported" / "not supported" / "inconclusive"), and
    ``evidence`` (the numbers behind the verdict: medians, p-values, ranks, ratios).
    """
    paper = _paper_lookup(paper_objective)
    combos = stats.scenario_cases(runs)
    expected = set(paper) | set(combos)
    protocols = {
        PROTOCOL_PAPER: runs,
        PROTOCOL_EQUAL: stats.at_budget(histories, 1.0, by="nfe"),
    }
    rows: list[dict] = []
    for cid in ("C1", "C2", "C3", "C4", "C5", "C6", "C7", "C8"):
        for protocol, df in protocols.items():
            if cid in ("C1", "C3"):
                rows += _c1_c3(df, combos, expected, paper, protocol, alpha, cid)
            elif cid == "C2":
                rows += _c2(df, combos, expected, paper, protocol, alpha)
            elif cid == "C4":
                rows += _c4(histories, combos, expected, protocol, alpha)
            elif cid == "C5":
                rows += _c5(runs, paper_time, protocol, alpha)
            elif cid == "C6":
                rows += _c6(runs, protocol, alpha)
            elif cid == "C7":
                rows += _c7(df, combos, expected, protocol, alpha)
            else:
                rows += _c8(df, combos, expected, paper, protocol)
    out = pd.DataFrame(rows, columns=COLUMNS)
    out["scenario"] = out["scenario"].astype("Int64")
    out["case"] = out["case"].astype("Int64")
    return out
