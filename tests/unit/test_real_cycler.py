"""Raw cycler exports → the canonical record (real/cycler.py): each supported format against a
known truth (sign, units, charge, time, voltage samples), the lag a filtered current channel
adds, rests, steps, and one-line errors that write nothing."""

import json
import re
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from cycler_fixtures import (
    CLASSIC_ARBIN_COLUMNS,
    WRITERS,
    cli_error,
    counters_with_dips,
    export,
    from_frame,
    hppc_eis_protocol,
    simulate,
    simulate_logged,
    write_arbin,
    write_arbin_classic,
    write_arbin_classic_xlsx,
    write_arbin_workbook,
    write_basytec,
)
from test_ecm import TRUTH, profile_frame, with_voltage

from avoa_pipeline.cli import main
from avoa_pipeline.errors import DataError, UserError
from avoa_pipeline.importers import cycler
from avoa_pipeline.io import sha256

CYCLERS = list(WRITERS)


@pytest.mark.parametrize("name", CYCLERS)
def test_each_cycler_gives_the_truth(tmp_path, name):
    """Discharge-positive interval means equal the truth's; time, voltage and temperature are
    the logged samples themselves; charge is conserved; the sidecar says what was done."""
    path, truth = export(name, tmp_path)
    frame, info = cycler.convert(path, name)
    assert list(frame.columns) == ["time_s", "current_a", "voltage_v", "temperature_c"]
    np.testing.assert_allclose(frame["time_s"], truth.t - truth.t[0], atol=1e-3)
    np.testing.assert_allclose(frame["current_a"][:-1], truth.interval_mean_discharge(), atol=1e-6)
    assert frame["current_a"].iloc[-1] == pytest.approx(-truth.channel[-1])
    np.testing.assert_allclose(frame["voltage_v"], truth.voltage, atol=1e-8)
    np.testing.assert_allclose(frame["temperature_c"], truth.temperature, atol=1e-3)
    # discharged minus charged over the record: the truth's, to the counters' rounding
    net = -(truth.charged[-1] - truth.discharged[-1])
    assert info["charge"]["discharged_ah_output"] == pytest.approx(net, abs=1e-9)
    assert info["source_sha256"] == sha256(path)
    assert info["cycler"] == name
    assert info["sign"]["cycler_convention"] == "charge-positive"
    assert info["sign"]["voltage_check"]["confirmed"]
    check = info["sign"]["voltage_check"]
    assert check["verdict"] == "discharge-positive"
    # R0 of the fixture cell, and a little of its RC over the two intervals around each step
    assert check["step_resistance_ohm"] == pytest.approx(0.05, rel=0.05)
    assert info["current"]["source"] == "charge counters"
    assert len(info["steps"]["kept"]) == 10
    assert info["steps"]["dropped"] == []
    assert info["resampling"].startswith("none")
    json.dumps(info, allow_nan=False)


def test_counter_restarts_are_counted(tmp_path):
    """Per-step (Maccor, Neware), per-cycle (Arbin) and per-direction (BioLogic) restarts."""
    restarts = {
        n: cycler.convert(export(n, tmp_path)[0], n)[1]["current"]["counters"]["restarts"]
        for n in ("arbin", "maccor", "neware", "biologic", "basytec")
    }
    # Maccor counts throughput per step (5 restarts after a non-rest step); Neware's pair
    # restarts at every step after charge or discharge; Arbin's both at step 6; BioLogic's at
    # the three changes of direction; Basytec's running counter never
    assert restarts == {"arbin": 2, "maccor": 5, "neware": 5, "biologic": 3, "basytec": 0}


def test_units_are_converted(tmp_path):
    truth = simulate()
    in_a, _ = cycler.convert(write_arbin(truth, tmp_path / "a.csv"), "arbin")
    in_ma, info = cycler.convert(
        write_arbin(truth, tmp_path / "ma.csv", current_unit="mA"), "arbin"
    )
    pd.testing.assert_frame_equal(in_a, in_ma, atol=1e-9, check_exact=False)
    assert info["columns"]["current"] == {"column": "Current (mA)", "unit": "mA"}
    # the last row has no interval: its channel reading, in A
    assert in_ma["current_a"].iloc[-1] == pytest.approx(-truth.channel[-1])


def test_lagging_current_channel_is_bypassed_by_the_counters(tmp_path):
    """A channel through a 1.5-s filter misses the truth at pulse edges by amps; the counters do
    not, and the sidecar shows where the two disagree."""
    truth = simulate(lag_tau=1.5)
    path = write_arbin(truth, tmp_path / "lag.csv")
    frame, info = cycler.convert(path, "arbin")
    want = truth.interval_mean_discharge()
    np.testing.assert_allclose(frame["current_a"][:-1], want, atol=1e-6)
    held, held_info = cycler.convert(path, "arbin", current_from="channel")
    assert np.max(np.abs(held["current_a"][:-1] - want)) > 1.0
    assert held_info["current"]["source"] == "current channel (held)"
    vs = info["current"]["counters_vs_channel"]
    assert vs["rms_difference_step_edges_a"] > 1.0 > vs["rms_difference_steady_a"]


