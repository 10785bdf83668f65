"""Statistics of the report (equal-budget readings, ranks, Friedman, Holm-Wilcoxon) and the
claims check, on small synthetic aggregates whose answers are known by construction."""

import numpy as np
import pandas as pd
import pytest
from scipy import stats as st

from avoa_pipeline.optimizers import ALGORITHMS
from avoa_pipeline.report import claims as cl
from avoa_pipeline.report import stats


def runs_frame(values: dict, scenario=1, case=1) -> pd.DataFrame:
    """``values``: algorithm → per-seed ISE (seed i+1 is the i-th value; NaN = no run)."""
    rows = [
        {"scenario": scenario, "case": case, "algorithm": a, "seed": i + 1, "best_ise": float(v)}
        for a, vals in values.items()
        for i, v in enumerate(vals)
        if not np.isnan(v)
    ]
    return pd.DataFrame(rows)


def seven(base: np.ndarray, **override) -> dict:
    """All seven algorithms at ``base`` (per seed) unless overridden."""
    return {a: override.get(a, base) for a in ALGORITHMS}


RNG = np.random.default_rng(12345)
BASE10 = 1.0 + RNG.random(10)


# ------------------------------------------------------------------------------------- Holm
def test_holm_hand_example():
    p = [0.01, 0.04, 0.03, np.nan, 0.005]
    # sorted 0.005·4 = 0.02, 0.01·3 = 0.03, 0.03·2 = 0.06, 0.04·1 = 0.04 → monotone 0.06
    np.testing.assert_allclose(stats.holm(p), [0.03, 0.06, 0.06, np.nan, 0.02])
    assert np.isnan(stats.holm([np.nan])).all()
    assert stats.holm([0.9, 0.8]).max() == 1.0  # capped


# ---------------------------------------------------------------------------- Holm-Wilcoxon
def test_clearly_best_reference_is_better_than_all_six():
    df = runs_frame(seven(BASE10 + 1.0, avoa=BASE10 * 0.5))
    hw = stats.holm_wilcoxon(df, 1, 1, ref="avoa")
    assert list(hw["other"]) == [a for a in ALGORITHMS if a != "avoa"]
    assert (hw["verdict"] == "ref better").all()
    assert (hw["n"] == 10).all()
    # every difference negative: exact one-sided p = 2^-10, two-sided 2^-9, Holm × 6 at most
    np.testing.assert_allclose(hw["p_raw"], 2.0**-9)
    assert (hw["p_one_sided_holm"] <= 6 * 2.0**-10 + 1e-15).all()
    assert (hw["p_one_sided_greater_holm"] == 1.0).all()
    assert (hw["median_diff"] < 0).all()


def test_reference_worse_is_reported_as_worse():
    df = runs_frame(seven(BASE10, avoa=BASE10 + 5.0))
    hw = stats.holm_wilcoxon(df, 1, 1, ref="avoa")
    assert (hw["verdict"] == "ref worse").all()
    assert (hw["p_one_sided_holm"] == 1.0).all()


def test_identical_algorithms_show_no_difference_without_warnings():
    df = runs_frame(seven(BASE10))
    hw = stats.holm_wilcoxon(df, 1, 1, ref="avoa")
    assert (hw["verdict"] == "no difference").all()
    assert (hw["p_raw"] == 1.0).all()
    assert (hw["n_nonzero"] == 0).all()


def test_exchangeable_algorithms_show_no_difference():
    rng = np.random.default_rng(7)
    df = runs_frame({a: 1.0 + rng.random(12) for a in ALGORITHMS})
    hw = stats.holm_wilcoxon(df, 1, 1, ref="avoa")
    assert (hw["verdict"] == "no difference").all(), hw


def test_too_few_seeds_gives_nan_and_a_verdict():
    df = runs_frame(seven(BASE10[:5] + 1, avoa=BASE10[:5]))
    hw = stats.holm_wilcoxon(df, 1, 1)
    assert (hw["verdict"] == "too few seeds").all()
    assert hw[["p_raw", "p_holm", "p_one_sided_holm"]].isna().all().all()


