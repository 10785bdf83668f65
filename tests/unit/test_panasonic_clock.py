"""Which clock the Panasonic import trusts when ``TimeStamp`` and ``Time`` disagree
(docs/real-data.md, "Which clock the import trusts"; issue 41, part 4).

The records here are synthetic HPPC tests written in the source's ``.mat`` layout: a pulse file
and its SOC-step file, each with its own ``Time``, logged as the tester logs them (the wall
clock truncated to the second and drifting 8 s a day against ``Time``, the ``Ah`` counter
running on across both files), and a wall clock that jumps mid-test. They need no data root.
"""

import copy
import hashlib
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import scipy.io

from avoa_pipeline import records
from avoa_pipeline.errors import DataError
from avoa_pipeline.importers import panasonic

START = pd.Timestamp("2017-06-15 10:00:00")  # no row at midnight (those carry a date alone)
DRIFT = 8.0 / 86400  # the wall clock's rate against Time, as measured on the real files
JUMP_S = 3 * 3600.0  # the wall clock set three hours ahead mid-test
LEVELS = 4  # SOC levels of the synthetic HPPC test
PULSE_SEG_S = 900  # one pulse set and its rests, logged by the pulse file every second
STEP_SEG_S = 1500  # a 1200-s 0.87 A SOC step and a 300-s rest, logged by the step file each 60 s
PULSES = ((50, -1.45), (350, -2.9), (650, -5.8))  # (start in the pulse set, current A), 10 s each
R_OHM, CAPACITY_AH = 0.05, 2.9


def _current(tau: np.ndarray) -> np.ndarray:
    """The cell's current (source sign: discharge negative) at true test time ``tau`` (s)."""
    period = PULSE_SEG_S + STEP_SEG_S
    k, s = np.divmod(tau, period)
    cur = np.zeros_like(tau, dtype=float)
    for start, amps in PULSES:
        cur[(s >= start) & (s < start + 10)] = amps
    cur[(s >= PULSE_SEG_S) & (s < PULSE_SEG_S + 1200) & (k < LEVELS)] = -0.87
    return cur


def _ah(tau: np.ndarray) -> np.ndarray:
    """The tester's running Ah count (negative = discharged): the exact integral of the current,
    piecewise constant on whole seconds."""
    fine = np.arange(0.0, np.max(tau) + 2.0)
    charge = np.r_[0.0, np.cumsum(_current(fine))] / 3600.0
    return np.interp(tau, np.r_[fine, fine[-1] + 1.0], charge)


def _file(tau, jump_at, jump_s, time0):
    """One source file's ``meas`` fields for rows at true times ``tau``."""
    tau = np.asarray(tau, dtype=float)
    cur, ah = _current(tau), _ah(tau)
    wall = tau * (1.0 + DRIFT) + np.where(tau >= jump_at, jump_s, 0.0)
    stamps = (START + pd.to_timedelta(np.floor(wall), unit="s")).strftime("%m/%d/%Y %I:%M:%S %p")
    volt = 4.1 + 0.5 * ah / CAPACITY_AH + R_OHM * cur  # discharge lowers the voltage
    return {"TimeStamp": np.array(list(stamps), dtype=object), "Time": tau - time0,
            "Current": cur, "Voltage": volt, "Ah": ah,
            "Battery_Temp_degC": np.full(tau.size, -20.0)}  # fmt: skip


def _test_files(jump_at, jump_s=JUMP_S, tail_s=0.0):
    """The pulse file (every second in each pulse set) and the step file (every 60 s in each
    step and its rest; ``tail_s`` more of rest after the test, as the real step files run on)."""
    period = PULSE_SEG_S + STEP_SEG_S
    pulse = np.concatenate([k * period + np.arange(PULSE_SEG_S) for k in range(LEVELS)])
    pulse = np.r_[pulse, LEVELS * period + np.arange(PULSE_SEG_S)]  # the last pulse set
    step = np.concatenate([k * period + PULSE_SEG_S + np.arange(0, STEP_SEG_S, 60)
                           for k in range(LEVELS)])  # fmt: skip
    if tail_s:
        end = LEVELS * period + PULSE_SEG_S
        step = np.r_[step, end + 1200 + np.arange(0, tail_s, 60)]
    # the tester logs near, not on, whole seconds of its clock, so the stamps' truncation falls
    # at every phase of the second (on whole seconds it would be one systematic offset)
    rng = np.random.default_rng(41)
    pulse, step = (x + rng.uniform(0.0, 0.9, x.size) for x in (pulse, step))
    return _file(pulse, jump_at, jump_s, 0.0), _file(step, jump_at, jump_s, PULSE_SEG_S)


