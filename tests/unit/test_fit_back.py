"""Fit back what was simulated (issue 37, part 1; ``gap/fit_back.py``, docs/gap-diagnosis.md "Fit
back what was simulated (issue 37)"): records the model library simulates from the base and from
each element the withheld-effect check makes, logged as a cycler logs them, fitted back along the
diagnosis's path.

The fast lane fits each case back on one seed; the slow lane measures issue 37's goals over
seeds. Goals that main does not meet yet are marked xfail(strict=True) with the cause measured
(docs/gap-diagnosis.md): once a fix makes them pass, the strict mark fails, and the mark is
removed.
"""

from __future__ import annotations

import functools

import numpy as np
import pytest

from avoa_pipeline.gap import EFFECTS, withheld
from avoa_pipeline.gap import fit_back as F
from avoa_pipeline.model import ecm
from avoa_pipeline.model.ecm import Record
from avoa_pipeline.model.fitted import reference_temperature

SEED = 0

BASIN = (
    "the base fit without the element lands where the table's offset is tens of mV and the "
    "rule's initial SOC sits at the table's top (or τ1 at its bound); the element's starts are "
    "that base, and its fit stays there (started from the truth, thermal's and current_offset's "
    "worst seeds reach the noise)"
)
CURRENT_NOISE = (
    "the logged current's 1 mA noise at rest drives the model as if it flowed: hysteresis's "
    "sgn(I) relaxes |h| during rests (M fitted 0.5 % high, R1 and τ1 low), Butler-Volmer's "
    "zero-current slope (2RT/F)/(2 i0) ≈ 0.2 Ω turns it into 0.2 mV (the truth itself is 2 % "
    "above the noise); without current noise both meet the goals"
)
KNOTS = (
    "ocv_shape's knots follow the base fit's SOC range, not the truth's: its coordinates are "
    "compared on other knots, and the capacity and the offset absorb the difference"
)
OFFSET_PRIOR = (
    "the case's table lies ±50 mV off the cell, 3.3 sd out in a measured table's offset prior "
    "(15 mV without a slow test's own branches, docs/gap-diagnosis.md): the prior pulls the "
    "offset back on some seeds, as it should for a table that far off"
)
EXPECTED_FAST = {
    "ocv_shape": f"{BASIN}; {KNOTS}",
}
"""Cases whose seed-0 fit misses issue 37's RMSE goal (measured: docs/gap-diagnosis.md). Since the
fit check and the opening window of at least 25 samples, current_offset's seed 0 meets it."""
EXPECTED_SLOW_RMSE = {
    "hysteresis": CURRENT_NOISE,
    "thermal": BASIN,
    "ocv_shape": f"{KNOTS}; {BASIN}",
    "voltage_offset": OFFSET_PRIOR,
}
"""Over 20 seeds, the cases that miss the RMSE goal on some seed. Before the fit check and the
opening window of at least 25 samples every case did (the rule read one or two samples of a
rest logged every 60 s; BASIN); since, base, second_rc,
butler_volmer, current_offset and coulombic_efficiency meet it on every seed."""
EXPECTED_SLOW_COVERAGE = {
    "hysteresis": CURRENT_NOISE,
    "thermal": BASIN,
    "ocv_shape": f"{KNOTS}; {BASIN}",
}
"""Cases with a parameter whose 95 % interval holds the truth on fewer than 88 % of 20 seeds."""


def _expected(cases, reasons):
    return [pytest.param(c, marks=pytest.mark.xfail(reason=reasons[c], strict=True))
            if c in reasons else c for c in cases]  # fmt: skip


def test_magnitudes_are_the_withheld_grids_largest(cfg):
    assert set(F.MAGNITUDES) == set(EFFECTS)
    for effect, m in F.MAGNITUDES.items():
        assert m == cfg["gap"]["magnitudes"][effect][-1], effect


def test_the_profile_is_logged_as_a_cycler_logs_it():
    rate, idx = F.profile()
    assert np.isin(np.flatnonzero(rate != 0), idx).all()  # every second under load
    gaps = np.diff(idx)
    assert gaps.max() == F.REST_LOG_S
    assert np.all(rate[idx[:-1][gaps > 1]] == 0)  # coarse only at rest
    # ... and every rest's first seconds at 1 s: the sample after a step is 1 s later
    steps = np.flatnonzero(np.diff(rate) != 0) + 1
    assert np.isin(steps, idx).all()
    assert np.isin(steps + 1, idx).all()
    charge = np.cumsum(rate) / 3600.0  # in capacities
    assert charge.max() == pytest.approx(0.5, abs=0.01)  # 50 % of the SOC range down ...
    assert charge.max() - charge[-1] == pytest.approx(0.25, abs=0.01)  # ... and 25 % back


