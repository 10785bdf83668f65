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

C9 *AVOA identifies the parameters most accurately* (new; the Abstract's "high accuracy"): per
   scenario × case the share of seeds whose every identified parameter lies within 1 % of the
   truth; exact McNemar test (paired by seed) of AVOA against each rival, Holm over six;
   supported only if AVOA's share is significantly larger than all six. Final parameters only,
   so under the paper protocol only.

How much, not only whether (docs/reproduction-notes.md, E1-E8). Every comparison is made on the
excess over the truth, e = (ISE − ISE_true) / ISE_true, and has an equivalence margin: for ISE
the rise a 0.1 mV model error causes on that record (m = N·δ² / ISE_true; about 1 % of the
truth's ISE in cases 2 and 4, whose truth leaves only the 1 mV noise, and 0.001-0.02 % in cases
1 and 3, whose truth also leaves the relaxation the model lacks), for time the ratio 0.8-1.25,
for spread ±m, for parameter-accuracy shares ±10 points. ``verdict`` then reads the claim's
reference against its rivals in four words (lower, higher, practically equivalent,
inconclusive; E4), ``size`` is the decisive comparison's effect (the median paired difference,
in ``unit``) and ``margin`` the margin it was judged against. ``budgets`` says which verdict the
claim gets at 1, 2, 5, 10, 20, 50 and 100 % of each pair's common evaluation count N (E8).
``our_verdict`` keeps the earlier supported / not supported reading and ``evidence`` its
p-values.

``paper_verdict`` is what the paper's own printed numbers say ("supported" / "not supported"),
or "claimed (no numbers)" / "claimed (figures only)" where the paper gives only words or
figures. For C1, C3 and C8 it reads the printed ISE of Tables 20-23; for C2 it says whether the
printed ranks agree with the printed ISE (they do not in S1/C4, where Quasi-Newton and RK are
swapped); for C5 it reads Table 24.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
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
    "C9": (
        "AVOA identifies the parameters most accurately: the largest share of seeds with every "
        "parameter within 1 % of the truth (Abstract: 'The proposed AVOA was fulfilled with high "
        "accuracy, the least error, and high closeness with the experimental data')"
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
    "verdict",
    "size",
    "margin",
    "unit",
    "reference",
    "budgets",
    "evidence",
]


@dataclass(frozen=True)
class _Ctx:
    """What every claim function needs besides its data."""

    alpha: float
    margins: dict  # (scenario, case) → equivalence margin in the compared value's units (E2)
    scale: float  # compared value → reported unit (100: excess as % of the truth's ISE)
    unit: str
    value: str  # "excess_ise" or "best_ise"
    seed: int  # bootstrap seed (E6, E7)

    def margin(self, s, c) -> float:
        return float(self.margins.get((s, c), np.nan))

    def rng(self, *key) -> np.random.SeedSequence:
        return np.random.SeedSequence([int(self.seed), *[int(k) for k in key]])


# ------------------------------------------------------------------------------------ helpers
def _lab(a: str) -> str:
    return PAPER_LABELS.get(a, a)


def _p(p) -> str:
    return "n/a" if p is None or (isinstance(p, float) and math.isnan(p)) else f"{p:.2g}"


def _g(x) -> str:
    return "n/a" if x is None or (isinstance(x, float) and math.isnan(x)) else f"{x:.4g}"


def _where(s, c) -> str:
    return "all" if s is None else f"S{s}/C{c}"


def _row(cid, s, c, protocol, paper_verdict, verdict, evidence, size=None) -> dict:
    """One row; ``size`` is a :class:`_Size` (the four-word verdict, its size and margin)."""
    size = size or _Size(stats.INCONCLUSIVE)
    return {
        "claim_id": cid,
        "claim": CLAIM_TEXT[cid],
        "where": _where(s, c),
        "scenario": s,
        "case": c,
        "protocol": protocol,
        "paper_verdict": paper_verdict,
        "our_verdict": verdict,
        "verdict": size.verdict,
        "size": size.size,
        "margin": size.margin,
        "unit": size.unit,
        "reference": size.reference,
        "budgets": "",
        "evidence": evidence,
        "_counts": size.counts,
    }


