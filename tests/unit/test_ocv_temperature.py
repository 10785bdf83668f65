"""OCV over temperature (docs/temperature-rule.md part 5): slow tests at several ambients give the
OCV table a ∂U/∂T profile over SOC, which the ``entropic`` element scales.

The slow tests are made with the project's own simulator from a known OCV and a known
SOC-dependent ∂U/∂T (an ``entropic`` element at scale 1 on a table carrying the true profile),
C/20 down and back with an RC branch and R0, 1 mV of voltage noise quantised to 1 mV, logged as
cyclers log (``temperature_cells.cycler_log``: coarse rests, the current a sample late)."""

import dataclasses
import json

import numpy as np
import pandas as pd
import pytest

from avoa_pipeline import inputs
from avoa_pipeline.cli import main
from avoa_pipeline.gap import temperature_cells
from avoa_pipeline.model import ecm, fitted, ocv
from avoa_pipeline.model.fitted import FittedModel, fit_model

Q_AH = 3.0
TREF_K = 298.15  # the true table's temperature
NOISE_V = 1e-3  # the voltage channel's noise, and its quantum
SLOW_DT_S = 10.0  # a slow test logged every 10 s under load, every 60 s at rest
AMBIENTS_C = (10.0, 25.0, 40.0)


def true_ocv(s):
    s = np.asarray(s, dtype=float)
    return 3.0 + 1.1 * s - 0.25 * np.exp(-s / 0.04) + 0.12 * np.tanh((s - 0.6) / 0.1)


def true_dudt(s):
    """V/K: −0.3 mV/K at empty rising to +0.2 mV/K at full, with a dip near SOC 0.6 (graphite's
    stage change); inside the ±1 mV/K of full cells."""
    s = np.asarray(s, dtype=float)
    return 1e-3 * (-0.3 + 0.5 * s - 0.15 * np.exp(-(((s - 0.6) / 0.08) ** 2)))


def _true_table() -> ecm.OcvTable:
    grid = np.linspace(0.0, 1.0, 201)
    table = ecm.OcvTable.from_points(grid, true_ocv(grid))
    return dataclasses.replace(table, dudt_v_per_k=true_dudt(table.grid()))


TRUE = _true_table()
TRUE_PARAMS = {"capacity_ah": Q_AH, "soc0": 1.0, "r0_ohm": 0.03, "r1_ohm": 0.015,
               "tau1_s": 60.0, "entropic_dudt_v_per_k": TRUE.dudt_peak(),
               "tref_k": TREF_K}  # fmt: skip
TRUE_CONFIG = ecm.Config(("entropic",), TRUE)


def _measured(frame: pd.DataFrame, ambient_c: float, seed: int, soc0: float = 1.0):
    """``frame``'s voltage from the true cell at a steady ``ambient_c``, with sensor noise."""
    f = frame.assign(temperature_c=ambient_c)
    v = ecm.simulate_params(f, {**TRUE_PARAMS, "soc0": soc0}, TRUE_CONFIG)
    rng = np.random.default_rng(seed)
    v = np.round((v + NOISE_V * rng.standard_normal(v.size)) / NOISE_V) * NOISE_V
    temp = np.round((ambient_c + 0.05 * rng.standard_normal(v.size)) / 0.01) * 0.01
    return f.assign(voltage_v=v, temperature_c=temp)


def slow_test(ambient_c: float, seed: int) -> pd.DataFrame:
    """C/20 full to empty, a rest, C/20 back to full, logged as a cycler logs."""
    i = Q_AH / 20.0
    n = round(Q_AH / i * 3600.0 / SLOW_DT_S)
    cur = np.concatenate([np.zeros(30), np.full(n, i), np.zeros(60), np.full(n, -i),
                          np.zeros(30)])  # fmt: skip
    t = SLOW_DT_S * np.arange(cur.size)
    frame = pd.DataFrame({"time_s": t, "current_a": cur, "voltage_v": 0.0})
    return temperature_cells.cycler_log(_measured(frame, ambient_c, seed), 60.0)


