"""Time a Snakemake run of this workflow and say where the time went.

    .venv/bin/python benchmarks/bench_workflow.py                 # `snakemake -j2 paper` here
    .venv/bin/python benchmarks/bench_workflow.py --target all --cores 2 --workdir /work/clone

Run it in a fresh clone (``results/`` absent) for the full cost; in a directory with results it
times whatever is out of date. Prints the wall time, the Snakemake process's own CPU time (its
per-job overhead), the CPU time of everything it started, the number of jobs per rule, and the
optimizer time per algorithm from ``results/aggregate/runs.parquet``. Nothing is asserted.
"""

from __future__ import annotations

import argparse
import os
import re
import subprocess
import sys
import time
from collections import Counter
from pathlib import Path

import psutil

ROOT = Path(__file__).resolve().parents[1]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--target", default="paper")
    ap.add_argument("--cores", type=int, default=2)
    ap.add_argument("--workdir", type=Path, default=ROOT)
    ap.add_argument("--configfile", default=None)
    ap.add_argument("--log", type=Path, default=None, help="Snakemake's output (default: temp)")
    args = ap.parse_args()

    wd = args.workdir.resolve()
    snakemake = Path(sys.executable).with_name("snakemake")
    cmd = [str(snakemake), f"-j{args.cores}", args.target]
    if args.configfile:
        cmd += ["--configfile", args.configfile]
    env = dict(os.environ, XDG_CACHE_HOME=str(wd / ".cache"))
    log = args.log or wd / "logs" / "bench_workflow.log"
    log.parent.mkdir(parents=True, exist_ok=True)

    t0 = time.perf_counter()
    with log.open("w") as out:
        proc = subprocess.Popen(cmd, cwd=wd, env=env, stdout=out, stderr=subprocess.STDOUT)
        main_proc = psutil.Process(proc.pid)
        main_cpu = 0.0
        while proc.poll() is None:
            try:
                t = main_proc.cpu_times()
                main_cpu = t.user + t.system  # the scheduler, bookkeeping and `run:` threads
            except psutil.NoSuchProcess:
                break
            time.sleep(1.0)
        rc = proc.wait()
    wall = time.perf_counter() - t0
    children = os.times()  # every waited-for descendant: fit workers, papermill kernels, ...

    text = log.read_text()
    jobs = Counter(re.findall(r"^(?:local)?rule (\w+):", text, flags=re.M))
    n_jobs = sum(jobs.values())
    print(f"command: {' '.join(cmd)}  (in {wd})")
    print(f"exit code {rc}; wall {int(wall // 60)} min {wall % 60:.0f} s ({wall:.0f} s)")
    print(
        f"Snakemake process CPU: {main_cpu:.0f} s"
        + (f" = {main_cpu / n_jobs * 1000:.0f} ms per job over {n_jobs} jobs" if n_jobs else "")
    )
    print(f"CPU of all child processes: {children.children_user + children.children_system:.0f} s")
    for rule, n in sorted(jobs.items(), key=lambda kv: -kv[1]):
        print(f"  {rule:28s} {n:5d} jobs")

    runs = wd / "results" / "aggregate" / "runs.parquet"
    if runs.exists():
        import pandas as pd

        df = pd.read_parquet(runs)
        per = df.groupby("algorithm")["wall_s"].agg(["mean", "sum", "count"])
        total = per["sum"].sum()
        print(f"optimizer wall time in the records: {total:.0f} s over {len(df)} fits")
        for algo, row in per.sort_values("sum", ascending=False).iterrows():
            print(
                f"  {algo:14s} {row['mean']:.2f} s per fit  {row['sum']:7.0f} s "
                f"({100 * row['sum'] / total:.0f} %)"
            )
    sys.exit(rc)


if __name__ == "__main__":
    main()
