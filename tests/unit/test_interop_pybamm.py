"""Export to PyBaMM's Thevenin model (``avoa_pipeline.interop.pybamm``, ``export --to pybamm``).

The comparison (docs/pybamm.md): one record, its current held over each interval as our records
define it (row k's current over [t_k, t_k+1)) and its measured temperature held the same way;
PyBaMM's voltage at each sample time from the written module's ``simulate`` (IDAKLU, rtol = atol
= 1e-6) against ``FittedModel.simulate`` from the same initial SOC; RMS of the difference over
all samples ≤ 0.1 mV, for every element that maps, alone and stacked, on both OCV kinds.
"""

from __future__ import annotations

import dataclasses
import importlib.util
import json
import os
import subprocess
import sys
import textwrap

import numpy as np
import pandas as pd
import pytest
from test_ecm import ACTIVE, TRUTH
from test_model_json import heat_block

from avoa_pipeline import cli
from avoa_pipeline.interop import pybamm as X
from avoa_pipeline.model import ecm, elements, heat
from avoa_pipeline.model.elements.element import Export
from avoa_pipeline.model.fitted import FittedModel

TOL_RMS_MV = 0.1
SOC0 = 0.6
TREF_K = 300.15

# the cell (test_ecm's truth) and each element's parameters away from neutral (test_ecm's)
BASE = {k: v for k, v in TRUTH.items() if k != "soc0"}

R1_SOC_GENTLE = {"r1_soc_u0": 0.3, "r1_soc_u2": 0.2}
R1_SOC_STEEP = {"r1_soc_u0": 1.5, "r1_soc_u2": 1.0}  # a factor of e^±3 across the knots
# test_ecm's 0.97 moves this record's voltage by 0.3 mV: too little to test the export by
ETA_LOW = {"coulombic_efficiency": 0.8}

# every exportable configuration the diagnosis can select: each element alone on the OCV kind
# it applies to, RC branches 1-3, and everything stacked
CASES = [
    ("rational", (), {}),
    ("table", (), {}),
    ("table", ("second_rc",), {}),
    ("rational", ("second_rc", "third_rc"), {}),
    ("table", ("second_rc",), {"r1_ohm": 0.0}),  # a branch with R = 0 is left out
    ("table", ("soc_resistance",), {}),
    ("rational", ("soc_resistance",), {}),
    ("table", ("thermal",), {}),
    ("rational", ("butler_volmer",), {}),
    ("table", ("ocv_shape",), {}),
    ("rational", ("voltage_offset", "ocv_shape"), {}),
    ("table", ("second_rc", "third_rc", "soc_resistance", "thermal", "butler_volmer",
               "ocv_shape"), {}),
    ("table", ("r0_soc",), {}),
    # R1 by SOC, held over each interval at its value at the interval's start, in ours and in
    # the module: a factor rising 25 % per 0.1 SOC (test_ecm's: 60 %) under the 6C pulse, then
    # a steep one with soc_resistance (which fails the bound without the hold)
    ("rational", ("r1_soc",), R1_SOC_GENTLE),
    ("table", ("r0_charge",), {}),
    ("table", ("butler_volmer", "bv_arrhenius"), {}),
    ("table", ("second_rc", "r0_soc", "r1_soc", "r0_charge", "thermal"), R1_SOC_GENTLE),
    ("table", ("second_rc", "soc_resistance", "r1_soc"), R1_SOC_STEEP),
    # the states beyond Thevenin's (issue 28): submodels of the module's own
    ("table", ("diffusion",), {}),
    ("rational", ("diffusion",), {}),
    ("rational", ("hysteresis",), {}),
    ("table", ("current_offset",), {}),
    ("table", ("coulombic_efficiency",), ETA_LOW),
    ("table", ("hysteresis", "coulombic_efficiency"), ETA_LOW),
    ("table", ("second_rc", "diffusion", "hysteresis", "thermal", "butler_volmer",
               "current_offset", "coulombic_efficiency", "ocv_shape"), ETA_LOW),
    # the temperature laws (issue 28), on the record's moving temperature: τ_j(T), OCV + ∂U/∂T·ΔT,
    # Q(T) wherever the charge is counted (the SoC, hysteresis's rate, the interval-start SoC)
    ("table", ("thermal", "thermal_tau"), {}),
    ("table", ("second_rc", "thermal", "thermal_tau"), {}),
    ("table", ("entropic",), {}),
    ("rational", ("entropic", "hysteresis"), {}),
    ("table", ("capacity_temperature",), {}),
    ("table", ("capacity_temperature", "hysteresis", "coulombic_efficiency"), ETA_LOW),
    ("table", ("capacity_temperature", "second_rc", "soc_resistance", "r1_soc"), R1_SOC_GENTLE),
    ("table", ("second_rc", "diffusion", "hysteresis", "thermal", "thermal_tau", "entropic",
               "capacity_temperature", "butler_volmer", "coulombic_efficiency"), ETA_LOW),
]  # fmt: skip
CASE_IDS = ["+".join((k, *e)) + ("-r1=0" if "r1_ohm" in x else "") for k, e, x in CASES]


