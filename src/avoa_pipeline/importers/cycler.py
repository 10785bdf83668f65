"""Raw cycler exports (Arbin, Maccor, Neware, BioLogic, Basytec) → the record ``diagnose`` reads.

Binary files (Neware ``.nda``/``.ndax``, BioLogic ``.mpr``, Arbin ``.res``) are read by their own
libraries in :mod:`.binary` into the same columns; everything after reading is this module's.

**Reading is PyProBE's.** ``pyprobe-data`` (Imperial College London, BSD-3-Clause) reads the five
cyclers' exports into one column set, with their header lines, time columns and unit prefixes.
A cycler may have several column layouts (Arbin: the newer ``Test Time (s)`` one PyProBE maps,
and MITS Pro's classic ``Test_Time(s)`` one that most public Arbin datasets use); the others come
in through PyProBE's own extra column importers. A workbook's data sheets are found by their
columns and named; one is read, or each, or all in order (``choose_sheets``, ``_join``), never
silently the first.
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
  conserved by construction. Counters restart (per step, per cycle) and dip: a fall to near
  zero is a restart, the interval's charge the new value; a fall by a few quanta is a dip, a
  negative increment (``RESTART_FRACTION``, ``COUNT_MARGIN``). (PyProBE's own ``Capacity [Ah]``
  clips every drop to zero and loses that charge.) Without counters, or with
  ``current_from="channel"``, each sample of the channel is held.
- *Sign*: every supported cycler writes charge as positive; the output has discharge positive.
  The convention is confirmed against the voltage's answer to the current channel
  (``records.sign_evidence``, the one sign check of the package), and for cyclers with
  direction-named counters the channel's sign against theirs. A contradiction is an error, a
  record whose voltage cannot tell a warning.
- *Units*: PyProBE converts prefixes (mA, mV, mAh, mA.h, ...). The counters' current and the
  channel's must agree within a factor of √1000: unit mistakes are factors of 1000 (a prefix) or
  3600 (A·s for Ah); lag and counter resolution are far below that.
- *Temperature*: each layout's common headers; of several channels the first is used and the
  others named in a warning; K converted, kelvin in a °C column refused by the records layer.
- *Which cycler*: ``sniff`` matches a header against each cycler's columns, so a file given to
  the wrong reader, or without ``--cycler``, is named ("it looks like an Arbin export").
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
import math
import tempfile
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from .. import records
from ..errors import DataError, UserError
from ..io import regular_file, sha256
from ..names import CURRENT_FROM
from . import binary

CONVENTION = "charge-positive"  # what every supported cycler writes (docs/cyclers.md)
UNIT_FACTOR_LIMIT = math.sqrt(1000.0)  # counters' vs channel's current; a unit slip is ≥ 1000×
REST_POINTS_PER_DECADE = 10

RESTART_FRACTION = 0.5
"""A counter has restarted when it falls to at most this fraction of its previous value. A
restart is a reset to zero: the value after it is the charge of part of one logging interval,
while the value before it held a step's or a cycle's count (a 10-s interval of an 18-A pulse is
0.05 Ah against the ampere-hours of a cycle). A dip is a fall by a few quanta (an Arbin charge
counter reads 4.685807 then 4.685794 Ah during a discharge pulse: its offset corrected, or a
reverse trickle counted), a millionth of the value. Half lies orders of magnitude from both.
A dip is kept as a (negative) increment, so it cancels when the counter recovers; taking it for
a restart would count the whole counter (4.69 Ah) into one 0.25-s interval. At a change of step
a fall is a restart also when the new value is no more than the interval could have counted
(COUNT_MARGIN): a per-step counter after a short step (5 s at 3 A, 4.2 mAh) whose next step's
first row comes 10 s in (1 A, 2.8 mAh)."""

COUNT_MARGIN = 2.0
"""The most an interval can count: the larger |channel current| at its two rows × its length ×
this, in the counter's own direction (a charge counter counts charging current only). The
channel may lag the true current at a step edge (a filter of about a second against logging
intervals of 1-10 s at a step's start); twice its reading covers a channel at half its final
value. A dip comes while the current flows against the counter's direction, where its
direction's current, and so what it could count, is zero."""

SNIFF_BYTES = 65536
"""How much of a text file the sniffer reads for a header: BioLogic's header block, the longest
of the five cyclers', is about a hundred lines of at most a few hundred characters."""

DEGREE_MARKS = " °º℃o\ufffdÂ"
"""What may stand before the C of a unit in °C (``°C``, ``℃``, ``degC``, ``oC``), including
the degree sign as a text reader decodes ISO-8859-1 (``�C``, ``Â°C``): BioLogic writes
``Temperature/°C`` in ISO-8859-1, PyProBE reads it as UTF-8."""


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
    temperature: tuple[str, ...]  # regular expressions: (?P<unit>...) and a channel (?P<n>...)
    mode: tuple[str, ...] = ()  # a charge/discharge mode column that signs an unsigned current


@dataclass(frozen=True)
class Cycler:
    name: str
    reader: str  # module:class of pyprobe
    layouts: tuple[Layout, ...]
    extensions: tuple[str, ...]
    expects: str  # what its reader needs of a file, for the message when it cannot read one

    @property
    def label(self) -> str:
        return {"biologic": "BioLogic"}.get(self.name, self.name.capitalize())

    @property
    def article(self) -> str:
        return "an" if self.label[0] in "AEIOU" else "a"


ARBIN_TEMPERATURE = (
    r"Aux_Temperature_(?P<n>\d+) ?\((?P<unit>[^()]*)\)",  # MITS Pro's auxiliary channels
    r"Temperature ?\((?P<unit>[^()]*)\)_(?P<n>\d+)",  # its channel thermocouples, numbered
    r"Temperature ?\((?P<unit>[^()]*)\)",
)
"""Arbin's temperature headers, in the order preferred (both layouts): PyProBE maps
``Aux_Temperature_1 (*)`` alone; ``Temperature (C)_1`` is what MITS Pro writes for a channel's
own thermocouple (CALCE's drive-cycle workbooks)."""

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
                    ARBIN_TEMPERATURE,
                ),
                Layout(
                    "MITS Pro, classic export",
                    ("Test_Time(*)",),
                    ("Current(*)",),
                    ("Voltage(*)",),
                    ("Step_Index",),
                    (Counters("pair", ("Charge_Capacity(*)", "Discharge_Capacity(*)")),),
                    ARBIN_TEMPERATURE,
                ),
            ),
            (".csv", ".xlsx"),
            "a CSV or workbook of MITS Pro's columns",
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
                    (r"Temp (?P<n>\d+)(?: ?\((?P<unit>[^()]*)\))?",),
                    ("MD",),
                ),
            ),
            (".csv", ".txt"),
            "two header lines (Today's Date, Date of Test:) before the columns",
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
                    (
                        r"T(?P<n>\d+)\((?P<unit>[^()]*)\)",
                        r"(?:Auxiliary )?[Tt]emperature ?\((?P<unit>[^()]*)\)",
                    ),
                ),
            ),
            (".csv", ".xlsx"),
            "BTSDA's record columns, with 'Date' or 'Total Time'",
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
                    (r"Temperature(?: (?P<n>\d+))?/(?P<unit>.+)",),
                ),
            ),
            (".txt", ".mpt", ".csv"),
            "an EC-Lab text export with its 'Nb header lines' and 'Acquisition started on' lines",
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
                    (r"T(?P<n>\d*)\[(?P<unit>[^\]]*)\]",),
                ),
            ),
            (".txt", ".csv"),
            "a BaSyTest export with '~' header lines, '~Start of Test:' among them",
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
    raise DataError(
        f"{path}: no time column {want}; not {cycler.article} {cycler.label} export"
        + _hint(path, cycler.name)
    )