def test_rests_are_thinned_from_existing_samples_with_charge_kept(tmp_path):
    path, _truth = export("arbin", tmp_path)
    full, _ = cycler.convert(path, "arbin")
    thin, info = cycler.convert(path, "arbin", rest_dt=10.0)
    assert len(thin) < len(full)
    assert info["rows"]["rest_thinned"] == len(full) - len(thin)
    # every written sample is a logged one (no interpolation): voltage and time pairs
    logged = dict(zip(np.round(full["time_s"], 6), full["voltage_v"], strict=True))
    assert all(logged[round(t, 6)] == v for t, v in zip(thin["time_s"], thin["voltage_v"],
                                                         strict=True))  # fmt: skip
    charge = np.sum(thin["current_a"][:-1] * np.diff(thin["time_s"])) / 3600.0
    assert charge == pytest.approx(info["charge"]["discharged_ah_counters"], abs=1e-12)
    gaps = np.diff(thin["time_s"])
    assert gaps.max() <= 10.0 + 1e-9
    # load steps keep every sample: the 1-s spacing of every non-rest row survives
    load = np.abs(full["current_a"].to_numpy()) > 0.1
    assert set(np.round(full["time_s"][load], 6)) <= set(np.round(thin["time_s"], 6))


def test_maccor_unsigned_current_is_signed_by_its_mode_column(tmp_path):
    path, truth = export("maccor", tmp_path, unsigned=True)
    frame, info = cycler.convert(path, "maccor")
    np.testing.assert_allclose(frame["current_a"][:-1], truth.interval_mean_discharge(), atol=1e-6)
    assert "'MD'" in info["columns"]["current"]["signed_by"]
    (tmp_path / "signed").mkdir()
    signed, signed_info = cycler.convert(export("maccor", tmp_path / "signed")[0], "maccor")
    assert "not needed" in signed_info["columns"]["current"]["signed_by"]
    pd.testing.assert_frame_equal(frame, signed)


def test_repeated_time_keeps_the_later_row(tmp_path):
    path, truth = export("maccor", tmp_path, duplicate_row=50)
    frame, info = cycler.convert(path, "maccor")
    assert info["rows"]["repeated_time_dropped"] == 1
    assert len(frame) == truth.t.size
    np.testing.assert_allclose(frame["current_a"][:-1], truth.interval_mean_discharge(), atol=1e-6)


def test_a_step_range_is_kept_and_the_rest_listed(tmp_path):
    path, truth = export("neware", tmp_path)
    frame, info = cycler.convert(path, "neware", steps=(2, 8))
    rows = (truth.step >= 2) & (truth.step <= 8)
    assert len(frame) == rows.sum()
    assert frame["time_s"].iloc[0] == 0.0
    assert [s["step"] for s in info["steps"]["kept"]] == list(range(2, 9))
    assert [s["step"] for s in info["steps"]["dropped"]] == [1, 9, 10]
    with pytest.raises(DataError, match=r"Step Index.*no step 12"):
        cycler.convert(path, "neware", steps=(2, 12))


@pytest.mark.parametrize(
    ("name", "column"), [("maccor", "'Current'"), ("basytec", "'I[A]'"), ("arbin", "'Current (A)'")]
)
def test_a_sign_against_the_cyclers_convention_is_refused(tmp_path, name, column):
    """Maccor (direction from the channel) and Basytec (a signed counter) with everything
    negated fail the voltage check; Arbin with its channel negated contradicts its counters."""
    truth = simulate()
    truth.channel = -truth.channel
    if name == "basytec":
        truth.charged, truth.discharged = truth.discharged, truth.charged
    if name == "maccor":
        truth.current = -truth.current
    path, _ = export(name, tmp_path, truth)
    with pytest.raises(DataError, match=re.escape(column) + ".*not charge-positive"):
        cycler.convert(path, name)


