"""The records layer and the input layer: one validator, scale check and sign check, right on
records logged the way cyclers log them; every command's inputs read and checked once, before
any work; bad input never gets a confident answer (a one-line refusal, or a warning)."""

import ast
import json
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from cycler_fixtures import (
    CAPACITY_AH,
    canonical,
    gitt_protocol,
    simulate,
    simulate_logged,
    write_arbin,
    write_arbin_classic,
    write_arbin_classic_xlsx,
)
from scipy.signal import lfilter
from test_ecm import TRUTH, profile_frame, with_voltage

from avoa_pipeline import inputs, records
from avoa_pipeline.cli import main
from avoa_pipeline.errors import DataError, UserError
from avoa_pipeline.importers import cycler
from avoa_pipeline.model import ecm
from avoa_pipeline.model.fitted import FittedModel

SRC = Path(__file__).resolve().parents[2] / "src" / "avoa_pipeline"


def _gitt(pulses=3, *, dt_rest=60.0, edge_rows=True, rest_s=3600.0, seed=0, **kw):
    """A GITT record as ``convert`` writes one (interval means from the counters, the logged
    voltage), discharge positive."""
    truth = simulate_logged(gitt_protocol(pulses, -0.5, rest_s=rest_s), dt_rest=dt_rest,
                            dt_load=10.0, edge_rows=edge_rows, noise_v=1e-3, seed=seed,
                            soc0=0.98, **kw)  # fmt: skip
    return canonical(truth), truth


def _flip(frame):
    return frame.assign(current_a=-frame["current_a"])


def _csv(folder, frame, name):
    path = Path(folder) / name
    frame.to_csv(path, index=False)
    return path


def _good(seed=0):
    frame = profile_frame([(300, 0.0), (1200, 2.0), (600, 0.0), (600, -1.5), (300, 0.0)])
    return with_voltage(frame, TRUTH, noise_v=1e-3, seed=seed)


def _one_line_error(capsys, *words):
    err = capsys.readouterr().err
    assert err.count("\n") == 1, err
    assert err.startswith("error: "), err
    for w in words:
        assert w in err, err
    return err


# ----------------------------------------------------------------------------------------------
# the sign check


@pytest.mark.parametrize("edge_rows", [True, False], ids=["edge-rows", "late-logged"])
@pytest.mark.parametrize("dt_rest", [60.0, 300.0])
@pytest.mark.parametrize("pulses", [3, 20], ids=["short", "long"])
def test_sign_check_reads_logs_as_cyclers_write_them(edge_rows, dt_rest, pulses):
    """GITT logged as cyclers do (rests every 60 or 300 s, the step's end row under the old
    current or no row at the edge, interval means from the counters): the median of step
    ratios gave ~0 here, refused in both signs; all the evidence gives the sign, both ways."""
    frame, _ = _gitt(pulses, dt_rest=dt_rest, edge_rows=edge_rows, rest_s=1800.0)
    ev = records.frame_sign(frame)
    assert ev.verdict == "discharge-positive", ev
    assert ev.steps + ev.events >= 2 * pulses  # every transition
    assert records.frame_sign(_flip(frame)).verdict == "charge-positive"


@pytest.mark.parametrize("lag_tau", [None, 3.0])
def test_sign_check_reads_the_held_channel(lag_tau):
    """A canonical file made from the current channel (held, perhaps filtered) instead of the
    counters: the same verdict."""
    _, truth = _gitt(3, lag_tau=lag_tau)
    frame = canonical(truth).assign(current_a=-truth.channel)
    assert records.frame_sign(frame).verdict == "discharge-positive"
    assert records.frame_sign(_flip(frame)).verdict == "charge-positive"


def test_sign_check_sees_ramped_edges():
    """A filtered current (no one-sample step reaches STEP_FRACTION of the scale, so a check on
    steps alone never ran): the ramps and the rest/load transitions carry the sign."""
    frame = profile_frame()
    b = np.exp(-1.0 / 15.0)
    frame["current_a"] = lfilter([1 - b], [1, -b], frame["current_a"])
    frame = with_voltage(frame, TRUTH, noise_v=1e-3)
    scale = records.current_scale(frame["current_a"])
    assert np.max(np.abs(np.diff(frame["current_a"]))) < records.STEP_FRACTION * scale
    assert records.frame_sign(frame).verdict == "discharge-positive"
    assert records.frame_sign(_flip(frame)).verdict == "charge-positive"


