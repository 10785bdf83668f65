"""The withheld-effect generator and the evaluation tables (no diagnosis needed: verdict lists
are made by hand here)."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest

from avoa_pipeline.errors import ConfigError
from avoa_pipeline.gap import EFFECTS, VERDICTS, diagnoses
from avoa_pipeline.gap import evaluate as ev
from avoa_pipeline.gap import withheld as W
from avoa_pipeline.report import gap_figures

SEED = 7
# a magnitude per effect that is clearly visible, in the unit of W.UNITS
VISIBLE = {
    "second_rc": 0.03,
    "hysteresis": 0.02,
    "butler_volmer": 0.1,
    "thermal": 30000.0,
    "ocv_shape": 0.03,
    "current_offset": 0.05,
    "voltage_offset": 0.03,
    "coulombic_efficiency": 0.05,
}


def _frame(ds):
    return ds.frame()


@pytest.mark.parametrize("effect", EFFECTS)
def test_zero_magnitude_reproduces_the_control_exactly(effect):
    control = W.make(SEED, "none", 0.0, 2.0, "drive", 1)
    zero = W.make(SEED, effect, 0.0, 2.0, "drive", 1)
    pd.testing.assert_frame_equal(_frame(zero), _frame(control), check_exact=True)
    assert zero.meta["raw_residual_mv"] == 0.0
    assert zero.meta["effect_residual_mv"] == 0.0


@pytest.mark.parametrize("effect", EFFECTS)
def test_effect_changes_the_data_and_its_residual_grows_with_magnitude(effect):
    control = W.make(SEED, "none", 0.0, 1.0, "drive", 1)
    small = W.make(SEED, effect, VISIBLE[effect] / 4, 1.0, "drive", 1)
    large = W.make(SEED, effect, VISIBLE[effect], 1.0, "drive", 1)
    # the logged current stays the profile's even under current_offset (the cell's current
    # differs), so it is the voltage that changes in every case
    np.testing.assert_array_equal(large.current_a, control.current_a)
    assert not np.array_equal(large.voltage_v, control.voltage_v)
    assert 0 < small.meta["raw_residual_mv"] < large.meta["raw_residual_mv"]
    # (1 µV of slack: the refit of an absorbed effect ends at the optimizer's tolerance)
    assert small.meta["effect_residual_mv"] <= large.meta["effect_residual_mv"] + 1e-3
    assert small.meta["effect_residual_mv"] <= small.meta["raw_residual_mv"] + 1e-9


def test_refit_residual_is_what_the_base_model_cannot_absorb():
    # a constant voltage offset is a Möbius function of charge plus a constant, which is again
    # Möbius: the rational OCV with free SOC0 and Q absorbs it exactly
    off = W.make(SEED, "voltage_offset", 0.05, 1.0, "drive", 1)
    assert off.meta["raw_residual_mv"] == pytest.approx(50.0)
    assert off.meta["effect_residual_mv"] < 0.05
    # a temperature-driven resistance cannot be absorbed by constant resistances
    th = W.make(SEED, "thermal", 30000.0, 1.0, "drive", 1)
    assert th.meta["effect_residual_mv"] > 0.5 * th.meta["raw_residual_mv"]


def test_generator_is_deterministic_per_seed():
    a = W.make(SEED, "hysteresis", 0.01, 2.0, "pulse", 3)
    W._noise_free.cache_clear()
    b = W.make(SEED, "hysteresis", 0.01, 2.0, "pulse", 3)
    pd.testing.assert_frame_equal(_frame(a), _frame(b), check_exact=True)
    assert a.meta == b.meta
    c = W.make(SEED + 1, "hysteresis", 0.01, 2.0, "pulse", 3)
    assert not np.array_equal(a.voltage_v, c.voltage_v)
    d = W.make(SEED, "hysteresis", 0.01, 2.0, "pulse", 4)
    assert a.meta["cell"] != d.meta["cell"]


@pytest.mark.parametrize("profile", W.PROFILES)
def test_datasets_carry_a_varying_temperature_and_plausible_records(profile):
    ds = W.make(SEED, "thermal", 20000.0, 1.0, profile, 1)
    assert ds.temperature_c.max() - ds.temperature_c.min() > 5.0
    assert 5_000 <= ds.time_s.size <= 15_000
    assert np.all(np.diff(ds.time_s) == 1.0)
    assert (ds.current_a > 0).any()
    assert (ds.current_a < 0).any()
    assert ds.voltage_v.min() > 3.0
    assert ds.voltage_v.max() < 4.4
    assert ds.meta["noise_rmse_mv"] == pytest.approx(1.0, rel=0.1)
    control = W.make(SEED, "none", 0.0, 1.0, profile, 1)
    np.testing.assert_array_equal(ds.temperature_c, control.temperature_c)


def test_unknown_effect_or_profile_or_negative_magnitude_is_a_config_error():
    with pytest.raises(ConfigError, match="unknown effect 'bogus'"):
        W.make(SEED, "bogus", 0.1, 1.0, "drive", 1)
    with pytest.raises(ConfigError, match="unknown profile 'wltp'"):
        W.make(SEED, "second_rc", 0.1, 1.0, "wltp", 1)
    with pytest.raises(ConfigError, match="must be >= 0"):
        W.make(SEED, "second_rc", -0.1, 1.0, "drive", 1)


def test_batch_writes_the_grid_with_sidecars(tmp_path):
    gcfg = {
        "replicates": [1],
        "control_replicates": [1, 2],
        "noise_mv": [1.0, 3.0],
        "magnitudes": {e: [VISIBLE[e]] for e in EFFECTS},
    }
    assert W.all_replicates(gcfg) == [1, 2]
    assert W.names(gcfg, 2) == ["none_m0_n0", "none_m0_n1"]
    names = W.names(gcfg, 1)
    assert len(names) == 2 + len(EFFECTS) * 2
    written = W.write_batch(SEED, gcfg, "pulse", 1, tmp_path)
    assert [p.stem for p in written] == names
    meta = json.loads((tmp_path / "thermal_m0_n1.json").read_text())
    assert meta["effect"] == "thermal"
    assert meta["noise_mv"] == 3.0
    assert meta["name"] == "thermal_m0_n1"
    head = (tmp_path / "thermal_m0_n1.csv").read_text().splitlines()[0]
    assert head == "time_s,current_a,voltage_v,temperature_c"
    assert W.parse_name("coulombic_efficiency_m3_n1") == ("coulombic_efficiency", 3, 1)


# --- evaluation on hand-made verdicts ----------------------------------------------------------


def _hand_made() -> pd.DataFrame:
    rows = [
        # effect, verdict, ratio, shrink, noise
        ("second_rc", "second_rc", 5.0, 0.6, 1.0),
        ("second_rc", "hysteresis", 2.0, 0.2, 1.0),
        ("second_rc", "none", 0.2, 0.0, 1.0),
        ("thermal", "thermal", 9.0, 0.8, 4.0),
        ("thermal", "thermal", 1.6, 0.3, 4.0),
        ("none", "none", 0.0, 0.0, 1.0),
        ("none", "none", 0.0, 0.0, 4.0),
        ("none", "voltage_offset", 0.0, 0.05, 4.0),
        ("none", "none", 0.0, 0.0, 4.0),
    ]
    df = pd.DataFrame(rows, columns=["effect", "verdict", "ratio", "shrink", "noise_mv"])
    df["raw_ratio"] = 2 * df["ratio"]
    df["effect_residual_mv"] = df["ratio"] * df["noise_mv"]
    return ev.with_judgement(df)


def test_confusion_counts_every_pair_in_order():
    c = ev.confusion(_hand_made())
    assert list(c.index) == list(VERDICTS)
    assert list(c.columns) == list(diagnoses())  # what the diagnosis can name
    assert c.loc["second_rc", "second_rc"] == 1
    assert c.loc["second_rc", "hysteresis"] == 1
    assert c.loc["second_rc", "none"] == 1
    assert c.loc["thermal", "thermal"] == 2
    assert c.loc["none", "none"] == 3
    assert c.loc["none", "voltage_offset"] == 1
    assert c.to_numpy().sum() == 9
    assert c.loc["hysteresis"].sum() == 0


def test_accuracy_and_targets_follow_the_definitions():
    df = _hand_made()
    acc = ev.accuracy(df).set_index("effect")
    assert acc.loc["second_rc", "accuracy"] == pytest.approx(1 / 3)
    # detectable: ratio >= 1.5 -> the 5.0 (right) and the 2.0 (wrong) second_rc datasets
    assert acc.loc["second_rc", "n_detectable"] == 2
    assert acc.loc["second_rc", "accuracy_detectable"] == pytest.approx(0.5)
    assert acc.loc["second_rc", "called_other"] == pytest.approx(1 / 3)
    assert acc.loc["thermal", "accuracy_detectable"] == 1.0
    assert acc.loc["none", "accuracy"] == pytest.approx(0.75)
    assert acc.loc["all effects", "n_detectable"] == 4
    assert acc.loc["all effects", "accuracy_detectable"] == pytest.approx(0.75)
    assert np.isnan(acc.loc["hysteresis", "accuracy"])
    rows = ev.target(df)
    assert list(rows["result"]) == ["FAIL", "FAIL", "FAIL"]
    assert rows.loc[0, "measured"] == pytest.approx(0.75)
    assert rows.loc[0, "n"] == 4
    assert rows.loc[1, "measured"] == pytest.approx(0.75)
    assert rows.loc[1, "n"] == 4
    assert rows.loc[2, "n"] == 4  # raw ratio 2x: the 0.2 one stays below 1.5 too
    assert rows.loc[0, "ci95_low"] < 0.75 < rows.loc[0, "ci95_high"]
    good = ev.with_judgement(df.assign(verdict=df["effect"]))
    assert list(ev.target(good)["result"]) == ["PASS", "PASS", "PASS"]


def test_detection_limit_bins_by_ratio_and_noise():
    dl = ev.detection_limit(_hand_made())
    allrow = dl[(dl["effect"] == "all effects") & (dl["noise_mv"] == "all")].set_index("ratio_bin")
    assert allrow["n"].sum() == 5
    assert allrow.loc["[0, 0.5)", "n"] == 1
    assert allrow.loc["[0, 0.5)", "called_none"] == 1.0
    assert allrow.loc["[1.5, 3)", "n"] == 2
    assert allrow.loc["[1.5, 3)", "accuracy"] == 0.5
    assert allrow.loc["[3, 10)", "n"] == 2
    assert allrow.loc["[3, 10)", "accuracy"] == 1.0
    th4 = dl[(dl["effect"] == "thermal") & (dl["noise_mv"] == "4")]
    assert th4["n"].sum() == 2


def test_shrink_distribution_and_unknown_verdicts():
    sh = ev.shrink_distribution(_hand_made()).set_index(["effect", "verdict_right"])
    assert sh.loc[("thermal", True), "n"] == 2
    assert sh.loc[("thermal", True), "q50"] == pytest.approx(0.55)
    assert sh.loc[("none", False), "n"] == 1
    bad = _hand_made().assign(verdict="maybe")
    with pytest.raises(ValueError, match="maybe"):
        ev.with_judgement(bad)


def test_evaluate_writes_every_table_from_files(tmp_path):
    pairs = []
    for k, (effect, verdict) in enumerate([("thermal", "thermal"), ("none", "none")]):
        meta = {
            "name": f"d{k}",
            "profile": "drive",
            "replicate": 1,
            "effect": effect,
            "magnitude": 1.0,
            "magnitude_unit": "",
            "noise_mv": 1.0,
            "noise_rmse_mv": 1.0,
            "raw_residual_mv": 3.0,
            "effect_residual_mv": 2.0 if effect != "none" else 0.0,
            "n_samples": 100,
        }
        diag = {"verdict": {"effect": verdict, "shrink": 0.5}, "base": {"rmse_mv": 1.2}}
        d, g = tmp_path / f"d{k}.json", tmp_path / f"g{k}.json"
        d.write_text(json.dumps(meta))
        g.write_text(json.dumps(diag))
        pairs.append((d, g))
    keys = ("records", "confusion", "accuracy", "detection_limit", "shrink", "target")
    out = {k: tmp_path / "out" / f"{k}.csv" for k in keys}
    df = ev.evaluate(pairs, out)
    assert df["right"].all()
    for path in out.values():
        assert path.stat().st_size > 0
    target = pd.read_csv(out["target"])
    assert list(target["result"][:2]) == ["PASS", "PASS"]


def test_paper_scenarios_fade_is_absorbed_by_the_base_model(tmp_path):
    from avoa_pipeline import config

    cfg = config.load()
    fade = ev.paper_dataset(cfg, 2, 2, tmp_path / "s2c2.csv")
    # fade is a new parameter set of the same model: nothing is left after the refit
    assert fade["raw_residual_mv"] > 10.0
    assert fade["effect_residual_mv"] < 0.01
    load = ev.paper_dataset(cfg, 3, 2, tmp_path / "s3c2.csv")
    assert 0.0 < load["effect_residual_mv"] < load["raw_residual_mv"]
    meta = json.loads((tmp_path / "s3c2.json").read_text())
    assert meta["gap"]["expected"] == "current_offset"
    diag = tmp_path / "d.json"
    diag.write_text(json.dumps({"verdict": {"effect": "none", "shrink": 0.0}}))
    row = ev.paper_record(tmp_path / "s3c2.json", diag)
    # a load current the base model absorbs below 1.5 x noise cannot be asked of a diagnosis
    assert row["detectable"] == (load["effect_residual_mv"] >= 1.5 * load["noise_rmse_mv"])
    assert row["as_expected"] == ("none" in row["acceptable_verdicts"].split())


def test_figures_are_written(tmp_path):
    df = _hand_made()
    gap_figures.fig_confusion(df, tmp_path / "c")
    gap_figures.fig_accuracy(ev.accuracy(df), tmp_path / "a")
    gap_figures.fig_shrink(df, tmp_path / "s")
    gap_figures.fig_detection_limit(ev.detection_limit(df), tmp_path / "d")
    for name in "casd":
        assert (tmp_path / f"{name}.png").read_bytes()[:4] == b"\x89PNG"
