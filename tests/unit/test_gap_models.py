"""Gap-diagnosis candidate models: the base is the paper's model, each effect is neutral at its
neutral parameters and acts away from them, fits recover known parameters."""

import dataclasses

import numpy as np
import pandas as pd
import pytest

from avoa_pipeline.gap import EFFECTS
from avoa_pipeline.gap import models as M
from avoa_pipeline.model.battery import ModelSpec, simulate, vector

TRUTH = {
    "vnom_v": 3.73,
    "beta": 0.932,
    "capacity_ah": 2.57,
    "soc0": 0.95,
    "r0_ohm": 0.0536,
    "r1_ohm": 0.0153,
    "tau1_s": 109.7,
}

# an effect's parameters away from neutral (each visibly changes the voltage)
ACTIVE = {
    "second_rc": {"r2_ohm": 0.01, "tau2_s": 1000.0},
    "hysteresis": {"hysteresis_m_v": 0.01, "hysteresis_gamma": 100.0, "hysteresis_h0": 0.0},
    "butler_volmer": {"bv_inv_i0_per_a": 2.0},
    "thermal": {"thermal_theta_r0_k": 4000.0, "thermal_theta_rc_k": 4000.0},
    "ocv_shape": {"ocv_shape_u0_v": 0.01, "ocv_shape_u1_v": -0.005},
    "current_offset": {"current_offset_a": 0.02},
    "voltage_offset": {"voltage_offset_v": 0.01},
    "coulombic_efficiency": {"coulombic_efficiency": 0.97},
}
# parameters that only matter once an effect's main parameter leaves neutral
DORMANT = {"tau2_s": 20.0, "hysteresis_gamma": 500.0, "hysteresis_h0": 0.7}


def profile_frame(segments=None, temperature=True) -> pd.DataFrame:
    segments = segments or [
        (300, 0.0), (1200, 2.0), (600, 0.0), (300, 1.0), (300, 0.0), (1200, -1.75),
        (600, 0.0), (200, 3.0), (400, 0.0), (400, -1.0), (500, 0.0),
    ]  # fmt: skip
    cur = np.concatenate([np.full(d, c) for d, c in segments])
    t = np.arange(cur.size, dtype=float)
    frame = pd.DataFrame({"time_s": t, "current_a": cur, "voltage_v": np.zeros_like(t)})
    if temperature:
        frame["temperature_c"] = 25.0 + 3.0 * np.sin(t / 3000.0)
    return frame


def with_voltage(frame, params, noise_v=0.0, seed=0):
    out = frame.copy()
    v = M.simulate_params(frame, params)
    if noise_v:
        rng = np.random.default_rng(seed)
        v = np.round((v + noise_v * rng.standard_normal(v.size)) / 1e-3) * 1e-3
    out["voltage_v"] = v
    return out


def test_base_is_the_papers_model():
    """The base kernel reproduces model/battery.py (β from Vdis, Qdis) to rounding."""
    truth = {"vnom": 3.73, "q": 2.57, "vdis": 3.53, "r0": 0.0536, "rtr": 0.0053, "tau": 109.7}
    spec = ModelSpec(dynamics=True, fade_factors=np.ones(6), load_ohm=None, soc0=1.0, qdis_ah=1.4)
    frame = profile_frame(temperature=False)
    ref = simulate(vector(truth), frame["current_a"].to_numpy(), 1.0, spec)["voltage_v"]
    soc1 = 1.4 / truth["q"]
    beta = (1 - truth["vnom"] * soc1 / truth["vdis"]) / (1 - soc1)
    ours = M.simulate_params(
        frame,
        {
            "vnom_v": truth["vnom"], "beta": beta, "capacity_ah": truth["q"], "soc0": 1.0,
            "r0_ohm": truth["r0"], "r1_ohm": truth["rtr"], "tau1_s": truth["tau"],
        },
    )  # fmt: skip
    np.testing.assert_allclose(ours, ref, rtol=0, atol=1e-12)


