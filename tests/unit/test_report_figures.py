"""Figures 1-21: each writes a PNG and a PDF, or nothing; the convergence statistics by hand."""

import inspect

import numpy as np
import pandas as pd
import pytest
from matplotlib.figure import Figure
from report_helpers import history

from avoa_pipeline import problem, synthetic
from avoa_pipeline.optimizers import ALGORITHMS
from avoa_pipeline.optimizers import avoa as avoa_mod
from avoa_pipeline.report import figures as F


def assert_written(stem):
    png = stem.with_name(stem.name + ".png")
    pdf = stem.with_name(stem.name + ".pdf")
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert pdf.read_bytes()[:5] == b"%PDF-"
    assert png.stat().st_size > 1000
    assert pdf.stat().st_size > 1000


def assert_empty(folder):
    assert not folder.exists() or list(folder.iterdir()) == []


@pytest.fixture
def hand_runs():
    """Three AVOA runs with known best-ISE steps at known evaluation counts."""
    return pd.concat(
        [
            history("avoa", 1, [20, 40, 60], [10.0, 5.0, 1.0]),
            history("avoa", 2, [20, 50], [8.0, 2.0]),
            history("avoa", 3, [30, 60], [6.0, 3.0]),
        ],
        ignore_index=True,
    )


@pytest.fixture
def small_histories():
    rng = np.random.default_rng(1)
    frames = []
    for k, algo in enumerate(ALGORITHMS):
        for seed in (1, 2, 3):
            n = 12 if algo not in ("nelder_mead", "quasi_newton") else 8 + seed
            raw = 0.5 * np.exp(-np.arange(n + 1) / (3 + k)) * (1 + rng.random(n + 1))
            best = np.minimum.accumulate(raw)
            frames.append(history(algo, seed, 20 * np.arange(1, n + 2), best))
    return pd.concat(frames, ignore_index=True)


# --- helpers -----------------------------------------------------------------------------


def test_figure_number():
    assert F.figure_number(1, 1) == 4
    assert F.figure_number(1, 4) == 7
    assert F.figure_number(2, 1) == 8
    assert F.figure_number(4, 4) == 19
    assert sorted(F.figure_number(s, c) for s in range(1, 5) for c in range(1, 5)) == list(
        range(4, 20)
    )
    for bad in ((0, 1), (1, 5), (1.5, 1), (True, 1)):
        with pytest.raises(ValueError, match=r"integer in 1\.\.4"):
            F.figure_number(*bad)


def test_bands_on_evaluations_by_hand(hand_runs):
    b = F.convergence_bands(hand_runs, 4, 4, x="nfe")
    # grid: breakpoints from the latest first entry (30) to the latest last entry (60)
    assert b["nfe"].tolist() == [30, 40, 50, 60]
    # values at 30: 10, 8, 6; at 40: 5, 8, 6; at 50: 5, 2, 6; at 60: 1, 2, 3
    assert b["median"].tolist() == [8.0, 6.0, 5.0, 2.0]
    assert b["q25"].tolist() == [7.0, 5.5, 3.5, 1.5]
    assert b["q75"].tolist() == [9.0, 7.0, 5.5, 2.5]
    assert set(b["n_runs"]) == {3}
    assert set(b["algorithm"]) == {"avoa"}


def test_bands_on_a_given_grid(hand_runs):
    b = F.convergence_bands(hand_runs, 4, 4, x="nfe", grid=[10, 25, 45, 100])
    assert np.isnan(b["median"].iloc[0])  # before every run started
    assert np.isnan(b["median"].iloc[1])  # run 3 starts at 30
    assert b["median"].iloc[2] == 6.0  # 5, 8, 6
    assert b["median"].iloc[3] == 2.0  # after the end every run keeps its final best


def test_bands_on_iterations_carry_a_finished_run(hand_runs):
    b = F.convergence_bands(hand_runs, 4, 4, x="iteration")
    assert b["iteration"].tolist() == [0, 1, 2]
    # iteration 2: run 1 -> 1.0; runs 2, 3 stopped at iteration 1 and keep 2.0, 3.0
    assert b["median"].tolist() == [8.0, 3.0, 2.0]  # iteration 1: 5, 2, 3
    assert b["q25"].tolist()[2] == 1.5


def test_bands_order_and_checks(small_histories, hand_runs):
    b = F.convergence_bands(small_histories, 4, 4)
    assert list(dict.fromkeys(b["algorithm"])) == list(ALGORITHMS)
    with pytest.raises(ValueError, match="x must be"):
        F.convergence_bands(hand_runs, 4, 4, x="wall_s")
    with pytest.raises(ValueError, match="no rows for scenario 1, case 4"):
        F.convergence_bands(hand_runs, 1, 4)
    with pytest.raises(ValueError, match="duplicate entry"):
        F.convergence_bands(pd.concat([hand_runs, hand_runs.iloc[:1]]), 4, 4)
    bad = hand_runs.assign(algorithm="pso")
    with pytest.raises(ValueError, match="unknown algorithm"):
        F.convergence_bands(bad, 4, 4)
    nan = hand_runs.copy()
    nan.loc[0, "best_ise"] = np.nan
    with pytest.raises(ValueError, match="best_ise"):
        F.convergence_bands(nan, 4, 4)


def test_avoa_settings_follow_the_code():
    s = F.avoa_settings()
    params = inspect.signature(avoa_mod.avoa).parameters
    for name in ("p1", "p2", "p3", "alpha", "beta", "gamma"):
        assert s[name] == params[name].default
    assert s["levy_beta"] == avoa_mod.LEVY_BETA
    assert s["levy_sigma"] == pytest.approx(0.6966, abs=1e-4)


