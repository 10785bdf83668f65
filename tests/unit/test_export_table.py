"""Export as a BMS-style lookup table (``avoa_pipeline.interop.table``, ``export --to table``).

The check (docs/pybamm.md, "A lookup table"): a table simulator written here, as a user would
write one in Simulink or C (linear interpolation in the CSV, in SOC and then in temperature; the
recursion the sidecar states), runs a record; its voltage against ``FittedModel.simulate``'s
from the same initial SOC.
"""

from __future__ import annotations

import dataclasses
import json
import math
import re

import numpy as np
import pandas as pd
import pytest
from test_interop_pybamm import SOC0, fitted, measured, record, rms_mv, run_cli

from avoa_pipeline.interop import table as T
from avoa_pipeline.interop.pybamm import without
from avoa_pipeline.model import ecm, elements

TOL_RMS_MV = 0.5
"""A table simulator on a 0.01 SOC grid (plus the knots) and a 1 K temperature grid against our
simulator: the difference is linear interpolation between grid points (the laws are exponential
in SOC and 1/T). Measured on this record: 0.14 mV RMS (resistances) and 0.07 (states); on the
default 2 K grid 0.53 and 0.23 (the 6C pulse through R0 with θ = 4,000 K)."""
GRID_1K = ",".join(str(t) for t in range(20, 33))  # the record's 24-29.3 °C inside, 1 K apart

# SOC- and temperature-dependent resistances, a charge R0, two RC branches, a measured OCV
RESISTANCES = ("second_rc", "soc_resistance", "r0_soc", "r1_soc", "thermal", "r0_charge")
# every state the sidecar's recursion carries, and Butler–Volmer's law from its scalars
STATES = ("diffusion", "hysteresis", "current_offset", "coulombic_efficiency", "butler_volmer",
          "bv_arrhenius", "thermal")  # fmt: skip
# the temperature laws of issue 28 (τ_j(T), the entropic OCV, Q(T)), with the states that count
# the charge (hysteresis's rate, the coulombic efficiency) and a second branch
LAWS = ("second_rc", "thermal", "thermal_tau", "entropic", "capacity_temperature", "hysteresis",
        "coulombic_efficiency")  # fmt: skip


def lookup(tab: pd.DataFrame, column: str, soc: float, temp_c: float) -> float:
    """Linear interpolation in the table: in SOC at the two grid temperatures around ``temp_c``,
    then in temperature (held at the grid's ends)."""
    temps = np.unique(tab["temperature_c"].to_numpy())
    j = int(np.clip(np.searchsorted(temps, temp_c) - 1, 0, max(temps.size - 2, 0)))
    around = temps[j : j + 2]
    at = []
    for t in around:
        rows = tab[tab["temperature_c"] == t]
        at.append(np.interp(soc, rows["soc"].to_numpy(), rows[column].to_numpy()))
    if around.size == 1:
        return float(at[0])
    return float(np.interp(temp_c, around, at))


