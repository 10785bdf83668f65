"""A measured OCV for the model library: from a slow test of the cell, or from a table. Files are
read by the input layer (``inputs.read_ocv``); this module turns a checked record or a table's
columns into an :class:`~avoa_pipeline.model.ecm.OcvTable`.

**Slow test** (a checked record: time_s, current_a discharge positive, voltage_v). Every run of
each sign (current beyond the rest line, ``records.at_rest``) is considered; a run is
*slow* if its median |I| is at most C/10 of its own charge (``SLOW_C_RATE``), and of each sign the
slow run that moves the most charge (the widest SOC range) is the branch. Real pseudo-OCV tests
start with a fast cycle (a C/2 discharge and a CC-CV charge) before the slow branches; those runs
are found and passed over. A test with no slow run is refused, naming the runs it has. SOC along
a branch is coulomb-counted over that branch's own charge: discharge s = 1 − q_out/Q_dis (full to
empty), charge s = q_in/Q_ch.

**Combining the branches.** The usual pseudo-OCV is the mean of the two branches at equal SOC: the
ohmic drop and most of the hysteresis enter them with opposite signs and cancel. That needs both
branches to span the same SOC range, i.e. to move the same charge: a cell returns ≥ 99 % of its
charge at slow rates, so branches whose charges differ by more than ``BRANCH_CHARGE_TOLERANCE``
did not (a charge cut short, a different protocol) and are not averaged; the discharge branch is
used alone (the model's fitted offset then absorbs its IR drop). The choice and the reason go into
the table's ``how``.

**Checks.** The curve must rise with SOC (``_check_rises``: the OCV of every lithium-ion
chemistry does; a slow test whose current sign is wrong gives a falling one). A branch that shows
no steep end-of-discharge knee may stop short of empty, so that its SOC 0-1 covers part of the
cell only: a note (``OcvTable.notes``), not an error.

**Table** (columns ``soc, ocv_v``): SOC in [0, 1] over at least ``MIN_TABLE_SPAN``, volts within
one cell's range, rising with SOC; then made strictly increasing for the inverse lookup.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pandas as pd

from ..errors import DataError
from ..records import at_rest, check_voltage, current_scale, runs_of
from .ecm import OcvTable

SLOW_C_RATE = 0.1
"""A branch is slow enough to stand for the OCV at ≤ C/10 (the common definition of a
quasi-static test; the ohmic drop is then ~1/10 of that at 1C and the diffusion overpotential
smaller still)."""
BRANCH_CHARGE_TOLERANCE = 0.02
"""The branches are averaged only if their charges agree within 2 % (slow-rate coulombic
efficiency is above 99 %, so a larger difference means they did not span the same SOC range)."""
OFFSET_SD_V = 0.015
"""How far a table not measured against the cell's own branches (one slow branch, or a table
given as is) may lie from the cell's OCV, one standard deviation: a slow branch lies off the OCV
by its overpotential (about 50 mΩ × C/20 of a 3 Ah cell ≈ 8 mV) plus half a hysteresis loop
(graphite cells 5-20 mV wide, LFP up to 30 mV): about 5-20 mV, so 15 mV."""
OFFSET_SD_FLOOR_V = 0.002
"""The least a table's offset is uncertain: the slow test's voltage channel and the records'
are each accurate to about ±1 mV (±0.02 % of a 5 V range), so they may differ by 2 mV."""
OFFSET_BOUND_SDS = 5.0
"""A fit's offset from a table stays within five of its standard deviations: farther, the table
is not this cell's OCV, and the fit stops at the bound and says so (``at_bounds``) instead of
absorbing it (the library's range, ±0.3 V, still caps it)."""
CAPACITY_SD_FLOOR = 0.01
"""The least a slow test's capacity is uncertain, relative: its charge between the voltage limits
at ≤ C/10 is the cell's to about 1 % (the overpotential left at the cut-offs holds back a little
of the knee's charge; a cycler's current gain is within ±0.1 % of full scale)."""
GRID = 401
MIN_BRANCH_SAMPLES = 20
MIN_TABLE_SPAN = 0.5
"""A table must span at least half of the SOC range: the model holds the OCV at a table's end
value beyond it, and a fit with a free capacity would squeeze a record into a narrower table."""
FALL_TOLERANCE_V = 0.01
"""How far the curve may fall below its running maximum (noise and relaxation wiggles of a slow
branch stay within a few mV); beyond that it does not rise with SOC."""
KNEE_SPAN = 0.05
KNEE_RATIO = 3.0
"""At empty the OCV of every lithium-ion chemistry falls steeply: over the last 5 % of a branch's
charge at least three times faster than over its middle (10-90 %; ratios of 5-30 are usual)."""


def _branches(t, cur, volt):
    """Every run of each sign: (name, first row, end row, charge Ah, median |I| A)."""
    dt = np.diff(t, append=t[-1] + np.median(np.diff(t)))  # zero-order hold: I[k] for dt[k]
    moving = ~at_rest(cur, max(current_scale(cur), 1e-12))
    out = []
    for name, sign in (("discharge", 1.0), ("charge", -1.0)):
        for a, b in runs_of(moving & (sign * cur > 0)):
            q = float(np.sum(np.abs(cur[a:b]) * dt[a:b])) / 3600.0
            out.append((name, a, b, q, float(np.median(np.abs(cur[a:b])))))
    return out, dt


def _curve(t, cur, volt, dt, a, b, sign):
    q = np.r_[0.0, np.cumsum(np.abs(cur[a:b]) * dt[a:b])] / 3600.0  # charge before each sample
    total = float(q[-1])
    soc = 1.0 - q[:-1] / total if sign > 0 else q[:-1] / total
    order = np.argsort(soc, kind="stable")
    grid = np.linspace(0.0, 1.0, GRID)
    return np.interp(grid, soc[order], volt[a:b][order])


def _check_rises(soc, v, source: str, what: str) -> None:
    """The OCV rises with SOC: overall, and nowhere falling more than FALL_TOLERANCE_V below its
    running maximum."""
    order = np.argsort(soc, kind="stable")
    v = np.asarray(v, dtype=float)[order]
    drop = float(np.max(np.maximum.accumulate(v) - v))
    if not v[-1] > v[0] or drop > FALL_TOLERANCE_V:
        raise DataError(
            f"{source}: {what}: the voltage does not rise with SOC ({v[0]:.4g} V at the "
            f"lowest SOC, {v[-1]:.4g} V at the highest, falling by up to "
            f"{1e3 * drop:.0f} mV); an OCV rises with SOC (current sign?)"
        )


def _knee(curve: np.ndarray) -> float:
    """The end-of-discharge slope over KNEE_SPAN against the mid-range slope."""
    grid = np.linspace(0.0, 1.0, GRID)
    end = (np.interp(KNEE_SPAN, grid, curve) - curve[0]) / KNEE_SPAN
    mid = (np.interp(0.9, grid, curve) - np.interp(0.1, grid, curve)) / 0.8
    return float(end / mid) if mid > 0 else np.inf


def _describe(runs) -> str:
    shown = sorted(runs, key=lambda r: -r[3])[:4]
    return "; ".join(
        f"{n} {q:.4g} Ah at {i:.3g} A (C/{q / i:.2g} of its own charge)"
        for n, _, _, q, i in shown
        if i > 0
    )


def _why_not_slow(runs) -> str:
    """What a run that is not slow of its own charge may be: a time in minutes (each run 60 times
    shorter, so 60 times faster of its own charge) or a test over part of the cell (its own
    charge a fraction of the capacity)."""
    big = min((r for r in runs if r[3] > 0 and r[4] > 0), key=lambda r: r[4] / r[3], default=None)
    if big is None:  # the slowest run of its own charge: the one the test meant as slow
        return ""
    rate = big[4] / big[3]
    hints = []
    if rate / 60.0 <= SLOW_C_RATE:
        hints.append(f"if the time is in minutes (need s), it is C/{60 / rate:.2g}")
    hints.append(
        f"if it covers part of the cell only, the cell is larger than its {big[3]:.4g} Ah and a "
        "slow test must run across its whole range"
    )
    return "; " + "; ".join(hints)


def from_slow_test(frame: pd.DataFrame, source: str) -> OcvTable:
    """The OCV table of a slow test (see the module docstring)."""
    t = frame["time_s"].to_numpy(dtype=float)
    cur = frame["current_a"].to_numpy(dtype=float)
    volt = frame["voltage_v"].to_numpy(dtype=float)
    runs, dt = _branches(t, cur, volt)
    branches = {}
    for name, a, b, q, i_med in runs:
        slow = b - a >= MIN_BRANCH_SAMPLES and q > 0 and i_med <= SLOW_C_RATE * q
        if slow and (name not in branches or q > branches[name][3]):
            branches[name] = (a, b, 1.0 if name == "discharge" else -1.0, q, i_med)
    if not branches:
        found = _describe(runs) or "no current beyond the rest line"
        raise DataError(
            f"{source}: column 'current_a': no slow branch (a discharge or charge at "
            f"≤ C/{1 / SLOW_C_RATE:g} of its own charge); found {found}{_why_not_slow(runs)}"
        )
    curves = {}
    for name, (a, b, sign, _, _) in branches.items():
        curves[name] = _curve(t, cur, volt, dt, a, b, sign)
        _check_rises(np.linspace(0, 1, GRID), curves[name], source, f"the {name} branch")
    if len(branches) == 2:
        qd, qc = branches["discharge"][3], branches["charge"][3]
        if abs(qc - qd) <= BRANCH_CHARGE_TOLERANCE * qd:
            ocv = 0.5 * (curves["discharge"] + curves["charge"])
            how = (
                f"mean of the discharge ({qd:.4g} Ah) and charge ({qc:.4g} Ah) branches at "
                "equal SOC"
            )
        else:
            ocv = curves["discharge"]
            how = (
                f"discharge branch alone ({qd:.4g} Ah): the charge branch moved {qc:.4g} Ah, "
                f"more than {BRANCH_CHARGE_TOLERANCE:.0%} off, so the two do not span the "
                "same SOC range"
            )
    else:
        (name,) = branches
        ocv = curves[name]
        how = f"{name} branch alone (the test has no other slow branch)"
    cap = branches.get("discharge", branches.get("charge"))[3]
    offset_sd, offset_why, cap_sd = _uncertainties(branches, curves, cap)
    how += "; " + ", ".join(
        f"{n}: {b[3]:.4g} Ah at median {b[4]:.3g} A" for n, b in branches.items()
    )
    passed = [r for r in runs if not any(r[1] == b[0] and r[0] == n for n, b in branches.items())]
    if passed:
        how += f"; passed over (not slow or narrower): {_describe(passed)}"
    notes = []
    knee = _knee(ocv)
    if knee < KNEE_RATIO:
        notes.append(
            f"{source}: the slow branch shows no end-of-discharge knee (slope over its "
            f"last {KNEE_SPAN:.0%} of charge {knee:.2g}× the mid-range's, a cell's is "
            f"≥ {KNEE_RATIO:g}×): it may stop short of empty, and its SOC 0-1 "
            f"({cap:.4g} Ah) then covers part of the cell only"
        )
    table = OcvTable.from_points(
        np.linspace(0.0, 1.0, GRID), ocv, capacity_ah=cap, source=str(source), how=how
    )
    return dataclasses.replace(table, notes=tuple(notes), offset_sd_v=offset_sd,
                               offset_why=offset_why, capacity_sd_ah=cap_sd)  # fmt: skip


def _uncertainties(branches: dict, curves: dict, cap: float) -> tuple[float, str, float]:
    """(offset sd V, its reason, capacity sd Ah) of a slow test's table. With both branches:
    half their median gap over SOC 10-90 % (each branch lies off the OCV by its overpotential
    plus half the hysteresis, together half the gap; the mean of the two lies off by the
    difference of the two sides' overpotentials, at most that), and the capacity to the
    difference of the branches' charges; else OFFSET_SD_V. Floors: OFFSET_SD_FLOOR_V and
    CAPACITY_SD_FLOOR."""
    cap_sd = CAPACITY_SD_FLOOR * cap
    if len(branches) < 2:
        return OFFSET_SD_V, (f"one slow branch: {1e3 * OFFSET_SD_V:g} mV, a C/20 overpotential "
                             "plus half a hysteresis loop"), cap_sd  # fmt: skip
    grid = np.linspace(0.0, 1.0, GRID)
    mid = (grid >= 0.1) & (grid <= 0.9)
    half = 0.5 * float(np.median(curves["charge"][mid] - curves["discharge"][mid]))
    sd = max(abs(half), OFFSET_SD_FLOOR_V)
    why = (f"half the median charge-discharge branch gap over SOC 10-90 %: {1e3 * half:.3g} mV"
           + (f" (floor {1e3 * OFFSET_SD_FLOOR_V:g} mV)" if sd > abs(half) else ""))  # fmt: skip
    cap_sd = max(cap_sd, abs(branches["charge"][3] - branches["discharge"][3]))
    return sd, why, cap_sd


def offset_prior(table: OcvTable) -> tuple[float, str]:
    """(sd V, why) of a table's offset from the cell's OCV: the one measured from its slow test
    (:func:`_uncertainties`), else OFFSET_SD_V."""
    if table.offset_sd_v is not None:
        return float(table.offset_sd_v), table.offset_why
    return OFFSET_SD_V, (f"not measured: {1e3 * OFFSET_SD_V:g} mV, a C/20 overpotential plus "
                         "half a hysteresis loop")  # fmt: skip


def capacity_prior(table: OcvTable) -> tuple[float, float] | None:
    """(capacity Ah, sd Ah) the table's slow test measured, or None (a table given as is)."""
    if not table.capacity_ah:
        return None
    sd = table.capacity_sd_ah or CAPACITY_SD_FLOOR * table.capacity_ah
    return float(table.capacity_ah), float(sd)


def from_table(frame: pd.DataFrame, source: str) -> OcvTable:
    """An OCV table ``soc, ocv_v`` (numbers already) with its checks (module docstring)."""
    soc = frame["soc"].to_numpy(dtype=float)
    v = frame["ocv_v"].to_numpy(dtype=float)
    if soc.size < 2 or not np.all(np.isfinite(soc)) or not np.all(np.isfinite(v)):
        raise DataError(f"{source}: columns 'soc', 'ocv_v': need at least 2 finite rows")
    if soc.min() < 0 or soc.max() > 1:
        raise DataError(
            f"{source}: column 'soc': values {soc.min():g}..{soc.max():g} outside "
            "[0, 1] (percent given?)"
        )
    check_voltage(v, source, "ocv_v")
    if np.ptp(soc) < MIN_TABLE_SPAN:
        raise DataError(
            f"{source}: column 'soc': the table spans SOC {soc.min():g}..{soc.max():g}"
            f"; an OCV table must span at least {MIN_TABLE_SPAN:g}"
        )
    _check_rises(soc, v, source, "column 'ocv_v'")
    return OcvTable.from_points(soc, v, source=str(source), how="table as given")


def over_temperature(tables, ambients_c, tref_c: float) -> OcvTable:
    """The OCV table of slow tests at two temperatures or more (docs/temperature-rule.md part 5):
    ∂U/∂T at each point of the grid, the least-squares slope over the tests' ambients (°C) of
    their OCVs at that SOC (numpy's polyfit, each point's line on its own), and the table the
    OCV at ``tref_c`` (the training records' reference temperature, where the ``entropic``
    term's T − Tref vanishes): the test nearest it, moved along its profile by
    ∂U/∂T·(tref − its ambient) and made strictly increasing again as :meth:`OcvTable.from_points`
    does. Its capacity, offset and capacity priors and notes are that test's. ``tables``: each
    test's table (``from_slow_test``: every one on the same grid, SOC 0-1 of its own charge)."""
    temps = np.asarray(ambients_c, dtype=float)
    U = np.vstack([t(tables[0].grid()) for t in tables])
    slope, _ = np.polyfit(temps, U, 1)
    near = int(np.argmin(np.abs(temps - tref_c)))
    base = tables[near]
    shift = slope * (tref_c - temps[near])
    vals = np.maximum.accumulate(base.values + shift) + np.linspace(0.0, 1e-6, base.values.size)
    spread = ""
    if temps.size > 2:  # a slope's standard error where the line has residual degrees of freedom
        resid = U - (U.mean(axis=0) + np.outer(temps - temps.mean(), slope))
        sxx = float(np.sum((temps - temps.mean()) ** 2))
        se = np.sqrt(np.sum(resid**2, axis=0) / (temps.size - 2) / sxx)
        spread = f", its standard error {1e6 * float(np.median(se)):.3g} µV/K (median over SOC)"
    order = np.argsort(temps)
    how = (
        "∂U/∂T: least-squares slope over the slow tests' ambients of their OCVs at each SOC ("
        + ", ".join(f"{tables[k].source} at {temps[k]:.4g} °C" for k in order)
        + f"); |∂U/∂T| up to {1e3 * float(np.max(np.abs(slope))):.3g} mV/K{spread}"
    )
    moved = (
        f"; the table: {base.source} (the slow test nearest the records' reference "
        f"temperature {tref_c:.4g} °C) moved by ∂U/∂T·({tref_c:.4g} − {temps[near]:.4g}) K"
    )
    return dataclasses.replace(base, values=np.ascontiguousarray(vals),
                               how=base.how + moved, dudt_v_per_k=np.ascontiguousarray(slope),
                               dudt_how=how)  # fmt: skip


def to_json(table: OcvTable) -> dict:
    out = {
        "soc_lo": table.lo,
        "soc_step": table.step,
        "soc": table.grid().tolist(),
        "ocv_v": table.values.tolist(),
        "capacity_ah": table.capacity_ah,
        "source": table.source,
        "how": table.how,
        "offset_sd_v": table.offset_sd_v,
        "offset_why": table.offset_why,
        "capacity_sd_ah": table.capacity_sd_ah,
    }
    if table.dudt_v_per_k is not None:  # absent: one slow test, as before (file unchanged)
        out |= {"dudt_v_per_k": table.dudt_v_per_k.tolist(), "dudt_how": table.dudt_how}
    return out


def from_json(d: dict) -> OcvTable:
    return OcvTable(
        float(d["soc_lo"]),
        float(d["soc_step"]),
        np.ascontiguousarray(d["ocv_v"], dtype=float),
        d.get("capacity_ah"),
        d.get("source", ""),
        d.get("how", ""),
        offset_sd_v=d.get("offset_sd_v"),  # absent from files written before issue 37
        offset_why=d.get("offset_why", ""),
        capacity_sd_ah=d.get("capacity_sd_ah"),
        dudt_v_per_k=None if d.get("dudt_v_per_k") is None
        else np.ascontiguousarray(d["dudt_v_per_k"], dtype=float),
        dudt_how=d.get("dudt_how", ""),
    )  # fmt: skip
