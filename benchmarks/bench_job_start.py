"""What a workflow job spends before its first useful instruction, per job kind.

    .venv/bin/python benchmarks/bench_job_start.py [--repeat 5]

Each measurement is a fresh process, as Snakemake starts one per job; the median of ``--repeat``
runs is printed. Stages:

- ``interpreter``: ``python -c pass`` (start and exit);
- ``script preamble``: what Snakemake's ``script:`` preamble imports (``snakemake.script``,
  ``pickle``) before the rule's script runs;
- fit job: the package imports of ``workflow/scripts/fit.py``, then ``problem.build`` of a
  scenario-4 dataset and the first population-kernel call (numba's cache loaded, nothing
  compiled: the benchmark runs one warm-up process first);
- diagnosis job: the imports of ``workflow/scripts/gap_diagnose.py``, then the whole
  ``diagnose_file`` of a paper dataset, and the diagnosis's own clock (``wall_s``, which starts
  after the record is read): the difference is reading, checking and kernel loading;
- notebook job: papermill executing a one-cell notebook that imports what the report notebooks
  import (``avoa_pipeline.report``), with the ``avoa-pipeline`` kernel: papermill's start, the
  kernel's start and the imports.

Then the start-up cost of the paper grid's fit jobs (``config/config.yaml``, one block of seeds
per job): the fit job's start-up × their number, with one job per scenario × case × algorithm
(before issue 20) and with one per scenario × case.
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

PY = sys.executable

FIT_CHILD = """
import json, sys, time
t0 = time.perf_counter()
from avoa_pipeline import jobs
from avoa_pipeline.jobs.identify import fit_algorithms
t1 = time.perf_counter()
import numpy as np
from avoa_pipeline import config, problem
prob = problem.build(config.load(), 4, 4, data=sys.argv[1])
prob.objective(np.tile((prob.lb + prob.ub) / 2, (20, 1)))
t2 = time.perf_counter()
print(json.dumps({"imports": t1 - t0, "kernel load": t2 - t1}))
"""

DIAG_CHILD = """
import json, sys, time
t0 = time.perf_counter()
from avoa_pipeline import jobs
from avoa_pipeline.jobs.gap import diagnose_file
t1 = time.perf_counter()
diagnose_file(sys.argv[1], sys.argv[2])
t2 = time.perf_counter()
wall = json.loads(open(sys.argv[2]).read())["wall_s"]
print(json.dumps({"imports": t1 - t0, "read, check, kernel load": t2 - t1 - wall,
                  "diagnosis": wall}))
"""

NOTEBOOK = {
    "cells": [{"cell_type": "code", "execution_count": None, "id": "c1", "metadata": {},
               "outputs": [], "source": ["from avoa_pipeline.report import figures, tables\n"]}],
    "metadata": {"kernelspec": {"display_name": "avoa-pipeline", "language": "python",
                                "name": "avoa-pipeline"}},
    "nbformat": 4, "nbformat_minor": 5,
}  # fmt: skip


def timed(cmd: list[str]) -> tuple[float, str]:
    t0 = time.perf_counter()
    out = subprocess.run(cmd, capture_output=True, text=True, check=True).stdout
    return time.perf_counter() - t0, out


def median_of(cmd: list[str], repeat: int) -> tuple[float, dict]:
    """Median wall of ``cmd`` and the medians of the stage times it prints (a JSON line)."""
    walls, stages = [], {}
    for _ in range(repeat):
        wall, out = timed(cmd)
        walls.append(wall)
        lines = [ln for ln in out.splitlines() if ln.startswith("{")]
        for k, v in (json.loads(lines[-1]) if lines else {}).items():
            stages.setdefault(k, []).append(v)
    return statistics.median(walls), {k: statistics.median(v) for k, v in stages.items()}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--repeat", type=int, default=5)
    args = ap.parse_args()
    from avoa_pipeline import config
    from avoa_pipeline.jobs import data as data_jobs

    cfg = config.load()
    tmp = Path(tempfile.mkdtemp(prefix="bench_job_start_"))
    data = tmp / "s4c4.csv"
    data_jobs.dataset(cfg, 4, 4, str(data))
    nb = tmp / "start.ipynb"
    nb.write_text(json.dumps(NOTEBOOK))
    fit_cmd = [PY, "-c", FIT_CHILD, str(data)]
    diag_cmd = [PY, "-c", DIAG_CHILD, str(data), str(tmp / "diag.json")]
    nb_cmd = [PY, "-m", "papermill", "--no-progress-bar", "-k", "avoa-pipeline", str(nb),
              str(tmp / "out.ipynb")]  # fmt: skip
    for cmd in (fit_cmd, diag_cmd, nb_cmd):  # warm-up: numba's cache and the OS's file cache
        timed(cmd)
    rows = []
    base, _ = median_of([PY, "-c", "pass"], args.repeat)
    rows.append(("any job", "interpreter", base))
    pre, _ = median_of([PY, "-c", "import pickle; from snakemake import script"], args.repeat)
    rows.append(("script job", "script preamble (beyond the interpreter)", pre - base))
    fit_wall, fit = median_of(fit_cmd, args.repeat)
    rows += [("fit job", k, v) for k, v in fit.items()]
    diag_wall, diag = median_of(diag_cmd, args.repeat)
    rows += [("diagnosis job", k, v) for k, v in diag.items()]
    nb_wall, _ = median_of(nb_cmd, args.repeat)
    rows.append(("notebook job", "papermill + kernel start + report imports", nb_wall))
    print(f"{'job':<15} {'stage':<45} {'s':>7}")
    for job, stage, s in rows:
        print(f"{job:<15} {stage:<45} {s:7.3f}")
    fit_start = pre + fit_wall  # interpreter, preamble, imports, kernel load, exit
    diag_start = pre + diag_wall - diag.get("diagnosis", 0.0)
    print(
        f"\nstart-up before the first useful instruction (wall, one process): fit job "
        f"{fit_start:.2f} s, diagnosis job {diag_start:.2f} s, notebook job {nb_wall:.2f} s"
    )
    pairs = len(cfg["scenarios"]) * len(cfg["cases"])
    for n, per in ((pairs * len(cfg["algorithms"]), "scenario × case × algorithm"),
                   (pairs, "scenario × case")):  # fmt: skip
        print(f"paper grid, {n} fit jobs (one per {per}): {n * fit_start:.0f} s of start-up")


if __name__ == "__main__":
    main()
