"""The paper's tables as DataFrames, and the CSV/Markdown/LaTeX writer."""

import numpy as np
import pandas as pd
import pytest

from avoa_pipeline import aggregate
from avoa_pipeline.errors import UserError
from avoa_pipeline.model.battery import CASES, PARAM_NAMES
from avoa_pipeline.optimizers import ALGORITHMS, PAPER_LABELS
from avoa_pipeline.report import tables

TRUE = {"vnom": 3.73, "q": 2.57, "vdis": 3.53, "r0": 0.0536, "rtr": 0.0053, "tau": 109.7}


def param_runs(scenario=1, case=2, seeds=(1, 2, 3)):
    """Per algorithm: ISE 1, 2, 3 (× algorithm index) on seeds 1-3 → median run = seed 2,
    whose estimates are the truth × (1 + 0.01·k), k = algorithm index."""
    rows = []
    for k, a in enumerate(ALGORITHMS):
        for seed in seeds:
            factor = 1 + 0.01 * k if seed == 2 else 1 + 0.1 * seed
            row = {
                "scenario": scenario,
                "case": case,
                "algorithm": a,
                "seed": seed,
                "best_ise": float(seed * (k + 1)),
                "true_ise": 0.5,
            }
            for p in PARAM_NAMES:
                free = p in CASES[case].free
                est = TRUE[p] * factor if free else np.nan
                row[f"est_{p}"] = est
                row[f"true_{p}"] = TRUE[p] if free else np.nan
                row[f"relerr_{p}"] = est / TRUE[p] - 1 if free else np.nan
            rows.append(row)
    return pd.DataFrame(rows)


def paper_params(scenario=1, case=2):
    rows = []
    for k, a in enumerate(ALGORITHMS):
        for p in (*CASES[case].free, "ise"):
            value = 0.01 * (k + 1) if p == "ise" else TRUE[p] * 1.05
            rows.append(
                {"table": 5, "scenario": scenario, "case": case, "algorithm": a}
                | {"parameter": p, "value": value}
            )
    return pd.DataFrame(rows)


# ------------------------------------------------------------------------------ Tables 4-19
def test_param_table_shows_the_median_run_and_the_paper():
    t = tables.param_table(param_runs(), paper_params(), 1, 2)
    assert list(t.columns) == ["Quantity", "Row", "True", *[PAPER_LABELS[a] for a in ALGORITHMS]]
    t = t.set_index(["Quantity", "Row"])
    r0 = tables.param_label("r0")
    avoa = PAPER_LABELS["avoa"]
    k = ALGORITHMS.index("avoa")
    assert t.loc[(r0, "ours (median-ISE run)"), avoa] == pytest.approx(TRUE["r0"] * (1 + 0.01 * k))
    assert t.loc[(r0, "ours rel. err. (%)"), avoa] == pytest.approx(k)
    assert t.loc[(r0, "paper"), avoa] == pytest.approx(TRUE["r0"] * 1.05)
    assert t.loc[(r0, "paper rel. err. (%)"), avoa] == pytest.approx(5.0)
    assert t.loc[(r0, "ours (median-ISE run)"), "True"] == pytest.approx(TRUE["r0"])
    # |rel. err.| over seeds 1, 2, 3: 10 %, k %, 30 % → median 10 % (k ≤ 6)
    assert t.loc[(r0, "ours median abs. rel. err. (%)"), avoa] == pytest.approx(10.0)
    ise = tables.ISE_LABEL
    assert t.loc[(ise, "ours mean"), avoa] == pytest.approx(2.0 * (k + 1))
    assert t.loc[(ise, "ours sd"), avoa] == pytest.approx(1.0 * (k + 1))
    assert t.loc[(ise, "ours best"), avoa] == pytest.approx(k + 1)
    assert t.loc[(ise, "ours worst"), avoa] == pytest.approx(3.0 * (k + 1))
    assert t.loc[(ise, "paper"), avoa] == pytest.approx(0.01 * (k + 1))
    assert t.loc[(ise, "ours mean"), "True"] == pytest.approx(0.5)
    assert t.loc[("Runs", "seed of median run"), avoa] == 2
    # excess over the truth (ISE_true 0.5): 2·seed·(k + 1) − 1 → quartiles at seeds 1.5, 2, 2.5
    assert t.loc[(ise, "excess (%) median"), avoa] == pytest.approx(100 * (4 * (k + 1) - 1))
    assert t.loc[(ise, "excess (%) q25"), avoa] == pytest.approx(100 * (3 * (k + 1) - 1))
    assert t.loc[(ise, "excess (%) q75"), avoa] == pytest.approx(100 * (5 * (k + 1) - 1))
    assert t.loc[(ise, "excess (%) median"), "True"] == 0.0
    # only case 2's parameters appear (no Q), in the paper's row order
    quantities = list(dict.fromkeys(t.index.get_level_values(0)))
    assert quantities == [
        *map(tables.param_label, CASES[2].free),
        ise,
        tables.ACCURACY_QUANTITY,
        "Runs",
    ]
    rows = list(t.index.get_level_values(1))
    assert rows.index("excess (%) median") == rows.index("paper", rows.index("ours worst")) + 1


