"""The heat block of a model whose voltage reads no temperature (docs/temperature-rule.md part 6,
issue 41): fitted from every training record whose measured temperature moves, whether or not
the model has a temperature law; its prediction from the ambient tracks the thermocouple; the
voltage is the same, bit for bit, with and without it; diagnose and simulate say so."""

from __future__ import annotations

import json

import numpy as np
import pytest
from test_ecm import TRUTH
from test_heat import (
    AMBIENT_C,
    TRUE,
    assert_gives_back,
    cell,
    checked,
    drive,
    measured,
    write_records,
)

from avoa_pipeline import ambient, diagnosis
from avoa_pipeline.cli import main
from avoa_pipeline.model import ecm, elements, heat
from avoa_pipeline.model.fitted import FittedModel

PLAIN = ("second_rc",)  # two RC branches, no element that reads the temperature


@pytest.fixture(scope="module")
def plain_records():
    """The plain cell's records: its voltage and a thermocouple (0.05 K noise) that follows its
    own losses from a 10 °C ambient (``test_heat.measured``, the truth ``test_heat.TRUE``)."""
    model = cell(PLAIN)
    return model, [checked(measured(model, TRUE, drive(70 + k), 80 + k), k) for k in range(3)]


def test_a_model_without_a_temperature_law_gets_its_heat_block(plain_records):
    """The rule itself: without it (a thermal element required) there is no block here."""
    model, recs = plain_records
    assert ambient.needs_temperature(model) == []
    assert heat.temperature_readers(model) == []
    got, why = heat.fit_heat(model, recs)
    assert got is not None, why
    assert_gives_back(got, TRUE)
    assert not got.entropic  # the truth has no reversible heat
    assert got.report["rmse_k"] < 0.1  # the 0.05 K noise, as the thermal model's test accepts
    # the heat is the circuit's own loss: R0 and both RC branches heat the cell by kelvins
    rise = max(float(np.max(r.frame["temperature_c"])) for r in recs) - AMBIENT_C
    assert rise > 3.0


def test_its_prediction_tracks_an_unseen_record_and_leaves_the_voltage_as_it_is(plain_records):
    model, recs = plain_records
    model.heat, _ = heat.fit_heat(model, recs)
    frame = measured(model, TRUE, drive(90), 91)  # not among the training records
    pred = heat.predict(model, model.heat, frame, AMBIENT_C)
    rms = float(np.sqrt(np.mean((pred.temp_k - heat.KELVIN - frame["temperature_c"]) ** 2)))
    assert rms < 0.1
    # the heat does not depend on the temperature: the second pass moves nothing
    assert pred.converged
    assert pred.passes == 2
    assert pred.last_change_k == 0.0
    bare = frame.drop(columns="temperature_c")
    v_none = model.simulate(bare)
    v_measured = model.simulate(frame)
    v_predicted = model.simulate(frame.assign(temperature_c=pred.temp_k - heat.KELVIN))
    np.testing.assert_array_equal(v_measured, v_none)
    np.testing.assert_array_equal(v_predicted, v_none)
    # and the block leaves the fitted model's voltage as it was
    without = FittedModel(model.config, model.x, model.knots, model.tref_k, model.bounds)
    np.testing.assert_array_equal(without.simulate(frame), v_measured)


def test_records_whose_temperature_does_not_move_still_give_no_block(plain_records):
    model, recs = plain_records
    frame = recs[0].frame
    flat = frame.assign(temperature_c=AMBIENT_C + 0.5 * np.sin(frame["time_s"] / 100.0))
    got, why = heat.fit_heat(model, [checked(flat, 0)])
    assert got is None
    assert why == (f"no training record has a measured temperature_c moving "
                   f"{heat.MIN_RANGE_C:g} °C or more: nothing to fit C_th and hA to")  # fmt: skip
    no_t = checked(frame.drop(columns="temperature_c"), 1)
    assert heat.fit_heat(model, [no_t])[0] is None