def test_bad_exports_are_one_line_errors_naming_file_and_column(tmp_path, capsys):
    arbin, _truth = export("arbin", tmp_path)
    base = pd.read_csv(arbin)

    def variant(name, frame):
        path = tmp_path / name
        frame.to_csv(path, index=False)
        return path

    cases = [
        (arbin, "maccor", "not a Maccor export; it looks like an Arbin export: use --cycler arbin"),
        (variant("no_i.csv", base.drop(columns="Current (A)")), "arbin", "no current column"),
        (variant("no_v.csv", base.drop(columns="Voltage (V)")), "arbin", "'Voltage (<unit>)'"),
        (
            variant("two.csv", base.assign(**{"Current (mA)": base["Current (A)"] * 1e3})),
            "arbin",
            "'Current (A)', 'Current (mA)'",
        ),
        (
            variant("unit.csv", base.rename(columns={"Current (A)": "Current (mAmp)"})),
            "arbin",
            "column 'Current (mAmp)': unit 'mAmp' not recognised",
        ),
        # counters written in mAh but labelled Ah: the counters' current is 1000× the channel's
        (
            variant(
                "mixed.csv",
                base.assign(
                    **{
                        c: base[c] * 1e3
                        for c in ("Charge Capacity (Ah)", "Discharge Capacity (Ah)")
                    }
                ),
            ),
            "arbin",
            "mixed units",
        ),
        (variant("text.csv", base.assign(**{"Voltage (V)": "n/a"})), "arbin", "Voltage"),
        (tmp_path / "missing.csv", "arbin", "no such file"),
    ]
    wrong_ext = tmp_path / "arbin.dat"
    wrong_ext.write_text(arbin.read_text())
    cases.append((wrong_ext, "arbin", "'.dat'"))
    for raw, name, word in cases:
        cli_error(tmp_path, capsys, raw, name, word)
    # a mixed-units message names both columns
    cli_error(tmp_path, capsys, tmp_path / "mixed.csv", "arbin", "'Charge Capacity (Ah)'")


def test_cli_convert_writes_csv_and_sidecar(tmp_path, capsys):
    path, _truth = export("biologic", tmp_path)
    out = tmp_path / "conv" / "cell.csv"
    assert main(["convert", str(path), "--cycler", "biologic", "--out", str(out),
                 "--rest-dt", "20", "--steps", "1-9"]) == 0  # fmt: skip
    printed = capsys.readouterr().out
    assert "sign confirmed" in printed
    assert str(out) in printed
    frame = pd.read_csv(out)
    side = json.loads(out.with_suffix(".json").read_text())
    assert side["source_file"] == str(path)
    assert side["steps"]["selection"] == "1-9"
    assert side["rows"]["written"] == len(frame)
    assert "at most 20 s apart" in side["resampling"]
    assert (
        main(["convert", str(path), "--cycler", "biologic", "--out", str(tmp_path / "x.txt")]) == 2
    )


@pytest.fixture(scope="module")
def canonical_and_raw(tmp_path_factory):
    """One record as a canonical CSV and as an Arbin export (running counters)."""
    folder = tmp_path_factory.mktemp("raw")
    frame = with_voltage(profile_frame(), TRUTH, noise_v=1e-3, seed=4)
    csv = folder / "cell.csv"
    frame.to_csv(csv, index=False)
    raw = write_arbin(from_frame(frame), folder / "cell_arbin.csv", restart_step=None)
    return frame, csv, raw


def test_raw_export_reproduces_the_canonical_record(canonical_and_raw):
    frame, _, raw = canonical_and_raw
    got, _ = cycler.convert(raw, "arbin")
    np.testing.assert_allclose(got["current_a"], frame["current_a"], atol=1e-8)
    np.testing.assert_allclose(got["voltage_v"], frame["voltage_v"], atol=1e-9)


def test_diagnose_reader_and_ocv_take_a_raw_export_directly(canonical_and_raw, tmp_path):
    """The one reader behind diagnose, --validate and simulate, and --ocv, given --cycler."""
    from avoa_pipeline import inputs

    _, csv, raw = canonical_and_raw
    a = inputs.read_record(csv)
    b = inputs.read_record(raw, cycler="arbin")
    pd.testing.assert_frame_equal(a.frame, b.frame, atol=1e-8, check_exact=False)
    assert a.sign.verdict == b.sign.verdict == "discharge-positive"
    # a canonical CSV given with --cycler is read as it is
    c = inputs.read_record(csv, cycler="arbin")
    assert c.origin["read_as"] == "canonical CSV"
    pd.testing.assert_frame_equal(a.frame, c.frame)
    # --ocv: a slow test as a raw Basytec export
    slow = with_voltage(_slow(), {**TRUTH, "soc0": 1.0})
    slow.to_csv(tmp_path / "slow.csv", index=False)
    raw_slow = write_basytec(from_frame(slow), tmp_path / "slow.txt")
    a, b = inputs.read_ocv(tmp_path / "slow.csv"), inputs.read_ocv(raw_slow, cycler="basytec")
    np.testing.assert_allclose(a.values, b.values, atol=1e-9)
    assert a.capacity_ah == pytest.approx(b.capacity_ah, rel=1e-9)


