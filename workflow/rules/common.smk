import sys
from pathlib import Path

import avoa_pipeline.config as avoa_config
from avoa_pipeline import jobguard, plan, snakemake_compat
from avoa_pipeline.model.battery import CASES

# Jobs learn which Snakemake started them, so a job that starts after a kill -9 of it stops at once
# (avoa_pipeline.jobguard).
jobguard.announce()

# A killed run's lock files, when no live Snakemake works here, are removed so that a plain rerun
# resumes; the workflow runs correctly without this (then `snakemake --unlock` once).
for _lock in snakemake_compat.clear_stale_locks_of(workflow):
    print(f"removed stale Snakemake lock .snakemake/locks/{_lock} (no live run here)",
          file=sys.stderr)

# At most one of the scheduler's re-evaluation timers pending: Snakemake 9 adds one that re-arms
# itself each second for every finished job, and its rounds took a third of a core in the whole
# study (avoa_pipeline.snakemake_compat; which jobs run is unchanged).
snakemake_compat.coalesce_reevaluation()

# `localrule: True` marks the jobs of a few seconds (notebooks, aggregates, tables, datasets and
# imports): on a cluster the submitting Snakemake runs them itself, as Snakemake's docs advise for
# short jobs, since a submission costs more than they do (a job step and a second Snakemake
# start-up: about 10-20 s on the local SLURM, docs/cluster.md); locally it changes nothing. Fits
# and diagnoses, minutes of CPU, are submitted (in groups, profiles/slurm). Each also takes one
# `local_job`: Snakemake 9 on a cluster starts local jobs without counting cores (its
# --local-cores is not used), so the SLURM profile caps them with that resource.

# The schema (Snakefile) checks shapes; these are the checks it cannot state. The whole config is
# checked here once, and each job gets only the parts its rule passes (config_part).
avoa_config.check(config, "snakemake config")


# Threads of a job (`threads:`): the job uses exactly these (avoa_pipeline.jobs.start gives them to
# numba and to a diagnosis's independent fits, avoa_pipeline.threads), and Snakemake lowers them to
# --cores. Most jobs take 1: many run side by side, which keeps every core busy. The long
# diagnoses, minutes each and often the last jobs running (the Panasonic joint fit and each
# temperature's diagnosis, the Samsung diagnoses), take 2 for their independent fits
# (selection.each; the joint fit's first rung 38.8 s on two threads against 48.2 s on one, at
# load 5-6, docs/real-data.md; on one thread the 25 degC diagnosis, the last job of
# tests/workflow/test_real.py, ran past that test's limit on a loaded machine). The many short
# ones (the withheld effects, the gap rows) take 1: a withheld-effect diagnosis took 21.2 s on two
# free cores against 22.5 s on one, for 1.5x the CPU time (docs/benchmarks.md, "A thread
# policy").
LONG_DIAGNOSIS_THREADS = 2


def config_part(*paths):
    """The parts of the config at ``paths`` (avoa_pipeline.config.part): what a rule passes to
    its job as a ``params`` entry, and all of the config the job sees."""
    return avoa_config.part(config, *paths)


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


def budget_figures():
    """The fixed-budget curves (beyond the paper), one figure and two CSVs per scenario."""
    return expand("results/figures/budget_s{s}{x}", s=SCENARIOS,
                  x=[".png", ".pdf", "_ecdf.csv", "_rank.csv"])


def papermill(notebook, executed, log, **params):
    """Shell command executing ``notebook`` with papermill (kernel of this venv, on sockets of
    its own: avoa_pipeline.notebook says why not papermill's command line)."""
    args = " ".join(f"-p {k} {v!r}" if isinstance(v, str) else f"-p {k} {v}" for k, v in params.items())
    # under the job guard: papermill and its kernel stop if Snakemake dies (kill safety); one
    # simple command, the log written by the guard, so that bash execs it and the kernel ties
    # the guard to Snakemake (avoa_pipeline.jobguard)
    return (f"{PY} -m avoa_pipeline.jobguard --log {log} {PY} -m avoa_pipeline.notebook "
            f"-k avoa-pipeline {notebook} {executed} {args}")


def case_inputs(w):
    s, c = scenario_case(w.nn)
    if not ran(s, c):
        return []
    return [f"results/aggregate/s{s}/c{c}/runs.parquet",
            f"results/aggregate/s{s}/c{c}/histories.parquet"]


def scenario_runs(w):
    s = int(w.nn) - 19
    return [f"results/aggregate/s{s}/c{c}/runs.parquet" for c in CASE_LIST if ran(s, c)]

# --- real data (rules in real.smk; docs/real-data.md) --------------------------------------------
from avoa_pipeline.real.experiments import drive_cycles as real_dc
from avoa_pipeline.importers import panasonic as real_panasonic

REAL = config.get("real") or {}
REAL_ROOT = Path(REAL["root"]) if REAL else None
REAL_PRESENT = bool(REAL) and REAL_ROOT.is_dir()  # relative to the working directory
REAL_CANON = "results/real/canonical"
SAMSUNG_CFG = REAL.get("samsung") or {}
NASA_CFG = REAL.get("nasa") or {}
SAMSUNG_TEMPS = list(SAMSUNG_CFG.get("hppc", {}))


