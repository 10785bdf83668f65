"""A model of per-temperature parameter sets (``FittedModel.by_temperature``,
docs/temperature-rule.md parts 3-4): built from ordinary models (``per_temperature``), written
and read back with every check, run at a record's ambient (``at_ambient``) by ``simulate``,
``estimate`` and the table export; refused by the PyBaMM export.

The sets are models of chosen values (test_estimate's, with intervals as a fit writes them): a
cold cell (0 °C: higher resistances, less capacity, no second RC branch), one at 25 °C with a
second branch, a warm one at 40 °C.
"""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest
from json_compare import assert_same_json
from test_ecm import ACTIVE, TRUTH, profile_frame, with_voltage
from test_estimate import drive, ocv_table

from avoa_pipeline import cli
from avoa_pipeline.errors import DataError
from avoa_pipeline.model import ecm, fitting, intervals
from avoa_pipeline.model.fitted import FittedModel, fit_model

SOC0 = 0.9
BASE = {k: v for k, v in TRUTH.items() if k != "soc0"}
SETS = {  # ambient °C: (elements, values beside BASE, reference temperature K)
    0.0: ((), {"r0_ohm": 0.12, "r1_ohm": 0.04, "tau1_s": 150.0, "capacity_ah": 2.40}, 274.0),
    25.0: (("second_rc",), {}, 299.0),
    40.0: (("second_rc",), {"r0_ohm": 0.04, "r2_ohm": 0.006, "capacity_ah": 2.62}, 314.0),
}
TABLE = ocv_table()


def cell(effects, values, tref_k, table=TABLE) -> FittedModel:
    """A model of chosen values, bounds ±1 around each (internal coordinates), intervals of
    ±0.02 around each, as ``fit_model`` writes them (test_estimate's ``fitted``)."""
    config = ecm.Config(tuple(effects), table)
    names = config.names()
    chosen = {**BASE, **{k: v for e in effects for k, v in ACTIVE[e].items()}, **values,
              "voltage_offset_v": -0.01}  # fmt: skip
    x = ecm.vector({k: v for k, v in chosen.items() if ecm.BY_REPORT[k] in names})
    bounds = {n: (x[ecm.IDX[n]] - 1.0, x[ecm.IDX[n]] + 1.0) for n in names
              if not ecm.PARAMS[n].per_record}  # fmt: skip
    model = FittedModel(config, x, ecm.Knots(0.2, 0.12), tref_k, bounds, {"by": "test"}, 5.0)
    entries = {}
    for n in model.names:
        rep = ecm.PARAMS[n].report
        ends = sorted(ecm.report(np.where(np.arange(ecm.NX) == ecm.IDX[n], x + d, x), [n])[rep]
                      for d in (-0.02, 0.02))  # fmt: skip
        entries[rep] = {"value": model.parameters()[rep], "low95": ends[0], "high95": ends[1],
                        "at_bound": False, "identified": True, "held": False}  # fmt: skip
    model.intervals = {"method": "test", "level": intervals.LEVEL, "samples": 1000,
                       "effective_samples": 1000.0, "residual_sd_mv": 2.0,
                       "parameters": entries, "correlated_pairs": [],
                       "flags": intervals.flags(entries, [])}  # fmt: skip
    return model


def sets() -> list[tuple[float, FittedModel]]:
    return [(a, cell(*spec)) for a, spec in SETS.items()]


def joint() -> FittedModel:
    return FittedModel.per_temperature(sets(), {"handed_over": "per-temperature models"})


def frame_at(ambient_c: float, temperature: bool = True, seconds: int = 900) -> pd.DataFrame:
    """test_estimate's drive record, its temperature starting at ``ambient_c``."""
    f = drive(seconds, temperature=temperature)
    if temperature:
        f["temperature_c"] += ambient_c - float(f["temperature_c"].iloc[0])
    return f


def inverse_k(c: float) -> float:
    return 1.0 / (c + 273.15)


# ----------------------------------------------------------------------------------------------
# the format


