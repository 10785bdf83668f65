"""Per-temperature parameters as a candidate (docs/temperature-rule.md part 2;
avoa_pipeline.per_temperature): each test temperature's R0, RC branch and capacity fitted to its
records, the rest held at the circuit's; held out by test temperature (the other temperatures'
sets interpolated in 1/T) or by record; judged against the laws' model by the selection's tests."""

from __future__ import annotations

import numpy as np
import pytest
from test_ecm import TRUTH
from test_temperature_holdout import at_ambient, context

from avoa_pipeline import per_temperature, selection
from avoa_pipeline.model import ecm
from avoa_pipeline.model.fitted import FittedModel
from avoa_pipeline.selection import RECORD, TEMPERATURE

# R0 rises in the cold, the RC branch's resistance falls: no one Arrhenius law follows both
CELLS = {5.0: {"r0_ohm": 0.060, "r1_ohm": 0.010}, 35.0: {"r0_ohm": 0.030, "r1_ohm": 0.030}}


@pytest.fixture(scope="module")
def two():
    """Two test temperatures, two records each (different noise), and the base fitted."""
    ambients = [a for a in CELLS for _ in range(2)]
    frames = [at_ambient(a, {**TRUTH, **CELLS[a]}, seed=k) for k, a in enumerate(ambients)]
    ctx = context(frames, ambients)
    return ctx, selection.fit_base(ctx), frames


def test_each_temperature_gets_its_own_resistances_and_shares_the_rest(two):
    ctx, base, _ = two
    table = per_temperature.fit(ctx, base)
    assert table.circuit is base  # the base has no law: its circuit is itself
    assert table.ambients == [5.0, 35.0]
    for g, a in enumerate(table.ambients):
        p = table.models[g].parameters()
        assert p["r0_ohm"] == pytest.approx(CELLS[a]["r0_ohm"], rel=0.05)
        assert p["r1_ohm"] == pytest.approx(CELLS[a]["r1_ohm"], rel=0.15)
        assert set(table.sets[g].st.shared) == {"r0", "r1", "ltau1", "lq"}
        held = [n for n in table.sets[g].st.pinned]
        np.testing.assert_array_equal(table.sets[g].X[:, [ecm.IDX[n] for n in held]],
                                      base.X[np.ix_(ctx.groups[g],
                                                    [ecm.IDX[n] for n in held])])  # fmt: skip
    assert table.k == 2 * 4 + (base.k - 4)
    assert table.cand.rss < 0.2 * base.rss


def test_held_out_by_record_a_record_is_predicted_by_its_temperatures_other_record(two):
    ctx, base, frames = two
    table = per_temperature.fit(ctx, base)
    ho = per_temperature.hold_out(table, RECORD)
    o = ctx.layout.offsets
    for g, group in enumerate(ctx.groups):
        sub = table.subs[g]
        for k, r in enumerate(group):
            fold = selection.Candidate(table.sets[g].st, table.sets[g].fold_X[k],
                                       table.sets[g].v, table.sets[g].rss)  # fmt: skip
            v = selection.fitted_model(sub, fold).simulate(frames[r])
            np.testing.assert_allclose(ho[o[r] : o[r + 1]], v, rtol=0, atol=1e-9)
    # judged by record (two test temperatures) against the base: it pays
    ctx.cross_validate(base)
    row = per_temperature.judge(ctx, base, table, 0.003)
    assert row["held_out"] == "leave one record out"
    assert row["pays"]
    assert row["shrink"] > 0.5
    assert row["kept"] == per_temperature.NAME
    assert not row["failed"]


def test_held_out_by_temperature_a_middle_temperature_is_interpolated_in_one_over_t():
    cells = {5.0: (0.060, 0.010), 20.0: (0.042, 0.020), 35.0: (0.030, 0.030)}
    ambients = list(cells)
    frames = [at_ambient(a, {**TRUTH, "r0_ohm": r0, "r1_ohm": r1}, seed=k)
              for k, (a, (r0, r1)) in enumerate(cells.items())]  # fmt: skip
    ctx = context(frames, ambients)
    base = selection.fit_base(ctx)
    table = per_temperature.fit(ctx, base)
    ho = per_temperature.hold_out(table, TEMPERATURE)
    assert table.cand.ho_t is ho
    o = ctx.layout.offsets
    mid = FittedModel.per_temperature([(5.0, table.models[0]), (35.0, table.models[2])])
    want = mid.at_ambient(20.0)
    w = (1 / 293.15 - 1 / 278.15) / (1 / 308.15 - 1 / 278.15)
    r0 = [m.parameters()["r0_ohm"] for m in table.models]
    assert want.parameters()["r0_ohm"] == pytest.approx(r0[0] + w * (r0[2] - r0[0]))
    np.testing.assert_allclose(ho[o[1] : o[2]], want.simulate(frames[1]), rtol=0, atol=1e-9)
    # an end is predicted by its nearest set
    np.testing.assert_allclose(ho[o[0] : o[1]], table.models[1].simulate(frames[0]),
                               rtol=0, atol=1e-9)  # fmt: skip


def test_a_table_that_does_not_pay_loses_to_the_laws_model_with_fewer_parameters():
    """One Arrhenius factor explains R0 and R1 alike (θ 3000 K): the law and the table predict
    held-out records as well; the table has more parameters, so the law's model stays."""
    truth = {**TRUTH, "thermal_theta_r0_k": 3000.0, "thermal_theta_rc_k": 3000.0}
    ambients = [5.0, 5.5, 35.0, 34.5]
    frames = [at_ambient(a, truth, seed=k) for k, a in enumerate(ambients)]
    ctx = context(frames, ambients)
    base = selection.fit_base(ctx)
    law = ctx.cross_validate(selection.try_effects(ctx, base, ["thermal"], cv=False)["thermal"])
    table = per_temperature.fit(ctx, law)
    assert table.circuit.effects == ()
    row = per_temperature.judge(ctx, law, table, 0.003)
    assert not row["pays"]
    assert row["n_params"] > row["laws_n_params"]
    assert row["kept"] == per_temperature.LAWS


@pytest.mark.slow  # a whole diagnosis with two own ones inside: about 60-120 s
def test_diagnose_hands_over_the_table_where_it_wins_and_model_json_holds_its_sets(two, tmp_path):
    from avoa_pipeline import diagnosis

    _ctx, _, frames = two
    held = at_ambient(35.0, {**TRUTH, **CELLS[35.0], "soc0": 0.8}, seed=9)
    d = diagnosis.diagnose(frames, validate=[held], progress=False)
    handed = d.report["handed_over"]
    verdict = handed["per_temperature_parameters"]
    assert verdict["kept"] == per_temperature.NAME
    assert handed["name"] in (per_temperature.NAME, "per-temperature models")
    d.write(tmp_path, figure=False)
    model = FittedModel.load(tmp_path / "model.json")
    assert [a for a, _ in model.by_temperature] == [5.0, 35.0]
    assert handed["laws"]["name"] == "base"  # the laws' model: no law paid on two temperatures
    for a, m in model.by_temperature:  # the table's set, or (part 4) that temperature's own
        assert m.parameters()["r0_ohm"] == pytest.approx(CELLS[a]["r0_ohm"], rel=0.05)
    (row,) = [v for v in d.report["validation"] if v["model"] == "handed_over"]
    assert row["ambient_c"] == 35.0
    assert row["rmse_mv"] < 5.0