def _slow(rate_c=0.05, capacity=2.57, share=0.9):
    """A C/20 discharge of ``share`` of the capacity from full, a rest, the charge back."""
    i = rate_c * capacity
    n = int(share * 3600 / rate_c)
    cur = np.concatenate([np.zeros(60), np.full(n, i), np.zeros(600), np.full(n, -i)])
    t = np.arange(cur.size, dtype=float)
    return pd.DataFrame({"time_s": t, "current_a": cur, "voltage_v": np.zeros_like(t)})


def test_diagnose_and_simulate_take_a_raw_export_like_its_canonical_csv(canonical_and_raw,
                                                                        tmp_path):  # fmt: skip
    _, csv, raw = canonical_and_raw
    reports, preds = [], []
    for data, extra in ((csv, []), (raw, ["--cycler", "arbin"])):
        out = tmp_path / data.stem
        assert main(["diagnose", str(data), "--out", str(out), *extra]) == 0
        reports.append(json.loads((out / "diagnosis.json").read_text()))
        pred = tmp_path / f"pred_{data.stem}.csv"
        model = str(tmp_path / csv.stem / "model.json")  # the canonical run's model for both
        assert main(["simulate", model, str(data), "--out", str(pred), *extra]) == 0
        preds.append(pd.read_csv(pred))
    a, b = reports
    assert a["verdict"]["effect"] == b["verdict"]["effect"]
    assert a["selected"]["name"] == b["selected"]["name"]
    assert a["base"]["rmse_mv"] == pytest.approx(b["base"]["rmse_mv"], rel=1e-3)
    np.testing.assert_allclose(preds[0]["model_v"], preds[1]["model_v"], atol=1e-8)


DATA = Path(__file__).resolve().parents[1] / "data" / "pyprobe"


def test_pyprobes_own_arbin_export():
    """A genuine Arbin export (time stamps with a leading tab, an ACR-like charge and discharge
    at the step start): the step up to 2.65 A charge confirms the sign, the counters give the
    interval means, charge equals the counters'."""
    frame, info = cycler.convert(DATA / "sample_data_arbin.csv", "arbin")
    assert len(frame) == 13
    # one current step (rest to a 2.65 A charge, the voltage 60 mV up) is one item of evidence:
    # the sign check cannot tell on one item (a glitch could make it), and says so
    check = info["sign"]["voltage_check"]
    assert check["verdict"] == "cannot tell"
    assert (check["steps"], check["agreeing_share"]) == (1, 1.0)
    assert check["step_resistance_ohm"] == pytest.approx((3.599601 - 3.534586) / 2.65, rel=0.01)
    (note,) = info["warnings"]
    assert "'Current (A)': the voltage does not tell the current's sign" in note
    # the interval from row 12 to 13: (0.000400839 - 2.01404e-5) Ah in 0.5161 s, charging
    want = -(0.000400839 - 2.01404e-5) * 3600.0 / (301.214 - 300.6979)
    assert frame["current_a"].iloc[11] == pytest.approx(want)
    assert info["charge"]["discharged_ah_output"] == pytest.approx(
        info["charge"]["discharged_ah_counters"], abs=1e-15
    )


def test_pyprobes_own_maccor_export_warns_of_its_coarse_counter(capsys):
    """Maccor's 3-decimal Capacity steps by 8 mAh and stalls for two rows while 28.8 A flows:
    the counters' current is 28.8, 28.8, 28.8, 0, 0 A. The conversion says so; the channel
    is the user's alternative."""
    raw = DATA / "sample_data_maccor.csv"
    frame, info = cycler.convert(raw, "maccor")
    np.testing.assert_allclose(-frame["current_a"][11:16], [28.8, 28.8, 28.8, 0.0, 0.0], atol=1e-9)
    counter = [w for w in info["warnings"] if "--current-from channel" in w]
    assert len(counter) == 1
    held, held_info = cycler.convert(raw, "maccor", current_from="channel")
    np.testing.assert_allclose(-held["current_a"][11:], [28.844, 28.799, 28.798, 28.798, 28.798,
                                                         28.798])  # fmt: skip
    assert not [w for w in held_info["warnings"] if "--current-from channel" in w]
    # one step from rest into a 28.8 A discharge: one item, the sign check cannot tell
    for i in (info, held_info):
        assert i["sign"]["voltage_check"]["verdict"] == "cannot tell"
        assert i["sign"]["voltage_check"]["agreeing_share"] == 1.0


def test_the_cli_names_the_cyclers_read_here():
    from avoa_pipeline import names

    assert tuple(cycler.CYCLERS) == names.CYCLERS


# ----------------------------------------------------------------------------------------------
# real logs (issue 25): counters that dip, workbooks of several sheets, temperature channels,
# files given to the wrong reader