def test_free_vector_forms(cfg):
    pb = problem.build(cfg, 4, 4)
    x = pb.true_free()
    assert np.array_equal(F.free_vector(pb, x), x)
    assert np.array_equal(F.free_vector(pb, dict(zip(pb.names, x, strict=True))), x)
    row = pd.Series({f"est_{n}": v for n, v in zip(pb.names, x, strict=True)} | {"est_q": np.nan})
    assert np.array_equal(F.free_vector(pb, row), x)
    with pytest.raises(ValueError, match="expected 5 values"):
        F.free_vector(pb, x[:3])
    with pytest.raises(ValueError, match="lack"):
        F.free_vector(pb, {"vnom": 3.9})
    with pytest.raises(ValueError, match="finite"):
        F.free_vector(pb, np.full(5, np.nan))
    assert np.allclose(F.initial_guess(pb), (pb.lb + pb.ub) / 2)


def test_median_run_is_the_lower_middle_run():
    runs = pd.DataFrame(
        {
            "scenario": 4,
            "case": 4,
            "algorithm": ["avoa"] * 4 + ["gto"],
            "seed": [1, 2, 3, 4, 1],
            "best_ise": [4.0, 1.0, 3.0, 2.0, 0.5],
        }
    )
    assert F.median_run(runs)["seed"] == 4  # sorted 1.0, 2.0, 3.0, 4.0 -> the 2.0 run
    assert F.median_run(runs.iloc[:3])["seed"] == 3
    with pytest.raises(ValueError, match="no ga rows"):
        F.median_run(runs, algorithm="ga")
    with pytest.raises(ValueError, match="missing column"):
        F.median_run(runs.drop(columns="seed"))


# --- drawing -----------------------------------------------------------------------------


def test_fig01_and_fig03(tmp_path, cfg):
    F.fig01(tmp_path / "fig01")
    F.fig03(tmp_path / "fig03", cfg=cfg)
    F.fig03(tmp_path / "fig03_plain")
    for stem in ("fig01", "fig03", "fig03_plain"):
        assert_written(tmp_path / stem)
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(
        f"{s}.{e}" for s in ("fig01", "fig03", "fig03_plain") for e in ("png", "pdf")
    )


def test_fig02(tmp_path, cfg):
    ds = synthetic.generate(cfg, 1, 1)
    F.fig02(ds, tmp_path / "fig02")
    assert_written(tmp_path / "fig02")
    ds.meta = {k: v for k, v in ds.meta.items() if k != "segments"}
    with pytest.raises(ValueError, match="segments"):
        F.fig02(ds, tmp_path / "bad" / "fig02")
    assert_empty(tmp_path / "bad")


def test_convergence(tmp_path, small_histories):
    F.convergence(small_histories, 4, 4, tmp_path / "fig19")
    F.convergence(small_histories, 4, 4, tmp_path / "plain.v2", paper_label=False)
    assert_written(tmp_path / "fig19")
    assert_written(tmp_path / "plain.v2")  # a dot in the stem is kept, not a suffix


def test_convergence_with_zero_ise_warns_nothing(tmp_path, hand_runs):
    zero = hand_runs.copy()
    zero.loc[zero["seed"] == 1, "best_ise"] = [1.0, 0.0, 0.0]
    zero.loc[zero["seed"] == 2, "best_ise"] = [1.0, 0.0]
    F.convergence(zero, 4, 4, tmp_path / "zero")  # filterwarnings=error: log(0) would fail
    assert_written(tmp_path / "zero")


def test_convergence_bad_input_writes_nothing(tmp_path, small_histories):
    out = tmp_path / "figs"
    with pytest.raises(ValueError, match=r"missing column.*nfe"):
        F.convergence(small_histories.drop(columns="nfe"), 4, 4, out / "fig19")
    with pytest.raises(TypeError, match="DataFrame"):
        F.convergence(small_histories.to_dict(), 4, 4, out / "fig19")
    with pytest.raises(ValueError, match=r"integer in 1\.\.4"):
        F.convergence(small_histories, 5, 4, out / "fig19")
    assert_empty(out)


def test_failed_render_leaves_neither_file(tmp_path, small_histories, monkeypatch):
    real = Figure.savefig

    def pdf_fails(self, fname, *args, **kwargs):
        if kwargs.get("format") == "pdf":
            raise OSError("disk full")
        return real(self, fname, *args, **kwargs)

    monkeypatch.setattr(Figure, "savefig", pdf_fails)
    with pytest.raises(OSError, match="disk full"):
        F.convergence(small_histories, 4, 4, tmp_path / "fig19")
    assert_empty(tmp_path)  # the PNG rendered but was not published, no temporary files


def test_fig20_fig21(tmp_path, cfg):
    pb = problem.build(cfg, 4, 4)
    runs = pd.DataFrame(
        [
            {"scenario": 4, "case": 4, "algorithm": "avoa", "seed": s, "best_ise": f}
            | {f"est_{n}": v for n, v in zip(pb.names, pb.true_free(), strict=True)}
            for s, f in ((1, 0.3), (2, 0.1), (3, 0.2))
        ]
    )
    row = F.median_run(runs)
    F.fig20(pb, row, tmp_path / "fig20")
    F.fig21(pb, row, tmp_path / "fig21")
    F.fig21(pb, pb.true_free(), tmp_path / "fig21_given", before=pb.lb)
    for stem in ("fig20", "fig21", "fig21_given"):
        assert_written(tmp_path / stem)
    with pytest.raises(ValueError, match="expected 5 values"):
        F.fig20(pb, [1.0, 2.0], tmp_path / "bad" / "fig20")
    assert_empty(tmp_path / "bad")