def ocv_table() -> ecm.OcvTable:
    soc = np.linspace(0.0, 1.0, 41)
    v = 3.3 + 0.8 * soc + 0.12 * np.tanh((soc - 0.1) / 0.05) + 0.03 * np.sin(9 * soc)
    return ecm.OcvTable.from_points(soc, v, source="ocv.csv", how="test table")


def fitted(kind: str, effects, extra=None) -> FittedModel:
    """A FittedModel of chosen parameter values (bounds ±1 around them, internal coordinates)."""
    config = ecm.Config(tuple(effects), ocv_table() if kind == "table" else None)
    names = config.names()
    values = {**BASE, **{k: v for e in effects for k, v in ACTIVE[e].items()}, **(extra or {})}
    if kind == "table":
        values["voltage_offset_v"] = -0.01  # the table's fitted offset (base)
    x = ecm.vector({k: v for k, v in values.items() if ecm.BY_REPORT[k] in names})
    bounds = {n: (x[ecm.IDX[n]] - 1.0, x[ecm.IDX[n]] + 1.0) for n in names
              if not ecm.PARAMS[n].per_record}  # fmt: skip
    return FittedModel(config, x, ecm.Knots(0.2, 0.12), TREF_K, bounds, {"selected_by": "test"})


def record(uniform: bool = True, temperature: bool = True, seed: int = 0) -> pd.DataFrame:
    """About 300 samples: rest, discharge, rest, a drive segment (a new current every sample),
    a 6C pulse, rest, charge, rest; with ``uniform`` False, 1-4 s steps."""
    rng = np.random.default_rng(seed)
    c = BASE["capacity_ah"]  # A per C
    segments = [np.zeros(15), np.full(50, 2 * c), np.zeros(25),
                rng.uniform(-1.5 * c, 3 * c, 60), np.full(15, 6 * c), np.zeros(30),
                np.full(50, -1.5 * c), np.zeros(40)]  # fmt: skip
    cur = np.concatenate(segments)
    dt = np.ones(cur.size) if uniform else rng.choice([1.0, 2.0, 4.0], cur.size)
    t = np.concatenate([[0.0], np.cumsum(dt[:-1])]) + 100.0
    frame = pd.DataFrame({"time_s": t, "current_a": cur, "voltage_v": np.full(t.size, 3.7)})
    if temperature:  # a measured temperature that moves every sample (5 °C over the record)
        frame["temperature_c"] = 24.0 + 5.0 * (t - t[0]) / (t[-1] - t[0]) + 0.3 * np.sin(t / 7)
    return frame


def measured(model: FittedModel, frame: pd.DataFrame) -> pd.DataFrame:
    """The record with the model's voltage from SOC0 as its measured voltage (a CSV the
    command's record checks accept)."""
    return frame.assign(voltage_v=model.simulate(frame, soc0=SOC0))