def test_a_counter_dip_is_a_negative_increment_and_a_fall_to_near_zero_a_restart():
    """The numbers of a real MITS Pro export: Charge_Capacity(Ah) reads 4.685807 then 4.685794
    during a discharge pulse (a dip of 13 µAh, then back), later falls to 0.000125 (a new
    cycle: the count since the restart)."""
    c = np.array([4.685801, 4.685807, 4.685794, 4.685794, 4.685807, 0.000125, 0.00025])
    inc, restarts, dips = cycler._increments(c)
    assert restarts == 1
    np.testing.assert_allclose(inc, [6e-6, -13e-6, 0.0, 13e-6, 0.000125, 0.000125], atol=1e-12)
    assert dips.max() == pytest.approx(13e-6)
    assert (dips > 0).sum() == 1


def test_a_per_step_counter_after_a_short_step_restarts_at_the_step_change(tmp_path):
    """Maccor's per-step counter: 5 s at 3 A (4.2 mAh), then a 1-A step whose first row comes
    10 s in (2.8 mAh, two thirds of the previous count): not near zero, but no more than that
    interval could count, at a change of step: a restart."""
    from cycler_fixtures import write_maccor

    protocol = [(60.0, 0.0, 10.0), (5.0, -3.0, 1.0), (60.0, 1.0, 10.0), (60.0, 0.0, 10.0)]
    truth = simulate_logged(protocol)
    path = write_maccor(truth, tmp_path / "m.csv")
    counter = pd.read_csv(path, skiprows=2)["Capacity"].to_numpy()
    k = int(np.flatnonzero(truth.step == 3)[0])
    assert 0.5 < counter[k] / counter[k - 1] < 1.0  # the case a fraction alone takes for a dip
    frame, info = cycler.convert(path, "maccor")
    np.testing.assert_allclose(frame["current_a"][:-1], truth.interval_mean_discharge(), atol=1e-6)
    assert info["current"]["counters"]["dips"] == 0


def test_a_dip_at_a_step_change_is_not_a_restart():
    """Arbin's charge counter at 37.5 mAh (three charge pulses into a new cycle) dips by 13 µAh
    on the first row after an 18-A discharge pulse, logged 10 s later: at a change of step the
    interval could have counted 0.1 Ah, but of discharge: the charge counter counts none."""
    arrays = {
        "time": np.array([0.0, 10.0, 20.0]),
        "step": np.array([4, 5, 5]),
        "current": np.array([-18.0, 0.0, 0.0]),
        "counters": [np.array([0.0375, 0.037487, 0.037487]), np.array([4.2, 4.25, 4.25])],
    }
    q, info = cycler.net_charge(arrays, "pair")
    np.testing.assert_allclose(q, [0.0, -0.05 - 13e-6, -0.05 - 13e-6], atol=1e-12)
    assert (info["restarts"], info["dips"]) == (0, 1)


HPPC_RESTART_STEP = 17  # the first step after the EIS: a new cycle, both counters restart


def _hppc_export(folder: Path, edge_rows: bool = True):
    truth = simulate_logged(hppc_eis_protocol(), grid=0.25, lag_tau=0.5, soc0=0.05,
                            capacity_ah=5.0, r0=0.015, edge_rows=edge_rows)  # fmt: skip
    counters = counters_with_dips(truth, HPPC_RESTART_STEP)
    return write_arbin_classic(truth, folder / "hppc_eis.csv", counters=counters), truth


@pytest.mark.parametrize("edge_rows", [True, False])
def test_an_hppc_and_eis_export_with_dipping_counters_converts_to_its_charge(tmp_path,
                                                                            edge_rows):  # fmt: skip
    """A classic Arbin HPPC + EIS export as MITS Pro writes it: 18-A pulses logged every
    0.25 s, 10-s logging elsewhere, a 57,000-s EIS step of two rows, a channel lagging by
    0.5 s, counters to 6 decimals that dither by 0-2 quanta and dip by 1, 2 or 13 µAh in pulses
    against their direction (half of the dips recovering), and a new cycle (both counters
    restart) after the EIS. Taking each fall for a restart counted the whole 4.5-Ah counter into
    a 0.25-s interval, and the export was refused as "mixed units"."""
    path, truth = _hppc_export(tmp_path, edge_rows)
    assert np.diff(truth.t).max() == 57000.0  # the EIS step: no row between its ends
    frame, info = cycler.convert(path, "arbin")
    net = truth.discharged[-1] - truth.charged[-1]
    assert info["charge"]["discharged_ah_output"] == pytest.approx(net, rel=0.005)  # the goal
    # everywhere within the dips left uncorrected (13 + 2 + 1 + 13 µAh) and the rounding
    counted = np.cumsum(np.diff(frame["time_s"]) * frame["current_a"][:-1]) / 3600.0
    wanted = np.cumsum(np.diff(truth.t) * truth.interval_mean_discharge()) / 3600.0
    assert np.abs(counted - wanted).max() < 5e-5
    counters = info["current"]["counters"]
    assert counters["restarts"] == 2
    assert counters["dips"] > 8 * 10  # falls in each of the 8 pulses, none taken for a restart
    assert 13e-6 - 1e-9 < counters["largest_dip_ah"] < 15e-6 + 1e-9  # 13 µAh and the dither
    assert info["sign"]["voltage_check"]["confirmed"]


