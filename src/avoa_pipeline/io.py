"""Files: reading CSVs and JSON, writing outputs atomically, checking output paths first.

Every reader fails with one line naming the file (what a record's columns must hold is
``records.py``'s); writers go through a temporary file in the target folder and an atomic rename,
so an error never leaves half a file; :func:`check_output` is called before any work.

Faults of the machine, not of the input, are handled here, once (docs/inputs.md, "Faults"):

- a write the system refuses (:data:`WRITE_FAULTS`: a full disk or quota, a file too large, a
  read-only file system, no permission) is one :class:`UserError` naming the path
  (:func:`write_refusal`), from :func:`atomic_paths`, the lock and the probe alike; every
  temporary and the lock are removed on the way out. Any other OSError is not expected and keeps
  its traceback;
- every temporary carries its run's pid and host in its name (:func:`_run_tag`), so a later run
  on the same output removes those of runs that no longer live (:func:`sweep_temporaries`, called
  by the lock and by every writer): a run killed mid-write leaves them for one run only;
- a CSV still being written is told by two signals (:func:`read_csv`): a last line without its
  line end (the row is dropped, with a warning) and a size, modification time or inode that
  changes while the file is read (refused).
"""

from __future__ import annotations

import contextlib
import csv
import datetime
import errno
import fcntl
import hashlib
import json
import os
import re
import socket
import stat
import tempfile
import warnings
from pathlib import Path

import numpy as np
import pandas as pd

from .errors import DataError, UserError

# The checkout's root: a config's relative paths that do not exist in the working directory
# are taken from here. It lives in this bottom module so importers (below the config) can use it.
REPO_ROOT = Path(__file__).resolve().parents[2]

_UMASK = os.umask(0)
os.umask(_UMASK)

WRITE_FAULTS = frozenset({errno.ENOSPC, errno.EDQUOT, errno.EFBIG, errno.EROFS, errno.EACCES,
                          errno.EPERM})  # fmt: skip
"""The errors of a write that the machine, not the program, causes and the user fixes (free some
space or quota, write elsewhere, get permission): each is one line naming the path. Any other
OSError while writing (EIO of a failing disk, EBADF of a bug) is unexpected and keeps its
traceback."""


def write_refusal(exc: OSError, path: str | Path, what: str = "") -> UserError | None:
    """The one-line UserError of a write fault (:data:`WRITE_FAULTS`) at ``path`` (``what``: the
    option that named it, e.g. "--out"), or None for an OSError that is not one: the caller
    re-raises it."""
    if exc.errno not in WRITE_FAULTS:
        return None
    lead = f"{what} {path}" if what else f"{path}"
    return UserError(f"{lead}: cannot write ({exc.strerror or exc})")


def _refuse_write(exc: OSError, path: str | Path, what: str = "") -> None:
    """Raise the refusal of :func:`write_refusal`, or ``exc`` itself if it is not a write fault."""
    err = write_refusal(exc, path, what)
    if err is None:
        raise exc
    raise err from None


TMP_SUFFIX = ".tmp"
_TMP_NAME = re.compile(r"^\.(?P<name>.+)\.(?P<pid>\d+)@(?P<host>[A-Za-z0-9_.-]+)\."
                       r"(?P<tag>[a-z0-9_]{8}|bak)\.tmp$")  # fmt: skip
"""A temporary of this package: ``.NAME.PID@HOST.XXXXXXXX.tmp`` (``mkstemp``'s eight random
characters) or ``.NAME.PID@HOST.bak.tmp`` (:func:`_keep`); :func:`sweep_temporaries` reads the
pid and host back from the name."""


def _host() -> str:
    """Where a pid means this process: the machine's name (characters outside a host name's
    letters, digits, ``.`` and ``-`` as ``_``) and, on Linux, the pid namespace's number
    (containers that share a host name and a folder count their pids apart: a live process of
    one looks dead from another)."""
    name = re.sub(r"[^A-Za-z0-9.-]", "_", socket.gethostname()) or "localhost"
    try:
        ns = re.sub(r"\D", "", os.readlink("/proc/self/ns/pid"))  # "pid:[4026531836]"
    except OSError:
        ns = ""
    return f"{name}-pidns{ns}" if ns else name