def table_simulator(tab: pd.DataFrame, side: dict, frame: pd.DataFrame, soc0: float):
    """The sidecar's recursion, every column read from the table at (T_k, s_k)."""
    sc = {k: v["value"] for k, v in side["scalars"].items()}
    branches = [int(c[3:-2]) for c in tab.columns if c.startswith("tau")]
    t = frame["time_s"].to_numpy()
    i_meas = frame["current_a"].to_numpy()
    temps = frame["temperature_c"].to_numpy()
    capacity = "capacity_ah" in tab.columns  # capacity_temperature: Q by temperature
    s, delta, h, v_rc = soc0, 0.0, 0.0, np.zeros(len(branches))
    out = np.empty(t.size)
    for k in range(t.size):
        dt = t[k + 1] - t[k] if k + 1 < t.size else 1.0
        i, temp = i_meas[k] + sc["current_offset_a"], temps[k]
        r0 = lookup(tab, "r0_ohm" if i >= 0 else "r0_charge_ohm", s, temp)
        v = lookup(tab, "ocv_v", s - delta, temp) + sc["hysteresis_m_v"] * h - r0 * i
        v -= v_rc.sum()
        if "bv_inv_i0_per_a" in sc:
            tk = temp + 273.15
            inv_i0 = sc["bv_inv_i0_per_a"] * math.exp(sc["bv_theta_i0_k"]
                                                      * (1 / tk - 1 / sc["tref_k"]))  # fmt: skip
            v -= 2 * ecm.GAS_R * tk / ecm.FARADAY * math.asinh(0.5 * inv_i0 * i)
        out[k] = v
        for n, j in enumerate(branches):
            a = math.exp(-dt / lookup(tab, f"tau{j}_s", s, temp))
            v_rc[n] = a * v_rc[n] + (1 - a) * lookup(tab, f"r{j}_ohm", s, temp) * i
        ad = math.exp(-dt / sc["diffusion_tau_s"])
        delta = ad * delta + (1 - ad) * sc["diffusion_soc_per_a"] * i
        ie = i if i > 0 else sc["coulombic_efficiency"] * i
        q = 3600.0 * (lookup(tab, "capacity_ah", s, temp) if capacity else sc["capacity_ah"])
        if i != 0:
            e = math.exp(-abs(sc["hysteresis_gamma"] * ie * dt / q))
            h = e * h - (1 - e) * math.copysign(1.0, i)
        s -= ie * dt / q
    return out


def write_table(tmp_path, capsys, model, *options):
    model.save(tmp_path / "model.json")
    out = tmp_path / "cell.csv"
    code, stdout, err = run_cli(["export", str(tmp_path / "model.json"), "--to", "table",
                                 "--out", str(out), *options], capsys)  # fmt: skip
    assert code == 0, err
    return pd.read_csv(out), json.loads((tmp_path / "cell.json").read_text()), stdout


@pytest.mark.parametrize("effects", [RESISTANCES, STATES, LAWS],
                         ids=["resistances", "states", "temperature-laws"])  # fmt: skip
def test_a_table_simulator_reproduces_ours(tmp_path, capsys, effects):
    extra = {"coulombic_efficiency": 0.9} if "coulombic_efficiency" in effects else {}
    model = fitted("table", effects, extra)
    tab, side, _ = write_table(tmp_path, capsys, model, "--temperatures", GRID_1K)
    frame = record()  # 1-4 s steps would do too: the recursion is the same
    ours = model.simulate(frame, soc0=SOC0)
    # the record moves through what the table holds: SOC 0.6 ± 0.2, 24-29.3 °C
    assert rms_mv(ours, fitted("table", ()).simulate(frame, soc0=SOC0)) > 5.0
    for law in {"thermal_tau", "entropic", "capacity_temperature"} & set(effects):
        # each temperature law moves this record's voltage (else the check says nothing of it)
        assert rms_mv(ours, without(model, [law]).simulate(frame, soc0=SOC0)) > 1.0
    theirs = table_simulator(tab, side, frame, SOC0)
    assert rms_mv(theirs, ours) <= TOL_RMS_MV