def _drive(seed: int, steps: int = 40) -> list[tuple[float, float]]:
    """A drive cycle: 5-20 s steps at -4..2 A (charge positive) after a rest, logged at 1 s."""
    rng = np.random.default_rng(seed)
    out = [(300.0, 0.0)]
    for _ in range(steps):
        out.append((float(rng.integers(5, 21)), float(rng.choice([-4.0, -2.5, -1.0, 0.5, 2.0]))))
    return [*out, (300.0, 0.0)]


CYCLES = ("DST", "US06", "FUDS")


@pytest.fixture(scope="module")
def drive_workbook(tmp_path_factory):
    """One test's drive cycles on a sheet each (as CALCE publishes them), each its own test
    (time and counters from 0), the channel's thermocouple as ``Temperature (C)_1``; and each
    sheet as a classic CSV of its own."""
    folder = tmp_path_factory.mktemp("drive")
    truths = {name: simulate_logged(_drive(j), dt_rest=10.0, soc0=0.9 - 0.2 * j, seed=j)
              for j, name in enumerate(CYCLES)}  # fmt: skip
    book = write_arbin_workbook(truths, folder / "drive.xlsx", restart_step=None,
                                temperature="Temperature (C)_1")  # fmt: skip
    csvs = {name: write_arbin_classic(truth, folder / f"{name}.csv", restart_step=None,
                                      temperature="Temperature (C)_1")
            for name, truth in truths.items()}  # fmt: skip
    return book, truths, csvs


def test_a_workbook_of_several_data_sheets_is_never_read_silently(drive_workbook, tmp_path,
                                                                  capsys):  # fmt: skip
    book, _, _ = drive_workbook
    assert cycler.data_sheets(book, "arbin") == list(CYCLES)  # not Global_Info, Statistics
    names = "'DST', 'US06', 'FUDS'"
    with pytest.raises(
        UserError, match=f"3 data sheets \\({names}\\); choose with convert --sheet"
    ):
        cycler.convert(book, "arbin")
    out = tmp_path / "out" / "drive.csv"
    for argv in (["convert", str(book), "--cycler", "arbin", "--out", str(out)],
                 ["diagnose", str(book), "--cycler", "arbin", "--out", str(tmp_path / "d")],
                 ["convert", str(book), "--cycler", "arbin", "--out", str(out), "--sheet",
                  "Global_Info"]):  # fmt: skip
        assert main(argv) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1, err
        assert names in err, err
        assert str(book) in err, err
    assert not out.parent.exists()
    assert not (tmp_path / "d").exists()


def test_a_workbook_sheet_each_sheet_or_all_sheets_in_order(drive_workbook, tmp_path, capsys):
    """--sheet NAME is that sheet's record (the same as its CSV export, with its
    ``Temperature (C)_1``); --sheets each writes one per sheet; --sheets concat one record in
    sheet order, each test placed one sampling interval after the last, a rest between."""
    book, truths, csvs = drive_workbook
    alone = {name: cycler.convert(csv, "arbin")[0] for name, csv in csvs.items()}
    for name, truth in truths.items():
        np.testing.assert_allclose(alone[name]["temperature_c"], truth.temperature, atol=1e-5)
    got, info = cycler.convert(book, "arbin", sheet="US06")
    pd.testing.assert_frame_equal(got, alone["US06"])
    assert info["sheets"]["read"] == ["US06"]
    assert info["columns"]["temperature"]["column"] == "Temperature (C)_1"

    out = tmp_path / "cell.csv"
    assert main(["convert", str(book), "--cycler", "arbin", "--out", str(out), "--sheets",
                 "each"]) == 0  # fmt: skip
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(
        f"cell-{n}.{e}" for n in CYCLES for e in ("csv", "json")
    )
    for name in CYCLES:
        pd.testing.assert_frame_equal(pd.read_csv(tmp_path / f"cell-{name}.csv"), alone[name],
                                      check_exact=False, rtol=1e-12)  # fmt: skip
    assert capsys.readouterr().out.count("wrote") == 3

    joined, info = cycler.convert(book, "arbin", concat=True)
    sizes = [len(alone[n]) for n in CYCLES]
    assert len(joined) == sum(sizes)
    assert info["sheets"]["read"] == list(CYCLES)
    assert (np.diff(joined["time_s"]) > 0).all()
    starts = np.r_[0, np.cumsum(sizes)]
    for k, name in enumerate(CYCLES):
        part = joined.iloc[starts[k] : starts[k + 1]].reset_index(drop=True)
        # its own record, shifted in time, but for its last row: the join, counted as a rest
        np.testing.assert_allclose(part["time_s"] - part["time_s"][0], alone[name]["time_s"])
        # (to rounding: the charge and time carried over from the sheets before)
        np.testing.assert_allclose(part["current_a"][:-1], alone[name]["current_a"][:-1],
                                   atol=1e-9)  # fmt: skip
        np.testing.assert_array_equal(part["voltage_v"], alone[name]["voltage_v"])
        if k < len(CYCLES) - 1:
            assert part["current_a"].iloc[-1] == 0.0
            gap = joined["time_s"][starts[k + 1]] - part["time_s"].iloc[-1]
            assert gap == pytest.approx(np.median(np.diff(truths[CYCLES[k + 1]].t)))
    total = sum(cycler.convert(csvs[n], "arbin")[1]["charge"]["discharged_ah_output"]
                for n in CYCLES)  # fmt: skip
    assert info["charge"]["discharged_ah_output"] == pytest.approx(total, abs=1e-9)
    assert info["sheets"]["joins"][0].startswith("time started over")


