"""Record files (records.read, records.write): checksum gate, validation messages, atomic write,
round trip."""

import hashlib

import numpy as np
import pandas as pd
import pytest

from avoa_pipeline import records
from avoa_pipeline.errors import DataError


def _frame(n=5):
    return pd.DataFrame(
        {
            "time_s": np.arange(n, dtype=float),
            "current_a": np.linspace(-1.0, 2.0, n),
            "voltage_v": np.linspace(4.1, 3.9, n),
            "temperature_c": np.full(n, 25.0),
        }
    )


SIDECAR = {
    "cell": "test cell",
    "nominal_capacity_ah": 2.9,
    "ambient_temperature_c": 25.0,
    "test_type": "drive_cycle",
    "source_file": "ds/file.mat",
    "source_sha256": "0" * 64,
    "citation": "nobody",
    "licence": "unknown",
}


def test_check_source_accepts_matching_sha(tmp_path):
    f = tmp_path / "a.bin"
    f.write_bytes(b"abc")
    digest = hashlib.sha256(b"abc").hexdigest()
    assert records.check_source(f, digest.upper(), key="ds/a.bin") == f


def test_check_source_missing_file(tmp_path):
    with pytest.raises(DataError, match=r"a\.bin: missing \(config real\.sources\['ds/a\.bin'\]\)"):
        records.check_source(tmp_path / "a.bin", "0" * 64, key="ds/a.bin")


def test_check_source_changed_file(tmp_path):
    f = tmp_path / "a.bin"
    f.write_bytes(b"abd")
    with pytest.raises(DataError, match=r"a\.bin: sha256 [0-9a-f]{64} does not match config"):
        records.check_source(f, hashlib.sha256(b"abc").hexdigest())


def test_validate_orders_columns_and_drops_extras():
    df = _frame()[["voltage_v", "temperature_c", "time_s", "current_a"]]
    df["extra"] = 1
    out = records.validate(df, "src", first_row=0, required=records.COLUMNS)
    assert tuple(out.columns) == records.COLUMNS
    assert all(out[c].dtype == float for c in out.columns)


@pytest.mark.parametrize("col", records.COLUMNS)
def test_validate_missing_column(col):
    with pytest.raises(DataError, match=rf"^src: missing column '{col}'"):
        records.validate(_frame().drop(columns=col), "src", required=records.COLUMNS)


@pytest.mark.parametrize(
    ("col", "value", "what"),
    [
        ("voltage_v", np.nan, "missing value"),
        ("current_a", np.inf, "not finite"),
        ("temperature_c", "hot", "not a number"),
    ],
)
def test_validate_bad_value(col, value, what):
    df = _frame().astype(object)
    df.loc[3, col] = value
    with pytest.raises(DataError, match=rf"^src: column '{col}' row 3: {what}"):
        records.validate(df, "src", first_row=0, required=records.COLUMNS)


def test_validate_duplicate_and_backwards_time():
    df = _frame()
    df.loc[2, "time_s"] = 1.0
    with pytest.raises(DataError, match=r"^src: column 'time_s' row 2: duplicate time"):
        records.validate(df, "src", first_row=0, required=records.COLUMNS)
    df.loc[2, "time_s"] = 0.5
    with pytest.raises(DataError, match=r"^src: column 'time_s' row 2: time goes backwards"):
        records.validate(df, "src", first_row=0, required=records.COLUMNS)


def test_write_read_round_trip(tmp_path):
    out = tmp_path / "sub" / "rec.csv"
    records.write(_frame(), SIDECAR, out)
    rec = records.read(out)
    pd.testing.assert_frame_equal(rec.frame, _frame())
    assert rec.meta == SIDECAR
    assert (tmp_path / "sub" / "rec.json").is_file()
    assert sorted(p.name for p in (tmp_path / "sub").iterdir()) == ["rec.csv", "rec.json"]


