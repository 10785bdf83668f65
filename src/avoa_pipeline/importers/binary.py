"""Binary cycler files (Neware ``.nda``/``.ndax``, BioLogic ``.mpr``, Arbin ``.res``) → the
columns :func:`.cycler.read_columns` gives for a text export, so that ``convert`` treats both
alike (counters → current, sign check, units, rests, steps: all of ``cycler.convert``).

**Reading is the kept libraries'.** NewareNDA (SES AI, BSD-3-Clause) reads ``.nda`` and
``.ndax``; galvani (GPL-3.0-or-later) reads ``.mpr`` and, through mdbtools' ``mdb-export`` (a
Debian package, not a Python one), Arbin's ``.res`` (a Microsoft Access database). Each is
imported only when a file of its format is read: a missing library or ``mdb-export`` is one
line saying how to install it. cellpy was checked first (issue 38): its 2.x releases read
these formats too but need Python 3.13 (this project: 3.11) and pandas 3.0.3 or later, its
1.0.3 pins pandas below 3 (docs/cyclers.md).

**What is ours** is how each library's columns become the cycler's quantities, each chosen
where a wrong choice would give a silently wrong record (docs/cyclers.md, "Binary files"):

- *Neware time*: NewareNDA's ``Time`` is the cycler's clock, which in ``.ndax`` and newer
  ``.nda`` files starts again at each step (0 at the instant of the previous step's last row)
  and in older ``.nda`` files runs on. The test time adds it up: at a change of step where the
  clock fell, the new step began at the previous row (the interval is the new row's clock);
  elsewhere the interval is the clock's difference. The wall-clock ``Timestamp`` is not used:
  it has whole seconds in older files and jumps when the tester's clock is set (NewareNDA's
  own ``TestFile.nda``: 165 s backwards in a rest).
- *Neware counters*: ``Charge_Capacity(mAh)`` and ``Discharge_Capacity(mAh)``, a pair that
  restarts at every step (``cycler.net_charge``'s ``pair``).
- *BioLogic current*: ``I/mA``, else ``<I>/mA``; a galvanostatic file (GCPL) that has neither
  keeps the charge of each interval (``dq/mA.h``), the interval's mean current, which is then
  the channel too (nothing independent of the counters to compare it with: the sign check is
  the voltage's alone). ``control/V/mA`` is not a current outside galvanostatic steps.
- *BioLogic counters*: ``Q charge/mA.h`` with ``Q discharge/mA.h``, else ``(Q-Qo)/mA.h`` (the
  running signed count).
- *Arbin .res*: MITS Pro's ``Channel_Normal_Table`` in SI units (s, A, V, Ah); one test per
  file (several ``Test_ID`` are refused, naming them). Its auxiliary temperatures are not read.
- *Temperature*: Neware's auxiliary ``T1``, ``T2``, ... (°C) and BioLogic's ``Temperature/°C``:
  the first channel read on every row; the others named in a warning.
"""

from __future__ import annotations

import contextlib
import importlib
import io
import logging
import re
import shutil
import tempfile
import warnings
from pathlib import Path

import numpy as np

from ..errors import DataError, UserError

FORMATS = {".nda": "neware", ".ndax": "neware", ".mpr": "biologic", ".res": "arbin"}
"""Binary file extension → the cycler whose software writes it."""

LIBRARIES = {"neware": "NewareNDA", "biologic": "galvani", "arbin": "galvani"}
"""The library that reads each cycler's binary files (import name = PyPI name)."""

MDB_EXPORT = "mdb-export"
INSTALL_MDBTOOLS = (
    "apt-get install mdbtools (Debian, Ubuntu), dnf install mdbtools (Fedora), "
    "brew install mdbtools (macOS)"
)

MA = 1e-3  # mA → A, mAh (mA.h) → Ah


def cycler_of(path: str | Path) -> str:
    """The cycler whose binary format ``path``'s extension names, or ""."""
    return FORMATS.get(Path(path).suffix.lower(), "")


def extensions(cycler_name: str) -> tuple[str, ...]:
    return tuple(e for e, c in FORMATS.items() if c == cycler_name)


def _library(cycler_name: str, path: Path):
    name = LIBRARIES[cycler_name]
    try:
        return importlib.import_module(name)
    except ModuleNotFoundError as exc:
        if exc.name != name:
            raise
        raise UserError(
            f"{path}: reading {path.suffix} files needs {name}: "
            f"pip install {name} (or pip install 'avoa-pipeline[cyclers]')"
        ) from None


