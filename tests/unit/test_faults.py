"""Faults of the machine and of files in motion (issue 38 parts 1-3), through the command line.

Each case runs ``cli.main`` as a user would and asserts: exit 2 with one ``error:`` line naming
the path (or exit 0 with one ``warning:`` line where the answer stands), no traceback, and an
output folder holding nothing but what was there before: no temporary, no lock. A full disk and
a read-only folder are made for real on a tiny tmpfs where this machine lets the test mount one
(root with the capability: CI runs as root), and by a writer that raises the system's error
everywhere else (they skip the mount with its reason, never silently).
"""

from __future__ import annotations

import contextlib
import errno
import json
import os
import signal
import socket
import subprocess
import sys
from pathlib import Path

import matplotlib.figure
import numpy as np
import pandas as pd
import pytest
from test_estimate import drive, fitted, measured

from avoa_pipeline import io
from avoa_pipeline.cli import main

TINY_DISK = "size=64k"
"""A tmpfs of 64 KiB: the estimate's CSV of 930 samples (about 80 KB) does not fit, its lock
file and temporaries (inodes, no blocks) do."""


def _one_line(err: str, kind: str, *needles: str) -> str:
    lines = err.splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith(f"{kind}: "), err
    assert "Traceback" not in err
    for needle in needles:
        assert needle in lines[0], lines[0]
    return lines[0]


def _names(folder: Path) -> list[str]:
    """Every name in ``folder``, hidden ones too (a temporary or a lock starts with a dot)."""
    return sorted(p.name for p in folder.iterdir())


@pytest.fixture
def cell(tmp_path):
    """A model of the cell (table OCV, second_rc, intervals) and a 930-s record of it, in
    ``tmp_path/in``; outputs go to ``tmp_path/out`` (made, empty)."""
    folder = tmp_path / "in"
    folder.mkdir()
    model = fitted("table", ("second_rc",))
    model.save(folder / "model.json")
    frame = measured(model, drive(seconds=900, temperature=False))
    frame.to_csv(folder / "rec.csv", index=False)
    (tmp_path / "out").mkdir()
    return folder / "model.json", folder / "rec.csv", tmp_path / "out"


def _commands(model: Path, rec: Path, out: Path) -> dict[str, list[str]]:
    """Commands that write: three files (estimate: CSV, JSON, PNG), one (simulate), a pair
    (export's table and sidecar)."""
    return {
        "estimate": ["estimate", str(model), str(rec), "--out", str(out / "soc.csv")],
        "simulate": ["simulate", str(model), str(rec), "--out", str(out / "sim.csv")],
        "export": ["export", str(model), "--to", "table", "--out", str(out / "table.csv")],
    }


# ----------------------------------------------------------------------------------------------
# part 1: a full disk, a read-only folder: one line, nothing left


def _failing(err: int):
    """A writer that starts its file, then gets ``err`` from the system (no file name: a
    buffered write's error names none)."""

    def write(self, path=None, *args, **kwargs):
        target = self if isinstance(self, Path) else path
        with open(target, "wb") as f:
            f.write(b"partial")
        raise OSError(err, os.strerror(err))

    return write


WRITERS = {
    "csv": (pd.DataFrame, "to_csv"),
    "json": (Path, "write_text"),
    "png": (matplotlib.figure.Figure, "savefig"),
}
FAULTS = {"ENOSPC": errno.ENOSPC, "EDQUOT": errno.EDQUOT, "EROFS": errno.EROFS,
          "EACCES": errno.EACCES}  # fmt: skip


@pytest.mark.parametrize("fault", FAULTS)
@pytest.mark.parametrize("writer", WRITERS)
def test_a_write_the_system_refuses_is_one_line_and_leaves_nothing(cell, capsys, monkeypatch,
                                                                   writer, fault):  # fmt: skip
    model, rec, out = cell
    monkeypatch.setattr(*WRITERS[writer], _failing(FAULTS[fault]))
    assert main(_commands(model, rec, out)["estimate"]) == 2
    # the three files are written together: the error names their folder and each of them
    _one_line(capsys.readouterr().err, "error", f"{out} (soc.csv, soc.json, soc.png): cannot "
              f"write ({os.strerror(FAULTS[fault])})")  # fmt: skip
    assert _names(out) == []