@dataclass
class _Size:
    """A claim's four-word verdict (reproduction-notes E4), the size of the decisive comparison
    and the margin it was judged against."""

    verdict: str
    size: float = np.nan
    margin: float = np.nan
    unit: str = ""
    reference: str = ""
    counts: str = ""

    @classmethod
    def decide(cls, words, sizes, lowest: bool, margin, unit, reference) -> _Size:
        """The claim's verdict from its comparisons' verdicts (:func:`stats.combine_four`) and
        the decisive size: the largest of ``sizes`` for a "lowest" claim, the smallest for a
        "highest" one (NaNs left out)."""
        finite = [float(x) for x in sizes if np.isfinite(x)]
        size = (max(finite) if lowest else min(finite)) if finite else np.nan
        return cls(stats.combine_four(list(words), lowest=lowest), size, margin, unit, reference)


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


def _combine_sizes(sizes: dict, expected: set, lowest: bool) -> _Size:
    """The "all" row's four-word verdict from the places' (E4: one place against the claim is
    enough; a place without runs leaves it inconclusive otherwise); its size is the decisive
    place's (largest for a "lowest" claim, smallest for a "highest" one), its margin the
    median of the places'."""
    if not sizes:
        return _Size(stats.INCONCLUSIVE)
    words = [z.verdict for z in sizes.values()]
    v = stats.combine_four(words, lowest=lowest)
    bad = stats.HIGHER if lowest else stats.LOWER
    if expected - set(sizes) and v != bad:
        v = stats.INCONCLUSIVE
    vals = [z.size for z in sizes.values() if np.isfinite(z.size)]
    size = (max(vals) if lowest else min(vals)) if vals else np.nan
    margins = [z.margin for z in sizes.values() if np.isfinite(z.margin)]
    first = next(iter(sizes.values()))
    counts = ", ".join(f"{w} {words.count(w)}" for w in sorted(set(words), key=words.index))
    return _Size(v, size, float(np.median(margins)) if margins else np.nan, first.unit,
                 first.reference, counts)  # fmt: skip


def _all_row(cid, protocol, paper_verdict, verdicts, sizes, expected, lowest, note="") -> dict:
    """The "all" row of a claim: its test verdict over the places (:func:`_combine`) and its
    four-word verdict and size (:func:`_combine_sizes`); ``note`` is added to the evidence."""
    v, ev = _combine(verdicts, expected)
    z = _combine_sizes(sizes, expected, lowest)
    return _row(cid, None, None, protocol, paper_verdict, v, ev + note, z)


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


def _value_name(ctx: _Ctx) -> str:
    return "excess" if ctx.value == "excess_ise" else "ISE"


def _dominance(df, s, c, ref, column, ctx: _Ctx, lower: bool) -> tuple[str, str, _Size]:
    """C1/C3 per scenario × case: ``ref`` significantly lower (higher) than all six rivals, and
    the four-word verdict with the decisive rival's median paired difference."""
    missing = _missing(df, s, c)
    m = ctx.margin(s, c)
    ref_text = f"{_lab(ref)} − each rival"
    if ref in missing:
        return INCONCLUSIVE, f"no runs of {_lab(ref)}", _Size(stats.INCONCLUSIVE)
    hw = stats.holm_wilcoxon(df, s, c, ref=ref, alpha=ctx.alpha, margin=m)
    if hw.empty:
        return INCONCLUSIVE, "no rivals with runs", _Size(stats.INCONCLUSIVE)
    alpha = ctx.alpha
    sig = hw[column] < alpha
    contra = hw[hw["verdict"] == ("ref worse" if lower else "ref better")]["other"]
    name = _value_name(ctx)
    parts = [f"{_lab(ref)} median {name} {_g(hw['median_ref'].iloc[0] * ctx.scale)}"]
    for r in hw.itertuples(index=False):
        parts.append(
            f"vs {_lab(r.other)}: n={r.n}, median diff {_g(r.median_diff * ctx.scale)}, "
            f"p_holm(one-sided)={_p(getattr(r, column))}, p_equiv(Holm)={_p(r.p_tost_holm)}: "
            f"{r.size_verdict}"
        )
    if len(contra):
        word = "lower" if lower else "higher"
        parts.append(
            "rivals significantly " + word + " than " + _lab(ref) + ": "
            f"{', '.join(map(_lab, contra))}"
        )
    diffs = hw["median_diff"] * ctx.scale
    size = _Size.decide(hw["size_verdict"], diffs, lower, m * ctx.scale, ctx.unit, ref_text)
    if missing:
        parts.append("no runs of " + ", ".join(map(_lab, missing)))
        size.verdict = stats.INCONCLUSIVE
        return INCONCLUSIVE, "; ".join(parts), size
    if (hw["verdict"] == "too few seeds").any():
        return INCONCLUSIVE, "; ".join(parts), size
    not_beaten = hw[~sig]["other"]
    if len(not_beaten):
        parts.append(
            ("not significantly " + ("lower" if lower else "higher") + " than: ")
            + ", ".join(map(_lab, not_beaten))
        )
    return (SUPPORTED if sig.all() else NOT_SUPPORTED), "; ".join(parts), size


