"""Raw cycler exports (Arbin, Maccor, Neware, BioLogic, Basytec) → the record ``diagnose`` reads.

**Reading is PyProBE's.** ``pyprobe-data`` (Imperial College London, BSD-3-Clause) reads the five
cyclers' exports into one column set, with their header lines, time columns and unit prefixes.
A cycler may have several column layouts (Arbin: the newer ``Test Time (s)`` one PyProBE maps,
and MITS Pro's classic ``Test_Time(s)`` one that most public Arbin datasets use); the others come
in through PyProBE's own extra column importers, and a workbook's data sheet is found by name.
It was chosen over cellpy (its current release pins pandas < 3, which this environment has
passed) and battery-data-toolkit (no Neware or Basytec reader). This module uses its cycler
classes and their column maps, and adds the raw charge counters as extra column importers (its
own ``extra_column_importers`` option).

**What is ours** is what a diagnosis needs beyond a column set, each a way to get a silently wrong
answer (docs/cyclers.md):

- *Header checks*: a file whose columns do not match the declared cycler, a missing current,
  voltage, time or step column, an unknown unit, or one quantity in two units (``Current (A)``
  beside ``Current (mA)``) is a one-line DataError naming the file and the column. PyProBE would
  take the first match of a wildcard, in set order.
- *Current from the charge counters*: the mean current over each interval [t_k, t_k+1) (the
  model's zero-order hold: row k's current is held until row k+1), ΔQ/Δt of the cell's net charge.
  The counters do not lag at pulse edges as a filtered current channel does, and charge is
  conserved by construction. Counters that restart (per step, per cycle) are handled: a drop
  means the counter restarted during the interval, so the interval's charge is the new value.
  (PyProBE's own ``Capacity [Ah]`` clips such a drop to zero and loses that charge.) Without
  counters, or with ``current_from="channel"``, each sample of the channel is held.
- *Sign*: every supported cycler writes charge as positive; the output has discharge positive.
  The convention is confirmed against the voltage's answer to the current channel
  (``records.sign_evidence``, the one sign check of the package), and for cyclers with
  direction-named counters the channel's sign against theirs. A contradiction is an error, a
  record whose voltage cannot tell a warning.
- *Units*: PyProBE converts prefixes (mA, mV, mAh, mA.h, ...). The counters' current and the
  channel's must agree within a factor of √1000: unit mistakes are factors of 1000 (a prefix) or
  3600 (A·s for Ah); lag and counter resolution are far below that.
- *Voltage and temperature are never interpolated*: the output keeps the cycler's own samples.
  A repeated time stamp (a step's last row and the next step's first) keeps the later row.
- *Rests*: optionally thinned (``rest_dt``), keeping existing samples only, at 10 per decade of
  the time since the rest began (the usual density for relaxation and impedance data), at most
  ``rest_dt`` apart; the step's first and last rows stay. The counters carry the charge over
  the merged intervals.
- *Steps*: optionally one contiguous range of the cycler's step numbers (``steps=(a, b)``); every
  step occurrence, kept or dropped, is listed in the sidecar.
"""

from __future__ import annotations

import contextlib
import importlib
import json
import math
import tempfile
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from .. import records
from ..errors import DataError, UserError
from ..io import atomic_path, sha256
from ..names import CURRENT_FROM

CONVENTION = "charge-positive"  # what every supported cycler writes (docs/cyclers.md)
UNIT_FACTOR_LIMIT = math.sqrt(1000.0)  # counters' vs channel's current; a unit slip is ≥ 1000×
REST_POINTS_PER_DECADE = 10


@dataclass(frozen=True)
class Counters:
    """Charge counters of an export, as PyProBE column patterns.

    ``kind``: ``pair`` = a charge and a discharge counter, each unsigned and counting up, either
    may restart (per step or cycle); ``step`` = one unsigned counter restarting at every step,
    its direction the current's; ``signed`` = one running counter, charge positive.
    """

    kind: str
    columns: tuple[str, ...]


@dataclass(frozen=True)
class Layout:
    """One way a cycler's software names its columns, as PyProBE column patterns (one ``*`` = the
    unit); the first present of each tuple is used. A cycler's first layout is the one PyProBE's
    reader maps itself; the others come in as extra column importers."""

    name: str
    time: tuple[str, ...]
    current: tuple[str, ...]
    voltage: tuple[str, ...]
    step: tuple[str, ...]
    counters: tuple[Counters, ...]  # alternatives, the first whose columns are all present
    temperature: tuple[str, ...]
    mode: tuple[str, ...] = ()  # a charge/discharge mode column that signs an unsigned current