def test_the_columns_are_the_laws_and_the_sidecar_says_what_they_mean(tmp_path, capsys):
    model = fitted("table", (*RESISTANCES, "third_rc", "butler_volmer"))
    tab, side, stdout = write_table(tmp_path, capsys, model, "--soc-grid", "0.1,0.5,0.9",
                                    "--temperatures", "10,25")  # fmt: skip
    assert list(tab.columns) == ["temperature_c", "soc", "ocv_v", "r0_ohm", "r0_charge_ohm",
                                 "r1_ohm", "tau1_s", "c1_f", "r2_ohm", "tau2_s", "c2_f",
                                 "r3_ohm", "tau3_s", "c3_f", "r_bv0_ohm"]  # fmt: skip
    assert tab["temperature_c"].tolist() == [10.0] * 3 + [25.0] * 3
    assert set(side["columns"]) == set(tab.columns)
    assert all(c["unit"] and c["meaning"] for c in side["columns"].values())
    # R0 at (SOC 0.5, 10 °C) by the element laws, written out here
    P = ecm.to_physical(model.x)[0]
    tk = 283.15
    g = 1 + P[ecm.KLOW] * math.exp(-0.5 / P[ecm.SIG])
    l0 = np.interp(0.5, model.knots.grid(), P[ecm.L0 : ecm.L0 + ecm.N_KNOTS])
    f0 = math.exp(P[ecm.TH0] * (1 / tk - 1 / model.tref_k))
    row = tab[(tab["soc"] == 0.5) & (tab["temperature_c"] == 10.0)].iloc[0]
    assert row["r0_ohm"] == pytest.approx(P[ecm.R0] * g * math.exp(l0) * f0, rel=1e-9)
    assert row["r0_charge_ohm"] == pytest.approx(row["r0_ohm"] * math.exp(P[ecm.RHO]), rel=1e-9)
    assert row["c2_f"] == pytest.approx(row["tau2_s"] / row["r2_ohm"], rel=1e-9)
    assert row["r_bv0_ohm"] == pytest.approx(ecm.GAS_R * tk / ecm.FARADAY * P[ecm.BVG], rel=1e-9)
    assert any("asinh" in line for line in side["cannot"])
    assert side["grid"]["soc"] == [0.1, 0.5, 0.9]
    assert "given" in side["grid"]["temperature_note"]
    errors = side["interpolation_error"]
    assert set(errors) == set(tab.columns[2:])
    # a coarse grid strays from the exponential laws: the sidecar says so, and so does the line
    assert errors["r0_ohm"]["max_rel"] > 0.01
    assert "strays at most" in stdout


def test_a_branch_without_resistance_is_left_out(tmp_path, capsys):
    """R1 = 0 holds no voltage (and C1 = τ1/R1 has no value): branch 2 stays branch 2."""
    tab, _, _ = write_table(tmp_path, capsys, fitted("table", ("second_rc",), {"r1_ohm": 0.0}))
    rc = [c for c in tab.columns if re.fullmatch(r"(r|tau|c)[123]_(ohm|s|f)", c)]
    assert rc == ["r2_ohm", "tau2_s", "c2_f"]
    assert np.isfinite(tab.drop(columns="soc").to_numpy()).all()


def test_defaults_follow_the_model(tmp_path, capsys):
    """No temperature law: one temperature (T_ref); with one: T_ref ± 10 K in 2 K steps; SOC 0-1
    in 0.01 steps plus the knots."""
    tab, side, _ = write_table(tmp_path, capsys, fitted("table", ("second_rc",)))
    assert side["grid"]["temperature_c"] == [round(fitted("table", ()).tref_k - 273.15, 2)]
    knots = fitted("table", ()).knots.grid()
    assert set(np.round(knots[(knots > 0) & (knots < 1)], 9)) <= set(np.round(tab["soc"], 9))
    soc = np.array(side["grid"]["soc"])
    assert np.all(np.diff(soc) > 1e-9)  # a knot on the 0.01 grid is not a second point
    assert soc.size == 101  # this model's knots (0.2 + 0.12 j) lie on it
    _, side, _ = write_table(tmp_path, capsys, fitted("table", ("thermal",)))
    temps = side["grid"]["temperature_c"]
    assert len(temps) == 11
    assert temps[5] == pytest.approx(fitted("table", ()).tref_k - 273.15, abs=0.01)
    assert np.diff(temps) == pytest.approx(2.0)


@pytest.mark.parametrize("temperatures", ["-10,0,10", "-10, -5.5,0", "-1e1,0,1e1"])
def test_a_list_of_negative_temperatures_is_a_value_not_an_option(tmp_path, capsys, temperatures):
    """argparse took ``-10,0,10`` for an option ("expected one argument"); a list of numbers
    starting with a minus is a value (cli.NUMBERS), and the next option is still one."""
    tab, side, _ = write_table(tmp_path, capsys, fitted("table", ("thermal",)), "--temperatures",
                               temperatures, "--soc-grid", "0,0.5,1")  # fmt: skip
    want = [float(t) for t in temperatures.split(",")]
    assert side["grid"]["temperature_c"] == want
    assert sorted(set(tab["temperature_c"])) == want
    assert side["grid"]["soc"] == [0.0, 0.5, 1.0]


