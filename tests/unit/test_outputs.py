"""Outputs: no command overwrites an input, every output path is judged before any work, files
written together are written all or none, and one run at a time writes an output (the lock)."""

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
import yaml

from avoa_pipeline import io
from avoa_pipeline.cli import main
from avoa_pipeline.errors import DataError, UserError

FIT = ["fit", "--scenario", "1", "--case", "2", "--algorithm", "avoa", "--seed", "3"]
FAST = ["--iterations", "3", "--pop-size", "6"]
GENERATE = ["generate", "--scenario", "1", "--case", "2"]


def _error(capsys, needle: str) -> str:
    err = capsys.readouterr().err
    lines = err.splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith("error: "), err
    assert "Traceback" not in err
    assert needle in lines[0], lines[0]
    return lines[0]


def _tree(folder: Path) -> dict[str, bytes | None]:
    """Every path under ``folder`` with its bytes (None for a folder or a symlink)."""
    out = {}
    for p in sorted(folder.rglob("*")):
        plain = p.is_file() and not p.is_symlink()
        out[str(p.relative_to(folder))] = p.read_bytes() if plain else None
    return out


@pytest.fixture(scope="module")
def dataset(tmp_path_factory) -> Path:
    """A generated dataset (CSV + sidecar) of scenario 1 × case 2."""
    path = tmp_path_factory.mktemp("data") / "g.csv"
    assert main([*GENERATE, "--out", str(path)]) == 0
    return path


@pytest.fixture
def data(tmp_path, dataset) -> Path:
    """A private copy of :func:`dataset` with its sidecar, in ``tmp_path``."""
    copy = tmp_path / dataset.name
    copy.write_bytes(dataset.read_bytes())
    io.sidecar_of(copy).write_bytes(io.sidecar_of(dataset).read_bytes())
    return copy


@pytest.fixture
def no_work(monkeypatch):
    """Fail the test if a command gets as far as building a problem or fitting."""
    from avoa_pipeline import fit, problem, recovery, synthetic

    def boom(*args, **kwargs):
        raise AssertionError("the command started its work before refusing")

    for module, name in ((problem, "build"), (fit, "run"), (recovery, "recover"),
                         (synthetic, "generate")):  # fmt: skip
        monkeypatch.setattr(module, name, boom)


# ----------------------------------------------------------------------------------------------
# inputs are never overwritten


def test_fit_refuses_its_data_and_the_datas_sidecar_as_out(tmp_path, capsys, data, no_work):
    before = _tree(tmp_path)
    assert main([*FIT, *FAST, "--data", str(data), "--out", str(data)]) == 2
    _error(capsys, "is an input of this command")
    assert main([*FIT, *FAST, "--data", str(data), "--out", str(io.sidecar_of(data))]) == 2
    _error(capsys, f"is the sidecar of the input {data}")
    assert _tree(tmp_path) == before


def test_generate_writes_a_csv_whose_sidecar_is_no_input(tmp_path, capsys, cfg, no_work):
    assert main([*GENERATE, "--out", str(tmp_path / "g.json")]) == 2
    _error(capsys, "must end .csv")
    config = tmp_path / "c.json"  # YAML reads JSON: a config that is some CSV's sidecar
    config.write_text(json.dumps(cfg))
    before = _tree(tmp_path)
    assert main([*GENERATE, "--config", str(config), "--out", str(tmp_path / "c.csv")]) == 2
    _error(capsys, f"--out's sidecar {config}: is an input")
    assert _tree(tmp_path) == before


def test_every_command_protects_the_sidecars_of_its_inputs(tmp_path, capsys, data):
    model = tmp_path / "model.json"
    model.write_text("{}")
    before = _tree(tmp_path)
    assert main(["simulate", str(model), str(data), "--out", str(io.sidecar_of(data))]) == 2
    _error(capsys, "is the sidecar of the input")
    # diagnose writes model.json into --out: the sidecar of a record named model.csv there
    record = data.rename(tmp_path / "model.csv")
    model.rename(tmp_path / "model.json")
    before = _tree(tmp_path)
    assert main(["diagnose", str(record), "--out", str(tmp_path)]) == 2
    _error(capsys, f"is the sidecar of the input {record}")
    assert _tree(tmp_path) == before


# ----------------------------------------------------------------------------------------------
# output paths are judged before any work


def _unwritable(tmp_path) -> Path:
    """A folder this process cannot write in (root writes anywhere chmod allows: use /sys)."""
    folder = tmp_path / "ro"
    folder.mkdir()
    folder.chmod(0o555)
    if os.access(folder, os.W_OK):
        if not os.path.isdir("/sys"):
            pytest.skip("running as root without /sys: no unwritable folder to test with")
        return Path("/sys")
    return folder


def _loop(tmp_path) -> Path:
    loop = tmp_path / "loop.json"
    loop.symlink_to(loop)
    return loop


def _dangling(tmp_path) -> Path:
    link = tmp_path / "dangling.json"
    link.symlink_to(tmp_path / "nowhere" / "r.json")
    return link