def drive(ambient_c: float, seed: int) -> pd.DataFrame:
    """1 Hz, from 95 % SOC: seven 10-min 2 A discharges, each followed by a 1 A charge pulse
    and a rest, down to about 30 % SOC (so the OCV's SOC dependence is in every record)."""
    parts = [(120, 0.0)]
    for _ in range(7):
        parts += [(600, 2.0), (120, 0.0), (120, -1.0), (240, 0.0)]
    cur = np.concatenate([np.full(d, c) for d, c in parts])
    frame = pd.DataFrame({"time_s": np.arange(cur.size, dtype=float), "current_a": cur,
                          "voltage_v": 0.0})  # fmt: skip
    return _measured(frame, ambient_c, seed, soc0=0.95)


def _write(frame: pd.DataFrame, path) -> str:
    frame.to_csv(path, index=False)
    return str(path)


@pytest.fixture(scope="module")
def slow_files(tmp_path_factory):
    root = tmp_path_factory.mktemp("slow")
    return [_write(slow_test(a, k), root / f"slow_{a:g}C.csv") for k, a in enumerate(AMBIENTS_C)]


@pytest.fixture(scope="module")
def profile_model(slow_files) -> FittedModel:
    """entropic scaling the slow tests' profile, fitted to drives at 25 and 40 °C."""
    table = inputs.read_ocv(slow_files)
    return fit_model([drive(25.0, 11), drive(40.0, 12)], ecm.Config(("entropic",), table),
                     Q_AH).model  # fmt: skip


def test_the_profile_is_recovered_within_its_noise(slow_files):
    """∂U/∂T at each SOC within its noise: each point's OCV carries about 0.6 mV (1 mV of noise,
    the branches averaged), so its slope over 10, 25 and 40 °C about 0.6/√450 = 0.028 mV/K; the
    RMS error over SOC 5-95 % stays below 0.05 mV/K (a profile with its SOC dependence lost,
    its mean alone, is 0.13 mV/K off), and the largest below 0.12 mV/K (four standard errors)."""
    table = inputs.read_ocv(slow_files)
    g = table.grid()
    mid = (g >= 0.05) & (g <= 0.95)
    err = table.dudt_v_per_k[mid] - true_dudt(g[mid])
    assert np.sqrt(np.mean(err**2)) < 0.05e-3
    assert np.max(np.abs(err)) < 0.12e-3
    flat = true_dudt(g[mid]).mean() - true_dudt(g[mid])
    assert np.sqrt(np.mean(flat**2)) > 0.1e-3  # the test can tell a profile from a constant
    # with no training records the table is the OCV at 25 °C, the middle slow test's
    assert table.source == slow_files[1]
    assert np.sqrt(np.mean((table.values[mid] - true_ocv(g[mid])) ** 2)) < 1e-3
    assert all(path in table.dudt_how for path in slow_files)


def test_the_table_is_the_ocv_at_the_training_records_reference_temperature(slow_files,
                                                                             tmp_path):  # fmt: skip
    """Training records at 35 °C: the slow test nearest (40 °C), moved by its profile to 35 °C,
    is the true OCV at 35 °C within the noise (2 mV off without the move at the dip)."""
    train = _write(drive(35.0, 7), tmp_path / "d35.csv")
    table = inputs.read_inputs([train], (), slow_files).ocv
    assert table.source == slow_files[2]
    g = table.grid()
    mid = (g >= 0.05) & (g <= 0.95)
    tref_c = fitted.reference_temperature([pd.read_csv(train)]) - 273.15
    want = true_ocv(g[mid]) + true_dudt(g[mid]) * (tref_c + 273.15 - TREF_K)
    assert np.sqrt(np.mean((table.values[mid] - want) ** 2)) < 0.8e-3
    assert np.all(np.diff(table.values) > 0.0)  # still inverts