def test_sign_check_cannot_tell_on_weak_evidence():
    rng = np.random.default_rng(1)
    t = np.arange(3000.0)
    noise = pd.DataFrame({"time_s": t, "current_a": rng.choice([0.0, 1.0, -1.0], t.size),
                          "voltage_v": 3.7 + 1e-3 * rng.standard_normal(t.size)})  # fmt: skip
    assert records.frame_sign(noise).verdict == "cannot tell"
    one_step = pd.DataFrame({"time_s": t, "current_a": np.where(t < 1500, 0.0, 1.0),
                             "voltage_v": np.where(t < 1500, 3.7, 3.65)})  # fmt: skip
    ev = records.frame_sign(one_step)
    assert ev.verdict == "cannot tell"  # one transition is one item, however clear
    assert (ev.steps, ev.events, ev.agreeing) == (1, 0, 1.0)


def _flat_cell_logged_late(seed=3, lag=1):
    """A flat-OCV cell (LFP's plateau) under drive-like 1-Hz steps: its voltage answers only
    through R0 (no drift, no relaxation to tell the sign after the jump), 1 mV of noise; the
    current channel ``lag`` samples late, as a cycler logs it at each edge."""
    rng = np.random.default_rng(seed)
    steps = [np.full(int(rng.integers(10, 61)), rng.choice([0.0, -1.0, 0.5, 1.0, 2.0]))
             for _ in range(60)]  # fmt: skip
    cur = np.concatenate(steps)
    v = 3.30 - 0.03 * cur + 1e-3 * rng.standard_normal(cur.size)
    logged = np.r_[np.full(lag, cur[0]), cur[: cur.size - lag]]
    return pd.DataFrame({"time_s": np.arange(cur.size, dtype=float), "current_a": logged,
                         "voltage_v": v})  # fmt: skip


def test_sign_check_reads_a_current_logged_a_sample_late():
    """With the current a sample late the first look's window V[k+1] − V[k−1] opens after the
    jump: a flat OCV leaves it nothing. The second look (the current a row earlier) tells, both
    ways, and says it did; without the lag the first look tells and the second is not taken."""
    frame = _flat_cell_logged_late()
    i, v = frame["current_a"].to_numpy(), frame["voltage_v"].to_numpy()
    first = records._sign_look(frame["time_s"].to_numpy(), i, v, records.SIGN_Z)
    assert first.verdict == "cannot tell", first
    ev = records.frame_sign(frame)
    assert (ev.verdict, ev.current_lag_samples) == ("discharge-positive", 1), ev
    assert ev.z > 5 * records.SIGN_LATE_Z  # every step clear: 3 units each
    assert "read a row earlier" in ev.describe()
    assert records.SignEvidence.from_dict(ev.as_dict()).current_lag_samples == 1  # a sidecar too
    flipped = records.frame_sign(_flip(frame))
    assert (flipped.verdict, flipped.current_lag_samples) == ("charge-positive", 1)
    on_time = records.frame_sign(_flat_cell_logged_late(lag=0))
    assert (on_time.verdict, on_time.current_lag_samples) == ("discharge-positive", 0)
    assert "current_lag_samples" not in on_time.as_dict()  # sidecars as before the lag


def test_the_second_look_declares_no_sign_on_noise():
    """Voltage that does not answer the current: neither look declares a sign (at the two
    looks' thresholds chance declares one in at most 0.15 % of records)."""
    rng = np.random.default_rng(5)
    for _ in range(20):
        cur = np.repeat(rng.choice([0.0, 1.0, -1.0, 2.0], 60), 10)
        frame = pd.DataFrame({"time_s": np.arange(cur.size, dtype=float), "current_a": cur,
                              "voltage_v": 3.7 + 1e-3 * rng.standard_normal(cur.size)})  # fmt: skip
        assert records.frame_sign(frame).verdict == "cannot tell"