def _temperatures(path, layout: Layout, columns: list[str]) -> list[tuple[str, str]]:
    """(column, unit) of every temperature channel of the export, the preferred first: by the
    layout's order of headers, then by channel number. DataError for a unit that is neither
    °C nor K."""
    import re

    found: list[tuple[int, int, int, str, str]] = []
    for rank, pattern in enumerate(layout.temperature):
        for position, column in enumerate(columns):
            m = re.fullmatch(pattern, column.strip())
            if m is None or any(column == f[3] for f in found):
                continue
            unit = (m.groupdict().get("unit") or "").strip()
            if unit != "K" and unit.replace("deg", "").strip(DEGREE_MARKS) not in ("C", ""):
                raise DataError(f"{path}: column {column!r}: temperature unit {unit!r} not "
                                "recognised (need °C or K)")  # fmt: skip
            channel = int(m.groupdict().get("n") or 0)
            found.append((rank, channel, position, column, unit))
    return [(c, u) for *_, c, u in sorted(found)]


def _quantities_present(layout: Layout, columns: list[str]) -> bool:
    """The layout's time, current, voltage and step columns are all in ``columns``."""
    quantities = (layout.time, layout.current, layout.voltage, layout.step)
    return all(any(_matches(p, columns) for p in pats) for pats in quantities)


# ----------------------------------------------------------------------------------------------
# which cycler wrote a file (the header alone, without PyProBE)


def _header_rows(path: Path) -> list[list[str]]:
    """Candidate header rows: each line of a text file's first SNIFF_BYTES split on tab, comma
    or semicolon; the first row of each sheet of a workbook."""
    if path.suffix.lower() in (".xlsx", ".xlsm", ".xls"):
        return list(_sheet_headers(path).values())
    try:
        with open(path, "rb") as f:
            text = f.read(SNIFF_BYTES).decode("latin-1")  # every byte decodes; headers are ASCII
    except OSError:
        return []
    rows = []
    for line in text.splitlines():
        for sep in ("\t", ",", ";"):
            cells = [c.strip().strip('"') for c in line.split(sep)]
            if len(cells) >= 4:
                rows.append(cells)
    return rows


def sniff(path: str | Path, exclude: str = "") -> str:
    """The cycler (other than ``exclude``) one of whose layouts' time, current, voltage and
    step columns a header row of the file holds, or ""."""
    path = Path(path)
    own = binary.cycler_of(path)
    if own:  # a binary file: its extension says whose
        return "" if own == exclude else own
    try:
        rows = _header_rows(path)
    except Exception:  # an unreadable workbook: nothing to say about it
        return ""
    for name, cycler in CYCLERS.items():
        if name == exclude or path.suffix.lower() not in cycler.extensions:
            continue
        if any(_quantities_present(lay, row) for row in rows for lay in cycler.layouts):
            return name
    return ""


def looks_like(path: str | Path, exclude: str = "") -> str:
    """``this looks like an Arbin export: add --cycler arbin`` (the sniff's verdict), or ""."""
    name = sniff(path, exclude)
    if not name:
        return ""
    cycler = CYCLERS[name]
    return f"this looks like {cycler.article} {cycler.label} export: add --cycler {name}"