@dataclass(frozen=True)
class Cycler:
    name: str
    reader: str  # module:class of pyprobe
    layouts: tuple[Layout, ...]
    extensions: tuple[str, ...]

    @property
    def label(self) -> str:
        return {"biologic": "BioLogic"}.get(self.name, self.name.capitalize())

    @property
    def article(self) -> str:
        return "an" if self.label[0] in "AEIOU" else "a"


CYCLERS = {
    c.name: c
    for c in (
        Cycler(
            "arbin",
            "pyprobe.cyclers.arbin:Arbin",
            (
                Layout(
                    "MITS Pro, newer export",
                    ("Test Time (*)",),
                    ("Current (*)",),
                    ("Voltage (*)",),
                    ("Step Index",),
                    (Counters("pair", ("Charge Capacity (*)", "Discharge Capacity (*)")),),
                    ("Aux_Temperature_1 (*)",),
                ),
                Layout(
                    "MITS Pro, classic export",
                    ("Test_Time(*)",),
                    ("Current(*)",),
                    ("Voltage(*)",),
                    ("Step_Index",),
                    (Counters("pair", ("Charge_Capacity(*)", "Discharge_Capacity(*)")),),
                    ("Aux_Temperature_1(*)", "Temperature(*)"),
                ),
            ),
            (".csv", ".xlsx"),
        ),
        Cycler(
            "maccor",
            "pyprobe.cyclers.maccor:Maccor",
            (
                Layout(
                    "Maccor export",
                    ("Test Time (sec)",),
                    ("Current",),
                    ("Voltage",),
                    ("Step",),
                    (Counters("step", ("Capacity",)),),
                    ("Temp 1",),
                    ("MD",),
                ),
            ),
            (".csv", ".txt"),
        ),
        Cycler(
            "neware",
            "pyprobe.cyclers.neware:Neware",
            (
                Layout(
                    "Neware export",
                    ("Date", "Total Time"),
                    ("Current(*)",),
                    ("Voltage(*)",),
                    ("Step Index",),
                    (
                        Counters("pair", ("Chg. Cap.(*)", "DChg. Cap.(*)")),
                        Counters("step", ("Capacity(*)",)),
                    ),
                    ("T1(*)",),
                ),
            ),
            (".csv", ".xlsx"),
        ),
        Cycler(
            "biologic",
            "pyprobe.cyclers.biologic:Biologic",
            (
                Layout(
                    "EC-Lab text export",
                    ("time/*",),
                    ("I/*", "<I>/*"),
                    ("Ecell/*", "Ewe/*"),
                    ("Ns",),
                    (
                        Counters("pair", ("Q charge/*", "Q discharge/*")),
                        Counters("signed", ("(Q-Qo)/*",)),
                    ),
                    ("Temperature/*",),
                ),
            ),
            (".txt", ".mpt", ".csv"),
        ),
        Cycler(
            "basytec",
            "pyprobe.cyclers.basytec:Basytec",
            (
                Layout(
                    "Basytec result file",
                    ("~Time[*]",),
                    ("I[*]",),
                    ("U[*]",),
                    ("Line",),
                    (Counters("signed", ("Ah[*]",)),),
                    ("T1[*]",),
                ),
            ),
            (".txt", ".csv"),
        ),
    )
}


# ----------------------------------------------------------------------------------------------
# header


def _matches(pattern: str, columns: list[str]) -> list[tuple[str, str]]:
    """(column, unit) of every column matching a PyProBE pattern (one ``*`` = the unit)."""
    if "*" not in pattern:
        return [(pattern, "")] if pattern in columns else []
    prefix, suffix = pattern.split("*")
    return [
        (c, c[len(prefix) : len(c) - len(suffix)])
        for c in columns
        if c.startswith(prefix) and c.endswith(suffix) and len(c) > len(prefix) + len(suffix) - 1
    ]