def test_a_few_odd_rows_do_not_flip_the_sign():
    """Spikes of the wrong sign at a fifth of the steps (glitches, rows logged at the wrong
    instant): each item weighs at most SIGN_CLIP noise units, so the rest carry the verdict."""
    frame, _ = _gitt(20)
    v = frame["voltage_v"].to_numpy().copy()
    steps = np.flatnonzero(np.abs(np.diff(frame["current_a"])) > 0.1) + 1
    for k in steps[::5]:
        v[k + 1] += 1.0 * np.sign(frame["current_a"].iloc[k] - frame["current_a"].iloc[k - 1])
    ev = records.frame_sign(frame.assign(voltage_v=v))
    assert ev.verdict == "discharge-positive", ev


def test_contradicted_sign_advises_the_flag_only_when_every_file_disagrees(tmp_path):
    a, _ = _gitt(3, seed=1)
    b, _ = _gitt(4, seed=2)
    pa, pb = _csv(tmp_path, _flip(a), "a.csv"), _csv(tmp_path, _flip(b), "b.csv")
    with pytest.raises(DataError, match="rerun with --current-sign charge-positive") as info:
        inputs.read_inputs([pa], [pb])
    assert "a.csv: column 'current_a': sign contradicts" in str(info.value)
    # the advised flag makes both pass
    read = inputs.read_inputs([pa], [pb], current_sign="charge-positive")
    np.testing.assert_allclose(read.train[0].frame["current_a"], a["current_a"])
    # only the validation file is flipped: the file is to be fixed, not the flag
    good = _csv(tmp_path, a, "good.csv")
    with pytest.raises(DataError) as info:
        inputs.read_inputs([good], [pb])
    msg = str(info.value)
    assert "b.csv: column 'current_a': sign contradicts" in msg
    assert "negate this file's current_a" in msg
    assert "rerun with" not in msg


def test_a_charge_positive_slow_test_is_refused(tmp_path):
    slow = _pseudo_ocv()
    good = _csv(tmp_path, _gitt(3)[0], "train.csv")
    path = _csv(tmp_path, _flip(slow), "c25.csv")
    with pytest.raises(DataError, match=r"c25\.csv: column 'current_a': sign contradicts"):
        inputs.read_ocv(path)
    with pytest.raises(DataError, match="negate this file's current_a"):
        inputs.read_inputs([good], ocv=path)


# ----------------------------------------------------------------------------------------------
# the OCV


def _pseudo_ocv(capacity=2.0):
    """A real pseudo-OCV test as ``convert`` writes it (:func:`_pocv_truth`)."""
    return canonical(_pocv_truth(capacity, edge_rows=True))


def test_pseudo_ocv_test_branches_are_the_slow_ones(tmp_path):
    """The longest runs by rows would be the slow ones here too, but the fast cycle comes first
    and moves as much charge: every run is considered, the slow ones are the branches."""
    table = inputs.read_ocv(_csv(tmp_path, _pseudo_ocv(), "pocv.csv"))
    assert table.how.startswith("mean of the discharge (1.9")
    assert "at median 0.08 A" in table.how
    assert "passed over (not slow or narrower): discharge 1.9 Ah at 1 A" in table.how
    assert table.capacity_ah == pytest.approx(0.95 * 2.0, rel=1e-3)
    assert table.notes == ()


def test_no_slow_branch_names_what_was_found(tmp_path):
    frame, _ = _gitt(20)  # C/4 pulses of 0.1 Ah: no run is slow
    with pytest.raises(DataError, match=r"no slow branch .*; found discharge 0\.1 Ah at 0\.5 A"):
        inputs.read_ocv(_csv(tmp_path, frame, "gitt.csv"))


def test_bad_ocv_inputs_are_refused_or_warned(tmp_path):
    soc = np.linspace(0, 1, 21)
    table = pd.DataFrame({"soc": soc, "ocv_v": 3.2 + 0.9 * soc})
    cases = {
        "mv.csv": (table.assign(ocv_v=1e3 * table["ocv_v"]), "column 'ocv_v': values 3200..4100"),
        "narrow.csv": (table.assign(soc=0.01 * soc), "spans SOC 0..0.01"),
        "falling.csv": (table.assign(ocv_v=table["ocv_v"][::-1].to_numpy()), "does not rise"),
        "percent.csv": (table.assign(soc=100 * soc), "outside [0, 1]"),
    }
    for name, (frame, words) in cases.items():
        with pytest.raises(DataError, match=words.replace("(", r"\(").replace("[", r"\[")):
            inputs.read_ocv(_csv(tmp_path, frame, name))
    slow = _pseudo_ocv()
    # a slow test in mA alone: the OCV over SOC does not depend on the current's unit, and the
    # records cannot tell mA of a small cell from A of a large one: a warning names the assumption
    ma = _csv(tmp_path, slow.assign(current_a=1e3 * slow["current_a"]), "ma.csv")
    assert any("taken as amperes" in n for n in inputs.read_ocv(ma).notes)
    # beside records in A, its charge (a capacity in its own units) gives the slip away
    from avoa_pipeline.gap import diagnose

    read = inputs.read_inputs([_csv(tmp_path, _good(), "good.csv")], ocv=ma)
    with pytest.raises(UserError, match=r"the slow branch's .* is the capacity in mAh"):
        diagnose.check_options(read.train, read.validate, None, None, read.ocv)