@pytest.mark.parametrize(
    ("make_out", "needle"),
    [
        (lambda d: "", "--out: empty path"),
        (lambda d: "  ", "--out: empty path"),
        (lambda d: _unwritable(d) / "r.json", "cannot write in"),
        (_dangling, "a symlink to"),
        (_loop, "a symlink loop"),
        (lambda d: d / ("n" * 300 + ".json"), "too long"),
        (lambda d: d.joinpath(*["deep"] * 1000, "r.json"), "too long"),
        (lambda d: d / "a-file" / "r.json", "is a file, not a folder"),
        (lambda d: d, "is a folder; need a file"),
    ],
    ids=["empty", "blank", "unwritable", "dangling", "loop", "300", "5000", "under-file", "folder"],
)
def test_fit_refuses_an_output_path_before_any_work(tmp_path, capsys, no_work, make_out, needle):
    (tmp_path / "a-file").write_text("x")
    out = make_out(tmp_path)
    before = _tree(tmp_path)
    assert main([*FIT, *FAST, "--out", str(out)]) == 2
    line = _error(capsys, needle)
    assert len(line) < 400  # a 5000-character path is shortened
    assert _tree(tmp_path) == before


def test_generate_refuses_a_folder_in_the_sidecars_place_and_writes_nothing(tmp_path, capsys):
    (tmp_path / "g.json").mkdir()
    assert main([*GENERATE, "--out", str(tmp_path / "g.csv")]) == 2
    _error(capsys, "--out's sidecar")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["g.json"]


def test_recovery_checks_both_outputs_first(tmp_path, capsys, no_work):
    recovery = ["recovery", "--scenario", "1", "--case", "2", "--out"]
    assert main([*recovery, str(tmp_path / "r.md")]) == 2
    _error(capsys, "must end .csv")
    (tmp_path / "r.md").mkdir()
    assert main([*recovery, str(tmp_path / "r.csv")]) == 2
    _error(capsys, "--out's summary")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["r.md"]


def test_a_negative_seed_is_an_argument_error(tmp_path, capsys, no_work):
    args = [a if a != "3" else "-1" for a in FIT]
    assert main([*args, "--out", str(tmp_path / "r.json")]) == 2
    _error(capsys, "--seed must be 0 or more, got -1")
    assert list(tmp_path.iterdir()) == []


# ----------------------------------------------------------------------------------------------
# inputs that are not what they claim


@pytest.mark.parametrize(
    ("make", "needle"),
    [
        (lambda p: p.write_text("{not json"), "not readable JSON (sidecar of"),
        (lambda p: p.write_text("[1, 2]"), "not a JSON object (sidecar of"),
        (lambda p: p.mkdir(), "a folder, not a JSON file (sidecar of"),
        (lambda p: p.symlink_to(p), "cannot read (sidecar of"),
    ],
    ids=["malformed", "a list", "a folder", "a loop"],
)
def test_a_broken_sidecar_is_one_line(tmp_path, capsys, data, make, needle):
    side = io.sidecar_of(data)
    side.unlink()
    make(side)
    out = tmp_path / "out" / "r.json"
    assert main([*FIT, *FAST, "--data", str(data), "--out", str(out)]) == 2
    _error(capsys, f"{side}: {needle}")
    assert not (tmp_path / "out").exists()


def test_a_symlink_loop_as_model_is_one_line(tmp_path, capsys, data):
    model = _loop(tmp_path)
    assert main(["simulate", str(model), str(data), "--out", str(tmp_path / "p.csv")]) == 2
    _error(capsys, str(model))
    assert not (tmp_path / "p.csv").exists()


def test_a_device_is_refused_without_reading_it(tmp_path, capsys):
    # /dev/zero has no end and no line end: a reader that read it whole would never return
    assert main(["diagnose", "/dev/zero", "--out", str(tmp_path / "d")]) == 2
    _error(capsys, "/dev/zero: not a regular file")
    assert list(tmp_path.iterdir()) == []


def test_a_device_as_model_is_refused_without_reading_it(tmp_path, capsys, data):
    assert main(["simulate", "/dev/zero", str(data), "--out", str(tmp_path / "p.csv")]) == 2
    _error(capsys, "/dev/zero: not a regular file")
    assert not (tmp_path / "p.csv").exists()