@contextlib.contextmanager
def _quiet():
    """The libraries' chatter (galvani prints its progress, NewareNDA logs file versions, both
    warn of pandas' future changes) silenced while they read; our messages name the file."""
    with (
        contextlib.redirect_stdout(io.StringIO()),
        warnings.catch_warnings(),
    ):
        warnings.simplefilter("ignore", FutureWarning)
        warnings.simplefilter("ignore", DeprecationWarning)
        logging.disable(logging.WARNING)
        try:
            yield
        finally:
            logging.disable(logging.NOTSET)


def _first_line(exc: BaseException) -> str:
    text = str(exc).strip()
    return text.splitlines()[0] if text else type(exc).__name__


def _column(path, frame, names: tuple[str, ...], what: str) -> str:
    """The first of ``names`` that the file has; DataError naming them all."""
    for n in names:
        if n in frame:
            return n
    want = " or ".join(repr(n) for n in names)
    raise DataError(f"{path}: no {what} column {want}")


def _finite(path, name: str, values) -> np.ndarray:
    out = np.asarray(values, dtype=float)
    bad = ~np.isfinite(out)
    if bad.any():
        raise DataError(f"{path}: column {name!r} data row {int(np.flatnonzero(bad)[0]) + 1}: "
                        "missing or not a number")  # fmt: skip
    return out


def _temperature(path, frame, columns: list[str]) -> tuple[np.ndarray | None, dict | None, str]:
    """The first temperature channel read on every row (°C), which it is, and a note naming
    the channels not used (or ``""``)."""
    used = next((c for c in columns if np.isfinite(np.asarray(frame[c], float)).all()), None)
    if used is None:
        note = (f"{path}: temperature columns {', '.join(map(repr, columns))} miss readings; "
                "no temperature written") if columns else ""  # fmt: skip
        return None, None, note
    others = [c for c in columns if c != used]
    note = (f"{path}: {len(columns)} temperature columns; column {used!r} is used, "
            f"{', '.join(map(repr, others))} not") if others else ""  # fmt: skip
    return np.asarray(frame[used], float), {"column": used, "unit": "°C (the cycler's)"}, note


# ----------------------------------------------------------------------------------------------
# Neware


PAUSE_GAP_S = 60.0
"""An interval over which the wall clock (``Timestamp``) runs ahead of the cycler's clock by
more than this is a pause: the cycler's clock stood still while the cell rested (NewareNDA's
``TestFile.nda``: 444 s and 4.7 h in rests, the clock advancing 0.01-0.02 s). The wall clock
is set by the tester's PC, whose corrections move it back by 0.9-3.0 s, 22 times in 8 days
(``BTS85...ndax``), and once by 165 s (``TestFile.nda``); a minute lies above the small ones,
and a pause shorter than a minute changes a rest's relaxation little. The wall clock's
resolution (whole seconds in older files) is far below it."""


def step_clock_to_test_time(path, clock: np.ndarray, step: np.ndarray,
                            wall: np.ndarray | None = None) -> tuple[np.ndarray, dict]:  # fmt: skip
    """The test time (s from the first row) from Neware's ``Time`` (the module docstring says
    why), and how: the kind of clock (``per step`` where it falls at most changes of step)
    and the pauses, where the wall clock ``wall`` (s) ran ahead by more than PAUSE_GAP_S."""
    d = np.diff(clock)
    change = np.diff(step) != 0
    back = np.flatnonzero((d < 0) & ~change)
    if back.size:
        raise DataError(f"{path}: column 'Time' data row {int(back[0]) + 2}: the clock goes "
                        "backwards within a step")  # fmt: skip
    fell = change & (d < 0)
    per_step = fell.sum() * 2 > change.sum()
    dt = np.where(change, clock[1:], d) if per_step else d
    how: dict = {"clock": "per step, added up" if per_step else "running"}
    if wall is not None:
        dw = np.diff(wall)
        pause = dw - dt > PAUSE_GAP_S
        dt = np.where(pause, dw, dt)
        how["pauses"] = [{"data_row": int(k) + 2, "wall_clock_s": float(dw[k]),
                          "cycler_clock_s": float(d[k] if not change[k] else clock[k + 1])}
                         for k in np.flatnonzero(pause)]  # fmt: skip
    return np.concatenate([[0.0], np.cumsum(dt)]), how