# ------------------------------------------------------------------------------------ claims
def _c1_c3(df, combos, expected, paper, protocol, ctx, cid):
    ref, lower = ("avoa", True) if cid == "C1" else ("ga", False)
    column = "p_one_sided_holm" if lower else "p_one_sided_greater_holm"
    rows, verdicts, sizes = [], {}, {}
    for s, c in combos:
        v, ev, z = _dominance(df, s, c, ref, column, ctx, lower)
        verdicts[(s, c)], sizes[(s, c)] = v, z
        pv = _paper_extreme(paper, (s, c), ref, lower)
        rows.append(_row(cid, s, c, protocol, pv, v, ev, z))
    pv = _combine_paper([_paper_extreme(paper, k, ref, lower) for k in sorted(expected)])
    rows.append(_all_row(cid, protocol, pv, verdicts, sizes, expected, lower))
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


_SWAP = {stats.LOWER: stats.HIGHER, stats.HIGHER: stats.LOWER}


def _printed_pairs(pw: pd.DataFrame, p_rank: pd.Series, ctx: _Ctx, m: float) -> tuple[_Size, str]:
    """C2's four-word verdict: every pair the paper ranks apart, read as printed-better against
    printed-worse ("lower" = the printed order holds beyond the margin)."""
    words, diffs = [], []
    for better, worse in combinations(ALGORITHMS, 2):
        if p_rank[better] == p_rank[worse]:
            continue  # a printed tie constrains nothing
        if p_rank[better] > p_rank[worse]:
            better, worse = worse, better
        if (better, worse) in pw.index:
            r = pw.loc[(better, worse)]
            word, d = r["size_verdict"], r["median_diff"]
        else:
            r = pw.loc[(worse, better)]
            word, d = _SWAP.get(r["size_verdict"], r["size_verdict"]), -r["median_diff"]
        words.append(word)
        diffs.append(d * ctx.scale)
    counts = {w: words.count(w) for w in dict.fromkeys(words)}
    text = (
        f"{len(words)} pairs ranked apart by the paper, ours (printed-better − printed-worse): "
        + ", ".join(f"{w} {n}" for w, n in counts.items())
    )
    ref = "printed-better − printed-worse, each pair ranked apart"
    size = _Size.decide(words, diffs, True, m * ctx.scale, ctx.unit, ref)
    return size, text


def _c2(df, combos, expected, paper, protocol, ctx):
    alpha = ctx.alpha
    rows, verdicts, taus, sizes = [], {}, [], {}
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
        m = ctx.margin(s, c)
        pw = stats.pairwise_wilcoxon(df, s, c, margin=m, alpha=alpha).set_index(["a", "b"])
        size, pairs_text = _printed_pairs(pw, p_rank, ctx, m)
        parts.append(pairs_text)
        sizes[(s, c)] = size
        if int(r["n_blocks"].iloc[0]) < stats.MIN_SEEDS:
            verdicts[(s, c)] = INCONCLUSIVE
            rows.append(_row("C2", s, c, protocol, pv, INCONCLUSIVE, "; ".join(parts), size))
            continue
        if not disc:
            v = SUPPORTED
            parts.append("no pair ordered against the paper")
        else:
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
        rows.append(_row("C2", s, c, protocol, pv, v, "; ".join(parts), size))
    note = ""
    if taus:
        finite = [t for t in taus if np.isfinite(t)]
        note = f"; mean Kendall tau-b {_g(float(np.mean(finite)) if finite else np.nan)}"
    pv = _combine_paper([r["paper_verdict"] for r in rows])
    rows.append(_all_row("C2", protocol, pv, verdicts, sizes, expected, True, note))
    return rows