def _run_tag() -> str:
    """``PID@HOST``: which run a temporary belongs to (:data:`_TMP_NAME`)."""
    return f"{os.getpid()}@{_host()}"


def _alive(pid: int) -> bool:
    """Whether a process ``pid`` runs on this machine (signal 0 checks, sends nothing; a process
    of another user exists too). A pid reused since is taken as alive: its temporaries stay."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    except OverflowError:  # no process has a pid beyond the kernel's range
        return False
    return True


def sweep_temporaries(folder: str | Path) -> list[Path]:
    """Remove the temporaries in ``folder`` (:data:`_TMP_NAME`) of runs on this host that no
    longer live (a run killed mid-write); those of live runs and of other hosts or pid
    namespaces (a shared file system, another container: their pids mean nothing here) stay.
    Returns the paths removed. Called by :func:`output_lock` (a rerun that is refused still
    sweeps beside its output) and :func:`atomic_paths` (every writer, the Snakemake jobs too).
    A dead run's temporary is never renamed by anyone, so no lock is needed to remove it."""
    host, removed = _host(), []
    try:
        names = os.listdir(folder)
    except OSError:
        return removed  # a folder not yet made, or not listable: nothing of ours to sweep
    for name in names:
        m = _TMP_NAME.match(name)
        if m is None or m["host"] != host or _alive(int(m["pid"])):
            continue
        path = Path(folder) / name
        try:
            os.unlink(path)
        except OSError:  # removed meanwhile, or another user's in a sticky folder: not ours
            continue
        removed.append(path)
    return removed


@contextlib.contextmanager
def atomic_path(path: str | Path):
    """Yield a temporary path beside ``path``; on success rename it onto ``path``."""
    with atomic_paths(path) as (tmp,):
        yield tmp


@contextlib.contextmanager
def atomic_paths(*paths: str | Path):
    """Yield temporary paths beside ``paths``; on success rename them all onto ``paths``, or
    none: where a later rename fails (a target became a folder), the targets already renamed get
    their earlier content back (kept through a hard link while the renames run). The
    temporaries of dead runs in the targets' folders are swept first (:func:`sweep_temporaries`:
    the Snakemake jobs write through here without a lock)."""
    for folder in dict.fromkeys(Path(p).parent for p in paths):
        sweep_temporaries(folder)  # of killed runs: every writer of a folder sweeps it
    with contextlib.ExitStack() as stack:
        tmps = [stack.enter_context(_temporary(Path(p))) for p in paths]
        try:
            yield tmps
        except OSError as exc:  # writing a temporary: a full disk names the files
            _refuse_write(exc, _written(paths, tmps, exc))
        backups, done = [], []
        try:
            for p, tmp in zip(map(Path, paths), tmps, strict=True):
                backups.append(_keep(p))
                os.chmod(tmp, 0o666 & ~_UMASK)  # mkstemp creates 0600; outputs are ordinary
                try:
                    os.replace(tmp, p)
                except OSError as exc:
                    raise UserError(f"{p}: cannot write ({exc.strerror or exc})") from None
                done.append(p)
        except BaseException:
            for p, backup in zip(done, backups, strict=False):
                if backup is None:
                    os.unlink(p)
                else:
                    os.replace(backup, p)
            raise
        finally:
            for backup in backups:
                if backup is not None:
                    with contextlib.suppress(FileNotFoundError):
                        os.unlink(backup)


def _written(paths, tmps, exc: OSError) -> str:
    """What a write fault inside :func:`atomic_paths` names: the target whose temporary the
    error names, else the one target, else the folder and the targets' names (a full disk fails
    whichever file is being written; the error of a buffered write names no file)."""
    for p, tmp in zip(paths, tmps, strict=True):
        if exc.filename is not None and os.fspath(exc.filename) == os.fspath(tmp):
            return str(p)
    if len(paths) == 1:
        return str(paths[0])
    folders = {Path(p).parent for p in paths}
    if len(folders) == 1:
        return f"{folders.pop()} ({', '.join(Path(p).name for p in paths)})"
    return ", ".join(map(str, paths))


@contextlib.contextmanager
def _temporary(path: Path):
    """A temporary file beside ``path`` (its folder made if missing; named by :data:`_TMP_NAME`),
    removed on the way out."""
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.{_run_tag()}.", suffix=TMP_SUFFIX,
                                   dir=path.parent)  # fmt: skip
    except OSError as exc:  # a read-only folder, a file on the way: the user's to fix
        raise UserError(f"{path}: cannot write ({exc.strerror or exc})") from None
    os.close(fd)
    try:
        yield Path(tmp)
    finally:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)


