"""One model over temperature (real/experiments/joint_temperature.py, jobs.real's table job): the
joint diagnosis's unseen errors beside each temperature's own, from small synthetic reports."""

import json

import numpy as np
import pandas as pd

from avoa_pipeline.jobs.real import joint_temperature_table
from avoa_pipeline.real.experiments import joint_temperature as jt
from avoa_pipeline.real.experiments.drive_cycles import diagnosis_record


def _report(selected: str, rows: dict[str, tuple[float, float]]) -> dict:
    """A diagnosis.json with validation rows for the selected model and one other rung."""
    validation = []
    for record, (rmse, mx) in rows.items():
        for model, scale in ((selected, 1.0), ("base", 2.0)):
            errors = {"rmse_mv": rmse * scale, "max_err_mv": mx * scale,
                      "rmse_in_training_soc_mv": rmse, "share_in_training_soc": 1.0}  # fmt: skip
            validation.append({"record": record, "model": model, "effects": [model], **errors})
    return {"source": ["a.csv", "b.csv"], "ocv": {}, "verdict": {}, "ladder": [],
            "selected": {"name": selected, "heldout_rmse_mv": 1.0}, "wall_s": 1.0,
            "validation": validation}  # fmt: skip


AMBIENT = {"25degC": 25.0, "0degC": 0.0}
JOINT = {"25degC/us06": (10.0, 50.0), "25degC/hwfet": (20.0, 60.0), "0degC/us06": (30.0, 90.0)}
OWN = {"25degC": {"us06": (12.0, 55.0), "hwfet": (18.0, 40.0)}, "0degC": {"us06": (130.0, 400.0)}}


def _records():
    joint = diagnosis_record("all", _report("thermal", JOINT), "joint", {k: k for k in JOINT})
    own = {t: diagnosis_record(t, _report(f"own_{t}", rows), "diagnosis")
           for t, rows in OWN.items()}  # fmt: skip
    return joint, own


def test_table_puts_each_unseen_cycle_beside_its_temperatures_own_model():
    joint, own = _records()
    df = jt.table(joint, own, AMBIENT)
    assert list(df.columns) == list(jt.COLUMNS)
    assert list(zip(df["temperature_c"], df["cycle"], strict=True)) == [
        (25.0, "hwfet"), (25.0, "us06"), (0.0, "us06")]  # fmt: skip
    for row in df.itertuples():
        temp = next(t for t, a in AMBIENT.items() if a == row.temperature_c)
        assert (row.joint_rmse_mv, row.joint_max_err_mv) == JOINT[f"{temp}/{row.cycle}"]
        assert (row.per_temperature_rmse_mv, row.per_temperature_max_err_mv) == OWN[temp][row.cycle]
        assert row.per_temperature_model == f"own_{temp}"
        assert row.joint_model == "thermal"
    med = jt.medians(df).set_index("temperature_c")
    assert med.loc[25.0].tolist() == [15.0, 15.0]  # joint, per temperature
    assert med.loc[0.0].tolist() == [30.0, 130.0]


def test_a_temperature_without_a_model_of_its_own_leaves_its_columns_empty():
    joint, own = _records()
    df = jt.table(joint, {"25degC": own["25degC"]}, AMBIENT)
    cold = df[df["temperature_c"] == 0.0].iloc[0]
    assert np.isnan(cold["per_temperature_rmse_mv"])
    assert cold["joint_rmse_mv"] == 30.0


def test_job_reads_the_diagnoses_and_names_the_cycles_by_their_files(tmp_path):
    tests = {k: str(tmp_path / f"{k.replace('/', '_')}.csv") for k in JOINT}
    (tmp_path / "joint").mkdir()
    rep = _report("thermal", {tests[k]: e for k, e in JOINT.items()})
    (tmp_path / "joint" / "diagnosis.json").write_text(json.dumps(rep))
    own_dirs = {}
    for temp, rows in OWN.items():
        own_dirs[temp] = tmp_path / temp
        own_dirs[temp].mkdir()
        rep = _report(f"own_{temp}", {tests[f"{temp}/{c}"]: e for c, e in rows.items()})
        (own_dirs[temp] / "diagnosis.json").write_text(json.dumps(rep))
    out = tmp_path / "joint_temperature.csv"
    stem = tmp_path / "figures" / "joint_temperature"
    joint_temperature_table(AMBIENT, tmp_path / "joint", own_dirs, tests, out, stem,
                            tmp_path / "log")  # fmt: skip
    df = pd.read_csv(out)
    assert stem.with_suffix(".png").stat().st_size > 0
    assert stem.with_suffix(".pdf").stat().st_size > 0
    assert df.loc[df["temperature_c"] == 0.0, "per_temperature_rmse_mv"].item() == 130.0
    assert "0 °C 30.0 / 130.0" in (tmp_path / "log").read_text()


