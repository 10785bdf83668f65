"""Issue 37: with a measured OCV table the offset is a small correction with a measured size, and
the slow test's capacity a prior; older files without them still load."""

import json

import numpy as np
import pandas as pd
import pytest

from avoa_pipeline.model import ecm, fitting, ocv
from avoa_pipeline.model.fitted import FittedModel


def _ocv(s):
    return 3.0 + 0.7 * s + 0.5 * s**2


def slow_test(gap_v: float, charge: bool = True, q_ah: float = 3.0) -> pd.DataFrame:
    """A C/20 pseudo-OCV test logged every 60 s: discharge full to empty, a rest, charge back;
    each branch lies half of ``gap_v`` off the OCV (its overpotential and half the loop)."""
    dt, i = 60.0, q_ah / 20.0
    n = round(q_ah / i * 3600.0 / dt)
    s_d = 1.0 - np.arange(n) * i * dt / 3600.0 / q_ah
    parts_i = [np.full(n, i), np.zeros(60)]
    parts_v = [_ocv(s_d) - 0.5 * gap_v, np.full(60, _ocv(0.0))]
    if charge:
        s_c = np.arange(n) * i * dt / 3600.0 / q_ah
        parts_i.append(np.full(n, -i))
        parts_v.append(_ocv(s_c) + 0.5 * gap_v)
    cur, v = np.concatenate(parts_i), np.concatenate(parts_v)
    return pd.DataFrame({"time_s": dt * np.arange(cur.size), "current_a": cur, "voltage_v": v})


def _record() -> ecm.Record:
    t = np.arange(600.0)
    cur = np.where(t < 300, 1.0, -1.0)
    return ecm.Record.from_frame(pd.DataFrame({"time_s": t, "current_a": cur,
                                               "voltage_v": np.full(t.size, 3.5)}))  # fmt: skip


def test_a_slow_tests_branch_gap_sizes_the_offset_prior_and_its_bound():
    """Both branches: the offset's sd is half their gap, its bound OFFSET_BOUND_SDS of it; the
    capacity's prior is the test's, in the fit's log10 coordinate."""
    table = ocv.from_slow_test(slow_test(0.02), "slow.csv")
    assert table.offset_sd_v == pytest.approx(0.01, rel=1e-6)
    assert "branch gap" in table.offset_why
    assert table.capacity_sd_ah == pytest.approx(ocv.CAPACITY_SD_FLOOR * 3.0, rel=1e-3)
    st = fitting.structure([_record()], ecm.Config((), table))
    k = st.shared.index("voff")
    assert tuple(st.prior[k]) == pytest.approx((0.0, 0.01))
    assert (st.lo[k], st.hi[k]) == pytest.approx((-0.05, 0.05))
    q = st.shared.index("lq")
    assert st.prior[q, 0] == pytest.approx(np.log10(3.0), abs=1e-6)
    assert st.prior[q, 1] == pytest.approx(0.01 / np.log(10.0), rel=1e-3)
    # a branch gap below the voltage channels' accuracy: the floor
    assert ocv.from_slow_test(slow_test(0.001), "s.csv").offset_sd_v == ocv.OFFSET_SD_FLOOR_V


def test_without_a_measured_gap_the_offset_gets_the_named_default():
    """One slow branch, or a table given as is: OFFSET_SD_V; a table without a slow test has no
    capacity prior."""
    one = ocv.from_slow_test(slow_test(0.02, charge=False), "slow.csv")
    assert one.offset_sd_v == ocv.OFFSET_SD_V
    s = np.linspace(0, 1, 21)
    given = ocv.from_table(pd.DataFrame({"soc": s, "ocv_v": _ocv(s)}), "ocv.csv")
    assert given.offset_sd_v is None
    assert ocv.offset_prior(given)[0] == ocv.OFFSET_SD_V
    st = fitting.structure([_record()], ecm.Config((), given))
    k = st.shared.index("voff")
    assert tuple(st.prior[k]) == (0.0, ocv.OFFSET_SD_V)
    assert st.hi[k] == pytest.approx(ocv.OFFSET_BOUND_SDS * ocv.OFFSET_SD_V)
    assert not np.isfinite(st.prior[st.shared.index("lq"), 1])
    # the rational OCV keeps the voltage_offset element's own weak prior and range
    rational = fitting.structure([_record()], ecm.Config(("voltage_offset",)))
    k = rational.shared.index("voff")
    assert rational.hi[k] == 0.3
    assert rational.prior[k, 1] == ecm.PARAMS["voff"].prior_sd


def test_the_table_resampling_follows_a_smooth_curve_between_its_points():
    """A table's points are joined by the monotone cubic, not by straight lines (a fit's
    finite-difference Jacobian otherwise reads each segment's slope, issue 37)."""
    s = np.linspace(0, 1, 201)
    table = ecm.OcvTable.from_points(s, _ocv(s))
    g = table.grid()
    assert table.values.size == ecm.TABLE_POINTS
    assert np.max(np.abs(table.values - _ocv(g))) < 2e-6  # straight lines: 3.1 µV
    assert np.all(np.diff(table.values) > 0)


def test_older_model_json_without_the_table_uncertainties_loads(tmp_path):
    """A model.json written before issue 37 (no offset_sd_v, offset_why, capacity_sd_ah in its
    table) loads, and its fit would take the named defaults."""
    table = ocv.from_slow_test(slow_test(0.02), "slow.csv")
    x = ecm.vector({"capacity_ah": 3.0, "r0_ohm": 0.03, "r1_ohm": 0.015, "tau1_s": 30.0,
                    "voltage_offset_v": 0.004})  # fmt: skip
    config = ecm.Config((), table)
    bounds = {n: fitting.internal_limits(n) for n in config.names() if n != "soc0"}
    model = FittedModel(config, x, ecm.Knots(0.2, 0.12), 298.15, bounds, {"by": "test"}, 3.0)
    d = model.to_json()
    assert d["ocv_table"]["offset_sd_v"] == pytest.approx(0.01)
    again = FittedModel.from_json(json.loads(json.dumps(d)), "new.json")
    assert again.config.table.offset_sd_v == pytest.approx(0.01)
    for key in ("offset_sd_v", "offset_why", "capacity_sd_ah"):
        del d["ocv_table"][key]
    old = FittedModel.from_json(json.loads(json.dumps(d)), "old.json")
    assert old.config.table.offset_sd_v is None
    assert ocv.offset_prior(old.config.table)[0] == ocv.OFFSET_SD_V
    assert ocv.capacity_prior(old.config.table) == pytest.approx(
        (table.capacity_ah, ocv.CAPACITY_SD_FLOOR * table.capacity_ah)
    )