def test_a_partial_slow_test_is_noted_and_checked_against_the_records(tmp_path):
    """A slow discharge that stops half-way: no end-of-discharge knee (a note), and records
    that move more charge than its branch, or a capacity above it, are refused."""
    from avoa_pipeline.gap import diagnose

    cap, i = 2.0, 0.08
    protocol = [(600.0, 0.0), (0.5 * 3600 * cap / i, -i), (600.0, 0.0)]
    half = canonical(simulate_logged(protocol, dt_load=60.0, grid=1.0, soc0=0.97,
                                     capacity_ah=cap))  # fmt: skip
    path = _csv(tmp_path, half, "half.csv")
    table = inputs.read_ocv(path)
    assert table.capacity_ah == pytest.approx(1.0, rel=1e-3)
    (note,) = table.notes
    assert "no end-of-discharge knee" in note
    long = records.check(_gitt(20)[0], "gitt")  # moves 2 Ah
    with pytest.raises(DataError, match=r"half\.csv: the slow branch moves 1 Ah, less than the 2"):
        diagnose.check_options([long], [], None, None, table)
    short = records.check(_good(), "good")
    with pytest.raises(DataError, match=r"less than --capacity-ah 2\.9 Ah"):
        diagnose.check_options([short], [], 2.9, None, table)


# ----------------------------------------------------------------------------------------------
# units and scale


def test_time_in_ms_or_hours_is_refused():
    frame, _ = _gitt(20)
    good = _good()
    cases = [
        (frame.assign(time_s=1e3 * frame["time_s"]), "time in ms"),
        (frame.assign(time_s=frame["time_s"] / 3600), "in hours"),  # 60-s rests: from the rests
        (good.assign(time_s=good["time_s"] / 3600), "in hours"),  # 1-s logging: from the step
        (good.assign(time_s=1e3 * good["time_s"]), "time in ms"),
    ]
    for bad, words in cases:
        with pytest.raises(DataError, match=f"column 'time_s': .*{words}"):
            records.check(bad, "f")
    records.check(frame, "f")
    records.check(good, "f")


def test_capacity_outside_what_the_records_allow_is_an_error():
    good = records.check(_good(), "good")
    scale = records.current_scale(good.frame["current_a"])
    swing = records.charge_swing_ah(good.frame["time_s"], good.frame["current_a"])
    for value, words in ((2900.0, "in mAh"), (0.3, "below the"), (0.0, "positive"),
                         (0.03, "in mA")):  # fmt: skip
        with pytest.raises(UserError, match=words):
            records.check_capacity(value, swing, scale, "--capacity-ah")
    records.check_capacity(2.57, swing, scale, "--capacity-ah")


def test_delimiters_and_decimal_commas_are_named(tmp_path):
    good = _good().iloc[:10]
    semi = tmp_path / "semi.csv"
    good.to_csv(semi, sep=";", decimal=",", index=False)
    with pytest.raises(DataError, match="separated by ';'"):
        inputs.read_record(semi)
    comma = tmp_path / "comma.csv"
    comma.write_text("time_s,current_a,voltage_v\n0,0,3,7\n1,0,3,7\n")
    with pytest.raises(DataError, match="more fields than the header"):
        inputs.read_record(comma)
    with pytest.raises(DataError, match="a folder, not a CSV"):
        inputs.read_record(tmp_path)


# ----------------------------------------------------------------------------------------------
# the commands


