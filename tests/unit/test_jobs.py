"""Job execution any executor can run: every package rule has an adapter, a job stops when its
Snakemake dies, and a killed run's locks are cleared only when no Snakemake works there."""

import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path
from types import SimpleNamespace

import psutil
import pytest

from avoa_pipeline import jobguard, jobs, snakemake_compat

REPO = Path(__file__).resolve().parents[2]


def _fake_snakemake(tmp_path: Path, body: str) -> Path:
    """A Python script whose file name is ``snakemake`` (what the guard and the lock check
    recognise in a command line)."""
    path = tmp_path / "bin" / "snakemake"
    path.parent.mkdir(exist_ok=True)
    path.write_text(textwrap.dedent(body))
    return path


def test_every_script_rule_has_an_adapter():
    rules = []
    for smk in (REPO / "workflow/rules").glob("*.smk"):
        text = smk.read_text()
        for block in text.split("rule ")[1:]:
            name = block.split(":")[0].strip()
            if "scripts/job.py" in block.split("\nrule ")[0] and name.isidentifier():
                rules.append(name)
    assert "dataset" in rules
    for name in rules:
        assert jobs.adapter(name), name
    assert jobs.adapter("fit_3") is jobs.fit
    with pytest.raises(KeyError, match="no job adapter"):
        jobs.adapter("nonsense")


def test_dataset_adapter_runs_without_snakemake(cfg, tmp_path):
    out = SimpleNamespace(csv=str(tmp_path / "s1c2.csv"), meta=str(tmp_path / "s1c2.json"))
    job = SimpleNamespace(rule="dataset", config=cfg, wildcards=SimpleNamespace(scenario="1",
                          case="2"), output=out, log=[str(tmp_path / "d.log")])  # fmt: skip
    jobs.run(job)
    assert Path(out.csv).stat().st_size > 0
    assert "wrote" in (tmp_path / "d.log").read_text()


def test_a_job_stops_when_its_snakemake_is_killed(tmp_path):
    """A job (grandchild through a shell, as Snakemake's shell rules run it) ends within a
    second or two of a kill -9 of its Snakemake; without a Snakemake ancestor it is left alone."""
    child = tmp_path / "child.py"
    child.write_text("import time\nfrom avoa_pipeline import jobguard\n"
                     "jobguard.watch(0.1)\ntime.sleep(60)\n")  # fmt: skip
    shell_cmd = f"{sys.executable} {child}"
    fake = _fake_snakemake(tmp_path, f"""
        import subprocess, time
        subprocess.Popen(["/bin/sh", "-c", {shell_cmd!r}])
        time.sleep(60)
    """)  # fmt: skip
    parent = subprocess.Popen([sys.executable, str(fake)], start_new_session=True)
    try:
        deadline = time.monotonic() + 30
        kids = []
        while time.monotonic() < deadline:
            kids = [p for p in psutil.Process(parent.pid).children(recursive=True)
                    if "child.py" in " ".join(p.cmdline())]  # fmt: skip
            if kids:
                break
            time.sleep(0.1)
        assert kids
        time.sleep(1.0)  # the guard is running
        os.kill(parent.pid, signal.SIGKILL)
        parent.wait()
        _, alive = psutil.wait_procs(kids, timeout=5)
        assert not alive
    finally:
        parent.kill()
        parent.wait()
    assert jobguard.snakemake_ancestor() is None  # pytest has no Snakemake above it


def test_stale_locks_are_cleared_only_without_a_live_snakemake_here(tmp_path):
    locks = tmp_path / ".snakemake" / "locks"
    locks.mkdir(parents=True)
    (locks / "0.input.lock").write_text("x")
    fake = _fake_snakemake(tmp_path, "import time; time.sleep(60)")
    live = subprocess.Popen([sys.executable, str(fake)], cwd=tmp_path)
    try:
        time.sleep(0.5)
        assert snakemake_compat.live_snakemakes_here(tmp_path) == [live.pid]
        assert snakemake_compat.clear_stale_locks(tmp_path, True, False) == []
        assert (locks / "0.input.lock").exists()
    finally:
        live.kill()
        live.wait()
    assert snakemake_compat.clear_stale_locks(tmp_path, False, False) == []  # not the main run
    assert snakemake_compat.clear_stale_locks(tmp_path, True, False) == ["0.input.lock"]
    assert not (locks / "0.input.lock").exists()
