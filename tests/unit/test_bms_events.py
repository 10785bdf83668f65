"""``--bms-events`` and ``--reference-full`` (issue 40 parts 3-4, docs/soc-filter.md part 5), on
development records with CC-CV charges in them.

The records come from a cycler emulated on the development cell of ``test_soc_filter.py`` (a
model with the diffusion lag and the hysteresis the filter's model lacks): constant-current steps
that stop at a voltage limit, constant-voltage steps that hold the top until the current falls
to a cut-off, rests and a drive-like stretch; the cell stepped by the filter's own state-space
form (``estimate.Model``, which reproduces ``FittedModel.simulate`` to 1e-9 V), its true SOC
kept. They are logged as cyclers log: the current channel a sample late, rests and CV phases
every 60 s, loads every second, 1 mV of noise.
"""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest
from test_estimate import BASE, files, fitted, run_cli
from test_soc_filter import CELL, FILTER, LOGGER_MV, expected_error_of, measured

from avoa_pipeline import estimate as E
from avoa_pipeline.gap.temperature_cells import cycler_log

C = BASE["capacity_ah"]
V_TOP = 4.232  # the charger's set point: the cell's voltage at full on charge (OCV(1) + h)
V_CUT = 3.40  # the lower cut-off
I_CUT = C / 20  # the CV phase's cut-off current
SLOW_LOG_S = 60  # rests and CV phases logged every 60 s


def emulate(cell, steps, soc0: float):
    """A cycler's run of ``steps`` on ``cell`` at 1 Hz: ("cc", A, stop V or None, s),
    ("cv", V, stop |A|, s), ("rest", s); per sample time, current, voltage, true SOC and
    whether it is logged every SLOW_LOG_S (rest, CV)."""
    m = E.filter_model(cell)
    m = m.rows(m.P[:1])
    rec = cell.record(pd.DataFrame({"time_s": [0.0, 1.0], "current_a": [0.0, 0.0],
                                    "voltage_v": [3.7, 3.7]}))  # fmt: skip
    dinv, rtf = float(rec.dinv_t[0]), float(rec.two_rt_f[0])
    X = np.zeros((1, m.layout.n))
    X[0, 0] = soc0
    rows = []
    for kind, value, stop, seconds in steps:
        i = 0.0 if kind == "rest" else value
        first = len(rows)
        for _ in range(int(seconds)):
            if kind == "cv":  # the current that holds the voltage at the set point (secant)
                v0 = m.measurement(X, 0.0, dinv, rtf)[0]
                v1 = m.measurement(X, i, dinv, rtf)[0]
                i = i * (value - v0) / (v1 - v0)
            v = m.measurement(X, i, dinv, rtf)[0]
            rows.append((i, v, X[0, 0], kind != "cc"))
            X = m.transition(X, i, 1.0, dinv, rtf)
            if kind == "cc" and stop is not None and (v >= stop if i < 0 else v <= stop):
                break
            if kind == "cv" and abs(i) <= stop:
                break
        for k in (first, first + 1, len(rows) - 1):  # a step's edges are logged
            if k < len(rows):
                rows[k] = (*rows[k][:3], False)
    i, v, soc, slow = (np.array(c) for c in zip(*rows, strict=True))
    return np.arange(i.size, dtype=float), i, v, soc, slow


def logged(t, i, v, soc, slow, seed: int):
    """As a cycler logs (``temperature_cells.cycler_log``): the current a sample late, slow
    phases every SLOW_LOG_S, 1 mV noise."""
    noise = np.random.default_rng(seed).normal(0.0, 1e-3 * LOGGER_MV, t.size)
    frame = pd.DataFrame({"time_s": t, "current_a": i, "voltage_v": v + noise, "soc": soc})
    out = cycler_log(frame, SLOW_LOG_S, slow=slow)
    return out.drop(columns="soc"), out["soc"].to_numpy()


def drive(seed: int, seconds: int) -> list:
    """Drive-like steps: a new current every 10-60 s around C/3, with charge pulses and rests."""
    rng = np.random.default_rng(seed)
    out, total = [], 0
    while total < seconds:
        level = rng.choice(
            [0.0, -0.5 * C, 0.2 * C, 0.5 * C, 1.0 * C], p=[0.2, 0.15, 0.3, 0.2, 0.15]
        )
        n = int(rng.integers(10, 61))
        out.append(("cc", float(level), V_CUT, n))
        total += n
    return out


def cc_cv(rate: float = 1.0) -> list:
    return [("cc", -rate * C, V_TOP, 7200), ("cv", V_TOP, I_CUT, 7200), ("rest", 0, None, 600)]