def _find(path, what: str, patterns: tuple[str, ...], columns: list[str],
          required: bool = True) -> tuple[str, str, str] | None:  # fmt: skip
    """(column, unit, pattern) of a quantity's one column: DataError if missing (required), in
    two units, or in a unit PyProBE does not know."""
    valid_units = _pyprobe("pyprobe.units").valid_units

    for pattern in patterns:
        found = _matches(pattern, columns)
        if not found:
            continue
        if "*" in pattern and what != "temperature":
            bad = [(c, u) for c, u in found if u not in valid_units]
            if bad:
                c, u = bad[0]
                raise DataError(f"{path}: column {c!r}: unit {u!r} not recognised")
        units = {u for _, u in found}
        if len(found) > 1:
            names = ", ".join(repr(c) for c, _ in found)
            kind = "mixed units" if len(units) > 1 else "repeated column"
            raise DataError(f"{path}: columns {names}: {kind} for the {what}")
        return (*found[0], pattern)
    if not required:
        return None
    want = " or ".join(repr(p.replace("*", "<unit>")) for p in patterns)
    raise DataError(f"{path}: no {what} column {want}")


def _layout(path, cycler: Cycler, columns: list[str]) -> Layout:
    """The layout whose time column the export has; DataError naming every layout's."""
    for layout in cycler.layouts:
        if any(_matches(p, columns) for p in layout.time):
            return layout
    want = " or ".join(
        f"{' or '.join(repr(p.replace('*', '<unit>')) for p in lay.time)} ({lay.name})"
        for lay in cycler.layouts
    )
    hint = _looks_like(path, cycler.name)
    raise DataError(
        f"{path}: no time column {want}; not {cycler.article} {cycler.label} export"
        + (f" (it reads as --cycler {hint})" if hint else "")
    )


def _looks_like(path, declared: str) -> str:
    """The other cycler whose reader finds the time, current, voltage and step columns of one of
    its layouts."""
    for name, other in CYCLERS.items():
        if name == declared or Path(path).suffix.lower() not in other.extensions:
            continue
        try:
            with _quiet_pyprobe():
                columns = list(_reader(other).read_file(str(path)).collect_schema().names())
        except Exception:  # not this one either
            continue
        for lay in other.layouts:
            quantities = (lay.time, lay.current, lay.voltage, lay.step)
            if all(any(_matches(p, columns) for p in pats) for pats in quantities):
                return name
    return ""


def _pyprobe(module: str):
    """A pyprobe module. Its import warns of pydantic's class-based config (pyprobe's own code,
    pydantic 2.x); that warning is silenced here, no other."""
    with warnings.catch_warnings():
        warnings.filterwarnings(
            "ignore", "Support for class-based `config` is deprecated", DeprecationWarning
        )
        try:
            return importlib.import_module(module)
        except ModuleNotFoundError as exc:
            if not (exc.name or "").startswith("pyprobe"):
                raise
            raise UserError(
                "reading cycler exports needs pyprobe-data: pip install 'avoa-pipeline[cyclers]' "
                "(scripts/setup.sh installs it)"
            ) from None


_READERS: dict = {}


def _reader(cycler: Cycler):
    """PyProBE's reader class of a cycler, extended to read a workbook's data sheet: Arbin's
    MITS Pro writes ``Global_Info`` first and the rows in ``Channel_<n>-<m>`` sheets, while
    PyProBE reads the first sheet of an .xlsx (and, in 2.6.1, cannot finish reading one)."""
    module, name = cycler.reader.split(":")
    base = getattr(_pyprobe(module), name)
    if base not in _READERS:

        def read_file(filepath, header_row_index: int = 0):
            if not str(filepath).lower().endswith(".xlsx"):
                return base.read_file(filepath, header_row_index)
            import fastexcel
            import polars as pl

            sheets = fastexcel.read_excel(str(filepath)).sheet_names
            data = next((n for n in sheets if n.lower().startswith("channel")), sheets[0])
            # numbers as numbers (PyProBE reads every cell as text, which keeps 9 digits: a
            # counter then loses 1e-10 Ah, 0.16 mA over a 10-ms interval), the types inferred
            # from every row; lazy, as PyProBE's CSV path (its own .xlsx path, in 2.6.1, returns
            # a DataFrame that its reader then fails to .collect())
            return pl.read_excel(filepath, sheet_name=data, engine="calamine",
                                 infer_schema_length=None,
                                 read_options={"header_row": header_row_index}).lazy()  # fmt: skip

        _READERS[base] = type(name, (base,), {"read_file": staticmethod(read_file)})
    return _READERS[base]


def _first_line(exc: BaseException) -> str:
    text = str(exc).strip()
    return text.splitlines()[0] if text else type(exc).__name__


