"""Units a record cannot tell alone, and what a known capacity tells (records.check_scale).

Records logged as cyclers log them (GITT with coarse rests, from ``test_inputs``' fixtures): time in
minutes, current in mA of a small cell or in A of a large-format one, temperature in kelvin, a
logging gap under load, a repeated column.
"""

from __future__ import annotations

import numpy as np
import pytest
from test_inputs import _gitt, _good

from avoa_pipeline import records
from avoa_pipeline.cli import main
from avoa_pipeline.errors import DataError


def test_minutes_are_refused_with_a_capacity_and_warned_without():
    gitt, _ = _gitt(5)  # a 2 Ah cell, 1-h rests logged every 60 s, 10-s pulse logging
    assert records.check_scale(gitt, "gitt", 2.0) == ()
    minutes = gitt.assign(time_s=gitt["time_s"] / 60.0)
    with pytest.raises(DataError, match=r"V per unit SOC of 2 Ah .*is the time in minutes"):
        records.check_scale(minutes, "m", 2.0)
    # on a record logged every second the median step becomes 16.7 ms: a warning without capacity
    fast = _good().assign(time_s=lambda f: f["time_s"] / 60.0)
    (note,) = records.check_scale(fast, "fast")
    assert "taken as seconds; if the time is in minutes" in note


def test_large_format_currents_pass_with_their_capacity_and_mA_of_a_small_cell_do_not():
    good = _good()  # 2 A pulses
    large = good.assign(current_a=112.0 * good["current_a"])  # 224 A: 0.8 C of a 280 Ah cell
    (note,) = records.check_scale(large, "large")
    assert "taken as amperes" in note
    assert "give the capacity" in note
    assert records.check_scale(large, "large", 280.0) == ()
    small_ma = good.assign(current_a=25.0 * good["current_a"])  # 50 mA of a 0.1 Ah cell as "50"
    with pytest.raises(DataError, match=r"over 50 C for 0\.1 Ah; looks like mA"):
        records.check_scale(small_ma, "small", 0.1)


def test_kelvin_and_impossible_temperatures_are_refused():
    good = _good()
    assert records.check_scale(good.assign(temperature_c=25.0), "c") == ()
    with pytest.raises(DataError, match=r"column 'temperature_c': values 298.15\.\.298.15; looks "
                                        "like kelvin"):  # fmt: skip
        records.check_scale(good.assign(temperature_c=298.15), "k")
    with pytest.raises(DataError, match=r"outside -60\.\.150 °C"):
        records.check_scale(good.assign(temperature_c=-100.0), "x")


def test_a_logging_gap_under_load_is_refused_and_one_at_rest_is_not():
    good = _good()  # 300 s rest, 1200 s at 2 A, ...
    t = good["time_s"].to_numpy().copy()
    k = int(np.flatnonzero(good["current_a"].to_numpy() > 1.0)[10])
    gap = t.copy()
    gap[k + 1 :] += 7200.0
    with pytest.raises(DataError, match=rf"row {k + 2}: a 7201-s logging gap after a row at 2 A"):
        records.check_scale(good.assign(time_s=gap), "gap")
    rest = t.copy()
    rest[100:] += 7200.0  # inside the opening rest
    records.check_scale(good.assign(time_s=rest), "rest")