def test_ties_and_zero_differences_are_tested_without_warnings():
    # 16 seeds: 3 zero differences, tied absolute differences among the rest
    ref = np.array([1, 1, 1] + [2] * 13, float)
    other = np.array([1, 1, 1] + [3] * 12 + [4], float)
    df = runs_frame(seven(other, avoa=ref))
    hw = stats.holm_wilcoxon(df, 1, 1)
    direct = st.wilcoxon(ref, other, zero_method="wilcox").pvalue
    np.testing.assert_allclose(hw["p_raw"], direct)
    assert (hw["n_nonzero"] == 13).all()
    assert (hw["verdict"] == "ref better").all()


def test_pairs_are_matched_by_seed_not_by_row_order():
    # seed effects dwarf the algorithm effect: only a paired test sees avoa is always lower
    base = 10.0 ** np.arange(10)
    df = runs_frame(seven(base * 1.01, avoa=base))
    df = df.sample(frac=1.0, random_state=3).reset_index(drop=True)
    hw = stats.holm_wilcoxon(df, 1, 1)
    assert (hw["verdict"] == "ref better").all()
    # a missing seed of one rival drops only that pair's seed
    df2 = df[~((df["algorithm"] == "gto") & (df["seed"] == 4))]
    hw2 = stats.holm_wilcoxon(df2, 1, 1).set_index("other")
    assert hw2.loc["gto", "n"] == 9
    assert hw2.loc["ga", "n"] == 10


def test_unknown_reference_is_an_error():
    df = runs_frame({"ga": BASE10, "gto": BASE10})
    with pytest.raises(ValueError, match="avoa"):
        stats.holm_wilcoxon(df, 1, 1, ref="avoa")


def test_duplicate_runs_are_an_error():
    df = runs_frame(seven(BASE10))
    df = pd.concat([df, df.iloc[[0]]], ignore_index=True)
    with pytest.raises(ValueError, match="more than once"):
        stats.friedman(df, 1, 1)


# ------------------------------------------------------------------------- ranks, Friedman
HAND = {
    # seeds 1-3 complete; seed 4 has no GA run
    "avoa": [1.0, 2.0, 1.0, 0.5],
    "gto": [2.0, 1.0, 100.0, 0.5],
    "ga": [3.0, 3.0, 4.0, np.nan],
}


def test_ranks_on_a_hand_computed_example():
    r = stats.ranks(runs_frame(HAND)).set_index("algorithm")
    assert list(r.index) == ["ga", "avoa", "gto"]  # the paper's column order
    assert r.loc["avoa", "n_seeds"] == 4
    assert r.loc["ga", "n_seeds"] == 3
    np.testing.assert_allclose(r.loc[["avoa", "gto", "ga"], "mean_ise"], [1.125, 25.875, 10 / 3])
    np.testing.assert_allclose(r.loc[["avoa", "gto", "ga"], "median_ise"], [1.0, 1.5, 3.0])
    assert list(r.loc[["avoa", "gto", "ga"], "rank_by_mean"]) == [1, 3, 2]
    assert list(r.loc[["avoa", "gto", "ga"], "rank_by_median"]) == [1, 2, 3]
    # per-seed ranks over the complete seeds 1-3: avoa 1,2,1; gto 2,1,3; ga 3,3,2
    np.testing.assert_allclose(r.loc[["avoa", "gto", "ga"], "mean_rank"], [4 / 3, 2.0, 8 / 3])
    assert (r["n_blocks"] == 3).all()
    assert list(r.loc[["avoa", "gto", "ga"], "rank_by_mean_rank"]) == [1, 2, 3]


def test_ranks_average_ties_within_a_seed():
    r = stats.ranks(runs_frame({"avoa": [1.0, 5.0], "gto": [1.0, 6.0], "ga": [2.0, 7.0]}))
    r = r.set_index("algorithm")
    np.testing.assert_allclose(r.loc[["avoa", "gto", "ga"], "mean_rank"], [1.25, 1.75, 3.0])


def test_friedman_matches_a_direct_scipy_call_on_complete_seeds():
    res = stats.friedman(runs_frame(HAND), 1, 1)
    direct = st.friedmanchisquare([3.0, 3.0, 4.0], [1.0, 2.0, 1.0], [2.0, 1.0, 100.0])
    assert res["n_blocks"] == 3
    assert res["k"] == 3
    assert res["statistic"] == pytest.approx(direct.statistic)
    assert res["p"] == pytest.approx(direct.pvalue)


