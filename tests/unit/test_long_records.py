"""Long records (issue 25): the simulator's shortcuts for thinned output give the voltage its
full pass gives, the diagnosis says what it fitted, and a long diagnosis talks on stderr only."""

import json

import numpy as np
import pandas as pd
import pytest
from test_ecm import ACTIVE, TRUTH, profile_frame, with_voltage

from avoa_pipeline.cli import main
from avoa_pipeline.gap import diagnose
from avoa_pipeline.model import ecm, fitting

MERGED_ATOL_V = 1e-12
"""A merged rest decays its states by exp(−Σ Δt/τ) where the full pass multiplies the samples'
factors one by one: each product rounds, so a state of at most a volt drifts by about one unit
in the last place (1e-16) per sample stepped; 1e-12 V allows rests of 10⁴ samples."""


def _held_record(n=30000, hz=10.0, temperature="constant", seed=0, rest=True) -> ecm.Record:
    """Currents held 1-30 s (as a cycler's steps), 10 Hz; a quarter of them rests (zero
    current), or none (``rest=False``: a small current instead)."""
    rng = np.random.default_rng(seed)
    levels = [0.0 if rest else 0.1, 0.5, -1, 2.0]
    cur = np.concatenate([np.full(int(rng.uniform(1, 30) * hz), rng.choice(levels))
                          for _ in range(n // 50)])[:n]  # fmt: skip
    t = np.arange(cur.size) / hz
    frame = pd.DataFrame({"time_s": t, "current_a": cur, "voltage_v": 3.7})
    if temperature == "constant":
        frame["temperature_c"] = 25.0
    elif temperature == "steps":  # held for minutes at a time: a thermal model's holds too
        frame["temperature_c"] = 25.0 + np.floor(t / 600.0) % 3
    return ecm.Record.from_frame(frame, tref_k=298.15)


def _rows(effects, m=7):
    params = dict(TRUTH, capacity_ah=30.0, soc0=0.7)
    for e in effects:
        params.update(ACTIVE[e])
    X = np.repeat(ecm.vector(params)[None, :], m, axis=0)
    X[:, ecm.IDX["r0"]] *= np.linspace(1.0, 1.2, m)  # rows differ, as a Jacobian's do
    return X


@pytest.mark.parametrize("effects", [(), ("hysteresis",), ("second_rc", "diffusion"),
                                     ("thermal", "coulombic_efficiency", "current_offset"),
                                     ("soc_resistance",), ("r1_soc", "r0_charge"),
                                     ("thermal", "thermal_tau", "hysteresis"),
                                     ("capacity_temperature", "entropic",
                                      "hysteresis")])  # fmt: skip
@pytest.mark.parametrize("temperature", ["constant", "steps"])
@pytest.mark.parametrize("rest", [False, True])
def test_thinned_output_is_the_full_pass_at_those_samples(effects, temperature, rest):
    """A fit asks for every s-th sample; the simulator then steps only the state between them
    (held currents in tight loops). Those voltages must be the full pass's, bit for bit, where
    no rest is merged (a record without rests), and within rounding where rests are
    (:data:`MERGED_ATOL_V`)."""
    rec = _held_record(temperature=temperature, rest=rest)
    X = _rows(effects)
    knots = ecm.Knots(0.5, 0.1)
    full = ecm.simulate_rows(rec, X, knots)
    for stride in (1, 7, 50, 1000):
        idx = np.arange(3, rec.n, stride)
        thin = ecm.simulate_rows(rec, X, knots, idx=idx)
        np.testing.assert_allclose(thin, full[idx], rtol=0, atol=MERGED_ATOL_V if rest else 0)


def _logged_at_1_hz(cur: np.ndarray, rng) -> ecm.Record:
    """Current ``cur`` at 1 Hz with a measured temperature that moves by a hundredth of a kelvin
    at most samples (as the Panasonic thermocouple does) and drifts by kelvins."""
    t = np.arange(cur.size, dtype=float)
    temp = 25.0 + 5.0 * np.sin(t / 4000.0) + 0.01 * rng.integers(-1, 2, t.size)
    frame = pd.DataFrame({"time_s": t, "current_a": cur, "voltage_v": 3.7, "temperature_c": temp})
    return ecm.Record.from_frame(frame, tref_k=298.15)


def _flickering_record(n=20000, seed=1) -> ecm.Record:
    """Rests and holds at 1 Hz, a measured temperature that moves by a hundredth of a kelvin at
    most samples (as the Panasonic thermocouple does) and drifts by kelvins."""
    rng = np.random.default_rng(seed)
    cur = np.concatenate([np.full(int(rng.uniform(5, 600)), rng.choice([0, 0, 1.5, -1, 3.0]))
                          for _ in range(n // 100)])[:n]  # fmt: skip
    return _logged_at_1_hz(cur, rng)


@pytest.mark.parametrize("effects", [("thermal",), ("thermal", "hysteresis", "diffusion"),
                                     ("butler_volmer", "bv_arrhenius", "second_rc"),
                                     ("thermal", "r0_charge", "r1_soc", "soc_resistance"),
                                     ("thermal", "current_offset")])  # fmt: skip
def test_a_rest_holds_its_temperature_and_every_voltage_is_the_same(effects):
    """At zero current the temperature acts on nothing: the simulator is given each rest's
    first temperature through the rest (``Record.rest_held``, so that a rest is one hold) and
    returns, bit for bit, the voltages of the measured temperature (the traced pass, which
    always reads the measured one). With a current offset a current flows at rest: the
    measured temperature is kept."""
    rec = _flickering_record()
    rest = rec.i == 0.0
    held_dinv, held_rtf = rec.rest_held
    assert np.mean(np.diff(rec.dinv_t)[rest[1:]] != 0) > 0.5  # the flicker the shortcut skips
    tail = rest & np.concatenate([[False], rest[:-1]])
    assert (np.diff(held_dinv)[tail[1:]] == 0).all()
    assert (np.diff(held_rtf)[tail[1:]] == 0).all()
    assert (held_dinv[~tail] == rec.dinv_t[~tail]).all()
    X = _rows(effects)
    knots = ecm.Knots(0.5, 0.1)
    measured, _ = ecm.simulate_rows(rec, X, knots, traces=True)
    np.testing.assert_array_equal(ecm.simulate_rows(rec, X, knots), measured)
    idx = np.arange(5, rec.n, 37)  # the rests between them merged: within rounding
    np.testing.assert_allclose(ecm.simulate_rows(rec, X, knots, idx=idx), measured[idx],
                               rtol=0, atol=MERGED_ATOL_V)  # fmt: skip


def _resting_record(n=40000, seed=2) -> ecm.Record:
    """An HPPC-like test at 1 Hz: pulses of 10-30 s between rests of 5-40 min (rest at about
    nine samples in ten), a measured temperature that flickers and drifts."""
    rng = np.random.default_rng(seed)
    parts = []
    while sum(p.size for p in parts) < n:
        parts += [np.full(int(rng.uniform(10, 30)), rng.choice([1.5, -1.0, 3.0])),
                  np.zeros(int(rng.uniform(300, 2400)))]  # fmt: skip
    cur = np.concatenate(parts)[:n]
    return _logged_at_1_hz(cur, rng)


@pytest.mark.parametrize("effects", [(), ("hysteresis", "diffusion", "second_rc"),
                                     ("third_rc", "soc_resistance", "r1_soc"),
                                     ("thermal", "coulombic_efficiency", "r0_charge"),
                                     ("butler_volmer", "bv_arrhenius")])  # fmt: skip
def test_a_thinned_pass_over_rests_merges_them_and_gives_the_full_pass(effects):
    """On a record that rests most of the time each rest between returned samples is one
    merged step (far fewer steps), and the voltages are the full pass's within rounding."""
    rec = _resting_record()
    X = _rows(effects)
    knots = ecm.Knots(0.5, 0.1)
    full = ecm.simulate_rows(rec, X, knots)
    for stride in (1, 7, 50, 1000):
        idx = np.arange(3, rec.n - 500, stride)
        steps = ecm._rests_merged(rec, idx)
        if stride > 1:  # every sample returned: only the record's tail goes
            assert steps[0].size < 0.5 * rec.n
            span = rec.t[idx[-1]] - rec.t[0] + rec.dt[idx[-1]]  # up to the last one returned
            assert steps[1].sum() == pytest.approx(span)
        np.testing.assert_allclose(ecm.simulate_rows(rec, X, knots, idx=idx), full[idx],
                                   rtol=0, atol=MERGED_ATOL_V)  # fmt: skip


def test_unsorted_samples_come_back_in_their_order():
    """A thinned pass returns the samples in the order asked for, merged rests or not."""
    rec = _resting_record(n=8000)
    X = _rows(("second_rc",))
    knots = ecm.Knots(0.5, 0.1)
    full = ecm.simulate_rows(rec, X, knots)
    idx = np.array([7000, 12, 3500, 6999, 40])
    np.testing.assert_allclose(ecm.simulate_rows(rec, X, knots, idx=idx), full[idx], rtol=0,
                               atol=MERGED_ATOL_V)  # fmt: skip


def test_merged_steps_are_made_once_per_record_and_index_array():
    """The merged steps are reused for the same record and index array, made anew for another
    record of the same length, and forgotten with their index array."""
    import gc

    rec, twin = _resting_record(n=5000), _resting_record(n=5000, seed=3)
    idx = np.arange(3, 4000, 50)
    first = ecm._rests_merged(rec, idx)
    assert ecm._rests_merged(rec, idx) is first
    other = ecm._rests_merged(twin, idx)
    assert other is not first
    assert not np.array_equal(other[1], first[1])  # its own rests
    key = id(idx)
    del idx
    gc.collect()
    assert not any(k[0] == key for k in ecm._PER_INDEX)


@pytest.mark.parametrize("effects", [("current_offset",), ("thermal", "thermal_tau"),
                                     ("entropic",)])  # fmt: skip
def test_rests_are_not_merged_where_something_acts_at_rest(effects):
    """A current offset makes a current flow at rest, a temperature-dependent time constant or
    an entropic term reads the temperature there: the rests are stepped sample by sample and
    the voltages are the full pass's bit for bit."""
    rec = _resting_record(n=20000)
    X = _rows(effects)
    knots = ecm.Knots(0.5, 0.1)
    full, _ = ecm.simulate_rows(rec, X, knots, traces=True)  # the traced pass reads every sample
    idx = np.arange(5, rec.n, 37)
    np.testing.assert_array_equal(ecm.simulate_rows(rec, X, knots, idx=idx), full[idx])


def test_thinned_output_under_a_load_is_the_full_pass():
    """Under the paper's load the current follows the voltage: no shortcut may skip it."""
    rec = _held_record(n=5000)
    X = _rows(("hysteresis",))
    full = ecm.simulate_rows(rec, X, ecm.Knots(0, 0.2), load_ohm=50.0)
    idx = np.arange(0, rec.n, 13)
    np.testing.assert_array_equal(
        ecm.simulate_rows(rec, X, ecm.Knots(0, 0.2), load_ohm=50.0, idx=idx), full[idx]
    )


def _small_frame():
    return with_voltage(profile_frame(), TRUTH, noise_v=1e-3, seed=3)


def test_samples_say_what_was_fitted():
    frame = pd.concat([_small_frame()] * 4, ignore_index=True)  # 24,000 samples: thinned
    frame["time_s"] = np.arange(len(frame), dtype=float)
    r = diagnose.diagnose(frame, progress=None)
    s = r["samples"]
    n = len(frame)
    assert s["given"] == r["n_samples"] == n
    assert s["stride"] == int(np.ceil(n / fitting.MAX_FIT_POINTS)) == 2
    assert s["fitted"] == len(range(0, n, 2))
    assert set(s["residual_correlation_samples"]) == {"base", "selected"}
    for k, tau in s["residual_correlation_samples"].items():
        assert tau > 0
        assert s["effective_samples"][k] == pytest.approx(n / max(tau, 1.0))
    assert "every sample" in s["method"]


def test_residual_correlation_reads_white_and_smooth_residuals():
    from avoa_pipeline.model.intervals import autocorrelation_time

    rng = np.random.default_rng(0)
    white = rng.standard_normal(100_000)
    assert autocorrelation_time(white) == pytest.approx(1.0, abs=0.5)
    # an AR(1) with coefficient 0.9: integrated autocorrelation time (1 + 0.9)/(1 − 0.9) = 19
    ar = np.empty_like(white)
    ar[0] = white[0]
    for k in range(1, ar.size):
        ar[k] = 0.9 * ar[k - 1] + white[k]
    assert autocorrelation_time(ar) == pytest.approx(19.0, rel=0.2)


def test_progress_goes_to_stderr_once_slow_and_stdout_keeps_one_line(tmp_path, capsys,
                                                                     monkeypatch):  # fmt: skip
    path = tmp_path / "r.csv"
    _small_frame().to_csv(path, index=False)
    monkeypatch.setattr(diagnose, "PROGRESS_AFTER_S", 0.0)  # every diagnosis counts as slow
    assert main(["diagnose", str(path), "--out", str(tmp_path / "out")]) == 0
    cap = capsys.readouterr()
    assert cap.out.count("\n") == 1
    lines = cap.err.splitlines()
    assert lines
    # progress lines, and after them the warnings (parameters the records do not identify)
    assert all(x.startswith(("diagnose: ", "warning: ")) for x in lines)
    assert any("base fit done" in x for x in lines)
    assert any("rung 1:" in x for x in lines)
    report = json.loads((tmp_path / "out" / "diagnosis.json").read_text())
    assert report["samples"]["given"] == len(_small_frame())


def test_a_quick_diagnosis_is_silent(capsys, monkeypatch):
    monkeypatch.setattr(diagnose, "PROGRESS_AFTER_S", 1e9)
    diagnose.diagnose(_small_frame())
    assert capsys.readouterr().err == ""


def test_an_element_that_reads_the_temperature_at_rest_keeps_the_measured_one(monkeypatch):
    """Only the elements of REST_BLIND act through the current alone; another that reads the
    temperature (here thermal, as if it acted at rest) turns the held rest temperature off
    wherever it is not neutral."""
    P = ecm.to_physical(_rows(("thermal",)))
    assert not ecm.temperature_acts_at_rest(P)  # every temperature element today is blind
    cols = np.array([ecm.IDX[n] for n in ecm.element_params("thermal")])
    monkeypatch.setattr(ecm, "_REST_ACTING", cols)
    assert ecm.temperature_acts_at_rest(P)
    assert not ecm.temperature_acts_at_rest(ecm.to_physical(_rows(("second_rc",))))
    rec = _flickering_record(n=3000)
    measured, _ = ecm.simulate_rows(rec, _rows(("thermal",)), ecm.Knots(0.5, 0.1), traces=True)
    np.testing.assert_array_equal(ecm.simulate_rows(rec, _rows(("thermal",)), ecm.Knots(0.5, 0.1)),
                                  measured)  # fmt: skip