def test_param_table_even_seed_count_takes_the_lower_middle_run():
    runs = param_runs(seeds=(1, 2, 3, 4))
    t = tables.param_table(runs, None, 1, 2).set_index(["Quantity", "Row"])
    assert (t.loc[("Runs", "seed of median run")].drop("True") == 2).all()
    assert t.loc[(tables.param_label("vnom"), "paper")].drop("True").isna().all()


def accuracy_runs():
    """Seeds 1-4 of param_runs with chosen relative errors: AVOA's every parameter within 1 % on
    seeds 1 and 2, one parameter 3 % off on seed 3 and 20 % on seed 4 → 50 % within 1 %, 75 %
    within 5 %; GA's all 0.5 % off, but seed 4 has no ISE → 3 seeds, all within 1 %; the others
    20 % off everywhere."""
    runs = param_runs(seeds=(1, 2, 3, 4))
    free = [f"relerr_{p}" for p in CASES[2].free]
    runs[free] = 0.2
    avoa, ga = runs["algorithm"] == "avoa", runs["algorithm"] == "ga"
    runs.loc[avoa, free] = -0.005
    runs.loc[avoa & (runs["seed"] == 3), free[-1]] = 0.03
    runs.loc[avoa & (runs["seed"] == 4), free[0]] = -0.2
    runs.loc[ga, free] = 0.005
    runs.loc[ga & (runs["seed"] == 4), "best_ise"] = np.nan
    return runs


def test_param_table_accuracy_rows():
    t = tables.param_table(accuracy_runs(), None, 1, 2).set_index(["Quantity", "Row"])
    q = tables.ACCURACY_QUANTITY
    one, five = (f"seeds within {x} % (all params) (%)" for x in (1, 5))
    assert t.loc[(q, one), "AVOA"] == pytest.approx(50.0)
    assert t.loc[(q, five), "AVOA"] == pytest.approx(75.0)
    assert t.loc[(q, one), "GA"] == pytest.approx(100.0)
    assert t.loc[(q, five), "GWO"] == 0.0
    assert t.loc[("Runs", "seeds"), "GA"] == 3