def test_the_sets_are_widened_ordered_and_the_top_level_is_the_set_at_25_c():
    given = sets()
    m = FittedModel.per_temperature(given[::-1])  # any order: coldest first after
    assert [a for a, _ in m.by_temperature] == [0.0, 25.0, 40.0]
    assert all(s.config.effects == ("second_rc",) for _, s in m.by_temperature)
    assert m.config.effects == ("second_rc",)
    # the top level is the 25 °C set (the sets' references differ: 25 °C), a reader of the
    # top level alone runs it
    assert m.parameters() == given[1][1].parameters()
    frame = frame_at(25.0)
    assert np.array_equal(FittedModel.simulate(m, frame, SOC0), given[1][1].simulate(frame, SOC0))
    with pytest.raises(ValueError, match="at least 2"):
        FittedModel.per_temperature(given[:1])
    with pytest.raises(ValueError, match="two at 25"):
        FittedModel.per_temperature([given[1], given[1]])


def test_a_missing_element_is_neutral_within_the_librarys_limits_and_changes_nothing():
    cold = sets()[0][1]
    wide = joint().by_temperature[0][1]
    assert cold.config.effects == ()
    assert wide.config.effects == ("second_rc",)
    assert wide.parameters()["r2_ohm"] == 0.0  # neutral
    for n in ecm.element_params("second_rc"):
        assert wide.bounds[n] == fitting.internal_limits(n)
    for temperature in (True, False):
        frame = frame_at(0.0, temperature)
        assert np.array_equal(wide.simulate(frame, SOC0), cold.simulate(frame, SOC0))
        assert wide.initial_soc(wide.record(frame)) == cold.initial_soc(cold.record(frame))
    # the element's interval entries say what its bounds say: R2 at its lower limit (0), τ2 no
    # fit's, its interval the whole range, not identified
    entries = wide.intervals["parameters"]
    assert entries["r2_ohm"]["at_bound"]
    assert entries["r2_ohm"]["low95"] is None
    assert entries["tau2_s"]["low95"] == pytest.approx(wide.physical_bounds("ltau2")[0])
    assert not entries["tau2_s"]["identified"]


def test_it_round_trips_through_save_and_load(tmp_path):
    m = joint()
    m.save(tmp_path / "model.json")
    back = FittedModel.load(tmp_path / "model.json")
    assert_same_json(back.to_json(), json.loads((tmp_path / "model.json").read_text()))
    assert_same_json(back.to_json(), json.loads(json.dumps(m.to_json())))
    d = back.to_json()
    assert [e["ambient_c"] for e in d["by_temperature"]] == [0.0, 25.0, 40.0]
    assert all("by_temperature" not in e["model"] for e in d["by_temperature"])
    for (a, s), (b, t) in zip(m.by_temperature, back.by_temperature, strict=True):
        assert a == b
        assert t.parameters() == pytest.approx(s.parameters(), rel=1e-12)
        assert t.tref_k == s.tref_k
    frame = frame_at(10.0)
    assert np.allclose(back.simulate(frame, SOC0), m.simulate(frame, SOC0), rtol=0, atol=1e-12)


def test_fitted_sets_round_trip_and_their_interpolation_loads(tmp_path):
    """Sets as ``fit_model`` leaves them (its bounds and intervals, each its records' knots and
    mean temperature): the widened cold set and the model interpolated between load back."""
    fits = []
    for ambient, effects, values in ((0.0, (), {"r0_ohm": 0.1}), (25.0, ("second_rc",), {})):
        frame = profile_frame().assign(temperature_c=ambient)
        cfg = ecm.Config(effects)
        truth = {**TRUTH, **{k: v for e in effects for k, v in ACTIVE[e].items()}, **values}
        fit = fit_model(with_voltage(frame, truth, noise_v=1e-3, config=cfg), cfg).model
        fits.append((ambient, fit, frame))
    m = FittedModel.per_temperature([(a, f) for a, f, _ in fits])
    m.save(tmp_path / "model.json")
    back = FittedModel.load(tmp_path / "model.json")
    assert back.by_temperature[0][1].intervals["parameters"]["r2_ohm"]["at_bound"]
    mid = back.at_ambient(12.0)
    assert "interpolated" in back.ambient_note(12.0)  # the trefs differ, no law reads them
    mid.save(tmp_path / "mid.json")
    FittedModel.load(tmp_path / "mid.json")
    cold_frame = fits[0][2].assign(voltage_v=0.0)
    assert np.allclose(back.simulate(cold_frame, SOC0), fits[0][1].simulate(cold_frame, SOC0),
                       rtol=0.0, atol=1e-12)  # fmt: skip


