"""Rule `real_samsung_diagnose` (rules/real.smk): issue 28 on the Samsung 30Q, the diagnosis of
the training temperatures' HPPC tests (together, or one alone), the unseen one validated only."""

from pathlib import Path

from avoa_pipeline import jobs

log = jobs.start(snakemake)

from avoa_pipeline.jobs.real import diagnose_one

diagnose_one(list(snakemake.input.train), dict(snakemake.params.tests),
             str(Path(snakemake.output.json).parent), None, log)  # fmt: skip
