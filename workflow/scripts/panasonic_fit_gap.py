"""Rule `panasonic_fit_gap` (rules/real.smk): the diagnosis of the training cycle alone, without
--ocv (what a user without a slow test gets); the unseen cycles as validation records only."""

from pathlib import Path

from avoa_pipeline import jobs

log = jobs.start(snakemake)

from avoa_pipeline.jobs.real import diagnose_one

diagnose_one([snakemake.input.train], dict(snakemake.params.tests),
             str(Path(snakemake.output.json).parent), None, log)  # fmt: skip