def _keep(path: Path) -> Path | None:
    """A hard link to the file at ``path`` (None if there is none, or the file system links no
    files): what :func:`atomic_paths` puts back if a later rename fails (without one, the new
    file is removed)."""
    backup = path.with_name(f".{path.name}.{_run_tag()}.bak{TMP_SUFFIX}")
    try:
        os.link(path, backup)
    except OSError:
        return None
    return backup


def write_json(obj, path: str | Path) -> None:
    with atomic_path(path) as tmp:
        tmp.write_text(json.dumps(obj, indent=1, sort_keys=False, allow_nan=False) + "\n")


def read_json(path: str | Path, what: str = ""):
    """A JSON file's content; a missing, unreadable or malformed file is a one-line DataError
    naming it (``what`` says whose file it is, e.g. "sidecar of x.csv")."""
    path = Path(path)
    label = f" ({what})" if what else ""
    regular_file(path, "a JSON file", label)
    try:
        return json.loads(path.read_bytes().decode("utf-8"))
    except FileNotFoundError:
        raise DataError(f"{path}: no such file{label}") from None
    except OSError as exc:  # a symlink loop, a name too long, no permission
        raise DataError(f"{path}: cannot read{label} ({exc.strerror or exc})") from None
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise DataError(f"{path}: not readable JSON{label} ({exc})") from None


def sidecar_of(csv_path: str | Path) -> Path:
    """The JSON sidecar beside a record CSV (``g.csv`` → ``g.json``): its metadata, an input of
    every command that reads the CSV."""
    return Path(csv_path).with_suffix(".json")


def read_sidecar(csv_path: str | Path) -> dict:
    """A CSV's sidecar as a mapping ({} if there is none); a folder in its place, a malformed
    file or JSON that is not an object is a one-line DataError naming the sidecar."""
    side = sidecar_of(csv_path)
    if not _lexists(side):
        return {}
    meta = read_json(side, f"sidecar of {csv_path}")
    if not isinstance(meta, dict):
        raise DataError(f"{side}: not a JSON object (sidecar of {csv_path})")
    return meta


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


HEADER_BYTES = 1 << 16
"""What is read of a CSV before pandas sees it (64 KiB): the header line of any cycler export fits
many times over, and a device, a binary file or junk without line ends (``/dev/zero``) must not be
read into memory whole to find that it has no header."""

_MAGIC = (
    (b"\x1f\x8b", "gzip-compressed: decompress first"),
    (b"PK\x03\x04", "a zip archive (an .xlsx workbook?): export it as CSV"),
    (b"\xff\xfe", "UTF-16 text: save as UTF-8"),
    (b"\xfe\xff", "UTF-16 text: save as UTF-8"),
)


def _not_csv(head: bytes) -> str | None:
    """Why the first bytes of a file cannot start a CSV (None if they can)."""
    if not head.strip():
        return "empty file" if not head else "no header (blank first line)"
    for magic, why in _MAGIC:
        if head.startswith(magic):
            return why
    if b"\x00" in head:
        # UTF-16 without a byte-order mark: ASCII text with a NUL beside every character
        even, odd = head[0::2], head[1::2]
        for nul, text in ((odd, even), (even, odd)):
            if nul.count(0) > 0.9 * len(nul) and text.count(0) < 0.1 * len(text):
                return "UTF-16 text: save as UTF-8"
        return "binary, not a CSV"
    line = head.split(b"\n", 1)[0]
    if len(line) == len(head) == HEADER_BYTES:
        return f"no line end in the first {HEADER_BYTES // 1024} KiB: binary or not a CSV"
    try:
        line.decode("utf-8")
    except UnicodeDecodeError as exc:
        return (
            f"header not UTF-8 (byte {line[exc.start]:#04x} at offset {exc.start}): save as UTF-8"
        )
    if any(b < 32 and b not in b"\t\r\x0c" for b in line):
        return "binary, not a CSV"
    return None


