"""Fixed-budget curves: hitting evaluations, ECDFs and rank curves on hand-made histories."""

import numpy as np
import pandas as pd
import pytest
import report_helpers

from avoa_pipeline.optimizers import ALGORITHMS
from avoa_pipeline.report import budget
from avoa_pipeline.report import figures as F
from avoa_pipeline.report.stats import BUDGET_FRACTIONS, EXCESS_TARGETS


def history(algorithm, seed, nfe, excess, scenario=1, case=1, true_ise=2.0):
    """A run whose best-so-far excess over the truth (ISE_true = ``true_ise``) is ``excess``."""
    excess = np.asarray(excess, dtype=float)
    return report_helpers.history(
        algorithm, seed, nfe, true_ise * (1.0 + excess), scenario, case, excess=excess
    )


@pytest.fixture
def three_runs():
    """One algorithm, three seeds: reaches every target in turn / never / from the start."""
    return pd.concat(
        [
            history("avoa", 1, [10, 20, 30, 40], [0.5, 0.05, 0.005, -0.02]),
            history("avoa", 2, [10, 20, 30], [0.3, 0.2, 0.15]),
            history("avoa", 3, [15, 25], [-0.1, -0.2]),  # beats the truth at once
        ],
        ignore_index=True,
    )


@pytest.fixture
def crossing():
    """Nelder-Mead is ahead early on every seed, GA ahead late; seed 6 ties at 20 evaluations."""
    frames = []
    for seed in range(1, 7):
        nm_mid = 0.3 if seed == 6 else 0.1
        frames.append(history("nelder_mead", seed, [10, 20, 100], [0.5, nm_mid, 0.05]))
        frames.append(history("ga", seed, [10, 20, 100], [1.0, 0.3, 0.001 * seed]))
    return pd.concat(frames, ignore_index=True)


def test_hitting_nfe_known_answers(three_runs):
    hits = budget.hitting_nfe(three_runs)
    assert list(hits.columns) == [
        "scenario",
        "case",
        "algorithm",
        "seed",
        "target",
        "hit_nfe",
        "last_nfe",
    ]
    got = hits.pivot(index="seed", columns="target", values="hit_nfe")
    assert got.loc[1].tolist() == [40.0, 30.0, 20.0]  # columns sorted: 0.001, 0.01, 0.1
    assert got.loc[2].isna().all()  # never within 10 %
    assert got.loc[3].tolist() == [15.0, 15.0, 15.0]  # negative excess: within every target
    assert hits.groupby("seed")["last_nfe"].first().tolist() == [40, 30, 25]
    assert hits["target"].tolist()[:3] == list(EXCESS_TARGETS)


def test_hitting_nfe_targets_and_missing_truth(three_runs):
    hits = budget.hitting_nfe(three_runs, targets=[0.25])
    assert hits.set_index("seed")["hit_nfe"].tolist() == [20.0, 20.0, 15.0]
    on_target = budget.hitting_nfe(three_runs, targets=[0.05])  # seed 1 reaches exactly 0.05
    assert on_target["hit_nfe"].tolist()[0] == 20.0
    no_truth = three_runs.assign(excess_ise=np.nan)
    assert budget.hitting_nfe(no_truth)["hit_nfe"].isna().all()
    with pytest.raises(ValueError, match="with_excess"):
        budget.hitting_nfe(three_runs.drop(columns="excess_ise"))


def test_hitting_nfe_matches_a_loop_over_runs():
    rng = np.random.default_rng(3)
    frames = []
    for algo in ALGORITHMS:
        for seed in range(1, 6):
            n = int(rng.integers(3, 40))
            nfe = np.cumsum(rng.integers(1, 30, n))
            excess = np.minimum.accumulate(np.exp(rng.normal(-2, 2, n)) - 0.05)
            frames.append(history(algo, seed, nfe, excess, case=1 + seed % 2))
    h = pd.concat(frames, ignore_index=True).sample(frac=1.0, random_state=0)
    hits = budget.hitting_nfe(h).set_index(["case", "algorithm", "seed", "target"])
    for (c, a, s), run in h.groupby(["case", "algorithm", "seed"]):
        for t in EXCESS_TARGETS:
            within = run.loc[run["excess_ise"] <= t, "nfe"]
            want = float(within.min()) if len(within) else np.nan
            np.testing.assert_equal(hits.loc[(c, a, s, t), "hit_nfe"], want)


def test_ecdf_counts_never_hit_runs(three_runs):
    hits = budget.hitting_nfe(three_runs)
    e = budget.ecdf(hits, 1, 1, [10, 15, 20, 39, 40, 1000])
    assert set(e["n_runs"]) == {3}
    share = e.pivot(index="nfe", columns="target", values="share")
    assert share[0.1].tolist() == pytest.approx([0, 1 / 3, 2 / 3, 2 / 3, 2 / 3, 2 / 3])
    assert share[0.001].tolist() == pytest.approx([0, 1 / 3, 1 / 3, 1 / 3, 2 / 3, 2 / 3])
    with pytest.raises(ValueError, match="scenario 2 case 1"):
        budget.ecdf(hits, 2, 1, [10])


