"""The gap diagnosis: `none` on the base model's own data, the right effect on data with one
strong effect, its JSON, and the CLI's one-line errors that write nothing."""

import json

import numpy as np
import pandas as pd
import pytest
from test_ecm import TRUTH, profile_frame, with_voltage

from avoa_pipeline import inputs, records, selection
from avoa_pipeline.cli import main
from avoa_pipeline.gap import diagnose, diagnoses
from avoa_pipeline.model import ecm, heat
from avoa_pipeline.report import gap_figures as figure


@pytest.fixture(scope="module")
def base_report():
    frame = with_voltage(profile_frame(), TRUTH, noise_v=1e-3, seed=1)
    return diagnose.diagnose(frame, source="base.csv")


def test_base_model_data_gives_none(base_report):
    assert base_report["verdict"]["effect"] == "none"
    assert base_report["ladder"] == []
    # quantised 1 mV noise: sqrt(1 + 1/12) = 1.04 mV
    assert base_report["base"]["noise_floor_mv"] == pytest.approx(1.04, rel=0.1)
    assert base_report["base"]["rmse_mv"] == pytest.approx(1.04, rel=0.1)


def test_report_keys_and_json(base_report):
    r = base_report
    assert {"base", "localization", "candidates", "verdict", "ladder"} <= r.keys()
    assert {"parameters", "rmse_mv", "noise_floor_mv"} <= r["base"].keys()
    for region in r["localization"]:
        assert {"region", "share", "rmse_mv"} <= region.keys()
    groups = {reg["group"] for reg in r["localization"]}
    assert {"mode", "direction", "since_step", "soc", "current", "temperature"} <= groups
    assert sorted(c["effect"] for c in r["candidates"]) == sorted(ecm.EFFECTS)
    for c in r["candidates"]:
        if c["applicable"]:
            assert {"effect", "heldout_rmse_mv", "shrink", "delta_bic"} <= c.keys()
    skipped = {c["effect"]: c["reason"] for c in r["candidates"] if not c["applicable"]}
    # the profile has charge and a moving temperature; three elements need another first
    assert skipped == {"third_rc": "needs second_rc first",
                       "bv_arrhenius": "needs butler_volmer first",
                       "thermal_tau": "needs thermal first"}  # fmt: skip
    assert r["verdict"]["effect"] in diagnoses()
    assert sum(reg["share"] for reg in r["localization"] if reg["group"] == "mode") == (
        pytest.approx(1.0)
    )
    json.dumps(r, allow_nan=False)


def test_thermal_needs_a_varying_temperature():
    frame = with_voltage(profile_frame(temperature=False), TRUTH, noise_v=1e-3)
    rec = ecm.Record.from_frame(frame)
    assert selection.applicable([rec], "thermal") == (False, "no temperature_c column")


@pytest.fixture(scope="module")
def second_rc_run(tmp_path_factory):
    truth = {**TRUTH, "r2_ohm": 0.01, "tau2_s": 1000.0}
    frame = with_voltage(profile_frame(), truth, noise_v=1e-3, seed=2)
    path = tmp_path_factory.mktemp("rc") / "rc.csv"
    frame.to_csv(path, index=False)
    out = path.parent / "out"
    assert main(["diagnose", str(path), "--out", str(out)]) == 0
    return json.loads((out / "diagnosis.json").read_text()), out


def test_cli_finds_a_second_rc_branch(second_rc_run):
    report, out = second_rc_run
    assert report["verdict"]["effect"] == "second_rc"
    assert report["verdict"]["shrink"] > 0.5
    assert report["verdict"]["heldout_rmse_after_mv"] < 1.2  # down to the noise
    assert report["ladder"][0]["effect"] == "second_rc"
    assert (out / "diagnosis.png").stat().st_size > 10_000


def test_strong_hysteresis_is_found():
    truth = {**TRUTH, "hysteresis_m_v": 0.01, "hysteresis_gamma": 100.0}
    frame = with_voltage(profile_frame(), truth, noise_v=1e-3, seed=3)
    report = diagnose.diagnose(frame)
    assert report["verdict"]["effect"] == "hysteresis"
    row = next(c for c in report["candidates"] if c["effect"] == "hysteresis")
    assert row["pays"]
    assert row["delta_bic"] < -10


