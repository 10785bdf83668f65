"""The paper's tables as DataFrames, and the CSV/Markdown/LaTeX writer."""

import numpy as np
import pandas as pd
import pytest

from avoa_pipeline import aggregate
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
    # only case 2's parameters appear (no Q), in the paper's row order
    quantities = list(dict.fromkeys(t.index.get_level_values(0)))
    assert quantities == [*map(tables.param_label, CASES[2].free), ise, "Runs"]


def test_param_table_even_seed_count_takes_the_lower_middle_run():
    runs = param_runs(seeds=(1, 2, 3, 4))
    t = tables.param_table(runs, None, 1, 2).set_index(["Quantity", "Row"])
    assert (t.loc[("Runs", "seed of median run")].drop("True") == 2).all()
    assert t.loc[(tables.param_label("vnom"), "paper")].drop("True").isna().all()


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
    with pytest.raises(IsADirectoryError):
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
