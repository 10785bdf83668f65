"""The Python API (avoa_pipeline/api.py, diagnosis.py; docs/api.md): its names load on first use,
``diagnose`` gives what the ``diagnose`` command writes and prints, ``Diagnosis.write`` writes
all or none, and a loaded model simulates, estimates and exports what the commands write."""

from __future__ import annotations

import contextlib
import io
import json
import subprocess
import sys

import numpy as np
import pandas as pd
import pytest
from test_ecm import TRUTH, profile_frame, with_voltage

from avoa_pipeline import diagnose, load_model, read_record, records
from avoa_pipeline.cli import main
from avoa_pipeline.errors import DataError, UserError


def test_the_api_names_load_on_first_use():
    """``import avoa_pipeline`` (and so ``python -m avoa_pipeline``'s start) loads neither the
    pipeline nor numpy; the names do on first use, and an unknown name is an AttributeError."""
    code = (
        "import sys, avoa_pipeline as a\n"
        "assert 'numpy' not in sys.modules and 'avoa_pipeline.diagnosis' not in sys.modules\n"
        "from avoa_pipeline import diagnose, load_model, read_record, Diagnosis\n"
        "assert diagnose.__module__ == 'avoa_pipeline.diagnosis'\n"
        "assert load_model.__module__ == read_record.__module__ == 'avoa_pipeline.api'\n"
        "from avoa_pipeline import diagnosis\n"  # a submodule still imports as one
        "assert diagnosis.Diagnosis is Diagnosis and 'diagnose' in dir(a)\n"
        "try:\n    a.nope\nexcept AttributeError:\n    pass\nelse:\n    raise SystemExit(1)\n"
    )
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr


@pytest.fixture(scope="module")
def both(tmp_path_factory):
    """One record diagnosed by the command and by the API (its checked record handed in)."""
    root = tmp_path_factory.mktemp("api")
    truth = {**TRUTH, "r2_ohm": 0.01, "tau2_s": 1000.0}
    path = root / "rc.csv"
    with_voltage(profile_frame(), truth, noise_v=1e-3, seed=2).to_csv(path, index=False)
    cli_out = root / "cli"
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = main(["diagnose", str(path), "--out", str(cli_out)])
    assert code == 0, err.getvalue()
    said = (out.getvalue(), err.getvalue())
    return path, cli_out, said, diagnose([read_record(path)], progress=None)


def test_diagnose_writes_and_says_what_the_command_does(both, tmp_path):
    _, cli_out, (out, err), d = both
    written = d.write(tmp_path / "api")
    assert sorted(p.name for p in written) == ["diagnosis.json", "diagnosis.png", "model.json"]
    mine = json.loads((tmp_path / "api" / "diagnosis.json").read_text())
    theirs = json.loads((cli_out / "diagnosis.json").read_text())
    assert mine.pop("wall_s") > 0  # the one field a clock sets
    assert theirs.pop("wall_s") > 0
    assert mine == theirs
    assert (tmp_path / "api" / "model.json").read_bytes() == (cli_out / "model.json").read_bytes()
    assert d.verdict == mine["verdict"]
    assert d.intervals == mine.get("intervals")
    assert d.verdict["effect"] == "second_rc"
    assert out.splitlines() == [d.summary_line(cli_out)]
    said = [f"warning: {w}" for w in d.warning_lines(cli_out)]
    assert [line for line in err.splitlines() if line.startswith("warning: ")] == said


def test_write_is_all_or_none_and_never_over_an_input(both, tmp_path):
    path, _, _, d = both
    out = tmp_path / "out"
    (out / "model.json").mkdir(parents=True)  # the last file cannot be written
    with pytest.raises(UserError, match=r"model\.json: is a folder"):
        d.write(out)
    assert [p.name for p in out.iterdir()] == ["model.json"]
    with pytest.raises(UserError, match="is an input of this command"):
        d.write(path, figure=False)
    jobs_like = tmp_path / "jobs"
    assert [p.name for p in d.write(jobs_like, figure=False)] == ["diagnosis.json", "model.json"]
    assert sorted(p.name for p in jobs_like.iterdir()) == ["diagnosis.json", "model.json"]


def test_diagnose_refuses_bad_input_before_any_fit(tmp_path):
    frame = with_voltage(profile_frame(), TRUTH)
    frame.loc[10, "voltage_v"] = 40.0  # mV slipped into one row
    with pytest.raises(DataError, match="frame 0: column 'voltage_v'"):
        diagnose(frame)
    with pytest.raises(TypeError, match="a record is a path"):
        diagnose([frame.to_numpy()])
    with pytest.raises(DataError, match="no such file"):
        diagnose(tmp_path / "missing.csv")


# ----------------------------------------------------------------------------------------------
# a loaded model: simulate, estimate, export, against the commands