def test_a_test_split_over_sheets_joins_into_its_whole_record(tmp_path):
    """MITS Pro splits a long test over sheets (``Channel_1-006``, ``Channel_1-006_1``): the
    clock and the counters run on, so the join is counted as any interval; the record equals
    the unsplit export's."""
    from dataclasses import fields

    from cycler_fixtures import Truth

    truth = simulate()
    k = 50  # the split falls mid-step, as a row limit falls: here under load (2 A)
    assert truth.step[k - 1] == truth.step[k] == 2

    def part(rows):
        return Truth(*(getattr(truth, f.name)[rows] for f in fields(Truth)))

    book = write_arbin_workbook({"Channel_1-006": part(slice(0, k)),
                                 "Channel_1-006_1": part(slice(k, None))},
                                tmp_path / "split.xlsx", restart_step=None)  # fmt: skip
    whole, _ = cycler.convert(write_arbin_classic(truth, tmp_path / "whole.csv",
                                                  restart_step=None), "arbin")  # fmt: skip
    joined, info = cycler.convert(book, "arbin", concat=True)
    assert info["sheets"]["joins"] == ["time continued"]
    pd.testing.assert_frame_equal(joined, whole, check_exact=False, rtol=0, atol=1e-9)


def test_sheets_of_different_columns_are_not_joined(tmp_path):
    from openpyxl import load_workbook

    book = write_arbin_workbook({"A": simulate()}, tmp_path / "a.xlsx")
    wb = load_workbook(book)
    other = wb.copy_worksheet(wb["A"])
    other.title = "B"
    other.cell(1, len(CLASSIC_ARBIN_COLUMNS)).value = "Temperature (C)_1"
    wb.save(book)
    want = ("sheet 'B': its temperature column 'Temperature (C)_1' differs from sheet 'A''s "
            "'Aux_Temperature_1(C)'")  # fmt: skip
    with pytest.raises(DataError, match=re.escape(want)):
        cycler.convert(book, "arbin", concat=True)


def test_a_sheet_flag_on_a_text_export_is_refused(tmp_path):
    path, _ = export("arbin", tmp_path)
    with pytest.raises(UserError, match="--sheet X: not a workbook"):
        cycler.convert(path, "arbin", sheet="X")


@pytest.mark.parametrize(
    ("name", "columns", "chosen"),
    [
        ("arbin", ["Temperature (C)_1", "dV/dt(V/s)_1"], "Temperature (C)_1"),
        ("arbin", ["Temperature (C)_2", "Aux_Temperature_1(C)"], "Aux_Temperature_1(C)"),
        ("arbin", ["Aux_Temperature_2 (C)", "Aux_Temperature_1 (C)"], "Aux_Temperature_1 (C)"),
        ("arbin", ["Temperature(C)"], "Temperature(C)"),
        ("maccor", ["Temp 2", "Temp 1"], "Temp 1"),
        ("neware", ["T1(℃)"], "T1(℃)"),
        ("neware", ["Auxiliary temperature(℃)"], "Auxiliary temperature(℃)"),
        ("biologic", ["Temperature/°C"], "Temperature/°C"),
        ("basytec", ["T1[°C]"], "T1[°C]"),
        ("basytec", ["T[K]"], "T[K]"),
    ],
)
def test_each_cyclers_temperature_headers_are_found(name, columns, chosen):
    layouts = cycler.CYCLERS[name].layouts
    found = [c for c, _ in cycler._temperatures("f", layouts[-1], ["x", *columns])]
    assert found[0] == chosen
    assert sorted(found) == sorted(columns if "dV/dt" not in columns[-1] else columns[:1])


