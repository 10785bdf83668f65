"""Small raw cycler exports with a known truth, written by the tests themselves.

A cell (linear OCV, R0, one RC branch) runs a protocol of constant-current steps (charge
positive, the cyclers' sign), simulated on a 10-ms grid. Each step is logged once a second, at
its first 10 ms and at its exact end, as cyclers do. The truth is the net charge at every row,
so every interval's mean current is known exactly. Writers give each cycler's own header lines,
column names, units and counter style (docs/cyclers.md):

- Arbin: pair counters in Ah, running over the test but restarting at one step (a new cycle);
  optionally a current channel through a first-order filter (a lag at pulse edges);
- Maccor: one unsigned ``Capacity`` restarting at every step;
- Neware: pair counters in mAh restarting at every step; current in mA;
- BioLogic: pair counters in mA.h restarting when the direction changes; current in mA;
- Basytec: one signed running ``Ah[Ah]``.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass
from datetime import datetime, timedelta
from pathlib import Path

import numpy as np

GRID = 0.01
# (duration s, current A charge positive); consecutive discharges at two currents on purpose
PROTOCOL = (
    (30.0, 0.0),
    (40.37, -2.0),
    (30.0, 0.0),
    (40.0, 1.0),
    (30.2, 0.0),
    (20.0, -1.0),
    (20.0, -2.5),
    (60.0, 0.0),
    (25.0, 1.5),
    (30.0, 0.0),
)
R0, R1, TAU1 = 0.05, 0.02, 10.0
CAPACITY_AH = 2.0
START = datetime(2024, 5, 13, 11, 19, 51)


@dataclass
class Truth:
    t: np.ndarray  # row times (s)
    step: np.ndarray  # 1-based step numbers
    current: np.ndarray  # the step's set current at the row (A, charge positive)
    channel: np.ndarray  # what the current channel logs (the set current, or filtered)
    voltage: np.ndarray
    charged: np.ndarray  # cumulative charge in (Ah) and out, at each row
    discharged: np.ndarray
    temperature: np.ndarray

    def interval_mean_discharge(self) -> np.ndarray:
        """Exact mean current over [t_k, t_k+1), discharge positive."""
        net = self.charged - self.discharged
        return -np.diff(net) * 3600.0 / np.diff(self.t)


def simulate(lag_tau: float | None = None, protocol=PROTOCOL) -> Truth:
    """The cell and its log; ``lag_tau`` (s) filters the logged current channel."""
    ends = np.cumsum([d for d, _ in protocol])
    n = round(ends[-1] / GRID)
    tg = GRID * np.arange(n + 1)
    seg = np.searchsorted(ends, tg[:-1] + GRID / 2)  # the step of each grid interval
    i = np.array([c for _, c in protocol])[seg]
    charged = np.concatenate([[0], np.cumsum(np.clip(i, 0, None) * GRID)]) / 3600.0
    discharged = np.concatenate([[0], np.cumsum(np.clip(-i, 0, None) * GRID)]) / 3600.0
    soc = 0.5 + (charged - discharged) / CAPACITY_AH
    a = np.exp(-GRID / TAU1)
    v1 = np.zeros(n + 1)
    filt = np.zeros(n + 1)
    b = np.exp(-GRID / lag_tau) if lag_tau else 0.0
    for k in range(n):
        v1[k + 1] = a * v1[k] + R1 * (1 - a) * i[k]
        filt[k + 1] = b * filt[k] + (1 - b) * i[k]
    # the current at a grid point: the one flowing just before it (a step's last row is logged
    # before the next step switches on, as the channel logs it)
    i_at = np.concatenate([[i[0]], i])
    vg = 3.4 + 0.6 * soc + R0 * i_at + v1
    # rows: each step's first 10 ms, then every second, then its exact end
    rows, steps = [], []
    starts = np.concatenate([[0.0], ends[:-1]])
    for j, (s, e) in enumerate(zip(starts, ends, strict=True)):
        ts = np.concatenate([[s + GRID], np.arange(s + 1.0, e - 0.5, 1.0), [e]])
        rows.append(np.round(ts / GRID).astype(int))
        steps.append(np.full(ts.size, j + 1))
    k = np.concatenate(rows)
    step = np.concatenate(steps)
    cur = np.array([c for _, c in protocol])[step - 1]
    channel = filt[k] if lag_tau else cur
    temp = 25.0 + 0.1 * np.sin(tg[k] / 50.0)
    return Truth(tg[k], step, cur, channel.copy(), vg[k], charged[k], discharged[k], temp)


def ocv_knee(soc):
    """An OCV with the shape of a real cell's: a gentle slope over the middle, a steep knee at
    empty (9 V per unit SOC at 0 against 0.7 mid-range) and a rise towards full."""
    s = np.asarray(soc, dtype=float)
    return 3.45 + 0.7 * s - 0.35 * np.exp(-s / 0.04) + 0.05 * np.exp((s - 1.0) / 0.03)


def simulate_logged(protocol, *, dt_load: float = 1.0, dt_rest: float = 60.0,
                    grid: float = 0.1, lag_tau: float | None = None, edge_rows: bool = True,
                    soc0: float = 0.95, capacity_ah: float = CAPACITY_AH, r0: float = R0,
                    noise_v: float = 0.0, seed: int = 0, ocv=ocv_knee) -> Truth:  # fmt: skip
    """A cell (``ocv`` + R0 + one RC, charge positive) logged the way cyclers log long tests:
    rows every ``dt_load`` s under current and every ``dt_rest`` s at rest (coarse rests), or
    every ``protocol[j][2]`` s where a step gives its own (0.25-s pulses, a two-row EIS step),
    each step's first row at its start; with ``edge_rows`` also a row at each step's exact end
    (its voltage under the step's current, the next step not yet on); without, the step ends
    between two rows and the interval after the last load row straddles the edge (a late-logged
    rest). ``lag_tau`` filters the current channel (first order, s); ``noise_v`` adds Gaussian
    voltage noise, quantised to 1 mV as a logger's channel. Simulated on a ``grid``-s grid with
    the current piecewise constant on it (vectorised)."""
    from scipy.signal import lfilter

    durations = np.array([p[0] for p in protocol], dtype=float)
    set_current = np.array([p[1] for p in protocol], dtype=float)
    ends = np.cumsum(durations)
    n = round(ends[-1] / grid)
    tg = grid * np.arange(n + 1)
    seg = np.searchsorted(np.round(ends / grid), np.arange(n), side="right")
    i = set_current[seg]
    charged = np.r_[0.0, np.cumsum(np.clip(i, 0, None) * grid)] / 3600.0
    discharged = np.r_[0.0, np.cumsum(np.clip(-i, 0, None) * grid)] / 3600.0
    soc = soc0 + (charged - discharged) / capacity_ah
    a = np.exp(-grid / TAU1)
    v1 = np.r_[0.0, lfilter([R1 * (1 - a)], [1, -a], i)]
    i_at = np.r_[i[0], i]  # the current flowing just before each grid point
    vg = ocv(soc) + r0 * i_at + v1
    if noise_v:
        rng = np.random.default_rng(seed)
        vg = np.round((vg + noise_v * rng.standard_normal(vg.size)) / 1e-3) * 1e-3
    channel = i_at
    if lag_tau:
        b = np.exp(-grid / lag_tau)
        channel = np.r_[0.0, lfilter([1 - b], [1, -b], i)]
    rows, steps = [], []
    starts = np.r_[0.0, ends[:-1]]
    for j, (s, e) in enumerate(zip(starts, ends, strict=True)):
        every = protocol[j][2] if len(protocol[j]) > 2 else (dt_rest if set_current[j] == 0
                                                               else dt_load)  # fmt: skip
        ts = np.arange(s, e - 0.5 * grid, every)
        if edge_rows:
            ts = np.r_[ts, e]
        rows.append(np.round(ts / grid).astype(int))
        steps.append(np.full(ts.size, j + 1))
    k = np.unique(np.concatenate(rows))  # a step's end row and the next one's start: one row
    step_of = np.concatenate(steps)[np.unique(np.concatenate(rows), return_index=True)[1]]
    cur = set_current[step_of - 1]
    temp = 25.0 + 0.1 * np.sin(tg[k] / 50.0)
    return Truth(tg[k], step_of, cur, channel[k].copy(), vg[k], charged[k], discharged[k], temp)


def canonical(truth: Truth):
    """What ``convert`` writes for an export of ``truth``: time from 0, each row's current the
    exact mean over the interval to the next row (discharge positive; the last row: the channel),
    the logged voltage."""
    import pandas as pd

    cur = np.r_[truth.interval_mean_discharge(), -truth.channel[-1]]
    return pd.DataFrame(
        {
            "time_s": truth.t - truth.t[0],
            "current_a": cur,
            "voltage_v": truth.voltage,
            "temperature_c": truth.temperature,
        }
    )


def gitt_protocol(
    pulses: int = 20, current_a: float = -0.5, pulse_s: float = 720.0, rest_s: float = 14400.0
) -> list[tuple[float, float]]:
    """GITT: a rest, then pulses (charge positive: negative = discharge) each followed by a
    long rest."""
    return [(600.0, 0.0), *[(d, c) for _ in range(pulses)
                            for d, c in ((pulse_s, current_a), (rest_s, 0.0))]]  # fmt: skip


def from_frame(frame) -> Truth:
    """The log of a canonical record (discharge positive, each row's current held until the
    next row): a new step at every change of current, starting at its first row. No row marks
    a step's end, so only running counters (Arbin without a restart, Basytec) keep its charge."""
    t = frame["time_s"].to_numpy(dtype=float)
    cp = -frame["current_a"].to_numpy(dtype=float)
    dt = np.diff(t)
    charged = np.concatenate([[0.0], np.cumsum(np.clip(cp[:-1], 0, None) * dt)]) / 3600.0
    discharged = np.concatenate([[0.0], np.cumsum(np.clip(-cp[:-1], 0, None) * dt)]) / 3600.0
    step = 1 + np.concatenate([[0], np.cumsum(np.diff(cp) != 0)])
    temp = frame["temperature_c"].to_numpy() if "temperature_c" in frame else np.full(t.size, 25.0)
    v = frame["voltage_v"].to_numpy(dtype=float)
    return Truth(t, step, cp, cp.copy(), v, charged, discharged, temp)


def _restart(counter: np.ndarray, restart_rows: np.ndarray) -> np.ndarray:
    """A running counter made to restart at zero at each of ``restart_rows`` (the value at
    that row is the count since the restart, which happened at the step's start)."""
    out = counter.copy()
    for r in sorted(restart_rows):
        out[r:] = counter[r:] - counter[r - 1]
    return out


def _step_starts(step: np.ndarray) -> np.ndarray:
    return np.flatnonzero(np.diff(step) != 0) + 1


def _per_step(counter: np.ndarray, truth: Truth) -> np.ndarray:
    """The counter's count since its step began (at the previous row, the last step's end)."""
    start_value = np.zeros_like(counter)
    starts = np.r_[_step_starts(truth.step), counter.size]
    for s, e in itertools.pairwise(starts):
        start_value[s:e] = counter[s - 1]
    return counter - start_value


def _stamp(truth: Truth, k: int, fmt: str) -> str:
    return (START + timedelta(seconds=float(truth.t[k]))).strftime(fmt)


def _kind(current: float, rest: str, charge: str, discharge: str) -> str:
    return rest if current == 0 else (charge if current > 0 else discharge)


def _write(path: Path, head: list[str], rows: list[list], sep: str = ",",
           encoding: str = "utf-8") -> Path:  # fmt: skip
    lines = [*head, *(sep.join(map(str, row)) for row in rows)]
    path.write_text("\n".join(lines) + "\n", encoding=encoding)
    return path


def write_arbin(truth: Truth, path: Path, current_unit: str = "A", restart_step: int | None = 6,
                extra_columns: dict | None = None) -> Path:  # fmt: skip
    scale = {"A": 1.0, "mA": 1e3}[current_unit]
    restart = np.flatnonzero(truth.step == restart_step)[:1] if restart_step else []
    chg = _restart(truth.charged, restart)
    dch = _restart(truth.discharged, restart)
    extra = extra_columns or {}
    cols = ["Data Point", "Date Time", "Test Time (s)", "Step Time (s)", "Cycle Index",
            "Step Index", f"Current ({current_unit})", "Voltage (V)", "Charge Capacity (Ah)",
            "Discharge Capacity (Ah)", "Aux_Temperature_1 (C)", *extra]  # fmt: skip
    rows = [[k + 1, _stamp(truth, k, "%m/%d/%Y %H:%M:%S.%f")[:-3], f"{truth.t[k]:.4f}", "0", 1,
             int(truth.step[k]), f"{truth.channel[k] * scale:.9g}", f"{truth.voltage[k]:.9g}",
             f"{chg[k]:.12g}", f"{dch[k]:.12g}", f"{truth.temperature[k]:.5f}",
             *(v[k] for v in extra.values())]
            for k in range(truth.t.size)]  # fmt: skip
    return _write(path, [",".join(cols)], rows)


CLASSIC_ARBIN_COLUMNS = (
    "Data_Point", "Test_Time(s)", "Date_Time", "Step_Time(s)", "Step_Index", "Cycle_Index",
    "Current(A)", "Voltage(V)", "Charge_Capacity(Ah)", "Discharge_Capacity(Ah)",
    "Charge_Energy(Wh)", "Discharge_Energy(Wh)", "dV/dt(V/s)", "Internal_Resistance(Ohm)",
    "Aux_Temperature_1(C)",
)  # fmt: skip


def _arbin_classic_rows(truth: Truth, restart_step: int | None, counters=None,
                        temperatures: dict | None = None) -> list[list]:  # fmt: skip
    """``counters``: (charge, discharge) as the export writes them (default: the truth's,
    restarting at ``restart_step``); ``temperatures``: extra temperature columns' values."""
    if counters is None:
        restart = np.flatnonzero(truth.step == restart_step)[:1] if restart_step else []
        counters = (_restart(truth.charged, restart), _restart(truth.discharged, restart))
    chg, dch = counters
    extra = list((temperatures or {}).values())
    starts = np.r_[0, _step_starts(truth.step)]
    step_t0 = truth.t[starts][np.searchsorted(starts, np.arange(truth.t.size), "right") - 1]
    return [[k + 1, float(f"{truth.t[k]:.4f}"), _stamp(truth, k, "%Y/%m/%d %H:%M:%S"),
             float(f"{truth.t[k] - step_t0[k]:.4f}"), int(truth.step[k]), 1,
             float(f"{truth.channel[k]:.9g}"), float(f"{truth.voltage[k]:.9g}"),
             float(f"{chg[k]:.12g}"), float(f"{dch[k]:.12g}"), 0.0, 0.0, 0.0, 0.0,
             float(f"{truth.temperature[k]:.5f}"), *(float(f"{x[k]:.5f}") for x in extra)]
            for k in range(truth.t.size)]  # fmt: skip


def write_arbin_classic(truth: Truth, path: Path, restart_step: int | None = 6, counters=None,
                        temperature: str = "Aux_Temperature_1(C)",
                        temperatures: dict | None = None) -> Path:  # fmt: skip
    """Arbin MITS Pro's classic CSV export (``Test_Time(s)``, ``Current(A)``, ...): the layout
    of most public Arbin datasets. ``temperature``: the header of the truth's temperature;
    ``temperatures``: more temperature columns (header → values)."""
    cols = [*CLASSIC_ARBIN_COLUMNS[:-1], temperature, *(temperatures or {})]
    rows = _arbin_classic_rows(truth, restart_step, counters, temperatures)
    return _write(path, [",".join(cols)], rows)


def write_arbin_classic_xlsx(truth: Truth, path: Path, restart_step: int | None = 6) -> Path:
    """The same as MITS Pro's workbook: a ``Global_Info`` sheet first, the rows in a
    ``Channel_<n>-<m>`` sheet, statistics after."""
    return write_arbin_workbook({"Channel_1-006": truth}, path, restart_step)


def write_arbin_workbook(sheets: dict, path: Path, restart_step: int | None = 6,
                         temperature: str = "Aux_Temperature_1(C)") -> Path:  # fmt: skip
    """A MITS Pro workbook: ``Global_Info`` first, a sheet of rows per entry of ``sheets``
    (name → truth; e.g. one test's drive cycles on a sheet each, as CALCE publishes them, with
    ``temperature`` = ``Temperature (C)_1``), a ``Statistics`` sheet (a row per cycle) last."""
    from openpyxl import Workbook

    wb = Workbook()
    info = wb.active
    info.title = "Global_Info"
    info.append(["TEST REPORT"])
    info.append(["Channel", "Start DateTime", "Schedule File Name"])
    info.append([1, START.strftime("%m/%d/%Y %H:%M:%S"), "fixture.sdx"])
    for name, truth in sheets.items():
        data = wb.create_sheet(name)
        data.append([*CLASSIC_ARBIN_COLUMNS[:-1], temperature])
        for row in _arbin_classic_rows(truth, restart_step):
            data.append(row)
    stats = wb.create_sheet("Statistics_1-006")
    stats.append(["Cycle_Index", "Test_Time(s)", "Step_Index", "Current(A)", "Voltage(V)"])
    stats.append([1, float(max(t.t[-1] for t in sheets.values())), 1, 0.0, 3.7])
    wb.save(path)
    return Path(path)


def hppc_eis_protocol(blocks: int = 4, pulse_a: float = 18.0) -> list[tuple[float, float, float]]:
    """A classic Arbin HPPC + EIS test of a 5-Ah cell, logged as its schedule logs
    (duration s, current A charge positive, logging interval s): a C/2 charge, then per block
    an 18-A discharge and a 13.5-A charge pulse of 10 s logged every 0.25 s, rests and a
    10 % discharge logged every 10 s; after the second block an EIS step of 57,000 s that
    the cycler logs as two rows (its start and end)."""
    charge = [(600.0, 0.0, 10.0), (32400.0, 0.5, 10.0), (3600.0, 0.0, 10.0)]
    block = [(10.0, -pulse_a, 0.25), (40.0, 0.0, 10.0), (10.0, 0.75 * pulse_a, 0.25),
             (40.0, 0.0, 10.0), (720.0, -2.5, 10.0), (1800.0, 0.0, 10.0)]  # fmt: skip
    out = list(charge)
    for b in range(blocks):
        out += block
        if b == 1:
            out.append((57000.0, 0.0, 57000.0))
    return out


def counters_with_dips(truth: Truth, restart_step: int, dips_ah=(13e-6, 1e-6, 2e-6),
                       decimals: int = 6, seed: int = 0):  # fmt: skip
    """Arbin's charge and discharge counters as MITS Pro exports them (``decimals`` places,
    both restarting at ``restart_step``, a new cycle), with the dips a real export shows: in
    each pulse against a counter's direction, from a row inside it on, the counter reads a few
    quanta low (4.685807 then 4.685794 Ah), and recovers at the pulse's end or stays corrected
    (every other dip); and over the pulse's inner rows it dithers by 0-2 quanta."""
    rng = np.random.default_rng(seed)
    restart = np.flatnonzero(truth.step == restart_step)[:1]
    chg, dch = _restart(truth.charged, restart), _restart(truth.discharged, restart)
    starts = np.r_[0, _step_starts(truth.step), truth.t.size]
    n = 0
    for a, b in itertools.pairwise(starts):
        if b - a < 8 or truth.current[a] == 0 or abs(truth.current[a]) < 5:
            continue  # the pulses only
        counter = chg if truth.current[a] < 0 else dch  # the counter not counting
        dip = dips_ah[n % len(dips_ah)]
        k = a + int(rng.integers(2, b - a - 2))
        end = b - 1 if n % 2 == 0 else counter.size  # recovers at the pulse's last row, or not
        counter[k:end] -= dip
        counter[a + 1 : b - 1] -= 10.0**-decimals * rng.integers(0, 3, b - a - 2)
        n += 1
    return np.round(chg, decimals), np.round(dch, decimals)


def write_maccor(truth: Truth, path: Path, duplicate_row: int | None = None,
                 unsigned: bool = False) -> Path:  # fmt: skip
    """``unsigned``: the current as |I| with a mode column ``MD`` (C, D, R) saying which."""
    capacity = _per_step(truth.charged + truth.discharged, truth)
    head = ["Today's Date ,28-Nov-23", "Date of Test:,13-May-24 11:19:51 AM",
            "Rec,Cycle C,Step,Test Time (sec),Step Time (sec),Capacity,Energy,Current,Voltage,"
            "DPT Time,Temp 1,MD"]  # fmt: skip
    current = np.abs(truth.channel) if unsigned else truth.channel
    rows = [[k + 1, 1, int(truth.step[k]), f"{truth.t[k]:.4f}", "0", f"{capacity[k]:.12g}", 0,
             f"{current[k]:.9g}", f"{truth.voltage[k]:.9g}",
             _stamp(truth, k, "%d-%b-%y %I:%M:%S %p"), f"{truth.temperature[k]:.4f}",
             _kind(truth.current[k], "R", "C", "D")]
            for k in range(truth.t.size)]  # fmt: skip
    if duplicate_row is not None:  # the logger writes an instant twice; the later row is kept
        rows.insert(duplicate_row + 1, rows[duplicate_row])
    return _write(path, head, rows)


def write_neware(truth: Truth, path: Path) -> Path:
    chg = _per_step(truth.charged, truth) * 1e3
    dch = _per_step(truth.discharged, truth) * 1e3
    head = ["DataPoint,Cycle Index,Step Index,Step Type,Time,Current(mA),Voltage(V),"
            "Chg. Cap.(mAh),DChg. Cap.(mAh),Date,T1(℃)"]  # fmt: skip
    rows = [[k + 1, 1, int(truth.step[k]), _kind(truth.current[k], "Rest", "CC Chg", "CC DChg"),
             "00:00:00", f"{truth.channel[k] * 1e3:.9g}", f"{truth.voltage[k]:.9g}",
             f"{chg[k]:.12g}", f"{dch[k]:.12g}", _stamp(truth, k, "%Y-%m-%d %H:%M:%S.%f")[:-3],
             f"{truth.temperature[k]:.3f}"]
            for k in range(truth.t.size)]  # fmt: skip
    return _write(path, head, rows)


def write_biologic(truth: Truth, path: Path) -> Path:
    direction = np.sign(truth.current)
    changes = []
    last = 0
    for k in range(truth.t.size):
        if direction[k] != 0 and direction[k] != last:
            if last != 0:
                changes.append(k)
            last = direction[k]
    chg = _restart(truth.charged, np.array(changes, dtype=int)) * 1e3
    dch = _restart(truth.discharged, np.array(changes, dtype=int)) * 1e3
    head = ["EC-Lab ASCII FILE", "Nb header lines : 4",
            "Acquisition started on : 05/13/2024 11:19:51.000",
            "mode\tox/red\ttime/s\tEcell/V\tI/mA\tNs\tQ charge/mA.h\tQ discharge/mA.h\t"
            "Temperature/°C"]  # fmt: skip
    rows = [[1, int(truth.current[k] > 0), f"{truth.t[k]:.6E}", f"{truth.voltage[k]:.9E}",
             f"{truth.channel[k] * 1e3:.9E}", int(truth.step[k]) - 1, f"{chg[k]:.12E}",
             f"{dch[k]:.12E}", f"{truth.temperature[k]:.6E}"]
            for k in range(truth.t.size)]  # fmt: skip
    return _write(path, head, rows, "\t", "iso-8859-1")


def write_basytec(truth: Truth, path: Path) -> Path:
    head = ["~Resultfile from Basytec Battery Test System", "~Name of Test: fixture",
            "~Start of Test: 13.05.2024 11:19:51", "~",
            "~Time[s]\tDataSet\tLine\tCommand\tU[V]\tI[A]\tAh[Ah]\tT1[°C]"]  # fmt: skip
    net = truth.charged - truth.discharged
    rows = [[f"{truth.t[k]:.6f}", k + 1, int(truth.step[k]),
             _kind(truth.current[k], "Pause", "Charge", "Discharge"), f"{truth.voltage[k]:.9g}",
             f"{truth.channel[k]:.9g}", f"{net[k]:.12g}", f"{truth.temperature[k]:.4f}"]
            for k in range(truth.t.size)]  # fmt: skip
    return _write(path, head, rows, "\t")


WRITERS = {
    "arbin": (write_arbin, ".csv"),
    "maccor": (write_maccor, ".csv"),
    "neware": (write_neware, ".csv"),
    "biologic": (write_biologic, ".txt"),
    "basytec": (write_basytec, ".txt"),
}


def export(cycler: str, folder: Path, truth: Truth | None = None, **kw) -> tuple[Path, Truth]:
    truth = simulate() if truth is None else truth
    writer, ext = WRITERS[cycler]
    return writer(truth, Path(folder) / f"{cycler}{ext}", **kw), truth


def cli_error(tmp_path: Path, capsys, raw, name: str, word: str) -> str:
    """``convert RAW --cycler NAME`` refused: exit 2, one stderr line naming the file and
    ``word``, nothing written; returns the line."""
    from avoa_pipeline.cli import main

    out = tmp_path / "out" / "x.csv"
    assert main(["convert", str(raw), "--cycler", name, "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1, err
    assert str(raw) in err, err
    assert word in err, err
    assert not out.parent.exists() or not any(out.parent.iterdir())
    return err