@pytest.mark.parametrize("case", ["thermal", "hysteresis", "current_offset"])
def test_the_record_is_the_model_on_its_own_log(case):
    # simulated at 1 s and sampled at the logged instants = the library on the logged record
    # (zero-order hold through a coarse rest): the truth is inside the fitted family exactly
    c = F.make_case(case, SEED)
    cell = withheld.base_cell(SEED, F.NAME, 0)
    rate, idx = F.profile()
    current = rate * cell.q_ah
    temp_c = withheld.temperature_k(cell, current, SEED, F.NAME, 0) - 273.15
    clean = c.frame.assign(current_a=(current - c.x[ecm.IDX["ioff"]])[idx],
                           temperature_c=temp_c[idx])  # fmt: skip
    rec = Record.from_frame(clean, tref_k=reference_temperature([c.frame]))
    v = ecm.simulate_rows(rec, c.x, c.knots, c.table)[:, 0]
    np.testing.assert_allclose(v, c.v_clean, rtol=0, atol=1e-12)


def test_the_cases_of_a_seed_differ_only_by_their_element():
    base, rc = F.make_case("base", SEED), F.make_case("second_rc", SEED)
    for col in ("time_s", "current_a", "temperature_c"):
        np.testing.assert_array_equal(base.frame[col], rc.frame[col])
    assert 1e3 * np.sqrt(np.mean((base.v_clean - rc.v_clean) ** 2)) > 10.0
    assert F.structure_of("voltage_offset") == ()  # with a table, the base's own offset


def test_a_swapped_pair_of_rc_branches_is_compared_branch_by_branch():
    names = ("r1", "ltau1", "r2", "ltau2")
    truth = np.array([0.01, 1.5, 0.06, 3.0])
    value = np.array([0.06, 3.0, 0.01, 1.5])
    low, high = value - 0.001, value + 0.001
    assert F._in_truth_order(names, truth, value, low, high)
    np.testing.assert_array_equal(value, truth)
    assert not F._in_truth_order(names, truth, value, low, high)


def test_coverage_verdicts():
    assert F.coverage_verdict(38, 40) == "ok"
    assert F.coverage_verdict(28, 40) == "low"  # 70 %: far below 88 %
    assert F.coverage_verdict(40, 40) == "ok"  # 40 seeds cannot show intervals too wide
    assert F.coverage_verdict(1000, 1000) == "high"


@pytest.mark.parametrize("case", _expected(F.CASES, EXPECTED_FAST))
def test_fit_back_leaves_the_noise(case):
    r = F.run(case, SEED)
    assert r.ratio <= F.RATIO_MAX, f"{case}: RMSE {r.rmse_mv:.3f} mV, noise {r.noise_mv:.3f} mV"


# ----------------------------------------------------------------------------------------------
# issue 37's goals over seeds (minutes)

SLOW_SEEDS = 20
"""Seeds per case: a 95 % coverage falls below 88 % on a one-sided binomial test at 5 % with
probability 0.03 % at 20 seeds (14 or fewer of 20); a coverage of 70 % is caught with
probability 0.58."""


@functools.cache
def _results(case: str) -> tuple[F.FitBack, ...]:
    """Each case's fits over the seeds, shared by the two slow tests."""
    return tuple(F.run(case, s) for s in range(SLOW_SEEDS))


@pytest.mark.slow
@pytest.mark.parametrize("case", _expected(F.CASES, EXPECTED_SLOW_RMSE))
def test_fit_back_leaves_the_noise_on_every_seed(case):
    ratios = [r.ratio for r in _results(case)]
    assert max(ratios) <= F.RATIO_MAX, f"{case}: RMSE/noise up to {max(ratios):.4f}"


@pytest.mark.slow
@pytest.mark.parametrize("case", _expected(F.CASES, EXPECTED_SLOW_COVERAGE))
def test_intervals_cover_the_truth(case):
    bad = {name: f"{hits}/{n}" for name, (hits, n) in F.coverage(_results(case)).items()
           if F.coverage_verdict(hits, n) != "ok"}  # fmt: skip
    assert not bad, f"{case}: coverage outside 88-99 % for {bad}"
