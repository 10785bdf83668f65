"""The lumped thermal state (model/heat.py): the exact step against an independent integration,
the fixed point of the coupling, the identification of C_th, hA (and dU/dT) on a synthetic cell
whose temperature the module itself made, and what the heat block needs."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest
from scipy.integrate import solve_ivp
from test_ecm import ACTIVE, TRUTH

from avoa_pipeline import records
from avoa_pipeline.errors import DataError
from avoa_pipeline.model import ecm, fitting, heat
from avoa_pipeline.model.fitted import FittedModel

AMBIENT_C = 10.0
TRUE = heat.Heat(c_th=40.0, ha=0.08)  # an 18650 in a chamber: τ = 500 s


def cell(effects=("thermal", "second_rc")) -> FittedModel:
    """A thermal model of an 18650-like cell (TRUTH with the elements' active values)."""
    config = ecm.Config(tuple(effects))
    values = {**TRUTH, **{k: v for e in effects for k, v in ACTIVE[e].items()}}
    x = ecm.vector(values)
    bounds = {n: fitting.internal_limits(n) for n in config.names() if not ecm.PARAMS[n].per_record}
    return FittedModel(config, x, ecm.Knots(0.0, 0.2), AMBIENT_C + heat.KELVIN, bounds)


def drive(seed: int, n: int = 2400) -> pd.DataFrame:
    """A rested start, then 20-s steps of discharge-weighted current (−1.5C..3C of 2.57 Ah) and
    a rest: a drive cycle's heat, its charge net discharge."""
    rng = np.random.default_rng(seed)
    steps = rng.uniform(-4.0, 8.0, n // 20)
    cur = np.concatenate([np.zeros(60), np.repeat(steps, 20)[: n - 360], np.zeros(300)])
    t = np.arange(cur.size, dtype=float)
    return pd.DataFrame({"time_s": t, "current_a": cur, "voltage_v": 3.9})


def measured(model, truth: heat.Heat, frame, seed: int) -> pd.DataFrame:
    """The record the cell logs: its voltage and temperature the coupled model's (from the
    ambient), the thermocouple with 0.05 K noise."""
    pred = heat.predict(model, truth, frame, AMBIENT_C, soc0=0.95)
    noise = np.random.default_rng(seed).normal(0.0, 0.05, pred.temp_k.size)
    return frame.assign(voltage_v=pred.voltage_v,
                        temperature_c=pred.temp_k - heat.KELVIN + noise)  # fmt: skip


def checked(frame, k: int) -> records.Checked:
    return records.check(frame, f"rec{k}.csv", meta={"ambient_temperature_c": AMBIENT_C})


def assert_gives_back(got: heat.Heat, truth: heat.Heat) -> None:
    """A fitted block's C_th and hA within 5 % of the truth, inside their 95 % intervals and
    off their bounds."""
    iv = got.report["intervals"]
    for key, value in (("c_th_j_per_k", truth.c_th), ("ha_w_per_k", truth.ha)):
        e = iv[key]
        assert not e["at_bound"]
        assert e["low95"] <= value <= e["high95"], (key, e)
        assert abs(e["value"] / value - 1.0) < 0.05, (key, e)


def write_records(root, frame: pd.DataFrame) -> None:
    """A record of the cell three ways for the commands: with its temperature (with_t.csv),
    without it beside a sidecar naming the ambient (no_t.csv) and without either (alone.csv)."""
    frame.to_csv(root / "with_t.csv", index=False)
    frame.drop(columns="temperature_c").to_csv(root / "no_t.csv", index=False)
    (root / "no_t.json").write_text(json.dumps({"ambient_temperature_c": AMBIENT_C}))
    frame.drop(columns="temperature_c").to_csv(root / "alone.csv", index=False)


def test_the_exact_step_is_the_ode_integrated_independently():
    """Zero-order hold of q on an uneven grid: the recursion against solve_ivp over each step."""
    rng = np.random.default_rng(1)
    t = np.cumsum(np.concatenate([[0.0], rng.uniform(0.2, 30.0, 200)]))
    q = rng.uniform(-0.5, 3.0, t.size)
    c_th, ha, amb, t0 = 40.0, 0.08, 283.15, 290.0
    got = heat.temperature(t, q, amb, c_th, ha, t0)
    want, state = [t0], t0
    for k in range(t.size - 1):
        sol = solve_ivp(lambda _, y, k=k: [(q[k] - ha * (y[0] - amb)) / c_th], (t[k], t[k + 1]),
                        [state], rtol=1e-11, atol=1e-11)  # fmt: skip
        state = float(sol.y[0, -1])
        want.append(state)
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-7)


def test_the_fixed_point_converges_and_one_more_pass_moves_less_than_the_tolerance():
    model = cell()
    frame = drive(2)
    pred = heat.predict(model, TRUE, frame, AMBIENT_C, soc0=0.95)
    assert pred.converged
    assert 2 <= pred.passes < heat.MAX_PASSES
    rise = pred.temp_k.max() - (AMBIENT_C + heat.KELVIN)
    assert rise > 3.0  # the coupling matters: the cell heats by kelvins
    q, _ = heat.heat_of(model, frame, pred.temp_k, soc0=0.95)
    again = heat.temperature(frame["time_s"], q, AMBIENT_C + heat.KELVIN, TRUE.c_th, TRUE.ha)
    assert np.max(np.abs(again - pred.temp_k)) < heat.FIXED_POINT_TOL_K
    # and the first pass (at the ambient) was not already the answer
    q0, _ = heat.heat_of(model, frame, np.full(len(frame), AMBIENT_C + heat.KELVIN), soc0=0.95)
    first = heat.temperature(frame["time_s"], q0, AMBIENT_C + heat.KELVIN, TRUE.c_th, TRUE.ha)
    assert np.max(np.abs(first - pred.temp_k)) > 10 * heat.FIXED_POINT_TOL_K


def test_the_heat_is_every_overpotential_times_the_current():
    """At rest no heat; under a held discharge i·(OCV − V) > 0, and dU/dT adds −i·T·dU/dT."""
    model = cell()
    frame = drive(3)
    temp = np.full(len(frame), 300.0)
    q, _v = heat.heat_of(model, frame, temp, soc0=0.95)
    i = frame["current_a"].to_numpy()
    assert np.all(q[i == 0.0][:50] == 0.0)
    assert np.all(q[i > 1.0] > 0.0)
    q2, _ = heat.heat_of(model, frame, temp, dudt=-3e-4, soc0=0.95)
    np.testing.assert_allclose(q2 - q, i * 300.0 * 3e-4, rtol=1e-9, atol=1e-12)


@pytest.mark.parametrize("truth", [TRUE, heat.Heat(60.0, 0.15, -3e-4, True)],
                         ids=["irreversible", "entropic"])  # fmt: skip
def test_a_synthetic_cell_gives_back_its_heat_capacity_and_conductance(truth):
    model = cell()
    recs = [checked(measured(model, truth, drive(10 + k), 20 + k), k) for k in range(3)]
    got, why = heat.fit_heat(model, recs)
    assert got is not None, why
    assert_gives_back(got, truth)
    assert got.entropic == truth.entropic
    if truth.entropic:
        e = got.report["intervals"]["dudt_v_per_k"]
        assert e["low95"] <= truth.dudt <= e["high95"], e
    assert got.report["rmse_k"] < 0.1  # the 0.05 K noise, from the ambient alone
    assert [r["ambient_from"] for r in got.report["records"]] == ["sidecar"] * 3


def test_the_block_is_written_only_where_the_records_allow():
    """A moving measured temperature is what the block needs, not a thermal element
    (docs/temperature-rule.md part 6; tests/unit/test_heat_without_law.py)."""
    frame = measured(cell(), TRUE, drive(4), 5)
    got, why = heat.fit_heat(cell(("second_rc",)), [checked(frame, 0)])
    assert got is not None, why
    flat = frame.assign(temperature_c=AMBIENT_C + 0.5 * np.sin(frame["time_s"] / 100.0))
    got, why = heat.fit_heat(cell(), [checked(flat, 0)])
    assert got is None
    assert "moving" in why


def test_the_ambient_is_the_sidecars_else_the_first_sample():
    frame = measured(cell(), TRUE, drive(4), 5)
    assert heat.ambient_of(checked(frame, 0)) == (AMBIENT_C, "sidecar")
    plain = records.check(frame, "plain.csv")
    assert heat.ambient_of(plain) == (frame["temperature_c"].iloc[0], "first temperature sample")
    for bad in ("cold", float("nan"), 400.0, True):
        rec = records.check(frame, "r.csv", meta={"ambient_temperature_c": bad})
        with pytest.raises(DataError, match=r"^r\.csv's sidecar: field 'ambient_temperature_c'"):
            heat.ambient_of(rec)
    bare = records.check(frame.drop(columns="temperature_c"), "bare.csv")
    with pytest.raises(DataError, match="no ambient"):
        heat.ambient_of(bare)


def test_the_block_survives_model_json(tmp_path):
    model = cell()
    recs = [checked(measured(model, TRUE, drive(10 + k), 20 + k), k) for k in range(2)]
    model.heat, _ = heat.fit_heat(model, recs)
    model.save(tmp_path / "model.json")
    back = FittedModel.load(tmp_path / "model.json")
    assert back.heat == model.heat
    frame = recs[0].frame
    a = heat.predict(model, model.heat, frame, AMBIENT_C)
    b = heat.predict(back, back.heat, frame, AMBIENT_C)
    np.testing.assert_array_equal(a.temp_k, b.temp_k)


def test_attach_says_what_it_wrote_or_why_not():
    model = cell()
    recs = [checked(measured(model, TRUE, drive(12), 13), 0)]
    line = heat.attach(model, recs)
    assert line.startswith("heat block: C_th ")
    assert model.heat is not None
    plain = cell(("second_rc",))  # no temperature law: the block, and what the voltage reads
    assert heat.attach(plain, recs).endswith(f"; {heat.VOLTAGE_BLIND}")
    assert plain.heat is not None
    flat = recs[0].frame.assign(temperature_c=AMBIENT_C)
    assert heat.attach(cell(), [checked(flat, 1)]).startswith("no heat block (no training record")
    bad = records.check(recs[0].frame, "bad.csv", meta={"ambient_temperature_c": "cold"})
    with pytest.raises(DataError, match=r"bad\.csv's sidecar"):
        heat.training_ambients([bad])


@pytest.mark.skipif("entropic" not in ecm.EFFECTS, reason="the library has no entropic element")
def test_an_electrical_entropic_term_is_the_heats_reversible_term_not_an_overpotential():
    """The model's own dU/dT shifts its OCV: that shift is no loss, and its reversible heat
    −i·T·dU/dT is in the heat (issue 28 item 1's element, where the library has it)."""
    plain = cell(("thermal",))
    config = ecm.Config(("thermal", "entropic"))
    values = {**TRUTH, **ACTIVE["thermal"], heat.ELECTRICAL_DUDT: 3e-4}
    bounds = {n: fitting.internal_limits(n) for n in config.names() if not ecm.PARAMS[n].per_record}
    ent = FittedModel(config, ecm.vector(values), plain.knots, plain.tref_k, bounds)
    frame = drive(6)
    temp = np.full(len(frame), 300.0)
    q_plain, _ = heat.heat_of(plain, frame, temp, soc0=0.9)
    q_ent, _ = heat.heat_of(ent, frame, temp, soc0=0.9)
    i = frame["current_a"].to_numpy()
    np.testing.assert_allclose(q_ent - q_plain, -i * 300.0 * 3e-4, rtol=0, atol=1e-9)