def test_duplicated_records_are_refused(tmp_path, capsys):
    a = _csv(tmp_path, _good(), "a.csv")
    copy = _csv(tmp_path, _good(), "copy.csv")
    for args in ([str(a), str(a)], [str(a), "--validate", str(a)], [str(a), "--validate",
                                                                     str(copy)]):  # fmt: skip
        assert main(["diagnose", *args, "--out", str(tmp_path / "out")]) == 2
        _one_line_error(capsys, "each record may be given once")
    assert not (tmp_path / "out").exists()


def _model(**params):
    table = ecm.OcvTable.from_points(np.linspace(0, 1, 11), 3.2 + 0.9 * np.linspace(0, 1, 11))
    names = [n for n in ecm.Config((), table).names() if not ecm.PARAMS[n].per_record]
    x = ecm.vector({"capacity_ah": 2.57, "r0_ohm": 0.05, "r1_ohm": 0.02, "tau1_s": 60.0,
                    **params})  # fmt: skip
    bounds = {n: (x[ecm.IDX[n]] - 1, x[ecm.IDX[n]] + 1) for n in names}
    return FittedModel(ecm.Config((), table), x, ecm.Knots(0, 0.2), 298.15, bounds)


def test_simulate_judges_a_model_by_the_librarys_physics(tmp_path, capsys):
    data = _csv(tmp_path, _good(), "d.csv")
    model = _model()
    ok = tmp_path / "ok.json"
    model.save(ok)
    assert main(["simulate", str(ok), str(data), "--out", str(tmp_path / "p.csv")]) == 0
    # a parameter and its bound edited together: the library's range refuses it
    d = json.loads(ok.read_text())
    d["parameters"]["r0_ohm"], d["bounds"]["r0_ohm"] = 50.0, [0.0, 100.0]
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps(d))
    capsys.readouterr()
    assert main(["simulate", str(bad), str(data), "--out", str(tmp_path / "q.csv")]) == 2
    _one_line_error(capsys, "parameters.r0_ohm", "physical range")
    # every value in range, the voltage not a cell's (2 Ω at 2 A)
    _model(r0_ohm=2.0).save(tmp_path / "r2.json")
    assert main(["simulate", str(tmp_path / "r2.json"), str(data), "--out",
                 str(tmp_path / "r.csv")]) == 2  # fmt: skip
    _one_line_error(capsys, "r2.json: the model predicts", "outside one cell's")
    assert {p.name for p in tmp_path.iterdir()} == {"d.csv", "ok.json", "p.csv", "bad.json",
                                                     "r2.json"}  # fmt: skip


def test_no_output_may_be_an_input_and_outputs_are_checked_first(tmp_path, capsys):
    data = _csv(tmp_path, _good(), "d.csv")
    model = tmp_path / "m.json"
    _model().save(model)
    raw = write_arbin(simulate(), tmp_path / "raw.csv")
    before = {p: p.read_bytes() for p in (data, model, raw)}
    (tmp_path / "folder").mkdir()
    (tmp_path / "afile").write_text("x")
    cases = [
        ["simulate", str(model), str(data), "--out", str(data)],
        ["simulate", str(model), str(data), "--out", str(model)],
        ["convert", str(raw), "--cycler", "arbin", "--out", str(raw)],
        ["simulate", str(model), str(data), "--out", str(tmp_path / "folder")],
        ["simulate", str(model), str(data), "--out", str(tmp_path / "afile" / "p.csv")],
        ["simulate", str(model), str(tmp_path / "folder"), "--out", str(tmp_path / "p.csv")],
        ["simulate", str(model), str(data), "--out", "/proc/avoa-test/p.csv"],
        ["diagnose", str(data), "--out", str(tmp_path / "afile")],
        ["diagnose", str(data), "--out", str(tmp_path / "afile" / "out")],
    ]
    for argv in cases:
        assert main(argv) == 2, argv
        _one_line_error(capsys)
    assert {p: p.read_bytes() for p in before} == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["afile", "d.csv", "folder", "m.json",
                                                          "raw.csv"]  # fmt: skip