def load_module(path):
    spec = importlib.util.spec_from_file_location(path.stem, path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def rms_mv(a, b) -> float:
    return 1e3 * float(np.sqrt(np.mean((np.asarray(a) - np.asarray(b)) ** 2)))


@pytest.fixture(scope="module")
def pybamm():
    return pytest.importorskip(
        "pybamm", reason="pybamm is not installed (pip install avoa-pipeline[pybamm])"
    )


# ----------------------------------------------------------------------------------------------
# the table


def test_every_element_exports():
    """Every element declares its piece of the export (``Element.pybamm``; issue 28)."""
    assert [e for e in ecm.EFFECTS if not elements.get(e).pybamm.exported] == []
    assert X.unsupported(fitted("table", ecm.EFFECTS[:6])) == []


def without_export(monkeypatch, *names):
    """The registry with ``names`` declaring no piece (what an element PyBaMM cannot hold
    declares), for the refusal and --drop-unsupported, which no element needs today."""
    for name in names:
        e = elements.get(name)
        monkeypatch.setitem(elements.REGISTRY, name,
                            dataclasses.replace(e, pybamm=Export("no way")))  # fmt: skip


@pytest.mark.parametrize("element", ["diffusion", "hysteresis"])
def test_an_unsupported_element_is_refused_in_one_line_naming_it(monkeypatch, element):
    without_export(monkeypatch, element)
    model = fitted("table", (element,))
    with pytest.raises(X.UserError) as exc:
        X.check_exportable(model, "m.json", drop_unsupported=False)
    msg = str(exc.value)
    assert "\n" not in msg
    assert msg.startswith("m.json: element ")
    assert element in msg
    assert "--drop-unsupported" in msg
    assert X.check_exportable(model, "m.json", drop_unsupported=True) == [element]


def test_the_papers_load_resistor_is_refused():
    model = fitted("rational", ())
    model.config = ecm.Config((), None, load_ohm=2.0)
    with pytest.raises(X.UserError, match="load_ohm"):
        X.check_exportable(model, "m.json", drop_unsupported=True)


# ----------------------------------------------------------------------------------------------
# PyBaMM against our simulator


@pytest.mark.parametrize(("kind", "effects", "extra"), CASES, ids=CASE_IDS)
def test_pybamm_from_the_written_module_gives_our_voltage(pybamm, tmp_path, kind, effects, extra):
    model = fitted(kind, effects, extra)
    # 1-4 s steps: where a resistance follows the SOC (soc_resistance, r0_soc, r1_soc), our
    # simulator holds it over each interval at its value at the interval's start, and so does
    # the module (soc_at_interval_start; docs/pybamm.md, "SOC-dependent resistances and the step")
    frame = record(uniform=False)
    ours = model.simulate(frame, soc0=SOC0)
    # the elements matter on this record (else agreement would say nothing about them)
    bare = X.without(model, effects).simulate(frame, soc0=SOC0)
    if effects:
        assert rms_mv(ours, bare) > 1.0
    path = tmp_path / "cell.py"
    path.write_text(X.export(model, "model.json", soc0=SOC0).text)
    cell = load_module(path)
    expected_rc = 1 + sum(e in effects for e in ("second_rc", "third_rc")) - ("r1_ohm" in extra)
    assert cell.OPTIONS["number of rc elements"] == expected_rc
    v = cell.simulate(frame["time_s"], frame["current_a"], frame["temperature_c"])
    assert v.shape == ours.shape
    assert rms_mv(v, ours) <= TOL_RMS_MV


@pytest.mark.parametrize("effects", [("second_rc", "third_rc", "thermal", "butler_volmer"),
                                     ("diffusion", "hysteresis")])  # fmt: skip
def test_a_record_solved_in_pieces_gives_our_voltage(pybamm, effects):
    """``simulate`` solves long records in pieces, each from the state the last ended in
    (``STATES``: SoC, the RC voltages, the surface-SOC lag, h; the record's temperature): pieces
    of 70 intervals on this record."""
    model = fitted("table", effects)
    frame = record(uniform=False)
    ours = model.simulate(frame, soc0=SOC0)
    cell = X.load_source(X.export(model, "model.json", soc0=SOC0).text)
    v = cell.simulate(frame["time_s"], frame["current_a"], frame["temperature_c"], chunk=70)
    assert rms_mv(v, ours) <= TOL_RMS_MV


def test_a_record_that_starts_full_and_charges_runs(pybamm):
    """Our model has no SoC bounds: a record from SOC 1 (the export's default, and the library's
    rule on a record that starts at the top of the OCV) that charges first runs in PyBaMM too
    (the module's model() drops Thevenin's SoC events, which would stop it at once)."""
    model = fitted("table", ("second_rc", "hysteresis"))
    frame = record()
    frame["current_a"] = -frame["current_a"]  # charge first
    ours = model.simulate(frame, soc0=1.0)
    cell = X.load_source(X.export(model, "model.json").text)
    assert cell.INITIAL_SOC == 1.0
    v = cell.simulate(frame["time_s"], frame["current_a"], frame["temperature_c"])
    assert rms_mv(v, ours) <= TOL_RMS_MV


def test_without_a_measured_temperature_the_cell_sits_at_the_reference(pybamm, tmp_path):
    """No temperature column: the module's ambient (T_ref) holds the cell there, where the
    Arrhenius factors are 1, as in our simulator with the record's temperature at T_ref."""
    model = fitted("table", ("second_rc", "thermal", "butler_volmer"))
    frame = record(temperature=False)
    at_ref = frame.assign(temperature_c=TREF_K - 273.15)
    ours = model.simulate(at_ref, soc0=SOC0)
    cell = X.load_source(X.export(model, "model.json", soc0=SOC0).text)
    assert rms_mv(cell.simulate(frame["time_s"], frame["current_a"]), ours) <= TOL_RMS_MV


def test_parameter_values_are_the_written_modules(pybamm):
    """``parameter_values(model)``: PyBaMM's Thevenin options and values; R0 and the OCV
    evaluate to the library's formulas at chosen points."""
    model = fitted("table", ("second_rc", "soc_resistance", "thermal", "butler_volmer",
                             "ocv_shape"))  # fmt: skip
    options, values = X.parameter_values(model, soc0=0.4)
    assert options == {"number of rc elements": 2}
    assert isinstance(values, pybamm.ParameterValues)
    assert values["Initial SoC"] == 0.4
    P = ecm.to_physical(model.x)[0]
    assert values["Cell capacity [A.h]"] == pytest.approx(P[ecm.Q], rel=1e-15)
    param = pybamm.EcmParameters()
    for soc, temp_c, cur in [(0.3, 20.0, 1.2), (0.8, 35.0, -0.7), (0.5, 27.0, 0.0)]:
        sym = param.rcr_element("R0 [Ohm]", pybamm.Scalar(temp_c), pybamm.Scalar(cur),
                                pybamm.Scalar(soc))  # fmt: skip
        r0 = np.asarray(values.process_symbol(sym).evaluate()).item()
        tk = temp_c + 273.15
        g = 1 + P[ecm.KLOW] * np.exp(-soc / P[ecm.SIG])
        f0 = np.exp(P[ecm.TH0] * (1 / tk - 1 / TREF_K))
        x = 0.5 * P[ecm.BVG] * cur
        bv = 2 * ecm.GAS_R * tk / ecm.FARADAY * (np.arcsinh(x) / cur if cur else P[ecm.BVG] / 2)
        assert r0 == pytest.approx(P[ecm.R0] * g * f0 + bv, rel=1e-12)
        ocv = np.asarray(values.process_symbol(param.ocv(pybamm.Scalar(soc))).evaluate()).item()
        want = ecm.ocv_values(P, soc, model.knots, model.config.table)
        assert ocv == pytest.approx(float(want), abs=1e-12)


def test_pybamm_model_carries_the_states_beyond_thevenins(pybamm):
    """``pybamm_model``: the module's model, with the surface-SOC lag and the hysteresis state,
    solved by PyBaMM for a constant discharge: h falls towards −1 at the rate γ·I/(3600·Q) and
    δ rises towards κ·I with τ_d, as their closed forms say."""
    model = fitted("table", ("diffusion", "hysteresis"))
    pb_model, values = X.pybamm_model(model, soc0=SOC0)
    assert {"Surface SoC lag", "Hysteresis state"} <= set(pb_model.variables.keys())
    amps = 2.0
    values["Current function [A]"] = amps
    sim = pybamm.Simulation(pb_model, parameter_values=values,
                            solver=pybamm.IDAKLUSolver(rtol=1e-8, atol=1e-8))  # fmt: skip
    t = np.array([0.0, 100.0, 300.0])
    sol = sim.solve(t_eval=t, t_interp=t)
    P = ecm.to_physical(model.x)[0]
    h = -1.0 + np.exp(-P[ecm.GAM] * amps * t / (3600 * P[ecm.Q]))
    delta = P[ecm.KD] * amps * (1.0 - np.exp(-t / P[ecm.TAUD]))
    np.testing.assert_allclose(sol["Hysteresis state"].entries, h, atol=1e-6)
    np.testing.assert_allclose(sol["Surface SoC lag"].entries, delta, atol=1e-6)


# ----------------------------------------------------------------------------------------------
# the command


def run_cli(args, capsys):
    code = cli.main(args)
    out, err = capsys.readouterr()
    return code, out, err


def test_export_writes_a_module_that_loads_without_this_package(pybamm, tmp_path, capsys):
    """The CLI's file, loaded by a fresh interpreter in which avoa_pipeline cannot be imported,
    runs a record to our voltage."""
    model = fitted("rational", ("second_rc", "thermal"))
    model.save(tmp_path / "model.json")
    frame = measured(model, record())
    frame.to_csv(tmp_path / "rec.csv", index=False)
    out = tmp_path / "cell.py"
    code, stdout, _ = run_cli(["export", str(tmp_path / "model.json"), "--to", "pybamm",
                               "--out", str(out), "--record", str(tmp_path / "rec.csv")],
                              capsys)  # fmt: skip
    assert code == 0
    assert "initial SOC" in stdout
    # on a record, PyBaMM ran the module before it was written: its difference from ours
    agreement = float(stdout.split(" mV RMS, ")[0].rsplit(" ", 1)[1])
    assert 0.0 < agreement <= TOL_RMS_MV
    assert "from our simulator" in stdout
    assert not (tmp_path / "cell.dropped.csv").exists()
    loaded = FittedModel.load(tmp_path / "model.json")
    ours = loaded.simulate(frame)  # the initial SOC by the library's rule, as the export's
    data = tmp_path / "rec.json"
    data.write_text(json.dumps({k: frame[k].tolist() for k in frame.columns}))
    script = textwrap.dedent(f"""
        import importlib.util, json, sys
        sys.modules["avoa_pipeline"] = None  # importing it now fails
        try:
            import avoa_pipeline
        except ImportError:
            pass
        else:
            raise SystemExit("avoa_pipeline importable")
        spec = importlib.util.spec_from_file_location("cell", {str(out)!r})
        cell = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(cell)
        import pybamm
        model = cell.model()
        values = pybamm.ParameterValues(cell.get_parameter_values())
        values.process_model(model)
        d = json.load(open({str(data)!r}))
        v = cell.simulate(d["time_s"], d["current_a"], d["temperature_c"])
        print(json.dumps([float(a) for a in v]))
    """)
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    env["PYBAMM_DISABLE_TELEMETRY"] = "true"
    res = subprocess.run([sys.executable, "-I", "-c", script], capture_output=True, text=True,
                         env=env, cwd=tmp_path, timeout=300, check=False)  # fmt: skip
    assert res.returncode == 0, res.stderr[-2000:]
    v = np.array(json.loads(res.stdout.strip().splitlines()[-1]))
    assert rms_mv(v, ours) <= TOL_RMS_MV


def test_drop_unsupported_exports_the_rest_and_writes_its_cost(pybamm, tmp_path, capsys,
                                                               monkeypatch):  # fmt: skip
    without_export(monkeypatch, "hysteresis", "diffusion")
    model = fitted("table", ("second_rc", "hysteresis", "diffusion"))
    model.save(tmp_path / "model.json")
    frame = measured(model, record())
    frame.to_csv(tmp_path / "rec.csv", index=False)
    out = tmp_path / "cell.py"
    args = ["export", str(tmp_path / "model.json"), "--to", "pybamm", "--out", str(out)]
    code, _, err = run_cli(args, capsys)
    assert code == 2
    assert err.count("\n") == 1
    assert "hysteresis, diffusion" in err
    assert not out.exists()
    code, _, err = run_cli([*args, "--drop-unsupported"], capsys)  # the cost needs a record
    assert code == 2
    assert "--record" in err
    assert not out.exists()
    code, stdout, _ = run_cli([*args, "--drop-unsupported", "--record", str(tmp_path / "rec.csv"),
                               "--soc0", str(SOC0)], capsys)  # fmt: skip
    assert code == 0
    assert "dropped hysteresis, diffusion" in stdout
    cost = pd.read_csv(tmp_path / "cell.dropped.csv")
    assert list(cost.columns) == ["time_s", "voltage_v", "model_v", "exported_v", "difference_mv"]
    np.testing.assert_allclose(cost["model_v"], model.simulate(frame, soc0=SOC0), atol=1e-12)
    kept = X.without(model, ("hysteresis", "diffusion"))
    np.testing.assert_allclose(cost["exported_v"], kept.simulate(frame, soc0=SOC0), atol=1e-12)
    np.testing.assert_allclose(cost["difference_mv"], 1e3 * (cost["exported_v"] - cost["model_v"]))
    assert rms_mv(cost["exported_v"], cost["model_v"]) > 1.0  # dropping them costs something
    cell = load_module(out)
    assert set(cell.DROPPED) == {"hysteresis", "diffusion"}
    assert cell.DROPPED["diffusion"]["rms_mv"] == pytest.approx(
        rms_mv(cost["exported_v"], cost["model_v"]), rel=1e-9
    )
    # what the file holds is what exported_v says
    v = cell.simulate(frame["time_s"], frame["current_a"], frame["temperature_c"])
    assert rms_mv(v, cost["exported_v"]) <= TOL_RMS_MV


def test_a_difference_above_the_promise_is_a_warning(pybamm, tmp_path, capsys, monkeypatch):
    """export --record warns in one line where PyBaMM's voltage strays from ours by more than
    AGREEMENT_RMS_MV (here made 0, so that any difference does); the module is written."""
    monkeypatch.setattr(X, "AGREEMENT_RMS_MV", 0.0)
    model = fitted("table", ("diffusion", "hysteresis"))
    model.save(tmp_path / "model.json")
    measured(model, record()).to_csv(tmp_path / "rec.csv", index=False)
    out = tmp_path / "cell.py"
    code, _, err = run_cli(["export", str(tmp_path / "model.json"), "--to", "pybamm", "--out",
                            str(out), "--record", str(tmp_path / "rec.csv")], capsys)  # fmt: skip
    assert code == 0
    warning = [line for line in err.splitlines() if "differs from our simulator" in line]
    assert len(warning) == 1
    assert warning[0].startswith("warning: ")
    assert out.exists()


def _tamper(tmp_path, how):
    model = fitted("table", ("second_rc",))
    model.save(tmp_path / "model.json")
    d = json.loads((tmp_path / "model.json").read_text())
    if how == "version":
        d["format_version"] = 2
    elif how == "out_of_bounds":
        d["parameters"]["r2_ohm"] = 50.0
    else:
        del d["parameters"]["tau1_s"]
    (tmp_path / "model.json").write_text(json.dumps(d))
    measured(model, record()).to_csv(tmp_path / "rec.csv", index=False)


@pytest.mark.parametrize("how", ["version", "out_of_bounds", "missing"])
def test_a_bad_model_json_gets_simulates_refusal_and_nothing_is_written(tmp_path, capsys, how):
    _tamper(tmp_path, how)
    m = str(tmp_path / "model.json")
    code_s, _, err_s = run_cli(["simulate", m, str(tmp_path / "rec.csv"), "--out",
                                str(tmp_path / "pred.csv")], capsys)  # fmt: skip
    code_e, _, err_e = run_cli(["export", m, "--to", "pybamm", "--out", str(tmp_path / "c.py"),
                                "--record", str(tmp_path / "rec.csv")], capsys)  # fmt: skip
    assert code_s == code_e == 2
    assert err_e == err_s
    assert err_e.count("\n") == 1
    assert not (tmp_path / "c.py").exists()
    assert not (tmp_path / "c.dropped.csv").exists()


def test_without_pybamm_the_command_says_how_to_install_it(tmp_path, capsys, monkeypatch):
    fitted("rational", ()).save(tmp_path / "model.json")
    monkeypatch.setitem(sys.modules, "pybamm", None)  # `import pybamm` now fails
    out = tmp_path / "c.py"
    code, _, err = run_cli(["export", str(tmp_path / "model.json"), "--to", "pybamm", "--out",
                            str(out)], capsys)  # fmt: skip
    assert code == 2
    assert err.count("\n") == 1
    assert "pip install 'avoa-pipeline[pybamm]'" in err
    assert not out.exists()


def test_out_must_be_a_python_module(tmp_path, capsys):
    fitted("rational", ()).save(tmp_path / "model.json")
    code, _, err = run_cli(["export", str(tmp_path / "model.json"), "--to", "pybamm", "--out",
                            str(tmp_path / "c.json")], capsys)  # fmt: skip
    assert code == 2
    assert ".py" in err


def test_the_command_line_does_not_import_pybamm():
    code = ("import sys, avoa_pipeline.cli, avoa_pipeline.interop.pybamm; "
            "assert 'pybamm' not in sys.modules, 'pybamm imported'")  # fmt: skip
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         timeout=120, check=False)  # fmt: skip
    assert res.returncode == 0, res.stderr


