"""Rules `gap_diagnose` and `gap_diagnose_real` (rules/gap.smk): one diagnosis of one record
(the CSV only, as a user runs it)."""

from avoa_pipeline import jobs

log = jobs.start(snakemake)

from avoa_pipeline.jobs.gap import diagnose_file

diagnose_file(snakemake.input[0], snakemake.output[0], log)
