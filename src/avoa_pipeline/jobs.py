"""What each Snakemake rule runs: one adapter per rule, from the job to a package function with
plain arguments.

Every rule that calls the package is a ``script:`` rule on ``workflow/scripts/job.py``, which
starts the kill-safety watch (:mod:`.jobguard`) and calls :func:`run` with Snakemake's job
object. A job is thus a Python process of its own that any Snakemake executor can run, locally
or on a cluster node; nothing computes inside the Snakemake process. An adapter reads only the
job's ``config``, ``input``, ``output``, ``params``, ``wildcards`` and ``log`` (a
``types.SimpleNamespace`` with those attributes runs it without Snakemake, as the tests do), and
the functions it calls take plain values.
"""

from __future__ import annotations

import os

os.environ.setdefault("PYBAMM_DISABLE_TELEMETRY", "true")
# one BLAS thread per job (set before numpy loads): scipy's least_squares and L-BFGS-B call
# BLAS on tiny matrices, and spinning BLAS threads on a busy 2-core machine made fits and
# diagnoses up to 30x slower (measured); a job claims one core (`threads: 1`)
for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")


def _log(job):
    return job.log[0] if len(job.log) else None


# --- the paper's grid ---------------------------------------------------------------------------


def dataset(job) -> None:
    from . import workflow as wf

    wf.dataset(job.config, job.wildcards.scenario, job.wildcards.case, job.output.csv, _log(job))


def effective_config(job) -> None:
    from . import workflow as wf

    wf.effective_config(job.config, job.output[0])


def fit(job) -> None:
    """One batch of seeds (the ``fit_*`` rules of ``identify.smk``)."""
    from . import workflow as wf

    w = job.wildcards
    wf.fit_batch(job.config, job.input.data, w.scenario, w.case, w.algorithm, job.params.seeds,
                 list(job.output), _log(job))  # fmt: skip


def aggregate_case(job) -> None:
    from . import workflow as wf

    wf.aggregate_runs(list(job.input), job.output.runs, job.output.histories, _log(job))


def aggregate_all(job) -> None:
    from . import workflow as wf

    wf.concat_aggregates(list(job.input.runs), list(job.input.histories), job.output.runs,
                         job.output.histories, _log(job))  # fmt: skip


# --- the gap check ------------------------------------------------------------------------------


def _gap_dir(job) -> str:
    return f"results/gap/data/{job.wildcards.profile}/r{job.wildcards.replicate}"


def gap_data(job) -> None:
    from .gap import evaluate as ev

    ev.generate(job.config["base_seed"], job.config["gap"], job.wildcards.profile,
                job.wildcards.replicate, _gap_dir(job), _log(job))  # fmt: skip


def gap_pair_data(job) -> None:
    from .gap import evaluate as ev

    ev.generate_pairs(job.config["base_seed"], job.config["gap"], job.wildcards.profile,
                      job.wildcards.replicate, _gap_dir(job), _log(job))  # fmt: skip


def gap_pairs_table(job) -> None:
    from .gap import evaluate as ev

    ev.pair_table_job(list(job.input.data), list(job.input.diag), job.output[0],
                      job.params.threshold, _log(job))  # fmt: skip


def gap_paper_data(job) -> None:
    from .gap import evaluate as ev

    ev.paper_job(job.config, job.wildcards.scenario, job.wildcards.case, job.output.csv,
                 _log(job))  # fmt: skip


def gap_pybamm_data(job) -> None:
    from .gap import evaluate as ev

    ev.pybamm(job.config["base_seed"], job.wildcards.name, job.output.csv, _log(job))


def gap_diagnose(job) -> None:
    from .gap import evaluate as ev

    ev.diagnose_file(job.input[0], job.output[0], _log(job))


def _table(job, make_row) -> None:
    from .gap import evaluate as ev

    ev.table_job(make_row, list(job.input.data), list(job.input.diag), job.output[0], _log(job))


def gap_real_table(job) -> None:
    from .gap import evaluate as ev

    _table(job, ev.real_record)


def gap_pybamm_table(job) -> None:
    from .gap import evaluate as ev

    _table(job, ev.pybamm_record)


def gap_paper_table(job) -> None:
    from functools import partial

    from .gap import evaluate as ev

    _table(job, partial(ev.paper_record, threshold=job.params.threshold))


def gap_evaluate(job) -> None:
    from .gap import evaluate as ev

    ev.evaluate_job(list(job.input.data), list(job.input.diag), dict(job.output),
                    job.params.threshold, _log(job), pairs_csv=list(job.input.pairs))  # fmt: skip


# --- real data ----------------------------------------------------------------------------------