def test_one_ocv_is_as_before(slow_files, tmp_path):
    """One --ocv: the slow test's own table, no profile, and model.json's table as before."""
    train = _write(drive(25.0, 3), tmp_path / "d25.csv")
    got = inputs.read_inputs([train], (), slow_files[1]).ocv
    listed = inputs.read_inputs([train], (), [slow_files[1]]).ocv
    want = ocv.from_slow_test(pd.read_csv(slow_files[1]), slow_files[1])
    for table in (got, listed):
        assert table.dudt_v_per_k is None
        assert table.dudt_shape().size == 0
        assert np.array_equal(table.values, want.values)
        assert ocv.to_json(table) == ocv.to_json(want)
    assert "dudt_v_per_k" not in ocv.to_json(got)
    assert table.entropic_shape(0.3) == 1.0


def test_the_entropic_term_scales_the_profile_and_stands_alone_without_one():
    """With a profile the term is dudt·shape(SOC)·(T − Tref) (shape = profile / its peak, so
    at scale 1 the true ∂U/∂T); without one it is the constant coefficient's dudt·(T − Tref).
    (Bit for bit as before: tests/unit/test_kernel_golden.py.)"""
    frame = drive(40.0, 1)
    params = {**TRUE_PARAMS, "soc0": 0.95}
    at_ref = ecm.simulate_params(frame.assign(temperature_c=25.0), params, TRUE_CONFIG)
    warm = ecm.simulate_params(frame, params, TRUE_CONFIG)
    cur = frame["current_a"].to_numpy()
    soc = 0.95 - np.r_[0.0, np.cumsum(cur[:-1])] / 3600.0 / Q_AH  # 1 s steps, forward Euler
    dtemp = frame["temperature_c"].to_numpy() + 273.15 - TREF_K
    assert np.max(np.abs((warm - at_ref) - true_dudt(soc) * dtemp)) < 2e-5  # grid, linear
    plain = ecm.Config(("entropic",), dataclasses.replace(TRUE, dudt_v_per_k=None))
    const = ecm.simulate_params(frame, params, plain)
    off = ecm.simulate_params(frame, {**params, "entropic_dudt_v_per_k": 0.0}, plain)
    assert np.allclose(const - off, TRUE.dudt_peak() * dtemp, rtol=0.0, atol=1e-12)


def _rmse(model: FittedModel, frame: pd.DataFrame) -> float:
    return float(np.sqrt(np.mean((model.simulate(frame) - frame["voltage_v"].to_numpy()) ** 2)))


def test_a_drive_at_another_temperature_is_predicted_better_with_the_profile(slow_files,
                                                                             tmp_path):  # fmt: skip
    """Trained on drives at 25 and 40 °C, a drive at 5 °C (outside them): the entropic term
    scaling the slow tests' profile predicts it better than the constant coefficient fitted
    from the drives (one slow test, as before) and than no entropic term; the scale comes
    out near 1 (the truth), and its prior holds the profile times the scale within 1 mV/K."""
    trains = [drive(25.0, 11), drive(40.0, 12)]
    paths = [_write(f, tmp_path / f"d{k}.csv") for k, f in enumerate(trains)]
    with_profile = inputs.read_inputs(paths, (), slow_files).ocv
    one = inputs.read_inputs(paths, (), slow_files[1]).ocv
    cold = drive(5.0, 13)
    fits = {
        "profile": fit_model(trains, ecm.Config(("entropic",), with_profile), Q_AH),
        "constant": fit_model(trains, ecm.Config(("entropic",), one), Q_AH),
        "none": fit_model(trains, ecm.Config((), one), Q_AH),
    }
    rmse = {k: _rmse(f.model, cold) for k, f in fits.items()}
    print(f"held-out 5 °C drive RMSE (mV): { ({k: round(1e3 * v, 3) for k, v in rmse.items()}) }")
    assert rmse["profile"] < 0.8 * rmse["constant"], rmse
    assert rmse["profile"] < 0.8 * rmse["none"], rmse
    assert rmse["profile"] < 2.0 * NOISE_V, rmse
    dudt = fits["profile"].model.parameters()["entropic_dudt_v_per_k"]
    scale = dudt / with_profile.dudt_peak()
    print(f"scale {scale:.4f}")
    assert 0.8 < scale < 1.2, scale