def test_diagnose_checks_every_input_and_output_before_the_first_fit(tmp_path, capsys,
                                                                     monkeypatch):  # fmt: skip
    from avoa_pipeline.gap import diagnose

    def no_fit(*a, **k):
        raise AssertionError("a fit started")

    monkeypatch.setattr(diagnose.selection.Context, "fit", no_fit)
    data = _csv(tmp_path, _good(), "d.csv")
    flipped = _csv(tmp_path, _flip(_good(seed=3)), "f.csv")
    (tmp_path / "afile").write_text("x")
    for extra, words in (
        (["--out", str(tmp_path / "afile")], "is a file"),
        (["--out", str(tmp_path / "o"), "--validate", str(flipped)], "sign contradicts"),
        (["--out", str(tmp_path / "o"), "--capacity-ah", "2900"], "--capacity-ah 2900"),
        (["--out", str(tmp_path / "o"), "--soc0", "2"], "--soc0"),
    ):
        assert main(["diagnose", str(data), *extra]) == 2
        _one_line_error(capsys, words)
    assert not (tmp_path / "o").exists()


def test_a_model_far_off_the_data_stops_the_diagnosis(tmp_path, capsys):
    """An OCV of another cell (4.6-5.5 V, this one's is 3.2-4.1 V): every check passes one by
    one, and the base fit misses by more than the record's own voltage varies."""
    soc = np.linspace(0, 1, 21)
    ocv = _csv(tmp_path, pd.DataFrame({"soc": soc, "ocv_v": 4.6 + 0.9 * soc}), "other_cell.csv")
    data = _csv(tmp_path, _good(), "d.csv")
    out = tmp_path / "out"
    assert main(["diagnose", str(data), "--ocv", str(ocv), "--out", str(out)]) == 2
    _one_line_error(capsys, "the base model misses the records by", "do not describe one cell")
    assert not out.exists()


# ----------------------------------------------------------------------------------------------
# raw exports


def test_classic_arbin_exports_read_as_the_newer_layout(tmp_path):
    truth = simulate()
    new, _ = cycler.convert(write_arbin(truth, tmp_path / "new.csv"), "arbin")
    for path in (write_arbin_classic(truth, tmp_path / "classic.csv"),
                 write_arbin_classic_xlsx(truth, tmp_path / "classic.xlsx")):  # fmt: skip
        got, info = cycler.convert(path, "arbin")
        pd.testing.assert_frame_equal(got, new)
        assert info["columns"]["layout"] == "MITS Pro, classic export"
        assert info["columns"]["time"]["column"] == "Test_Time(s)"
        assert info["current"]["counters"]["restarts"] == 2


def test_an_export_of_neither_arbin_layout_names_both(tmp_path):
    path = tmp_path / "x.csv"
    path.write_text("Time,Amps,Volts\n0,0,3.7\n1,1,3.6\n")
    with pytest.raises(DataError) as info:
        cycler.convert(path, "arbin")
    msg = str(info.value)
    assert "'Test Time (<unit>)' (MITS Pro, newer export)" in msg
    assert "'Test_Time(<unit>)' (MITS Pro, classic export)" in msg
    assert "not an Arbin export" in msg


def test_a_sign_the_export_cannot_tell_is_a_warning_on_stderr(capsys, tmp_path):
    """PyProBE's own Arbin sample holds one current step: not enough to tell; simulate says so
    on stderr and carries on in the cycler's convention."""
    raw = Path(__file__).resolve().parents[1] / "data" / "pyprobe" / "sample_data_arbin.csv"
    rec = inputs.read_record(raw, cycler="arbin")
    assert rec.sign.verdict == "cannot tell"
    (note,) = rec.warnings
    assert "does not tell the current's sign" in note
    model = tmp_path / "m.json"
    _model().save(model)
    assert main(["simulate", str(model), str(raw), "--cycler", "arbin", "--out",
                 str(tmp_path / "p.csv")]) == 0  # fmt: skip
    err = capsys.readouterr().err
    assert err.startswith("warning: ")
    assert "does not tell the current's sign" in err


# ----------------------------------------------------------------------------------------------
# the code's shape