def panasonic_import(job) -> None:
    from .real import jobs as rj

    rj.panasonic_import(job.config, f"{job.wildcards.ptemp}/{job.wildcards.ptest}",
                        job.output.csv, _log(job))  # fmt: skip


def panasonic_ocv(job) -> None:
    from .real import jobs as rj

    rj.panasonic_ocv(job.input[0], job.output.csv, _log(job))


def panasonic_fit_paper(job) -> None:
    from .real import jobs as rj

    w = job.wildcards
    rj.paper_fit_one(job.config, w.ptemp, w.pmodel, w.algorithm, job.input.train,
                     dict(job.params.tests), job.output[0], _log(job))  # fmt: skip


def panasonic_fit_c20(job) -> None:
    from .real import jobs as rj

    rj.c20_fit_one(job.wildcards.ptemp, job.input.train, dict(job.params.tests), job.input.ocv,
                   job.output[0], _log(job))  # fmt: skip


def _diagnose_dir(job) -> str:
    from pathlib import Path

    return str(Path(job.output.json).parent)


def panasonic_diagnose(job) -> None:
    from .real import jobs as rj

    rj.diagnose_one([job.input.train, job.input.hppc], dict(job.params.tests), _diagnose_dir(job),
                    job.input.ocv, _log(job))  # fmt: skip


def panasonic_fit_gap(job) -> None:
    from .real import jobs as rj

    rj.diagnose_one([job.input.train], dict(job.params.tests), _diagnose_dir(job), None,
                    _log(job))  # fmt: skip


def panasonic_cross_cycle(job) -> None:
    from .real import jobs as rj

    rj.cross_cycle_one(job.config, job.wildcards.ptemp, job.input.model, dict(job.params.cycles),
                       job.input.ocv, job.output[0], _log(job))  # fmt: skip


def panasonic_drive_cycle_table(job) -> None:
    from .real import jobs as rj

    rj.drive_cycle_table(job.config, list(job.input.fits), dict(job.params.diagnoses),
                         dict(job.params.tests), job.output.csv, job.output.runs,
                         job.output.pred, _log(job))  # fmt: skip


def real_samsung_import(job) -> None:
    from .real import cells_cli

    cells_cli.samsung_import(job.config, job.wildcards.stemp, job.output.csv, _log(job))


def real_samsung_arrhenius(job) -> None:
    from .real import cells_cli

    hppc = dict(zip(job.params.temperatures, job.input, strict=True))
    cells_cli.arrhenius(job.config, hppc, job.output.rc, job.output.arrhenius, _log(job))


def real_nasa_import(job) -> None:
    from .real import cells_cli

    cells_cli.nasa_import(job.config, job.output.csv, _log(job))


def real_nasa_fade(job) -> None:
    from .real import cells_cli

    cells_cli.fade(job.config, job.input[0], job.output.states, job.output.fits, _log(job))


# ------------------------------------------------------------------------------------------------

RULES = {
    "dataset": dataset, "effective_config": effective_config, "fit": fit,
    "aggregate_case": aggregate_case, "aggregate_all": aggregate_all,
    "gap_data": gap_data, "gap_controls": gap_data, "gap_pair_data": gap_pair_data,
    "gap_pairs_table": gap_pairs_table, "gap_paper_data": gap_paper_data,
    "gap_pybamm_data": gap_pybamm_data, "gap_diagnose": gap_diagnose,
    "gap_diagnose_real": gap_diagnose, "gap_real_table": gap_real_table,
    "gap_pybamm_table": gap_pybamm_table, "gap_paper_table": gap_paper_table,
    "gap_evaluate": gap_evaluate,
    "panasonic_import": panasonic_import, "panasonic_ocv": panasonic_ocv,
    "panasonic_fit_paper": panasonic_fit_paper, "panasonic_fit_c20": panasonic_fit_c20,
    "panasonic_diagnose": panasonic_diagnose, "panasonic_fit_gap": panasonic_fit_gap,
    "panasonic_cross_cycle": panasonic_cross_cycle,
    "panasonic_drive_cycle_table": panasonic_drive_cycle_table,
    "real_samsung_import": real_samsung_import, "real_samsung_arrhenius": real_samsung_arrhenius,
    "real_nasa_import": real_nasa_import, "real_nasa_fade": real_nasa_fade,
}  # fmt: skip
"""Rule name → adapter (rules added by other files register theirs here too)."""


def adapter(rule: str):
    """The adapter of a rule: by its name; the per-batch fit rules (``fit_<k>``) share ``fit``."""
    if rule in RULES:
        return RULES[rule]
    if rule.startswith("fit_") and rule[4:].isdigit():
        return fit
    raise KeyError(f"no job adapter for rule {rule!r}")


def run(job) -> None:
    adapter(job.rule)(job)