@pytest.mark.parametrize("command", ["simulate", "export"])
def test_a_full_disk_names_the_file_of_a_command_writing_one(cell, capsys, monkeypatch, command):
    model, rec, out = cell
    monkeypatch.setattr(pd.DataFrame, "to_csv", _failing(errno.ENOSPC))
    assert main(_commands(model, rec, out)[command]) == 2
    name = {"simulate": "sim.csv", "export": "(table.csv, table.json)"}[command]
    _one_line(capsys.readouterr().err, "error", name, "No space left on device")
    assert _names(out) == []


def test_a_disk_too_full_for_the_locks_details_leaves_no_lock(cell, capsys, monkeypatch):
    """A disk 100 % full still gives the lock file its inode, but not its bytes: the lock was
    left behind, with a traceback."""
    model, rec, out = cell

    def full(*args, **kwargs):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    monkeypatch.setattr(os, "pwrite", full)
    assert main(_commands(model, rec, out)["estimate"]) == 2
    _one_line(capsys.readouterr().err, "error", f"--out {out / 'soc.csv'}: cannot write (No "
              "space left on device)")  # fmt: skip
    assert _names(out) == []


def test_an_unexpected_os_error_keeps_its_traceback_and_still_leaves_nothing(cell, monkeypatch):
    """EIO (a failing disk) is no fault of the user's: it is raised, not turned into a line;
    the temporaries and the lock are removed all the same."""
    model, rec, out = cell
    monkeypatch.setattr(pd.DataFrame, "to_csv", _failing(errno.EIO))
    with pytest.raises(OSError, match="Input/output error") as exc:
        main(_commands(model, rec, out)["estimate"])
    assert exc.value.errno == errno.EIO
    assert _names(out) == []


@contextlib.contextmanager
def _tmpfs(path: Path, options: str):
    """A tmpfs mounted at ``path`` (skips where this machine cannot mount one)."""
    path.mkdir()
    try:
        done = subprocess.run(["mount", "-t", "tmpfs", "-o", options, "tmpfs", str(path)],
                              capture_output=True, text=True, check=False)  # fmt: skip
    except FileNotFoundError:
        pytest.skip("no mount command: the raised-error cases above stand in")
    if done.returncode != 0:
        pytest.skip(f"cannot mount a tmpfs here ({done.stderr.strip() or done.returncode}): the "
                    "raised-error cases above stand in")  # fmt: skip
    try:
        yield path
    finally:
        subprocess.run(["umount", "-l", str(path)], check=False)


def test_a_real_full_disk_is_one_line_and_leaves_nothing(cell, capsys, tmp_path):
    model, rec, _ = cell
    with _tmpfs(tmp_path / "tiny", TINY_DISK) as disk:
        commands = _commands(model, rec, disk)
        assert main(commands["estimate"]) == 2
        _one_line(capsys.readouterr().err, "error", f"{disk} (soc.csv, soc.json, soc.png): "
                  "cannot write (No space left on device)")  # fmt: skip
        assert _names(disk) == []
        assert main(commands["simulate"]) == 2
        _one_line(capsys.readouterr().err, "error", f"{disk / 'sim.csv'}: cannot write")
        assert _names(disk) == []
        # 100 % full: the lock file gets its inode but not its details
        with open(disk / "filler", "wb") as f, contextlib.suppress(OSError):
            f.write(b"\0" * (1 << 20))
        assert main(commands["estimate"]) == 2
        _one_line(capsys.readouterr().err, "error", "--out", "No space left on device")
        assert _names(disk) == ["filler"]


def test_a_real_read_only_folder_is_one_line(cell, capsys, tmp_path):
    model, rec, _ = cell
    with _tmpfs(tmp_path / "ro", f"ro,{TINY_DISK}") as disk:
        for command in _commands(model, rec, disk).values():
            assert main(command) == 2
            _one_line(capsys.readouterr().err, "error", f"{disk}", "Read-only file system")
        assert _names(disk) == []


