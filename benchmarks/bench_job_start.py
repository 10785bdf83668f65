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
  kernel's start and the imports; beside it the same notebook without a kernel (``NO_KERNEL``:
  papermill parameterizes it and its cells run by ``exec`` in papermill's own process, the least
  any in-process engine such as ploomber-engine's could cost), the report's imports alone and
  the job guard (``python -m avoa_pipeline.jobguard``) that the rules put around papermill.

Each row gives the wall and the CPU seconds (user + system of the process and its children,
``RUSAGE_CHILDREN``): on a shared machine the CPU seconds are the measure, the wall what one
waits.

Then the start-up cost of the paper grid's fit jobs (``config/config.yaml``, one block of seeds
per job): the fit job's start-up × their number, with one job per scenario × case × algorithm
(before issue 20) and with one per scenario × case.
"""

from __future__ import annotations

import argparse
import json
import resource
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


# A notebook run without a kernel: papermill's parameterization, then every code cell exec'd in
# this process's namespace (outputs not captured): a lower bound for an in-process engine.
NO_KERNEL = """
import sys
import nbformat
from papermill.iorw import load_notebook_node
from papermill.parameterize import parameterize_notebook
nb = parameterize_notebook(load_notebook_node(sys.argv[1]), {})
ns = {"__name__": "__main__"}
for cell in nb.cells:
    if cell.cell_type == "code":
        exec(compile(cell.source, "<cell>", "exec"), ns)
nbformat.write(nb, sys.argv[2])
"""


def cpu_children() -> float:
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def timed(cmd: list[str]) -> tuple[float, float, str]:
    """Wall and CPU seconds of ``cmd`` (its processes, children included) and its stdout."""
    c0, t0 = cpu_children(), time.perf_counter()
    out = subprocess.run(cmd, capture_output=True, text=True, check=True).stdout
    return time.perf_counter() - t0, cpu_children() - c0, out


def median_of(cmd: list[str], repeat: int) -> tuple[float, dict, float]:
    """Median wall of ``cmd``, the medians of the stage times it prints (a JSON line) and the
    median CPU seconds."""
    walls, cpus, stages = [], [], {}
    for _ in range(repeat):
        wall, cpu, out = timed(cmd)
        walls.append(wall)
        cpus.append(cpu)
        lines = [ln for ln in out.splitlines() if ln.startswith("{")]
        for k, v in (json.loads(lines[-1]) if lines else {}).items():
            stages.setdefault(k, []).append(v)
    return (statistics.median(walls), {k: statistics.median(v) for k, v in stages.items()},
            statistics.median(cpus))  # fmt: skip


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
    # the workflow's notebook command
    nb_cmd = [PY, "-m", "avoa_pipeline.notebook", "-k", "avoa-pipeline", str(nb),
              str(tmp / "out.ipynb")]  # fmt: skip
    nb_free_cmd = [PY, "-c", NO_KERNEL, str(nb), str(tmp / "out_free.ipynb")]
    imports_cmd = [PY, "-c", NOTEBOOK["cells"][0]["source"][0]]
    for cmd in (fit_cmd, diag_cmd, nb_cmd, nb_free_cmd):  # warm-up: numba's cache, file cache
        timed(cmd)
    rows = []  # job, stage, wall s, CPU s (None: a stage inside one process, wall only)
    base, _, base_cpu = median_of([PY, "-c", "pass"], args.repeat)
    rows.append(("any job", "interpreter", base, base_cpu))
    pre, _, pre_cpu = median_of([PY, "-c", "import pickle; from snakemake import script"],
                                args.repeat)  # fmt: skip
    rows.append(("script job", "script preamble (beyond the interpreter)", pre - base,
                 pre_cpu - base_cpu))  # fmt: skip
    fit_wall, fit, _ = median_of(fit_cmd, args.repeat)
    rows += [("fit job", k, v, None) for k, v in fit.items()]
    diag_wall, diag, _ = median_of(diag_cmd, args.repeat)
    rows += [("diagnosis job", k, v, None) for k, v in diag.items()]
    nb_wall, _, nb_cpu = median_of(nb_cmd, args.repeat)
    rows.append(("notebook job", "papermill + kernel start + report imports", nb_wall, nb_cpu))
    free_wall, _, free_cpu = median_of(nb_free_cmd, args.repeat)
    rows.append(("notebook job", "the same without a kernel (cells exec'd)", free_wall, free_cpu))
    imp_wall, _, imp_cpu = median_of(imports_cmd, args.repeat)
    rows.append(("notebook job", "the report's imports alone (with interpreter)", imp_wall,
                 imp_cpu))  # fmt: skip
    guard, _, guard_cpu = median_of([PY, "-m", "avoa_pipeline.jobguard", PY, "-c", "pass"],
                                    args.repeat)  # fmt: skip
    rows.append(("notebook job", "the job guard's process (beyond the interpreter)",
                 guard - base, guard_cpu - base_cpu))  # fmt: skip
    print(f"{'job':<15} {'stage':<46} {'wall s':>7} {'CPU s':>7}")
    for job, stage, s, c in rows:
        print(f"{job:<15} {stage:<46} {s:7.3f} {'' if c is None else f'{c:7.3f}':>7}")
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