def test_friedman_degenerate_inputs():
    tied = stats.friedman(runs_frame(seven(BASE10)), 1, 1)
    assert tied["statistic"] == 0.0
    assert tied["p"] == 1.0
    two = stats.friedman(runs_frame({"avoa": BASE10, "gto": BASE10 + 1}), 1, 1)
    assert np.isnan(two["p"])
    assert two["k"] == 2


# ------------------------------------------------------------------- equal-budget readings
def histories_frame() -> pd.DataFrame:
    rows = []
    for algo, nfes, best in (
        ("avoa", [20, 40, 60, 80], [5.0, 4.0, 3.0, 2.0]),
        ("gto", [20, 60, 100], [9.0, 7.0, 1.0]),
    ):
        for it, (n, b) in enumerate(zip(nfes, best, strict=True)):
            rows.append(
                {
                    "scenario": 2,
                    "case": 3,
                    "algorithm": algo,
                    "seed": 1,
                    "iteration": it,
                    "best_ise": b,
                    "nfe": n,
                    "wall_s": 0.1 * it,
                }
            )
    return pd.DataFrame(rows).sample(frac=1.0, random_state=0)  # row order must not matter


@pytest.mark.parametrize(
    ("nfe", "expected"),
    [
        (60, {"avoa": 3.0, "gto": 7.0}),
        (59, {"avoa": 4.0, "gto": 9.0}),
        (100, {"avoa": 2.0, "gto": 1.0}),
    ],
)
def test_best_at_nfe_reads_the_last_entry_within_the_budget(nfe, expected):
    b = stats.best_at_nfe(histories_frame(), nfe).set_index("algorithm")
    assert b["best_ise"].to_dict() == expected
    assert (b["nfe"] <= nfe).all()
    assert (b["budget_nfe"] == nfe).all()


def test_best_at_nfe_below_the_initial_population_is_nan():
    b = stats.best_at_nfe(histories_frame(), 10)
    assert len(b) == 2
    assert b["best_ise"].isna().all()


def test_best_at_nfe_per_scenario_case_mapping():
    b = stats.best_at_nfe(histories_frame(), {(2, 3): 40}).set_index("algorithm")
    assert b["best_ise"].to_dict() == {"avoa": 4.0, "gto": 9.0}
    missing = stats.best_at_nfe(histories_frame(), {(1, 1): 40})
    assert missing["best_ise"].isna().all()


def test_common_nfe_and_at_budget():
    h = histories_frame()
    assert stats.common_nfe(h, 2, 3) == 80
    assert stats.common_iterations(h, 2, 3) == 2
    eq = stats.at_budget(h, 1.0, by="nfe").set_index("algorithm")
    assert eq["best_ise"].to_dict() == {"avoa": 2.0, "gto": 7.0}
    half = stats.at_budget(h, 0.5, by="nfe").set_index("algorithm")  # N = 40
    assert half["best_ise"].to_dict() == {"avoa": 4.0, "gto": 9.0}
    with pytest.raises(ValueError, match="no history"):
        stats.common_nfe(h, 1, 1)


def test_brown_forsythe_and_mann_whitney_edge_cases():
    x = np.arange(10.0)
    assert stats.brown_forsythe(x, x + 3) == pytest.approx(1.0)
    assert stats.brown_forsythe(np.ones(8), np.ones(8)) == 1.0
    assert stats.brown_forsythe(x, 100 * x) < 0.01
    assert stats.mannwhitney(x, x + 100) < 0.001
    assert stats.mannwhitney(np.ones(8), np.ones(8)) == 1.0
    assert np.isnan(stats.mannwhitney(x[:3], x))


# ------------------------------------------------------------------------------------ claims
EPI = {a: (40 if a == "gto" else 20) for a in ALGORITHMS}
FINAL = {  # final ISE after the iteration budget; GTO spends twice the evaluations
    "gto": 0.5,
    "avoa": 1.0,
    "gwo": 3.0,
    "run": 3.2,
    "nelder_mead": 3.4,
    "quasi_newton": 3.6,
    "ga": 5.0,
}
ITERS, POP, SEEDS = 10, 20, 12  # 12 seeds: 2^-11 · 21 pairs (Holm) < 0.05