def test_rank_curve_flips_with_budget(crossing):
    rc = budget.rank_curve(crossing, 1, 1, [5, 10, 20, 100])
    rank = rc.pivot(index="nfe", columns="algorithm", values="mean_rank")
    assert rank.loc[5].isna().all()  # before any run's first entry: no complete seed
    assert rc.loc[rc["nfe"] == 5, "n_blocks"].eq(0).all()
    assert rank.loc[10].tolist() == [2.0, 1.0]  # columns sorted: ga, nelder_mead
    # seed 6 ties at 20: both 1.5; the other five seeds Nelder-Mead first
    assert rank.loc[20, "nelder_mead"] == pytest.approx((5 * 1 + 1.5) / 6)
    assert rank.loc[20, "ga"] == pytest.approx((5 * 2 + 1.5) / 6)
    assert rank.loc[100].tolist() == [1.0, 2.0]  # late, GA is lower on every seed
    med = rc.pivot(index="nfe", columns="algorithm", values="median_excess")
    assert med.loc[100, "ga"] == pytest.approx(0.0035)
    assert med.loc[20, "nelder_mead"] == pytest.approx(0.1)
    assert rc["algorithm"].tolist()[:2] == ["nelder_mead", "ga"]  # the paper's order


def test_budget_grid(crossing):
    g = budget.budget_grid(crossing, 1, 1, points=5)
    assert g[0] == 10
    assert g[-1] == 100
    assert np.all(np.diff(g) > 0)
    for f in BUDGET_FRACTIONS:
        if np.floor(f * 100) >= 10:
            assert int(np.floor(f * 100)) in g


def test_summary_censors_at_common_n(three_runs):
    hits = budget.hitting_nfe(three_runs)
    s = budget.summary(hits, three_runs).set_index("target")
    assert s.loc[0.1, "common_nfe"] == 25  # seed 3 stops at 25
    assert s.loc[0.1, "median_nfe"] == 20.0  # 15, 20, never
    assert s.loc[0.1, "share_by_n"] == pytest.approx(2 / 3)
    assert np.isnan(s.loc[0.01, "median_nfe"])  # 15, 30 > N, never: half or more not within N
    assert s.loc[0.01, "share_by_n"] == pytest.approx(1 / 3)


def test_summary_median_is_an_evaluation_some_run_needed():
    hits = pd.DataFrame(
        {
            "scenario": 1,
            "case": 1,
            "algorithm": "avoa",
            "seed": [1, 2, 3, 4],
            "target": 0.1,
            "hit_nfe": [10.0, 20.0, 60.0, np.nan],
            "last_nfe": 100,
        }
    )
    runs = pd.concat([history("avoa", k, [10, 100], [1.0, 1.0]) for k in range(1, 5)])
    s = budget.summary(hits, runs)
    assert s["median_nfe"].tolist() == [20.0]  # the ECDF reaches 1/2 at 20 (not 40)
    assert s["share_by_n"].tolist() == [0.75]


def test_fig_budget_writes_figure_and_curves(tmp_path):
    rng = np.random.default_rng(1)
    frames = []
    for case in (1, 2):
        for k, algo in enumerate(ALGORITHMS):
            for seed in (1, 2, 3):
                n = 15
                raw = 0.5 * np.exp(-np.arange(n) / (2 + k)) * (1 + rng.random(n)) - 0.01
                excess = np.minimum.accumulate(raw)
                frames.append(history(algo, seed, 20 * np.arange(1, n + 1), excess, case=case))
    h = pd.concat(frames, ignore_index=True)
    stem = tmp_path / "figs" / "budget_s1"
    F.fig_budget(h, 1, stem)
    assert (tmp_path / "figs" / "budget_s1.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert (tmp_path / "figs" / "budget_s1.pdf").read_bytes()[:5] == b"%PDF-"
    ecdf = pd.read_csv(tmp_path / "figs" / "budget_s1_ecdf.csv")
    rank = pd.read_csv(tmp_path / "figs" / "budget_s1_rank.csv")
    assert set(ecdf["case"]) == {1, 2}
    assert set(ecdf["target"]) == set(EXCESS_TARGETS)
    assert set(rank["algorithm"]) == set(ALGORITHMS)
    assert ecdf["nfe"].max() == 300
    assert (rank["common_nfe"] == 300).all()

    out = tmp_path / "bad"
    with pytest.raises(ValueError, match="excess_ise"):
        F.fig_budget(h.drop(columns="excess_ise"), 1, out / "budget_s1")
    with pytest.raises(ValueError, match="scenario 3"):
        F.fig_budget(h, 3, out / "budget_s3")
    assert not out.exists()