def test_accuracy_table_counts_seeds_within_the_tolerances():
    runs = pd.concat([accuracy_runs(), param_runs(scenario=2, case=2)], ignore_index=True)
    t = tables.accuracy_table(runs, scenario=1)
    labels = [PAPER_LABELS[a] for a in ALGORITHMS]
    assert list(t.columns) == ["Scenario", "Case", "Row", *labels]
    assert list(t["Row"]) == [
        "seeds within 1 % (all params) (%)",
        "seeds within 5 % (all params) (%)",
        "seeds",
    ]
    assert (t["Scenario"] == 1).all()
    assert (t["Case"] == 2).all()
    t = t.set_index("Row")
    assert t.loc["seeds within 1 % (all params) (%)", "AVOA"] == pytest.approx(50.0)
    assert t.loc["seeds within 5 % (all params) (%)", "AVOA"] == pytest.approx(75.0)
    assert t.loc["seeds within 1 % (all params) (%)", "GA"] == pytest.approx(100.0)
    assert t.loc["seeds", "GA"] == 3
    assert t.loc["seeds", "AVOA"] == 4
    assert (t.loc["seeds within 5 % (all params) (%)", ["GWO", "GTO"]] == 0).all()
    both = tables.accuracy_table(runs)
    assert list(both[["Scenario", "Case"]].drop_duplicates().itertuples(index=False)) == [
        (1, 2),
        (2, 2),
    ]


# ----------------------------------------------------------------------------- Tables 20-23
def objective_inputs():
    rng = np.random.default_rng(5)
    rows = []
    for c in (1, 2):
        base = 1 + rng.random(10)
        for k, a in enumerate(ALGORITHMS):
            ise = base * (0.5 if a == "avoa" else 1 + 0.1 * k)
            rows += [
                {"scenario": 3, "case": c, "algorithm": a, "seed": i + 1, "best_ise": v}
                for i, v in enumerate(ise)
            ]
    paper = pd.DataFrame(
        [
            {"table": 22, "scenario": 3, "case": c, "algorithm": a, "ise": 0.1 * (k + 1)}
            | {"rank_printed": f"{k + 1}", "rank": k + 1}
            for c in (1, 2)
            for k, a in enumerate(ALGORITHMS)
        ]
    )
    return pd.DataFrame(rows), paper


def test_objective_table():
    runs, paper = objective_inputs()
    t = tables.objective_table(runs, paper, 3)
    assert len(t) == 2 * 7
    assert list(t["Algorithm"][:7]) == [PAPER_LABELS[a] for a in ALGORITHMS]
    avoa = t[t["Algorithm"] == "AVOA"]
    assert (avoa["Rank (mean)"] == 1).all()
    assert (avoa["AVOA vs this"] == "").all()
    rivals = t[t["Algorithm"] != "AVOA"]
    assert (rivals["AVOA vs this"] == "AVOA lower").all()
    assert (rivals["p (Holm)"] < 0.05).all()
    assert (t.groupby("Case")["Friedman p"].nunique() == 1).all()
    assert (t["Friedman p"] < 1e-6).all()
    assert list(t["Paper rank"][:7]) == list(range(1, 8))
    assert t.loc[t["Algorithm"] == "GA", "Paper ISE"].iloc[0] == pytest.approx(0.3)
    # no truth in these runs: no excess, no margin; the size verdict is the difference test's
    excess = ["Median excess (%)", "Excess q25 (%)", "Excess q75 (%)", "Margin (%)"]
    assert (
        t[[*excess, "AVOA − this (median, % of ISE_true)", "p equiv. (Holm)"]].isna().all(axis=None)
    )
    assert (rivals["AVOA vs this (size)"] == "AVOA lower").all()
    assert (avoa["AVOA vs this (size)"] == "").all()


def excess_runs(with_column: bool):
    """Scenario 1 case 2, 30 seeds, N = 1000 samples and ISE_true = 1e-3 → margin
    1000·(0.1 mV)²/1e-3 = 1 % of ISE_true. AVOA's excess is 2 % ± 1 %; each rival's is AVOA's
    plus a shift (in excess units) and noise of the given spread."""
    rng = np.random.default_rng(12)
    n = 30
    base = 0.02 + 0.01 * rng.uniform(-1, 1, n)
    shift = {
        "avoa": (0.0, 0.0),
        "nelder_mead": (0.005, 0.001),  # 0.5 % worse, small spread: practically equivalent
        "quasi_newton": (0.05, 0.001),  # 5 % worse: AVOA lower
        "ga": (-0.05, 0.001),  # 5 % better: AVOA higher
        "gwo": (0.005, 0.05),  # 0.5 % worse, wide spread: inconclusive
        "run": (0.5, 0.01),
        "gto": (0.5, 0.01),
    }
    rows = []
    for a in ALGORITHMS:
        mean, spread = shift[a]
        e = base + mean + spread * rng.uniform(-1, 1, n)
        for i in range(n):
            row = {"scenario": 1, "case": 2, "algorithm": a, "seed": i + 1}
            row |= {"best_ise": 1e-3 * (1 + e[i]), "true_ise": 1e-3, "n_samples": 1000}
            if with_column:
                row["excess_ise"] = e[i]
            rows.append(row)
    return pd.DataFrame(rows), base