@pytest.mark.parametrize(
    "broken",
    [
        lambda f, s: (f.drop(columns="voltage_v"), s),
        lambda f, s: (f.assign(voltage_v=np.r_[f.voltage_v[:-1], np.nan]), s),
        lambda f, s: (f.assign(time_s=f.time_s[::-1].to_numpy()), s),
        lambda f, s: (f, {k: v for k, v in s.items() if k != "licence"}),
        lambda f, s: (f, {**s, "nominal_capacity_ah": float("nan")}),
    ],
)
def test_write_leaves_nothing_on_error(tmp_path, broken):
    frame, side = broken(_frame(), dict(SIDECAR))
    with pytest.raises(DataError, match=r"^ds/file\.mat: "):
        records.write(frame, side, tmp_path / "rec.csv")
    assert list(tmp_path.iterdir()) == []


def test_read_reports_csv_line_and_missing_sidecar(tmp_path):
    out = tmp_path / "rec.csv"
    records.write(_frame(), SIDECAR, out)
    text = out.read_text().splitlines()
    fields = text[3].split(",")
    fields[2] = ""  # blank voltage on CSV line 4
    text[3] = ",".join(fields)
    out.write_text("\n".join(text) + "\n")
    with pytest.raises(DataError, match=r"rec\.csv: column 'voltage_v' row 4: missing value"):
        records.read(out)
    (tmp_path / "rec.json").unlink()
    records.write(_frame(), SIDECAR, tmp_path / "ok.csv")
    (tmp_path / "ok.json").unlink()
    with pytest.raises(DataError, match=r"ok\.json: no such file"):
        records.read(tmp_path / "ok.csv")


def _pulses(sign=1.0):
    """Ten 1-A pulses between rests, the voltage dropping 50 mV under each: a clear sign."""
    cur = np.tile(np.r_[np.zeros(10), np.ones(10)], 10)
    t = np.arange(cur.size, dtype=float)
    volt = 3.7 - 0.05 * cur - 1e-4 * np.cumsum(cur)
    return pd.DataFrame({"time_s": t, "current_a": sign * cur, "voltage_v": volt,
                         "temperature_c": 25.0})  # fmt: skip


def test_every_read_checks_the_sign_and_the_sidecar_its_reader_needs(tmp_path):
    out = tmp_path / "rec.csv"
    records.write(_pulses(), SIDECAR, out)
    assert records.read(out).sign.verdict == "discharge-positive"
    records.write(_pulses(-1.0), SIDECAR, out)  # written as given (a writer's own sign check)
    with pytest.raises(DataError, match=r"rec\.csv: column 'current_a': sign contradicts"):
        records.read(out)
    flipped = records.read(out, current_sign="charge-positive")
    assert flipped.sign.verdict == "discharge-positive"
    unjudged = records.read(out, judge_sign=False)
    assert unjudged.sign.contradicts
    # a sidecar left unread (keys=None), optional (keys=()), or required with its keys
    (tmp_path / "rec.json").write_text("[1]")
    assert records.read(out, keys=None, current_sign="charge-positive").meta == {}
    with pytest.raises(DataError, match=r"rec\.json: not a JSON object"):
        records.read(out, keys=(), current_sign="charge-positive")
    with pytest.raises(DataError, match=r"rec\.json: sidecar is not a mapping"):
        records.read(out, current_sign="charge-positive")


def test_a_digest_written_is_checked_when_read(tmp_path):
    out = tmp_path / "rec.csv"
    records.write(_pulses(), {"name": "x"}, out, keys=(), digest="csv_sha256")
    assert (
        records.read(out, keys=()).meta["csv_sha256"]
        == hashlib.sha256(out.read_bytes()).hexdigest()
    )
    out.write_text("\n".join(out.read_text().splitlines()[:-3]) + "\n")
    with pytest.raises(DataError, match=r"rec\.json: field 'csv_sha256': does not match"):
        records.read(out, keys=())


def test_the_paper_problem_reads_its_data_through_the_records_layer(cfg, tmp_path):
    from avoa_pipeline import problem, synthetic

    data = tmp_path / "g.csv"
    synthetic.write(synthetic.generate(cfg, 1, 2), data)
    assert problem.build(cfg, 1, 2, data=data).notes == ()
    frame = pd.read_csv(data)
    records.write(frame.assign(current_a=-frame["current_a"]), {}, data, keys=())
    with pytest.raises(DataError, match=r"g\.csv: column 'current_a': sign contradicts"):
        problem.build(cfg, 1, 2, data=data)
