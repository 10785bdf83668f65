"""Files: reading CSVs and JSON, writing outputs atomically, checking output paths first.

Every reader fails with one line naming the file (what a record's columns must hold is
``records.py``'s); writers go through a temporary file in the target folder and an atomic rename,
so an error never leaves half a file; :func:`check_output` is called before any work.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import os
import tempfile
import warnings
from pathlib import Path

import numpy as np
import pandas as pd

from .errors import DataError, UserError

_UMASK = os.umask(0)
os.umask(_UMASK)


@contextlib.contextmanager
def atomic_path(path: str | Path):
    """Yield a temporary path beside ``path``; on success rename it onto ``path``."""
    path = Path(path)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    except OSError as exc:  # a read-only folder, a file on the way: the user's to fix
        raise UserError(f"{path}: cannot write ({exc.strerror or exc})") from None
    os.close(fd)
    try:
        yield Path(tmp)
        os.chmod(tmp, 0o666 & ~_UMASK)  # mkstemp creates 0600; outputs are ordinary files
        try:
            os.replace(tmp, path)
        except OSError as exc:  # e.g. the target became a folder
            raise UserError(f"{path}: cannot write ({exc.strerror or exc})") from None
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
    """A CSV with stripped column names; a missing, unreadable or mis-delimited file is a one-line
    DataError (a semicolon-separated file, or decimal commas in a comma-separated one, would
    otherwise be read as one column or as shifted values)."""
    path = Path(path)
    if path.is_dir():
        raise DataError(f"{path}: a folder, not a CSV file")
    try:
        with open(path, encoding="utf-8", errors="replace") as f:
            header = f.readline()
    except OSError:
        header = ""  # pandas names the problem below
    if ";" in header and "," not in header:
        raise DataError(
            f"{path}: fields separated by ';' (need ',' between fields and '.' in numbers)"
        )
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("error", pd.errors.ParserWarning)
            df = pd.read_csv(path, index_col=False)
    except FileNotFoundError:
        raise DataError(f"{path}: no such file") from None
    except pd.errors.ParserWarning:
        raise DataError(f"{path}: rows have more fields than the header (decimal commas? need "
                        "',' between fields and '.' in numbers)") from None  # fmt: skip
    except (pd.errors.ParserError, pd.errors.EmptyDataError, UnicodeDecodeError) as exc:
        msg = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        raise DataError(f"{path}: not a readable CSV ({msg})") from None
    except OSError as exc:
        raise DataError(f"{path}: cannot read ({exc.strerror or exc})") from None
    df.columns = [str(c).strip() for c in df.columns]
    return df


def check_output(path: str | Path, *, inputs=(), folder: bool = False, what: str = "--out"):
    """Before any work: an output path that can be written and is none of the inputs. ``folder``:
    the path is a folder the command writes into (it may exist); else a file (it may exist and
    is replaced, but not by a folder). Nothing is created: the nearest existing folder on the
    way is probed with a temporary file, removed at once. UserError naming the option."""
    path = Path(path)
    for p in inputs:
        if p is not None and _same(path, Path(p)):
            raise UserError(f"{what} {path}: is an input of this command; it would be overwritten")
    if path.exists() and path.is_dir() != folder:
        kind = "a folder" if path.is_dir() else "a file"
        raise UserError(f"{what} {path}: is {kind}; need {'a folder' if folder else 'a file'}")
    probe = path if folder and path.is_dir() else path.parent
    while not probe.exists():
        probe = probe.parent
    if not probe.is_dir():
        raise UserError(f"{what} {path}: {probe} is a file, not a folder")
    try:
        fd, tmp = tempfile.mkstemp(prefix=".avoa-probe.", dir=probe)
        os.close(fd)
        os.unlink(tmp)
    except OSError as exc:
        raise UserError(f"{what} {path}: cannot write in {probe} ({exc.strerror or exc})") from None


def _same(a: Path, b: Path) -> bool:
    try:
        return a.resolve() == b.resolve() or (a.exists() and b.exists() and os.path.samefile(a, b))
    except OSError:
        return False


def uniform_step(path, time_s: np.ndarray, rtol: float = 1e-6) -> float:
    """The sampling step of a uniformly sampled record (the ISE kernel needs one)."""
    dt = np.diff(time_s)
    ts = float(np.median(dt))
    if np.max(np.abs(dt - ts)) > rtol * max(ts, 1.0):
        raise DataError(f"{path}: column 'time_s': not uniformly sampled (resample first)")
    return ts