def _hint(path, declared: str) -> str:
    """``; it looks like an Arbin export: use --cycler arbin`` for a file of another cycler."""
    name = sniff(path, declared)
    if not name:
        return ""
    other = CYCLERS[name]
    return f"; it looks like {other.article} {other.label} export: use --cycler {name}"


# ----------------------------------------------------------------------------------------------
# workbooks: every data sheet found and named, one read at a time


_SHEETS: dict = {}  # the last workbook's sheets, read once: (path, mtime, size) -> {name: frame}


def _sheets(path: Path) -> dict:
    """Every sheet of a workbook as a polars frame (None where it holds no table), read once
    per command: calamine parses a whole sheet even for its header, and PyProBE reads a file
    twice (its columns, then its rows), so each sheet was parsed up to three times. Numbers as
    numbers (PyProBE reads every cell as text, which keeps 9 digits: a counter then loses
    1e-10 Ah, 0.16 mA over a 10-ms interval), the types inferred from every row."""
    import fastexcel
    import polars as pl

    stat = path.stat()
    key = (str(path.resolve()), stat.st_mtime_ns, stat.st_size)
    if key not in _SHEETS:
        _SHEETS.clear()  # one workbook at a time: a sheet may be a gigabyte
        out = {}
        for name in fastexcel.read_excel(str(path)).sheet_names:
            try:
                out[name] = pl.read_excel(path, sheet_name=name, engine="calamine",
                                          infer_schema_length=None)  # fmt: skip
            except Exception:  # an empty, chart or ragged sheet holds no table
                out[name] = None
        _SHEETS[key] = out
    return _SHEETS[key]


def _sheet_headers(path: Path) -> dict[str, list[str]]:
    """Each sheet's first row (its column names), in the workbook's order."""
    return {name: ([] if f is None else list(f.columns)) for name, f in _sheets(path).items()}


def data_sheets(path: str | Path, cycler_name: str) -> list[str]:
    """The sheets of a workbook whose first row holds one of the cycler's layouts' time,
    current, voltage and step columns, in the workbook's order; [] for a text export. MITS
    Pro's ``Statistics_...`` sheets (a row per cycle, not per sample) are not data."""
    path = Path(path)
    if path.suffix.lower() != ".xlsx":
        return []
    cycler = CYCLERS[cycler_name]
    try:
        headers = _sheet_headers(path)
    except Exception as exc:
        raise DataError(f"{path}: not readable as a workbook ({_first_line(exc)})") from None
    found = [
        name
        for name, columns in headers.items()
        if not name.lower().startswith("statistics")
        and any(_quantities_present(lay, columns) for lay in cycler.layouts)
    ]
    if not found:
        raise DataError(
            f"{path}: no sheet of {', '.join(repr(n) for n in headers)} has "
            f"{cycler.article} {cycler.label} export's time, current, voltage and step columns"
            + _hint(path, cycler_name)
        )
    return found


def choose_sheets(path: str | Path, cycler_name: str, sheet: str | None = None,
                  concat: bool = False) -> list[str | None]:  # fmt: skip
    """The sheets to read, in order: [None] for a text export; for a workbook the one data
    sheet, ``sheet``, or every data sheet (``concat``). Several data sheets and no choice: a
    UserError naming them and the flags, never silently the first."""
    path = Path(path)
    found = data_sheets(path, cycler_name) if path.is_file() else []
    if not found:
        if sheet is not None or concat:
            flag = f"--sheet {sheet}" if sheet is not None else "--sheets concat"
            raise UserError(f"{path}: {flag}: not a workbook (.xlsx); it has no sheets")
        return [None]
    names = ", ".join(repr(n) for n in found)
    if sheet is not None:
        if sheet not in found:
            raise UserError(f"{path}: --sheet {sheet!r}: no such data sheet (data sheets: {names})")
        return [sheet]
    if concat or len(found) == 1:
        return list(found)
    raise UserError(
        f"{path}: {len(found)} data sheets ({names}); choose with convert --sheet NAME, or "
        "--sheets each (one CSV per sheet) or --sheets concat (one record, time continued)"
    )


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


def _reader(cycler: Cycler, sheet: str | None = None):
    """PyProBE's reader class of a cycler, extended to read one sheet of a workbook, chosen by
    :func:`choose_sheets`: MITS Pro writes ``Global_Info`` first and the rows in
    ``Channel_<n>-<m>`` sheets, a test's drive cycles may sit on a sheet each, while PyProBE
    reads the first sheet of an .xlsx (and, in 2.6.1, cannot finish reading one)."""
    module, name = cycler.reader.split(":")
    base = getattr(_pyprobe(module), name)
    if (base, sheet) not in _READERS:

        def read_file(filepath, header_row_index: int = 0):
            if not str(filepath).lower().endswith(".xlsx"):
                return base.read_file(filepath, header_row_index)
            frame = _sheets(Path(filepath)).get(sheet)
            if frame is None or header_row_index != 0:
                raise ValueError(f"sheet {sheet!r} holds no table with its header in row 1")
            # lazy, as PyProBE's CSV path (its own .xlsx path, in 2.6.1, returns a DataFrame
            # that its reader then fails to .collect())
            return frame.lazy()

        _READERS[base, sheet] = type(name, (base,), {"read_file": staticmethod(read_file)})
    return _READERS[base, sheet]


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