def _c4(histories, combos, expected, protocol, ctx, at_nfe):
    """``at_nfe``: :func:`stats.at_budget` by evaluations, per fraction (read once in
    :func:`claims`); the paper protocol reads the histories by iteration here."""
    by = "iteration" if protocol == PROTOCOL_PAPER else "nfe"
    if by == "nfe":
        frames = {f: at_nfe[f] for f in CHECKPOINTS}
    else:
        frames = {f: stats.at_budget(histories, f, by=by) for f in CHECKPOINTS}
    rows, verdicts, sizes = [], {}, {}
    for s, c in combos:
        vs, zs, parts = [], [], []
        for f, fr in frames.items():
            v, ev, z = _dominance(fr, s, c, "avoa", "p_one_sided_holm", ctx, True)
            sub = fr[(fr["scenario"] == s) & (fr["case"] == c)]
            limit = sub[f"budget_{by}"].iloc[0] if len(sub) else np.nan
            med = sub.groupby("algorithm")["best_ise"].median()
            rank = int(med.rank(method="min").get("avoa", 0)) if med.notna().any() else 0
            vs.append(v)
            zs.append(z)
            parts.append(
                f"at {f:.0%} ({by} ≤ {_g(float(limit))}): {v} ({z.verdict}); AVOA's median "
                f"rank {rank}/{med.notna().sum()}; {ev}"
            )
        if NOT_SUPPORTED in vs:
            v = NOT_SUPPORTED
        elif all(x == SUPPORTED for x in vs):
            v = SUPPORTED
        else:
            v = INCONCLUSIVE
        z = _Size.decide([z.verdict for z in zs], [z.size for z in zs], True, zs[0].margin,
                         ctx.unit, "AVOA − each rival, at 10 % and 50 % of the budget")  # fmt: skip
        verdicts[(s, c)], sizes[(s, c)] = v, z
        rows.append(_row("C4", s, c, protocol, "claimed (figures only)", v, " | ".join(parts), z))
    pv = "claimed (figures only)"
    rows.append(_all_row("C4", protocol, pv, verdicts, sizes, expected, True))
    return rows


def _time_measure(protocol: str) -> tuple[str, str]:
    if protocol == PROTOCOL_PAPER:
        return "time_per_iter_s", "time per iteration"
    return "time_per_eval_s", "time per evaluation"


def _time_size(words, ratios, lowest: bool, reference: str) -> _Size:
    unit = (
        f"time ratio; practically equivalent inside {1 / stats.TIME_RATIO:.2f}-{stats.TIME_RATIO}"
    )
    return _Size.decide(words, ratios, lowest, stats.TIME_RATIO, unit, reference)


def _c5(runs, paper_time, protocol, ctx):
    alpha = ctx.alpha
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
        p_less = stats.holm([stats.mannwhitney(t["avoa"], t[a]) for a in rivals])
        p_more = stats.holm([stats.mannwhitney(t[a], t["avoa"]) for a in rivals])
        p_two = stats.holm([stats.mannwhitney(t["avoa"], t[a], "two-sided") for a in rivals])
        p_eq = stats.holm(
            [stats.tost_ratio_unpaired(t["avoa"], t[a], stats.TIME_RATIO) for a in rivals]
        )
        words = [stats.four_way(*x, alpha) for x in zip(p_two, p_less, p_more, p_eq, strict=True)]
        ratios = [
            float(np.median(t["avoa"]) / np.median(t[a]))
            if len(t[a]) and len(t["avoa"])
            else np.nan
            for a in rivals
        ]
        mean_avoa = float(np.mean(t["avoa"])) if len(t["avoa"]) else np.nan
        parts = [f"{what}: AVOA mean {_g(mean_avoa)} s"]
        for a, pl, pe, w in zip(rivals, p_less, p_eq, words, strict=True):
            ratio = float(np.mean(t[a])) / mean_avoa if len(t[a]) and mean_avoa > 0 else np.nan
            pr = ""
            if s is not None and a in paper and "avoa" in paper and col == "time_per_iter_s":
                pr = f", paper {paper[a] / paper['avoa']:.2f}x"
            if not len(t[a]):
                parts.append(f"{_lab(a)}: no runs")
                continue
            parts.append(
                f"{_lab(a)} {_g(ratio)}x AVOA (p_holm={_p(pl)}, p_equiv={_p(pe)}{pr}): AVOA {w}"
            )
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
        z = _time_size(words, ratios, True, f"AVOA / each rival, median {what}")
        rows.append(_row("C5", s, c, protocol, pvr, v, "; ".join(parts), z))
    return rows