# ----------------------------------------------------------------------------------------------
# the thermal state (issue 28 item 4): model.json's heat block as the module's LumpedHeat

HEAT = heat_block()  # test_model_json's: an 18650 in a chamber, 40 J/K, 0.1 W/K, dU/dT admitted
AMBIENT_C = 20.0
THERMAL_TOL_K = 0.01
"""The module's temperature (sampled as heat.py's: LumpedHeat's gates) against heat.py's: about
0.0003 K RMS on this record, on which the cell heats by 9-11 K; 0.01 K is heat.py's own
fixed-point tolerance (``heat.FIXED_POINT_TOL_K``) and 1/900 of the rise. Its voltage is held
to the export's promise, TOL_RMS_MV (it measures 0.003-0.006 mV RMS)."""


def with_heat(model: FittedModel, h: heat.Heat = HEAT) -> FittedModel:
    return dataclasses.replace(model, heat=h)


THERMAL_CASES = [("second_rc", "thermal"), ("thermal", "butler_volmer", "hysteresis", "diffusion")]


@pytest.mark.parametrize("effects", THERMAL_CASES)
def test_the_thermal_state_predicts_heat_pys_temperature_and_voltage(pybamm, effects):
    """On a record without temperature, from the ambient alone: the module's temperature and
    voltage against heat.py's fixed-point prediction (every overpotential in the heat: the
    hysteresis and the surface-SoC lag too)."""
    model = with_heat(fitted("table", effects))
    frame = record(temperature=False)
    module = X.loaded_module(model, SOC0)
    got = X.thermal_agreement(module, model, frame, SOC0, AMBIENT_C)
    ref = heat.predict(model, model.heat, frame, AMBIENT_C, soc0=SOC0)
    rise = float(ref.temp_k.max()) - heat.KELVIN - AMBIENT_C
    assert rise > 20 * THERMAL_TOL_K  # the cell heats: a state that stays at the ambient fails
    assert got["rms_k"] <= THERMAL_TOL_K
    assert got["rms_mv"] <= TOL_RMS_MV