def _diagnose(tmp_path, capsys, *argv):
    out = tmp_path / "out"
    code = main(["diagnose", *argv, "--out", str(out)])
    err = capsys.readouterr().err
    return code, err, out


def test_two_slow_tests_at_one_temperature_are_refused_in_one_line(slow_files, tmp_path, capsys):
    again = _write(slow_test(26.0, 20), tmp_path / "slow_26C.csv")
    train = _write(drive(25.0, 3), tmp_path / "d25.csv")
    code, err, out = _diagnose(tmp_path, capsys, train, "--ocv", slow_files[1], "--ocv", again)
    assert code == 2
    assert err.count("\n") == 1
    assert "Traceback" not in err
    assert slow_files[1] in err
    assert again in err
    assert "within 2 K" in err
    assert not out.exists() or not any(out.iterdir())


def test_a_slow_test_without_temperature_is_refused_where_ocv_is_repeated(slow_files, tmp_path,
                                                                          capsys):  # fmt: skip
    bare = _write(pd.read_csv(slow_files[0]).drop(columns="temperature_c"),
                  tmp_path / "bare.csv")  # fmt: skip
    train = _write(drive(25.0, 3), tmp_path / "d25.csv")
    code, err, out = _diagnose(tmp_path, capsys, train, "--ocv", bare, "--ocv", slow_files[1])
    assert code == 2
    assert err.count("\n") == 1
    assert "Traceback" not in err
    assert bare in err
    assert "'temperature_c'" in err
    assert "ambient_temperature_c" in err
    assert not out.exists() or not any(out.iterdir())
    table = _write(pd.DataFrame({"soc": [0.0, 0.5, 1.0], "ocv_v": [3.0, 3.6, 4.1]}),
                   tmp_path / "table.csv")  # fmt: skip
    code, err, _ = _diagnose(tmp_path, capsys, train, "--ocv", table, "--ocv", slow_files[1])
    assert code == 2
    assert err.count("\n") == 1
    assert table in err
    assert "'soc', 'ocv_v'" in err


def test_the_profile_goes_through_model_json(profile_model, tmp_path):
    """model.json holds the profile and reads it back: the same voltages; a profile of another
    length is refused naming the field."""
    model, table = profile_model, profile_model.config.table
    path = tmp_path / "model.json"
    model.save(path)
    back = FittedModel.load(path)
    assert np.array_equal(back.config.table.dudt_v_per_k, table.dudt_v_per_k)
    cold = drive(5.0, 13)
    assert np.array_equal(back.simulate(cold), model.simulate(cold))
    d = json.loads(path.read_text())
    d["ocv_table"]["dudt_v_per_k"] = d["ocv_table"]["dudt_v_per_k"][:-1]
    path.write_text(json.dumps(d))
    with pytest.raises(Exception, match=r"ocv_table\.dudt_v_per_k"):
        FittedModel.load(path)


def test_the_filters_open_loop_reads_the_profile(profile_model):
    """estimate's state-space step and the simulator are one statement with the profile too
    (to rounding, 1e-9 V, as tests/unit/test_estimate.py holds every element); the model with
    the profile dropped is millivolts away on the 5 °C drive, so the check can fail."""
    from avoa_pipeline import estimate as E

    frame = drive(5.0, 13)
    want = profile_model.simulate(frame, soc0=0.95)
    got = E.open_loop(E.filter_model(profile_model), E.Inputs.of(profile_model.record(frame)),
                      0.95)  # fmt: skip
    assert np.max(np.abs(got - want)) <= 1e-9
    flat = dataclasses.replace(profile_model.config.table, dudt_v_per_k=None)
    other = dataclasses.replace(profile_model, config=ecm.Config(("entropic",), flat))
    assert np.max(np.abs(other.simulate(frame, soc0=0.95) - want)) > 1e-3