def _c6(runs, protocol, ctx):
    alpha = ctx.alpha
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
        lt, lo = np.log(both["t"].to_numpy()), np.log(both["o"].to_numpy())
        results.append(
            {
                "s": s,
                "c": c,
                "p_two": w["p_two"],
                "p_less": w["p_less"],
                "p_greater": w["p_greater"],
                "p_eq": stats.tost_pair(lt, lo, np.log(stats.TIME_RATIO)),
                "median": float(o.median()),
                "ratio": float(np.exp(np.median(lt - lo))) if len(lt) else np.nan,
            }
        )
    res = pd.DataFrame(results)
    for k in ("p_two", "p_less", "p_greater", "p_eq"):
        res[k + "_holm"] = stats.holm(res[k])
    cols = ["p_two_holm", "p_less_holm", "p_greater_holm", "p_eq_holm"]
    words = [stats.four_way(*x, alpha) for x in res[cols].itertuples(index=False)]
    p_holm = res["p_greater_holm"].to_numpy()
    med = {(r.s, r.c): r.median for r in res.itertuples(index=False)}
    med[target] = float(tgt.median())
    order = sorted(med, key=med.get, reverse=True)
    parts = [
        f"{what}, blocked by algorithm × seed: S4/C4 median {_g(med[target])} s, "
        f"rank {order.index(target) + 1} of {len(order)} (1 = slowest)",
        f"slowest: {_where(*order[0])} ({_g(med[order[0]])} s)",
    ]
    weak = [
        f"{_where(r.s, r.c)} (p_holm={_p(p)})"
        for r, p in zip(res.itertuples(index=False), p_holm, strict=True)
        if not p < alpha
    ]
    if weak:
        parts.append("S4/C4 not significantly slower than: " + ", ".join(weak))
    equiv = [_where(r.s, r.c) for r, w in zip(res.itertuples(index=False), words, strict=True)
             if w == stats.EQUIVALENT]  # fmt: skip
    if equiv:
        parts.append("practically as slow (ratio inside 0.8-1.25): " + ", ".join(equiv))
    if np.isnan(p_holm).any():
        v = INCONCLUSIVE
    else:
        v = SUPPORTED if (p_holm < alpha).all() else NOT_SUPPORTED
    z = _time_size(words, list(res["ratio"]), False, f"S4/C4 / each other pair, {what}")
    return [_row("C6", 4, 4, protocol, CLAIMED, v, "; ".join(parts), z)]


def _c7(df, combos, expected, protocol, ctx):
    alpha = ctx.alpha
    rows, verdicts, sizes = [], {}, {}
    value = stats.value_column(df)
    for s, c in combos:
        sub = df[(df["scenario"] == s) & (df["case"] == c) & df["best_ise"].notna()]
        missing = _missing(df, s, c)
        x = {a: sub[sub["algorithm"] == a][value].to_numpy() for a in ALGORITHMS}
        spread = {a: float(stats.spread(v)) if len(v) else np.nan for a, v in x.items()}
        iqr = {
            a: float(np.subtract(*np.percentile(v, [75, 25]))) * ctx.scale if len(v) else np.nan
            for a, v in x.items()
        }
        rivals = [a for a in ALGORITHMS if a != "avoa"]
        enough = all(len(x[a]) >= stats.MIN_SEEDS for a in ALGORITHMS)
        p = stats.holm(
            [stats.brown_forsythe(x["avoa"], x[a]) if enough else np.nan for a in rivals]
        )
        rank = pd.Series(iqr).rank(method="min")
        m = ctx.margin(s, c)
        parts = [
            f"IQR of {_value_name(ctx)} over seeds: AVOA {_g(iqr['avoa'])} "
            f"(rank {_g(rank.get('avoa'))} of 7)"
        ]
        ok, words, diffs = [], [], []
        for i, (a, pa) in enumerate(zip(rivals, p, strict=True)):
            smaller = spread["avoa"] < spread[a]
            ok.append(bool(pa < alpha and smaller))
            pair = stats.seed_matrix(df, s, c, ["avoa", a]) if enough else pd.DataFrame()
            if len(pair) >= stats.MIN_SEEDS:
                est, lo, hi = stats.bootstrap_interval(
                    lambda u, w: stats.spread(u) - stats.spread(w),
                    [pair["avoa"], pair[a]],
                    seed=ctx.rng(s, c, i),
                )
                if stats.interval_equivalent(lo, hi, m):
                    word = stats.EQUIVALENT
                elif pa < alpha:
                    word = stats.LOWER if smaller else stats.HIGHER
                else:
                    word = stats.INCONCLUSIVE
            else:
                est, lo, hi, word = np.nan, np.nan, np.nan, stats.TOO_FEW
            words.append(word)
            diffs.append(est * ctx.scale)
            parts.append(
                f"{_lab(a)} IQR {_g(iqr[a])} (Brown-Forsythe p_holm={_p(pa)}; spread difference "
                f"{_g(est * ctx.scale)}, 90 % interval {_g(lo * ctx.scale)} to "
                f"{_g(hi * ctx.scale)}): AVOA {word}"
            )
        ref = "spread of AVOA − spread of each rival (mean |x − median|)"
        z = _Size.decide(words, diffs, True, m * ctx.scale, ctx.unit, ref)
        if missing or not enough:
            v = INCONCLUSIVE
            z.verdict = stats.INCONCLUSIVE
            parts.append(
                "too few runs" if not missing else "no runs of " + ", ".join(map(_lab, missing))
            )
        else:
            v = SUPPORTED if all(ok) else NOT_SUPPORTED
        verdicts[(s, c)], sizes[(s, c)] = v, z
        rows.append(_row("C7", s, c, protocol, CLAIMED, v, "; ".join(parts), z))
    rows.append(_all_row("C7", protocol, CLAIMED, verdicts, sizes, expected, True))
    return rows