def _csv(tmp_path, frame, name="d.csv"):
    path = tmp_path / name
    frame.to_csv(path, index=False)
    return path


def _good(n=3000):
    frame = profile_frame([(300, 0.0), (1200, 2.0), (600, 0.0), (600, -1.5), (n - 2700, 0.0)])
    return with_voltage(frame, TRUTH, noise_v=1e-3)


def _bad_inputs():
    g = _good()
    nan = g.copy()
    nan.loc[10, "voltage_v"] = np.nan
    back = g.copy()
    back.loc[20, "time_s"] = 5.0
    ma = g.copy()
    ma["current_a"] *= 1000.0
    mv = g.copy()
    mv["voltage_v"] *= 1000.0
    return {
        "missing column": (g.drop(columns="voltage_v"), [], "voltage_v"),
        "NaN": (nan, [], "voltage_v"),
        "time backwards": (back, [], "time_s"),
        "too short": (g.iloc[:1500], [], "samples"),
        # mA without a capacity: a warning, not a refusal (test_units: the records cannot tell
        # mA of a small cell from A of a large one); with the capacity, refused
        "current in mA": (ma, ["--capacity-ah", "2.57"], "mA"),
        "voltage in mV": (mv, [], "voltage_v"),
        "capacity <= 0": (g, ["--capacity-ah", "0"], "capacity"),
        "capacity not a number": (g, ["--capacity-ah", "x"], "capacity"),
        "soc0 > 1": (g, ["--soc0", "1.5"], "soc0"),
        "soc0 < 0": (g, ["--soc0", "-0.1"], "soc0"),
        "mA for the capacity": (
            g.assign(current_a=g["current_a"] * 40),
            ["--capacity-ah", "1"],
            "mA",
        ),
    }