@contextlib.contextmanager
def _quiet_pyprobe():
    from loguru import logger

    logger.disable("pyprobe")  # our messages name the file and column; its log lines do not
    try:
        yield
    finally:
        logger.enable("pyprobe")


# ----------------------------------------------------------------------------------------------
# reading


def read_columns(path: str | Path, cycler_name: str) -> tuple[dict[str, np.ndarray], dict]:
    """The export's time (s), step, channel current (A, cycler sign), voltage (V), counters
    (Ah) and temperature (°C) as arrays, and which raw column each came from."""
    if cycler_name not in CYCLERS:
        raise UserError(f"unknown cycler {cycler_name!r}; choose from {', '.join(CYCLERS)}")
    cycler = CYCLERS[cycler_name]
    path = Path(path)
    if not path.is_file():
        raise DataError(f"{path}: no such file")
    if path.suffix.lower() not in cycler.extensions:
        raise DataError(
            f"{path}: {cycler.article} {cycler.label} export is {' or '.join(cycler.extensions)}, "
            f"not {path.suffix or 'without extension'!r}"
        )
    cls = _reader(cycler)
    with _quiet_pyprobe():
        try:
            columns = [str(c) for c in cls.read_file(str(path)).collect_schema().names()]
        except Exception as exc:  # any reader failure is a file that is not this cycler's
            raise DataError(
                f"{path}: not readable as {cycler.article} {cycler.label} export "
                f"({_first_line(exc)})"
            ) from None
    layout = _layout(path, cycler, columns)
    used = {
        "time": _find(path, "time", layout.time, columns),
        "current": _find(path, "current", layout.current, columns),
        "voltage": _find(path, "voltage", layout.voltage, columns),
        "step": _find(path, "step", layout.step, columns),
        "temperature": _find(path, "temperature", layout.temperature, columns, False),
    }
    counters = None
    for option in layout.counters:
        found = [_find(path, "charge counter", (p,), columns, False) for p in option.columns]
        if all(found):
            counters = (option, found)
            break
    mode = _find(path, "mode", layout.mode, columns, False) if layout.mode else None
    own = layout is cycler.layouts[0]  # PyProBE maps its own layout; the others we add
    frame = _import(path, cls, used, counters, mode, own)
    arrays = {
        "time": frame["time"],
        "step": frame["step"],
        "current": frame["current"],
        "voltage": frame["voltage"],
    }
    if "temperature" in frame:
        arrays["temperature"] = frame["temperature"]
    info = {q: {"column": c[0], "unit": c[1]} for q, c in used.items() if c is not None}
    info["layout"] = layout.name
    if mode is not None:
        arrays["current"], info["current"]["signed_by"] = _signed(path, frame, used, mode[0])
    if counters is not None:
        option, found = counters
        arrays["counters"] = [frame[f"counter{j}"] for j in range(len(found))]
        info["counters"] = {
            "kind": option.kind,
            "columns": [{"column": c, "unit": u} for c, u, _ in found],
        }
    return arrays, info


def _signed(path, frame: dict, used: dict, mode_column: str) -> tuple[np.ndarray, str]:
    """Maccor's current signed by its mode column where the export writes it unsigned (``D``
    discharge, ``C`` charge, anything else a rest or a pause): charge positive."""
    current, mode = frame["current"], np.char.strip(frame["mode"].astype(str))
    if (current < 0).any():
        return current, f"the current itself (column {mode_column!r} not needed)"
    discharge = np.char.startswith(np.char.upper(mode), "D")
    if not discharge.any():
        return current, f"the current itself (column {mode_column!r} has no discharge)"
    return np.where(discharge, -np.abs(current), np.abs(current)), (
        f"column {mode_column!r} (the export's {used['current'][0]!r} is unsigned): D = discharge"
    )


