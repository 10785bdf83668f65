"""The tiny config on a real SLURM through Snakemake's SLURM executor, checked against a local run.

Needs a SLURM whose node takes jobs and the cluster extra (`environment-slurm.txt`, Snakemake's
SLURM executor): `scripts/slurm-local.sh start` sets up both on a Debian machine (docs/cluster.md).
Skipped, with the reason, where `sinfo` is missing, the plugin is not installed or no node is idle.
"""

from __future__ import annotations

import importlib.util
import os
import pwd
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

# the tiny run's helpers (fresh copy of the workflow, snakemake call, record without timings)
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "workflow"))
from test_tiny import _record, fresh_copy, snakemake

pytestmark = pytest.mark.slurm

# What a cluster user types (profiles/slurm: executor, resources, grouping, squeue status), plus
# a first status check after 5 s instead of 40 s: the tiny config's jobs take seconds
SLURM_ARGS = ("--workflow-profile", "profiles/slurm", "--slurm-init-seconds-before-status-checks",
              "5")  # fmt: skip
TARGET = "results/aggregate/runs.parquet"  # every fit record and their aggregates


def _slurm_ready() -> str | None:
    """Why SLURM cannot take the test's jobs here, or None if it can."""
    if shutil.which("sinfo") is None:
        return "sinfo not found: no SLURM here (scripts/slurm-local.sh start sets one up)"
    if importlib.util.find_spec("snakemake_executor_plugin_slurm") is None:
        return (
            "snakemake-executor-plugin-slurm not installed (the cluster extra: pip install -r "
            "environment-slurm.txt; scripts/slurm-local.sh start installs it)"
        )
    proc = subprocess.run(
        ["sinfo", "-h", "-N", "-o", "%N %t"],
        capture_output=True,
        text=True,
        check=False,
        timeout=30,
    )
    states = proc.stdout.split()[1::2]
    if proc.returncode != 0 or not {"idle", "mix"} & set(states):
        said = (proc.stdout + proc.stderr).strip().replace("\n", "; ") or "nothing"
        return f"no idle SLURM node (sinfo: {said}); scripts/slurm-local.sh start starts one"
    return None


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    reason = _slurm_ready()
    if reason:
        pytest.skip(reason)
    base = tmp_path_factory.mktemp("slurm")
    with pytest.MonkeyPatch.context() as mp:
        # the plugin reads os.environ["USER"] (a KeyError without it, e.g. in CI)
        mp.setenv("USER", os.environ.get("USER") or pwd.getpwuid(os.getuid()).pw_name)
        # the reference needs only the fits (tests/workflow runs the rest locally)
        local = fresh_copy(base / "local")
        proc = snakemake(local, "-j2", TARGET)
        assert proc.returncode == 0, proc.stderr[-4000:]
        cluster = fresh_copy(base / "slurm")
        proc = snakemake(cluster, *SLURM_ARGS, TARGET)
        assert proc.returncode == 0, proc.stderr[-6000:] + _failed_job_logs(cluster)
    return {"local": local, "slurm": cluster}


def _failed_job_logs(wd: Path) -> str:
    """The ends of the SLURM job logs that say a job failed (they hold the job's own error)."""
    out = []
    for log in sorted((wd / ".snakemake/slurm_logs").rglob("*.log")):
        text = log.read_text(errors="replace")
        if "Error" in text or "error:" in text:
            out.append(f"\n--- {log.relative_to(wd)}\n{text[-1500:]}")
    return "".join(out[:3])


def test_slurm_records_equal_a_local_run(runs):
    """Same fit records (best_params, best_ise, nfe, history; timings and versions aside)."""
    local, cluster = runs["local"], runs["slurm"]
    names = sorted(p.relative_to(local) for p in (local / "results/fits").rglob("*.json"))
    on_slurm = sorted(p.relative_to(cluster) for p in (cluster / "results/fits").rglob("*.json"))
    assert names == on_slurm
    assert len(names) == 2 * 2 * 3 * 2
    for name in names:
        assert _record(cluster / name) == _record(local / name), name