def read_columns(path: str | Path, cycler_name: str,
                 sheet: str | None = None) -> tuple[dict[str, np.ndarray], dict]:  # fmt: skip
    """The export's time (s), step, channel current (A, cycler sign), voltage (V), counters
    (Ah) and temperature (°C) as arrays, and which raw column each came from (``info["notes"]``:
    warnings, e.g. the temperature channels not used). ``sheet``: a workbook's data sheet
    (:func:`choose_sheets`)."""
    if cycler_name not in CYCLERS:
        raise UserError(f"unknown cycler {cycler_name!r}; choose from {', '.join(CYCLERS)}")
    cycler = CYCLERS[cycler_name]
    path = Path(path)
    regular_file(path, f"{cycler_name}'s export")
    own = binary.cycler_of(path)
    if own == cycler_name:
        return binary.read_columns(path, cycler_name)
    if own:
        raise DataError(f"{path}: {path.suffix} is {CYCLERS[own].label}'s binary file, not "
                        f"{cycler.article} {cycler.label} export: use --cycler {own}")  # fmt: skip
    if path.suffix.lower() not in cycler.extensions:
        exts = cycler.extensions + binary.extensions(cycler_name)
        raise DataError(
            f"{path}: {cycler.article} {cycler.label} export is {' or '.join(exts)}, "
            f"not {path.suffix or 'without extension'!r}" + _hint(path, cycler_name)
        )
    if sheet is None and path.suffix.lower() == ".xlsx":
        (sheet,) = choose_sheets(path, cycler_name)
    where = f"{path}" + (f": sheet {sheet!r}" if sheet is not None else "")
    cls = _reader(cycler, sheet)
    columns = _column_names(path, where, cls, cycler_name)
    layout = _layout(where, cycler, columns)
    used = {
        "time": _find(where, "time", layout.time, columns),
        "current": _find(where, "current", layout.current, columns),
        "voltage": _find(where, "voltage", layout.voltage, columns),
        "step": _find(where, "step", layout.step, columns),
    }
    temperatures = _temperatures(where, layout, columns)
    counters = _counters(where, layout, columns)
    mode = _find(where, "mode", layout.mode, columns, False) if layout.mode else None
    own = layout is cycler.layouts[0]  # PyProBE maps its own layout; the others we add
    label = f"{cycler.article} {cycler.label}"
    frame = _import(path, cls, used, counters, mode, own, temperatures, label, where)
    arrays = {
        "time": frame["time"],
        "step": frame["step"],
        "current": frame["current"],
        "voltage": frame["voltage"],
    }
    info = {q: {"column": c[0], "unit": c[1]} for q, c in used.items()}
    info["layout"] = layout.name
    if sheet is not None:
        info["sheet"] = sheet
    notes = []
    if "temperature" in frame:
        arrays["temperature"], info["temperature"], note = _temperature(
            where, frame["temperature"], frame["temperature_from"], temperatures
        )
        notes += [note] if note else []
    if mode is not None:
        arrays["current"], info["current"]["signed_by"] = _signed(where, frame, used, mode[0])
    if counters is not None:
        option, found = counters
        arrays["counters"] = [frame[f"counter{j}"] for j in range(len(found))]
        info["counters"] = {
            "kind": option.kind,
            "columns": [{"column": c, "unit": u} for c, u, _ in found],
        }
    info["notes"] = notes
    return arrays, info


def _column_names(path: Path, where: str, cls, cycler_name: str) -> list[str]:
    """The export's column names, as the cycler's PyProBE reader sees them."""
    cycler = CYCLERS[cycler_name]
    with _quiet_pyprobe():
        try:
            return [str(c) for c in cls.read_file(str(path)).collect_schema().names()]
        except Exception:  # any reader failure is a file that is not this cycler's: its own
            # words (e.g. "cannot access local variable 'start_time_line'") would not say so
            raise DataError(
                f"{where}: not readable as {cycler.article} {cycler.label} export (its reader "
                f"needs {cycler.expects})" + _hint(path, cycler_name)
            ) from None


def _counters(where: str, layout: Layout, columns: list[str]):
    """(the layout's first counter option whose columns are all there, those columns), or None."""
    for option in layout.counters:
        found = [_find(where, "charge counter", (p,), columns, False) for p in option.columns]
        if all(found):
            return option, found
    return None


def _temperature(where, values: np.ndarray, used: int, candidates: list[tuple[str, str]]):
    """The temperature (°C) of the first channel with readings, which column it came from, and
    a note naming the channels not used. A column labelled K is converted; one in °C that holds
    kelvin is refused by the records layer's range (``records.TEMPERATURE_RANGE_C``)."""
    column, unit = candidates[used]
    if unit == "K":
        values = values - 273.15
    others = [c for j, (c, _) in enumerate(candidates) if j != used]
    note = (
        f"{where}: {len(candidates)} temperature columns; column {column!r} is used, "
        f"{', '.join(repr(c) for c in others)} not"
        if others
        else ""
    )
    return values, {"column": column, "unit": unit or "°C (the cycler's)"}, note


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


def _extra_importers(used: dict, counters, mode, own: bool, temperatures) -> list:
    """PyProBE's column maps for what its own map of the cycler lacks: the raw counters, every
    temperature channel, a mode column, and (``own`` false: a layout PyProBE does not know) the
    time, current, voltage and step."""
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
    # each channel by its own name (PyProBE's one "Temperature [C]" map takes its first match)
    for j, (column, _) in enumerate(temperatures):
        extra.append(column_maps.CastAndRenameMap(f"temperature{j}", column, pl.Float64))
    if mode is not None:
        extra.append(column_maps.CastAndRenameMap("mode", mode[0], pl.Utf8))
    if counters is not None:
        _, found = counters
        for j, (column, unit, pattern) in enumerate(found):
            if unit:
                extra.append(column_maps.ConvertUnitsMap(f"counter{j}", pattern))
            else:  # Maccor: no unit in the header; its exports are in Ah
                extra.append(column_maps.CastAndRenameMap(f"counter{j}", column, pl.Float64))
    return extra