def _import(path, cls, used: dict, counters, mode=None, own: bool = True) -> dict[str, np.ndarray]:
    """PyProBE's frame of the export, with the raw counters (and a mode column, and for a layout
    PyProBE does not know its time, current, voltage, step and temperature) added as extra
    importers."""
    import polars as pl

    column_maps = _pyprobe("pyprobe.cyclers.column_maps")

    extra = []
    if not own:
        extra += [
            column_maps.ConvertUnitsMap(name, used[q][2])
            for q, name in (
                ("time", "Time [s]"),
                ("current", "Current [A]"),
                ("voltage", "Voltage [V]"),
            )
        ]
        extra.append(column_maps.CastAndRenameMap("Step", used["step"][0], pl.UInt64))
        if used["temperature"] is not None:
            extra.append(column_maps.ConvertTemperatureMap(used["temperature"][2]))
    if mode is not None:
        extra.append(column_maps.CastAndRenameMap("mode", mode[0], pl.Utf8))
    if counters is not None:
        _, found = counters
        for j, (column, unit, pattern) in enumerate(found):
            if unit:
                extra.append(column_maps.ConvertUnitsMap(f"counter{j}", pattern))
            else:  # Maccor: no unit in the header; its exports are in Ah
                extra.append(column_maps.CastAndRenameMap(f"counter{j}", column, pl.Float64))
    with _quiet_pyprobe(), tempfile.TemporaryDirectory() as tmp:
        try:
            reader = cls(
                input_data_path=str(path),
                output_data_path=str(Path(tmp) / "unused.parquet"),
                overwrite_existing=True,
                extra_column_importers=extra,
            )
            df = reader.get_pyprobe_dataframe()
        except Exception as exc:  # a value PyProBE cannot cast or parse
            raise DataError(f"{path}: {_first_line(exc)}") from None
    names = {
        "time": "Time [s]",
        "step": "Step",
        "current": "Current [A]",
        "voltage": "Voltage [V]",
        "temperature": "Temperature [C]",
    }
    out = {}
    for key, name in names.items():
        if name in df.columns and (key != "temperature" or used["temperature"] is not None):
            out[key] = df[name].cast(pl.Float64, strict=False).to_numpy()
    for key in ("time", "step", "current", "voltage"):
        if key not in out:  # PyProBE's map failed although the header matched
            raise DataError(f"{path}: column {used[key][0]!r}: could not be read")
    if counters is not None:
        for j in range(len(counters[1])):
            out[f"counter{j}"] = df[f"counter{j}"].cast(pl.Float64, strict=False).to_numpy()
    modes = df["mode"].fill_null("").to_numpy() if mode is not None else None
    if "temperature" in out and not np.isfinite(out["temperature"]).any():
        del out["temperature"]  # a temperature column the channel never filled
    for key, values in out.items():
        bad = ~np.isfinite(values)
        if bad.any():
            row = int(np.flatnonzero(bad)[0])
            column = used[key][0] if key in used else counters[1][int(key[-1])][0]
            raise DataError(
                f"{path}: column {column!r} data row {row + 1}: missing or not a number"
            )
    if modes is not None:
        out["mode"] = modes
    return out


# ----------------------------------------------------------------------------------------------
# counters


def _resolution(c: np.ndarray) -> float:
    """The counter's quantum: its smallest positive change (0 if it never changes)."""
    d = np.abs(np.diff(c))
    d = d[d > 0]
    return float(d.min()) if d.size else 0.0


def _increments(c: np.ndarray) -> tuple[np.ndarray, int]:
    """Per-interval count of an unsigned counter that may restart: a drop (by more than its
    quantum) means it restarted during the interval, which then counted the new value."""
    d = np.diff(c)
    restart = d < -max(_resolution(c), 1e-12)
    return np.where(restart, c[1:], d), int(restart.sum())


def net_charge(arrays: dict, kind: str) -> tuple[np.ndarray, dict]:
    """Cumulative charge into the cell (Ah, charge positive) at each row, from the counters."""
    cs = arrays["counters"]
    if kind == "pair":
        up, r1 = _increments(cs[0])
        down, r2 = _increments(cs[1])
        inc, restarts = up - down, r1 + r2
    elif kind == "step":
        count, restarts = _increments(cs[0])
        inc = count * np.sign(arrays["current"][1:])  # the direction of the interval's step
    else:  # signed
        inc, restarts = np.diff(cs[0]), 0
    q = np.concatenate([[0.0], np.cumsum(inc)])
    return q, {"restarts": restarts, "resolution_ah": [_resolution(c) for c in cs]}


# ----------------------------------------------------------------------------------------------
# the record


def _events(step: np.ndarray) -> np.ndarray:
    """Step occurrence index per row (a new one at each change of the step number)."""
    return np.concatenate([[0], np.cumsum(np.diff(step) != 0)])