# ----------------------------------------------------------------------------------------------
# part 1: a file that vanishes or changes while it is read


def _during_read(monkeypatch, target: Path, act):
    """``act(target)`` right before pandas reads ``target`` (after the header was looked at)."""
    real = pd.read_csv

    def read(path, *args, **kwargs):
        if Path(path) == target:
            act(target)
        return real(path, *args, **kwargs)

    monkeypatch.setattr(pd, "read_csv", read)


def _append_row(path: Path) -> None:
    with open(path, "a") as f:
        f.write("99999.0,1.0,3.7\n")


@pytest.mark.parametrize(("act", "needle"), [
    (os.unlink, "no such file"),
    (_append_row, "changed while it was read (its size went from"),
])  # fmt: skip
def test_a_record_that_vanishes_or_grows_while_it_is_read_is_one_line(cell, capsys, monkeypatch,
                                                                     act, needle):  # fmt: skip
    model, rec, out = cell
    _during_read(monkeypatch, rec, act)
    assert main(_commands(model, rec, out)["simulate"]) == 2
    _one_line(capsys.readouterr().err, "error", f"{rec}: {needle}")
    assert _names(out) == []


def test_a_raw_export_that_grows_while_it_is_converted_is_one_line(tmp_path, capsys,
                                                                  monkeypatch):  # fmt: skip
    """``convert`` reads a raw export through PyProBE, not ``io.read_csv``: the file is held
    unchanged over the conversion all the same."""
    import cycler_fixtures as cf

    from avoa_pipeline.importers import cycler

    raw, _ = cf.export("arbin", tmp_path)
    out = tmp_path / "out"
    out.mkdir()
    real = cycler.read_columns

    def read(path, *args, **kwargs):
        got = real(path, *args, **kwargs)
        with open(path, "a") as f:  # the cycler writes its next row once it was read
            f.write(Path(path).read_text().splitlines()[-1] + "\n")
        return got

    monkeypatch.setattr(cycler, "read_columns", read)
    assert main(["convert", str(raw), "--cycler", "arbin", "--out", str(out / "c.csv")]) == 2
    _one_line(capsys.readouterr().err, "error", f"{raw}: changed while it was read")
    assert _names(out) == []


def test_a_file_replaced_while_it_is_read_is_refused(tmp_path, monkeypatch):
    path = tmp_path / "r.csv"
    path.write_text("a,b\n1,2\n")

    def replace(p):
        other = p.with_name("new.csv")
        other.write_text("a,b\n1,2\n")
        os.replace(other, p)

    _during_read(monkeypatch, path, replace)
    with pytest.raises(io.DataError, match=r"changed while it was read \(replaced by another"):
        io.read_csv(path)


# ----------------------------------------------------------------------------------------------
# part 2: the temporaries of a killed run


def _dead_pid() -> int:
    done = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"],
                          capture_output=True, text=True, check=True)  # fmt: skip
    return int(done.stdout)


@pytest.fixture
def live():
    proc = subprocess.Popen(["sleep", "60"])
    yield proc.pid
    proc.kill()
    proc.wait()


def test_the_next_run_sweeps_the_temporaries_of_runs_that_no_longer_live(cell, capsys, live):
    model, rec, out = cell
    host, dead = io._host(), _dead_pid()
    gone = [
        f".soc.csv.{dead}@{host}.a1b2c3d4.tmp",
        f".soc.json.{dead}@{host}.bak.tmp",
        f".other.png.{dead}@{host}.zz_9y8x7.tmp",
        f".avoa-probe.{dead}@{host}.k2j3h4g5.tmp",
    ]
    kept = [f".soc.png.{live}@{host}.q1w2e3r4.tmp",  # a run that still writes
            f".soc.csv.{dead}@another-host.a1b2c3d4.tmp",  # its pid means nothing here
            ".soc.csv.a1b2c3d4.tmp", "notes.tmp"]  # fmt: skip  # not named by a run
    for name in gone + kept:
        (out / name).write_text("left by a run\n")
    assert main(_commands(model, rec, out)["estimate"]) == 0
    capsys.readouterr()
    assert _names(out) == sorted([*kept, "soc.csv", "soc.json", "soc.png"])


