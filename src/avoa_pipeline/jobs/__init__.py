"""The workflow's jobs, one module per rules file (``jobs/gap.py`` for ``rules/gap.smk``, ...):
the thin functions that read plain inputs, call the package and write the outputs.

Every rule that calls the package is a ``script:`` rule on a script of its own in
``workflow/scripts/`` (named after the rule), which calls :func:`start` and then one job with
plain values: the rule's ``input``, ``output``, ``params``, ``wildcards`` and ``log``, never
Snakemake's ``config`` (the parts of the config a job reads are the rule's ``params``, cut by
:func:`avoa_pipeline.config.part`, so a change elsewhere in the config neither reaches nor reruns
it). Reading a rule thus tells what it computes; a script that names a function the package no
longer has, or a ``params`` entry its rule does not pass, fails a unit test
(``tests/unit/test_jobs.py``), not a run.

A job is a Python process of its own that any Snakemake executor can run, locally or on a
cluster node; nothing computes inside the Snakemake process (which imports :mod:`..plan`, never
this package: importing it, before NumPy, pins the BLAS thread pools to one thread).
"""

from __future__ import annotations

import os

os.environ.setdefault("PYBAMM_DISABLE_TELEMETRY", "true")
# one BLAS thread per job (set before numpy loads): scipy's least_squares and L-BFGS-B call
# BLAS on tiny matrices, and spinning BLAS threads on a busy 2-core machine made fits and
# diagnoses up to 30x slower (measured); a job claims one core (`threads: 1`)
for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")


def start(job) -> str | None:
    """Start a job: the kill-safety watch (:mod:`..jobguard`: the job stops if the Snakemake that
    started it dies) and the threads its rule declares (``threads:``, which Snakemake lowers to
    ``--cores``; :func:`..threads.use`: numba's and a diagnosis's threads stay within them).
    Returns the job's log file (``None`` without one)."""
    from .. import jobguard, threads

    jobguard.watch()
    threads.use(job.threads)
    return job.log[0] if len(job.log) else None