def development_record(seed: int = 21):
    """From SOC 0.5: a drive, a CC-CV charge, a drive, a 1C discharge to the cut-off, a rest, a
    short 4C spike to the cut-off, a CC-only charge to the top (no CV), a drive."""
    steps = [("rest", 0, None, 300), *drive(seed, 1500), ("rest", 0, None, 300), *cc_cv(),
             *drive(seed + 1, 2400), ("cc", C, V_CUT, 7200), ("rest", 0, None, 900),
             ("cc", 3 * C, V_CUT, 10), ("rest", 0, None, 600), ("cc", -0.5 * C, V_TOP, 9000),
             ("rest", 0, None, 600), *drive(seed + 2, 1200)]  # fmt: skip
    return logged(*emulate(fitted("table", CELL), steps, 0.5), seed + 1000)


STARTS = (0.0, 0.2, -0.2)


@pytest.fixture(scope="module")
def record():
    return development_record()


@pytest.fixture(scope="module")
def model():
    """The filter's model (it lacks the lag and the hysteresis), its expected_error measured on
    test_soc_filter's held-out development record."""
    m = fitted("table", FILTER, residual_mv=LOGGER_MV)
    held, _ = measured(11, 7200)
    m.expected_error = expected_error_of(m, held)
    return m


def columns(frame):
    return (frame[c].to_numpy() for c in ("time_s", "current_a", "voltage_v"))


# ----------------------------------------------------------------------------------------------
# detection: where the events fire and where they do not


def test_the_cc_cv_end_fires_at_the_end_of_the_cv_phase_and_nowhere_else(record):
    frame, soc = record
    t, i, v = columns(frame)
    ends = E.cc_cv_ends(t, i, v, C)
    assert len(ends) == 1  # the CC-only charge to the same top later in the record is not one
    (end,) = ends
    k = end["sample"]
    assert v[k] >= V_TOP - E.TOP_TOL_V  # at the top ...
    assert i[k] < 0  # ... charging
    assert i[k + 1] == 0 or i[k + 2] == 0  # the charge stops there (the current a sample late)
    # the cut-off current read from the tail, within one 60-s log step of the taper's C/20
    assert I_CUT <= end["cutoff_current_a"] <= 1.5 * I_CUT
    assert soc[k] > 1.0 - 2 * end["sd"]  # the truth lies within the event's stated band
    assert E.FULL_SD_MIN <= end["sd"] < 0.05


def test_a_cc_charge_that_stops_at_the_top_is_not_a_cc_cv_end():
    steps = [("rest", 0, None, 120), ("cc", -C, V_TOP, 7200), ("rest", 0, None, 600)]
    frame, _ = logged(*emulate(fitted("table", CELL), steps, 0.3), 5)
    t, i, v = columns(frame)
    assert v.max() >= V_TOP  # it reached the top ...
    assert E.cc_cv_ends(t, i, v, C) == []  # ... with no taper
    rec = fitted("table", FILTER).record(frame)
    with pytest.raises(E.UserError, match=r"no end of a CC-CV charge"):
        E.full_reference(rec, E.filter_model(fitted("table", FILTER)))


def test_the_lower_cutoff_bounds_after_a_sustained_discharge_and_a_spike_does_not(record):
    frame, soc = record
    t, i, v = columns(frame)
    cuts = E.lower_cutoffs(t, i, v)
    assert [c["used"] for c in cuts] == [True, False]
    sustained, spike = cuts
    assert sustained["load_s"] > 1000
    assert spike["load_s"] < E.CUTOFF_MIN_LOAD_S
    assert abs(sustained["cutoff_v"] - V_CUT) < E.TOP_TOL_V
    assert spike["cutoff_v"] < V_CUT  # the spike dips below the cut-off within its first sample
    m = E.filter_model(fitted("table", FILTER))
    k = sustained["sample"]
    inp = E.Inputs.of(fitted("table", FILTER).record(frame))
    bound, sd = E.rest_soc(m, sustained["cutoff_v"], inp.dinv[k], inp.rtf[k])
    assert soc[k] >= bound - 2 * sd  # the bound holds for the cell (its OCV lies above)
    assert sd >= E.FULL_SD_MIN


def test_the_pseudo_measurement_is_a_scalar_kalman_update_and_a_bound_only_when_violated():
    class Ukf:
        x = np.array([0.30, 0.0])
        P = np.array([[0.01, 0.002], [0.002, 0.04]])

    f = Ukf()
    assert not E._pseudo_update(f, 0.2, 1e-4, True)  # above the bound: nothing
    assert f.x[0] == 0.30
    assert E._pseudo_update(f, 0.4, 0.01, True)  # below it: an update halfway (equal variances)
    assert f.x[0] == pytest.approx(0.35)
    assert f.x[1] == pytest.approx(0.01)  # the correlated state moves by P10/(P00 + R)
    assert f.P[0, 0] == pytest.approx(0.005)
    assert E._pseudo_update(f, 1.0, 1e-4, False)
    assert f.x[0] > 0.98