def _import_graph() -> dict[str, set[str]]:
    """Every import (module level and inside functions) between the package's modules."""
    mods = {}
    for p in SRC.rglob("*.py"):
        parts = list(p.relative_to(SRC.parent).with_suffix("").parts)
        mods[".".join(parts[:-1] if parts[-1] == "__init__" else parts)] = p
    graph = {m: set() for m in mods}
    for m, p in mods.items():
        pkg = m.split(".") if p.name == "__init__.py" else m.split(".")[:-1]
        for node in ast.walk(ast.parse(p.read_text())):
            if isinstance(node, ast.ImportFrom):
                base = ".".join(pkg[: len(pkg) - node.level + 1]) if node.level else ""
                target = ".".join(x for x in (base, node.module) if x)
                for a in node.names:
                    name = f"{target}.{a.name}"
                    graph[m].add(name if name in mods else target)
            elif isinstance(node, ast.Import):
                graph[m].update(a.name for a in node.names)
        graph[m] = {t for t in graph[m] if t in mods and t != m}
    return graph


def test_the_import_graph_has_no_circle():
    graph = _import_graph()
    state: dict[str, int] = {}

    def visit(m, path):
        state[m] = 1
        for t in sorted(graph[m]):
            if state.get(t) == 1:
                pytest.fail("import circle: " + " -> ".join([*path, m, t]))
            if t not in state:
                visit(t, [*path, m])
        state[m] = 2

    for m in sorted(graph):
        if m not in state:
            visit(m, [])
    # the layers: the records layer and the model library never reach up to the readers
    for low in ("avoa_pipeline.records", "avoa_pipeline.model.ocv",
                "avoa_pipeline.importers.cycler"):  # fmt: skip
        assert not graph[low] & {"avoa_pipeline.inputs", "avoa_pipeline.gap.diagnose",
                                 "avoa_pipeline.cli"}, low  # fmt: skip


def test_the_command_line_imports_stay_cheap():
    code = ("import sys, avoa_pipeline.cli; print(sorted(m for m in ('numpy', 'pandas', 'numba', "
            "'scipy', 'pyprobe', 'pybamm') if m in sys.modules))")  # fmt: skip
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"


@pytest.mark.parametrize(
    "definition",
    [r"def validate\(\s*frame", r"def check_scale\(", r"def sign_evidence\(",
     r"def check_capacity\(", r"\bREST_FRACTION = ", r"\bSTEP_FRACTION = ",
     r"\bVOLTAGE_RANGE_V = ", r"\bAMBIGUOUS_CURRENT_A = ", r"def current_scale\("],
)  # fmt: skip
def test_each_check_is_defined_once(definition):
    where = [p for p in SRC.rglob("*.py") if re.search(definition, p.read_text())]
    assert [p.name for p in where] == ["records.py"]


# ----------------------------------------------------------------------------------------------
# the real records

REAL = Path(__file__).resolve().parents[3] / "shared" / "data" / "real"


@pytest.mark.skipif(not REAL.is_dir(), reason="../shared/data/real is not beside the repository")
def test_every_real_record_passes_the_records_layer(tmp_path):
    """Every record the config's real-data sources make (Panasonic: every test file; Samsung:
    three HPPC files; NASA: the 168 discharges) imports through the records layer's checks, and
    its voltage says its sign, the pipeline's, itself."""
    from avoa_pipeline import config as config_mod
    from avoa_pipeline.importers import nasa, panasonic, samsung

    cfg = config_mod.load(None)
    cfg["real"]["root"] = str(REAL)
    made = []
    for name in panasonic.records(cfg):
        out = tmp_path / f"p_{name.replace('/', '_')}.csv"
        panasonic.import_named(cfg, name, out)
        made.append(out)
    for temp in cfg["real"]["samsung"]["hppc"]:
        out = tmp_path / f"s_{temp}.csv"
        samsung.import_hppc(cfg, temp, out)
        made.append(out)
    out = tmp_path / "nasa.csv"
    nasa.import_b0005(cfg, out)
    made.append(out)
    for path in made:
        checked = records.read(path)
        assert checked.sign.verdict == "discharge-positive", (path, checked.sign)
    assert len(made) == len(panasonic.records(cfg)) + len(cfg["real"]["samsung"]["hppc"]) + 1


# ----------------------------------------------------------------------------------------------
# the chain as a user runs it


def _dynamic_protocol(seed: int, steps: int = 45) -> list[tuple[float, float]]:
    """Load steps of 50 s at currents from −2 to 3 A (charge positive), with a rest of 30 min
    every 15 steps: a test logged at 1 s under load and every 60 s at rest."""
    rng = np.random.default_rng(seed)
    out = [(600.0, 0.0)]
    for k in range(steps):
        out.append((50.0, float(rng.choice([-3.0, -2.0, -1.0, 1.0, 2.0]))))
        if k % 15 == 14:
            out.append((1800.0, 0.0))
    return out