def test_a_model_json_without_the_block_loads_as_before(tmp_path):
    one = sets()[1][1]
    one.save(tmp_path / "one.json")
    back = FittedModel.load(tmp_path / "one.json")
    assert back.by_temperature is None
    assert "by_temperature" not in back.to_json()
    assert back.at_ambient(-10.0) is back


def _broken(d, how):
    sets_ = d["by_temperature"]
    if how == "not-increasing":
        sets_[2]["ambient_c"] = 25.0
    elif how == "one-set":
        del sets_[1:]
    elif how == "bad-set":
        sets_[1]["model"]["parameters"]["r0_ohm"] = "text"
    elif how == "bad-set-value":
        sets_[0]["model"]["parameters"]["r0_ohm"] = 50.0
    elif how == "bad-ambient":
        sets_[1]["ambient_c"] = 400.0
    elif how == "ambient-not-a-number":
        sets_[0]["ambient_c"] = True
    elif how == "nested":
        sets_[1]["model"]["by_temperature"] = [1, 2]
    elif how == "other-elements":  # the cold set as it was fitted, not widened
        sets_[0]["model"] = cell(*SETS[0.0]).to_json()
    elif how == "top-not-its-set":  # the 0 °C set now lies nearest 25 °C
        sets_[0]["ambient_c"], sets_[1]["ambient_c"], sets_[2]["ambient_c"] = 24.0, 50.0, 60.0
    elif how == "extra-field":
        sets_[0]["note"] = "x"
    return d


BROKEN = {
    "not-increasing": "field 'by_temperature[2].ambient_c': 25 °C, not above the set before",
    "one-set": "field 'by_temperature': a list of 1, need at least 2",
    "bad-set": "field 'by_temperature[1].model.parameters.r0_ohm': a string",
    "bad-set-value": "field 'by_temperature[0].model.parameters.r0_ohm': 50 outside",
    "bad-ambient": "field 'by_temperature[1].ambient_c': 400 outside a cell's ambient",
    "ambient-not-a-number": "field 'by_temperature[0].ambient_c': a boolean (true)",
    "nested": "field 'by_temperature[1].model.by_temperature': a set holds no sets",
    "other-elements": "field 'by_temperature[0].model.effects': [], but the top level's",
    "top-not-its-set": "field 'parameters': not by_temperature[0]'s (24 °C",
    "extra-field": "field 'by_temperature[0].note': not a field",
}


@pytest.mark.parametrize("how", list(BROKEN))
def test_a_broken_block_is_refused_in_one_line_naming_the_field(tmp_path, how):
    path = tmp_path / "model.json"
    d = _broken(joint().to_json(), how)
    path.write_text(json.dumps(d))
    with pytest.raises(DataError) as err:
        FittedModel.load(path)
    text = str(err.value)
    assert "\n" not in text
    assert text.startswith(f"{path}: field '")
    assert BROKEN[how] in text, text


# ----------------------------------------------------------------------------------------------
# at_ambient


def test_at_a_sets_own_ambient_it_is_that_set_exactly():
    m = joint()
    for a, s in m.by_temperature:
        frame = frame_at(a)
        want = s.simulate(frame, SOC0)
        assert np.array_equal(m.at_ambient(a).simulate(frame, SOC0), want)
        assert np.array_equal(m.simulate(frame, SOC0), want)  # the first temperature sample
        assert np.array_equal(m.simulate(frame), s.simulate(frame))  # the library's start


def test_between_two_sets_each_parameter_is_linear_in_one_over_t():
    m = joint()
    cold, room = m.by_temperature[0][1].parameters(), m.by_temperature[1][1].parameters()
    got = m.at_ambient(10.0).parameters()
    w = (inverse_k(10.0) - inverse_k(0.0)) / (inverse_k(25.0) - inverse_k(0.0))
    assert 0.0 < w < 1.0
    assert w != pytest.approx(10.0 / 25.0, abs=1e-3)
    # by hand: R0 0.12 Ω at 0 °C, 0.0536 Ω at 25 °C
    assert got["r0_ohm"] == pytest.approx(0.12 + w * (0.0536 - 0.12), rel=1e-12)
    assert got["tau1_s"] == pytest.approx(150.0 + w * (TRUTH["tau1_s"] - 150.0), rel=1e-12)
    for k in cold:
        lo, hi = sorted((cold[k], room[k]))
        assert lo - 1e-12 * abs(lo) <= got[k] <= hi + 1e-12 * abs(hi), k
    # linear in 1/T: three ambients between lie on one line
    r0 = [m.at_ambient(c).parameters()["r0_ohm"] for c in (5.0, 12.0, 20.0)]
    slope = [(r0[j + 1] - r0[j]) / (inverse_k(c1) - inverse_k(c0))
             for j, (c0, c1) in enumerate([(5.0, 12.0), (12.0, 20.0)])]  # fmt: skip
    assert slope[0] == pytest.approx(slope[1], rel=1e-9)
    assert "interpolated linearly in 1/T between the sets at 0 and 25" in m.ambient_note(10.0)
    # and the voltage lies between the two sets' on a record at 10 °C
    frame = frame_at(10.0)
    v = [s.simulate(frame, SOC0) for _, s in m.by_temperature[:2]]
    mid = m.simulate(frame, SOC0)
    assert np.all((mid - np.minimum(*v) >= -1e-9) & (np.maximum(*v) - mid >= -1e-9))
    assert not np.array_equal(mid, v[0])
    assert not np.array_equal(mid, v[1])