KILLED = """
import os, sys, time
from pathlib import Path
from avoa_pipeline import io
out = Path(sys.argv[1])
with io.atomic_paths(out / "soc.csv", out / "soc.json", out / "soc.png") as tmps:
    for t in tmps:
        t.write_text("half")
    print(" ".join(t.name for t in tmps), flush=True)
    time.sleep(60)
"""


def test_a_run_killed_mid_write_leaves_its_temporaries_for_one_run_only(cell, capsys):
    model, rec, out = cell
    env = {**os.environ, "PYTHONPATH": str(Path(io.__file__).parents[1])}
    proc = subprocess.Popen([sys.executable, "-c", KILLED, str(out)], stdout=subprocess.PIPE,
                            text=True, env=env)  # fmt: skip
    names = proc.stdout.readline().split()
    proc.send_signal(signal.SIGKILL)  # no clean-up runs
    proc.wait()
    proc.stdout.close()
    assert _names(out) == sorted(names)
    assert all(f".{proc.pid}@" in n for n in names)
    assert main(_commands(model, rec, out)["estimate"]) == 0
    capsys.readouterr()
    assert _names(out) == ["soc.csv", "soc.json", "soc.png"]


def test_a_folder_output_sweeps_inside_it(tmp_path):
    """``diagnose`` writes into its --out folder: the lock sweeps there."""
    out = tmp_path / "d"
    out.mkdir()
    stale = out / f".model.json.{_dead_pid()}@{io._host()}.a1b2c3d4.tmp"
    stale.write_text("{")
    beside = tmp_path / stale.name  # beside the folder: another output's business
    beside.write_text("{")
    with io.output_lock(out, folder=True, command="test"):
        assert not stale.exists()
    assert beside.exists()


def test_every_writer_sweeps_the_folder_it_writes_into(tmp_path):
    """The Snakemake jobs write through ``atomic_path`` without the lock: the sweep is there too.
    A temporary of the same pid in another pid namespace (a container sharing the host name) is
    another machine's."""
    dead, host = _dead_pid(), io._host()
    stale = tmp_path / f".r.json.{dead}@{host}.a1b2c3d4.tmp"
    other_ns = tmp_path / f".r.json.{dead}@{socket.gethostname()}-pidns1.a1b2c3d4.tmp"
    for p in (stale, other_ns):
        p.write_text("{")
    io.write_json({"a": 1}, tmp_path / "r.json")
    assert _names(tmp_path) == sorted([other_ns.name, "r.json"])


def test_a_temporary_that_cannot_be_removed_is_left_without_a_word(tmp_path, monkeypatch):
    """Another user's in a sticky folder (``/tmp``): not ours to remove, and no reason to fail."""
    theirs = tmp_path / f".r.json.{_dead_pid()}@{io._host()}.a1b2c3d4.tmp"
    theirs.write_text("{")
    real = os.unlink

    def unlink(path, *args, **kwargs):
        if Path(path) == theirs:
            raise PermissionError(errno.EPERM, os.strerror(errno.EPERM), str(path))
        return real(path, *args, **kwargs)

    monkeypatch.setattr(os, "unlink", unlink)
    assert io.sweep_temporaries(tmp_path) == []
    io.write_json({"a": 1}, tmp_path / "r.json")
    assert _names(tmp_path) == sorted([theirs.name, "r.json"])


def test_temporaries_are_named_by_their_run(tmp_path):
    with io.atomic_paths(tmp_path / "x.csv") as (tmp,):
        m = io._TMP_NAME.match(tmp.name)
        assert m is not None, tmp.name
        assert (m["name"], int(m["pid"]), m["host"]) == ("x.csv", os.getpid(), io._host())
        tmp.write_text("x\n")
    assert _names(tmp_path) == ["x.csv"]


# ----------------------------------------------------------------------------------------------
# part 3: a file still being written