def _steps_table(t, step, events, current, kept: np.ndarray) -> list[dict]:
    """One row per step occurrence (events are runs of consecutive rows)."""
    starts = np.r_[0, np.flatnonzero(np.diff(events)) + 1]
    ends = np.r_[starts[1:], events.size] - 1
    means = np.add.reduceat(current, starts) / (ends - starts + 1)
    return [
        {
            "step": int(step[a]),
            "start_s": float(t[a] - t[0]),
            "duration_s": float(t[b] - t[a]),
            "samples": int(b - a + 1),
            "mean_channel_current_a": float(m),
            "kept": bool(kept[a]),
        }
        for a, b, m in zip(starts, ends, means, strict=True)
    ]


def _step_range(path, step: np.ndarray, steps: tuple[int, int] | None, column: str) -> np.ndarray:
    keep = np.ones(step.size, dtype=bool)
    if steps is None:
        return keep
    a, b = steps
    first = np.flatnonzero(step == a)
    last = np.flatnonzero(step == b)
    if not first.size or not last.size:
        missing = a if not first.size else b
        raise DataError(f"{path}: column {column!r}: no step {missing} (--steps {a}-{b})")
    if last[-1] < first[0]:
        raise DataError(f"{path}: column {column!r}: step {b} ends before step {a} starts")
    keep[:] = False
    keep[first[0] : last[-1] + 1] = True
    return keep


def _thin_rests(t: np.ndarray, events: np.ndarray, rest_event: np.ndarray, rest_dt: float):
    """Keep mask: inside each rest step, rows at 10 per decade of the time since it began and
    at most ``rest_dt`` apart; a step's first and last rows always."""
    keep = np.ones(t.size, dtype=bool)
    growth = 10.0 ** (1.0 / REST_POINTS_PER_DECADE) - 1.0
    for e in np.flatnonzero(rest_event):  # events are non-decreasing: each a run of rows
        a, b = np.searchsorted(events, e, "left"), np.searchsorted(events, e, "right")
        start, last_kept = t[a], t[a]
        for k in range(a + 1, b - 1):
            if t[k] - last_kept >= min(rest_dt, growth * (t[k] - start)):
                last_kept = t[k]
            else:
                keep[k] = False
    return keep