@pytest.mark.parametrize("effect", EFFECTS)
def test_effect_neutral_is_base_and_active_differs(effect):
    frame = profile_frame()
    base = M.simulate_params(frame, TRUTH)
    x = M.vector(TRUTH)
    # the effect's other parameters set to non-default values change nothing while it is neutral
    for name in M.EFFECT_PARAMS[effect]:
        if name in ("ltau2", "lgamma", "h0"):
            report = M._REPORT[name][0]
            x[M.IDX[name]] = M.vector({report: DORMANT[report]})[M.IDX[name]]
    rec = M.Record.from_frame(frame)
    neutral = M.simulate_rows(rec, x, M.Knots(0.0, 0.2))[:, 0]
    np.testing.assert_array_equal(neutral, base)
    active = M.simulate_params(frame, {**TRUTH, **ACTIVE[effect]})
    assert np.sqrt(np.mean((active - base) ** 2)) > 1e-3  # at least 1 mV RMS


def test_effects_stack():
    """Combinations act together: two effects differ from either alone."""
    frame = profile_frame()
    a = M.simulate_params(frame, {**TRUTH, **ACTIVE["hysteresis"]})
    b = M.simulate_params(frame, {**TRUTH, **ACTIVE["second_rc"]})
    ab = M.simulate_params(frame, {**TRUTH, **ACTIVE["hysteresis"], **ACTIVE["second_rc"]})
    base = M.simulate_params(frame, TRUTH)
    # hysteresis and the RC branch enter the voltage additively
    np.testing.assert_allclose(ab - base, (a - base) + (b - base), atol=1e-12)


def test_non_uniform_steps_match_uniform_path():
    frame = profile_frame()
    rec = M.Record.from_frame(frame)
    assert rec.uniform
    x = M.vector({**TRUTH, **ACTIVE["second_rc"], **ACTIVE["hysteresis"]})
    v_uniform = M.simulate_rows(rec, x, M.Knots(0, 0.2))[:, 0]
    v_general = M.simulate_rows(dataclasses.replace(rec, uniform=False), x, M.Knots(0, 0.2))
    np.testing.assert_allclose(v_general[:, 0], v_uniform, rtol=0, atol=1e-12)


def test_fit_recovers_base_parameters_noise_free():
    frame = with_voltage(profile_frame(), TRUTH)
    fitted = M.fit(frame, capacity_ah=TRUTH["capacity_ah"], soc0=TRUTH["soc0"])
    for key, value in TRUTH.items():
        assert fitted.params[key] == pytest.approx(value, rel=1e-4), key
    assert fitted.rmse_mv < 1e-3


def test_fit_without_capacity_or_soc0_matches_voltage_and_dynamics():
    """Capacity, SOC0, Vnom and β trade off over a partial SOC range; R0, R1, τ1 do not."""
    frame = with_voltage(profile_frame(), TRUTH)
    fitted = M.fit(frame)
    assert fitted.rmse_mv < 1e-2
    for key in ("r0_ohm", "r1_ohm", "tau1_s"):
        assert fitted.params[key] == pytest.approx(TRUTH[key], rel=1e-3), key


def test_fit_with_an_effect_recovers_it():
    truth = {**TRUTH, **ACTIVE["second_rc"]}
    frame = with_voltage(profile_frame(), truth)
    fitted = M.fit(frame, ("second_rc",), capacity_ah=2.57, soc0=0.95)
    assert fitted.effects == ("second_rc",)
    assert fitted.params["r2_ohm"] == pytest.approx(0.01, rel=1e-3)
    assert fitted.params["tau2_s"] == pytest.approx(1000.0, rel=1e-3)


def test_fitted_predicts_another_record_from_its_rest_voltage():
    truth = {**TRUTH, "soc0": 0.8}
    frame = with_voltage(profile_frame(), truth)
    fitted = M.fit(frame, capacity_ah=2.57, soc0=0.8)
    other = profile_frame([(200, 0.0), (900, 1.5), (400, 0.0), (600, -1.0), (300, 0.0)])
    other = with_voltage(other, {**truth, "soc0": 0.6})
    predicted = fitted.simulate(other)  # initial SOC from the first (rest) voltage
    assert np.sqrt(np.mean((predicted - other["voltage_v"].to_numpy()) ** 2)) < 1e-4
    given = fitted.simulate(other, soc0=0.6)
    np.testing.assert_allclose(given, other["voltage_v"].to_numpy(), atol=1e-6)