def _c8(df, combos, expected, paper, protocol, ctx):
    rows, verdicts, sizes = [], {}, {}
    value = stats.value_column(df)
    for s, c in combos:
        sub = df[(df["scenario"] == s) & (df["case"] == c) & df["best_ise"].notna()]
        missing = _missing(df, s, c)
        best = sub.groupby("algorithm")[value].min().reindex(list(ALGORITHMS))
        m = ctx.margin(s, c)
        parts = [
            f"best run over seeds ({_value_name(ctx)}): "
            + ", ".join(f"{_lab(a)} {_g(best[a] * ctx.scale)}" for a in ALGORITHMS)
        ]
        diffs = (best["avoa"] - best.drop("avoa")) * ctx.scale
        words = [
            stats.EQUIVALENT
            if abs(d) < m * ctx.scale or d == 0
            else (stats.LOWER if d < 0 else stats.HIGHER)
            for d in diffs
        ]
        ref = "AVOA's best run − each rival's best run (descriptive, no test)"
        z = _Size.decide(words, diffs, True, m * ctx.scale, ctx.unit, ref)
        if missing:
            v = INCONCLUSIVE
            z.verdict = stats.INCONCLUSIVE
            parts.append("no runs of " + ", ".join(map(_lab, missing)))
        else:
            others = best.drop("avoa")
            v = SUPPORTED if (best["avoa"] < others).all() else NOT_SUPPORTED
            parts.append(f"AVOA's best run ranks {int(best.rank(method='min')['avoa'])} of 7")
        verdicts[(s, c)], sizes[(s, c)] = v, z
        pv = _paper_extreme(paper, (s, c), "avoa", True)
        rows.append(_row("C8", s, c, protocol, pv, v, "; ".join(parts), z))
    pv = _combine_paper([_paper_extreme(paper, k, "avoa", True) for k in sorted(expected)])
    rows.append(_all_row("C8", protocol, pv, verdicts, sizes, expected, True))
    return rows