def claims_inputs():
    """Two cases (S1/C1, S4/C4). By iterations GTO is best; at equal evaluations (N = 220,
    where GTO is only half-way) AVOA is best. GA is worst in both. AVOA is fastest per
    iteration but GTO per evaluation. S4/C4 costs 30 % more time than S1/C1."""
    rng = np.random.default_rng(99)
    hist, runs = [], []
    for s, c in ((1, 1), (4, 4)):
        for a in ALGORITHMS:
            for seed in range(1, SEEDS + 1):
                it = np.arange(ITERS + 1)
                noise = 1 + 0.01 * rng.random()
                best = FINAL[a] * (1 + 6 * (ITERS - it) / ITERS) * noise
                nfe = POP + EPI[a] * it
                per_iter = (1.0 if a == "avoa" else 1.5) * (1.3 if s == 4 else 1.0)
                wall = per_iter * it * (1 + 0.01 * rng.random())
                key = {"scenario": s, "case": c, "algorithm": a, "seed": seed}
                hist.append(pd.DataFrame({**key, "iteration": it, "best_ise": best, "nfe": nfe}))
                runs.append(
                    {
                        **key,
                        "best_ise": best[-1],
                        "nfe": int(nfe[-1]),
                        "iterations": ITERS,
                        "wall_s": wall[-1],
                        "time_per_iter_s": wall[-1] / ITERS,
                        "evals_per_iter": float(EPI[a]),
                        "time_per_eval_s": wall[-1] / nfe[-1],
                    }
                )
    order = ["avoa", "gto", "gwo", "run", "nelder_mead", "quasi_newton", "ga"]
    paper = pd.DataFrame(
        [
            {"scenario": s, "case": c, "algorithm": a, "ise": 0.1 * (i + 1), "rank": i + 1}
            for s, c in ((1, 1), (4, 4))
            for i, a in enumerate(order)
        ]
    )
    paper["rank_printed"] = paper["rank"].astype(str)
    paper_time = pd.DataFrame({"algorithm": list(ALGORITHMS), "seconds": [4, 4, 16, 6, 5, 1, 4]})
    return pd.DataFrame(runs), pd.concat(hist, ignore_index=True), paper, paper_time


@pytest.fixture(scope="module")
def claim_table():
    runs, hist, paper, paper_time = claims_inputs()
    return cl.claims(runs, hist, paper, paper_time)


def verdict(table, cid, where, protocol):
    row = table[(table.claim_id == cid) & (table["where"] == where) & (table.protocol == protocol)]
    assert len(row) == 1, (cid, where, protocol)
    return row.iloc[0]


P, E = cl.PROTOCOL_PAPER, cl.PROTOCOL_EQUAL


def test_claims_table_shape(claim_table):
    assert list(claim_table.columns[:3]) == ["claim_id", "claim", "where"]
    for col in ("protocol", "paper_verdict", "our_verdict", "evidence"):
        assert col in claim_table.columns
    assert set(claim_table["our_verdict"]) <= {"supported", "not supported", "inconclusive"}
    assert set(claim_table["protocol"]) == {P, E}
    assert set(claim_table["claim_id"]) == {f"C{i}" for i in range(1, 10)}
    assert not claim_table.duplicated(["claim_id", "where", "protocol"]).any()


def test_avoa_lowest_depends_on_the_protocol(claim_table):
    r = verdict(claim_table, "C1", "S4/C4", P)
    assert r.our_verdict == "not supported"
    assert r.paper_verdict == "supported"
    assert "rivals significantly lower than AVOA: GTO" in r.evidence
    assert verdict(claim_table, "C1", "all", P).our_verdict == "not supported"
    assert verdict(claim_table, "C1", "S4/C4", E).our_verdict == "supported"
    assert verdict(claim_table, "C1", "all", E).our_verdict == "supported"


def test_printed_ranks(claim_table):
    r = verdict(claim_table, "C2", "S1/C1", P)
    assert r.our_verdict == "not supported"  # GTO significantly ahead of AVOA
    assert "AVOA/GTO reversed" in r.evidence
    assert "significant" in r.evidence
    r = verdict(claim_table, "C2", "S1/C1", E)
    assert r.our_verdict == "supported"
    assert "Kendall tau-b = 1" in r.evidence


def test_ga_worst(claim_table):
    for protocol in (P, E):
        assert verdict(claim_table, "C3", "all", protocol).our_verdict == "supported"


def test_convergence_claim(claim_table):
    # GTO's curve is below AVOA's at every iteration
    assert verdict(claim_table, "C4", "S1/C1", P).our_verdict == "not supported"