def _neware(path: Path) -> tuple[dict, dict]:
    lib = _library("neware", path)
    with _quiet():
        try:
            frame = lib.read(str(path), log_level="CRITICAL")
        except Exception as exc:  # its words say what it could not parse
            raise DataError(f"{path}: not readable as a Neware {path.suffix} file "
                            f"(NewareNDA: {_first_line(exc)})") from None  # fmt: skip
    if len(frame) < 2:
        raise DataError(f"{path}: {len(frame)} data rows; need at least 2")
    names = {
        "time": "Time",
        "current": "Current(mA)",
        "voltage": "Voltage",
        "step": "Step",
        "charge": "Charge_Capacity(mAh)",
        "discharge": "Discharge_Capacity(mAh)",
    }
    raw = {k: _finite(path, _column(path, frame, (n,), k), frame[n]) for k, n in names.items()}
    wall = None
    if "Timestamp" in frame:
        stamps = frame["Timestamp"]
        wall = (stamps - stamps.iloc[0]).dt.total_seconds().to_numpy(float)
        wall = wall if np.isfinite(wall).all() else None
    time, how = step_clock_to_test_time(path, raw["time"], raw["step"], wall)
    counters, notes = [], []
    for p in how.get("pauses", []):
        notes.append(f"{path}: data row {p['data_row']}: the wall clock ran "
                     f"{p['wall_clock_s']:.0f} s, the cycler's {p['cycler_clock_s']:.3g} s: "
                     "a pause, its wall-clock length taken")  # fmt: skip
    for k in ("charge", "discharge"):  # direction-named: a count, whatever its sign
        if (raw[k] < 0).any():
            notes.append(
                f"{path}: column {names[k]!r} is negative in {(raw[k] < 0).sum()} rows "
                "(NewareNDA reads some steps' counters signed); its magnitude is used"
            )
        counters.append(np.abs(raw[k]) * MA)
    arrays = {
        "time": time,
        "step": raw["step"],
        "current": raw["current"] * MA,
        "voltage": raw["voltage"],
        "counters": counters,
    }
    info = {
        "time": {"column": "Time", "unit": "s", **how},
        "current": {"column": names["current"], "unit": "mA"},
        "voltage": {"column": "Voltage", "unit": "V"},
        "step": {"column": "Step", "unit": ""},
        "counters": {
            "kind": "pair",
            "columns": [{"column": names[k], "unit": "mAh"} for k in ("charge", "discharge")],
        },
    }
    temps = sorted((c for c in frame.columns if re.fullmatch(r"T\d+", str(c))),
                   key=lambda c: int(c[1:]))  # fmt: skip
    arrays, info = _with_temperature(path, frame, temps, arrays, info)
    info["notes"] = notes + info["notes"]
    return arrays, info


def _with_temperature(path, frame, temps, arrays, info) -> tuple[dict, dict]:
    values, used, note = _temperature(path, frame, temps)
    if values is not None:
        arrays["temperature"], info["temperature"] = values, used
    info["notes"] = [note] if note else []
    return arrays, info


# ----------------------------------------------------------------------------------------------
# BioLogic

UNIT_AH = {"mA.h": MA, "C": 1.0 / 3600.0}
"""BioLogic's charge units in Ah (a coulomb is an ampere-second)."""

BIOLOGIC_COUNTERS = (
    ("pair", ("Q charge/mA.h", "Q discharge/mA.h")),
    ("signed", ("(Q-Qo)/mA.h",)),
    ("signed", ("(Q-Qo)/C",)),
)
"""The counters of an .mpr, the first present used (``cycler.net_charge``'s kinds)."""


def _biologic(path: Path) -> tuple[dict, dict]:
    import pandas as pd

    lib = _library("biologic", path)
    with _quiet():
        try:
            with open(path, "rb") as f:  # given a path, galvani leaves the file open
                frame = pd.DataFrame(lib.BioLogic.MPRfile(f).data)
        except Exception as exc:
            raise DataError(f"{path}: not readable as a BioLogic .mpr file "
                            f"(galvani: {_first_line(exc)})") from None  # fmt: skip
    if len(frame) < 2:
        raise DataError(f"{path}: {len(frame)} data rows; need at least 2")
    t_col = _column(path, frame, ("time/s",), "time")
    v_col = _column(path, frame, ("Ecell/V", "Ewe/V", "<Ewe>/V"), "voltage")
    s_col = _column(path, frame, ("Ns",), "step")
    t = _finite(path, t_col, frame[t_col])
    arrays = {
        "time": t - t[0],
        "step": _finite(path, s_col, frame[s_col]),
        "voltage": _finite(path, v_col, frame[v_col]),
    }
    info = {
        "time": {"column": t_col, "unit": "s"},
        "voltage": {"column": v_col, "unit": "V"},
        "step": {"column": s_col, "unit": ""},
    }
    i_col = next((c for c in ("I/mA", "<I>/mA") if c in frame), None)
    if i_col is not None:
        arrays["current"] = _finite(path, i_col, frame[i_col]) * MA
        info["current"] = {"column": i_col, "unit": "mA"}
    else:  # the interval's charge: its mean current, held from its start
        dq_col = _column(path, frame, ("dq/mA.h", "dQ/C"), "current ('I/mA', '<I>/mA') or charge")
        dq = _finite(path, dq_col, frame[dq_col]) * UNIT_AH[dq_col.split("/")[-1]]
        dt = np.diff(t)
        mean = np.divide(dq[1:] * 3600.0, dt, out=np.zeros_like(dt), where=dt > 0)
        arrays["current"] = np.append(mean, mean[-1])
        info["current"] = {"column": dq_col, "unit": "charge per interval / its length"}
    for kind, cols in BIOLOGIC_COUNTERS:
        if all(c in frame for c in cols):
            unit = cols[0].split("/")[-1]
            arrays["counters"] = [_finite(path, c, frame[c]) * UNIT_AH[unit] for c in cols]
            info["counters"] = {
                "kind": kind,
                "columns": [{"column": c, "unit": unit} for c in cols],
            }
            break
    temps = [c for c in frame.columns if str(c).startswith("Temperature") and "/" in str(c)]
    return _with_temperature(path, frame, temps, arrays, info)


