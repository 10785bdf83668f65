"""Parameter intervals (model/intervals.py) against brute force: the spread of refits on
independent noise, white and autocorrelated, as a logger's noise and a model's miss are."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from test_ecm import TRUTH, profile_frame, simulate

from avoa_pipeline.model import ecm, fitting, intervals
from avoa_pipeline.model import ocv as ocv_mod
from avoa_pipeline.model.ecm import Config, Record
from avoa_pipeline.model.fitted import fit_model

# a cell's day: rest, two discharges with a pulse between, a charge; 1-s logging, 9,720 samples
SEGMENTS = [(600, 0.0), (1800, 2.0), (600, 0.0), (60, 3.0), (300, 0.0), (1800, 2.0), (900, 0.0),
            (60, -2.0), (300, 0.0), (2400, -1.5), (900, 0.0)]  # fmt: skip


def _table():
    soc = np.linspace(0.1, 1.0, 181)
    P = ecm.to_physical(ecm.vector(TRUTH))[0]
    v = ecm.ocv_values(P, soc, ecm.Knots(0.0, 0.2), None)
    return ocv_mod.from_table(pd.DataFrame({"soc": soc, "ocv_v": v}), "truth")


def _ar1(n, phi, sd, rng):
    e = rng.standard_normal(n) * sd * np.sqrt(1.0 - phi**2)
    out = np.empty(n)
    out[0] = rng.standard_normal() * sd
    for k in range(1, n):
        out[k] = phi * out[k - 1] + e[k]
    return out


def _fit(frame, config):
    fit = fit_model(frame, config)
    recs = [Record.from_frame(frame)]
    st = fitting.structure(recs, config, fit.model.knots)
    return intervals.of_fit(recs, st, fit.X)


@pytest.mark.parametrize("phi", [0.0, 0.9])
def test_intervals_agree_with_the_spread_of_refits(phi):
    frame = profile_frame(SEGMENTS, temperature=False)
    v0 = simulate(frame, TRUTH, None)
    config = Config((), _table())
    runs = []
    for seed in range(40):
        noisy = frame.assign(
            voltage_v=v0 + _ar1(len(frame), phi, 2e-3, np.random.default_rng(seed))
        )
        runs.append(_fit(noisy, config))
    names = runs[0].names
    assert names == ("lq", "r0", "r1", "ltau1", "voff")
    empirical = np.std([r.value for r in runs], axis=0, ddof=1)
    predicted = np.median([r.sd for r in runs], axis=0)
    # within 20 % (40 refits estimate a spread to about ±11 %, one standard error)
    np.testing.assert_allclose(predicted / empirical, 1.0, atol=0.2)
    if phi:  # the correlated noise carries fewer independent samples, and wider intervals
        assert runs[0].n_eff < 0.2 * runs[0].n
    # a naive interval (independent residuals) would be far too narrow under correlated noise:
    # the check above can fail
    assert all(np.isfinite(r.sd).all() for r in runs)


def test_what_the_records_do_not_identify_is_flagged():
    # without a measured OCV, the rational curve's level, curvature and the capacity trade along
    # a valley on this short profile: no interval, flagged; the resistances keep theirs
    frame = profile_frame(temperature=False)
    frame = frame.assign(voltage_v=simulate(frame, TRUTH, None)
                         + 1e-3 * np.random.default_rng(0).standard_normal(len(frame)))  # fmt: skip
    iv = _fit(frame, Config(()))
    rep = iv.report()
    for p in ("vnom_v", "beta", "capacity_ah"):
        assert not rep["parameters"][p]["identified"], p
        assert any(f.startswith(p) for f in rep["flags"])
    for p in ("r0_ohm", "r1_ohm", "tau1_s"):
        entry = rep["parameters"][p]
        assert entry["identified"], p
        assert entry["low95"] < entry["value"] < entry["high95"]
    truth_r0 = TRUTH["r0_ohm"]
    assert rep["parameters"]["r0_ohm"]["low95"] < truth_r0 < rep["parameters"]["r0_ohm"]["high95"]


def test_a_parameter_at_its_bound_gets_no_interval_and_a_flag():
    frame = profile_frame(temperature=False)
    frame = frame.assign(voltage_v=simulate(frame, TRUTH, None)
                         + 1e-3 * np.random.default_rng(1).standard_normal(len(frame)))  # fmt: skip
    fit = fit_model(frame, Config(()))
    recs = [Record.from_frame(frame)]
    st = fitting.structure(recs, Config(()), fit.model.knots)
    X = fit.X.copy()
    k = ecm.IDX["r1"]
    X[:, k] = st.lo[st.shared.index("r1")]  # R1 = 0: pressed against its lower bound
    rep = intervals.of_fit(recs, st, X).report()
    assert rep["parameters"]["r1_ohm"]["at_bound"]
    assert rep["parameters"]["r1_ohm"]["low95"] is None
    assert "r1_ohm at a bound of its fit" in rep["flags"]


def test_two_parameters_the_records_cannot_separate_have_a_correlation_within_one():
    """A second RC branch with the first one's time constant: R1 and R2 trade one for one, their
    correlation rounds to about -1, and is written within ±1 (model.json's schema refuses more;
    an LFP HPPC record's fit gave -1.0000003 before the clip)."""
    frame = profile_frame(temperature=False)
    truth = {**TRUTH, "r2_ohm": 0.01, "tau2_s": TRUTH["tau1_s"]}
    cfg = Config(("second_rc",), _table())
    frame = frame.assign(voltage_v=simulate(frame, truth, cfg)
                         + 1e-4 * np.random.default_rng(1).standard_normal(len(frame)))  # fmt: skip
    recs = [Record.from_frame(frame)]
    st = fitting.structure(recs, cfg, ecm.Knots(0.0, 0.2))
    iv = intervals.of_fit(recs, st, fitting.complete(st, recs, np.array([ecm.vector(truth)])))
    off = iv.corr[~np.eye(len(iv.names), dtype=bool)]
    off = off[np.isfinite(off)]
    assert np.max(np.abs(off)) <= 1.0
    assert np.max(np.abs(off)) > 0.999
    # the covariance's rounding past ±1, as that record's: clipped
    sd = np.array([2e-3, 3e-4, 1.0])
    cov = np.outer(sd, sd) * np.array([[1, -1 - 3e-7, 0], [-1 - 3e-7, 1, 0], [0, 0, 1]])
    sd[2] = np.inf  # a parameter at a bound: no interval
    rho = intervals.correlation(cov, sd)
    assert rho[0, 1] == -1.0
    assert np.isnan(rho[2, 0])


def test_long_run_one_row_at_a_time_is_the_whole_transform_bit_for_bit():
    """``_long_run`` transforms the cross-spectra one row at a time (issue 42: memory); its
    Newey–West sum is the one of all rows at once, bit for bit, and the brute-force sum's."""
    rng = np.random.default_rng(4)
    U = rng.standard_normal((3000, 7)) * np.linspace(1.0, 3.0, 7)
    lags = 40
    m = 1 << int(np.ceil(np.log2(2 * U.shape[0])))
    F = np.fft.rfft(U, n=m, axis=0)
    C = np.fft.irfft(F[:, :, None] * np.conjugate(F[:, None, :]), n=m, axis=0)[: lags + 1]
    w = 1.0 - np.arange(lags + 1) / (lags + 1.0)
    S = np.tensordot(w[1:], C[1:], axes=1)
    whole = C[0] + S + S.T
    got = intervals._long_run(U, lags)
    assert np.array_equal(got.view(np.uint64), whole.view(np.uint64))
    brute = U.T @ U + sum(w[k] * (U[k:].T @ U[:-k] + U[:-k].T @ U[k:]) for k in range(1, lags + 1))
    np.testing.assert_allclose(got, brute, rtol=1e-9, atol=1e-9 * np.abs(brute).max())