def _model_with(effects) -> FittedModel:
    """A model with ``effects`` (each with what it requires first) at active values."""
    from test_ecm import ACTIVE

    chain = []
    for e in effects:
        need = ecm.REQUIRES.get(e)
        chain += [*([need] if need and need not in chain else []), e]
    values = {**TRUTH, **{k: v for e in chain for k, v in ACTIVE[e].items()}}
    return FittedModel(ecm.Config(tuple(chain)), ecm.vector(values), ecm.Knots(0.0, 0.2),
                       AMBIENT_C + heat.KELVIN, {})  # fmt: skip


@pytest.mark.parametrize("effect", list(elements.REGISTRY))
def test_the_readers_are_the_elements_whose_voltage_moves_with_the_temperature(effect):
    """``temperature_readers`` (read from the elements' statements) against the simulator: a
    model's voltage at 0 °C and at 40 °C differs exactly where it names an element."""
    model = _model_with((effect,))
    frame = drive(5, n=600)
    cold = model.simulate(frame.assign(temperature_c=0.0), soc0=0.9)
    warm = model.simulate(frame.assign(temperature_c=40.0), soc0=0.9)
    readers = heat.temperature_readers(model)
    assert set(ambient.needs_temperature(model)) <= set(readers)
    assert bool(readers) == (not np.array_equal(cold, warm)), readers


def test_diagnose_writes_the_block_and_says_the_voltage_does_not_depend_on_it(
    plain_records, monkeypatch, tmp_path
):
    """diagnosis.diagnose's hook on a handed-over model without a temperature law (the ladder
    replaced by the plain cell: what is tested is the heat block's call and its words)."""
    from avoa_pipeline.gap import diagnose as gap_diagnose

    model, recs = plain_records
    handed = FittedModel(model.config, model.x, model.knots, model.tref_k, model.bounds)
    monkeypatch.setattr(gap_diagnose, "diagnose_records", lambda *a, **k: ({}, {}, handed))
    d = diagnosis.diagnose(recs, progress=False)
    assert d.model.heat is not None
    assert d.heat_line.startswith("heat block: C_th ")
    assert d.heat_line.endswith(f"; {heat.VOLTAGE_BLIND}")
    assert d.report["heat"] == {"written": True, "summary": d.heat_line,
                                "voltage_reads_temperature": []}  # fmt: skip
    json.dumps(d.report, allow_nan=False)
    d.model.save(tmp_path / "model.json")
    assert FittedModel.load(tmp_path / "model.json").heat == d.model.heat
    # a thermal model's line does not say it
    thermal = cell()
    thermal_recs = [checked(measured(thermal, TRUE, drive(12), 13), 0)]
    assert heat.VOLTAGE_BLIND not in heat.attach(thermal, thermal_recs)
    assert heat.block_summary(thermal, "x")["voltage_reads_temperature"] == ["thermal"]


@pytest.fixture(scope="module")
def plain_files(plain_records, tmp_path_factory):
    """The plain model with its heat block and without it, an unseen record with its
    thermocouple, without it (a sidecar naming the ambient) and without either."""
    model, recs = plain_records
    root = tmp_path_factory.mktemp("plain_heat")
    bare = FittedModel(model.config, model.x, model.knots, model.tref_k, model.bounds)
    bare.save(root / "bare.json")
    model.heat, _ = heat.fit_heat(model, recs)
    model.save(root / "model.json")
    write_records(root, measured(model, TRUE, drive(95), 96))
    return root


def _simulate(root, model, data, capsys, *extra):
    import pandas as pd

    out = root / "out" / f"{model}-{data}{''.join(extra)}.csv"
    out.parent.mkdir(exist_ok=True)
    code = main(["simulate", str(root / model), str(root / data), "--out", str(out),
                 "--soc0", "0.95", *extra])  # fmt: skip
    got = capsys.readouterr()
    assert code == 0, got.err
    return pd.read_csv(out), got.err


