"""What Snakemake's own process costs while its jobs run: jobs that only wait, so every CPU second
measured is Snakemake's.

    .venv/bin/python benchmarks/bench_snakemake_idle.py [--jobs 60] [--seconds 4] [--inputs 100]

A throw-away workflow in a temporary folder: ``--jobs`` jobs that each sleep ``--seconds`` (one
core each, ``-j2``: two at a time, so the others wait ready, as the long diagnoses keep the
notebooks and tables of the whole study waiting), each reading ``--inputs`` small files (as a
notebook or a table rule reads many), then one job reading every job's output. Run twice,
Snakemake's default job-rate limit (100 per second) both times: as Snakemake schedules, and with
the workflow's ``snakemake_compat.coalesce_reevaluation`` (one re-evaluation timer pending), as
``workflow/rules/common.smk`` calls it. Printed per run: the wall seconds, Snakemake's CPU
seconds (user + system of the process and the ``sleep`` jobs it waited for, which cost next to
nothing), and the CPU share of one core it took.

Why (issue 42): in the whole study, Snakemake's process took a third of a core over its run
(1,571 s of CPU in 76 min; py-spy: the scheduler's job selection, ``update_input_sizes``
stat-ing the inputs of every ready job). The rate limiter's re-evaluation timer
(``JobScheduler._schedule_reevalutation``, Snakemake 9) is started in every scheduling round
with the limit's timespan as its delay, and each timer that fires starts a round, so every
round that a finished job triggers adds one more timer that re-fires each timespan: with
hundreds of finished jobs, hundreds of rounds a second while the ready jobs wait for cores.
"""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

SNAKEFILE = """
if config.get("coalesce"):
    from avoa_pipeline import snakemake_compat
    snakemake_compat.coalesce_reevaluation()
N = {jobs}
rule all:
    input: expand("out/{{i}}.txt", i=range(N))
    output: "done.txt"
    shell: "cat {{input}} > {{output}}"

rule wait:
    input: expand("in/{{k}}.txt", k=range({inputs}))
    output: "out/{{i}}.txt"
    threads: 1
    shell: "sleep {seconds} && echo {{wildcards.i}} > {{output}}"
"""


def run(workdir: Path, coalesce: bool) -> tuple[float, float]:
    """One run of the workflow in ``workdir`` (outputs removed first): (wall s, CPU s)."""
    shutil.rmtree(workdir / "out", ignore_errors=True)
    shutil.rmtree(workdir / ".snakemake", ignore_errors=True)
    (workdir / "done.txt").unlink(missing_ok=True)
    cmd = [sys.executable, "-m", "snakemake", "-j2", "--quiet", "all", "--scheduler", "greedy",
           "--directory", str(workdir), "--snakefile", str(workdir / "Snakefile"),
           "--config", f"coalesce={int(coalesce)}"]  # fmt: skip
    env = {**os.environ, "XDG_CACHE_HOME": str(workdir / ".cache")}
    t0 = time.perf_counter()
    proc = subprocess.Popen(cmd, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    _, status, ru = os.wait4(proc.pid, 0)
    wall = time.perf_counter() - t0
    if os.waitstatus_to_exitcode(status) != 0:
        raise SystemExit(f"snakemake failed: {proc.stderr.read().decode()[-2000:]}")
    return wall, ru.ru_utime + ru.ru_stime


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--jobs", type=int, default=60)
    ap.add_argument("--seconds", type=float, default=4.0)
    ap.add_argument("--inputs", type=int, default=100)
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        wd = Path(tmp)
        (wd / "in").mkdir()
        for k in range(args.inputs):
            (wd / "in" / f"{k}.txt").write_text(f"{k}\n")
        (wd / "Snakefile").write_text(SNAKEFILE.format(jobs=args.jobs, inputs=args.inputs,
                                                       seconds=args.seconds))  # fmt: skip
        print(f"{args.jobs} jobs of {args.seconds:g} s on 2 cores, {args.inputs} inputs each")
        print("| re-evaluation timers | wall s | Snakemake CPU s | share of a core |")
        print("|---|---:|---:|---:|")
        for coalesce in (False, True):
            wall, cpu = run(wd, coalesce)
            what = "one pending (coalesce_reevaluation)" if coalesce else "Snakemake's own"
            print(f"| {what} | {wall:.1f} | {cpu:.1f} | {cpu / wall:.0%} |")


if __name__ == "__main__":
    main()