def test_the_full_reference_counts_from_one_at_each_cc_cv_end(record, model):
    frame, soc = record
    rec = model.record(frame)
    ref, ends = E.full_reference(rec, E.filter_model(model))
    k = ends[0]["sample"]
    assert ref[k] == 1.0
    # coulomb counting with the model's capacity (the cell's) follows the truth's changes
    assert np.max(np.abs((ref - 1.0) - (soc - soc[k]))) < 0.01


# ----------------------------------------------------------------------------------------------
# the filter with and without the events


@pytest.mark.slow
@pytest.mark.parametrize("start", STARTS, ids=["true", "+20%", "-20%"])
def test_the_events_fire_in_the_filter_and_the_full_charge_moves_the_soc(record, model, start):
    """With --bms-events the CC-CV end updates the SOC towards 1 and narrows it (the test that
    fails if the full-charge event is ignored); the spike's cut-off is not used; with or without
    the events the band covers the truth ≥ 90 % after 5 min and the RMSE differs by < 0.5 %."""
    frame, soc = record
    t = frame["time_s"].to_numpy()
    runs = {ev: E.estimate_record(model, frame, 0.5 + start, bms_events=ev) for ev in (0, 1)}
    ev = runs[1].summary["bms_events"]
    assert "bms_events" not in runs[0].summary
    assert [e["applied"] for e in ev["cc_cv_end"]] == [True]
    assert [(e["used"], e["applied"]) for e in ev["lower_cutoff"]][1] == (False, False)
    k = ev["cc_cv_end"][0]["sample"]
    off, on = runs[0].frame, runs[1].frame
    assert abs(on["soc"][k] - 1.0) < abs(off["soc"][k] - 1.0)
    assert on["soc_sd"][k] < off["soc_sd"][k]
    assert np.array_equal(on["soc"][:k], off["soc"][:k])  # nothing before the first event
    scores = {e: E.score(t, r.frame["soc"].to_numpy(), r.frame["soc_sd"].to_numpy(), soc)
              for e, r in runs.items()}  # fmt: skip
    for s in scores.values():
        assert s["coverage_2sd"] >= 0.9
    assert abs(scores[1]["rmse_after_window"] - scores[0]["rmse_after_window"]) < 0.005


# ----------------------------------------------------------------------------------------------
# the command


def test_the_command_writes_the_events_and_the_full_reference(tmp_path, capsys):
    steps = [("rest", 0, None, 300), ("cc", C, V_CUT, 1800), ("rest", 0, None, 600), *cc_cv(),
             ("cc", C, V_CUT, 900), ("rest", 0, None, 600)]  # fmt: skip
    frame, _ = logged(*emulate(fitted("table", CELL), steps, 0.8), 7)
    m, _ = files(tmp_path)
    rec = tmp_path / "rec.csv"
    frame.to_csv(rec, index=False)
    out = tmp_path / "soc.csv"
    code, text, err = run_cli(["estimate", m, str(rec), "--out", str(out), "--bms-events",
                               "--reference-full"], capsys)  # fmt: skip
    assert code == 0, err
    summary = json.loads(out.with_suffix(".json").read_text())
    (end,) = summary["bms_events"]["cc_cv_end"]
    assert end["applied"]
    assert summary["reference"]["kind"] == "full"
    assert summary["reference"]["cc_cv_end_s"] == [end["time_s"]]
    assert set(summary["filter"]) >= {"rmse_after_window", "max_error_after_window",
                                      "error_at_end", "coverage_2sd"}  # fmt: skip
    written = pd.read_csv(out)
    assert written["soc_reference"].iloc[end["sample"]] == 1.0
    assert "±2σ coverage" in text
    code, _, err = run_cli(["estimate", m, str(rec), "--out", str(tmp_path / "b.csv"),
                            "--reference-full", "--reference-soc0", "0.5"], capsys)  # fmt: skip
    assert code != 0
    assert "--reference-soc0 and --reference-full are two references: give one" in err


def test_a_record_without_a_cc_cv_end_is_refused_a_full_reference(tmp_path, capsys):
    m, rec = files(tmp_path)
    code, _, err = run_cli(["estimate", m, rec, "--out", str(tmp_path / "s.csv"),
                            "--reference-full"], capsys)  # fmt: skip
    assert code != 0
    assert "no end of a CC-CV charge" in err
    assert not (tmp_path / "s.json").exists()