def test_job_predicts_each_unseen_cycles_temperature_from_its_ambient(tmp_path):
    """With a heat block in the joint model.json: the temperature columns, the traces and
    their figure; each cycle's temperature from its sidecar's ambient alone."""
    from test_heat import AMBIENT_C, TRUE, cell, checked, drive, measured

    from avoa_pipeline.model import heat

    model = cell()
    model.heat, _ = heat.fit_heat(model, [checked(measured(model, TRUE, drive(70), 71), 0)])
    tests = {k: str(tmp_path / f"{k.replace('/', '_')}.csv") for k in JOINT}
    for j, (k, path) in enumerate(tests.items()):
        measured(model, TRUE, drive(80 + j), 90 + j).to_csv(path, index=False)
        ambient = AMBIENT_C if k.startswith("0degC") else 25.0  # 25degC's: a wrong ambient
        (tmp_path / f"{k.replace('/', '_')}.json").write_text(
            json.dumps({"ambient_temperature_c": ambient}))  # fmt: skip
    (tmp_path / "joint").mkdir()
    rep = _report("thermal", {tests[k]: e for k, e in JOINT.items()})
    (tmp_path / "joint" / "diagnosis.json").write_text(json.dumps(rep))
    model.save(tmp_path / "joint" / "model.json")
    out, traces = tmp_path / "t.csv", tmp_path / "heat.csv"
    stem = tmp_path / "figures" / "heat"
    joint_temperature_table(AMBIENT, tmp_path / "joint", {}, tests, out, tmp_path / "f" / "j",
                            tmp_path / "log", traces, stem)  # fmt: skip
    df = pd.read_csv(out).set_index("cycle")
    assert set(jt.HEAT_COLUMNS) <= set(df.columns)
    cold = df[df["temperature_c"] == 0.0].loc["us06"]
    assert cold["temperature_rmse_k"] < 0.2  # the right ambient: the thermocouple's noise
    assert cold["ambient_c"] == AMBIENT_C
    warm = df[df["temperature_c"] == 25.0]
    assert (warm["temperature_rmse_k"] > 5.0).all()  # 15 K off: the ambient is all it has
    assert (warm["joint_rmse_predicted_t_mv"] > warm["joint_rmse_measured_t_mv"]).all()
    assert cold["joint_rmse_measured_t_mv"] < 1.0  # the model's own records
    tr = pd.read_csv(traces)
    assert set(tr["key"]) == set(JOINT)
    assert stem.with_suffix(".png").stat().st_size > 0
    assert "self-heating from the ambient: C_th" in (tmp_path / "log").read_text()


def test_job_leaves_the_temperature_columns_empty_without_a_heat_block(tmp_path):
    tests = {k: str(tmp_path / f"{k.replace('/', '_')}.csv") for k in JOINT}
    (tmp_path / "joint").mkdir()
    rep = _report("thermal", {tests[k]: e for k, e in JOINT.items()})
    (tmp_path / "joint" / "diagnosis.json").write_text(json.dumps(rep))
    out, traces = tmp_path / "t.csv", tmp_path / "heat.csv"
    joint_temperature_table(AMBIENT, tmp_path / "joint", {}, tests, out, tmp_path / "f" / "j",
                            tmp_path / "log", traces, tmp_path / "f" / "h")  # fmt: skip
    df = pd.read_csv(out)
    assert df["temperature_rmse_k"].isna().all()
    assert pd.read_csv(traces).empty
    assert (tmp_path / "f" / "h.png").stat().st_size > 0
    assert "no " in (tmp_path / "log").read_text().splitlines()[-1]


def test_a_cycle_every_diagnosis_refused_has_no_row_and_the_log_names_it(tmp_path):
    """The -20 °C case (docs/real-data.md): a temperature whose one unseen cycle the joint and
    its own diagnosis both refused (``refused_validation``): no row, no failure, one log line
    each."""
    tests = {k: str(tmp_path / f"{k.replace('/', '_')}.csv") for k in JOINT}
    tests["-20degC/us06"] = str(tmp_path / "m20_us06.csv")
    refusal = {
        "record": tests["-20degC/us06"],
        "refusal": f"{tests['-20degC/us06']}: column 'time_s': the rested voltage ...",
    }
    (tmp_path / "joint").mkdir()
    rep = _report("thermal", {tests[k]: e for k, e in JOINT.items()})
    rep["refused_validation"] = [refusal]
    (tmp_path / "joint" / "diagnosis.json").write_text(json.dumps(rep))
    own_dirs = {}
    for temp, rows in {**OWN, "-20degC": {}}.items():
        own_dirs[temp] = tmp_path / temp
        own_dirs[temp].mkdir()
        rep = _report(f"own_{temp}", {tests[f"{temp}/{c}"]: e for c, e in rows.items()})
        if not rows:
            rep["refused_validation"] = [refusal]
        (own_dirs[temp] / "diagnosis.json").write_text(json.dumps(rep))
    out = tmp_path / "joint_temperature.csv"
    log = tmp_path / "log"
    joint_temperature_table({**AMBIENT, "-20degC": -20.0}, tmp_path / "joint", own_dirs, tests,
                            out, tmp_path / "figures" / "joint_temperature", log)  # fmt: skip
    df = pd.read_csv(out)
    assert -20.0 not in set(df["temperature_c"])
    assert len(df) == len(JOINT)
    lines = [x for x in log.read_text().splitlines() if x.startswith("refused")]
    assert len(lines) == 2
    assert all("m20_us06.csv: column 'time_s'" in x for x in lines)