@pytest.mark.parametrize(
    ("options", "says"),
    [
        (["--temperatures", "-10,-x"], "--temperatures"),  # not a list of numbers: an option
        (["--soc-grid", "0,0.5,1.2"], "--soc-grid"),
        (["--soc-grid", "0.5,0.2"], "increase"),
        (["--soc-grid", "0.5"], "at least 2"),
        (["--soc-grid", "a,b"], "numbers"),
        (["--soc-grid", "0,nan"], "finite"),
        (["--temperatures", "-100,25"], "--temperatures"),
        (["--record", "x.csv"], "--to pybamm"),
        (["--soc0", "0.5"], "--to pybamm"),
        (["--drop-unsupported"], "--to pybamm"),
    ],
)  # fmt: skip
def test_bad_options_get_one_line_and_nothing_is_written(tmp_path, capsys, options, says):
    fitted("table", ("thermal",)).save(tmp_path / "model.json")
    out = tmp_path / "cell.csv"
    code, _, err = run_cli(["export", str(tmp_path / "model.json"), "--to", "table", "--out",
                            str(out), *options], capsys)  # fmt: skip
    assert code == 2
    assert err.count("\n") == 1
    assert err.startswith("error: ")
    assert says in err
    assert not out.exists()
    assert not (tmp_path / "cell.json").exists()


def test_grid_options_belong_to_the_table(tmp_path, capsys):
    fitted("table", ()).save(tmp_path / "model.json")
    code, _, err = run_cli(["export", str(tmp_path / "model.json"), "--to", "pybamm", "--out",
                            str(tmp_path / "c.py"), "--soc-grid", "0,1"], capsys)  # fmt: skip
    assert code == 2
    assert "--to table" in err


@pytest.mark.parametrize("how", ["suffix", "unwritable", "model"])
def test_a_bad_out_or_model_gets_one_line_and_nothing_is_written(tmp_path, capsys, how):
    model = fitted("table", ("second_rc",))
    model.save(tmp_path / "model.json")
    out = tmp_path / "cell.csv"
    if how == "suffix":
        out = tmp_path / "cell.txt"
    elif how == "unwritable":
        (tmp_path / "file").write_text("")
        out = tmp_path / "file" / "cell.csv"  # under a file: no folder can hold it
    else:
        d = json.loads((tmp_path / "model.json").read_text())
        d["parameters"]["r2_ohm"] = 50.0
        (tmp_path / "model.json").write_text(json.dumps(d))
        measured(model, record()).to_csv(tmp_path / "rec.csv", index=False)
    code, _, err = run_cli(["export", str(tmp_path / "model.json"), "--to", "table", "--out",
                            str(out)], capsys)  # fmt: skip
    assert code == 2
    assert err.count("\n") == 1
    if how == "model":  # the loader's refusal, as simulate gives it
        code_s, _, err_s = run_cli(["simulate", str(tmp_path / "model.json"),
                                    str(tmp_path / "rec.csv"), "--out",
                                    str(tmp_path / "p.csv")], capsys)  # fmt: skip
        assert code_s == 2
        assert err == err_s
    assert not out.exists()
    assert not out.with_suffix(".json").exists()


def test_every_element_is_expressed_and_another_is_refused(monkeypatch):
    """The table writes every element's law (EXPRESSED, from each element's ``table``); an
    element that says why its law cannot enter a table is refused in one line with its reason,
    not written without its law."""
    assert set(ecm.EFFECTS) == T.EXPRESSED
    cannot = dataclasses.replace(elements.get("thermal"), table="no grid holds this law")
    monkeypatch.setitem(elements.REGISTRY, "thermal", cannot)
    with pytest.raises(T.UserError, match="thermal: no grid holds this law") as exc:
        T.export_table(fitted("table", ("thermal",)), "m.json")
    assert "\n" not in str(exc.value)


def test_parse_grid_and_the_defaults_directly():
    assert T.parse_grid("0, 0.5,1", "--soc-grid", T.SOC_RANGE, "").tolist() == [0, 0.5, 1]
    model = fitted("table", ("butler_volmer",))  # RT/F: Butler–Volmer depends on temperature
    assert T.default_temperatures(model).size == 11
