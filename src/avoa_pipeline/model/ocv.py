"""A measured OCV for the model library: from a slow test of the cell, or from a table.

**Slow test** (canonical columns ``time_s, current_a, voltage_v``; current positive = discharge).
The longest discharge run and the longest charge run (|I| above the rest threshold) are the two
branches. A branch counts only if it is slow: its median |I| at most C/10 of its own charge
(``SLOW_C_RATE``); a test with no slow branch is refused. SOC along a branch is coulomb-counted
over that branch's own charge: discharge s = 1 − q_out/Q_dis (full to empty), charge s = q_in/Q_ch.

**Combining the branches.** The usual pseudo-OCV is the mean of the two branches at equal SOC: the
ohmic drop and most of the hysteresis enter them with opposite signs and cancel. That needs both
branches to span the same SOC range, i.e. to move the same charge: a cell returns ≥ 99 % of its
charge at slow rates, so branches whose charges differ by more than ``BRANCH_CHARGE_TOLERANCE``
did not (a charge cut short, a different protocol) and are not averaged; the discharge branch is
used alone (the model's fitted offset then absorbs its IR drop). The choice and the reason go into
the table's ``how``.

**Table** (columns ``soc, ocv_v``): used as it is (SOC in [0, 1]; the OCV must rise with SOC,
up to noise, and is made strictly increasing for the inverse lookup).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from ..errors import DataError
from ..io import read_csv
from .ecm import OcvTable

SLOW_C_RATE = 0.1
"""A branch is slow enough to stand for the OCV at ≤ C/10 (the common definition of a
quasi-static test; the ohmic drop is then ~1/10 of that at 1C and the diffusion overpotential
smaller still)."""
BRANCH_CHARGE_TOLERANCE = 0.02
"""The branches are averaged only if their charges agree within 2 % (slow-rate coulombic
efficiency is above 99 %, so a larger difference means they did not span the same SOC range)."""
REST_FRACTION = 0.02
"""|I| at most this fraction of the record's 99th-percentile |I| counts as rest."""
GRID = 401
MIN_BRANCH_SAMPLES = 20


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    edges = np.flatnonzero(np.diff(np.r_[0, mask.astype(int), 0]))
    return list(zip(edges[::2], edges[1::2], strict=True))


def _branch(t, cur, volt, sign: int):
    """(SOC, V, charge Ah, median |I|) of the longest run of current with ``sign``, or None."""
    thr = REST_FRACTION * max(float(np.quantile(np.abs(cur), 0.99)), 1e-12)
    runs = _runs(sign * cur > thr)
    if not runs:
        return None
    a, b = max(runs, key=lambda r: r[1] - r[0])
    if b - a < MIN_BRANCH_SAMPLES:
        return None
    dt = np.diff(t, append=t[-1] + np.median(np.diff(t)))[a:b]  # zero-order hold: I[k] for dt[k]
    q = np.r_[0.0, np.cumsum(np.abs(cur[a:b]) * dt)] / 3600.0  # charge moved before each sample
    total = float(q[-1])
    q = q[:-1]
    soc = 1.0 - q / total if sign > 0 else q / total
    return soc, volt[a:b], total, float(np.median(np.abs(cur[a:b])))