def test_the_header_is_read_within_its_bound(tmp_path):
    junk = tmp_path / "junk.csv"
    junk.write_bytes(b"7" * (io.HEADER_BYTES + 1))
    with pytest.raises(DataError, match="no line end in the first 64 KiB"):
        io.read_csv(junk)
    fits = tmp_path / "long-header.csv"
    names = [f"c{k}" for k in range(io.HEADER_BYTES // 8)]
    fits.write_text(",".join(names) + "\n" + ",".join("1" * len(names)) + "\n")
    assert list(io.read_csv(fits).columns) == names  # a long header within the bound is read


# ----------------------------------------------------------------------------------------------
# several files: all or none


def test_atomic_paths_puts_back_what_it_replaced_when_a_later_rename_fails(tmp_path):
    first, second = tmp_path / "a.csv", tmp_path / "a.json"
    first.write_text("old\n")
    with (  # noqa: PT012
        pytest.raises(UserError, match=r"a\.json: cannot write"),
        io.atomic_paths(first, second) as (t1, t2),
    ):
        t1.write_text("new\n")
        t2.write_text("{}\n")
        second.mkdir()  # after the checks: a folder appears where the file goes
        (second / "x").write_text("keeps it from being replaced")
    assert first.read_text() == "old\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.csv", "a.json"]
    with io.atomic_paths(tmp_path / "b.csv", tmp_path / "b.json") as (t1, t2):
        t1.write_text("b\n")
        t2.write_text("{}\n")
    assert (tmp_path / "b.csv").read_text() == "b\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.csv", "a.json", "b.csv", "b.json"]


def test_generate_writes_the_csv_and_the_sidecar_that_describes_it(tmp_path):
    out = tmp_path / "g.csv"
    assert main([*GENERATE, "--out", str(out)]) == 0
    assert io.read_sidecar(out)["csv_sha256"] == io.sha256(out)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["g.csv", "g.json"]


# ----------------------------------------------------------------------------------------------
# the output lock

HOLD = """
import sys, time
from avoa_pipeline.io import output_lock
with output_lock(sys.argv[1], folder=sys.argv[2] == "folder", command="the holder"):
    print("held", flush=True)
    time.sleep(60)
"""


@pytest.fixture
def holder():
    """Start a process that holds the lock of an output until killed."""
    procs = []

    def start(out: Path, folder: bool = False) -> subprocess.Popen:
        env = {**os.environ, "PYTHONPATH": str(Path(io.__file__).parents[1])}
        proc = subprocess.Popen(
            [sys.executable, "-c", HOLD, str(out), "folder" if folder else "file"],
            stdout=subprocess.PIPE,
            text=True,
            env=env,
        )
        procs.append(proc)
        assert proc.stdout.readline().strip() == "held"
        return proc

    yield start
    for proc in procs:
        if proc.poll() is None:
            proc.kill()
        proc.wait()
        proc.stdout.close()


def test_a_second_run_on_a_locked_output_is_refused_naming_the_first(tmp_path, capsys, holder):
    out = tmp_path / "d"
    proc = holder(out, folder=True)
    started = json.loads((out / ".avoa-lock").read_text())["start"]
    assert main(["diagnose", "/dev/null", "--out", str(out)]) == 2
    _error(capsys, f"another run is writing it (pid {proc.pid} on ")
    assert main(["diagnose", "/dev/null", "--out", str(out)]) == 2
    assert started in capsys.readouterr().err
    assert [p.name for p in out.iterdir()] == [".avoa-lock"]  # the holder's, nothing else


def test_the_lock_of_a_killed_run_is_taken_over(tmp_path, capsys, holder):
    out = tmp_path / "g.csv"
    proc = holder(out)
    assert main([*GENERATE, "--out", str(out)]) == 2
    _error(capsys, f"pid {proc.pid}")
    proc.send_signal(signal.SIGKILL)  # no clean-up runs: its lock file stays behind
    proc.wait()
    assert (tmp_path / ".g.csv.avoa-lock").exists()
    assert main([*GENERATE, "--out", str(out)]) == 0
    assert sorted(p.name for p in tmp_path.iterdir()) == ["g.csv", "g.json"]


def test_the_lock_is_released_on_an_error_and_its_folders_removed(tmp_path, capsys):
    out = tmp_path / "new" / "deeper" / "r.json"
    bad = tmp_path / "bad.csv"
    bad.write_text("time_s;current_a;voltage_v\n")
    assert main([*FIT, *FAST, "--data", str(bad), "--out", str(out)]) == 2
    _error(capsys, "separated by ';'")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bad.csv"]


def test_a_lock_names_its_holder_and_is_gone_after_it(tmp_path):
    out = tmp_path / "r.json"
    with io.output_lock(out, command="avoa_pipeline fit ...") as lock:
        info = json.loads(lock.read_text())
        assert info["pid"] == os.getpid()
        assert info["command"] == "avoa_pipeline fit ..."
        assert abs(time.time() - _epoch(info["start"])) < 60
        with pytest.raises(UserError, match=f"pid {os.getpid()}"), io.output_lock(out):
            pass
    assert list(tmp_path.iterdir()) == []


def _epoch(iso: str) -> float:
    from datetime import datetime

    return datetime.fromisoformat(iso).timestamp()


def test_a_config_that_is_no_mapping_is_still_one_line(tmp_path, capsys):
    config = tmp_path / "c.yaml"
    config.write_text(yaml.safe_dump([1, 2]))
    assert main([*FIT, *FAST, "--config", str(config), "--out", str(tmp_path / "r.json")]) == 2
    _error(capsys, str(config))
    assert sorted(p.name for p in tmp_path.iterdir()) == ["c.yaml"]
