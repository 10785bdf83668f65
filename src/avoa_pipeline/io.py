"""Reading measurement CSVs and writing outputs atomically.

Every reader check fails with one line naming the file and the field; writers go through a
temporary file in the target folder and an atomic rename, so an error never leaves half a file.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import os
import tempfile
from pathlib import Path

import numpy as np
import pandas as pd

from .errors import DataError

_UMASK = os.umask(0)
os.umask(_UMASK)

REQUIRED = ("time_s", "current_a", "voltage_v")
OPTIONAL = ("temperature_c",)


@contextlib.contextmanager
def atomic_path(path: str | Path):
    """Yield a temporary path beside ``path``; on success rename it onto ``path``."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    os.close(fd)
    try:
        yield Path(tmp)
        os.chmod(tmp, 0o666 & ~_UMASK)  # mkstemp creates 0600; outputs are ordinary files
        os.replace(tmp, path)
    finally:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)


def write_json(obj, path: str | Path) -> None:
    with atomic_path(path) as tmp:
        tmp.write_text(json.dumps(obj, indent=1, sort_keys=False, allow_nan=False) + "\n")


def read_json(path: str | Path, what: str = ""):
    """A JSON file's content; a missing or unreadable file is a one-line DataError naming it
    (``what`` says whose file it is, e.g. "sidecar of x.csv")."""
    path = Path(path)
    label = f" ({what})" if what else ""
    try:
        return json.loads(path.read_text())
    except FileNotFoundError:
        raise DataError(f"{path}: no such file{label}") from None
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise DataError(f"{path}: not readable JSON{label} ({exc})") from None


def write_log(path: str | Path | None, text: str) -> None:
    """A job's one-line log (nothing if ``path`` is empty); its folder is made if missing."""
    if path:
        Path(path).parent.mkdir(parents=True, exist_ok=True)
        Path(path).write_text(text.rstrip() + "\n")


def sha256(path: str | Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def read_csv(path: str | Path) -> pd.DataFrame:
    """A CSV with stripped column names; a missing or unreadable file is a one-line DataError."""
    path = Path(path)
    try:
        df = pd.read_csv(path)
    except FileNotFoundError:
        raise DataError(f"{path}: no such file") from None
    except (pd.errors.ParserError, pd.errors.EmptyDataError, UnicodeDecodeError) as exc:
        msg = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        raise DataError(f"{path}: not a readable CSV ({msg})") from None
    df.columns = [str(c).strip() for c in df.columns]
    return df


def read_measurement(path: str | Path, min_samples: int = 2) -> pd.DataFrame:
    """Read ``time_s, current_a, voltage_v[, temperature_c]`` and check what a fit relies on."""
    path = Path(path)
    df = read_csv(path)
    for col in REQUIRED:
        if col not in df.columns:
            raise DataError(f"{path}: missing column {col!r} (need {', '.join(REQUIRED)})")
    cols = [c for c in (*REQUIRED, *OPTIONAL) if c in df.columns]
    for col in cols:
        values = pd.to_numeric(df[col], errors="coerce")
        bad = values.isna() & df[col].notna()
        if bad.any():
            row = int(np.flatnonzero(bad.to_numpy())[0])
            raise DataError(
                f"{path}: column {col!r} row {row + 2}: not a number ({df[col].iloc[row]!r})"
            )
        if values.isna().any():
            row = int(np.flatnonzero(values.isna().to_numpy())[0])
            raise DataError(f"{path}: column {col!r} row {row + 2}: missing value (NaN)")
        if not np.isfinite(values.to_numpy()).all():
            row = int(np.flatnonzero(~np.isfinite(values.to_numpy()))[0])
            raise DataError(f"{path}: column {col!r} row {row + 2}: not finite")
        df[col] = values.astype(float)
    df = df[cols]
    if len(df) < min_samples:
        raise DataError(f"{path}: {len(df)} samples; need at least {min_samples}")
    dt = np.diff(df["time_s"].to_numpy())
    if (dt == 0).any():
        row = int(np.flatnonzero(dt == 0)[0]) + 1
        raise DataError(f"{path}: column 'time_s' row {row + 2}: duplicate time")
    if (dt < 0).any():
        row = int(np.flatnonzero(dt < 0)[0]) + 1
        raise DataError(f"{path}: column 'time_s' row {row + 2}: time goes backwards")
    return df


def uniform_step(path, time_s: np.ndarray, rtol: float = 1e-6) -> float:
    """The sampling step of a uniformly sampled record (the ISE kernel needs one)."""
    dt = np.diff(time_s)
    ts = float(np.median(dt))
    if np.max(np.abs(dt - ts)) > rtol * max(ts, 1.0):
        raise DataError(f"{path}: column 'time_s': not uniformly sampled (resample first)")
    return ts


def step_resistance(time_s, current_a, voltage_v, min_step_a: float,
                    max_dt_s: float = np.inf) -> tuple[float, int]:  # fmt: skip
    """The current's sign, read from the voltage: median −ΔV/ΔI (Ω) over the current steps of at
    least ``min_step_a`` between samples at most ``max_dt_s`` apart, and their number; (nan, 0)
    without one. With positive current = discharge a step up in current pulls the voltage down
    (ohmic drop, and over a longer step the falling OCV too), so a record in the pipeline's sign
    gives a positive resistance and one written charge-positive a negative one. The one check
    behind every importer and the diagnosis."""
    di = np.diff(np.asarray(current_a, dtype=float))
    dv = np.diff(np.asarray(voltage_v, dtype=float))
    dt = np.diff(np.asarray(time_s, dtype=float))
    steps = (np.abs(di) >= min_step_a) & (dt <= max_dt_s) & (min_step_a > 0)
    if not steps.any():
        return float("nan"), 0
    return float(np.median(-dv[steps] / di[steps])), int(steps.sum())