def convert(
    path: str | Path,
    cycler_name: str,
    *,
    steps: tuple[int, int] | None = None,
    rest_dt: float | None = None,
    current_from: str = "counters",
) -> tuple[pd.DataFrame, dict]:
    """The canonical record of a raw export (time_s, current_a discharge-positive, voltage_v
    [, temperature_c]) and its sidecar dict. One-line DataError/UserError on bad input."""
    if current_from not in CURRENT_FROM:
        raise UserError(f"--current-from must be one of {', '.join(CURRENT_FROM)}")
    if rest_dt is not None and not (np.isfinite(rest_dt) and rest_dt > 0):
        raise UserError(f"--rest-dt must be a positive number of seconds, got {rest_dt}")
    path = Path(path)
    arrays, columns = read_columns(path, cycler_name)
    cycler = CYCLERS[cycler_name]
    t, step, i_ch, v = (arrays[k] for k in ("time", "step", "current", "voltage"))
    name = {q: columns[q]["column"] for q in ("time", "current", "voltage", "step")}
    if t.size < 2:
        raise DataError(f"{path}: {t.size} data rows; need at least 2")

    # net charge at every raw row (before rows are dropped, so no interval's charge is lost)
    have_counters = "counters" in arrays
    if have_counters:
        q, counter_info = net_charge(arrays, columns["counters"]["kind"])
    use_counters = have_counters and current_from == "counters"

    # repeated time stamps: the later row stays; time going backwards is an error
    dt = np.diff(t)
    if (dt < 0).any():
        k = int(np.flatnonzero(dt < 0)[0]) + 1
        raise DataError(f"{path}: column {name['time']!r} data row {k + 1}: time goes backwards")
    unique = np.append(dt > 0, True)
    keep_steps = _step_range(path, step, steps, name["step"])
    events = _events(step)
    rows = unique & keep_steps
    if rows.sum() < 2:
        raise DataError(f"{path}: fewer than 2 rows left after the step selection")

    # interval currents (charge positive) on the rows kept: ΔQ/Δt, or the channel held (over
    # rest rows merged by thinning, the first row's reading: a rest)
    def intervals(idx):
        return np.diff(q[idx]) * 3600.0 / np.diff(t[idx]) if use_counters else i_ch[idx][:-1]

    idx = np.flatnonzero(rows)
    interval = intervals(idx)
    i99 = float(np.quantile(np.abs(interval), 0.99))

    # rests thinned (existing samples only)
    rest_rows = 0
    if rest_dt is not None:
        ev = events[idx]
        load = np.zeros(int(ev[-1]) + 1, dtype=bool)
        inside = ev[:-1] == ev[1:]  # an interval into the next step carries that step's current
        busy = np.abs(interval) > records.REST_FRACTION * max(i99, 1e-12)
        np.logical_or.at(load, ev[:-1][inside], busy[inside])
        present = np.zeros_like(load)
        present[ev] = True
        thin = _thin_rests(t[idx], ev, present & ~load, rest_dt)
        rest_rows = int((~thin).sum())
        idx = idx[thin]
        interval = intervals(idx)
    tk = t[idx]

    current_cp = np.append(interval, i_ch[idx[-1]])  # the last row: its channel reading
    out = pd.DataFrame({"time_s": tk - tk[0], "current_a": 0.0 - current_cp, "voltage_v": v[idx]})
    if "temperature" in arrays:
        out["temperature_c"] = arrays["temperature"][idx]

    # the counters against the channel: units, sign, lag
    sign_agreement, agreement = None, None
    if have_counters:
        sign_agreement, agreement = _agreement(
            path, q, t, i_ch, step, unique & keep_steps, columns, records.STEP_FRACTION
        )

    # the scale of one cell, the records layer's limits, named by the raw columns
    records.check_scale(out, str(path), names={"time_s": name["time"], "current_a": name["current"],
                                               "voltage_v": name["voltage"]})  # fmt: skip

    # the sign, from the voltage's answer to the channel: its reading is the current at the
    # voltage's instant (the interval means of a coarse or stalled counter are checked again
    # when the written record is read)
    ev = records.sign_evidence(out["time_s"], -i_ch[idx], out["voltage_v"])
    if ev.contradicts:
        raise DataError(
            f"{path}: column {name['current']!r}: the voltage falls when the {cycler.label} "
            f"current rises (negated to discharge positive: {ev.describe()}): "
            f"the export is not {CONVENTION} as {cycler.label} writes it"
        )

    notes = []
    if ev.verdict == records.CANNOT_TELL:
        notes.append(f"{path}: column {name['current']!r}: the voltage does not tell the "
                     f"current's sign ({ev.describe()}); {cycler.label}'s {CONVENTION} "
                     "convention is taken as it is")  # fmt: skip
    if use_counters and agreement and "rms_difference_steady_a" in agreement:
        rms, scale = agreement["rms_difference_steady_a"], agreement["current_scale_a"]
        if rms > records.REST_FRACTION * scale:
            q_ah = ", ".join(f"{x:.3g}" for x in counter_info["resolution_ah"])
            notes.append(
                f"{path}: the charge counters and column {name['current']!r} differ by "
                f"{rms:.3g} A RMS on steady intervals, over {records.REST_FRACTION:.0%} of the "
                f"99th-percentile |I| (the line between rest and load); the counters step by "
                f"{q_ah} Ah. Export them with more digits, or use --current-from channel"
            )

    kept = np.zeros(t.size, dtype=bool)
    kept[np.flatnonzero(rows)] = True
    table = _steps_table(t, step, events, i_ch, kept)
    charge_out = float(np.sum(out["current_a"].to_numpy()[:-1] * np.diff(tk))) / 3600.0
    info = {
        "source_file": str(path),
        "source_sha256": sha256(path),
        "cycler": cycler_name,
        "reader": f"pyprobe-data {_pyprobe_version()} ({cycler.reader.split(':')[1]})",
        "columns": columns,
        "sign": {
            "cycler_convention": CONVENTION,
            "output": "discharge-positive",
            "voltage_check": {**ev.as_dict(), "confirmed": ev.verdict == records.SIGNS[0]},
            "counters_vs_channel": sign_agreement,
        },
        "current": {
            "source": "charge counters" if use_counters else "current channel (held)",
            "hold": "zero-order: row k's current is the mean over [t_k, t_k+1); the last row "
            "has its channel reading",
            **({"counters": counter_info} if have_counters else {}),
            **({"counters_vs_channel": agreement} if agreement else {}),
        },
        "charge": {
            "discharged_ah_output": charge_out,
            **({"discharged_ah_counters": -float(q[idx[-1]] - q[idx[0]])} if have_counters else {}),
        },
        "rows": {
            "raw": int(t.size),
            "repeated_time_dropped": int((~unique).sum()),
            "outside_steps_dropped": int((unique & ~keep_steps).sum()),
            "rest_thinned": rest_rows,
            "written": int(idx.size),
        },
        "steps": {
            "selection": f"{steps[0]}-{steps[1]}" if steps else "all",
            "kept": [s for s in table if s["kept"]],
            "dropped": [s for s in table if not s["kept"]],
        },
        "warnings": notes,
        "resampling": (
            "none: the cycler's own samples; voltage and temperature never interpolated"
            if rest_dt is None
            else f"rests thinned to {REST_POINTS_PER_DECADE} samples per decade of rest time, "
            f"at most {rest_dt:g} s apart (existing samples kept, none interpolated)"
        ),
    }
    return out, info


