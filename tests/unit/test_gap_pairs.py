"""Two withheld effects at once: the pair generator (the control plus exactly the two effects) and
the ladder's judgement on hand-made diagnoses (no diagnosis runs here)."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest

from avoa_pipeline import plan as plan_mod
from avoa_pipeline.errors import ConfigError
from avoa_pipeline.gap import evaluate as ev
from avoa_pipeline.gap import withheld as W
from avoa_pipeline.jobs import gap as gap_jobs

SEED = 7
NOISE = 2.0
# (pair, magnitudes): the two effects act through different states, so the one order of the
# simulation in the generator is tested on additive and non-additive combinations
PAIRS = [
    {"second_rc": 0.03, "hysteresis": 0.02},
    {"thermal": 30000.0, "second_rc": 0.03},  # listed out of EFFECTS order on purpose
    {"butler_volmer": 0.1, "ocv_shape": 0.03},
    {"second_rc": 0.03, "current_offset": 0.05},
]


def _frame(ds):
    return ds.frame()


def test_pair_at_zero_magnitudes_is_the_control_exactly():
    control = W.make(SEED, "none", 0.0, NOISE, "pulse", 2)
    zero = W.make_pair(SEED, {"hysteresis": 0.0, "ocv_shape": 0.0}, NOISE, "pulse", 2)
    pd.testing.assert_frame_equal(_frame(zero), _frame(control), check_exact=True)
    assert zero.meta["raw_residual_mv"] == 0.0
    assert zero.meta["effect_residual_mv"] == 0.0


@pytest.mark.parametrize("magnitudes", PAIRS, ids=lambda p: "+".join(p))
@pytest.mark.parametrize("kept", [0, 1])
def test_pair_with_one_magnitude_zero_is_the_single_effect_dataset(magnitudes, kept):
    effect = list(magnitudes)[kept]
    other = list(magnitudes)[1 - kept]
    pair = W.make_pair(SEED, {effect: magnitudes[effect], other: 0.0}, NOISE, "drive", 1)
    single = W.make(SEED, effect, magnitudes[effect], NOISE, "drive", 1)
    pd.testing.assert_frame_equal(_frame(pair), _frame(single), check_exact=True)
    for key in ("raw_residual_mv", "effect_residual_mv", "noise_rmse_mv", "ratio"):
        assert pair.meta[key] == single.meta[key]
    assert pair.meta["effect_params"][effect] == single.meta["effect_params"]


@pytest.mark.parametrize("magnitudes", PAIRS, ids=lambda p: "+".join(p))
def test_pair_is_the_control_plus_both_effects_with_their_own_parameters(magnitudes):
    a, b = W.pair_effects(magnitudes)
    pair = W.make_pair(SEED, magnitudes, NOISE, "drive", 1)
    control = W.make(SEED, "none", 0.0, NOISE, "drive", 1)
    alone = {e: W.make(SEED, e, magnitudes[e], NOISE, "drive", 1) for e in (a, b)}
    # the logged current and the temperature are the control's; only the voltage moves
    np.testing.assert_array_equal(pair.current_a, control.current_a)
    np.testing.assert_array_equal(pair.temperature_c, control.temperature_c)
    for e in (a, b):
        assert pair.meta["effect_params"][e] == alone[e].meta["effect_params"]
        assert pair.meta["cell"] == alone[e].meta["cell"] == control.meta["cell"]
    # the noise-free voltage is the control's with both effects' code paths switched on
    cell = W.base_cell(SEED, "drive", 1)
    logged = W.c_rate_profile("drive", SEED, 1) * cell.q_ah
    temp = W.temperature_k(cell, logged, SEED, "drive", 1)
    both = W.simulate(cell, logged, temp, pair.meta["effect_params"])
    v_control = W.simulate(cell, logged, temp)
    assert pair.meta["raw_residual_mv"] == pytest.approx(
        1e3 * np.sqrt(np.mean((both - v_control) ** 2)), rel=1e-12
    )
    # and the measured voltage is that plus the control's noise draw (to the logger's 0.1 mV)
    noise = control.voltage_v - v_control
    assert np.max(np.abs(pair.voltage_v - (both + noise))) <= W.VOLTAGE_LSB_V + 1e-12
    # the pair is neither effect alone
    for e in (a, b):
        assert pair.meta["raw_residual_mv"] > 0.5 * alone[e].meta["raw_residual_mv"]
        assert not np.array_equal(pair.voltage_v, alone[e].voltage_v)


def test_additive_pair_is_the_sum_of_the_two_effects():
    # a second RC and a hysteresis both add to the voltage and neither changes the current
    # the other sees: their effects on the voltage add exactly
    cell = W.base_cell(SEED, "pulse", 1)
    logged = W.c_rate_profile("pulse", SEED, 1) * cell.q_ah
    temp = W.temperature_k(cell, logged, SEED, "pulse", 1)
    p = {e: W.effect_params(e, m, SEED, "pulse", 1) for e, m in PAIRS[0].items()}
    v0 = W.simulate(cell, logged, temp)
    va = W.simulate(cell, logged, temp, {"second_rc": p["second_rc"]})
    vb = W.simulate(cell, logged, temp, {"hysteresis": p["hysteresis"]})
    vab = W.simulate(cell, logged, temp, p)
    np.testing.assert_allclose(vab - v0, (va - v0) + (vb - v0), atol=1e-12)
    assert np.abs(va - v0).max() > 1e-3
    assert np.abs(vb - v0).max() > 1e-3


def test_pair_sidecar_records_both_effects_and_each_alone():
    magnitudes = {"ocv_shape": 0.03, "butler_volmer": 0.1}
    pair = W.make_pair(SEED, magnitudes, NOISE, "pulse", 1)
    meta = pair.meta
    assert meta["effects"] == ["butler_volmer", "ocv_shape"]  # EFFECTS order, not the listing's
    assert meta["magnitudes"] == [0.1, 0.03]
    assert meta["magnitude_units"] == [W.UNITS["butler_volmer"], W.UNITS["ocv_shape"]]
    assert meta["ratio"] == pytest.approx(meta["effect_residual_mv"] / meta["noise_rmse_mv"])
    assert 0 < meta["effect_residual_mv"] <= meta["raw_residual_mv"] + 1e-9
    for effect, m in magnitudes.items():
        single = W.make(SEED, effect, m, NOISE, "pulse", 1).meta
        alone = meta["alone"][effect]
        assert alone["magnitude"] == m
        for key in ("raw_residual_mv", "effect_residual_mv", "noise_rmse_mv", "ratio"):
            assert alone[key] == single[key]
    # a pair with a large and a small effect: each alone is told apart
    assert meta["alone"]["ocv_shape"]["ratio"] != meta["alone"]["butler_volmer"]["ratio"]
    assert "effect" not in meta  # a pair is never read as a single-effect dataset


@pytest.mark.parametrize(
    ("magnitudes", "message"),
    [
        ({"second_rc": 0.03}, "exactly two different effects"),
        ({"second_rc": 0.03, "hysteresis": 0.01, "thermal": 1e4}, "exactly two different"),
        ({"second_rc": 0.03, "bogus": 0.01}, "unknown effect 'bogus'"),
        ({"second_rc": 0.03, "none": 0.0}, "unknown effect 'none'"),
    ],
)
def test_a_pair_that_is_not_two_known_effects_is_a_config_error(magnitudes, message):
    with pytest.raises(ConfigError, match=message):
        W.make_pair(SEED, magnitudes, NOISE, "pulse", 1)


def _gcfg(pairs):
    return {
        "profiles": ["pulse"],
        "replicates": [1],
        "control_replicates": [1, 2],
        "noise_mv": [1.0, 2.0],
        "magnitudes": {e: [] for e in W.EFFECTS} | {"second_rc": [0.01, 0.03]},
        "pairs": pairs,
        "paper_scenarios": [],
        "paper_cases": [],
        "pybamm": [],
    }


def test_pair_names_and_the_batch_with_its_alone_references(tmp_path):
    gcfg = _gcfg(
        {
            "noise_mv": [2.0],
            "magnitudes": [
                {"hysteresis": 0.02, "second_rc": 0.03},
                {"second_rc": 0.01, "hysteresis": 0.02},
            ],
        }
    )
    # both entries are the same two effects: m0, m1 in the order listed
    assert W.pair_names(gcfg, 1) == ["second_rc-hysteresis_m0_n0", "second_rc-hysteresis_m1_n0"]
    assert W.pair_names(gcfg, 2) == []  # control-only cells carry no pairs
    assert W.parse_name("second_rc-hysteresis_m1_n0") == ("second_rc-hysteresis", 1, 0)
    written = W.write_pair_batch(SEED, gcfg, "pulse", 1, tmp_path)
    assert [p.stem for p in written] == W.pair_names(gcfg, 1)
    meta = json.loads((tmp_path / "second_rc-hysteresis_m1_n0.json").read_text())
    assert meta["name"] == "second_rc-hysteresis_m1_n0"
    assert meta["effects"] == ["second_rc", "hysteresis"]
    assert meta["magnitudes"] == [0.01, 0.02]
    assert meta["noise_mv"] == 2.0
    # second_rc 0.01 at 2 mV is the grid's second_rc_m0_n1; no hysteresis in the grid
    assert meta["alone"]["second_rc"]["dataset"] == "second_rc_m0_n1"
    assert meta["alone"]["hysteresis"]["dataset"] is None
    head = (tmp_path / "second_rc-hysteresis_m0_n0.csv").read_text().splitlines()[0]
    assert head == "time_s,current_a,voltage_v,temperature_c"


def test_plan_lists_the_pair_records_and_their_table():
    gcfg = _gcfg({"noise_mv": [1.0, 2.0], "magnitudes": [{"second_rc": 0.03, "thermal": 1e4}]})
    gcfg["profiles"] = ["pulse", "drive"]
    plan = plan_mod.gap(gcfg)
    assert plan["pair_names"] == ["second_rc-thermal_m0_n0", "second_rc-thermal_m0_n1"]
    assert plan["pair_records"] == [
        "pulse/r1/second_rc-thermal_m0_n0",
        "pulse/r1/second_rc-thermal_m0_n1",
        "drive/r1/second_rc-thermal_m0_n0",
        "drive/r1/second_rc-thermal_m0_n1",
    ]
    assert "results/gap/pairs.csv" in plan["outputs"]
    assert not set(plan["pair_records"]) & set(plan["records"])
    without = plan_mod.gap({k: v for k, v in gcfg.items() if k != "pairs"})
    assert without["pair_records"] == []
    assert "results/gap/pairs.csv" not in without["outputs"]


# --- the judgement on hand-made diagnoses ------------------------------------------------------


def _diagnosis(*rungs):
    """A diagnosis dict as diagnose() writes it: a ladder whose rung k holds the first k effects."""
    ladder = [{"effect": e, "effects": list(rungs[: k + 1])} for k, e in enumerate(rungs)]
    verdict = {"effect": rungs[0] if rungs else "none", "shrink": 0.5 if rungs else 0.0}
    return {"verdict": verdict, "ladder": ladder, "wall_s": 1.0}


def _pair_meta(name, a, b, ratio_a, ratio_b, noise=1.0):
    return {
        "name": name,
        "profile": "pulse",
        "replicate": 1,
        "effects": [a, b],
        "magnitudes": [0.03, 0.02],
        "noise_mv": noise,
        "noise_rmse_mv": noise,
        "raw_residual_mv": 9.0,
        "effect_residual_mv": 5.0,
        "alone": {
            a: {"effect_residual_mv": ratio_a * noise, "noise_rmse_mv": noise, "dataset": None},
            b: {"effect_residual_mv": ratio_b * noise, "noise_rmse_mv": noise},
        },
    }


CASES = [
    # name, alone ratios, ladder, both named, extra
    ("both", (4.0, 3.0), ("hysteresis", "second_rc"), True, ""),
    ("one_missing", (4.0, 3.0), ("second_rc",), False, ""),
    ("extra", (4.0, 3.0), ("second_rc", "thermal", "hysteresis"), True, "thermal"),
    ("wrong", (4.0, 2.0), ("ocv_shape",), False, "ocv_shape"),
    ("nothing", (5.0, 1.6), (), False, ""),
    ("faint", (4.0, 1.4), ("second_rc", "voltage_offset"), False, "voltage_offset"),
]


def _pair_files(tmp_path):
    files = []
    for name, (ra, rb), rungs, _, _ in CASES:
        d, g = tmp_path / f"{name}.json", tmp_path / f"{name}.diagnosis.json"
        d.write_text(json.dumps(_pair_meta(name, "second_rc", "hysteresis", ra, rb)))
        g.write_text(json.dumps(_diagnosis(*rungs)))
        files.append((d, g))
    return files


def test_final_effects_and_judge_pair():
    assert ev.final_effects(_diagnosis()) == []
    assert ev.final_effects(_diagnosis("thermal", "second_rc")) == ["thermal", "second_rc"]
    # since pruning: the selected model, which may hold fewer elements than the last rung
    pruned = {**_diagnosis("current_offset", "hysteresis", "ocv_shape"),
              "selected": {"effects": ["hysteresis", "ocv_shape"]},
              "pruned": [{"effect": "current_offset"}]}  # fmt: skip
    assert ev.final_effects(pruned) == ["hysteresis", "ocv_shape"]
    j = ev.judge_pair(("second_rc", "hysteresis"), ["hysteresis", "thermal"])
    assert j == {"missing": ["second_rc"], "extra": ["thermal"]}
    both = ev.judge_pair(("second_rc", "hysteresis"), ["hysteresis", "second_rc"])
    assert both == {"missing": [], "extra": []}
    nothing = ev.judge_pair(("second_rc", "hysteresis"), [])
    assert nothing == {"missing": ["second_rc", "hysteresis"], "extra": []}
    beyond = ev.judge_pair(("second_rc", "hysteresis"), ["second_rc", "hysteresis", "rc3"])
    assert beyond == {"missing": [], "extra": ["rc3"]}


def test_pair_records_are_judged_as_defined(tmp_path):
    rows = [ev.pair_record(d, g) for d, g in _pair_files(tmp_path)]
    df = ev.with_pair_judgement(pd.DataFrame(rows, columns=list(ev.PAIR_COLUMNS))).set_index("name")
    for name, (ra, rb), rungs, both, extra in CASES:
        row = df.loc[name]
        assert row["ratio_a"] == pytest.approx(ra)
        assert row["ratio_b"] == pytest.approx(rb)
        assert row["both_named"] == both, name
        assert row["extra"] == extra, name
        assert row["nothing_extra"] == (extra == ""), name
        assert row["final_effects"] == " ".join(rungs)
        # clearly detectable: each effect alone >= 1.5 x noise (1.4 is not, 1.6 is)
        assert row["clearly_detectable"] == (min(ra, rb) >= 1.5), name
    assert df.loc["one_missing", "missing"] == "hysteresis"
    assert df.loc["nothing", "verdict"] == "none"
    assert df.loc["both", "ladder"] == "hysteresis > second_rc"


def test_pair_target_counts_the_clearly_detectable_records(tmp_path):
    rows = [ev.pair_record(d, g) for d, g in _pair_files(tmp_path)]
    df = ev.with_pair_judgement(pd.DataFrame(rows, columns=list(ev.PAIR_COLUMNS)))
    t = ev.pair_target(df)
    # clearly detectable: both, one_missing, extra, wrong, nothing (faint is out)
    assert list(t["n"]) == [5, 5, 6]
    assert list(t["right"]) == [2, 3, 2]  # both named: both, extra; nothing extra: all but 2
    assert list(t["required"]) == [1.0, 0.9, 1.0]
    assert list(t["result"]) == ["FAIL", "FAIL", "FAIL"]
    assert t.loc[0, "ci95_low"] < 0.4 < t.loc[0, "ci95_high"]
    good = df.assign(missing="", extra="")
    good = ev.with_pair_judgement(good)
    assert list(ev.pair_target(good)["result"]) == ["PASS", "PASS", "PASS"]
    # one extra in ten clearly detectable records still meets the >= 90 % goal
    ten = ev.with_pair_judgement(
        pd.concat([good.iloc[[0]]] * 10, ignore_index=True).assign(extra=["thermal"] + [""] * 9)
    )
    assert list(ev.pair_target(ten)["result"][:2]) == ["PASS", "PASS"]
    assert ev.pair_target(ten).loc[1, "measured"] == pytest.approx(0.9)


def test_pair_table_and_target_rows_from_files(tmp_path):
    files = _pair_files(tmp_path)
    out_csv = tmp_path / "out" / "pairs.csv"
    gap_jobs.pair_table_job([d for d, _ in files], [g for _, g in files], out_csv, 1.5)
    table = pd.read_csv(out_csv)
    assert len(table) == len(CASES)
    assert table["both_named"].sum() == 2
    # the pair targets join the single-effect targets in target.csv
    single = tmp_path / "single.json"
    single.write_text(
        json.dumps(
            {
                "name": "s",
                "profile": "pulse",
                "replicate": 1,
                "effect": "none",
                "magnitude": 0.0,
                "magnitude_unit": "",
                "noise_mv": 1.0,
                "noise_rmse_mv": 1.0,
                "raw_residual_mv": 0.0,
                "effect_residual_mv": 0.0,
                "n_samples": 100,
            }
        )
    )
    diag = tmp_path / "single.diagnosis.json"
    diag.write_text(json.dumps(_diagnosis()))
    out = {k: tmp_path / "out" / f"{k}.csv" for k in plan_mod.GAP_TABLES}
    gap_jobs.evaluate_job([single], [diag], out, 1.5, pairs_csv=[out_csv])
    target = pd.read_csv(out["target"])
    assert len(target) == 3 + 3
    assert target["check"].str.startswith("pairs:").sum() == 3
    assert list(target["result"][3:]) == ["FAIL", "FAIL", "FAIL"]
    gap_jobs.evaluate_job([single], [diag], out, 1.5)
    assert len(pd.read_csv(out["target"])) == 3