@pytest.mark.parametrize("with_column", [True, False], ids=["excess_ise", "older aggregate"])
def test_objective_table_excess_and_equivalence(with_column):
    runs, base = excess_runs(with_column)
    t = tables.objective_table(runs, None, 1).set_index("Algorithm")
    assert (t["Case"] == 2).all()
    assert t["Margin (%)"].to_numpy() == pytest.approx(1.0)
    assert t.loc["AVOA", "Median excess (%)"] == pytest.approx(100 * np.median(base))
    q25, q75 = np.quantile(100 * base, [0.25, 0.75])
    assert (t.loc["AVOA", "Excess q25 (%)"], t.loc["AVOA", "Excess q75 (%)"]) == pytest.approx(
        (q25, q75)
    )
    assert t.loc["RK", "Median excess (%)"] == pytest.approx(100 * np.median(base) + 50, abs=1)
    diff = t["AVOA − this (median, % of ISE_true)"]
    assert np.isnan(diff["AVOA"])
    assert diff["Nelder–Mead"] == pytest.approx(-0.5, abs=0.1)
    assert diff["Quasi-Newton"] == pytest.approx(-5.0, abs=0.1)
    assert diff["GA"] == pytest.approx(5.0, abs=0.1)
    size = t["AVOA vs this (size)"]
    assert size.to_dict() == {
        "Nelder–Mead": "practically equivalent",
        "Quasi-Newton": "AVOA lower",
        "GA": "AVOA higher",
        "GWO": "inconclusive",
        "RK": "AVOA lower",
        "AVOA": "",
        "GTO": "AVOA lower",
    }
    # the difference test alone calls the 0.5 % a difference; the size verdict says it is small
    assert t.loc["Nelder–Mead", "AVOA vs this"] == "AVOA lower"
    assert t.loc["Nelder–Mead", "p equiv. (Holm)"] < 0.05
    assert t.loc["Quasi-Newton", "p equiv. (Holm)"] > 0.05
    assert t.loc["GWO", "p equiv. (Holm)"] > 0.05


# ---------------------------------------------------------------------------------- Table 24
def test_time_table_ratios():
    rows = []
    for k, a in enumerate(ALGORITHMS):
        for seed in (1, 2):
            per_iter = 1.0 if a == "avoa" else 2.0 + k
            epi = 40.0 if a == "gto" else 20.0
            rows.append(
                {"scenario": 4, "case": 4, "algorithm": a, "seed": seed}
                | {"time_per_iter_s": per_iter, "evals_per_iter": epi}
                | {"time_per_eval_s": per_iter / epi}
            )
    paper = pd.DataFrame(
        {"algorithm": list(ALGORITHMS), "seconds": [4.28, 4.37, 15.78, 5.96, 5.54, 1.24, 3.95]}
    )
    t = tables.time_table(pd.DataFrame(rows), paper).set_index("Algorithm")
    assert t.loc["AVOA", "Ratio to AVOA (iter)"] == 1.0
    assert t.loc["GA", "Ratio to AVOA (iter)"] == pytest.approx(4.0)
    k_gto = ALGORITHMS.index("gto")
    assert t.loc["GTO", "Ratio to AVOA (eval)"] == pytest.approx((2.0 + k_gto) / 2)
    assert t.loc["GTO", "Time/eval (ms)"] == pytest.approx(1000 * (2.0 + k_gto) / 40)
    assert t.loc["GA", "Paper ratio to AVOA"] == pytest.approx(15.78 / 1.24)
    assert (t["Runs"] == 2).all()