def _import(path, cls, used: dict, counters, mode=None, own: bool = True,
            temperatures: list[tuple[str, str]] = (), label: str = "the cycler's",
            where: str = "") -> dict[str, np.ndarray]:  # fmt: skip
    """PyProBE's frame of the export, with the raw counters, every temperature channel (and a
    mode column, and for a layout PyProBE does not know its time, current, voltage and step)
    added as extra importers. ``temperature``: the first channel with readings, the index of
    its column in ``temperatures`` as ``temperature_from``."""
    import polars as pl

    where = where or str(path)  # messages name the sheet too

    extra = _extra_importers(used, counters, mode, own, temperatures)
    with _quiet_pyprobe(), tempfile.TemporaryDirectory() as tmp:
        try:
            reader = cls(
                input_data_path=str(path),
                output_data_path=str(Path(tmp) / "unused.parquet"),
                overwrite_existing=True,
                extra_column_importers=extra,
            )
            df = reader.get_pyprobe_dataframe()
        except Exception as exc:  # a value PyProBE cannot cast or parse (its words name it)
            raise DataError(
                f"{where}: read as {label} export, a value could not be parsed: {_first_line(exc)}"
            ) from None
    names = {
        "time": "Time [s]",
        "step": "Step",
        "current": "Current [A]",
        "voltage": "Voltage [V]",
    }
    out = {}
    for key, name in names.items():
        if name in df.columns:
            out[key] = df[name].cast(pl.Float64, strict=False).to_numpy()
    for j, (column, _) in enumerate(temperatures):
        values = df[f"temperature{j}"].cast(pl.Float64, strict=False).to_numpy()
        if np.isfinite(values).any():  # a channel never filled is no temperature
            out["temperature"], out["temperature_from"] = values, j
            used = {**used, "temperature": (column,)}
            break
    for key in ("time", "step", "current", "voltage"):
        if key not in out:  # PyProBE's map failed although the header matched
            raise DataError(f"{where}: column {used[key][0]!r}: could not be read")
    if counters is not None:
        for j in range(len(counters[1])):
            out[f"counter{j}"] = df[f"counter{j}"].cast(pl.Float64, strict=False).to_numpy()
    modes = df["mode"].fill_null("").to_numpy() if mode is not None else None
    for key, values in out.items():
        if key == "temperature_from":
            continue
        bad = ~np.isfinite(values)
        if bad.any():
            row = int(np.flatnonzero(bad)[0])
            column = used[key][0] if key in used else counters[1][int(key[-1])][0]
            raise DataError(
                f"{where}: column {column!r} data row {row + 1}: missing or not a number"
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


def _increments(c: np.ndarray, countable: np.ndarray | None = None
                ) -> tuple[np.ndarray, int, np.ndarray]:  # fmt: skip
    """Per-interval count of an unsigned counter that may restart, the number of restarts, and
    the dips (falls that are not restarts). A restart is a fall (by more than its quantum) from a
    positive value to at most RESTART_FRACTION of it, or to at most what the interval could count
    (``countable``, Ah; 0 where the step does not change): the interval then counted the new
    value. Any other fall is a dip, kept as a negative increment (RESTART_FRACTION says why)."""
    d = np.diff(c)
    fall = d < -max(_resolution(c), 1e-12)
    near_zero = c[1:] <= RESTART_FRACTION * c[:-1]
    if countable is not None:
        near_zero |= c[1:] <= countable
    restart = fall & (c[:-1] > 0) & near_zero
    dips = np.where((d < 0) & ~restart, -d, 0.0)
    return np.where(restart, c[1:], d), int(restart.sum()), dips


def net_charge(arrays: dict, kind: str) -> tuple[np.ndarray, dict]:
    """Cumulative charge into the cell (Ah, charge positive) at each row, from the counters."""
    cs = arrays["counters"]
    dips = np.zeros(max(cs[0].size - 1, 0))
    change = np.diff(arrays["step"]) != 0

    def countable(i):  # at a change of step, what the interval could count (COUNT_MARGIN)
        big = np.maximum(i[:-1], i[1:]) * np.diff(arrays["time"]) / 3600.0
        return np.where(change, COUNT_MARGIN * big, 0.0)

    current = arrays["current"]
    if kind == "pair":  # each counts one direction only (a dip comes in the other one)
        up, r1, d1 = _increments(cs[0], countable(np.clip(current, 0.0, None)))
        down, r2, d2 = _increments(cs[1], countable(np.clip(-current, 0.0, None)))
        inc, restarts, dips = up - down, r1 + r2, np.maximum(d1, d2)
    elif kind == "step":
        count, restarts, dips = _increments(cs[0], countable(np.abs(current)))
        inc = count * np.sign(arrays["current"][1:])  # the direction of the interval's step
    else:  # signed: a running count, every change an increment
        inc, restarts = np.diff(cs[0]), 0
    q = np.concatenate([[0.0], np.cumsum(inc)])
    return q, {
        "restarts": restarts,
        "restart_rule": f"a fall to at most {RESTART_FRACTION:g} of the previous value, or at "
        f"a change of step to at most {COUNT_MARGIN:g} x |I| x the interval",
        "dips": int((dips > 0).sum()),
        "largest_dip_ah": float(dips.max()) if dips.size else 0.0,
        "resolution_ah": [_resolution(c) for c in cs],
    }


# ----------------------------------------------------------------------------------------------
# the record


def _events(step: np.ndarray, part: np.ndarray | None = None) -> np.ndarray:
    """Step occurrence index per row (a new one at each change of the step number, or of the
    sheet ``part``)."""
    change = np.diff(step) != 0
    if part is not None:
        change |= np.diff(part) != 0
    return np.concatenate([[0], np.cumsum(change)])


def _check_sheets(path, parts, keys: list[str], first: dict, first_sheet) -> None:
    """Sheets joined have the first one's columns, at least 2 rows each and a time that never
    goes backwards within a sheet."""
    for arrays, columns in parts:
        where = f"{path}" + (f": sheet {columns['sheet']!r}" if "sheet" in columns else "")
        other = {k: columns[k] for k in columns if k not in ("sheet", "notes")}
        if other != first:
            diff = next(k for k in {*keys, *other} if first.get(k) != other.get(k))

            def named(entry) -> str:  # the raw column names of a quantity, or "none"
                if not isinstance(entry, dict):
                    return "none" if entry is None else repr(entry)
                cols = entry.get("columns", [entry])
                return " + ".join(repr(c["column"]) for c in cols if "column" in c) or "none"

            raise DataError(
                f"{where}: its {diff} column {named(other.get(diff))} differs from sheet "
                f"{first_sheet!r}'s {named(first.get(diff))}; sheets joined by --sheets "
                "concat must have the same columns"
            )
        t = arrays["time"]
        if t.size < 2:
            raise DataError(f"{where}: {t.size} data rows; need at least 2")
        back = np.flatnonzero(np.diff(t) < 0)
        if back.size:
            raise DataError(f"{where}: column {columns['time']['column']!r} data row "
                            f"{int(back[0]) + 2}: time goes backwards")  # fmt: skip


def _merged_counter_info(total: dict, info: dict) -> dict:
    """The counters' account of the sheets so far (``total``; empty before the first) and of
    one more sheet: restarts and dips summed, the largest dip, the finer resolution."""
    if not total:
        return info
    total["restarts"] += info["restarts"]
    total["dips"] += info["dips"]
    total["largest_dip_ah"] = max(total["largest_dip_ah"], info["largest_dip_ah"])
    total["resolution_ah"] = [
        min(a, b) if a > 0 and b > 0 else max(a, b)
        for a, b in zip(total["resolution_ah"], info["resolution_ah"], strict=True)
    ]
    return total


def _join(path, parts: list[tuple[dict, dict]]):
    """One record of the sheets read (each ``read_columns``'s arrays and columns), in order:
    (arrays, columns, net charge or None, counter info, step occurrences, sheets info).

    Each sheet's charge is counted on its own rows. A sheet whose time starts at or after the
    previous one's last row continues that test: its clock is kept, and the counters' change
    over the join is counted with the same rule as any interval's. A sheet whose time starts
    over (a test of its own) is placed one of its own median sampling intervals after the last
    row (the gap between two tests is unknown, so the join is a short rest: nothing is counted
    over it)."""
    keys = [k for k in parts[0][1] if k not in ("sheet", "notes")]
    first = {k: parts[0][1][k] for k in keys}
    sheet_names = [c.get("sheet") for _, c in parts]
    _check_sheets(path, parts, keys, first, sheet_names[0])
    kind = first["counters"]["kind"] if "counters" in first else None
    out: dict = {k: [] for k in parts[0][0] if k != "counters"}
    charge, offsets, joins, sheet_of = [], [], [], []
    counter_info: dict = {}
    end_t, end_q = None, 0.0
    for j, (arrays, _) in enumerate(parts):
        t = arrays["time"]
        offset, join_q = 0.0, 0.0
        if end_t is not None:
            prev = parts[j - 1][0]
            if t[0] >= end_t:  # (a row repeated across sheets: the later one stays)
                joins.append("time continued")
                if kind is not None:
                    ends = zip(prev["counters"], arrays["counters"], strict=True)
                    pair = {
                        "counters": [np.r_[c0[-1], c1[0]] for c0, c1 in ends],
                        **{k: np.r_[prev[k][-1], arrays[k][0]]
                           for k in ("current", "time", "step")},
                    }  # fmt: skip
                    join_q = float(net_charge(pair, kind)[0][1])
            else:
                dt = np.diff(t)
                offset = end_t + float(np.median(dt[dt > 0]) if (dt > 0).any() else 1.0) - t[0]
                joins.append("time started over: placed one median interval later, a rest")
        offsets.append(offset)
        for k in out:
            out[k].append(arrays[k] + offset if k == "time" else arrays[k])
        sheet_of.append(np.full(t.size, j))
        if kind is not None:
            qj, info = net_charge(arrays, kind)
            charge.append(qj + end_q + join_q)
            end_q = float(charge[-1][-1])
            counter_info = _merged_counter_info(counter_info, info)
        end_t = float(t[-1] + offset)
    arrays = {k: np.concatenate(v) for k, v in out.items()}
    part = np.concatenate(sheet_of)
    q = np.concatenate(charge) if kind is not None else None
    sheets_info = None
    if sheet_names[0] is not None:
        sheets_info = {
            "read": sheet_names,
            "rows": [int(a["time"].size) for a, _ in parts],
            "time_offset_s": offsets,
            "joins": joins,
        }
    return arrays, first, q, counter_info, _events(arrays["step"], part), sheets_info


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


def _check_options(cycler_name: str, rest_dt: float | None, current_from: str) -> None:
    """convert's options, each refused in one line before the file is opened."""
    if current_from not in CURRENT_FROM:
        raise UserError(f"--current-from must be one of {', '.join(CURRENT_FROM)}")
    if rest_dt is not None and not (np.isfinite(rest_dt) and rest_dt > 0):
        raise UserError(f"--rest-dt must be a positive number of seconds, got {rest_dt}")
    if cycler_name not in CYCLERS:
        raise UserError(f"unknown cycler {cycler_name!r}; choose from {', '.join(CYCLERS)}")


def _written_rows(t, q, i_ch, events, rows, rest_dt: float | None):
    """(rows written, as indices of the raw rows; the interval currents between them, charge
    positive; rest rows thinned). An interval's current is ΔQ/Δt of the counters ``q``, or
    (``q`` None) the channel held: over rest rows merged by thinning, the first row's reading (a
    rest). Rests are thinned to ``rest_dt`` (:func:`_thin_rests`: existing samples only)."""

    def intervals(idx):
        return np.diff(q[idx]) * 3600.0 / np.diff(t[idx]) if q is not None else i_ch[idx][:-1]

    idx = np.flatnonzero(rows)
    interval = intervals(idx)
    if rest_dt is None:
        return idx, interval, 0
    i99 = float(np.quantile(np.abs(interval), 0.99))
    ev = events[idx]
    load = np.zeros(int(ev[-1]) + 1, dtype=bool)
    inside = ev[:-1] == ev[1:]  # an interval into the next step carries that step's current
    busy = ~records.at_rest(interval, max(i99, 1e-12))
    np.logical_or.at(load, ev[:-1][inside], busy[inside])
    present = np.zeros_like(load)
    present[ev] = True
    thin = _thin_rests(t[idx], ev, present & ~load, rest_dt)
    idx = idx[thin]
    return idx, intervals(idx), int((~thin).sum())


def _voltage_sign(path, out: pd.DataFrame, channel, column: str, cycler: Cycler):
    """(the sign evidence, its note) from the voltage's answer to the channel: its reading is
    the current at the voltage's instant (the interval means of a coarse or stalled counter are
    checked again when the written record is read). A contradiction is refused."""
    ev = records.sign_evidence(out["time_s"], -channel, out["voltage_v"])
    if ev.contradicts:
        raise DataError(
            f"{path}: column {column!r}: the voltage falls when the {cycler.label} "
            f"current rises (negated to discharge positive: {ev.describe()}): "
            f"the export is not {CONVENTION} as {cycler.label} writes it"
        )
    if ev.verdict != records.CANNOT_TELL:
        return ev, []
    return ev, [f"{path}: column {column!r}: the voltage does not tell the "
                f"current's sign ({ev.describe()}); {cycler.label}'s {CONVENTION} "
                "convention is taken as it is"]  # fmt: skip


def _counter_notes(path, agreement: dict | None, counter_info: dict, column: str) -> list[str]:
    """A warning where the counters and the channel differ on steady intervals by more than the
    line between rest and load."""
    if not agreement or "rms_difference_steady_a" not in agreement:
        return []
    rms, scale = agreement["rms_difference_steady_a"], agreement["current_scale_a"]
    if rms <= records.REST_FRACTION * scale:
        return []
    q_ah = ", ".join(f"{x:.3g}" for x in counter_info["resolution_ah"])
    return [
        f"{path}: the charge counters and column {column!r} differ by "
        f"{rms:.3g} A RMS on steady intervals, over {records.REST_FRACTION:.0%} of the "
        f"99th-percentile |I| (the line between rest and load); the counters step by "
        f"{q_ah} Ah. Export them with more digits, or use --current-from channel"
    ]


def convert(
    path: str | Path,
    cycler_name: str,
    *,
    steps: tuple[int, int] | None = None,
    rest_dt: float | None = None,
    current_from: str = "counters",
    sheet: str | None = None,
    concat: bool = False,
) -> tuple[pd.DataFrame, dict]:
    """The canonical record of a raw export (time_s, current_a discharge-positive, voltage_v
    [, temperature_c]) and its sidecar dict. One-line DataError/UserError on bad input.
    A workbook: its one data sheet, ``sheet``, or (``concat``) all of them in order
    (:func:`choose_sheets`, :func:`_join`)."""
    _check_options(cycler_name, rest_dt, current_from)
    path = Path(path)
    regular_file(path, f"{cycler_name}'s export")
    chosen = choose_sheets(path, cycler_name, sheet, concat)
    parts = [read_columns(path, cycler_name, s) for s in chosen]
    # net charge at every raw row (before rows are dropped, so no interval's charge is lost)
    arrays, columns, q, counter_info, events, sheets_info = _join(path, parts)
    notes = [n for _, c in parts for n in c["notes"]]
    t, step, i_ch, v = (arrays[k] for k in ("time", "step", "current", "voltage"))
    name = {k: columns[k]["column"] for k in ("time", "current", "voltage", "step")}
    use_counters = q is not None and current_from == "counters"

    # repeated time stamps: the later row stays (time going backwards: refused in _join)
    unique = np.append(np.diff(t) > 0, True)
    keep_steps = _step_range(path, step, steps, name["step"])
    rows = unique & keep_steps
    if rows.sum() < 2:
        raise DataError(f"{path}: fewer than 2 rows left after the step selection")
    idx, interval, rest_rows = _written_rows(t, q if use_counters else None, i_ch, events, rows,
                                             rest_dt)  # fmt: skip
    tk = t[idx]
    current_cp = np.append(interval, i_ch[idx[-1]])  # the last row: its channel reading
    out = pd.DataFrame({"time_s": tk - tk[0], "current_a": 0.0 - current_cp, "voltage_v": v[idx]})
    if "temperature" in arrays:
        out["temperature_c"] = arrays["temperature"][idx]

    # the counters against the channel: units, sign, lag
    sign_agreement, agreement = None, None
    if q is not None:
        sign_agreement, agreement = _agreement(
            path, q, t, i_ch, events, unique & keep_steps, columns, records.STEP_FRACTION
        )
    # the scale of one cell, the records layer's limits, named by the raw columns
    # (and the temperature's, where records checks it: named by the raw column as the others)
    raw_names = {"time_s": name["time"], "current_a": name["current"], "voltage_v": name["voltage"]}
    if "temperature" in columns:
        raw_names["temperature_c"] = columns["temperature"]["column"]
    notes += list(records.check_scale(out, str(path), names=raw_names) or ())  # its warnings
    ev, sign_note = _voltage_sign(path, out, i_ch[idx], name["current"], CYCLERS[cycler_name])
    notes += sign_note
    if use_counters:
        notes += _counter_notes(path, agreement, counter_info, name["current"])

    kept = np.zeros(t.size, dtype=bool)
    kept[np.flatnonzero(rows)] = True
    charge_out = float(np.sum(out["current_a"].to_numpy()[:-1] * np.diff(tk))) / 3600.0
    info = {
        **_source_info(path, cycler_name, columns, sheets_info),
        "sign": {
            "cycler_convention": CONVENTION,
            "output": "discharge-positive",
            "voltage_check": {**ev.as_dict(), "confirmed": ev.verdict == records.SIGNS[0]},
            "counters_vs_channel": sign_agreement,
        },
        "current": _current_info(use_counters, None if q is None else counter_info, agreement),
        "charge": {
            "discharged_ah_output": charge_out,
            **({"discharged_ah_counters": -float(q[idx[-1]] - q[idx[0]])} if q is not None else {}),
        },
        "rows": _row_counts(unique, keep_steps, rest_rows, int(idx.size)),
        "steps": _steps_info(_steps_table(t, step, events, i_ch, kept), steps),
        "warnings": notes,
        "resampling": _resampling(rest_dt),
    }
    return out, info


def _source_info(path: Path, cycler_name: str, columns: dict, sheets_info) -> dict:
    """The sidecar's account of the source: the file and its digest, the cycler, the reader,
    the raw columns used, the sheets joined."""
    reader = CYCLERS[cycler_name].reader.split(":")[1]
    return {
        "source_file": str(path),
        "source_sha256": sha256(path),
        "cycler": cycler_name,
        "reader": columns.get("reader") or f"pyprobe-data {_pyprobe_version()} ({reader})",
        "columns": {k: c for k, c in columns.items() if k not in ("notes", "sheet", "reader")},
        **({"sheets": sheets_info} if sheets_info else {}),
    }


def _current_info(use_counters: bool, counters: dict | None, agreement) -> dict:
    """How the current was made: from the counters (None: the export has none) or the channel."""
    return {
        "source": "charge counters" if use_counters else "current channel (held)",
        "hold": "zero-order: row k's current is the mean over [t_k, t_k+1); the last row "
        "has its channel reading",
        **({"counters": counters} if counters is not None else {}),
        **({"counters_vs_channel": agreement} if agreement else {}),
    }


def _row_counts(unique, keep_steps, rest_rows: int, written: int) -> dict:
    """Where the raw rows went."""
    return {
        "raw": int(unique.size),
        "repeated_time_dropped": int((~unique).sum()),
        "outside_steps_dropped": int((unique & ~keep_steps).sum()),
        "rest_thinned": rest_rows,
        "written": written,
    }


def _steps_info(table: list[dict], steps: tuple[int, int] | None) -> dict:
    return {
        "selection": f"{steps[0]}-{steps[1]}" if steps else "all",
        "kept": [s for s in table if s["kept"]],
        "dropped": [s for s in table if not s["kept"]],
    }


def _resampling(rest_dt: float | None) -> str:
    if rest_dt is None:
        return "none: the cycler's own samples; voltage and temperature never interpolated"
    return (f"rests thinned to {REST_POINTS_PER_DECADE} samples per decade of rest time, "
            f"at most {rest_dt:g} s apart (existing samples kept, none interpolated)")  # fmt: skip


def _agreement(path, q, t, i_ch, events, rows, columns,
               step_fraction) -> tuple[dict | None, dict]:  # fmt: skip
    """The counters' interval current against the channel's over the rows kept: the units (a
    factor of √1000 at most), the sign (direction-named counters), the lag at step edges
    (``events``: step occurrences). Returns (sign agreement or None without steady intervals,
    the rest for the sidecar)."""
    idx = np.flatnonzero(rows)
    tk, qk, ik, sk = t[idx], q[idx], i_ch[idx], events[idx]
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


def sheet_path(out: str | Path, sheet: str) -> Path:
    """``--sheets each``: OUT's stem + ``-`` + the sheet's name (characters other than letters,
    digits, ``.``, ``_`` and ``-`` as ``_``, so a name never makes a folder or a hidden file)."""
    import re

    out = Path(out)
    safe = re.sub(r"[^A-Za-z0-9._-]", "_", sheet).lstrip(".") or "_"
    return out.with_name(f"{out.stem}-{safe}{out.suffix}")


def write(frame: pd.DataFrame, info: dict, out: str | Path) -> Path:
    """The CSV and its JSON sidecar (same stem), both or neither (``records.write``)."""
    out = Path(out)
    if out.suffix.lower() != ".csv":
        raise UserError(f"--out must be a .csv path, got {str(out)!r}")
    return records.write(frame, info, out, keys=(), required=records.REQUIRED)