def regular_file(path: Path, kind: str = "a CSV file", label: str = "") -> None:
    """DataError naming what ``path`` is when it is not a readable regular file: missing, a
    folder, a device or a pipe (``/dev/zero`` would be read without end), a symlink loop, a name
    too long (``kind`` says what was wanted, ``label`` whose file it is, e.g. " (sidecar of x)")."""
    try:
        mode = os.stat(path).st_mode
    except FileNotFoundError:
        raise DataError(f"{path}: no such file{label}") from None
    except OSError as exc:  # a symlink loop, a name too long, no permission
        raise DataError(f"{path}: cannot read{label} ({exc.strerror or exc})") from None
    if stat.S_ISDIR(mode):
        raise DataError(f"{path}: a folder, not {kind}{label}")
    if not stat.S_ISREG(mode):
        raise DataError(
            f"{path}: not a regular file (a device or a pipe){label}: save it to a file first"
        )


def _header(path: Path) -> list[str]:
    """The file's column names, read from at most :data:`HEADER_BYTES`; DataError if the file
    cannot be a comma-separated text file (naming what it is instead)."""
    regular_file(path)
    try:
        with open(path, "rb") as f:
            head = f.read(HEADER_BYTES)
    except FileNotFoundError:
        raise DataError(f"{path}: no such file") from None
    except IsADirectoryError:
        raise DataError(f"{path}: a folder, not a CSV file") from None
    except OSError as exc:  # a symlink loop, a name too long, no permission
        raise DataError(f"{path}: cannot read ({exc.strerror or exc})") from None
    why = _not_csv(head)
    if why:
        raise DataError(f"{path}: {why}")
    header = head.split(b"\n", 1)[0].decode("utf-8").removeprefix("\ufeff")
    if "," not in header:
        if "\t" in header:
            raise DataError(f"{path}: tab-separated: need ',' between fields")
        if ";" in header:
            raise DataError(
                f"{path}: fields separated by ';' (need ',' between fields and '.' in numbers)"
            )
    names = [c.strip() for c in next(csv.reader([header]), [])]
    twice = sorted({c for c in names if names.count(c) > 1})
    if twice:
        raise DataError(
            f"{path}: column {twice[0]!r} appears {names.count(twice[0])} times in the header"
        )
    return names


READ_NOTES = "read_notes"
"""The key of :func:`read_csv`'s warnings in the frame's ``attrs`` (a dropped partial row): the
records layer adds them to the record's warnings."""
SHOWN_CHARS = 40
"""How much of a dropped partial line a warning quotes (a row of a cycler's export is shorter)."""


def _stamp(path: Path) -> tuple[int, int, int, int]:
    """What changes when a file is written to or replaced: (device, inode, size, mtime in ns)."""
    st = os.stat(path)
    return st.st_dev, st.st_ino, st.st_size, st.st_mtime_ns


def _partial_tail(path: Path) -> tuple[bytes, list[bytes]] | None:
    """The last line of ``path`` if it has no line end and follows one that has (a row still
    being written, ``2556.0,2.0,3.``), with the whole lines before it in the same block (up to
    :data:`HEADER_BYTES`); None if the file ends with a line end (or blanks after one), or has a
    single line (the header alone: pandas reads no row)."""
    with open(path, "rb") as f:
        size = f.seek(0, os.SEEK_END)
        tail, pos = b"", size
        while pos > 0:  # back to the last line end, a block at a time
            step = min(HEADER_BYTES, pos)
            pos -= step
            f.seek(pos)
            tail = f.read(step) + tail
            cut = max(tail.rfind(b"\n"), tail.rfind(b"\r"))
            if cut >= 0:
                line = tail[cut + 1 :]
                before = tail[:cut].splitlines()[1:]  # the block's first line may be cut
                return (line, before) if line.strip() else None
    return None


def _cut_short(line: bytes, before: list[bytes], n_columns: int) -> bool:
    """Whether a last line without its line end is a row cut short by a writer that had not
    finished it: fewer fields than the header, an empty last field, or a last field shorter than
    every value of that column in the lines before it. Why the last: a writer writes a row left
    to right, so a cut falls in its last field or leaves fields out; and a logger writes a
    column at one precision, so a value cut short (``3.`` of ``3.8547``) is shorter than all
    its column's others. A file merely saved without its last line end (a row of full length)
    is kept: dropping it lost a real row (the NASA B0005 index's last discharge)."""
    fields = line.decode("utf-8", "replace").strip().split(",")
    if len(fields) < n_columns or not fields[-1].strip():
        return True
    rows = [b.decode("utf-8", "replace").strip().split(",") for b in before]
    widths = [len(r[-1].strip()) for r in rows if len(r) == len(fields)]
    return bool(widths) and len(fields[-1].strip()) < min(widths)