def test_speed_per_iteration_versus_per_evaluation(claim_table):
    r = verdict(claim_table, "C5", "S4/C4", P)
    assert r.our_verdict == "supported"
    assert r.paper_verdict == "supported"
    # GTO does 40 evaluations per iteration in 1.5× AVOA's time: faster per evaluation
    r = verdict(claim_table, "C5", "S4/C4", E)
    assert r.our_verdict == "not supported"
    assert "significantly faster than AVOA: GTO" in r.evidence


def test_s4c4_most_time_consuming(claim_table):
    assert verdict(claim_table, "C6", "S4/C4", P).our_verdict == "supported"


def test_reliability_and_best_run(claim_table):
    # every algorithm has the same relative spread, so AVOA's is not significantly smallest
    assert verdict(claim_table, "C7", "S4/C4", P).our_verdict == "not supported"
    assert verdict(claim_table, "C8", "S4/C4", P).our_verdict == "not supported"
    assert verdict(claim_table, "C8", "S4/C4", E).our_verdict == "supported"


def test_missing_algorithms_make_claims_inconclusive():
    runs, hist, paper, paper_time = claims_inputs()
    keep = runs["algorithm"] != "gwo"
    t = cl.claims(runs[keep], hist[hist["algorithm"] != "gwo"], paper, paper_time)
    r = verdict(t, "C1", "S4/C4", E)
    assert r.our_verdict == "inconclusive"
    assert "no runs of GWO" in r.evidence
    assert verdict(t, "C2", "all", E).our_verdict == "inconclusive"