def test_the_thermal_state_heat_is_ours_not_pybamms_element_heat(pybamm):
    """The heat PyBaMM integrates is q = I·(OCV − V) − I·T·dU/dT: with hysteresis (which PyBaMM's
    ThermalSubModel does not count) the module's heat at the samples is heat.py's."""
    model = with_heat(fitted("table", ("thermal", "hysteresis")))
    frame = record(temperature=False)
    module = X.loaded_module(model, SOC0)
    v, temp_c = module.simulate(frame["time_s"], frame["current_a"], initial_soc=SOC0,
                                ambient_c=AMBIENT_C)  # fmt: skip
    q, _ = heat.heat_of(model, frame, np.asarray(temp_c) + heat.KELVIN, HEAT.dudt, SOC0)
    i = frame["current_a"].to_numpy()
    _, tr = model.simulate(frame.assign(temperature_c=temp_c), soc0=SOC0, traces=True)
    ocv = ecm.ocv_values(ecm.to_physical(model.x)[0], tr[0], model.knots, model.config.table)
    theirs = i * (ocv - v) - i * (np.asarray(temp_c) + heat.KELVIN) * HEAT.dudt
    assert np.max(np.abs(q)) > 1.0  # watts: the record heats
    np.testing.assert_allclose(theirs, q, atol=0.02 * np.max(np.abs(q)))