def _write(tmp_path, pulse, step):
    root = tmp_path / "root"
    root.mkdir(parents=True)
    sources = {}
    for name, meas in (("pulse.mat", pulse), ("steps.mat", step)):
        scipy.io.savemat(root / name, {"meas": meas})
        sources[name] = hashlib.sha256((root / name).read_bytes()).hexdigest()
    return {"root": str(root), "sources": sources,
            "panasonic": {"cell": "synthetic", "nominal_capacity_ah": CAPACITY_AH,
                          "citation": "none (synthetic)", "licence": "none"}}  # fmt: skip


def _import(real, tmp_path):
    out = tmp_path / "out" / "hppc.csv"
    return panasonic.import_record(real, ["pulse.mat", "steps.mat"], "hppc", -20.0, out), out


# the jump while the cell rests between the second level's pulses (true time, s from the start)
JUMP_AT = 2 * (PULSE_SEG_S + STEP_SEG_S) + 500.0


def test_a_wall_clock_jump_splits_the_file_and_each_piece_goes_where_its_stamps_say(tmp_path):
    pulse, step = _test_files(JUMP_AT)
    for meas, time0 in ((pulse, 0.0), (step, float(PULSE_SEG_S))):
        df = pd.DataFrame(meas)
        clock = panasonic.wall_clock(df, "f.mat")
        assert len(clock.pieces) == 2  # one jump, two pieces, both placed
        assert all(p.placed for p in clock.pieces)
        time = df["Time"].to_numpy()
        tau = time + time0
        truth = (START - pd.Timestamp("2017-01-01")).total_seconds() + tau * (1 + DRIFT)
        truth += np.where(tau >= JUMP_AT, JUMP_S, 0.0)
        # each row where the wall clock was when it was logged: the stamps' line averages their
        # 1-s truncation (±0.5 s each) out
        assert np.max(np.abs(clock.wall - truth)) < 0.25
        for p in clock.pieces:
            # within a piece Time orders and spaces the rows, stretched by the drift alone
            ratio = np.diff(clock.wall[p.start : p.stop]) / np.diff(time[p.start : p.stop])
            assert np.all(np.abs(ratio - 1.0) < panasonic.MAX_CLOCK_DRIFT)
        (jump,) = clock.jumps()
        assert jump["jump_s"] == pytest.approx(JUMP_S, abs=1.0)

    side, out = _import(_write(tmp_path, pulse, step), tmp_path)
    frame = records.read(out).frame
    assert set(side["clock_jumps"]) == {"pulse.mat", "steps.mat"}
    assert side["later_test_rows_dropped"] == 0
    # the record's time is the wall clock's: the pulses after the jump sit three hours later
    cur = frame["current_a"].to_numpy()
    period = PULSE_SEG_S + STEP_SEG_S
    for k in range(LEVELS + 1):
        for start, amps in PULSES:
            tau = k * period + start + 5.0  # mid-pulse, true time
            at = tau * (1 + DRIFT) + (JUMP_S if tau >= JUMP_AT else 0.0)
            assert cur[int(at)] == pytest.approx(-amps, abs=0.02), (k, start)
    # the SOC steps between them too, and all the charge: the Ah counter's, to rounding
    assert np.sum(np.abs(cur - 0.87) < 0.01) > LEVELS * 1150
    assert side["discharged_ah"] == pytest.approx(side["discharged_ah_tester_counter"], rel=1e-3)
    assert len(frame) == pytest.approx((LEVELS * period + PULSE_SEG_S) * (1 + DRIFT) + JUMP_S,
                                       abs=3)  # fmt: skip