def test_an_interpolated_model_carries_intervals_that_load_and_estimate_reads(tmp_path):
    """``estimate`` sets its noise from the intervals' widths: the interpolated model's are the
    sets' interpolated, consistent with its bounds (the model saves and loads)."""
    from avoa_pipeline import estimate

    m = joint()
    mid = m.at_ambient(10.0)
    r0 = mid.intervals["parameters"]["r0_ohm"]
    assert r0["low95"] < mid.parameters()["r0_ohm"] < r0["high95"]
    mid.save(tmp_path / "mid.json")
    assert FittedModel.load(tmp_path / "mid.json").parameters() == pytest.approx(
        mid.parameters(), rel=1e-12)  # fmt: skip
    frame = frame_at(10.0, seconds=600)
    frame["voltage_v"] = mid.simulate(frame, SOC0)
    got = estimate.estimate_record(m, frame)  # the first temperature sample: 10 °C
    want = estimate.estimate_record(mid, frame)
    assert got.summary["capacity_ah"] == pytest.approx(mid.parameters()["capacity_ah"])
    assert np.array_equal(got.frame["soc"], want.frame["soc"])
    assert got.summary["noise"] == want.summary["noise"]


def test_outside_the_sets_span_it_is_the_nearest_set():
    m = joint()
    frame = frame_at(-10.0)
    assert np.array_equal(m.at_ambient(-10.0).simulate(frame, SOC0),
                          m.by_temperature[0][1].simulate(frame, SOC0))  # fmt: skip
    assert m.at_ambient(55.0).parameters() == m.by_temperature[2][1].parameters()
    assert "outside the sets' 0..40 °C" in m.ambient_note(55.0)


def test_sets_whose_parameters_mean_different_things_fall_back_to_the_nearest_set():
    other = ecm.OcvTable(TABLE.lo, TABLE.step, TABLE.values + 0.002, source="other.csv")
    given = sets()
    given[0] = (0.0, cell((), SETS[0.0][1], 274.0, table=other))
    m = FittedModel.per_temperature(given)
    assert m.at_ambient(10.0).parameters() == m.by_temperature[0][1].parameters()  # nearer 0
    assert m.at_ambient(15.0).parameters() == m.by_temperature[1][1].parameters()  # nearer 25
    assert "differ in their OCV" in m.ambient_note(10.0)
    # the reference temperatures differ too, but no law reads them: 25 and 40 °C interpolate
    assert "interpolated" in m.ambient_note(30.0)


def test_a_record_without_temperature_is_refused_in_one_line():
    with pytest.raises(DataError, match="field 'by_temperature': the model holds per-temperature"):
        joint().simulate(frame_at(25.0, temperature=False))


# ----------------------------------------------------------------------------------------------
# the commands


def run_cli(args, capsys):
    code = cli.main(args)
    out, err = capsys.readouterr()
    return code, out, err


@pytest.fixture
def files(tmp_path):
    """model.json of the sets; a record at 0 °C (its temperature measured), and one without
    temperature whose sidecar gives 40 °C; each the voltage of its own set."""
    m = joint()
    m.save(tmp_path / "model.json")
    cold, warm = m.by_temperature[0][1], m.by_temperature[2][1]
    f = frame_at(0.0)
    f.assign(voltage_v=cold.simulate(f, SOC0)).to_csv(tmp_path / "cold.csv", index=False)
    f = frame_at(40.0, temperature=False)
    f.assign(voltage_v=warm.simulate(f, SOC0)).to_csv(tmp_path / "warm.csv", index=False)
    (tmp_path / "warm.json").write_text(json.dumps({"ambient_temperature_c": 40.0}))
    f.assign(voltage_v=warm.simulate(f, SOC0)).to_csv(tmp_path / "bare.csv", index=False)
    return tmp_path