def from_slow_test(frame: pd.DataFrame, source: str) -> OcvTable:
    """The OCV table of a slow test (see the module docstring)."""
    t = frame["time_s"].to_numpy(dtype=float)
    cur = frame["current_a"].to_numpy(dtype=float)
    volt = frame["voltage_v"].to_numpy(dtype=float)
    branches = {}
    for name, sign in (("discharge", 1), ("charge", -1)):
        br = _branch(t, cur, volt, sign)
        if br is None:
            continue
        soc, v, q, i_med = br
        if i_med > SLOW_C_RATE * q:
            continue
        branches[name] = (soc, v, q, i_med)
    if not branches:
        raise DataError(
            f"{source}: column 'current_a': no slow branch (a discharge or charge at "
            f"≤ C/{1 / SLOW_C_RATE:g} of its own charge); not an OCV test"
        )
    grid = np.linspace(0.0, 1.0, GRID)
    curves = {}
    for name, (soc, v, _, _) in branches.items():
        order = np.argsort(soc, kind="stable")
        curves[name] = np.interp(grid, soc[order], v[order])
    if len(branches) == 2:
        qd, qc = branches["discharge"][2], branches["charge"][2]
        if abs(qc - qd) <= BRANCH_CHARGE_TOLERANCE * qd:
            ocv = 0.5 * (curves["discharge"] + curves["charge"])
            how = (f"mean of the discharge ({qd:.4g} Ah) and charge ({qc:.4g} Ah) branches at "
                   "equal SOC")  # fmt: skip
        else:
            ocv = curves["discharge"]
            how = (f"discharge branch alone ({qd:.4g} Ah): the charge branch moved {qc:.4g} Ah, "
                   f"more than {BRANCH_CHARGE_TOLERANCE:.0%} off, so the two do not span the "
                   "same SOC range")  # fmt: skip
    else:
        (name,) = branches
        ocv = curves[name]
        how = f"{name} branch alone (the test has no other slow branch)"
    cap = branches.get("discharge", branches.get("charge"))[2]
    how += "; " + ", ".join(f"{n}: {b[2]:.4g} Ah at median {b[3]:.3g} A"
                            for n, b in branches.items())  # fmt: skip
    return OcvTable.from_points(grid, ocv, capacity_ah=cap, source=str(source), how=how)


def from_table(frame: pd.DataFrame, source: str) -> OcvTable:
    soc = frame["soc"].to_numpy(dtype=float)
    v = frame["ocv_v"].to_numpy(dtype=float)
    if soc.size < 2 or not np.all(np.isfinite(soc)) or not np.all(np.isfinite(v)):
        raise DataError(f"{source}: columns 'soc', 'ocv_v': need at least 2 finite rows")
    if soc.min() < 0 or soc.max() > 1:
        raise DataError(f"{source}: column 'soc': values outside [0, 1]")
    order = np.argsort(soc)
    if np.polyfit(soc[order], v[order], 1)[0] <= 0:
        raise DataError(f"{source}: column 'ocv_v': does not rise with SOC")
    return OcvTable.from_points(soc, v, source=str(source), how="table as given")


def read(path: str | Path, cycler: str | None = None) -> OcvTable:
    """``--ocv``: a table ``soc, ocv_v`` or a slow test in the canonical columns, or a slow test
    as a cycler's raw export when ``cycler`` is named."""
    from ..real.cycler import read_any

    path = Path(path)
    frame, _ = read_any(path, cycler)
    if frame is not None:
        return from_slow_test(frame, str(path))
    raw = read_csv(path)
    if {"soc", "ocv_v"} <= set(raw.columns):
        try:
            frame = raw[["soc", "ocv_v"]].apply(pd.to_numeric, errors="raise")
        except (ValueError, TypeError):
            raise DataError(f"{path}: columns 'soc', 'ocv_v': not numbers") from None
        return from_table(frame, str(path))
    if {"time_s", "current_a", "voltage_v"} <= set(raw.columns):
        from ..io import read_measurement

        return from_slow_test(read_measurement(path), str(path))
    raise DataError(f"{path}: need columns 'soc', 'ocv_v' (a table) or 'time_s', 'current_a', "
                    "'voltage_v' (a slow test)")  # fmt: skip


def to_json(table: OcvTable) -> dict:
    return {
        "soc_lo": table.lo,
        "soc_step": table.step,
        "soc": table.grid().tolist(),
        "ocv_v": table.values.tolist(),
        "capacity_ah": table.capacity_ah,
        "source": table.source,
        "how": table.how,
    }


def from_json(d: dict) -> OcvTable:
    return OcvTable(float(d["soc_lo"]), float(d["soc_step"]),
                    np.ascontiguousarray(d["ocv_v"], dtype=float), d.get("capacity_ah"),
                    d.get("source", ""), d.get("how", ""))  # fmt: skip