def test_signed_rank_equals_scipy():
    """stats.signed_rank is scipy's wilcoxon (zero_method="wilcox", default method) for every
    branch: exact, permutation (n ≤ 13 with ties/zeros), normal approximation with ties."""
    from scipy import stats as st

    rng = np.random.default_rng(5)
    cases = []
    for n in (6, 9, 13, 14, 20, 30, 50, 60):
        cases.append(rng.normal(0.2, 1, n))  # untied, no zeros
        cases.append(np.round(rng.normal(0.3, 1, n), 1))  # ties
        z = rng.normal(-0.2, 1, n)
        z[: n // 4] = 0.0  # zeros
        cases.append(z)
    for d in cases:
        ours = stats.signed_rank(d)
        ref = [
            st.wilcoxon(d, alternative=alt, zero_method="wilcox").pvalue
            for alt in ("two-sided", "less", "greater")
        ]
        np.testing.assert_allclose(ours, ref, rtol=1e-9, atol=1e-12)


# --------------------------------------------------------- effect sizes and equivalence (E1-E8)
N_SAMPLES, TRUE_ISE = 5701, 0.006  # margin m = N·(0.1 mV)² / ISE_true = 0.950 % of ISE_true
FINAL_EXCESS = {"avoa": 0.008, "ga": 0.20}  # everyone else ends at the truth's ISE


def sized_inputs(n_seeds=12):
    """One pair, S1/C2. At the end AVOA is 0.8 % of the truth's ISE above the rest (significant,
    but inside the 0.95 % margin), GA 20 % above. Early on AVOA is ahead: its excess falls
    from 10 % while every other algorithm's falls from 50 %. AVOA and Nelder-Mead find every
    parameter within 1 % on every seed, the rest on none."""
    rng = np.random.default_rng(3)
    runs, hist = [], []
    for a in ALGORITHMS:
        for seed in range(1, n_seeds + 1):
            it = np.arange(11)
            final = FINAL_EXCESS.get(a, 0.0) + 1e-4 * rng.random()
            start = 0.10 if a == "avoa" else 0.50
            excess = final + (start - final) * np.exp(-it)
            ise = TRUE_ISE * (1 + excess)
            key = {"scenario": 1, "case": 2, "algorithm": a, "seed": seed}
            hist.append(
                pd.DataFrame({**key, "iteration": it, "best_ise": ise, "nfe": 20 + 20 * it})
            )
            rel = 0.001 if a in ("avoa", "nelder_mead") else 0.03
            runs.append(
                {
                    **key,
                    "best_ise": ise[-1],
                    "true_ise": TRUE_ISE,
                    "n_samples": N_SAMPLES,
                    "nfe": 220,
                    "iterations": 10,
                    "wall_s": 1.0,
                    "time_per_iter_s": 0.1 * (1 + 0.01 * rng.random()),
                    "evals_per_iter": 20.0,
                    "time_per_eval_s": 0.005 * (1 + 0.01 * rng.random()),
                    "relerr_r0": rel,
                    "relerr_tau": -rel,
                }
            )
    return pd.DataFrame(runs), pd.concat(hist, ignore_index=True)


@pytest.fixture(scope="module")
def sized_table():
    runs, hist = sized_inputs()
    return cl.claims(runs, hist, None, None, seed=7)


def test_margin_is_a_model_error_of_a_tenth_of_a_millivolt():
    runs, _ = sized_inputs()
    runs = stats.with_excess(runs)
    assert stats.margin_of(runs, 1, 2) == pytest.approx(N_SAMPLES * 1e-8 / TRUE_ISE)
    assert runs["excess_ise"].between(-1e-9, 0.21).all()


def test_a_significant_difference_inside_the_margin_is_practically_equivalent(sized_table):
    r = verdict(sized_table, "C1", "S1/C2", P)
    assert r.our_verdict == "not supported"  # AVOA significantly higher than five rivals
    assert r.verdict == "practically equivalent"  # ... by 0.8 %, inside the 0.95 % margin
    assert r["size"] == pytest.approx(0.8, abs=0.02)
    assert r.margin == pytest.approx(100 * N_SAMPLES * 1e-8 / TRUE_ISE)
    assert r.unit == "% of the truth's ISE"
    assert "vs GA" in r.evidence
    assert "lower" in r.evidence.split("vs GA")[1].split(";")[0]


def test_a_difference_beyond_the_margin_is_higher_or_lower(sized_table):
    r = verdict(sized_table, "C3", "S1/C2", P)
    assert r.our_verdict == "supported"
    assert r.verdict == "higher"  # GA 19 % above the closest rival
    assert r["size"] == pytest.approx(19.2, abs=0.1)


def test_best_run_and_reliability_take_sizes(sized_table):
    assert verdict(sized_table, "C8", "S1/C2", P).verdict == "practically equivalent"
    assert verdict(sized_table, "C7", "S1/C2", P).verdict == "practically equivalent"


def test_parameter_accuracy_claim(sized_table):
    r = verdict(sized_table, "C9", "S1/C2", P)
    assert r.verdict == "practically equivalent"  # ties Nelder-Mead, beats the other five
    assert r["size"] == pytest.approx(0.0)
    assert r.margin == pytest.approx(10.0)
    assert r.our_verdict == "not supported"  # not better than Nelder-Mead
    assert not ((sized_table.claim_id == "C9") & (sized_table.protocol == E)).any()


def test_budget_sentence_shows_where_the_verdict_changes(sized_table):
    r = verdict(sized_table, "C1", "S1/C2", P)
    # at 10-20 % of N (22-44 evaluations) AVOA is far ahead; at the end within the margin
    assert r.budgets.startswith("at equal evaluations, by share of each pair's N: ")
    assert "10-20 %: lower" in r.budgets  # 1-5 %: below the initial population, no reading
    assert r.budgets.endswith("100 %: practically equivalent")
    assert "C4 reads C1" in verdict(sized_table, "C4", "S1/C2", P).budgets
    assert "same at every budget" in verdict(sized_table, "C5", "S4/C4", P).budgets


def test_every_verdict_states_size_and_margin(sized_table):
    decided = sized_table[sized_table["verdict"] != "inconclusive"]
    assert len(decided) > 10
    assert decided["size"].notna().all()
    assert decided["margin"].notna().all()
    assert (decided["unit"] != "").all()
    assert set(sized_table["verdict"]) <= {
        "lower",
        "higher",
        "practically equivalent",
        "inconclusive",
    }


def test_median_position_is_the_lower_middle_finished_run():
    from avoa_pipeline.report.stats import median_position

    v = [3.0, 1.0, np.nan, 2.0, 4.0]
    assert median_position(v) == 3  # finished runs 1, 2, 3, 4: the lower middle is 2.0
    assert median_position(v[:2] + v[3:4]) == 2  # an odd count: the middle one
    # ties broken by the seed, then by position
    assert median_position([1.0, 1.0, 1.0, 5.0], ties=[9, 2, 7, 1]) == 2
    assert median_position([1.0, 1.0]) == 0
    assert median_position([np.nan, np.inf]) is None