def _agreement(path, q, t, i_ch, step, rows, columns, step_fraction) -> tuple[dict | None, dict]:
    """The counters' interval current against the channel's over the rows kept: the units (a
    factor of √1000 at most), the sign (direction-named counters), the lag at step edges.
    Returns (sign agreement or None without steady intervals, the rest for the sidecar)."""
    idx = np.flatnonzero(rows)
    tk, qk, ik, sk = t[idx], q[idx], i_ch[idx], step[idx]
    counted = np.diff(qk) * 3600.0 / np.diff(tk)
    channel = 0.5 * (ik[:-1] + ik[1:])  # the channel's trapezoid mean over the interval
    same = sk[:-1] == sk[1:]
    steady = same & np.r_[False, same[:-1]] & np.r_[same[1:], False]
    i99 = max(float(np.quantile(np.abs(ik), 0.99)), 1e-12)
    big = np.abs(channel) >= step_fraction * i99
    sel = steady & big
    counter_cols = ", ".join(repr(c["column"]) for c in columns["counters"]["columns"])
    current_col = columns["current"]["column"]
    out = {"steady_intervals": int(sel.sum()), "current_scale_a": i99}
    if sel.sum():
        ratio = np.median(np.abs(counted[sel]) / np.abs(channel[sel]))
        if not (1.0 / UNIT_FACTOR_LIMIT <= ratio <= UNIT_FACTOR_LIMIT):
            raise DataError(
                f"{path}: columns {current_col!r} and {counter_cols}: mixed units (the counters' "
                f"current is {ratio:.4g} times the channel's)"
            )
        out["median_ratio"] = float(ratio)
        out["rms_difference_steady_a"] = float(np.sqrt(np.mean((counted - channel)[sel] ** 2)))
        agree = float(np.mean(np.sign(counted[sel]) == np.sign(channel[sel])))
        sign = {"share_of_steady_intervals_agreeing": agree}
        if columns["counters"]["kind"] == "pair" and agree < 0.5:
            raise DataError(
                f"{path}: column {current_col!r}: its sign is opposite to the counters "
                f"{counter_cols} in {1 - agree:.0%} of steady intervals: the export is not "
                f"{CONVENTION}"
            )
    else:
        sign = None
    edges = ~same
    if edges.any():
        held = ik[:-1][edges]
        out["rms_difference_step_edges_a"] = float(np.sqrt(np.mean((counted[edges] - held) ** 2)))
        out["step_edge_intervals"] = int(edges.sum())
    return sign, out


def _pyprobe_version() -> str:
    from importlib.metadata import version

    return version("pyprobe-data")


def parse_steps(text: str | None) -> tuple[int, int] | None:
    """``--steps A-B`` (or one step ``A``) → (A, B)."""
    if text is None:
        return None
    parts = text.split("-")
    try:
        a, b = (int(parts[0]), int(parts[-1])) if len(parts) in (1, 2) else (None, None)
    except ValueError:
        a = None
    if a is None:
        raise UserError(f"--steps must be A-B (step numbers), got {text!r}")
    return a, b


def write(frame: pd.DataFrame, info: dict, out: str | Path) -> Path:
    """The CSV and its JSON sidecar (same stem), both or neither."""
    out = Path(out)
    if out.suffix.lower() != ".csv":
        raise UserError(f"--out must be a .csv path, got {str(out)!r}")
    side = out.with_suffix(".json")
    with atomic_path(out) as csv_tmp, atomic_path(side) as js_tmp:
        frame.to_csv(csv_tmp, index=False)
        js_tmp.write_text(json.dumps(info, indent=1, allow_nan=False) + "\n")
    return side