def _changed(path: Path, before) -> None:
    """DataError if ``path`` no longer has the stamp ``before`` (:func:`_stamp`): a file
    written to, truncated, replaced or removed while it was read is no snapshot of any moment."""
    try:
        after = _stamp(path)
    except FileNotFoundError:
        raise DataError(f"{path}: removed while it was read") from None
    if after == before:
        return
    if after[:2] != before[:2]:
        how = "replaced by another file"
    elif after[2] != before[2]:
        how = f"its size went from {before[2]} to {after[2]} bytes"
    else:
        how = "its modification time moved"
    raise DataError(f"{path}: changed while it was read ({how}): is a cycler still "
                    "writing it? read it once the test has ended, or read a copy")  # fmt: skip


@contextlib.contextmanager
def unchanged_while_read(path: str | Path):
    """Hold that the file at ``path`` is the same after the block (which reads it) as before:
    DataError otherwise (:func:`_changed`). A path that cannot be looked at before is left to
    the block's reader to name."""
    path = Path(path)
    try:
        before = _stamp(path)
    except OSError:
        before = None
    yield
    if before is not None:
        _changed(path, before)


def read_csv(path: str | Path) -> pd.DataFrame:
    """A CSV with stripped column names; a missing, unreadable or mis-delimited file is a one-line
    DataError. The header is looked at first (bounded, :data:`HEADER_BYTES`): a compressed,
    UTF-16, binary, tab- or semicolon-separated file is named as such (pandas would read it as
    one column, as shifted values, or fail on a codec), and a column given twice is refused
    (pandas would rename the second one and read the first silently).

    A file still being written (docs/inputs.md, "A file still being written"): a file whose
    size, modification time or inode changes while it is read is refused; a last line without
    its line end is dropped, with a warning in ``attrs[READ_NOTES]`` (the row of a cycler that
    had not finished writing it, ``2556.0,2.0,3.`` read as 3.0 V otherwise) when it is cut short
    (:func:`_cut_short`); a complete one (a file saved without its last line end) is kept."""
    path = Path(path)
    _header(path)
    try:
        with unchanged_while_read(path), warnings.catch_warnings():
            tail = _partial_tail(path)
            warnings.simplefilter("error", pd.errors.ParserWarning)
            df = pd.read_csv(path, index_col=False, encoding="utf-8-sig")
    except FileNotFoundError:
        raise DataError(f"{path}: no such file") from None
    except pd.errors.ParserWarning:
        raise DataError(f"{path}: rows have more fields than the header (decimal commas? need "
                        "',' between fields and '.' in numbers)") from None  # fmt: skip
    except UnicodeDecodeError as exc:
        raise DataError(f"{path}: not UTF-8 text past the header (byte offset {exc.start}): "
                        "save as UTF-8") from None  # fmt: skip
    except (pd.errors.ParserError, pd.errors.EmptyDataError) as exc:
        msg = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        raise DataError(f"{path}: not a readable CSV ({msg})") from None
    except OSError as exc:
        raise DataError(f"{path}: cannot read ({exc.strerror or exc})") from None
    df.columns = [str(c).strip() for c in df.columns]
    notes = []
    if tail is not None and len(df) and _cut_short(tail[0], tail[1], df.shape[1]):
        shown = tail[0].decode("utf-8", "replace")
        shown = shown if len(shown) <= SHOWN_CHARS else shown[:SHOWN_CHARS] + "..."
        notes.append(f"{path}: line {len(df) + 1} ({shown!r}) has no line end: a row still being "
                     "written, cut short; that row was dropped")  # fmt: skip
        df = df.iloc[:-1].copy()
    df.attrs[READ_NOTES] = tuple(notes)
    return df


def _lexists(path: Path) -> bool:
    """Whether anything (a dangling symlink too) stands at ``path``; False where the path cannot
    name a file at all (too long): :func:`check_output` names that."""
    try:
        os.lstat(path)
    except OSError:
        return False
    return True


