"""Issue 28 on the Samsung 30Q: the table of the selected models on the unseen temperature
(jobs.real.selected_on) and the rules' plan."""

from __future__ import annotations

import json
from pathlib import Path

import pandas as pd
import pytest

from avoa_pipeline import plan
from avoa_pipeline.jobs.real import selected_on


def _diagnosis(tmp_path, label, name, rmse, unseen):
    other = tmp_path / "other.csv"
    report = {
        "records": [{"source": f"results/real/canonical/samsung_hppc_{label}.csv"}],
        "selected": {"name": name, "parameters": {"r0_ohm": 0.02, "thermal_theta_r0_k": 3000.0}},
        "validation": [
            {"record": str(unseen), "model": "base", "rmse_mv": 99.0, "max_err_mv": 300.0},
            {"record": str(unseen), "model": name, "rmse_mv": rmse, "max_err_mv": 4 * rmse},
            {"record": str(other), "model": name, "rmse_mv": 1.0, "max_err_mv": 2.0},
        ],
    }
    path = tmp_path / label / "diagnosis.json"
    path.parent.mkdir()
    path.write_text(json.dumps(report))
    return str(path)


def test_the_selected_model_on_the_unseen_record(tmp_path):
    unseen = tmp_path / "samsung_hppc_30degC.csv"
    fits = {"joint": _diagnosis(tmp_path, "joint", "thermal", 5.0, unseen),
            "20degC": _diagnosis(tmp_path, "20degC", "second_rc", 8.0, unseen)}  # fmt: skip
    out = tmp_path / "table.csv"
    selected_on(fits, unseen, out)
    df = pd.read_csv(out).set_index("fit")
    assert df.loc["joint", "rmse_mv"] == 5.0
    assert df.loc["20degC", "max_err_mv"] == 32.0
    assert df.loc["joint", "selected"] == "thermal"
    assert json.loads(df.loc["joint", "laws"]) == {"thermal_theta_r0_k": 3000.0}


def test_the_handed_over_model_is_the_selected_one(tmp_path):
    """docs/handover-rule.md: the model a user gets (its rows ``handed_over``), the verdict's
    model beside it."""
    unseen = tmp_path / "samsung_hppc_30degC.csv"
    path = _diagnosis(tmp_path, "joint", "thermal", 5.0, unseen)
    report = json.loads(Path(path).read_text())
    report["handed_over"] = {"name": "second_rc", "parameters": {"r0_ohm": 0.02}}
    report["validation"].append({"record": str(unseen), "model": "handed_over", "rmse_mv": 3.0,
                                 "max_err_mv": 9.0})  # fmt: skip
    Path(path).write_text(json.dumps(report))
    out = tmp_path / "table.csv"
    selected_on({"joint": path}, unseen, out)
    row = pd.read_csv(out).iloc[0]
    assert (row["selected"], row["verdict_model"], row["rmse_mv"]) == ("second_rc", "thermal", 3.0)
    assert json.loads(row["laws"]) == {}


def test_a_diagnosis_without_the_unseen_record_is_refused(tmp_path):
    fits = {"joint": _diagnosis(tmp_path, "joint", "thermal", 5.0, tmp_path / "elsewhere.csv")}
    with pytest.raises(ValueError, match="no one validation entry"):
        selected_on(fits, tmp_path / "samsung_hppc_30degC.csv", tmp_path / "t.csv")


def test_the_table_is_a_target_only_with_the_joint_section():
    cfg = {"real": {"samsung": {"hppc": {}}}}
    assert plan.SAMSUNG_JOINT_TABLE not in plan.cell_targets(cfg)
    cfg["real"]["samsung"]["joint"] = {"train": ["20degC", "40degC"], "unseen": "30degC"}
    assert plan.SAMSUNG_JOINT_TABLE in plan.cell_targets(cfg)


def test_the_joint_fit_and_each_training_temperature_alone():
    assert plan.samsung_joint_fits({"real": {"samsung": {"hppc": {}}}}) == {}
    cfg = {"real": {"samsung": {"joint": {"train": ["20degC", "40degC"], "unseen": "30degC"}}}}
    assert plan.samsung_joint_fits(cfg) == {"joint": ["20degC", "40degC"], "20degC": ["20degC"],
                                            "40degC": ["40degC"]}  # fmt: skip