def test_one_line_through_a_jump_would_misplace_the_rows():
    """What the rule replaces: one line through both pieces misses the stamps by hours, which
    is why the import refused such files before, and why it now splits them."""
    pulse, _ = _test_files(JUMP_AT)
    df = pd.DataFrame(pulse)
    sec = (pd.to_datetime(df["TimeStamp"], format=panasonic._TS_FORMAT)
           - pd.Timestamp("2017-01-01")).dt.total_seconds().to_numpy() + 0.5  # fmt: skip
    t = df["Time"].to_numpy()
    b, a = np.polyfit(t - t[0], sec, 1)
    assert np.max(np.abs(a + b * (t - t[0]) - sec)) > 1000.0
    assert np.max(np.abs(panasonic.wall_clock(df, "f.mat").wall - sec)) < 1.0  # resolution


def test_a_file_without_a_jump_is_one_piece_on_one_line():
    pulse, _ = _test_files(jump_at=np.inf)
    df = pd.DataFrame(pulse)
    clock = panasonic.wall_clock(df, "f.mat")
    assert len(clock.pieces) == 1
    assert clock.jumps() == []
    assert clock.pieces[0].rate == pytest.approx(1 + DRIFT, abs=1e-5)


# --- what stays refused: one line naming file and field, nothing written --------------------


def _refused(real, tmp_path, pattern):
    with pytest.raises(DataError, match=pattern) as info:
        _import(real, tmp_path)
    assert "\n" not in str(info.value)
    assert not (tmp_path / "out").exists() or list((tmp_path / "out").iterdir()) == []


def test_time_going_backwards_is_still_refused(tmp_path):
    pulse, step = _test_files(JUMP_AT)
    step["Time"][30] = step["Time"][28]  # after the jump, in the step file's second piece
    _refused(_write(tmp_path, pulse, step), tmp_path,
             r"steps\.mat: field 'meas\.Time' row 31: time goes backwards")  # fmt: skip


def test_a_clock_set_back_onto_logged_samples_is_refused(tmp_path):
    # set back an hour: the rows after it land on the wall-clock hour already logged
    pulse, step = _test_files(JUMP_AT, jump_s=-3600.0)
    _refused(_write(tmp_path, pulse, step), tmp_path,
             r"pulse\.mat: blocks of the merged files overlap by \d+\.\d s "
             r"\(field 'meas\.TimeStamp'\)")  # fmt: skip


def _stamps_racing(step, rows):
    """``rows`` of the step file whose stamps run seven times as fast as ``Time`` (as in the
    -20 degC step file on 19 June): the clocks disagree on rate, not on a moment."""
    sec = pd.to_datetime(step["TimeStamp"], format=panasonic._TS_FORMAT)
    t = step["Time"]
    extra = np.zeros(t.size)
    extra[rows] = 6.0 * (t[rows] - t[rows[0] - 1])
    extra[rows[-1] + 1 :] = extra[rows[-1]]
    moved = sec + pd.to_timedelta(np.round(extra), unit="s")
    step["TimeStamp"] = np.array(list(moved.strftime("%m/%d/%Y %I:%M:%S %p")), dtype=object)


def test_a_piece_whose_clocks_disagree_on_rate_is_refused_inside_the_test(tmp_path):
    pulse, step = _test_files(jump_at=np.inf)
    _stamps_racing(step, np.arange(30, 36))  # in the third SOC step
    _refused(_write(tmp_path, pulse, step), tmp_path,
             r"steps\.mat: field 'meas\.TimeStamp': the piece from \S+ \S+ [AP]M between clock "
             r"jumps cannot be placed \(")  # fmt: skip


def test_unplaceable_pieces_after_the_test_are_left_out_with_the_next_test(tmp_path):
    pulse, step = _test_files(jump_at=np.inf, tail_s=3600.0)
    tail = np.flatnonzero(step["Time"] > step["Time"][-1] - 1800.0)[:6]
    _stamps_racing(step, tail)
    side, out = _import(_write(tmp_path, pulse, step), tmp_path)
    assert side["later_test_rows_dropped"] == 60  # the whole tail: an hour of 60-s rows
    assert not all(j["placed"] for j in side["clock_jumps"]["steps.mat"])
    # and the test itself is as without the tail (but for the step file's line, fitted through
    # the tail's first rows too: block edges move by milliseconds)
    pulse2, step2 = _test_files(jump_at=np.inf)
    side2, out2 = _import(_write(tmp_path / "b", pulse2, step2), tmp_path / "b")
    with_tail, without = records.read(out).frame, records.read(out2).frame
    assert len(with_tail) == len(without)
    assert np.max(np.abs(with_tail["current_a"] - without["current_a"])) < 0.05  # 0.87 A, ≤ 60 ms
    assert side["discharged_ah"] == pytest.approx(side2["discharged_ah"], rel=1e-5)