def _kind(path: Path, what: str) -> str:
    """The kind of an output path: "file", "folder" or "missing"; UserError for a path that
    cannot be written to as given (a symlink loop, a dangling symlink, a name too long)."""
    try:
        st = os.stat(path)
    except FileNotFoundError:
        if _lexists(path):
            target = os.readlink(path)
            raise UserError(f"{what} {path}: a symlink to {target}, which does not exist") from None
        return "missing"
    except NotADirectoryError:
        return "missing"  # a file on the way: the probe below names it
    except OSError as exc:
        if exc.errno == errno.ELOOP:
            raise UserError(f"{what} {path}: a symlink loop") from None
        if exc.errno == errno.ENAMETOOLONG:
            shown = (
                str(path)
                if len(str(path)) <= 100
                else f"{str(path)[:60]}...({len(str(path))} characters)"
            )
            raise UserError(
                f"{what} {shown}: file name or path too long for the file system"
            ) from None
        raise UserError(f"{what} {path}: cannot reach ({exc.strerror or exc})") from None
    return "folder" if stat.S_ISDIR(st.st_mode) else "file"


def check_output(path: str | Path, *, inputs=(), folder: bool = False, what: str = "--out"):
    """Before any work: an output path that can be written and is none of the inputs, nor the
    sidecar of an input CSV (:func:`sidecar_of`). ``folder``: the path is a folder the command
    writes into (it may exist); else a file (it may exist and is replaced, but not by a folder).
    Nothing is created: the nearest existing folder on the way is probed with a temporary file,
    removed at once. UserError naming the option."""
    if not os.fspath(path).strip():
        raise UserError(f"{what}: empty path")
    path = Path(path)
    kind = _kind(path, what)
    for p in inputs:
        if p is None:
            continue
        p = Path(p)
        if _same(path, p):
            raise UserError(f"{what} {path}: is an input of this command; it would be overwritten")
        if p.suffix.lower() == ".csv" and _same(path, sidecar_of(p)):
            raise UserError(
                f"{what} {path}: is the sidecar of the input {p}; it would be overwritten"
            )
    if kind != "missing" and (kind == "folder") != folder:
        raise UserError(f"{what} {path}: is a {kind}; need {'a folder' if folder else 'a file'}")
    probe = path if folder and kind == "folder" else path.parent
    while not _lexists(probe):
        probe = probe.parent
    if not probe.is_dir():
        raise UserError(f"{what} {path}: {probe} is a file, not a folder")
    try:
        fd, tmp = tempfile.mkstemp(prefix=f".avoa-probe.{_run_tag()}.", suffix=TMP_SUFFIX,
                                   dir=probe)  # fmt: skip
        os.close(fd)
        os.unlink(tmp)
    except OSError as exc:
        raise UserError(f"{what} {path}: cannot write in {probe} ({exc.strerror or exc})") from None


def _same(a: Path, b: Path) -> bool:
    """Whether two paths name one file (by path, through symlinks, or by inode). ``realpath``
    rather than ``Path.resolve``: it does not raise on a symlink loop (``_kind`` names that)."""
    if os.path.realpath(a) == os.path.realpath(b):
        return True
    try:
        return os.path.samefile(a, b)
    except (OSError, ValueError):
        return False


LOCK_SUFFIX = ".avoa-lock"
"""The lock of a file output ``x`` is the hidden file ``.x.avoa-lock`` beside it; a folder
output's is ``.avoa-lock`` inside it (beside it would need the folder above to be writable, which
``--out .`` in a home folder does not give)."""