# ----------------------------------------------------------------------------------------------
# Arbin .res


def _arbin(path: Path) -> tuple[dict, dict]:
    import sqlite3

    import pandas as pd

    if shutil.which(MDB_EXPORT) is None:
        raise UserError(f"{path}: reading an Arbin .res file needs mdbtools' {MDB_EXPORT}, which "
                        f"is not installed: {INSTALL_MDBTOOLS}")  # fmt: skip
    lib = importlib.import_module(f"{_library('arbin', path).__name__}.res2sqlite")
    columns = ("Test_ID", "Test_Time", "Step_Index", "Current", "Voltage",
               "Charge_Capacity", "Discharge_Capacity")  # fmt: skip
    with _quiet(), tempfile.TemporaryDirectory() as tmp:
        db = Path(tmp) / "res.sqlite"
        try:
            lib.convert_arbin_to_sqlite(str(path), str(db))
            with contextlib.closing(sqlite3.connect(db)) as con:
                frame = pd.read_sql(f"SELECT {', '.join(columns)} FROM Channel_Normal_Table "
                                    "ORDER BY Test_ID, Data_Point", con)  # fmt: skip
        except Exception as exc:
            raise DataError(f"{path}: not readable as an Arbin .res file "
                            f"(galvani, mdbtools: {_first_line(exc)})") from None  # fmt: skip
    tests = sorted(set(frame["Test_ID"]))
    if len(tests) > 1:
        raise DataError(f"{path}: column 'Test_ID': {len(tests)} tests in one file "
                        f"({', '.join(map(str, tests))}); export one test per file")  # fmt: skip
    if len(frame) < 2:
        raise DataError(f"{path}: {len(frame)} data rows; need at least 2")
    raw = {c: _finite(path, c, frame[c]) for c in columns[1:]}
    arrays = {
        "time": raw["Test_Time"] - raw["Test_Time"][0],
        "step": raw["Step_Index"],
        "current": raw["Current"],
        "voltage": raw["Voltage"],
        "counters": [raw["Charge_Capacity"], raw["Discharge_Capacity"]],
    }
    info = {
        "time": {"column": "Test_Time", "unit": "s"},
        "current": {"column": "Current", "unit": "A"},
        "voltage": {"column": "Voltage", "unit": "V"},
        "step": {"column": "Step_Index", "unit": ""},
        "counters": {
            "kind": "pair",
            "columns": [{"column": c, "unit": "Ah"} for c in columns[-2:]],
        },
        "notes": [],
    }
    return arrays, info


READERS = {"neware": _neware, "biologic": _biologic, "arbin": _arbin}


def read_columns(path: str | Path, cycler_name: str) -> tuple[dict[str, np.ndarray], dict]:
    """A binary file's time (s), step, current (A, the cycler's sign: charge positive),
    voltage (V), counters (Ah) and temperature (°C) as arrays, and which column each came from,
    as :func:`.cycler.read_columns` gives them for a text export."""
    path = Path(path)
    arrays, info = READERS[cycler_name](path)
    lib = LIBRARIES[cycler_name]
    info["layout"] = f"{path.suffix} binary file"
    info["reader"] = f"{lib} {_version(lib)}"
    return arrays, info


def _version(dist: str) -> str:
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version(dist)
    except PackageNotFoundError:
        return "(version unknown)"