def test_two_columns_of_one_name_are_refused(tmp_path, capsys):
    path = tmp_path / "two.csv"
    frame = _good()
    frame.insert(2, "current_a.dup", frame["current_a"])
    frame.to_csv(path, index=False, header=[c.replace(".dup", "") for c in frame.columns])
    assert main(["diagnose", str(path), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1
    assert "two.csv: column 'current_a' appears 2 times" in err  # io.read_csv, before pandas


def test_fit_refuses_a_sidecar_that_no_longer_describes_its_csv(tmp_path, capsys):
    csv = tmp_path / "g.csv"
    assert main(["generate", "--scenario", "1", "--case", "2", "--out", str(csv)]) == 0
    args = ["fit", "--scenario", "1", "--case", "2", "--algorithm", "avoa", "--seed", "1",
            "--iterations", "2", "--data", str(csv), "--out", str(tmp_path / "f.json")]  # fmt: skip
    lines = csv.read_text().splitlines()
    csv.write_text("\n".join(lines[:-5]) + "\n")  # the CSV edited after the sidecar was written
    assert main(args) == 2
    assert "field 'csv_sha256': does not match" in capsys.readouterr().err
    side = tmp_path / "g.json"
    for bad, words in (("[1, 2]", "not a JSON object"), ("{oops", "not readable JSON")):
        side.write_text(bad)
        assert main(args) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1, err
        assert words in err
    side.unlink()
    side.mkdir()
    assert main(args) == 2
    assert "g.json: a folder" in capsys.readouterr().err
    side.rmdir()
    for unit, col, k, words in (("ms", "time_s", 1e3, "is the time in ms"),
                                ("mA", "current_a", 1e3, "looks like mA")):  # fmt: skip
        import pandas as pd

        frame = pd.read_csv(csv)
        frame[col] *= k
        frame.to_csv(csv, index=False)
        assert main(args) == 2, unit
        assert words in capsys.readouterr().err
        frame[col] /= k
        frame.to_csv(csv, index=False)
    assert not (tmp_path / "f.json").exists()


def test_a_slow_test_that_is_not_slow_says_why_it_may_not_be():
    from test_inputs import _pseudo_ocv

    from avoa_pipeline.model import ocv

    slow = _pseudo_ocv()  # C/25 of a 2 Ah cell, a fast cycle first
    with pytest.raises(DataError, match=r"no slow branch .* if the time is in minutes \(need s\), "
                                        r"it is C/24; if it covers part of the cell"):  # fmt: skip
        ocv.from_slow_test(slow.assign(time_s=slow["time_s"] / 60.0), "minutes")
    # the fast cycle, then a slow discharge stopped after a tenth of the cell (C/2.5 of its own)
    part = slow[slow["time_s"] < 19680.0 + 0.1 * 3600 * 2.0 / 0.08]
    with pytest.raises(DataError, match="if it covers part of the cell only"):
        ocv.from_slow_test(part, "part")


def test_parameters_at_their_bounds_are_flagged(tmp_path, capsys):
    import json

    from test_ecm import TRUTH, profile_frame, with_voltage

    from avoa_pipeline.model import ecm
    from avoa_pipeline.model.ecm import IDX
    from avoa_pipeline.model.fitted import FittedModel

    path = tmp_path / "rec.csv"
    with_voltage(profile_frame(), TRUTH, noise_v=1e-3, seed=3).to_csv(path, index=False)
    out = tmp_path / "out"
    assert main(["diagnose", str(path), "--out", str(out)]) == 0
    report = json.loads((out / "diagnosis.json").read_text())
    err = capsys.readouterr().err
    # every flag is a warning line naming model.json and the parameter
    for f in report["at_bounds"]:
        assert f"{f['parameter']} = " in err
    model = FittedModel.load(out / "model.json")
    flagged = {f["parameter"] for f in model.at_bounds()}
    assert flagged == {f["parameter"] for f in report["at_bounds"]}
    # model.json carries diagnosis.json's intervals: an entry for every parameter of the cell
    iv = json.loads((out / "model.json").read_text())["intervals"]
    assert iv == report["intervals"] == model.intervals
    assert set(iv["parameters"]) == {ecm.PARAMS[n].report for n in model.names}
    for rep, e in iv["parameters"].items():
        assert e["at_bound"] == (rep in flagged)
        assert (e["low95"] is None) == (e["at_bound"] or e["held"]), rep
    # the other flags are warning lines too; simulate says them of the model it runs, one each
    lines = [f for f in iv["flags"] if not f.endswith("at a bound of its fit")]
    assert all(f"{out / 'model.json'}: {f}" in err for f in lines)
    assert main(["simulate", str(out / "model.json"), str(path), "--out",
                 str(tmp_path / "sim.csv")]) == 0  # fmt: skip
    said = [line for line in capsys.readouterr().err.splitlines() if "model.json: " in line]
    assert len(said) == len(report["at_bounds"]) + len(lines)
    lo, hi = model.bounds["lq"]
    model.x[IDX["lq"]] = hi - 1e-6 * (hi - lo)  # pressed against the upper bound
    (cap,) = [f for f in model.at_bounds() if f["parameter"] == "capacity_ah"]
    assert cap["bound"] == "upper"
    model.x[IDX["lq"]] = 0.5 * (lo + hi)
    assert "capacity_ah" not in {f["parameter"] for f in model.at_bounds()}