def _cut(rec: Path, keep_chars: int) -> str:
    """Cut the record's last line after ``keep_chars`` characters, without its line end, as a
    cycler leaves it mid-write; returns the partial line."""
    lines = rec.read_text().splitlines(keepends=True)
    partial = lines[-1][:keep_chars]
    rec.write_text("".join(lines[:-1]) + partial)
    return partial


def test_an_unterminated_last_row_is_dropped_with_a_warning(cell, capsys, tmp_path):
    model, rec, out = cell
    whole = rec.read_text().splitlines(keepends=True)
    complete = tmp_path / "complete.csv"  # the record without its last row
    complete.write_text("".join(whole[:-1]))
    partial = _cut(rec, len(whole[-1].split(",")[0]) + 4)  # time, a digit or two of the current
    assert main(["simulate", str(model), str(complete), "--out", str(out / "want.csv")]) == 0
    capsys.readouterr()
    assert main(_commands(model, rec, out)["simulate"]) == 0
    err = capsys.readouterr().err
    warned = [x for x in err.splitlines() if "has no line end" in x]
    assert len(warned) == 1, err
    _one_line(warned[0], "warning", f"{rec}: line {len(whole)} ({partial!r})", "row was dropped")
    got, want = pd.read_csv(out / "sim.csv"), pd.read_csv(out / "want.csv")
    assert len(got) == len(whole) - 2  # the header and the partial row
    pd.testing.assert_frame_equal(got, want)


def test_a_complete_last_row_without_its_line_end_is_kept(tmp_path):
    """A last line without its line end whose last field is as long as its column's others is a
    file saved without its last line end: kept, no warning; one cut short (``3.`` where the
    column holds ``3.70``) or missing a field is dropped with its warning (docs/inputs.md)."""
    path = tmp_path / "r.csv"
    path.write_text("time_s,current_a,voltage_v\n0,1,3.70\n1,1,3.69")
    frame = io.read_csv(path)
    assert frame["time_s"].tolist() == [0, 1]
    assert not frame.attrs[io.READ_NOTES]
    for cut in ("1,1,3.", "1,1", "1,1,"):
        path.write_text(f"time_s,current_a,voltage_v\n0,1,3.70\n{cut}")
        frame = io.read_csv(path)
        assert frame["time_s"].tolist() == [0], cut
        assert "cut short" in frame.attrs[io.READ_NOTES][0]
        assert f"line 3 ({cut!r}) has no line end" in frame.attrs[io.READ_NOTES][0]
    path.write_text("time_s,current_a,voltage_v\r\n0,1,3.7\r\n1,1,3.69\r\n")
    assert io.read_csv(path).attrs[io.READ_NOTES] == ()
    assert len(io.read_csv(path)) == 2


def test_an_unterminated_row_of_an_ocv_table_is_dropped_with_a_warning(tmp_path):
    from avoa_pipeline import inputs

    path = tmp_path / "ocv.csv"
    soc = np.linspace(0, 1, 11)
    text = "soc,ocv_v\n" + "".join(f"{s:.1f},{3.0 + s:.3f}\n" for s in soc)
    path.write_text(text + "1.0,4.")
    table = inputs.read_ocv(path)
    assert any("line 13 ('1.0,4.') has no line end" in n for n in table.notes)
    assert table.values[-1] == pytest.approx(4.0)


# ----------------------------------------------------------------------------------------------
# part 4 (simulate): an option that does not apply


def test_an_ambient_for_a_model_without_a_heat_law_is_one_warning(cell, capsys):
    model, rec, out = cell
    assert main([*_commands(model, rec, out)["simulate"], "--ambient-c", "25"]) == 0
    err = capsys.readouterr().err
    warned = [x for x in err.splitlines() if "--ambient-c" in x]
    assert len(warned) == 1, err
    _one_line(warned[0], "warning", "--ambient-c 25: ignored:", f"{model} has no temperature law")
    assert main(_commands(model, rec, out)["simulate"]) == 0  # without it: no such line
    assert "--ambient-c" not in capsys.readouterr().err
    assert json.loads(model.read_text()).get("heat") is None  # the model has no heat block