def test_the_chain_from_a_raw_export_to_a_prediction(tmp_path, capsys):
    """Raw Arbin exports logged as real cyclers log (coarse rests, a lagging current channel,
    no row at a step's end, a counter restart; the classic layout) → ``convert`` → ``diagnose``
    with ``--ocv`` (a pseudo-OCV test with its fast cycle first) and ``--validate`` →
    ``simulate``: every step takes the previous one's output, and the answers equal those of
    the direct ``--cycler`` path."""
    logged = {"edge_rows": False, "lag_tau": 2.0, "dt_rest": 60.0, "dt_load": 1.0,
              "noise_v": 1e-3, "soc0": 0.9}  # fmt: skip
    raw = {
        "train": write_arbin_classic(simulate_logged(_dynamic_protocol(1), seed=1, **logged),
                                     tmp_path / "train_raw.csv", restart_step=20),
        "test": write_arbin_classic(simulate_logged(_dynamic_protocol(2, 30), seed=2, **logged),
                                    tmp_path / "test_raw.csv", restart_step=20),
        "ocv": write_arbin(_pocv_truth(), tmp_path / "ocv_raw.csv", restart_step=None),
    }  # fmt: skip
    conv = {}
    for name, path in raw.items():
        conv[name] = tmp_path / f"{name}.csv"
        assert main(["convert", str(path), "--cycler", "arbin", "--out", str(conv[name])]) == 0
    capsys.readouterr()
    a, b = tmp_path / "a", tmp_path / "b"
    assert main(["diagnose", str(conv["train"]), "--ocv", str(conv["ocv"]), "--validate",
                 str(conv["test"]), "--out", str(a)]) == 0  # fmt: skip
    assert main(["diagnose", str(raw["train"]), "--ocv", str(raw["ocv"]), "--validate",
                 str(raw["test"]), "--cycler", "arbin", "--out", str(b)]) == 0  # fmt: skip
    ra, rb = (json.loads((d / "diagnosis.json").read_text()) for d in (a, b))
    assert ra["selected"] == rb["selected"]
    assert ra["verdict"]["effect"] == rb["verdict"]["effect"]
    assert ra["base"]["rmse_mv"] == pytest.approx(rb["base"]["rmse_mv"], rel=1e-9)
    assert [v["rmse_mv"] for v in ra["validation"]] == pytest.approx(
        [v["rmse_mv"] for v in rb["validation"]], rel=1e-9)  # fmt: skip
    assert ra["records"][0]["sign"]["verdict"] == "discharge-positive"
    assert (
        ra["validation"][0]["rmse_mv"] < 20.0
    )  # the same cell; its C/25 OCV table is no exact OCV
    pa, pb = tmp_path / "pa.csv", tmp_path / "pb.csv"
    assert main(["simulate", str(a / "model.json"), str(conv["test"]), "--out", str(pa)]) == 0
    assert main(["simulate", str(b / "model.json"), str(raw["test"]), "--cycler", "arbin",
                 "--out", str(pb)]) == 0  # fmt: skip
    np.testing.assert_allclose(pd.read_csv(pa)["model_v"], pd.read_csv(pb)["model_v"],
                               atol=1e-9)  # fmt: skip


def _pocv_truth(capacity=CAPACITY_AH, edge_rows=False):
    """A real pseudo-OCV test: a C/2 discharge and C/2 charge first, then the C/25 discharge
    and C/25 charge, each over 95 % of the capacity, rests between; logged every 60 s."""
    fast, slow = 0.5 * capacity, capacity / 25.0
    d_fast, d_slow = 0.95 * 3600.0 / 0.5, 0.95 * 3600.0 * 25.0
    protocol = [(600.0, 0.0), (d_fast, -fast), (1800.0, 0.0), (d_fast, fast), (3600.0, 0.0),
                (d_slow, -slow), (3600.0, 0.0), (d_slow, slow), (600.0, 0.0)]  # fmt: skip
    return simulate_logged(protocol, dt_load=60.0, dt_rest=60.0, grid=1.0, soc0=0.975,
                           capacity_ah=capacity, noise_v=1e-3, edge_rows=edge_rows)  # fmt: skip