def test_without_a_heat_block_ambient_c_is_refused(pybamm):
    module = X.loaded_module(fitted("table", ("thermal",)), SOC0)
    assert module.THERMAL_SUBMODELS == {}
    frame = record(temperature=False)
    with pytest.raises(ValueError, match="heat block"):
        module.simulate(frame["time_s"], frame["current_a"], ambient_c=AMBIENT_C)


def test_the_thermal_state_carries_over_the_pieces_of_a_record(pybamm):
    """simulate() in pieces starts each where the last ended (THERMAL_STATES): its temperature
    in small pieces is the one in a single piece."""
    model = with_heat(fitted("table", ("second_rc", "thermal")))
    frame = record(temperature=False)
    module = X.loaded_module(model, SOC0)
    args = (frame["time_s"], frame["current_a"])
    v1, t1 = module.simulate(*args, initial_soc=SOC0, ambient_c=AMBIENT_C)
    v2, t2 = module.simulate(*args, initial_soc=SOC0, ambient_c=AMBIENT_C, chunk=40)
    assert float(np.ptp(t1)) > 1.0
    np.testing.assert_allclose(t2, t1, atol=1e-3)
    assert rms_mv(v2, v1) <= 0.01


def test_export_compares_the_thermal_state_from_the_ambient(pybamm, tmp_path, capsys):
    """--predict-temperature: the record's ambient (its first temperature sample, no sidecar)
    drives both heat.py and the module; the line gives mV and K. Without a heat block it is
    refused in one line, nothing written."""
    model = with_heat(fitted("table", ("second_rc", "thermal")))
    model.save(tmp_path / "model.json")
    frame = record()
    measured(model, frame).to_csv(tmp_path / "rec.csv", index=False)
    out = tmp_path / "cell.py"
    args = ["export", str(tmp_path / "model.json"), "--to", "pybamm", "--out", str(out),
            "--record", str(tmp_path / "rec.csv"), "--predict-temperature"]  # fmt: skip
    code, stdout, _ = run_cli(args, capsys)
    assert code == 0
    first = float(frame["temperature_c"].iloc[0])
    assert f"temperature predicted from ambient {first:g} °C" in stdout
    kelvin = float(stdout.split(" K RMS")[0].rsplit(" ", 1)[1])
    assert 0.0 < kelvin <= THERMAL_TOL_K
    assert "def model(predict_temperature=False)" in out.read_text()
    fitted("table", ("second_rc", "thermal")).save(tmp_path / "plain.json")
    out.unlink()
    args[1] = str(tmp_path / "plain.json")
    code, _, err = run_cli(args, capsys)
    assert code == 2
    assert err.strip().splitlines() == [f"error: {tmp_path / 'plain.json'}: field 'heat': missing "
                                        "(--predict-temperature)"]  # fmt: skip
    assert not out.exists()