@pytest.mark.parametrize(("stamp_step_s", "placed"), [(35.0, False), (5.0, True)])
def test_a_piece_between_jumps_is_placed_only_if_its_clocks_agree_on_rate(stamp_step_s, placed):
    """Six rows 5 s apart in ``Time`` between two jumps of an hour, as on 19 June in the -20 degC
    step file: a line fits their stamps, but if the stamps advance 35 s a row the two clocks
    disagree on how fast time passes, and the piece is not placed; at 5 s a row it is."""
    rng = np.random.default_rng(7)
    before, mid, after = np.arange(100.0), 200.0 + 5.0 * np.arange(6), 300.0 + np.arange(100.0)
    t = np.r_[before, mid, after] + rng.uniform(0.0, 0.9, 206)
    wall = np.r_[t[:100], 3600.0 + t[100] + (t[100:106] - t[100]) * stamp_step_s / 5.0,
                 7200.0 + t[106:]]  # fmt: skip
    stamps = (START + pd.to_timedelta(np.floor(wall), unit="s")).strftime("%m/%d/%Y %I:%M:%S %p")
    df = pd.DataFrame({"TimeStamp": list(stamps), "Time": t})
    clock = panasonic.wall_clock(df, "steps.mat")
    assert [(p.start, p.stop) for p in clock.pieces] == [(0, 100), (100, 106), (106, 206)]
    assert [p.placed for p in clock.pieces] == [True, placed, True]
    if not placed:
        assert clock.pieces[1].rate == pytest.approx(7.0, rel=0.02)
        assert clock.refusal(clock.pieces[1]) == (
            "steps.mat: field 'meas.TimeStamp': the piece from 06/15/2017 11:03:20 AM between "
            f"clock jumps cannot be placed (its stamps run {clock.pieces[1].rate:.4g} times as "
            "fast as 'Time')"
        )


# --- the real -20 degC HPPC test (read in place from the configured data root) ---------------


def test_the_real_minus_20_hppc_imports_its_step_file_split_at_its_jumps(cfg, tmp_path):
    real = copy.deepcopy(cfg["real"])
    root = Path(real["root"])
    real["root"] = str(root if root.is_absolute() else (Path(__file__).parents[2] / root).resolve())
    spec = real["panasonic"]["temperatures"]["-20degC"]  # its files' sha256 in real.sources
    pulse_key, steps_key = spec["hppc"], spec["hppc_steps"]
    if not Path(real["root"], pulse_key).is_file():
        pytest.skip(f"Panasonic -20 degC data not found under {real['root']}")
    out = tmp_path / "hppc.csv"
    side = panasonic.import_record(real, [pulse_key, steps_key], "hppc", -20.0, out)
    checked = records.read(out, capacity_ah=side["nominal_capacity_ah"])
    assert checked.sign.verdict == "discharge-positive"
    assert checked.warnings == ()
    jumps = side["clock_jumps"][steps_key]
    assert pulse_key not in side["clock_jumps"]  # the pulse file's clock never jumped
    # the first jump: 26.7 h ahead, ten hours after the pulse file's last row (6/16 3:41 AM)
    assert jumps[0]["from"] == "6/17/2017 7:30:39 PM"
    assert jumps[0]["jump_s"] == pytest.approx(26.7 * 3600, abs=60)
    # every row from it on is the next test's, left out with the rows before it that follow
    # the recharge; none is refused, placed or not
    rows_after = sum(j["rows"] for j in jumps)
    assert side["later_test_rows_dropped"] > rows_after
    # and the record is an HPPC test: 0.87 A SOC steps between pulse sets, down to 2.5 V
    cur = checked.frame["current_a"].to_numpy()
    assert np.sum(np.abs(cur - 0.87) < 0.03) > 5000  # seconds of 0.87 A SOC steps
    assert np.max(cur) > 5.5  # 2C pulses (4C ones are cut by 2.5 V within a second at -20)
    assert abs(side["discharged_ah"] - side["discharged_ah_tester_counter"]) < 0.01 * 2.5
    assert checked.frame["voltage_v"].iloc[-1] < 2.6