def _c9(runs, combos, expected, protocol, ctx):
    """Parameter accuracy (E7): AVOA's share of seeds with every parameter within 1 %."""
    alpha = ctx.alpha
    tol = stats.ACCURACY_TOLERANCES[0]
    rows, verdicts, sizes = [], {}, {}
    d = runs[runs["best_ise"].notna()].copy()
    for t in stats.ACCURACY_TOLERANCES:
        d[f"_within_{t}"] = stats.within_truth(d, t).astype(float)
    unit = f"percentage points of seeds within {tol:.0%} of the truth"
    for s, c in combos:
        sub = d[(d["scenario"] == s) & (d["case"] == c)]
        missing = _missing(runs, s, c)
        share = {
            t: sub.groupby("algorithm")[f"_within_{t}"].mean().reindex(list(ALGORITHMS))
            for t in stats.ACCURACY_TOLERANCES
        }
        parts = [
            f"share of seeds with every parameter within {t:.0%}: "
            + ", ".join(f"{_lab(a)} {_g(100 * share[t][a])} %" for a in ALGORITHMS)
            for t in stats.ACCURACY_TOLERANCES
        ]
        if missing:
            verdicts[(s, c)] = INCONCLUSIVE
            parts.append("no runs of " + ", ".join(map(_lab, missing)))
            rows.append(_row("C9", s, c, protocol, CLAIMED, INCONCLUSIVE, "; ".join(parts)))
            continue
        wide = sub.pivot(index="seed", columns="algorithm", values=f"_within_{tol}").dropna()
        rivals = [a for a in ALGORITHMS if a != "avoa"]
        tests = [stats.mcnemar_exact(wide["avoa"] > 0, wide[a] > 0) for a in rivals]
        p_two = stats.holm([x["p_two"] for x in tests])
        p_more = stats.holm([x["p_greater"] for x in tests])
        words, diffs = [], []
        for i, (a, pt) in enumerate(zip(rivals, p_two, strict=True)):
            est, lo, hi = stats.bootstrap_interval(
                lambda u, w: u.mean(axis=-1) - w.mean(axis=-1),
                [wide["avoa"], wide[a]],
                seed=ctx.rng(s, c, 100 + i),
            )
            if len(wide) < stats.MIN_SEEDS:
                word = stats.TOO_FEW
            elif stats.interval_equivalent(lo, hi, stats.SHARE_MARGIN):
                word = stats.EQUIVALENT
            elif pt < alpha:
                word = stats.HIGHER if est > 0 else stats.LOWER
            else:
                word = stats.INCONCLUSIVE
            words.append(word)
            diffs.append(100 * est)
            parts.append(
                f"vs {_lab(a)}: AVOA − rival {_g(100 * est)} points (90 % interval "
                f"{_g(100 * lo)} to {_g(100 * hi)}), McNemar p_holm={_p(pt)}: AVOA {word}"
            )
        ref = "AVOA's share − each rival's share (paired by seed)"
        z = _Size.decide(words, diffs, False, 100 * stats.SHARE_MARGIN, unit, ref)
        if len(wide) < stats.MIN_SEEDS:
            v = INCONCLUSIVE
        else:
            v = SUPPORTED if (p_more < alpha).all() else NOT_SUPPORTED
        verdicts[(s, c)], sizes[(s, c)] = v, z
        rows.append(_row("C9", s, c, protocol, CLAIMED, v, "; ".join(parts), z))
    rows.append(_all_row("C9", protocol, CLAIMED, verdicts, sizes, expected, False))
    return rows


# ------------------------------------------------------------------------------------ budgets
def _fraction(f: float) -> str:
    return f"{100 * f:g} %"


def _budget_sentence(readings: list[tuple[float, str]]) -> str:
    """ "1-2 %: higher; 5-100 %: practically equivalent" from (fraction, text) in order."""
    groups: list[list] = []
    for f, text in readings:
        if groups and groups[-1][2] == text:
            groups[-1][1] = f
        else:
            groups.append([f, f, text])
    spans = [
        (_fraction(a) if a == b else f"{100 * a:g}-{_fraction(b)}") + f": {t}" for a, b, t in groups
    ]
    return "at equal evaluations, by share of each pair's N: " + "; ".join(spans)


def _budget_rows(at_nfe, combos, expected, paper, ctx) -> dict:
    """(claim, where) → its budget sentence, for the claims that read the ISE (E8); ``at_nfe``
    as in :func:`_c4`."""
    readings: dict = {}
    for f in stats.BUDGET_FRACTIONS:
        fr = at_nfe[f]
        rows = [
            *_c1_c3(fr, combos, expected, paper, PROTOCOL_EQUAL, ctx, "C1"),
            *_c1_c3(fr, combos, expected, paper, PROTOCOL_EQUAL, ctx, "C3"),
            *_c2(fr, combos, expected, paper, PROTOCOL_EQUAL, ctx),
            *_c7(fr, combos, expected, PROTOCOL_EQUAL, ctx),
            *_c8(fr, combos, expected, paper, PROTOCOL_EQUAL, ctx),
        ]
        for r in rows:
            text = r["verdict"] + (f" ({r['_counts']})" if r["where"] == "all" else "")
            readings.setdefault((r["claim_id"], r["where"]), []).append((f, text))
    out = {k: _budget_sentence(v) for k, v in readings.items()}
    for (cid, where), text in list(out.items()):
        if cid == "C1":
            out[("C4", where)] = "C4 reads C1 at 10 % and 50 % of N; C1 " + text
    return out