@pytest.mark.parametrize("case", list(_bad_inputs()))
def test_cli_bad_input_one_line_exit_2_nothing_written(tmp_path, capsys, case):
    frame, extra, word = _bad_inputs()[case]
    path = _csv(tmp_path, frame)
    out = tmp_path / "out"
    assert main(["diagnose", str(path), "--out", str(out), *extra]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1
    assert err.startswith("error: ")
    assert word in err
    assert not out.exists()


def test_missing_file_is_one_line(tmp_path, capsys):
    assert main(["diagnose", str(tmp_path / "nope.csv"), "--out", str(tmp_path / "o")]) == 2
    assert "no such file" in capsys.readouterr().err


def test_figure_failure_writes_no_json(tmp_path, monkeypatch):
    path = _csv(tmp_path, _good())
    fake = ({"verdict": {"effect": "none"}}, {}, None)
    monkeypatch.setattr(diagnose, "diagnose_records", lambda *a, **k: fake)
    # the fake has no model to fit a heat block to (the pipeline fits it before writing)
    monkeypatch.setattr(heat, "attach", lambda model, checked: "no heat block (test)")
    monkeypatch.setattr(heat, "block_summary", lambda model, line: {"written": False})

    def broken(*args, **kwargs):
        raise RuntimeError("figure failed")

    monkeypatch.setattr(figure, "render", broken)
    with pytest.raises(RuntimeError):
        main(["diagnose", str(path), "--out", str(tmp_path / "out")])
    assert not (tmp_path / "out" / "diagnosis.json").exists()
    assert not list((tmp_path / "out").glob("*"))


def test_diagnose_rejects_a_frame_in_milliamperes():
    # with the capacity known (without it the records cannot tell mA from a large cell's A)
    frame = _good()
    frame["current_a"] *= 1000.0
    with pytest.raises(diagnose.UserError, match="mA"):
        diagnose.diagnose(frame, capacity_ah=2.57, source="frame")


def test_noise_floor_ignores_smooth_misfit():
    rec = ecm.Record.from_frame(_good())
    rng = np.random.default_rng(0)
    smooth = 0.005 * np.sin(rec.t / 300.0)
    est = diagnose.noise_floor(rec, smooth + 0.002 * rng.standard_normal(rec.n))
    assert est == pytest.approx(0.002, rel=0.05)


def test_frame_input_accepts_no_temperature():
    frame = _good().drop(columns="temperature_c")
    checked = records.check(frame, "f").frame
    assert list(checked.columns) == ["time_s", "current_a", "voltage_v"]
    assert isinstance(checked, pd.DataFrame)


@pytest.mark.parametrize("per_fold", [1, 4])
def test_one_record_is_held_out_in_interleaved_blocks(per_fold):
    lay = selection.Layout.of([2003], 5, per_fold)
    assert not lay.by_record
    assert len(lay.folds) == 5
    np.testing.assert_array_equal(np.sort(np.concatenate(lay.folds)), np.arange(2003))
    for fold in lay.folds:  # each fold: per_fold blocks, spread over the record
        assert len(np.flatnonzero(np.diff(fold) > 1)) == per_fold - 1
    for batch in lay.batches:
        assert np.all(np.diff(batch) == 1)  # contiguous
    assert len(lay.batches) == 5 * selection.BATCHES_PER_FOLD


def test_several_records_are_held_out_whole_and_weigh_alike():
    """Leave one record out: each fold is one whole record; each record gets the same number of
    batches, and the records-alike weights make each record's mean squared error count once."""
    sizes = [2003, 997, 5000]
    lay = selection.Layout.of(sizes)
    assert lay.by_record
    assert [f.size for f in lay.folds] == sizes
    np.testing.assert_array_equal(np.concatenate(lay.folds), np.arange(sum(sizes)))
    record_of = np.repeat(np.arange(len(sizes)), sizes)
    counts = np.bincount([record_of[b[0]] for b in lay.batches])
    assert list(counts) == [selection.BATCHES_PER_RECORD] * 3
    for batch in lay.batches:
        assert len(set(record_of[batch])) == 1
    np.testing.assert_array_equal(lay.fold_of(), record_of)
    frames = [profile_frame([(n, 0.0)], temperature=False) for n in sizes]
    ctx = selection.Context([ecm.Record.from_frame(f.assign(voltage_v=3.7)) for f in frames])
    for r in range(len(sizes)):  # each record's weights sum to n_total / R
        assert ctx.w[record_of == r].sum() == pytest.approx(sum(sizes) / 3)


def test_loss_tests_see_a_systematic_gain_and_ignore_noise():
    rng = np.random.default_rng(0)
    n = 5000
    batches = selection.Layout.of([n]).batches
    a = rng.standard_normal(n) ** 2
    same = selection.batch_rank_test(a, rng.standard_normal(n) ** 2, batches)[1]
    better = selection.batch_rank_test(a, 0.8 * a, batches)[1]
    assert same > 0.01
    assert better < 1e-6
    t, _, se = selection.loss_test(a, 0.8 * a, batches)
    assert t > 10
    assert se > 0


def test_charge_positive_record_is_refused_with_the_fix(tmp_path, capsys):
    """A record whose voltage rises with positive current is the other cycler convention: one
    line naming the flag that fixes it; with the flag the same file is accepted."""
    flipped = _good().assign(current_a=lambda f: -f["current_a"])
    path = _csv(tmp_path, flipped)
    out = tmp_path / "out"
    assert main(["diagnose", str(path), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1
    assert "current_a" in err
    assert "--current-sign charge-positive" in err
    assert not out.exists()
    checked = inputs.read_record(path, current_sign="charge-positive").frame
    np.testing.assert_allclose(checked["current_a"], _good()["current_a"])


def _slow_test(rate_c=0.05, capacity=2.57, charge_ah=None, share=1.0):
    """A discharge at ``rate_c`` from full of ``share`` of the capacity, a rest, a charge back
    (of ``charge_ah``)."""
    i = rate_c * capacity
    n_d = int(share * 3600 / rate_c)
    n_c = int(3600 * (charge_ah or capacity) / i)
    cur = np.concatenate([np.zeros(60), np.full(n_d, i), np.zeros(600), np.full(n_c, -i)])
    t = np.arange(cur.size, dtype=float)
    frame = pd.DataFrame({"time_s": t, "current_a": cur, "voltage_v": np.zeros_like(t)})
    truth = {**TRUTH, "soc0": 1.0}
    return with_voltage(frame, truth)


def test_ocv_from_a_slow_test_recovers_the_cells_curve(tmp_path):
    """Both branches of a C/20 test, averaged: the OCV within the ohmic and RC drop that the
    averaging cancels to first order; the capacity from the discharge branch."""
    # the test stops at 3 % SOC (the paper's rational OCV falls to 0 V at empty): the table's
    # SOC 0-1 spans 97 % of the cell
    path = _csv(tmp_path, _slow_test(share=0.97, charge_ah=0.97 * 2.57), "c20.csv")
    table = inputs.read_ocv(path)
    assert "mean of the discharge" in table.how
    assert table.capacity_ah == pytest.approx(0.97 * 2.57, rel=1e-3)
    assert table.notes == ()  # it ends in the knee of the curve
    P = ecm.to_physical(ecm.vector(TRUTH))[0]
    soc = np.linspace(0.1, 0.9, 9)
    true = ecm.ocv_values(P, 1.0 - 0.97 * (1.0 - soc), ecm.Knots(0, 0.2), None)
    assert np.max(np.abs(table(soc) - true)) < 2e-3
    # a charge cut short: its branch spans another SOC range, so the discharge goes alone
    short = inputs.read_ocv(_csv(tmp_path, _slow_test(share=0.97, charge_ah=2.0), "c20s.csv"))
    assert short.how.startswith("discharge branch alone")


def test_bad_ocv_and_validation_inputs_are_one_line_errors(tmp_path, capsys):
    good = _csv(tmp_path, _good())
    fast = _csv(tmp_path, _slow_test(rate_c=1.0, share=0.8, charge_ah=0.8 * 2.57), "fast.csv")
    other = _csv(tmp_path, _good().drop(columns="temperature_c"), "other.csv")
    neither = tmp_path / "neither.csv"
    neither.write_text("a,b\n1,2\n3,4\n")
    cases = [
        (["--ocv", str(fast)], "no slow branch"),
        (["--ocv", str(neither)], "need columns 'soc', 'ocv_v'"),
        (["--validate", str(other)], "differ from the training"),
    ]
    for extra, word in cases:
        out = tmp_path / "out"
        assert main(["diagnose", str(good), "--out", str(out), *extra]) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1, err
        assert word in err, err
        assert not out.exists()


def test_simulate_predicts_from_model_json_and_refuses_a_tampered_one(second_rc_run, tmp_path,
                                                                      capsys):  # fmt: skip
    report, out = second_rc_run
    model = json.loads((out / "model.json").read_text())
    assert model["effects"] == report["selected"]["effects"] == ["second_rc"]
    data = _csv(tmp_path, with_voltage(profile_frame(), {**TRUTH, "r2_ohm": 0.01,
                                                          "tau2_s": 1000.0}, seed=5))  # fmt: skip
    pred = tmp_path / "pred.csv"
    assert main(["simulate", str(out / "model.json"), str(data), "--out", str(pred)]) == 0
    got = pd.read_csv(pred)
    assert list(got.columns) == ["time_s", "voltage_v", "model_v", "error_mv",
                                 "temperature_c_model", "temperature_source",
                                 "temperature_c"]  # fmt: skip
    assert len(got) == len(pd.read_csv(data))
    assert np.sqrt(np.mean(got["error_mv"] ** 2)) < 2.0  # the same cell: about the noise
    capsys.readouterr()
    model["parameters"]["r2_ohm"] = -1.0
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps(model))
    pred2 = tmp_path / "pred2.csv"
    assert main(["simulate", str(bad), str(data), "--out", str(pred2)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1
    assert "r2_ohm" in err
    assert not pred2.exists()


def test_cli_takes_several_training_records_and_validation(tmp_path):
    """Two training records of one cell (each its own initial SOC) and a validation record:
    all three outputs, per-record states, and one validation row per rung."""
    a = _csv(tmp_path, _good(), "a.csv")
    other = profile_frame([(300, 0.0), (1500, 1.5), (600, 0.0), (900, -1.0), (300, 0.0)])
    b = _csv(tmp_path, with_voltage(other, {**TRUTH, "soc0": 0.7}, noise_v=1e-3, seed=7), "b.csv")
    test = _csv(tmp_path, with_voltage(profile_frame(), {**TRUTH, "soc0": 0.8}, seed=9), "t.csv")
    out = tmp_path / "out"
    assert main(["diagnose", str(a), str(b), "--out", str(out), "--validate", str(test)]) == 0
    report = json.loads((out / "diagnosis.json").read_text())
    assert {p.name for p in out.iterdir()} == {"diagnosis.json", "diagnosis.png", "model.json"}
    per = report["base"]["parameters"]["per_record"]
    assert [p["source"] for p in per] == [str(a), str(b)]
    # each record its own start (SOC itself is not identifiable with a free rational OCV)
    assert per[0]["soc0"] - per[1]["soc0"] > 0.1
    rungs = 1 + len(report["ladder"])
    # and one row of the handed-over model (docs/handover-rule.md), named so
    assert len(report["validation"]) == rungs + 1
    assert report["validation"][-1]["model"] == "handed_over"
    assert report["validation"][-1]["effects"] == report["handed_over"]["effects"]
    assert report["validation"][0]["rmse_mv"] < 3.0  # the same cell, noise-free record
    # whole records held out: each predicted from the fit to the other
    assert report["method"]["held_out"] == "whole records (leave one out)"
    assert report["method"]["folds"] == 2
    # the floor beside every row: the selected configuration fitted to the record itself
    (floor,) = report["floors"]
    assert floor["model"] == report["selected"]["name"]
    for row in report["validation"]:
        assert row["floor_rmse_mv"] == floor["rmse_mv"]
        assert row["above_floor_mv"] == pytest.approx(row["rmse_mv"] - floor["rmse_mv"])
    assert floor["rmse_mv"] <= report["validation"][-1]["rmse_mv"] + 1e-6


def test_a_held_out_record_is_predicted_as_simulate_predicts_it():
    """Leave one record out: the held-out voltage of a record is what ``FittedModel.simulate``
    gives for it from the parameters fitted to the other record (started by the same rule)."""
    from avoa_pipeline.selection import fitted_model

    a = _good()
    other = profile_frame([(300, 0.0), (1500, 1.5), (600, 0.0), (900, -1.0), (300, 0.0)])
    b = with_voltage(other, {**TRUTH, "soc0": 0.7}, noise_v=1e-3, seed=7)
    recs = [ecm.Record.from_frame(f, tref_k=298.15) for f in (a, b)]
    ctx = selection.Context(recs)
    base = ctx.cross_validate(selection.fit_base(ctx))
    for r, frame in enumerate((a, b)):
        held = ctx.layout.folds[r]
        fold = selection.Candidate(base.st, base.fold_X[r], base.v, base.rss)
        v = fitted_model(ctx, fold).simulate(frame)
        np.testing.assert_allclose(base.ho[held], v, rtol=0, atol=1e-9)
    # and the fit that predicted record 0 saw record 1 only: its parameters differ
    assert not np.allclose(base.fold_X[0][0], base.fold_X[1][0])


def test_pruning_drops_what_no_longer_pays_and_keeps_what_does():
    """Backward pruning: a second RC branch in data that have one stays; a current offset that
    the data do not need is dropped, and the drop is reported."""
    truth = {**TRUTH, "r2_ohm": 0.01, "tau2_s": 1000.0}
    frame = with_voltage(profile_frame(), truth, noise_v=1e-3, seed=2)
    ctx = selection.Context([ecm.Record.from_frame(frame)])
    base = selection.fit_base(ctx)
    cands = selection.try_effects(ctx, base, ["second_rc"], cv=False)
    both = selection.try_effects(ctx, cands["second_rc"], ["current_offset"], cv=False)
    final = ctx.cross_validate(both["current_offset"])
    assert final.effects == ("second_rc", "current_offset")
    pruned, dropped = selection.prune(ctx, final)
    assert pruned.effects == ("second_rc",)
    assert [d["effect"] for d in dropped] == ["current_offset"]
    assert not dropped[0]["pays"]