def test_simulate_predicts_the_temperature_from_the_ambient_and_keeps_the_voltage(
    plain_files, capsys
):
    import pandas as pd

    truth = pd.read_csv(plain_files / "with_t.csv")["temperature_c"]
    without, _ = _simulate(plain_files, "bare.json", "no_t.csv", capsys)
    assert without["temperature_c_model"].isna().all()
    for extra in ((), ("--ambient-c", "10")):  # the sidecar's ambient, or the option's
        df, err = _simulate(plain_files, "model.json", "no_t.csv", capsys, *extra)
        assert "temperature predicted from ambient 10 °C" in err
        assert heat.VOLTAGE_BLIND in err
        assert "--ambient-c" not in err.replace("(--ambient-c)", "")  # no "ignored" warning
        rms = float(np.sqrt(np.mean((df["temperature_c_model"] - truth) ** 2)))
        assert rms < 0.2  # test_cli's bound for the thermal model's prediction
        np.testing.assert_array_equal(df["model_v"], without["model_v"])
    # beside the thermocouple, on request: the temperature's RMS is printed, the voltage unmoved
    df, _ = _simulate(plain_files, "model.json", "with_t.csv", capsys, "--predict-temperature",
                      "--ambient-c", "10")  # fmt: skip
    np.testing.assert_array_equal(df["model_v"], without["model_v"])
    # no ambient at hand: the run goes on without a temperature, as without the block
    df, err = _simulate(plain_files, "model.json", "alone.csv", capsys)
    assert df["temperature_c_model"].isna().all()
    assert "no ambient for the heat block" in err
    np.testing.assert_array_equal(df["model_v"], without["model_v"])


def test_an_ambient_is_ignored_only_where_there_is_no_heat_block(plain_files, capsys):
    _, err = _simulate(plain_files, "bare.json", "alone.csv", capsys, "--ambient-c", "25")
    warned = [x for x in err.splitlines() if "ignored" in x]
    assert warned == [f"warning: --ambient-c 25: ignored: {plain_files / 'bare.json'} has no "
                      "temperature law and no heat block, so no cell temperature is predicted "
                      "from the ambient"]  # fmt: skip
    df, err = _simulate(plain_files, "model.json", "alone.csv", capsys, "--ambient-c", "25")
    assert "ignored" not in err
    assert df["temperature_c_model"].iloc[0] == pytest.approx(25.0)


def test_export_compares_the_thermal_state_only_where_an_ambient_is_at_hand(plain_files):
    from avoa_pipeline import inputs

    model = FittedModel.load(plain_files / "model.json")
    for name, want in (("alone.csv", None), ("no_t.csv", AMBIENT_C), ("with_t.csv", None)):
        rec = inputs.read_record(str(plain_files / name))
        got = ambient.export_ambient(model, rec, model_name="model.json",
                                     record_name=str(plain_files / name))  # fmt: skip
        assert got == want, name


def test_the_pybamm_module_carries_the_block_of_a_model_without_a_law():
    """``export --to pybamm``'s LumpedHeat on a model whose voltage reads no temperature: its
    temperature from the ambient is heat.py's, and its voltage ours (test_interop_pybamm's
    record, tolerances and heat block)."""
    pytest.importorskip("pybamm", reason="pybamm is not installed")
    import dataclasses

    from test_interop_pybamm import AMBIENT_C as PYBAMM_AMBIENT_C
    from test_interop_pybamm import HEAT, SOC0, THERMAL_TOL_K, TOL_RMS_MV, fitted, record

    from avoa_pipeline.interop import pybamm as to_pybamm

    model = dataclasses.replace(fitted("table", PLAIN), heat=HEAT)
    frame = record(temperature=False)
    module = to_pybamm.loaded_module(model, SOC0)
    got = to_pybamm.thermal_agreement(module, model, frame, SOC0, PYBAMM_AMBIENT_C)
    assert "error" not in got, got
    ref = heat.predict(model, model.heat, frame, PYBAMM_AMBIENT_C, soc0=SOC0)
    assert float(ref.temp_k.max()) - heat.KELVIN - PYBAMM_AMBIENT_C > 20 * THERMAL_TOL_K
    assert got["rms_k"] <= THERMAL_TOL_K
    assert got["rms_mv"] <= TOL_RMS_MV