def test_simulate_runs_the_set_at_the_records_ambient(files, capsys):
    for data, ambient, where in (("cold", 0, "first temperature sample"),
                                 ("warm", 40, "sidecar")):  # fmt: skip
        out = files / f"{data}-pred.csv"
        code, _text, err = run_cli(["simulate", str(files / "model.json"),
                                   str(files / f"{data}.csv"), "--out", str(out),
                                   "--soc0", str(SOC0)], capsys)  # fmt: skip
        assert code == 0, err
        assert f"parameters at ambient {ambient:g} °C ({where})" in err, err
        assert f"the set at {ambient:g} °C" in err
        assert pd.read_csv(out)["error_mv"].abs().max() < 1e-6  # the set's own voltage
    # --ambient-c chooses the parameters; the measured temperature still runs
    out = files / "cold-at-25.csv"
    code, _, err = run_cli(["simulate", str(files / "model.json"), str(files / "cold.csv"),
                            "--out", str(out), "--soc0", str(SOC0), "--ambient-c", "25"],
                           capsys)  # fmt: skip
    assert code == 0, err
    assert "parameters at ambient 25 °C (--ambient-c)" in err
    assert pd.read_csv(out)["error_mv"].abs().max() > 5.0  # the 25 °C cell, not the cold one


def test_simulate_refuses_a_record_with_no_ambient_in_one_line(files, capsys):
    out = files / "bare-pred.csv"
    code, _, err = run_cli(["simulate", str(files / "model.json"), str(files / "bare.csv"),
                            "--out", str(out)], capsys)  # fmt: skip
    assert code == 2
    assert err.count("\n") == 1, err
    assert "model.json: field 'by_temperature': the model holds per-temperature" in err
    assert not out.exists()


def test_estimate_runs_the_set_at_the_records_ambient(files, capsys):
    joint().by_temperature[1][1].save(files / "room.json")  # the 25 °C set alone

    def estimate(model, data):
        out = files / f"{model}-{data}-soc.csv"
        code, _, err = run_cli(["estimate", str(files / f"{model}.json"),
                                str(files / f"{data}.csv"), "--out", str(out)],
                               capsys)  # fmt: skip
        assert code == 0, err
        return json.loads(out.with_suffix(".json").read_text()), err

    for data, ambient, capacity in (("cold", 0, 2.40), ("warm", 40, 2.62)):
        summary, err = estimate("model", data)
        assert f"parameters at ambient {ambient:g} °C" in err
        assert summary["capacity_ah"] == pytest.approx(capacity, rel=1e-12)
        # the record's own set follows its voltage better than the 25 °C set would
        other, _ = estimate("room", data)
        assert summary["innovation_rms_mv"] < 0.5 * other["innovation_rms_mv"]
    code, _, err = run_cli(["estimate", str(files / "model.json"), str(files / "bare.csv"),
                            "--out", str(files / "bare-soc.csv")], capsys)  # fmt: skip
    assert code == 2
    assert "field 'by_temperature'" in err
    assert err.count("\n") == 1


def test_the_api_runs_the_set_at_the_records_ambient(files):
    from avoa_pipeline import load_model

    model = load_model(files / "model.json")
    pred = model.simulate(files / "cold.csv", soc0=SOC0)
    assert pred["error_mv"].abs().max() < 1e-6
    est = model.estimate(files / "warm.csv")
    assert est.summary["capacity_ah"] == pytest.approx(2.62, rel=1e-12)