def test_the_table_export_reads_the_profile_and_pybamm_refuses_it(profile_model):
    """export --to table: ocv_v over temperature moves by dudt·shape(SOC)·(T − Tref) at each
    SOC; export --to pybamm refuses the profile in one line naming the field."""
    from avoa_pipeline.errors import UserError
    from avoa_pipeline.interop import pybamm as to_pybamm
    from avoa_pipeline.interop import table as to_table

    model, table = profile_model, profile_model.config.table
    soc = np.linspace(0.1, 0.9, 9)
    tref_c = model.tref_k - 273.15
    grid = to_table.grid_values(model, soc, [tref_c, tref_c + 10.0])
    ocv_v = np.asarray(grid["ocv_v"]).reshape(2, -1)
    dudt = model.parameters()["entropic_dudt_v_per_k"]
    want = dudt * table.entropic_shape(soc) * 10.0
    assert np.allclose(ocv_v[1] - ocv_v[0], want, rtol=0.0, atol=1e-9)
    assert np.ptp(want) > 1e-3  # the profile moves it by more than a millivolt across SOC
    with pytest.raises(UserError, match=r"ocv_table\.dudt_v_per_k") as err:
        to_pybamm.check_exportable(model, "model.json", drop_unsupported=False)
    assert "\n" not in str(err.value)


@pytest.mark.slow
def test_diagnose_with_three_slow_tests_end_to_end(slow_files, tmp_path, capsys):
    """diagnose --ocv ×3 on drives at 25 and 40 °C hands over entropic scaling the profile
    (held out by record, admitted by identification and prior: G = 2); model.json carries the
    profile; simulate predicts the unseen 5 °C drive within 2 mV RMS and estimate's SOC ends
    within 2 % of the truth; export --to table writes it and --to pybamm refuses in one line.
    51 s on 2 cores (175 s beside two other jobs)."""
    paths = [_write(drive(a, s), tmp_path / f"drive_{a:g}C.csv")
             for a, s in ((25.0, 11), (40.0, 12), (5.0, 13))]  # fmt: skip
    out = tmp_path / "out"
    args = ["diagnose", paths[0], paths[1], "--capacity-ah", str(Q_AH), "--out", str(out)]
    assert main([*args, *(x for f in slow_files for x in ("--ocv", f))]) == 0
    d = json.loads((out / "diagnosis.json").read_text())
    assert "entropic" in d["handed_over"]["effects"]
    profile = d["ocv"]["dudt_profile"]
    assert 0.7 < profile["scale_handed_over"] < 1.3
    model = json.loads((out / "model.json").read_text())
    assert len(model["ocv_table"]["dudt_v_per_k"]) == len(model["ocv_table"]["ocv_v"])
    sim = tmp_path / "sim.csv"
    assert main(["simulate", str(out / "model.json"), paths[2], "--out", str(sim)]) == 0
    err_mv = pd.read_csv(sim)["error_mv"].to_numpy()
    assert np.sqrt(np.mean(err_mv**2)) < 2.0
    est = tmp_path / "est.csv"
    assert main(["estimate", str(out / "model.json"), paths[2], "--out", str(est)]) == 0
    cold = pd.read_csv(paths[2])
    true_end = 0.95 - cold["current_a"].to_numpy()[:-1].sum() / 3600.0 / Q_AH
    assert abs(pd.read_csv(est)["soc"].to_numpy()[-1] - true_end) < 0.02
    tab = tmp_path / "table.csv"
    assert main(["export", str(out / "model.json"), "--to", "table", "--out", str(tab)]) == 0
    capsys.readouterr()
    code = main(["export", str(out / "model.json"), "--to", "pybamm", "--out",
                 str(tmp_path / "cell.py")])  # fmt: skip
    err = capsys.readouterr().err
    assert code == 2
    assert err.count("\n") == 1
    assert "dudt_v_per_k" in err
