import sys
from pathlib import Path

import avoa_pipeline.workflow as wf
from avoa_pipeline.model.battery import CASES

SCENARIOS = [int(s) for s in config["scenarios"]]
CASE_LIST = [int(c) for c in config["cases"]]
ALGOS = list(config["algorithms"])
SEEDS = [int(s) for s in config["seeds"]]
EFFECTIVE_CONFIG = "results/config.yaml"  # the validated config this run used
PAPER = "config/paper"
PY = sys.executable  # the interpreter running Snakemake: the project's venv


wildcard_constraints:
    scenario="|".join(map(str, SCENARIOS)),
    case="|".join(map(str, CASE_LIST)),
    algorithm="|".join(ALGOS),
    seed="|".join(map(str, SEEDS)),
    nn=r"\d\d",


def table_number(scenario, case):
    """Tables 4-19 and Figures 4-19: scenario-major, case-minor (the paper's numbering)."""
    return 4 + 4 * (int(scenario) - 1) + (int(case) - 1)


def scenario_case(nn):
    k = int(nn) - 4
    return k // 4 + 1, k % 4 + 1


def ran(scenario, case):
    return int(scenario) in SCENARIOS and int(case) in CASE_LIST


def fits_of(scenario, case):
    return expand(
        "results/fits/s{scenario}/c{case}/{algorithm}/seed{seed}.json",
        scenario=scenario, case=case, algorithm=ALGOS, seed=SEEDS,
    )


def sc_aggregate(scenario, case):
    """The scenario × case aggregate, or nothing when this config does not run it."""
    return f"results/aggregate/s{scenario}/c{case}/runs.parquet" if ran(scenario, case) else []


def ext(stem, exts):
    return [f"{stem}.{e}" for e in exts]


TABLE_EXT = ("csv", "md", "tex")
FIG_EXT = ("png", "pdf")


def all_tables():
    return [f"results/tables/table{n:02d}.{e}" for n in range(1, 25) for e in TABLE_EXT]


def all_figures():
    return [f"results/figures/fig{n:02d}.{e}" for n in range(1, 22) for e in FIG_EXT]


def papermill(notebook, executed, log, **params):
    """Shell command executing ``notebook`` with papermill (kernel of this venv)."""
    args = " ".join(f"-p {k} {v!r}" if isinstance(v, str) else f"-p {k} {v}" for k, v in params.items())
    return (f"{PY} -m papermill --no-progress-bar -k avoa-pipeline {notebook} {executed} "
            f"{args} > {log} 2>&1")


def case_inputs(w):
    s, c = scenario_case(w.nn)
    if not ran(s, c):
        return []
    return [f"results/aggregate/s{s}/c{c}/runs.parquet",
            f"results/aggregate/s{s}/c{c}/histories.parquet"]


def scenario_runs(w):
    s = int(w.nn) - 19
    return [f"results/aggregate/s{s}/c{c}/runs.parquet" for c in CASE_LIST if ran(s, c)]