def real_targets():
    """Every real-data output of the config (the `real` target): the Panasonic records, experiment
    1's table, figure and cross-cycle diagnostic, and experiments 2-3 (plan.cell_targets)."""
    out = [pan_canon(n) for n in pan_imports()]
    out += [f"{PAN_OUT}/cross_cycle/{t}.csv" for t in PAN_EXP_TEMPS]
    if PAN_EXP_TEMPS:
        out += ["results/real/drive_cycle_rmse.csv", "results/real/figures/panasonic_drive_cycles.png"]
    if PAN_JOINT_ON:  # one model over temperature (issue 28)
        out.append("results/real/joint_temperature.csv")
    if PAN_ESTIMATE_ON:  # SOC estimation with the selected models (issue 29; estimate.smk)
        out.append("results/real/soc_estimation.csv")
    return out + plan.cell_targets(config)


def real_outputs():
    """The real-data outputs for `all`: none without the data."""
    return real_targets() if REAL_PRESENT else []


PANASONIC = real_panasonic.records(config)
PAN_TEMPS = sorted({n.split("/")[0] for n in PANASONIC})
PAN_TESTS = sorted({n.split("/")[1] for n in PANASONIC})
PAN_EXP = (REAL.get("panasonic") or {}).get("experiment") or {}
PAN_OUT = "results/real/panasonic"
PAN_EXP_TEMPS = real_dc.temperatures(config) if PANASONIC and PAN_EXP else []
PAN_EXP_TEMP_RE = plan.regex(PAN_EXP_TEMPS)  # the ptemp wildcard of experiment 1's rules
PAN_GAP = bool(PAN_EXP.get("gap", True))
PAN_JOINT_ON = bool(PAN_EXP.get("joint", True)) and len(PAN_EXP_TEMPS) > 1  # rules in real.smk
PAN_ESTIMATE_ON = bool(PAN_EXP.get("estimate", True)) and bool(PAN_EXP_TEMPS)  # estimate.smk


def pan_sources(w):
    return [str(REAL_ROOT / k) for k in PANASONIC[f"{w.ptemp}/{w.ptest}"]["keys"]]


def pan_canon(name):
    return f"{REAL_CANON}/{plan.canonical_name(name)}.csv"


SAMSUNG_JOINT = SAMSUNG_CFG.get("joint") or {}
SAMSUNG_FITS = plan.samsung_joint_fits(config)  # issue 28's Samsung diagnoses (rules in real.smk)


def samsung_canon(temp):
    return f"{REAL_CANON}/samsung_hppc_{temp}.csv"


def pan_train(w):
    return pan_canon(f"{w.ptemp}/{PAN_EXP['train'][w.ptemp]}")


def pan_tests(temp):
    """Unseen drive cycles at ``temp``: cycle name → canonical CSV."""
    return {c: pan_canon(f"{temp}/{c}") for c in real_dc.unseen_cycles(config, temp)}


def pan_test_csvs(w):
    """The unseen drive cycles' CSVs at the rule's temperature (an input)."""
    return list(pan_tests(w.ptemp).values())


PAN_OCV_RECORD = pan_canon("25degC/ocv_c20") if PANASONIC else []  # the one slow test (25 degC)


def pan_imports():
    """The records `real` imports: with experiment 1, those of its temperatures and the C/20
    test (a config narrowing the experiment, e.g. config/tiny.yaml, imports no more); without
    it, every record the config names."""
    if not PAN_EXP_TEMPS:
        return list(PANASONIC)
    return [n for n in PANASONIC
            if n.split("/")[0] in PAN_EXP_TEMPS or pan_canon(n) == PAN_OCV_RECORD]


def pan_hppc(w):
    return pan_canon(f"{w.ptemp}/hppc")


def pan_fit_records():
    out = [f"{PAN_OUT}/fits/{t}/{m}/{a}.json" for t in PAN_EXP_TEMPS
           for m in real_dc.PAPER_MODELS for a in PAN_EXP["algorithms"]]
    return out + [f"{PAN_OUT}/fits/{t}/c20.json" for t in PAN_EXP_TEMPS]


def pan_diagnoses():
    """Diagnosis folders the table reads: prefix -> temperature -> folder (diagnosis.json,
    model.json); `gap` (the training cycle alone, no --ocv) only with experiment.gap."""
    out = {"diagnosis": {t: f"{PAN_OUT}/diagnosis/{t}" for t in PAN_EXP_TEMPS}}
    if PAN_GAP:
        out["gap"] = {t: f"{PAN_OUT}/gap/{t}" for t in PAN_EXP_TEMPS}
    return out


# --- the gap check (gap.smk) ----------------------------------------------------------------------
GAP = config.get("gap")
GAP_PLAN = plan.gap(GAP, real_present=REAL_PRESENT)  # every record and output of the gap rules
GAP_OUTPUTS = GAP_PLAN["outputs"]


def gap_grid(w, *keys):
    """The part of `gap:` one base cell's datasets are made from: ``keys`` and whether this
    cell carries the effect grid (``replicates`` holds it alone, so that adding a replicate
    reruns no other cell's datasets)."""
    gap = config["gap"]
    grid = {k: gap[k] for k in keys}
    grid["replicates"] = [int(w.replicate)] if int(w.replicate) in gap["replicates"] else []
    return grid


def gap_dir(w):
    """The folder of one base cell's datasets."""
    return f"results/gap/data/{w.profile}/r{w.replicate}"
