# The `script:` of every rule that calls the package (avoa_pipeline.jobs has one adapter per
# rule): a Python process per job, so any Snakemake executor can run it; the job stops if the
# Snakemake process that started it dies (avoa_pipeline.jobguard).
from avoa_pipeline import jobguard, jobs

jobguard.watch()
jobs.run(snakemake)  # noqa: F821 - Snakemake defines `snakemake` in scripts