def test_several_temperature_channels_the_first_used_the_others_named(tmp_path):
    truth = simulate()
    path = write_arbin_classic(
        truth,
        tmp_path / "two.csv",
        temperature="Temperature (C)_1",
        temperatures={"Temperature (C)_2": truth.temperature + 3.0},
    )
    frame, info = cycler.convert(path, "arbin")
    np.testing.assert_allclose(frame["temperature_c"], truth.temperature, atol=1e-5)
    (note,) = [w for w in info["warnings"] if "temperature columns" in w]
    assert "column 'Temperature (C)_1' is used, 'Temperature (C)_2' not" in note


def test_a_temperature_in_kelvin(tmp_path, capsys):
    """Labelled K: converted. Labelled °C with 250-350 in it: refused, never read as 298 °C."""
    truth = simulate()
    kelvin = truth.temperature + 273.15
    path = write_arbin_classic(truth, tmp_path / "k.csv", temperature="Aux_Temperature_9(x)",
                               temperatures={"Aux_Temperature_1(K)": kelvin})  # fmt: skip
    with pytest.raises(DataError, match="'Aux_Temperature_9\\(x\\)': temperature unit 'x'"):
        cycler.convert(path, "arbin")
    path = write_arbin_classic(truth, tmp_path / "k.csv", temperature="Aux_Temperature_1(K)")
    raw = pd.read_csv(path)
    raw["Aux_Temperature_1(K)"] = kelvin
    raw.to_csv(path, index=False)
    frame, _ = cycler.convert(path, "arbin")
    np.testing.assert_allclose(frame["temperature_c"], truth.temperature, atol=1e-9)
    raw = raw.rename(columns={"Aux_Temperature_1(K)": "Temperature (C)_1"})
    raw.to_csv(path, index=False)
    # (named by the raw column, whether cycler.py or records.check_scale refuses it)
    cli_error(tmp_path, capsys, path, "arbin", "column 'Temperature (C)_1': ")
    cli_error(tmp_path, capsys, path, "arbin", "looks like kelvin")


def test_each_cyclers_export_is_recognised_by_its_header(tmp_path):
    for name in CYCLERS:
        path, _ = export(name, tmp_path)
        assert cycler.sniff(path) == name
        assert cycler.sniff(path, exclude=name) == ""
    assert cycler.sniff(write_arbin_classic_xlsx(simulate(), tmp_path / "c.xlsx")) == "arbin"
    assert cycler.sniff(tmp_path / "missing.csv") == ""


def test_a_raw_export_without_cycler_is_named(tmp_path, capsys):
    """diagnose, simulate and --ocv without --cycler: which cycler it looks like and the flag,
    not "missing column 'time_s'" or a codec error."""
    from avoa_pipeline import inputs

    csv, _ = export("arbin", tmp_path)
    book = write_arbin_classic_xlsx(simulate(), tmp_path / "c.xlsx")
    mpt, _ = export("biologic", tmp_path)
    for path, label, name in ((csv, "an Arbin", "arbin"), (book, "an Arbin", "arbin"),
                              (mpt, "a BioLogic", "biologic")):  # fmt: skip
        want = f"{path}: this looks like {label} export: add --cycler {name}"
        with pytest.raises(DataError, match=re.escape(want)):
            inputs.read_record(path)
        with pytest.raises(DataError, match=re.escape(want)):
            inputs.read_ocv(path)
    assert main(["diagnose", str(csv), "--out", str(tmp_path / "d")]) == 2
    err = capsys.readouterr().err
    assert err == f"error: {csv}: this looks like an Arbin export: add --cycler arbin\n"
    # a workbook no cycler's header matches: still not a codec error
    from openpyxl import Workbook

    wb = Workbook()
    wb.active.append(["a", "b"])
    wb.save(tmp_path / "other.xlsx")
    with pytest.raises(DataError, match="a workbook; a record is a CSV"):
        inputs.read_record(tmp_path / "other.xlsx")


@pytest.mark.parametrize("wrong", ["basytec", "biologic", "maccor", "neware"])
def test_a_reader_failure_names_the_cycler_expected_and_the_one_it_looks_like(tmp_path, capsys,
                                                                              wrong):  # fmt: skip
    """PyProBE's Basytec reader on an Arbin CSV fails with "cannot access local variable
    'start_time_line'": one line instead, naming the file, the cycler and its look."""
    path, _ = export("arbin", tmp_path)
    label = cycler.CYCLERS[wrong].label
    cli_error(tmp_path, capsys, path, wrong, f"{cycler.CYCLERS[wrong].article} {label} export")
    cli_error(tmp_path, capsys, path, wrong, "it looks like an Arbin export: use --cycler arbin")
    main(["convert", str(path), "--cycler", wrong, "--out", str(tmp_path / "o.csv")])
    assert "start_time_line" not in capsys.readouterr().err