@contextlib.contextmanager
def output_lock(path: str | Path, *, folder: bool = False, command: str = ""):
    """Hold the lock of the output ``path`` while a command writes it: a second run on the same
    output is refused in one line naming the running one (pid, host, start, command).

    The lock is an ``fcntl.flock`` on a file beside or in the output (:data:`LOCK_SUFFIX`) that
    holds the holder's pid, host, start and command. The kernel drops it when its process ends,
    however it ends, so a lock file left by a killed run is stale by construction and the next
    run takes it over (Snakemake's ``--unlock`` is not needed); a run that ends removes it, also
    on an error. A file system that cannot lock (NFS mounted ``nolock``) runs unlocked. The path is
    checked first (:func:`check_output`); folders made for the lock are removed if left empty.
    Holding the lock, the run removes the temporaries of runs that no longer live beside (or in)
    its output (:func:`sweep_temporaries`)."""
    check_output(path, folder=folder)
    path = Path(os.path.abspath(path))
    lock = path / LOCK_SUFFIX if folder else path.parent / f".{path.name}{LOCK_SUFFIX}"
    made = _make_folders(lock.parent)
    try:
        fd = _take_lock(lock, path, command)
        try:
            sweep_temporaries(path if folder else path.parent)  # of killed runs, under the lock
            yield lock
        finally:
            if fd is not None:
                with contextlib.suppress(FileNotFoundError):
                    os.unlink(lock)  # while still held: no other run holds this file
                os.close(fd)
    finally:
        for d in reversed(made):
            with contextlib.suppress(OSError):
                d.rmdir()  # only if empty: a failed run leaves no folder behind


def _make_folders(folder: Path) -> list[Path]:
    """Make ``folder`` and its missing parents; the ones made, outermost first."""
    missing = []
    while not _lexists(folder):
        missing.append(folder)
        folder = folder.parent
    made = []
    for d in reversed(missing):
        try:
            d.mkdir()
        except FileExistsError:
            continue  # another run made it meanwhile
        except OSError as exc:
            for m in reversed(made):
                with contextlib.suppress(OSError):
                    m.rmdir()
            raise UserError(f"--out: cannot make {d} ({exc.strerror or exc})") from None
        made.append(d)
    return made


def _take_lock(lock: Path, out: Path, command: str) -> int | None:
    """The open, locked descriptor of ``lock`` with this run's details written in it."""
    while True:
        try:
            fd = os.open(lock, os.O_RDWR | os.O_CREAT, 0o666 & ~_UMASK)
        except OSError as exc:
            raise UserError(f"--out {out}: cannot write in {lock.parent} "
                            f"({exc.strerror or exc})") from None  # fmt: skip
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            holder = _holder(fd)
            os.close(fd)
            raise UserError(f"--out {out}: another run is writing it ({holder}); wait for it to "
                            "end, or choose another --out") from None  # fmt: skip
        except OSError as exc:
            os.close(fd)
            if exc.errno not in (errno.ENOLCK, errno.EINVAL, errno.EOPNOTSUPP, errno.ENOSYS):
                raise UserError(
                    f"--out {out}: cannot lock {lock} ({exc.strerror or exc})"
                ) from None
            with contextlib.suppress(OSError):
                os.unlink(lock)
            return None  # the file system cannot lock: unlocked, as before locks existed
        # the holder may have removed the file between our open and our lock: then we locked a
        # file no longer at that path, and try again on the one that is
        try:
            st, now = os.fstat(fd), os.stat(lock)
            current = (st.st_dev, st.st_ino) == (now.st_dev, now.st_ino)
        except FileNotFoundError:
            current = False
        if not current:
            os.close(fd)
            continue
        info = {
            "pid": os.getpid(),
            "host": socket.gethostname(),
            "start": datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
            "command": command,
        }
        try:
            os.ftruncate(fd, 0)
            os.pwrite(fd, (json.dumps(info) + "\n").encode(), 0)
        except OSError as exc:  # a full disk takes the lock's inode but not its details
            with contextlib.suppress(FileNotFoundError):
                os.unlink(lock)
            os.close(fd)
            _refuse_write(exc, out, "--out")
        return fd


def _holder(fd: int) -> str:
    """The running holder of a lock, as its file tells it."""
    try:
        info = json.loads(os.pread(fd, 1 << 14, 0).decode())
        return (f"pid {info['pid']} on {info['host']}, started {info['start']}: "
                f"{info['command']}")  # fmt: skip
    except (ValueError, KeyError, TypeError):
        return "a run that has not yet written its details"


def uniform_step(path, time_s: np.ndarray, rtol: float = 1e-6) -> float:
    """The sampling step of a uniformly sampled record (the ISE kernel needs one)."""
    dt = np.diff(time_s)
    ts = float(np.median(dt))
    if np.max(np.abs(dt - ts)) > rtol * max(ts, 1.0):
        raise DataError(f"{path}: column 'time_s': not uniformly sampled (resample first)")
    return ts