def claims(
    runs: pd.DataFrame,
    histories: pd.DataFrame,
    paper_objective: pd.DataFrame | None,
    paper_time: pd.DataFrame | None,
    alpha: float = 0.05,
    seed: int = 0,
) -> pd.DataFrame:
    """Decide the paper's claims (C1-C9 of the module docstring) under both protocols.

    ``runs`` and ``histories`` are the aggregates of docs/records.md (``excess_ise`` is added
    where missing); ``paper_objective`` and ``paper_time`` are config/paper/objective.csv and
    time_per_iteration.csv as DataFrames; ``seed`` seeds the bootstrap intervals (C7, C9).
    Returns one row per claim × place × protocol with columns ``claim_id, claim, where``
    ("S<s>/C<c>" or "all"), ``scenario, case`` (nullable ints; empty for "all"), ``protocol,
    paper_verdict, our_verdict`` ("supported" / "not supported" / "inconclusive": the tests
    alone), ``verdict`` (the four words of reproduction-notes E4), ``size`` (the decisive
    comparison's effect), ``margin`` and ``unit`` (what size and margin are in), ``reference``
    (what was subtracted from what), ``budgets`` (one sentence: the verdict at each budget, E8)
    and ``evidence`` (the numbers behind the verdicts: medians, p-values, ranks, ratios).
    """
    runs, histories = stats.with_excess(runs, histories)
    paper = _paper_lookup(paper_objective)
    combos = stats.scenario_cases(runs)
    expected = set(paper) | set(combos)
    value = stats.value_column(runs)
    scale, unit = (100.0, "% of the truth's ISE") if value == "excess_ise" else (1.0, "V²")
    margins = {(s, c): stats.margin_of(runs, s, c) for s, c in combos}
    ctx = _Ctx(alpha, margins, scale, unit, value, seed)
    # every reading by evaluations, once: the equal-evaluation protocol (1.0), C4's checkpoints
    # and the budget sentences share them
    at_nfe = {
        f: stats.at_budget(histories, f, by="nfe")
        for f in sorted({1.0, *CHECKPOINTS, *stats.BUDGET_FRACTIONS})
    }
    protocols = {PROTOCOL_PAPER: runs, PROTOCOL_EQUAL: at_nfe[1.0]}
    rows: list[dict] = []
    for cid in ("C1", "C2", "C3", "C4", "C5", "C6", "C7", "C8", "C9"):
        for protocol, df in protocols.items():
            if cid in ("C1", "C3"):
                rows += _c1_c3(df, combos, expected, paper, protocol, ctx, cid)
            elif cid == "C2":
                rows += _c2(df, combos, expected, paper, protocol, ctx)
            elif cid == "C4":
                rows += _c4(histories, combos, expected, protocol, ctx, at_nfe)
            elif cid == "C5":
                rows += _c5(runs, paper_time, protocol, ctx)
            elif cid == "C6":
                rows += _c6(runs, protocol, ctx)
            elif cid == "C7":
                rows += _c7(df, combos, expected, protocol, ctx)
            elif cid == "C8":
                rows += _c8(df, combos, expected, paper, protocol, ctx)
            elif protocol == PROTOCOL_PAPER:  # C9: final parameters only
                rows += _c9(runs, combos, expected, protocol, ctx)
    budgets = _budget_rows(at_nfe, combos, expected, paper, ctx)
    for r in rows:
        if r["claim_id"] in ("C5", "C6"):
            r["budgets"] = "a time per iteration or per evaluation: the same at every budget"
        elif r["claim_id"] == "C9":
            r["budgets"] = "final parameters only: the histories record no parameters"
        else:
            r["budgets"] = budgets.get((r["claim_id"], r["where"]), "")
    out = pd.DataFrame(rows, columns=COLUMNS)
    out["scenario"] = out["scenario"].astype("Int64")
    out["case"] = out["case"].astype("Int64")
    return out