# -------------------------------------------------------------------------------- Tables 1-3
def test_tables_1_to_3_from_the_config(cfg):
    t1 = tables.cell_table(cfg).set_index("Characteristic")
    assert t1.loc["Typical capacity (mAh)", "Value"] == "2600"
    t2 = tables.constants_table(cfg).set_index("Parameter")
    assert t2.loc["δQ (eq. 8)", "Value"] == pytest.approx(100 * (2.0 / 2.6 - 1))
    assert t2.loc["δR_o (eq. 9)", "Value"] == pytest.approx(200.0)
    assert t2.loc["Number of iterations", "Value"] == cfg["budget"]["iterations"]
    t3 = tables.bounds_table(cfg)
    assert len(t3) == 12
    flagged = t3[t3["Note"] != ""]
    assert list(flagged["Parameter"]) == [tables.param_label("vnom")]
    assert flagged["Temperature"].iloc[0].startswith("T2")
    assert (flagged["Printed lower"].iloc[0], flagged["Used lower"].iloc[0]) == (3.7, 3.9)


# ------------------------------------------------------------------------------------ writer
def test_write_table_writes_three_files(tmp_path):
    df = pd.DataFrame(
        {"Parameter": ["τ_tr (s)", "R_o (Ω)"], "Row": ["a|b", "5 %"], "Value": [109.7, np.nan]}
    )
    paths = tables.write_table(df, tmp_path / "table04", "Table 4. S1/C1 & more")
    assert [p.name for p in paths] == ["table04.csv", "table04.md", "table04.tex"]
    back = pd.read_csv(tmp_path / "table04.csv")
    assert back["Value"].iloc[0] == 109.7
    assert np.isnan(back["Value"].iloc[1])
    md = (tmp_path / "table04.md").read_text()
    assert md.startswith("Table 4. S1/C1 & more\n\n| Parameter")
    assert "a\\|b" in md
    assert "—" in md
    assert "109.7" in md
    tex = (tmp_path / "table04.tex").read_text()
    assert r"\caption{Table 4. S1/C1 \& more}" in tex
    assert r"$\tau$\_tr (s)" in tex
    assert r"5 \%" in tex
    assert r"\begin{tabular}{llr}" in tex
    assert sorted(p.name for p in tmp_path.iterdir()) == [
        "table04.csv",
        "table04.md",
        "table04.tex",
    ]


def test_write_table_writes_nothing_on_error(tmp_path):
    df = pd.DataFrame({"a": [1.0]})
    (tmp_path / "t.tex").mkdir()  # the last file cannot be put in place
    with pytest.raises(UserError, match=r"t\.tex: cannot write"):
        tables.write_table(df, tmp_path / "t", "caption")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["t.tex"]  # no csv, md, or temp file
    with pytest.raises(TypeError):
        tables.write_table([1, 2], tmp_path / "u", "caption")
    assert not (tmp_path / "u.csv").exists()


def test_param_table_of_a_pair_not_run_shows_the_truth_and_the_papers_error():
    truth = {"vnom": 3.73, "q": 2.57, "vdis": 3.53, "r0": 0.0536, "rtr": 0.0053, "tau": 109.7}
    empty = aggregate.empty_runs()
    t = tables.param_table(empty, paper_params(), 1, 2, truth=truth).set_index(["Quantity", "Row"])
    vnom = tables.param_label("vnom")
    assert t.loc[(vnom, "ours (median-ISE run)"), "True"] == pytest.approx(3.73)
    printed = t.loc[(vnom, "paper")].drop("True").dropna()
    assert len(printed) > 0
    err = t.loc[(vnom, "paper rel. err. (%)")].drop("True").dropna()
    np.testing.assert_allclose(err, 100 * (printed / 3.73 - 1))
    assert np.isnan(t.loc[(tables.ISE_LABEL, "ours mean"), "True"])  # needs data: not known
