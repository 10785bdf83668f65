"""Experiment 1's C/20 circuits with effects and their choice by blocked CV (real/circuits.py)."""

import numpy as np
import pandas as pd
import pytest

from avoa_pipeline.errors import ConfigError, DataError
from avoa_pipeline.real import circuits as ci
from avoa_pipeline.real import drive_cycles as dc

BASE = {"q": 2.8, "r0": 0.03, "r1": 0.01, "tau1": 10.0, "r2": 0.01, "tau2": 300.0,
        "offset": 0.0, "k": 0.0, "sigma": 0.05}  # fmt: skip


def _ocv():
    soc = np.linspace(0, 1, 201)
    ocv = pd.DataFrame({"soc": soc, "ocv_v": 3.0 + 1.2 * soc - 0.3 * (1 - soc) ** 4})
    ocv.attrs.update(capacity_ah=2.9, current_a=0.145)
    return ocv


def _frame(n=2000, seed=0, temp=25.0):
    rng = np.random.default_rng(seed)
    cur = np.clip(np.repeat(rng.normal(1.0, 2.0, n // 10), 10), -3, 8)
    cur[:30] = 0.0
    return pd.DataFrame({"time_s": np.arange(n, dtype=float), "current_a": cur,
                         "voltage_v": 4.1, "temperature_c": temp})  # fmt: skip


def test_no_effects_is_the_c20_2rc_lowsoc_circuit():
    frame, ocv = _frame(), _ocv()
    p = {**BASE, "k": 0.5}
    np.testing.assert_allclose(ci.simulate(p, frame, ocv), dc.c20_simulate(p, frame, ocv),
                               atol=1e-12)  # fmt: skip


def test_ocv_ir_lifts_the_curve_by_the_c20_drop():
    frame, ocv = _frame(), _ocv()
    frame["current_a"] = 0.0
    p = {**BASE, "k": 1.0, "sigma": 0.1}
    v = ci.simulate(p, frame, ocv, ("ocv_ir",))
    # at rest the terminal voltage is the corrected OCV at s0; s0 inverts that same OCV
    assert v[-1] == pytest.approx(4.1, abs=1e-6)
    s = 0.2
    lift = 0.145 * (0.03 + 0.01 + 0.01) * (1 + np.exp(-s / 0.1))
    frame["voltage_v"] = np.interp(s, ocv.soc, ocv.ocv_v) + lift
    assert ci.simulate(p, frame, ocv, ("ocv_ir",))[0] == pytest.approx(frame.voltage_v[0], abs=1e-5)


def test_thermal_lowers_the_drop_when_the_cell_is_warmer():
    ocv = _ocv()
    cold, warm = _frame(temp=25.0), _frame(temp=35.0)
    p = {**BASE, "b": 0.03}
    drop_cold = 4.1 - ci.simulate(p, cold, ocv, ("thermal",))
    drop_warm = 4.1 - ci.simulate(p, warm, ocv, ("thermal",))
    busy = cold.current_a.to_numpy() > 2
    assert np.all(drop_warm[busy] < drop_cold[busy])


def test_hysteresis_state_moves_towards_the_current_sign():
    h = ci._hysteresis(np.r_[np.full(500, 3.0), np.full(500, -3.0)], 1.0, 200.0, 2.8)
    assert h[499] < -0.5
    assert h[-1] > 0.5
    assert np.all(np.abs(h) <= 1)


def test_fit_recovers_a_circuit_with_effects():
    frame, ocv = _frame(3000, seed=2), _ocv()
    truth = {**BASE, "k": 0.0, "b": 0.0, "m": 0.01, "gamma": 50.0}
    del truth["q"]
    eff = ("q_c20", "hyst")
    frame["voltage_v"] = ci.simulate(truth, frame, ocv, eff)
    rec = ci.fit(eff, frame, ocv)
    assert rec["train_rmse_mv"] < 0.05


def test_blocked_cv_scores_held_out_blocks_only():
    frame, ocv = _frame(1500, seed=4), _ocv()
    frame["voltage_v"] = ci.simulate({**BASE, "k": 0.0}, frame, ocv, ())
    assert ci.blocked_cv((), frame, ocv, folds=5)["cv_rmse_mv"] < 0.1
    shifted = frame.copy()
    shifted.loc[1200:, "voltage_v"] += 0.05  # a step only the last block sees
    cv = ci.blocked_cv((), shifted, ocv, folds=5)
    assert len(cv["fold_rmse_mv"]) == 5
    # held out, the last block cannot be fitted: its whole 50 mV step is error
    assert cv["fold_rmse_mv"][-1] == pytest.approx(50.0, abs=2.0)
    with pytest.raises(ConfigError, match="folds"):
        ci.blocked_cv((), shifted, ocv, folds=1)


def test_unknown_effect_is_refused():
    with pytest.raises(ConfigError, match="unknown circuit effect"):
        ci.param_names(("warp_drive",))


def _hppc_like(ocv, cap=2.9):
    """Rests of 1,800 s between 0.87-A steps of 0.29 Ah, with rest voltages 20 mV below the
    table; short 1,200-s rests after a 10-s pulse in between (not OCV points)."""
    cur, volt, q = [], [], 0.0
    table = lambda q: float(np.interp(1 - q / cap, ocv["soc"], ocv["ocv_v"])) - 0.02  # noqa: E731
    for _ in range(4):
        cur += [0.0] * 1800
        volt += [table(q)] * 1800
        cur += [5.0] * 10 + [0.0] * 1200
        volt += [3.5] * 10 + [3.6] * 1200
        q += 5.0 * 10 / 3600
        cur += [0.87] * 1200
        volt += [3.6] * 1200
        q += 0.87 * 1200 / 3600
    cur += [0.0] * 1800
    volt += [table(q)] * 1800
    return pd.DataFrame({"time_s": np.arange(len(cur), dtype=float), "current_a": cur,
                         "voltage_v": volt, "temperature_c": 25.0})  # fmt: skip


def test_ocv_hppc_moves_the_table_onto_the_long_rests_only():
    ocv = _ocv()
    hppc = _hppc_like(ocv)
    pts = ci.hppc_rest_points(hppc, 2.9)
    assert len(pts) == 5  # the opening rest and the four after SOC steps, not the pulse rests
    q_out = np.array([0, 1, 2, 3, 4]) * (5.0 * 10 + 0.87 * 1200) / 3600
    assert np.allclose(np.sort(pts[:, 0]), np.sort(1 - q_out / 2.9))
    moved = ci.table_for(("ocv_hppc",), ocv, hppc)
    s = pts[:, 0]
    assert np.allclose(np.interp(s, moved["soc"], moved["ocv_v"]),
                       np.interp(s, ocv["soc"], ocv["ocv_v"]) - 0.02, atol=1e-6)  # fmt: skip
    assert np.all(np.diff(moved["ocv_v"]) > 0)
    # the fitted record keeps its points, and the table is rebuilt from them
    frame = _frame(1500, seed=5)
    frame["voltage_v"] = ci.simulate({**BASE, "k": 0.0}, frame, moved, ())
    rec = ci.fit(("ocv_hppc",), frame, ocv, hppc=hppc)
    assert rec["train_rmse_mv"] < 0.1
    assert np.allclose(ci.model_table(rec, ocv)["ocv_v"], moved["ocv_v"])
    assert ci.model_table({"effects": []}, ocv) is ocv


def test_ocv_hppc_needs_the_hppc_record_and_two_rests():
    ocv = _ocv()
    with pytest.raises(ConfigError, match="'ocv_hppc' needs the HPPC record"):
        ci.fit(("ocv_hppc",), _frame(500), ocv)
    flat = _frame(500)
    flat["current_a"] = 1.0
    flat.attrs["source"] = "hppc.csv"
    with pytest.raises(DataError, match=r"^hppc\.csv: column 'current_a': 0 rest"):
        ci.table_for(("ocv_hppc",), ocv, flat)


def test_cross_cycle_separates_the_circuits_own_error_from_the_transfer():
    ocv = _ocv()
    a, b = _frame(1200, seed=6), _frame(1200, seed=7)
    a["voltage_v"] = ci.simulate({**BASE, "k": 0.0}, a, ocv, ())
    b["voltage_v"] = ci.simulate({**BASE, "k": 0.0, "r0": 0.05}, b, ocv, ())  # another cell state
    rows = pd.DataFrame(ci.cross_cycle("25degC", {"a": a, "b": b}, ocv, {"base": ()}))
    assert len(rows) == 4
    assert rows["in_sample"].sum() == 2
    err = rows.set_index(["fit_on", "predict"])["rmse_mv"]
    assert err["a", "a"] < 0.1
    assert err["b", "b"] < 0.1
    assert err["a", "b"] > 5.0
    assert err["b", "a"] > 5.0
