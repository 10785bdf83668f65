"""Experiment 1 on the model library: the C/20 table (the library's slow-test rule, written and
read back), the C/20 circuits as library configurations, the diagnosis's records in the table,
and the cross-cycle diagnostic (real/drive_cycles.py, jobs/real.py, real/cross_cycle.py)."""

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from avoa_pipeline import records
from avoa_pipeline.errors import DataError
from avoa_pipeline.jobs import real as jobs
from avoa_pipeline.model import ecm
from avoa_pipeline.model.fitted import FittedModel
from avoa_pipeline.real.experiments import cross_cycle
from avoa_pipeline.real.experiments import drive_cycles as dc

TRUTH = {"capacity_ah": 2.8, "r0_ohm": 0.03, "r1_ohm": 0.012, "tau1_s": 25.0,
         "voltage_offset_v": 0.005}  # fmt: skip


def _table():
    soc = np.linspace(0, 1, 201)
    return ecm.OcvTable.from_points(soc, 3.0 + 1.2 * soc - 0.3 * (1 - soc) ** 4, capacity_ah=2.9,
                                    source="test table", how="made up")  # fmt: skip


def _frame(n=3000, seed=0, soc0=0.95, params=None, table=None):
    """A drive-cycle-like record starting at rest, its voltage that of the circuit ``params``."""
    rng = np.random.default_rng(seed)
    cur = np.clip(np.repeat(rng.normal(1.0, 2.0, n // 10), 10), -3, 8)
    cur[:30] = 0.0
    frame = pd.DataFrame({"time_s": np.arange(n, dtype=float), "current_a": cur,
                          "voltage_v": 0.0, "temperature_c": 25.0})  # fmt: skip
    x = ecm.vector({**(params or TRUTH), "soc0": soc0})
    rec = ecm.Record.from_frame(frame)
    frame["voltage_v"] = ecm.simulate_rows(rec, x[None, :], ecm.Knots(0.0, 0.2),
                                           table or _table())[:, 0]  # fmt: skip
    return frame


def test_c20_circuits_are_library_configurations():
    for effects in dc.C20_MODELS.values():
        ecm.Config(effects, _table())  # valid elements, table OCV
    assert dc.C20_MODELS["c20_rc"] == ()
    names = ecm.Config(dc.C20_MODELS["c20_2rc_lowsoc"], _table()).names()
    assert {"r2", "ltau2", "klow", "lsig", "voff"} <= set(names)


def test_c20_fits_recover_a_known_circuit_and_keep_the_model():
    table = _table()
    train, test = _frame(seed=1, table=table), _frame(seed=2, soc0=0.9, table=table)
    rec = dc.c20_fits("25degC", train, {"other": test}, table)
    m = rec["models"]["c20_rc"]
    assert m["train_rmse_mv"] < 0.05
    # the unseen record starts at rest: the initial-SOC rule finds its start, the error is tiny
    assert m["cycles"]["other"]["rmse_mv"] < 0.2
    p = m["model"]["parameters"]
    for name, value in TRUTH.items():
        assert p[name] == pytest.approx(value, rel=2e-3, abs=2e-4), name
    # what the table draws: the stored model predicts what the fit reported
    v = FittedModel.from_json(m["model"]).simulate(test)
    assert dc.errors_mv(v, test) == pytest.approx(m["cycles"]["other"])
    assert rec["models"]["c20_2rc_lowsoc"]["effects"] == ["second_rc", "soc_resistance"]


def _slow_test(tmp_path):
    """A C/20-like record logged every 10 s: rest, 20 h of discharge at 0.145 A, rest, a charge
    that moves 10 % less."""
    soc = np.linspace(0, 1, 201)
    curve = 3.0 + 1.2 * soc - 0.3 * (1 - soc) ** 4
    step, n = 10.0, 7200
    q = n * step * 0.145 / 3600
    s_dis = 1 - np.arange(n) * step * 0.145 / 3600 / q
    n_ch = int(0.9 * n)
    s_ch = np.arange(n_ch) * step * 0.145 / 3600 / q
    cur = np.r_[np.zeros(100), np.full(n, 0.145), np.zeros(100), np.full(n_ch, -0.145)]
    volt = np.r_[np.full(100, curve[-1]), np.interp(s_dis, soc, curve) - 0.01,
                 np.full(100, curve[0]), np.interp(s_ch, soc, curve) + 0.05]  # fmt: skip
    frame = pd.DataFrame({"time_s": step * np.arange(cur.size), "current_a": cur,
                          "voltage_v": volt, "temperature_c": 25.0})  # fmt: skip
    side = {"cell": "test", "nominal_capacity_ah": 2.9, "ambient_temperature_c": 25.0,
            "test_type": "ocv_c20", "source_file": "made_up.mat", "source_sha256": "0" * 64,
            "citation": "none", "licence": "none"}  # fmt: skip
    path = tmp_path / "slow.csv"
    records.write(frame, side, path)
    return path, soc, curve, q


def test_ocv_table_is_the_slow_test_rule_written_and_read_back(tmp_path):
    path, soc, curve, q = _slow_test(tmp_path)
    out = tmp_path / "ocv" / "ocv_c20.csv"
    jobs.panasonic_ocv(path, out)
    assert list(pd.read_csv(out).columns) == ["soc", "ocv_v"]
    table = jobs.read_ocv(out)
    assert isinstance(table, ecm.OcvTable)
    assert table.capacity_ah == pytest.approx(q, rel=1e-9)
    assert "discharge branch alone" in table.how  # the charge moved 10 % less: not averaged
    assert table.source == str(path)
    grid = np.linspace(0.02, 0.98, 50)
    np.testing.assert_allclose(table(grid), np.interp(grid, soc, curve) - 0.01, atol=2e-4)
    Path(out).with_suffix(".json").unlink()
    with pytest.raises(DataError, match=r"ocv_c20\.json: no such file"):
        jobs.read_ocv(out)


def _report(records=("a.csv", "b.csv")):
    rows = []
    for model, effects in (("base", []), ("second_rc", ["second_rc"]),
                           ("second_rc+thermal", ["second_rc", "thermal"])):  # fmt: skip
        for k, r in enumerate(records):
            rows.append({"record": r, "model": model, "effects": effects,
                         "rmse_mv": 10.0 + k + len(effects), "max_err_mv": 50.0,
                         "rmse_in_training_soc_mv": 9.0, "share_in_training_soc": 0.8})  # fmt: skip
    return {"source": ["train.csv", "hppc.csv"], "ocv": {"kind": "table"}, "verdict": {},
            "ladder": [{"effect": "second_rc", "heldout_rmse_mv": 5.0},
                       {"effect": "thermal", "heldout_rmse_mv": 4.0}],
            "selected": {"name": "second_rc", "heldout_rmse_mv": 5.0}, "wall_s": 1.0,
            "validation": rows}  # fmt: skip


def test_diagnosis_record_has_every_rung_and_the_selected_one():
    rec = dc.diagnosis_record("25degC", _report(), "diagnosis", {"a.csv": "us06", "b.csv": "hwfet"})
    assert set(rec["models"]) == {"diagnosis_base", "diagnosis_second_rc",
                                  "diagnosis_second_rc+thermal", "diagnosis_selected"}  # fmt: skip
    assert rec["models"]["diagnosis_selected"] == rec["models"]["diagnosis_second_rc"]
    assert rec["models"]["diagnosis_base"]["cycles"]["hwfet"]["rmse_mv"] == 11.0
    summary, detail = dc.table([rec], {"25degC": 25.0})
    assert len(summary) == 8
    assert set(detail["rmse_in_training_soc_mv"]) == {9.0}
    with pytest.raises(DataError, match=r"^d\.json: field 'validation\.record': 'b\.csv'"):
        dc.diagnosis_record("25degC", _report(), "x", {"a.csv": "us06"}, source="d.json")
    with pytest.raises(DataError, match="field 'validation': missing"):
        dc.diagnosis_record("25degC", {**_report(), "validation": []}, "x")


def test_diagnosis_record_takes_the_handed_over_model_as_selected():
    """docs/handover-rule.md: ``<prefix>_selected`` is the model.json a user gets, the verdict's
    model ``<prefix>_verdict`` beside it."""
    report = _report()
    rows = [{**r, "model": "handed_over", "effects": ["second_rc", "thermal"], "rmse_mv": 1.0}
            for r in report["validation"] if r["model"] == "base"]  # fmt: skip
    report = {**report, "validation": report["validation"] + rows,
              "handed_over": {"name": "second_rc+thermal", "heldout_rmse_mv": 3.0}}  # fmt: skip
    rec = dc.diagnosis_record("25degC", report, "d", {"a.csv": "us06", "b.csv": "hwfet"})
    assert rec["selected"] == "second_rc+thermal"
    assert rec["verdict_selected"] == "second_rc"
    assert rec["selected_heldout_rmse_mv"] == 3.0
    assert set(rec["models"]) == {"d_base", "d_second_rc", "d_second_rc+thermal",
                                  "d_selected", "d_verdict"}  # fmt: skip
    assert rec["models"]["d_verdict"] == rec["models"]["d_second_rc"]
    assert rec["models"]["d_selected"]["cycles"]["us06"]["rmse_mv"] == 1.0


def test_jobs_names_validation_records_by_their_cycle(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "d").mkdir()
    # the diagnosis names its records as given on its command line; the table by the rule's paths
    report = _report((str(tmp_path / "c" / "us06.csv"), "c/../c/hwfet.csv"))
    (tmp_path / "d" / "diagnosis.json").write_text(json.dumps(report))
    rec = jobs.diagnosis_record("0degC", "gap", "d", {"us06": "c/us06.csv",
                                                      "hwfet": "c/hwfet.csv"})  # fmt: skip
    assert set(rec["models"]["gap_selected"]["cycles"]) == {"us06", "hwfet"}


def test_a_refused_validation_record_has_no_rows_and_is_named():
    """diagnosis.json's ``refused_validation`` (the workflow's diagnoses leave such a record out,
    docs/real-data.md "-20 °C"): no rows for it, and a diagnosis whose only unseen cycle was
    refused is still a record of the table, with no validation rows."""
    refusal = {"record": "b.csv", "refusal": "b.csv: column 'time_s': the rested voltage ..."}
    report = _report(("a.csv",))
    rec = dc.diagnosis_record("25degC", {**report, "refused_validation": [refusal]}, "d",
                              {"a.csv": "us06", "b.csv": "hwfet"})  # fmt: skip
    assert set(rec["models"]["d_selected"]["cycles"]) == {"us06"}
    assert rec["refused"] == [refusal]
    alone = dc.diagnosis_record("-20degC", {**report, "validation": [],
                                            "refused_validation": [refusal]}, "d")  # fmt: skip
    assert alone["models"] == {}
    assert dc.table([alone], {"-20degC": -20.0})[0].empty


def _unrelaxed(n_pulses=8):
    """A record whose rests end far from relaxed (a cold cell's drive-cycle stops): each 60-s
    1 A pulse moves the rested voltage 0.2 V for 1/60 Ah, 35 V per unit SOC of 2.9 Ah."""
    cur, v = [], []
    for k in range(n_pulses):
        cur += [0.0] * 60 + [1.0] * 60
        v += [4.0 - 0.2 * k] * 60 + [3.9 - 0.2 * k] * 60
    cur += [0.0] * 60
    v += [4.0 - 0.2 * n_pulses] * 60
    return pd.DataFrame({"time_s": np.arange(len(cur), dtype=float), "current_a": cur,
                         "voltage_v": v, "temperature_c": 25.0})  # fmt: skip


def test_the_workflows_diagnosis_leaves_out_a_validation_record_it_refuses():
    """``diagnosis._without_refused`` (``skip_refused_validation``): the diagnosis's own checks,
    each validation record with the training records; the refused one named in one line (file
    and field), the others kept; a fault of the training records still stops."""
    from avoa_pipeline import diagnosis, inputs
    from avoa_pipeline.errors import UserError

    train = records.check(_frame(3000, seed=1), "train.csv")
    good = records.check(_frame(3000, seed=2), "good.csv")
    bad = records.check(_unrelaxed(), "cold_us06.csv")  # passes without a capacity
    read = inputs.Inputs([train], [good, bad], None, ())
    kept, refused = diagnosis._without_refused(read, 2.9, None, None)
    assert [c.source for c in kept.validate] == ["good.csv"]
    assert [r["record"] for r in refused] == ["cold_us06.csv"]
    line = refused[0]["refusal"]
    assert line.startswith("cold_us06.csv: column 'time_s': the rested voltage")
    assert "\n" not in line
    with pytest.raises(UserError, match="--capacity-ah"):  # the training record's fault stops
        diagnosis._without_refused(read, 0.01, None, None)


def test_the_drive_cycle_table_job_gives_a_refused_cycle_no_diagnosis_rows(tmp_path):
    """``jobs.real.drive_cycle_table`` on a diagnosis that refused its temperature's only unseen
    cycle (the -20 °C US06): no rows, the diagnosis's model not drawn on the figure cycle (its
    model.json is not even read), one log line naming the refusal."""
    us06 = tmp_path / "m20_us06.csv"
    side = {k: "x" for k in records.SIDECAR_KEYS}
    records.write(_unrelaxed(), {**side, "nominal_capacity_ah": 2.9,
                                 "ambient_temperature_c": -20.0}, us06)  # fmt: skip
    refusal = {"record": str(us06), "refusal": f"{us06}: column 'time_s': the rested voltage ..."}
    (tmp_path / "d").mkdir()
    report = {**_report(()), "validation": [], "refused_validation": [refusal]}
    (tmp_path / "d" / "diagnosis.json").write_text(json.dumps(report))
    cfg = {"real": {"panasonic": {
        "temperatures": {"-20degC": {"ambient_c": -20.0,
                                     "drive_cycles": {"udds": "u.mat", "us06": "s.mat"}}},
        "experiment": {"train": {"-20degC": "udds"}, "qdis_ah": 1.45,
                       "figure_cycle": {"-20degC": "us06"}}}}}  # fmt: skip
    out, log = tmp_path / "rmse.csv", tmp_path / "log"
    jobs.drive_cycle_table(cfg, [], {"diagnosis": {"-20degC": str(tmp_path / "d")}},
                           {"-20degC/us06": str(us06)}, out, tmp_path / "runs.csv",
                           tmp_path / "pred.parquet", log)  # fmt: skip
    assert pd.read_csv(out).empty
    assert pd.read_parquet(tmp_path / "pred.parquet").empty
    lines = [x for x in log.read_text().splitlines() if x.startswith("refused")]
    assert lines == [f"refused (diagnosis -20degC), no rows: {refusal['refusal']}"]


def test_cross_cycle_separates_the_models_own_error_from_the_transfer():
    table = _table()
    a = _frame(1500, seed=6, table=table)
    b = _frame(1500, seed=7, table=table, params={**TRUTH, "r0_ohm": 0.05})  # another cell state
    models = {"base": ecm.Config((), table)}
    rows = pd.DataFrame(cross_cycle.fit_each_predict_all("25degC", {"a": a, "b": b}, models))
    assert len(rows) == 4
    assert rows["in_sample"].sum() == 2
    err = rows.set_index(["fit_on", "predict"])["rmse_mv"]
    assert err["a", "a"] < 0.2
    assert err["b", "b"] < 0.2
    assert err["a", "b"] > 5.0
    assert err["b", "a"] > 5.0