def test_the_table_holds_each_sets_rows_at_its_ambient(files, capsys):
    out = files / "cell.csv"
    code, _text, err = run_cli(["export", str(files / "model.json"), "--to", "table", "--out",
                               str(out)], capsys)  # fmt: skip
    assert code == 0, err
    tab = pd.read_csv(out)
    side = json.loads(out.with_suffix(".json").read_text())
    assert sorted(set(tab["temperature_c"])) == [0.0, 25.0, 40.0]
    assert side["grid"]["temperature_c"] == [0.0, 25.0, 40.0]
    m = joint()
    for a, s in m.by_temperature:
        rows = tab[tab["temperature_c"] == a]
        p = s.parameters()
        assert np.allclose(rows["r0_ohm"], p["r0_ohm"], rtol=1e-9)
        assert np.allclose(rows["capacity_ah"], p["capacity_ah"], rtol=1e-9)
        assert np.allclose(rows["r2_ohm"], p["r2_ohm"], rtol=1e-9)
    cold = tab[tab["temperature_c"] == 0.0]
    assert (cold["r2_ohm"] == 0).all()
    assert cold["c2_f"].isna().all()
    assert tab.loc[tab["temperature_c"] == 25.0, "c2_f"].notna().all()
    assert [e["ambient_c"] for e in side["by_temperature"]] == [0.0, 25.0, 40.0]
    assert side["by_temperature"][0]["scalars"]["capacity_ah"]["value"] == pytest.approx(2.40)
    assert "1/T" in side["columns"]["temperature_c"]["meaning"]
    assert any("per-temperature parameter sets" in c for c in side["cannot"])
    assert "NaN" not in out.with_suffix(".json").read_text()
    # on a grid between the sets, a row is at_ambient's there
    code, _, err = run_cli(["export", str(files / "model.json"), "--to", "table", "--out",
                            str(files / "mid.csv"), "--temperatures", "10"], capsys)  # fmt: skip
    assert code == 0, err
    mid = pd.read_csv(files / "mid.csv")
    assert np.allclose(mid["r0_ohm"], m.at_ambient(10.0).parameters()["r0_ohm"], rtol=1e-9)


def test_the_pybamm_export_refuses_it_in_one_line(files, capsys):
    out = files / "cell.py"
    code, _, err = run_cli(["export", str(files / "model.json"), "--to", "pybamm", "--out",
                            str(out)], capsys)  # fmt: skip
    assert code == 2
    assert err.count("\n") == 1, err
    assert "model.json: field 'by_temperature': per-temperature parameter sets" in err
    assert not out.exists()


def test_the_sets_ambients_are_the_heat_blocks_range():
    from avoa_pipeline.model import heat

    lo, hi = heat.AMBIENT_RANGE_C
    d = joint().to_json()
    d["by_temperature"][0]["ambient_c"] = lo - 1.0
    with pytest.raises(DataError, match=f"outside a cell's ambient .°C. \\[{lo:g}, {hi:g}\\]"):
        FittedModel.from_json(d)


def test_where_the_joint_model_is_worse_at_one_temperature_only_that_one_takes_its_own():
    """docs/temperature-rule.md part 4, as amended: the test finds the joint model worse at
    0 °C only, so 0 °C gets its own set and 25 and 40 °C the joint model itself; the held-out
    RMSE handed over is each temperature's under the model it got."""
    from avoa_pipeline.gap import diagnose as gd

    own = sets()
    model = cell(("second_rc",), {"r0_ohm": 0.07}, 299.0)
    rows = [{"ambient_c": a, "own_model": "x", "joint_worse": a == 0.0, "own_handed_over": a == 0.0,
             "own_heldout_rmse_mv": 5.0, "joint_heldout_rmse_mv": j}
            for a, j in zip(SETS, (9.0, 4.0, 6.0), strict=True)]  # fmt: skip
    pt = {"groups": rows, "joint_worse": True}
    handed = {"name": "second_rc", "effects": ["second_rc"], "n_params": 8,
              "heldout_rmse_mv": 6.5, "score": "s", "parameters": model.parameters()}  # fmt: skip
    out, combined = gd._never_worse(None, handed, model, pt, own)
    got = dict(combined.by_temperature)
    assert got[0.0].parameters()["r0_ohm"] == pytest.approx(0.12)
    for a in (25.0, 40.0):
        assert got[a].parameters()["r0_ohm"] == pytest.approx(0.07)
    assert [r["handed_over"] for r in out["per_temperature"]["groups"]] == [
        "x", "the joint model", "the joint model"]  # fmt: skip
    assert out["heldout_rmse_mv"] == pytest.approx(np.sqrt((25 + 16 + 36) / 3))
    assert out["joint"]["heldout_rmse_mv"] == 6.5
    # at 30 °C, between two sets of the joint model: the joint model's values
    assert combined.at_ambient(30.0).parameters()["r0_ohm"] == pytest.approx(0.07)