@pytest.fixture(scope="module")
def cell_files(tmp_path_factory):
    """test_heat's thermal cell with a heat block, and a record of it with and without its
    temperature (the second with a sidecar naming the ambient)."""
    from test_heat import AMBIENT_C, TRUE, cell, checked, drive, measured

    from avoa_pipeline.model import heat

    root = tmp_path_factory.mktemp("cell")
    model = cell()
    model.heat, _ = heat.fit_heat(model, [checked(measured(model, TRUE, drive(30), 40), 0)])
    model.save(root / "model.json")
    frame = measured(model, TRUE, drive(50), 60)
    frame.to_csv(root / "with_t.csv", index=False)
    frame.drop(columns="temperature_c").to_csv(root / "no_t.csv", index=False)
    (root / "no_t.json").write_text(json.dumps({"ambient_temperature_c": AMBIENT_C}))
    return root


@pytest.mark.parametrize("data", ["with_t.csv", "no_t.csv"])
def test_simulate_returns_what_the_command_writes(cell_files, tmp_path, data):
    out = tmp_path / "sim.csv"
    args = ["simulate", str(cell_files / "model.json"), str(cell_files / data), "--out", str(out)]
    assert main([*args, "--soc0", "0.95"]) == 0
    want = pd.read_csv(out)
    got = load_model(cell_files / "model.json").simulate(cell_files / data, soc0=0.95)
    assert list(got.columns) == list(want.columns)
    cols = ["time_s", "voltage_v", "model_v", "error_mv", "temperature_c_model"]
    np.testing.assert_allclose(got[cols].to_numpy(), want[cols].to_numpy(), rtol=1e-12)
    assert (got["temperature_source"] == want["temperature_source"]).all()  # the one rule


def test_simulate_needs_an_ambient_where_the_record_has_no_temperature(cell_files, tmp_path):
    model = load_model(cell_files / "model.json")
    frame = pd.read_csv(cell_files / "no_t.csv")  # a frame: no sidecar to name the ambient
    with pytest.raises(UserError, match="no ambient"):
        model.simulate(frame)
    got = model.simulate(frame, ambient_c=10.0)
    want = model.simulate(cell_files / "no_t.csv")  # its sidecar says 10 °C
    np.testing.assert_array_equal(got["model_v"], want["model_v"])
    with pytest.raises(UserError, match="soc0 must lie in"):
        model.simulate(frame, soc0=1.5, ambient_c=10.0)
    with pytest.raises(TypeError, match="a record is a path"):
        model.simulate(frame.to_numpy())


def test_estimate_returns_what_the_command_writes(both, tmp_path):
    path, cli_out, _, _ = both  # a model diagnose wrote: estimate needs its intervals
    out = tmp_path / "est.csv"
    assert main(["estimate", str(cli_out / "model.json"), str(path), "--out", str(out),
                 "--soc0", "0.9"]) == 0  # fmt: skip
    result = load_model(cli_out / "model.json").estimate(path, soc0=0.9)
    want = pd.read_csv(out)
    assert list(result.frame.columns) == list(want.columns)
    np.testing.assert_allclose(result.frame.to_numpy(), want.to_numpy(), rtol=1e-12, atol=0)
    summary = json.loads(out.with_suffix(".json").read_text())
    assert result.summary["final_soc"] == summary["final_soc"]
    assert result.summary["soc0_guess"] == 0.9


def test_export_returns_what_the_command_writes(both, tmp_path):
    _, cli_out, _, _ = both
    model = load_model(cli_out / "model.json")
    csv = tmp_path / "table.csv"
    assert main(["export", str(cli_out / "model.json"), "--to", "table", "--out",
                 str(csv)]) == 0  # fmt: skip
    table = model.export(to="table")
    np.testing.assert_allclose(table.to_numpy(), pd.read_csv(csv).to_numpy(), rtol=1e-9)
    assert table.attrs["sidecar"] == json.loads(csv.with_suffix(".json").read_text())
    with pytest.raises(UserError, match="to must be 'pybamm' or 'table'"):
        model.export(to="bms")
    with pytest.raises(UserError, match="apply to to='pybamm'"):
        model.export(to="table", soc0=0.5)


def test_export_to_pybamm_is_the_commands_module(both, tmp_path):
    pytest.importorskip("pybamm")
    path, cli_out, _, _ = both
    py = tmp_path / "cell.py"
    assert main(["export", str(cli_out / "model.json"), "--to", "pybamm", "--out", str(py),
                 "--record", str(path)]) == 0  # fmt: skip
    text = load_model(cli_out / "model.json").export(to="pybamm", record=path, file_name="cell.py")
    assert text == py.read_text()


def test_read_record_is_the_input_layers(cell_files, tmp_path):
    rec = read_record(cell_files / "with_t.csv")
    assert isinstance(rec, records.Checked)
    assert rec.source == str(cell_files / "with_t.csv")
    bad = tmp_path / "bad.csv"
    pd.read_csv(cell_files / "with_t.csv").assign(voltage_v=lambda f: 1e3 * f["voltage_v"]).to_csv(
        bad, index=False
    )
    with pytest.raises(DataError, match="column 'voltage_v'"):
        read_record(bad)
